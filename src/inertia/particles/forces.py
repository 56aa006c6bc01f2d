"""Force objects for particle systems (Witkin & Baraff, "Particle System Dynamics").

References
----------
- Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes:
  force objects, damped springs with damping along the spring direction.
- Baraff, D. & Witkin, A. (1998), "Large steps in cloth simulation": force Jacobians.
- Choi, K.-J. & Ko, H.-S. (2002), "Stable but responsive cloth": dropping the transverse
  stiffness of compressed springs keeps the implicit system definite.
- Plummer, H. C. (1911): the softened point potential used by `Attractor`.

A force object is added with ``system.add_force(force)``, which calls ``force.bind(system)``
(checks indices and shapes against the system, computes defaults such as rest lengths). Then,
at every derivative evaluation, ``force.accumulate(x, v, t, f)`` adds its share into the
accumulator ``f`` ((N, D) float64, cleared before the first force). A force can be bound to one
system only.

Writing your own force
----------------------
Subclass `Force` and implement ``accumulate``; plain NumPy is fine::

    class Buoyancy(ia.forces.Force):
        def __init__(self, level, strength):
            self.level, self.strength = level, strength
        def accumulate(self, x, v, t, f):
            depth = np.clip(self.level - x[:, 2], 0.0, None)
            f[:, 2] += self.strength * depth

For speed, call a Numba kernel from ``accumulate`` (see `inertia.particles.kernels` for the
pattern: ``@njit(cache=True, parallel=True)`` over particles, adding into ``f``). Forces that
have a potential set ``conservative = True`` and implement ``potential_energy(x)``. Forces that
can give Jacobians for ``implicit_euler`` set ``provides_jacobian = True`` and implement
``jacobian_pairs``, ``bind_jacobian(pattern)`` and ``add_jacobians(x, v, t, dfdx, dfdv)``.

Limitations: `Springs` neglects the position derivative of its damping term in the Jacobian;
`ForceField` and `Wind` with a field callable give no Jacobian (they are explicit in
``implicit_euler``).
"""

from __future__ import annotations

import numpy as np

from .. import _validate as V
from . import kernels as K

__all__ = ["Force", "Gravity", "Drag", "QuadraticDrag", "Springs", "AnchorSprings", "ForceField",
           "GridForceField", "Wind", "Attractor"]


class Force:
    """Base class of force objects (see the module docstring for the protocol)."""

    conservative = False
    provides_jacobian = False
    system = None

    def bind(self, system) -> None:
        """Attach to `system`; called once by ``system.add_force``."""
        if self.system is not None and self.system is not system:
            raise ValueError(f"this {type(self).__name__} is already added to another system; "
                             f"create a new force object for each system")
        self.system = system

    def accumulate(self, x, v, t, f) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def potential_energy(self, x) -> float:
        return 0.0

    def affine_terms(self):
        """(acceleration g (D,), constant force F (D,), linear damping k) if this force has the
        per-particle form f = m g + F - k v; None otherwise. Enables the fused fast path."""
        return None

    # Jacobian protocol (implicit integration)
    def jacobian_pairs(self) -> np.ndarray:
        return np.zeros((0, 2), dtype=np.int64)

    def bind_jacobian(self, pattern) -> None:
        self.diag_slot = pattern.diag_slot

    def add_jacobians(self, x, v, t, dfdx, dfdv) -> None:
        pass

    def __repr__(self):
        fields = ", ".join(f"{k}={v!r}" for k, v in self.__dict__.items()
                           if not k.startswith("_") and k != "system" and np.ndim(v) == 0)
        return f"{type(self).__name__}({fields})"


class Gravity(Force):
    """Uniform gravity, f = m g. `acceleration`: (D,) in m/s^2, e.g. (0, 0, -9.81)."""

    conservative = True

    def __init__(self, acceleration=(0.0, 0.0, -9.81)):
        self.acceleration = V.as_vector(acceleration, "Gravity acceleration")

    def bind(self, system):
        super().bind(system)
        if self.acceleration.shape[0] != system.dim:
            raise ValueError(f"Gravity acceleration has {self.acceleration.shape[0]} components but "
                             f"the system is {system.dim}-D")

    def accumulate(self, x, v, t, f):
        K.add_gravity(self.system.mass, self.system.inv_mass, self.acceleration, f)

    def potential_energy(self, x):
        # U = -sum_i m_i g . x_i over free particles
        s = self.system
        free = s.inv_mass > 0
        return float(-np.sum(s.mass[free] * (x[free] @ self.acceleration)))

    def affine_terms(self):
        d = self.acceleration.shape[0]
        return self.acceleration, np.zeros(d), 0.0


