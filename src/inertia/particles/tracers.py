"""Tracers: massless particles carried by a velocity field, dx/dt = g(x, t).

References: Witkin & Baraff (2001), "Differential Equation Basics" (the particle in a flow field,
the canonical first-order example: explicit Euler spirals outward in a rotational field).

Arrays: ``state`` (N D,) positions; ``x`` (N, D) a view of it.
Limitations: first order, so only euler, midpoint, rk4 and rk45 apply.
"""

from __future__ import annotations

import numpy as np

from .. import _validate as V
from ..ode.system import PhaseSpaceSystem

__all__ = ["Tracers"]


class Tracers(PhaseSpaceSystem):
    """N massless points advected by ``velocity_field(points (N, D), t) -> (N, D)``.

    If the field has ``sample(points, t, out)`` it is used to avoid allocating per evaluation.
    """

    second_order = False

    def __init__(self, positions, velocity_field):
        x0 = V.as_points(positions, "positions")
        if not callable(velocity_field):
            raise ValueError("velocity_field must be callable as field(points (N, D), t) -> (N, D); "
                             f"got {type(velocity_field).__name__}")
        self.particle_count, self.dim = x0.shape
        self.state = x0.reshape(-1).copy()
        self.x = self.state.reshape(self.particle_count, self.dim)
        self.velocity_field = velocity_field
        self._sample = getattr(velocity_field, "sample", None)
        self.position_size = self.state.shape[0]
        self.stages: list = []
        self.radius = np.zeros(self.particle_count)
        self.active = np.ones(self.particle_count, dtype=bool)
        self.state_revision = 0

    def derivative(self, y, t, out) -> None:
        n, d = self.particle_count, self.dim
        points, velocities = y.reshape(n, d), out.reshape(n, d)
        if self._sample is not None:
            self._sample(points, t, velocities)
            return
        value = np.asarray(self.velocity_field(points, t), dtype=np.float64)
        if value.shape != (n, d):
            raise ValueError(f"velocity_field returned shape {value.shape}; expected {(n, d)}")
        velocities[:] = value

    @property
    def v(self) -> np.ndarray:
        """The field velocity at the current positions (computed on request)."""
        out = np.zeros_like(self.state)
        self.derivative(self.state, getattr(self, "t", 0.0), out)
        return out.reshape(self.particle_count, self.dim)

    def get_state(self) -> dict:
        return {"state": self.state.copy(), "state_revision": self.state_revision,
                "stages": [s.get_state() for s in self.stages]}

    def set_state(self, saved: dict) -> None:
        self.state[:] = saved["state"]
        for stage, s in zip(self.stages, saved["stages"]):
            stage.set_state(s)
        self.state_revision = saved["state_revision"]

    def describe_particles(self, indices) -> str:
        indices = np.asarray(indices)
        return f"tracers [{', '.join(str(i) for i in indices[:8])}{' ...' if indices.size > 8 else ''}]"

    def stability_hint(self, dt: float) -> str:
        return ""
