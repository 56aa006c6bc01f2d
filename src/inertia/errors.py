"""Exceptions raised by Inertia.

`ValueError` is used for bad input (it names the argument and the allowed values);
`SimulationDiverged` is raised when a step produces non-finite state.
"""

from __future__ import annotations

__all__ = ["SimulationDiverged"]


class SimulationDiverged(RuntimeError):
    """A step produced NaN or infinite values.

    Attributes
    ----------
    step : int
        Index of the step that diverged (0 is the first step taken).
    time : float
        Simulated time at the start of that step, in seconds.
    indices : numpy.ndarray
        Indices of the particles (or state entries) that became non-finite.
    """

    def __init__(self, message: str, *, step: int, time: float, indices):
        super().__init__(message)
        self.step = step
        self.time = time
        self.indices = indices