class Drag(Force):
    """Linear (viscous) drag, f = -k v. `coefficient` k >= 0 in kg/s (0.01..1 for light particles)."""

    provides_jacobian = True

    def __init__(self, coefficient=0.1):
        self.coefficient = V.positive_scalar(coefficient, "Drag coefficient", allow_zero=True)

    def accumulate(self, x, v, t, f):
        K.add_linear_drag(v, self.coefficient, f)

    def affine_terms(self):
        d = self.system.dim
        return np.zeros(d), np.zeros(d), self.coefficient

    def add_jacobians(self, x, v, t, dfdx, dfdv):
        K.add_diagonal_jacobian(self.diag_slot, -self.coefficient, dfdv)


class QuadraticDrag(Force):
    """Quadratic (aerodynamic) drag, f = -c |v| v; c = rho C_d A / 2 in kg/m."""

    provides_jacobian = True

    def __init__(self, coefficient=0.01):
        self.coefficient = V.positive_scalar(coefficient, "QuadraticDrag coefficient", allow_zero=True)

    def accumulate(self, x, v, t, f):
        K.add_quadratic_drag(v, self.coefficient, f)

    def add_jacobians(self, x, v, t, dfdx, dfdv):
        K.add_quadratic_drag_jacobian(v, self.diag_slot, self.coefficient, dfdv)


class Springs(Force):
    """Damped springs between index pairs (Hooke's law with damping along the spring).

    f_i = -[k (l - L) + c (v_i - v_j) . n] n, f_j = -f_i, with n = (x_i - x_j) / l.

    Parameters
    ----------
    pairs : (M, 2) int array of particle indices.
    stiffness : k in N/m, scalar or (M,). Explicit methods need dt < ~2 sqrt(m / k).
    damping : c in kg/s, scalar or (M,), >= 0.
    rest_lengths : L in m, scalar or (M,); default: the distances at the moment the force is added.
    """

    conservative = True
    provides_jacobian = True

    def __init__(self, pairs, stiffness=100.0, damping=0.0, rest_lengths=None):
        self._pairs_in = pairs
        self._stiffness_in, self._damping_in, self._rest_in = stiffness, damping, rest_lengths

    def bind(self, system):
        super().bind(system)
        n = system.particle_count
        self.pairs = V.index_array(self._pairs_in, "Springs pairs", n, columns=2)
        m = self.pairs.shape[0]
        same = np.flatnonzero(self.pairs[:, 0] == self.pairs[:, 1])
        if same.size:
            raise ValueError(f"Springs pairs must join two different particles; rows {same[:10].tolist()} "
                             f"join a particle to itself")
        self.stiffness = V.per_item(self._stiffness_in, "Springs stiffness", m, nonnegative=True)
        self.damping = V.per_item(self._damping_in, "Springs damping", m, nonnegative=True)
        if self._rest_in is None:
            self.rest_lengths = np.linalg.norm(system.x[self.pairs[:, 0]] - system.x[self.pairs[:, 1]], axis=1)
        else:
            self.rest_lengths = V.per_item(self._rest_in, "Springs rest_lengths", m, nonnegative=True)
        # CSR incidence: for every particle, the springs that touch it and their other ends
        ends = np.concatenate([self.pairs[:, 0], self.pairs[:, 1]])
        other = np.concatenate([self.pairs[:, 1], self.pairs[:, 0]])
        spring = np.concatenate([np.arange(m), np.arange(m)])
        order = np.argsort(ends, kind="stable")
        self.incident_other = np.ascontiguousarray(other[order])
        self.incident_spring = np.ascontiguousarray(spring[order])
        self.incident_start = np.zeros(n + 1, dtype=np.int64)
        np.add.at(self.incident_start, ends + 1, 1)
        self.incident_start = np.cumsum(self.incident_start)
        self._incident_end = np.ascontiguousarray(ends[order])

    @property
    def spring_count(self) -> int:
        return int(self.pairs.shape[0])

    def accumulate(self, x, v, t, f):
        K.add_springs_gathered(x, v, self.incident_start, self.incident_other, self.incident_spring,
                               self.stiffness, self.damping, self.rest_lengths, f)

    def potential_energy(self, x):
        return float(K.springs_energy(x, self.pairs, self.stiffness, self.rest_lengths))

    def jacobian_pairs(self):
        return self.pairs

    def bind_jacobian(self, pattern):
        super().bind_jacobian(pattern)
        self.incident_slot = pattern.slot_of(self._incident_end, self.incident_other)
        d = self.system.dim
        self._block_x = np.zeros((self.spring_count, d, d))
        self._block_v = np.zeros((self.spring_count, d, d))

    def add_jacobians(self, x, v, t, dfdx, dfdv):
        # one 3x3 block pair per spring, then gathered row by row (parallel and deterministic)
        K.spring_jacobian_blocks(x, v, self.pairs, self.stiffness, self.damping, self.rest_lengths,
                                 self._block_x, self._block_v)
        K.gather_spring_jacobian(self.incident_start, self.incident_spring, self.incident_slot,
                                 self.diag_slot, self._block_x, self._block_v, dfdx, dfdv)


