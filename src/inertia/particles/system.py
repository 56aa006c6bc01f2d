"""Particle systems: point masses in phase space (Witkin & Baraff, "Particle System Dynamics").

References
----------
Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes: the
particle system as a phase-space ODE and the three-phase derivative evaluation
(clear force accumulators -> every force object adds -> gather dv/dt = f / m).

Arrays (N = particle_count, D = dim, all float64 unless said):
- ``state``  (2 N D,)  the phase-space vector [x, v]; written by the integrator and by collision response.
- ``x``, ``v`` (N, D)  views of ``state`` (positions in m, velocities in m/s). They are views: a
  slice you keep changes with the simulation; ``.copy()`` to keep a snapshot.
- ``mass`` (N,)        kg; ``inf`` for pinned particles.
- ``inv_mass`` (N,)    1/kg; 0 for pinned and for inactive (emitter pool) particles.
- ``node_free`` (N,) bool  inv_mass > 0: the particles the integrators move.
- ``radius`` (N,)      m; 0 for points. Used by collisions and rendering.
- ``active`` (N,) bool False for unused emitter-pool slots (hidden from output).
- ``force_accumulator`` (N, D)  N; cleared and refilled at every derivative evaluation.

Limitations: the particle count is fixed at construction (emitters recycle a preallocated pool).
"""

from __future__ import annotations

import numpy as np

from .. import _validate as V
from ..ode.system import BlockSparsePattern, PhaseSpaceSystem
from . import kernels as K
from .forces import Force

__all__ = ["ParticleSystem"]


