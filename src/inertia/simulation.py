"""The fixed-step simulation loop.

One step of `Simulation.step` runs these stages, in order, each timed into ``profile``:

1. ``begin``     -- every stage of the system prepares (collision: remember the step's start
                   positions for continuous detection).
2. ``integrate`` -- the integrator advances ``system.state`` by dt; inside it, each derivative
                   evaluation clears the force accumulator, lets every force object add, applies
                   constraint force filters (resting contact), and gathers a = f / m.
3. ``end``       -- every stage finishes the step (collision detection and response, emitters
                   retiring and spawning particles).
4. ``check``     -- the state is checked for NaN/inf; a blow-up raises `SimulationDiverged`.
                   The fused kernels check the values they write in the same pass
                   (``system.finite_revision``, see ``inertia.ode.system``); only when no such
                   witness covers the final state does this stage read the state again.

Time is kept as ``start_time + step_count * dt`` so it does not drift by rounding.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from . import _validate as V
from .errors import SimulationDiverged
from .ode import integrators as _integrators
from .ode.kernels import all_finite

__all__ = ["Simulation", "SimulationState"]


@dataclass
class SimulationState:
    """A checkpoint: everything needed to continue a run bit for bit."""

    time: float
    step_count: int
    system: dict
    integrator: dict
    extra: dict = field(default_factory=dict)


class Simulation:
    """Steps a system with a chosen integrator at a fixed time step.

    Parameters
    ----------
    system : a `ParticleSystem`, `Tracers` or any phase-space system.
    integrator : a name from ``inertia.integrators.available()`` ("rk4" default).
    dt : time step in seconds (> 0).
    callback : optional ``callback(simulation)`` called after every step.
    check_finite : check the state for NaN/inf after each step (True default).
    **integrator_options : passed to the integrator (e.g. ``rtol`` for rk45).
    """

    def __init__(self, system, integrator="rk4", dt=1e-3, *, callback=None, check_finite=True,
                 start_time=0.0, **integrator_options):
        if not hasattr(system, "state") or not hasattr(system, "derivative"):
            raise ValueError(f"system must be a phase-space system (ParticleSystem, Tracers, ...); "
                             f"got {type(system).__name__}")
        self.system = system
        self.dt = V.positive_scalar(dt, "dt")
        if not isinstance(integrator, str):
            raise ValueError(f"integrator must be one of {_integrators.available()}; got {integrator!r}")
        self.integrator_name = integrator
        self.integrator = _integrators.create(integrator, system, **integrator_options)
        if callback is not None and not callable(callback):
            raise ValueError("callback must be callable as callback(simulation)")
        self.callback = callback
        self.check_finite = bool(check_finite)
        self.start_time = float(start_time)
        self.step_count = 0
        self.t = self.start_time
        system.t = self.t
        self.profile = {"begin": 0.0, "integrate": 0.0, "end": 0.0, "check": 0.0}

    def step(self) -> None:
        """Advance by one time step dt."""
        s, t, dt = self.system, self.t, self.dt
        clock = _time.perf_counter
        t0 = clock()
        s.integrator_fused_step = self.integrator.fused_step
        for stage in s.stages:
            stage.begin_step(s, t, dt)
        t1 = clock()
        s.finite_revision = None  # a fused kernel of this step may vouch for the new state
        self.integrator.step(t, dt)
        t2 = clock()
        for stage in s.stages:
            stage.end_step(s, t, dt)
        t3 = clock()
        self.step_count += 1
        self.t = self.start_time + self.step_count * dt
        s.t = self.t
        if self.check_finite:
            witness = getattr(s, "finite_revision", None)
            witnessed = witness is not None and witness == getattr(s, "state_revision", None)
            if not witnessed and not all_finite(s.state):
                self._diverged(t)
        t4 = clock()
        p = self.profile
        p["begin"] += t1 - t0
        p["integrate"] += t2 - t1
        p["end"] += t3 - t2
        p["check"] += t4 - t3
        if self.callback is not None:
            self.callback(self)

    def run(self, duration: float, callback=None) -> None:
        """Advance by `duration` seconds (rounded to a whole number of steps)."""
        duration = V.positive_scalar(duration, "duration", allow_zero=True)
        steps = int(np.ceil(duration / self.dt - 1e-9))
        for _ in range(steps):
            self.step()
            if callback is not None:
                callback(self)

    def _diverged(self, t_start):
        s = self.system
        y = s.state
        n = getattr(s, "particle_count", None)
        if n:
            rows = y.reshape(-1, n, s.dim) if getattr(s, "second_order", False) else y.reshape(1, n, s.dim)
            bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=(0, 2)))
            who = s.describe_particles(bad)
        else:
            bad = np.flatnonzero(~np.isfinite(y))
            who = f"state entries {bad[:8].tolist()}"
        hint = s.stability_hint(self.dt) if hasattr(s, "stability_hint") else ""
        message = (f"simulation diverged at step {self.step_count - 1} (t = {t_start:.6g} s): {who} "
                   f"became NaN or infinite with integrator {self.integrator_name!r} and dt = {self.dt:g} s. "
                   + (f"Likely cause: {hint}. " if hint else "")
                   + "Try a smaller dt or integrator='implicit_euler' for stiff springs.")
        raise SimulationDiverged(message, step=self.step_count - 1, time=t_start, indices=bad)

    # ---- checkpoints
    def save_state(self) -> SimulationState:
        """Snapshot of everything that changes; ``restore_state`` continues identically."""
        return SimulationState(self.t, self.step_count, self.system.get_state(),
                               self.integrator.get_state())

    def restore_state(self, saved: SimulationState) -> None:
        self.system.set_state(saved.system)
        self.integrator.set_state(saved.integrator)
        self.step_count = saved.step_count
        self.t = saved.time
        self.system.t = self.t

    def __repr__(self):
        return (f"Simulation({self.system!r}, integrator={self.integrator_name!r}, dt={self.dt:g}, "
                f"t={self.t:g})")