class AnchorSprings(Force):
    """Damped springs from particles to fixed points in space.

    Parameters: indices (M,), anchors (M, D) in m, stiffness (N/m), damping (kg/s) and
    rest_length (m, default 0: a zero-length spring, f = -k (x - a)), each scalar or (M,).
    """

    conservative = True
    provides_jacobian = True

    def __init__(self, indices, anchors, stiffness=100.0, damping=0.0, rest_length=0.0):
        self._in = (indices, anchors, stiffness, damping, rest_length)

    def bind(self, system):
        super().bind(system)
        indices, anchors, stiffness, damping, rest = self._in
        self.indices = V.index_array(np.atleast_1d(indices), "AnchorSprings indices", system.particle_count)
        m = self.indices.shape[0]
        self.anchors = V.as_points(np.reshape(anchors, (-1, system.dim)) if np.size(anchors) == m * system.dim
                                   else anchors, "AnchorSprings anchors", dim=system.dim, count=m)
        self.stiffness = V.per_item(stiffness, "AnchorSprings stiffness", m, nonnegative=True)
        self.damping = V.per_item(damping, "AnchorSprings damping", m, nonnegative=True)
        self.rest_length = V.per_item(rest, "AnchorSprings rest_length", m, nonnegative=True)

    def accumulate(self, x, v, t, f):
        K.add_anchor_springs(x, v, self.indices, self.anchors, self.stiffness, self.damping,
                             self.rest_length, f)

    def potential_energy(self, x):
        return float(K.anchor_energy(x, self.indices, self.anchors, self.stiffness, self.rest_length))

    def add_jacobians(self, x, v, t, dfdx, dfdv):
        K.add_anchor_jacobian(x, v, self.indices, self.anchors, self.diag_slot, self.stiffness,
                              self.damping, self.rest_length, dfdx, dfdv)


class ForceField(Force):
    """A user force field: ``fn(x, v, t) -> (N, D)`` forces in newtons, vectorised over particles.

    With ``per_mass=True`` the callable returns accelerations and the force is m times it.
    Anything with that call signature works, e.g. ``lambda x, v, t: -x`` (a central spring).
    """

    def __init__(self, fn, *, per_mass=False):
        if not callable(fn):
            raise ValueError(f"ForceField fn must be callable as fn(x, v, t) -> (N, D); got {type(fn).__name__}")
        self.fn, self.per_mass = fn, bool(per_mass)

    def accumulate(self, x, v, t, f):
        value = np.asarray(self.fn(x, v, t), dtype=np.float64)
        if value.shape != f.shape:
            raise ValueError(f"ForceField fn returned shape {value.shape}; expected {f.shape} "
                             f"(one force per particle)")
        s = self.system
        if self.per_mass:
            value = value * np.where(s.inv_mass > 0, s.mass, 0.0)[:, None]
        f += value


class GridForceField(Force):
    """A force (or acceleration) sampled on a regular 2D/3D grid, interpolated (bi/tri)linearly.

    Parameters: values (n0, n1, 2) or (n0, n1, n2, 3); origin: the world position of node
    (0, 0[, 0]); spacing: cell size (scalar or per axis); ``per_mass=True`` when the values are
    accelerations. Outside the grid the border value is used (clamped).
    """

    def __init__(self, values, origin, spacing, *, per_mass=False):
        values = np.ascontiguousarray(values, dtype=np.float64)
        if values.ndim not in (3, 4) or values.shape[-1] != values.ndim - 1:
            raise ValueError(f"GridForceField values must have shape (n0, n1, 2) or (n0, n1, n2, 3); "
                             f"got {values.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError("GridForceField values must be finite")
        dim = values.shape[-1]
        self.values = values
        self.origin = V.as_vector(origin, "GridForceField origin", dim)
        spacing = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (dim,)).copy()
        if np.any(~np.isfinite(spacing)) or np.any(spacing <= 0):
            raise ValueError(f"GridForceField spacing must be > 0; got {spacing.tolist()}")
        self.spacing, self.per_mass = spacing, bool(per_mass)

    def bind(self, system):
        super().bind(system)
        if system.dim != self.values.shape[-1]:
            raise ValueError(f"GridForceField is {self.values.shape[-1]}-D but the system is {system.dim}-D")

    def accumulate(self, x, v, t, f):
        s = self.system
        kernel = K.grid_sample_add_2d if s.dim == 2 else K.grid_sample_add_3d
        kernel(x, self.values, self.origin, self.spacing, 1.0, s.mass, s.inv_mass, self.per_mass, f)