class ParticleSystem(PhaseSpaceSystem):
    """N point masses in 2D or 3D under force objects.

    Parameters
    ----------
    positions : (N, D) array, D in {2, 3}; copied into the state.
    velocities : (N, D) array or None (zero).
    masses : scalar or (N,) in kg, > 0; ``inf`` pins a particle.
    pinned : optional indices (or boolean mask) of particles to pin (infinite mass).
    radius : scalar or (N,) in m, >= 0 (collision and rendering size; 0 = point).
    """

    second_order = True

    def __init__(self, positions, velocities=None, masses=1.0, *, pinned=None, radius=0.0):
        x0 = V.as_points(positions, "positions")
        n, d = x0.shape
        self.particle_count, self.dim = n, d
        self.position_size = n * d
        self.state = np.zeros(2 * n * d)
        self.x = self.state[: n * d].reshape(n, d)
        self.v = self.state[n * d:].reshape(n, d)
        self.x[:] = x0
        if velocities is not None:
            self.v[:] = V.as_points(velocities, "velocities", dim=d, count=n)
        self.mass = V.per_item(masses, "masses", n, positive=True, allow_inf=True)
        if pinned is not None:
            pinned = np.asarray(pinned)
            if pinned.dtype == bool:
                if pinned.shape != (n,):
                    raise ValueError(f"pinned as a mask must have shape ({n},); got {pinned.shape}")
                pinned = np.flatnonzero(pinned)
            self.mass[V.index_array(pinned.reshape(-1), "pinned", n)] = np.inf
        self.radius = V.per_item(radius, "radius", n, nonnegative=True)
        self.active = np.ones(n, dtype=bool)
        self.inv_mass = np.zeros(n)
        self.node_free = np.zeros(n, dtype=bool)
        self.refresh_masses()
        self.force_accumulator = np.zeros((n, d))
        self._acceleration = np.zeros((n, d))
        self.forces: list[Force] = []
        self.stages: list = []          # step stages (collisions, emitters): see docs/contracts.md
        self.force_filters: list = []   # constraint forces applied after all force objects
        self.emitters: list = []
        self._collision = None
        self._affine = None
        self._pattern = None
        self.state_revision = 0

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def pool(cls, capacity: int, dim: int = 3, *, mass=1.0, radius=0.0) -> "ParticleSystem":
        """A system of `capacity` inactive particles for emitters to fill."""
        if not isinstance(capacity, (int, np.integer)) or capacity <= 0:
            raise ValueError(f"capacity must be a positive integer; got {capacity!r}")
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3; got {dim!r}")
        system = cls(np.zeros((int(capacity), dim)), masses=mass, radius=radius)
        system.active[:] = False
        system.refresh_masses()
        return system

    def refresh_masses(self) -> None:
        """Recompute ``inv_mass`` and ``node_free`` from ``mass`` and ``active``."""
        with np.errstate(divide="ignore"):
            np.divide(1.0, self.mass, out=self.inv_mass)
        self.inv_mass[~self.active] = 0.0
        np.greater(self.inv_mass, 0.0, out=self.node_free)

    def add_force(self, force: Force) -> Force:
        """Add a force object (see `inertia.forces`); returns it."""
        if not isinstance(force, Force):
            raise ValueError(f"add_force expects an inertia.forces.Force (Gravity, Drag, Springs, ...); "
                             f"got {type(force).__name__}")
        force.bind(self)
        self.forces.append(force)
        self._affine = None
        self._pattern = None
        return force

    def add_emitter(self, emitter):
        """Attach an `inertia.Emitter`; it spawns into inactive particles of this system."""
        emitter.bind(self)
        self.emitters.append(emitter)
        self.add_stage(emitter)
        return emitter

    def add_stage(self, stage) -> None:
        """Insert a step stage, keeping ``stages`` sorted by ``stage.stage_order`` (default 50;
        collisions 50, emitters 90: emitters spawn after collision response)."""
        order = getattr(stage, "stage_order", 50)
        position = len(self.stages)
        while position > 0 and getattr(self.stages[position - 1], "stage_order", 50) > order:
            position -= 1
        self.stages.insert(position, stage)

    # ---- collisions: delegated to the collision layer (inertia.collision.particle_stage)
    def add_collider(self, collider, *, restitution=0.5, friction=0.0):
        """Collide the particles with `collider` (see `inertia.colliders`); returns the collider.

        restitution in [0, 1] (0.5 default), friction: Coulomb coefficient >= 0 (0 default).
        """
        from ..collision.particle_stage import attach_collider
        attach_collider(self, collider, restitution=restitution, friction=friction)
        return collider

    @property
    def collision_mode(self) -> str:
        """"a_priori" (continuous, default: nothing tunnels) or "a_posteriori" (detect after the step)."""
        return "a_priori" if self._collision is None else self._collision.mode

    @collision_mode.setter
    def collision_mode(self, mode: str) -> None:
        from ..collision.particle_stage import set_collision_mode
        set_collision_mode(self, mode)

    @property
    def self_collisions(self) -> bool:
        """Whether particles (as spheres of their ``radius``) collide with each other."""
        return False if self._collision is None else bool(self._collision.self_collisions)

    @self_collisions.setter
    def self_collisions(self, flag: bool) -> None:
        from ..collision.particle_stage import set_self_collisions
        set_self_collisions(self, flag)

    # ------------------------------------------------------------------ phase-space interface
    def _affine_terms(self):
        """Summed (g, F, k) when every force is affine per particle and every filter is fusable.

        A force filter with ``fusable = True`` promises that its owner reproduces its effect after a
        fused step (in its ``end_step``), so the fused kernels may skip it.
        """
        if any(not getattr(f, "fusable", False) for f in self.force_filters):
            return None
        if self._affine is None:
            g, F, k = np.zeros(self.dim), np.zeros(self.dim), 0.0
            for force in self.forces:
                terms = force.affine_terms()
                if terms is None:
                    self._affine = False
                    return None
                g, F, k = g + terms[0], F + terms[1], k + terms[2]
            self._affine = (g, F, k)
        return self._affine or None

    def accumulate_forces(self, x, v, t, f) -> None:
        """Phases 1 and 2 of the derivative: clear f, let every force and filter add."""
        f.fill(0.0)
        for force in self.forces:
            force.accumulate(x, v, t, f)
        for constraint in self.force_filters:
            constraint.apply(x, v, t, f)

    def acceleration(self, x, v, t, out) -> None:
        """out = dv/dt for flat (N*D,) x, v, out."""
        n, d = self.particle_count, self.dim
        x, v, out = x.reshape(n, d), v.reshape(n, d), out.reshape(n, d)
        affine = self._affine_terms()
        if affine is not None:
            K.affine_acceleration(v, self.inv_mass, affine[0], affine[1], affine[2], out)
            return
        self.accumulate_forces(x, v, t, self.force_accumulator)
        K.gather_acceleration(self.force_accumulator, self.inv_mass, out)

    def derivative(self, y, t, out) -> None:
        """out = dy/dt = [v, f/m] (three phases: clear, accumulate, gather)."""
        n, d = self.particle_count, self.dim
        m = n * d
        v = y[m:].reshape(n, d)
        affine = self._affine_terms()
        if affine is not None:
            K.affine_derivative(v, self.inv_mass, affine[0], affine[1], affine[2],
                                out[:m].reshape(n, d), out[m:].reshape(n, d))
            return
        out[:m] = y[m:]
        self.acceleration(y[:m], y[m:], t, out[m:])

    def kick_drift(self, t, dt) -> bool:
        """Fused semi-implicit Euler step when all forces are affine per particle.

        The kernel also checks the new state for NaN/inf (``finite_revision``) and, when the
        collision stage prepared for it, runs the collision pass in the same pass over memory."""
        return self._fused_step(dt, "kick_drift", K.affine_kick_drift)

    def fused_rk4(self, t, dt) -> bool:
        """Fused RK4 step when all forces are affine per particle (each particle is independent)."""
        return self._fused_step(dt, "rk4", K.affine_rk4)

    def _fused_step(self, dt, method, kernel) -> bool:
        affine = self._affine_terms()
        if affine is None:
            return False
        collision = self._collision
        if collision is not None and collision.fused_armed and collision.fused_step == method:
            collision.run_fused(self, affine, method == "rk4", dt)  # end_step reports the check
            return True
        finite = kernel(self.x, self.v, self.inv_mass, affine[0], affine[1], affine[2], dt)
        self.finite_revision = self.state_revision if finite else None
        return True

    # implicit integration -------------------------------------------------------
    @property
    def node_mass(self) -> np.ndarray:
        return self.mass

    @property
    def jacobian_pattern(self) -> BlockSparsePattern:
        """Block-sparse pattern of df/dx and df/dv over all forces that provide Jacobians."""
        if self._pattern is None:
            pairs = [f.jacobian_pairs() for f in self.forces if f.provides_jacobian]
            pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.int64)
            self._pattern = BlockSparsePattern.from_pairs(self.particle_count, pairs, self.dim)
            for f in self.forces:
                if f.provides_jacobian:
                    f.bind_jacobian(self._pattern)
        return self._pattern

    def evaluate_with_jacobians(self, x, v, t, f, dfdx, dfdv) -> None:
        """f = total force, dfdx and dfdv = its block-sparse Jacobians (forces without them are explicit)."""
        n, d = self.particle_count, self.dim
        x, v, f = x.reshape(n, d), v.reshape(n, d), f.reshape(n, d)
        self.jacobian_pattern  # binds the slots
        self.accumulate_forces(x, v, t, f)
        dfdx.fill(0.0)
        dfdv.fill(0.0)
        for force in self.forces:
            if force.provides_jacobian:
                force.add_jacobians(x, v, t, dfdx, dfdv)

    # ------------------------------------------------------------------ observables
    def kinetic_energy(self) -> float:
        """T = sum_i m_i |v_i|^2 / 2 over free particles (J)."""
        free = self.node_free
        return float(0.5 * np.sum(self.mass[free] * np.einsum("ij,ij->i", self.v[free], self.v[free])))

    def potential_energy(self) -> float:
        """Sum of the potential energies of the conservative forces (J)."""
        return float(sum(f.potential_energy(self.x) for f in self.forces if f.conservative))

    def total_energy(self) -> float:
        return self.kinetic_energy() + self.potential_energy()

    def momentum(self) -> np.ndarray:
        """Total linear momentum sum_i m_i v_i over free particles (kg m/s), shape (D,)."""
        free = self.node_free
        return np.sum(self.mass[free, None] * self.v[free], axis=0)

    # ------------------------------------------------------------------ checkpoints
    def get_state(self) -> dict:
        """Everything that changes during a run, for a bit-identical continuation."""
        return {
            "state": self.state.copy(), "mass": self.mass.copy(), "active": self.active.copy(),
            "state_revision": self.state_revision,
            "stages": [s.get_state() for s in self.stages],
        }

    def set_state(self, saved: dict) -> None:
        self.state[:] = saved["state"]
        self.mass[:] = saved["mass"]
        self.active[:] = saved["active"]
        self.refresh_masses()
        for stage, s in zip(self.stages, saved["stages"]):
            stage.set_state(s)
        self.state_revision = saved["state_revision"]

    def describe_particles(self, indices) -> str:
        """A short text naming particles, for error messages."""
        indices = np.asarray(indices)
        shown = ", ".join(str(i) for i in indices[:8])
        more = f" and {indices.size - 8} more" if indices.size > 8 else ""
        return f"particles [{shown}{more}]"

    def stability_hint(self, dt: float) -> str:
        """The likely cause of a blow-up at time step dt: the stiffest spring's explicit limit."""
        m_min = float(np.min(self.mass[self.node_free])) if np.any(self.node_free) else 1.0
        k_max, name = 0.0, None
        for f in self.forces:
            k = getattr(f, "stiffness", None)
            if k is not None and np.size(k):
                if float(np.max(k)) > k_max:
                    k_max, name = float(np.max(k)), type(f).__name__
        if name is None:
            return ""
        omega = np.sqrt(k_max / m_min)
        return (f"the stiffest force is {name} with stiffness {k_max:g} N/m on mass {m_min:g} kg "
                f"(omega = {omega:.3g} rad/s; explicit methods need dt below about {2.0 / omega:.3g} s, "
                f"dt is {dt:g} s)")

    def __repr__(self):
        return (f"ParticleSystem(particle_count={self.particle_count}, dim={self.dim}, "
                f"forces={[type(f).__name__ for f in self.forces]})")
