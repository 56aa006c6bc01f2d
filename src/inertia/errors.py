"""Exceptions raised by Inertia.

`ValueError` is used for bad input (it names the argument and the allowed values);
`SimulationDiverged` is raised when a step produces non-finite state.
"""

from __future__ import annotations

__all__ = ["SimulationDiverged", "check_substep_runaway", "MAX_SUBSTEPS_PER_ADVANCE"]

#: CFL substeps one ``advance`` may take before a fluid is declared diverged: a flow whose speed
#: keeps growing shrinks its CFL step without bound and never reaches the end of the step
MAX_SUBSTEPS_PER_ADVANCE = 2000


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


def check_substep_runaway(kind: str, substeps: int, done: float, frame_dt: float, speed: float, *,
                          step: int, time: float, dt: float | None = None) -> None:
    """Raise `SimulationDiverged` once a CFL-limited ``advance`` has taken more than
    `MAX_SUBSTEPS_PER_ADVANCE` substeps, or, given the substep ``dt`` about to be taken, as soon as the
    flow at its current speed would need more than ten times that many to finish the step: the flow's
    speed (``speed``, m/s) grew so fast that its stable step shrinks faster than time advances, so the
    run would never end (a 1e12 m/s inflow is caught before its first substep instead of after 2000)."""
    needed = substeps if dt is None or dt <= 0.0 else substeps + (frame_dt - done) / dt
    if substeps <= MAX_SUBSTEPS_PER_ADVANCE and needed <= 10 * MAX_SUBSTEPS_PER_ADVANCE:
        return
    raise SimulationDiverged(
        f"{kind} step {step} (t = {time:.6g} s): {substeps} CFL substeps covered only {done:.3g} of the "
        f"{frame_dt:g} s step (max speed {speed:.3g} m/s; at that speed the step needs {needed:.3g} substeps); "
        "likely cause: a body acceleration, source or inflow too strong for the grid, or a velocity blow-up",
        step=step, time=time, indices=[])