class Wind(Force):
    """Wind: f = k (w(x, t) - v), a drag toward the air velocity w.

    Parameters
    ----------
    velocity : (D,) air velocity in m/s, or a field callable ``field(points, t) -> (N, D)``
        (e.g. `inertia.fields.CurlNoise`).
    coefficient : k in kg/s (0.1 default).
    gust_amplitude : amplitude of gusts in m/s (0 = steady), added along the mean direction
        as a sum of three sinusoids with seeded phases (smooth and deterministic).
    gust_frequency : base gust frequency in Hz (0.5 default; 0.1..2 looks natural).
    seed : seed of the gust phases.
    """

    def __init__(self, velocity=(1.0, 0.0, 0.0), coefficient=0.1, *, gust_amplitude=0.0,
                 gust_frequency=0.5, seed=0):
        self.field = velocity if callable(velocity) else None
        self.velocity = None if self.field is not None else V.as_vector(velocity, "Wind velocity")
        self.coefficient = V.positive_scalar(coefficient, "Wind coefficient", allow_zero=True)
        self.gust_amplitude = V.positive_scalar(gust_amplitude, "Wind gust_amplitude", allow_zero=True)
        self.gust_frequency = V.positive_scalar(gust_frequency, "Wind gust_frequency")
        rng = np.random.default_rng(seed)
        self._phases = rng.uniform(0.0, 2 * np.pi, 3)
        self._ratios = np.array([1.0, 2.17, 3.71])
        self._wind = None

    def bind(self, system):
        super().bind(system)
        if self.velocity is not None and self.velocity.shape[0] != system.dim:
            raise ValueError(f"Wind velocity has {self.velocity.shape[0]} components; the system is {system.dim}-D")
        self._wind = np.zeros(system.dim)
        if self.field is not None:
            self._samples = np.zeros((system.particle_count, system.dim))

    def gust(self, t: float) -> float:
        """Gust factor g(t) in [-1, 1]: the wind speed is scaled by 1 + amplitude * g / |w|."""
        w = 2 * np.pi * self.gust_frequency * self._ratios * t + self._phases
        return float(np.sum(np.sin(w) / self._ratios) / np.sum(1.0 / self._ratios))

    def wind_at(self, t: float) -> np.ndarray:
        """The uniform wind velocity at time t (constant-velocity wind only)."""
        speed = np.linalg.norm(self.velocity)
        if self.gust_amplitude == 0.0 or speed == 0.0:
            return self.velocity
        return self.velocity * (1.0 + self.gust_amplitude * self.gust(t) / speed)

    def accumulate(self, x, v, t, f):
        if self.field is None:
            self._wind[:] = self.wind_at(t)
            K.add_wind(v, self._wind, self.coefficient, f)
            return
        if hasattr(self.field, "sample"):
            self.field.sample(x, t, self._samples)
        else:
            self._samples[:] = self.field(x, t)
        if self.gust_amplitude:
            self._samples *= 1.0 + self.gust_amplitude * self.gust(t)
        K.add_wind_field(v, self._samples, self.coefficient, f)


class Attractor(Force):
    """Softened point attractor (strength > 0) or repeller (strength < 0).

    f_i = s m_i (c - x_i) / (|c - x_i|^2 + eps^2)^(3/2), potential U = -s m_i / sqrt(r^2 + eps^2).
    `strength` s in m^3/s^2 (like G M); `softening` eps > 0 in m keeps the force finite at the centre.
    """

    conservative = True

    def __init__(self, center, strength=1.0, softening=0.1):
        self.center = V.as_vector(center, "Attractor center")
        try:
            self.strength = float(strength)
        except (TypeError, ValueError):
            raise ValueError(f"Attractor strength must be a number; got {strength!r}") from None
        if not np.isfinite(self.strength):
            raise ValueError(f"Attractor strength must be finite; got {strength!r}")
        self.softening = V.positive_scalar(softening, "Attractor softening")

    def bind(self, system):
        super().bind(system)
        if self.center.shape[0] != system.dim:
            raise ValueError(f"Attractor center has {self.center.shape[0]} components; the system is {system.dim}-D")

    def accumulate(self, x, v, t, f):
        s = self.system
        K.add_attractor(x, s.mass, s.inv_mass, self.center, self.strength, self.softening, f)

    def potential_energy(self, x):
        s = self.system
        return float(K.attractor_energy(x, s.mass, s.inv_mass, self.center, self.strength, self.softening))
