"""The shared contact buffer: one manifold per candidate pair, up to four points, impulses written back.

Filled in a fixed order (DESIGN.md "Contacts"): the broad phase gives candidate pairs sorted by
``(shape_a, shape_b)``; the narrow phase writes manifold ``i`` for pair ``i`` (count), a scan
compacts the manifolds that have points into ``active`` (scan), and the solver's prepare stage fills
the rows of those (fill). Pair order is canonical: ``shape_type[a] <= shape_type[b]`` (ties by index),
so the normal points from the lower-type shape A to B.

Arrays (M = capacity >= number of candidate pairs; only the first ``count`` rows are valid)
- ``contact_shape (M, 2) int32``, ``contact_body (M, 2) int32`` (-1 = static world): broad phase.
- ``contact_point_count (M,) int32`` (0..4): narrow phase.
- ``contact_normal (M, 3)``: unit normal from A to B, world frame: narrow phase.
- ``contact_point (M, 4, 3)`` m: world points midway between the two surfaces: narrow phase.
- ``contact_separation (M, 4)`` m: signed gap at detection (negative = penetration): narrow phase.
- ``contact_feature (M, 4) int64``: feature keys (which faces/edges/vertices made the point), used to
  match points to the previous step for warm starting: narrow phase.
- ``contact_friction``, ``contact_restitution``, ``contact_rolling_friction (M,)``: combined material
  (friction geometric mean, restitution max, rolling max): narrow phase.
- ``contact_is_sensor (M,) bool``: either shape is a sensor (no response): broad phase.
- ``contact_normal_impulse (M, 4)`` N s, ``contact_tangent_impulse (M, 4, 2)`` N s (along the two
  tangents of ``contact_tangent (M, 2, 3)``), ``contact_rolling_impulse (M, 3)`` N m s: accumulated
  impulses, warm-started from the previous step and written back by store_impulses.
- ``contact_max_normal_impulse (M, 4)`` N s: largest accumulated normal impulse of a substep
  (restitution applies only where it is > 0).
- ``contact_total_normal_impulse (M, 4)`` N s: normal impulse applied over the whole step (the sum of
  the substeps' impulses plus restitution) -- what events and coupling read.
- The accumulated impulses above are per substep (the soft step re-applies them each substep).
- ``contact_relative_velocity (M, 4)`` m/s: normal relative velocity before the step (restitution).
- ``contact_key (M,) int64``: ``shape_a * S + shape_b``, sorted ascending (warm-start merge).
- ``active (M,) int32``, ``active_count``: indices of manifolds with points (scan).

Particle rows (``World`` with particle groups; filled after the rigid rows, rows
``particle_start : particle_start + particle_count``, ``particle_start == count``): one row per
particle touching a shape-table row in the step, in group order, then particle order, then the order
the particle met its rows. Endpoint A is the shape, endpoint B the particle (three degrees of freedom,
no inertia): ``contact_shape[i] = (shape, -1)``, ``contact_body[i] = (body of the shape, -1)``,
``contact_particle (M, 2) int32 = (group index, particle index)`` (meaningful in the particle range
only), ``contact_point_count = 1``; ``contact_normal`` the shape's outward normal at the particle (from
A to B); ``contact_point[i, 0]`` midway between the particle's surface and the shape's;
``contact_separation[i, 0]`` the gap (distance to the shape minus the radius) at the end of the step;
``contact_normal_impulse[i, 0]`` = ``contact_total_normal_impulse[i, 0]`` and
``contact_tangent_impulse[i, 0]`` (along ``contact_tangent[i]``): the impulse the shape gave the
particle over the whole step (N s; the body received minus it); ``contact_is_sensor``: a sensor row
the particle overlaps (no response, zero impulse); ``contact_key = -1`` (particle rows are keyed by
(group, particle, shape) in events). See ``inertia.world`` for what makes a particle row.

References: Catto, E. (2024). Solver2D / Box2D v3 contact manifolds and feature ids; Gregorius, D.
(2015). Robust contact creation for physics simulations (GDC).
Limitations: four points per manifold; one manifold per shape pair; a particle row has one point
(a particle meets at most two shape rows per step in the buffer, see ``inertia.world``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Contacts", "ContactArrays", "ParticleRowArrays"]


class ContactArrays(NamedTuple):
    contact_shape: np.ndarray
    contact_body: np.ndarray
    contact_point_count: np.ndarray
    contact_normal: np.ndarray
    contact_point: np.ndarray
    contact_separation: np.ndarray
    contact_feature: np.ndarray
    contact_friction: np.ndarray
    contact_restitution: np.ndarray
    contact_rolling_friction: np.ndarray
    contact_is_sensor: np.ndarray
    contact_normal_impulse: np.ndarray
    contact_tangent_impulse: np.ndarray
    contact_tangent: np.ndarray
    contact_rolling_impulse: np.ndarray
    contact_max_normal_impulse: np.ndarray
    contact_total_normal_impulse: np.ndarray
    contact_relative_velocity: np.ndarray
    contact_key: np.ndarray
    active: np.ndarray


class ParticleRowArrays(NamedTuple):
    """Kernel bundle: the arrays a particle row writes (``Contacts.particle_arrays``)."""
    contact_shape: np.ndarray
    contact_body: np.ndarray
    contact_particle: np.ndarray
    contact_point_count: np.ndarray
    contact_is_sensor: np.ndarray
    contact_key: np.ndarray
    contact_normal: np.ndarray
    contact_point: np.ndarray
    contact_separation: np.ndarray
    contact_tangent: np.ndarray
    contact_normal_impulse: np.ndarray
    contact_total_normal_impulse: np.ndarray
    contact_max_normal_impulse: np.ndarray
    contact_tangent_impulse: np.ndarray
    contact_rolling_impulse: np.ndarray


_SPEC = {
    "contact_shape": ((2,), np.int32), "contact_body": ((2,), np.int32),
    "contact_point_count": ((), np.int32), "contact_normal": ((3,), np.float64),
    "contact_point": ((4, 3), np.float64), "contact_separation": ((4,), np.float64),
    "contact_feature": ((4,), np.int64), "contact_friction": ((), np.float64),
    "contact_restitution": ((), np.float64), "contact_rolling_friction": ((), np.float64),
    "contact_is_sensor": ((), np.bool_), "contact_normal_impulse": ((4,), np.float64),
    "contact_tangent_impulse": ((4, 2), np.float64), "contact_tangent": ((2, 3), np.float64),
    "contact_rolling_impulse": ((3,), np.float64), "contact_max_normal_impulse": ((4,), np.float64),
    "contact_total_normal_impulse": ((4,), np.float64),
    "contact_relative_velocity": ((4,), np.float64), "contact_key": ((), np.int64),
    "active": ((), np.int32), "contact_particle": ((2,), np.int32),
}


class Contacts:
    """Contact manifolds of one step (see the module docstring for every array).

    ``count`` manifolds are valid (one per candidate pair); ``active_count`` of them have points.
    Arrays are views owned by the buffer: copy them to keep them past the next step.
    """

    def __init__(self, capacity: int = 64):
        self.capacity = 0
        self.count = 0
        self.active_count = 0
        self.particle_start = 0
        self.particle_count = 0
        self.reserve(max(int(capacity), 1))

    def reserve(self, capacity: int) -> None:
        """Grow to hold ``capacity`` manifolds (done between steps, amortised doubling)."""
        if capacity <= self.capacity:
            return
        new = max(capacity, 2 * self.capacity)
        for name, (shape, dtype) in _SPEC.items():
            arr = np.zeros((new,) + shape, dtype=dtype)
            if self.capacity:
                arr[:self.capacity] = getattr(self, name)
            setattr(self, name, arr)
        self.capacity = new

    def arrays(self) -> ContactArrays:
        return ContactArrays(*(getattr(self, f) for f in ContactArrays._fields))

    def particle_arrays(self) -> ParticleRowArrays:
        return ParticleRowArrays(*(getattr(self, f) for f in ParticleRowArrays._fields))

    def copy(self) -> "Contacts":
        out = Contacts.__new__(Contacts)
        out.capacity, out.count, out.active_count = self.capacity, self.count, self.active_count
        out.particle_start, out.particle_count = self.particle_start, self.particle_count
        for name in _SPEC:
            setattr(out, name, getattr(self, name).copy())
        return out

    def assign(self, other: "Contacts") -> None:
        self.reserve(other.capacity)
        self.count, self.active_count = other.count, other.active_count
        self.particle_start = getattr(other, "particle_start", other.count)
        self.particle_count = getattr(other, "particle_count", 0)
        for name in _SPEC:
            getattr(self, name)[:other.capacity] = getattr(other, name)

    # ---- user-facing views
    def manifolds(self):
        """Indices of manifolds that have at least one point (a view; copy to keep)."""
        return self.active[:self.active_count]

    def particle_rows(self) -> np.ndarray:
        """Indices of the particle-shape rows of the last step (see the module docstring)."""
        return np.arange(self.particle_start, self.particle_start + self.particle_count)

    def total_normal_impulse(self) -> np.ndarray:
        """Per active manifold, the sum of its points' normal impulses (N s)."""
        a = self.manifolds()
        return self.contact_normal_impulse[a].sum(axis=1)
