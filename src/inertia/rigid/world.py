"""RigidWorld: the coupled step for rigid bodies (standalone until it merges with ``inertia.world``).

The step reads as the algorithm; each line is a timed stage in ``world.profile`` (seconds, summed):
```
broad_phase()      # shape world poses, swept AABBs, sort-and-sweep -> sorted candidate pairs
narrow_phase()     # manifolds -> Contacts (count, scan), warm-start match against the previous step
islands()          # wake sleeping islands that are touched, colour the constraints
collide()          # restitution > 0: bounce the points whose gap closes within the step, at their time of impact
for each substep:  # solve stage: integrate_velocities, warm_start, solve, integrate_positions, relax
    ...
restitution()      # inside the solve stage's timer
finalize()         # sleep, finite check, time
```

Parameters (after Box2D v3, stiffer; ranges are guidance). A soft contact of frequency f sags by
W / (m_eff (2 pi f)^2) under a load W, so a stack's contacts sag in proportion to the weight above
them; at Box2D's 30 Hz a 10-box stack of 0.2 m boxes sags ~27 mm and buckles, hence 60 Hz and 8
substeps here (measured: tests/rigid/test_world.py, the 10-box stack).
- ``dt`` 1/60 s; ``substeps`` 8 (one solver iteration each; 4 suffices for piles and low stacks: the
  1000-box pile rests 3.5 mm deep at most with ``substeps=4, contact_damping_ratio=5`` (5.5 mm at the
  default ratio 10) in about half the time per step, but a 10-box stack creeps ~16 mm in 60 s at 4
  substeps, so 8 stays the default; benchmarks/bench_rigid.py ``--substeps 4 --damping-ratio 5``).
- ``contact_hertz`` 60 Hz (capped at a quarter of the substep rate), ``contact_damping_ratio`` 10,
  ``push_max_velocity`` 3 m/s (the fastest overlapping bodies are pushed apart).
- ``restitution_threshold`` 1 m/s (slower impacts do not bounce).
- ``rolling_resistance`` 0.002: default rolling-resistance coefficient C_rr of round shapes (sphere,
  capsule, cylinder): a contact resists rolling with the torque C_rr r N (lever arm C_rr r, r the shape's
  radius; a material's ``rolling_friction`` lever arm wins when larger), so a ball rolling on a level
  plane decelerates at C_rr g / (1 + I / (m r^2)) (0.014 m/s^2 for a solid sphere) and comes to rest, where
  without it a pile of balls keeps rolling apart and never sleeps. 0.002 is a hard ball on a hard floor
  (steel on steel ~0.001, billiard ball on cloth ~0.01: Bullet's ``rollingFriction`` and Box2D v3.1's
  rolling resistance are the same model as a per-shape lever); on an incline it lowers the rolling
  acceleration by the fraction C_rr / tan(theta) (0.55 % at 20 degrees). 0 turns it off.
- ``twist_radius`` 0.005 m: twisting friction about the normal, friction * twist_radius * normal
  impulse (MuJoCo's default torsional friction, 0.005 m); 0 turns it off.
- ``restitution_iterations`` 8: passes of the collision pass before the substeps (Guendelman et al.
  2003): bodies with restitution whose gap closes within the step bounce at their time of impact (the
  rebound independent of the step), pass after pass, so a touching chain (Newton's cradle) hands an impact
  on; 0 leaves only Box2D's post-step restitution.
- Sleep: ``linear_sleep_tolerance`` 0.05 m/s, ``angular_sleep_tolerance`` 2 deg/s (raised per body to
  linear_sleep_tolerance / bounding radius: the farthest point's speed, as Box2D v3),
  ``time_to_sleep`` 0.5 s; ``enable_sleep`` True.
- ``match_distance`` 0.01 m: a contact point without a matching feature key takes the warm-start
  impulse of the previous point nearest to it within this distance.
- ``speculative`` True, ``time_of_impact`` True, ``toi_slop`` 0.001 m: continuous collision (below).
- ``parallel``: "auto" (serial: see below), True (parallel colour batches), or False (serial twins).
  Both paths compute identical bits. A parallel solve waits at a barrier after every colour (about 14
  colours x 3 passes x 8 substeps per step on the 1000-box pile); on 2 cores shared with other work each
  barrier waits for a time slice: measured 3.2 s per step parallel against 0.1 s serial at load 11, so
  "auto" runs serially until a machine with idle cores shows the parallel path paying.

Continuous collision, two layers:
- speculative contacts (``speculative`` True: a gap closed within the step is a contact with bias gap / h)
  stop fast bodies at thin walls (tests/rigid/test_world.py, 300 m/s through 1 cm);
- the ``toi`` stage (``time_of_impact`` True; Mirtich 1996 conservative advancement, Catto 2013): bodies
  flagged ``bullet`` (``add_body(bullet=True)``, scene key ``bullet = true``) are swept against the convex
  shapes of all their broad-phase candidate pairs, and every other dynamic body a point of which moved
  farther than its smallest half extent in the step against static and kinematic ones (Box2D v3's
  split), from the start-of-step pose to the solved one
  (``inertia.geometry.toi.time_of_impact_batch``); a body whose first impact comes at a fraction
  ``0 < toi < 1`` goes back to its pose at ``toi`` (``toi_slop`` = 1 mm short of touching, which must be
  below the shapes' margins) and keeps its velocity: the next step's contact stops it at the surface.
  This catches what speculative margins miss (two movers closing on each other, fast spin). Pairs
  already touching at the start of the step, planes, meshes and heightfields are left to the contacts.

Solve stage: on the serial path the substep loop is one compiled call (``solver.substeps_serial``);
on the parallel path each stage kernel is a call (colour batches in parallel).

Memory: every work array of the step is made at build (``_allocate``: shape poses and boxes, the
sweep's merge-sort scratch, the narrow phase's scratch banks ``NarrowWork``, constraint and colour
arrays, the finite check's output); the pair buffers and the constraint arrays are replaced by ones of
twice the needed size when a step's pair or constraint count exceeds them, and the contact buffers
double likewise (``Contacts.reserve``), as do the mesh bank's candidate slots (``fit_narrow_work``), so
growth is amortised O(log n) over a run. A warm step's kernels allocate nothing, the mesh, heightfield
and SDF narrow phases included (tests/rigid/test_step_allocations.py and
test_step_allocations_mesh_sdf.py count Numba's NRT allocations and tracemalloc's peak).

Baked signed-distance colliders (``SDF`` rows with a grid, ``inertia.geometry.sdf_collide``) collide with
the dynamic bodies' convex shapes through surface samples; unbaked ones cannot (a warning at build names
them).

Limitations: no joints yet; no particles in the same step (the lead merges this world with
``inertia.world.World``); bodies whose shapes the narrow phase does not pair (see
``inertia.geometry.narrowphase``) pass through each other.
"""

from __future__ import annotations

import math
import time
import warnings
from contextlib import contextmanager

import numpy as np

from ..dynamics import islands as isl
from ..dynamics import solver as sv
from ..dynamics.contacts import Contacts
from ..errors import SimulationDiverged
from ..geometry import shapes as S
from ..geometry.broadphase import shape_world_bounds, sort_and_sweep_into
from ..geometry.narrowphase import (closed_token, compact_active, fit_narrow_work, match_warm_start,
                                    narrow_phase_closed, narrow_phase_general, narrow_phase_mesh, new_narrow_work,
                                    scene_families, scene_mesh_rows)
from ..geometry.sdf_collide import narrow_phase_sdf, sdf_arrays
from ..geometry.toi import time_of_impact_batch
from ..model import Control, Model, State

__all__ = ["RigidWorld"]

STAGES = ("broad_phase", "narrow_phase", "islands", "solve", "toi", "finalize")


class _Kernels:
    def __init__(self, parallel: bool):
        self.shape_world_bounds = shape_world_bounds
        self.narrow_phase_closed = narrow_phase_closed
        self.narrow_phase_general = narrow_phase_general
        self.narrow_phase_mesh = narrow_phase_mesh
        self.narrow_phase_sdf = narrow_phase_sdf
        self.time_of_impact_batch = time_of_impact_batch
        if parallel:
            self.integrate_velocities = sv.integrate_velocities
            self.integrate_positions = sv.integrate_positions
            self.world_inverse_inertia = sv.world_inverse_inertia
            self.prepare_contacts = sv.prepare_contacts
            self.warm_start = sv.warm_start
            self.solve_contacts = sv.solve_contacts
            self.restitution = sv.restitution
        else:
            from .._jit import serial_twin
            for name, fn in sv.serial_versions().items():
                setattr(self, name, fn)
            self.shape_world_bounds = serial_twin(shape_world_bounds)
            self.narrow_phase_closed = serial_twin(narrow_phase_closed)
            self.narrow_phase_general = serial_twin(narrow_phase_general)
            self.narrow_phase_mesh = serial_twin(narrow_phase_mesh)
            self.narrow_phase_sdf = serial_twin(narrow_phase_sdf)
            self.time_of_impact_batch = serial_twin(time_of_impact_batch)


_KERNELS: dict[bool, _Kernels] = {}


class RigidWorld:
    """Steps a rigid-body `Model` (see the module docstring for the stages and parameters).

    >>> world = RigidWorld(model, dt=1/60)
    >>> for _ in range(60):
    ...     world.step()
    >>> world.state.body_q        # (B, 7) view: copy it to keep it past the next step
    """

    def __init__(self, model: Model, *, dt: float = 1.0 / 60.0, substeps: int = 8, contact_hertz=60.0,
                 contact_damping_ratio=10.0, push_max_velocity=3.0, restitution_threshold=1.0,
                 enable_sleep=True, linear_sleep_tolerance=0.05, angular_sleep_tolerance=math.radians(2.0),
                 time_to_sleep=0.5, max_speed=1e4, match_distance=0.01, restitution_iterations=8, twist_radius=0.005,
                 rolling_resistance=0.002, speculative=True, time_of_impact=True, toi_slop=0.001, parallel="auto",
                 state: State | None = None):
        from .._validate import positive_scalar as _positive
        from ..model import _nonneg
        self.model = model
        self.dt = _positive(dt, "dt")
        if not isinstance(substeps, (int, np.integer)) or substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1; got {substeps!r}")
        self.substeps = int(substeps)
        self.contact_hertz = _positive(contact_hertz, "contact_hertz")
        self.contact_damping_ratio = _nonneg(contact_damping_ratio, "contact_damping_ratio")
        self.push_max_velocity = _positive(push_max_velocity, "push_max_velocity")
        self.restitution_threshold = _nonneg(restitution_threshold, "restitution_threshold")
        self.enable_sleep = bool(enable_sleep)
        self.linear_sleep_tolerance = _nonneg(linear_sleep_tolerance, "linear_sleep_tolerance")
        self.angular_sleep_tolerance = _nonneg(angular_sleep_tolerance, "angular_sleep_tolerance")
        self.time_to_sleep = _positive(time_to_sleep, "time_to_sleep")
        self.max_speed = _positive(max_speed, "max_speed")
        self.match_distance = _nonneg(match_distance, "match_distance")
        if not isinstance(restitution_iterations, (int, np.integer)) or restitution_iterations < 0:
            raise ValueError(f"restitution_iterations must be an integer >= 0; got {restitution_iterations!r}")
        self.restitution_iterations = int(restitution_iterations)
        self.twist_radius = _nonneg(twist_radius, "twist_radius")
        self.rolling_resistance = _nonneg(rolling_resistance, "rolling_resistance")
        for name, flag in (("speculative", speculative), ("time_of_impact", time_of_impact)):
            if not isinstance(flag, (bool, np.bool_)):
                raise ValueError(f"{name} must be True or False; got {flag!r}")
        self.speculative = bool(speculative)
        self.time_of_impact = bool(time_of_impact)
        self.toi_slop = _nonneg(toi_slop, "toi_slop")
        if parallel not in ("auto", True, False):
            raise ValueError(f"parallel must be 'auto', True or False; got {parallel!r}")
        use_parallel = False if parallel == "auto" else bool(parallel)
        if use_parallel not in _KERNELS:
            _KERNELS[use_parallel] = _Kernels(use_parallel)
        self._k = _KERNELS[use_parallel]
        self.parallel = use_parallel

        self.state = state if state is not None else model.state()
        self.control = model.control()
        self.contacts = Contacts(max(64, 4 * model.shape_count))
        self._prev_contacts = Contacts(self.contacts.capacity)
        self.profile = {s: 0.0 for s in STAGES}
        self.initial_overlaps: list[tuple[str, str, float]] = []
        # objects with their own state stepped with this world (vehicles): save() / restore() carry it
        self.checkpoint_parts: list = []
        self._allocate()

    # ------------------------------------------------------------------ scratch
    def _allocate(self):
        m = self.model
        nb, ns = m.body_count, m.shape_count
        self._shapes = m.shapes()
        self._families = scene_families(m.shape_type)      # (general convex, mesh, SDF pairs) possible
        self._closed = closed_token(m.shape_type)          # the closed-form pair kinds compiled in
        self._sdf = sdf_arrays(m)
        self._warn_unbaked_sdf()
        self._shape_pose = np.zeros((ns, 7))
        self._aabb = np.zeros((ns, 6))
        self._order = np.zeros(ns, np.int64)
        # clipping, GJK/EPA and mesh/SDF scratch banks
        rows = scene_mesh_rows(m.shape_type, m.shape_vert_count) if self._families[1] or self._families[2] else 0
        self._narrow_work = new_narrow_work(self._families[0], rows)
        self._grow_pairs(max(64, 4 * ns))
        self._body_dp = np.zeros((nb, 3))
        self._body_dtheta = np.zeros((nb, 3))
        self._body_impact_time = np.zeros(nb)          # the collision pass's scratch
        self._solver_inv_mass = np.zeros(nb)
        self._inv_inertia_world = np.zeros((nb, 9))
        self._body_mask = np.zeros(nb, np.uint64)
        self._parent = np.zeros(nb, np.int64)
        self._island_min = np.zeros(nb)
        self._colour_start = np.zeros(sv.MAX_COLOURS + 2, np.int64)
        self._grow_constraints(self.contacts.capacity)
        # time of impact (bullets): end-of-step shape poses, start-of-step body poses, per-body flags
        self._pose1 = np.zeros((ns, 7))
        self._aabb1 = np.zeros((ns, 6))
        self._body_q0 = np.zeros((nb, 7))
        self._body_fast = np.zeros(nb, np.bool_)
        self._bad = np.zeros(nb, np.int64)              # the finite check's output (_first_bad_bodies)
        self._body_toi = np.ones(nb)
        bullet = getattr(m, "body_bullet", None)
        self._bullet = np.zeros(nb, np.bool_)
        if bullet is not None:
            self._bullet[:len(bullet)] = bullet
        self._min_half_extent = _body_min_half_extent(m)

    def _warn_unbaked_sdf(self):
        """Once, at build: the SDF rows without a distance grid (unbaked ``SDF`` colliders), which the
        dynamic bodies cannot collide with."""
        m = self.model
        rows = np.flatnonzero((m.shape_type == S.SDF) & (self._sdf.shape_sdf_start[:, 0] < 0))
        if rows.size == 0 or not np.any(m.body_type == S.DYNAMIC):
            return
        source = getattr(m, "shape_source", np.full(m.shape_count, -1))
        names = ", ".join(f"colliders[{int(source[s])}] (shape row {int(s)})" if source[s] >= 0
                          else f"shape row {int(s)}" for s in rows[:10])
        warnings.warn(f"rigid bodies do not collide with the unbaked SDF collider(s) {names}: pass "
                      "bake={'bounds': (lo, hi), 'resolution': n} to inertia.colliders.SDF so they collide "
                      "with its distance grid", stacklevel=4)

    def _grow_pairs(self, cap):
        """Pair buffers of ``cap`` rows: made once, then doubled past the pair count whenever a step's
        sort-and-sweep finds more (amortised: O(log P) growths over a run)."""
        self._pairs = np.zeros((cap, 2), np.int32)
        self._keys = np.zeros(cap, np.int64)
        # sort-and-sweep's merge-sort scratch
        self._sweep_perm = np.zeros(max(cap, self.model.shape_count), np.int64)
        self._sweep_tmp = np.zeros(max(cap, self.model.shape_count), np.int64)
        self._toi_pairs = np.zeros((cap, 2), np.int32)
        self._toi = np.zeros(cap)
        self._toi_normal = np.zeros((cap, 3))
        self._toi_point = np.zeros((cap, 3))

    def _grow_constraints(self, cap):
        self._cons_cap = cap
        self._cons_manifold = np.zeros(cap, np.int32)
        self._cons_anchor = np.zeros((cap, 4, 2, 3))
        self._cons_base_sep = np.zeros((cap, 4))
        self._cons_normal_mass = np.zeros((cap, 4))
        self._cons_tangent_mass = np.zeros((cap, 4, 2))
        self._cons_rolling_mass = np.zeros((cap, 9))
        self._cons_soft = np.zeros((cap, 3))
        self._cons_twist = np.zeros((cap, 3))
        self._colour_of = np.zeros(cap, np.int64)
        self._colour_items = np.zeros(cap, np.int64)

    @contextmanager
    def _timed(self, stage):
        t0 = time.perf_counter()
        yield
        self.profile[stage] += time.perf_counter() - t0

    # ------------------------------------------------------------------ the step
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``."""
        for _ in range(n):
            with self._timed("broad_phase"):
                npairs = self._broad_phase()
            with self._timed("narrow_phase"):
                self._narrow_phase(npairs)
            with self._timed("islands"):
                n_cons = self._islands()
            with self._timed("solve"):
                self._solve(n_cons)
            with self._timed("toi"):
                self._time_of_impact(npairs)
            with self._timed("finalize"):
                self._finalize()

    def _broad_phase(self) -> int:
        m, st = self.model, self.state
        self._k.shape_world_bounds(self._shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd,
                                   self.dt, self._shape_pose, self._aabb)
        while True:
            n = sort_and_sweep_into(self._aabb, self._shapes, m.body_type, st.body_awake, self._order,
                                    self._keys, self._pairs, self._sweep_perm, self._sweep_tmp)
            if n <= len(self._pairs):
                return n
            self._grow_pairs(2 * n)

    def _narrow_phase(self, npairs: int) -> None:
        m, st = self.model, self.state
        # double buffer: last step's contacts become the warm-start source
        self._prev_contacts, self.contacts = self.contacts, self._prev_contacts
        c = self.contacts
        c.reserve(npairs)
        ca = c.arrays()
        # speculative=False: only the shapes' margins (dt = 0 closes nothing), as a test of the TOI sweep
        dt = self.dt if self.speculative else 0.0
        self._k.narrow_phase_closed(self._pairs, self._keys, npairs, self._shapes, self._shape_pose, st.body_qd,
                                    m.body_bound_radius, dt, ca, self._narrow_work.scratch, self._closed)
        # the other families' kernels only when the scene's shape types can pair that way: a box-and-sphere
        # scene never compiles GJK/EPA or the triangle routines
        if self._families[0]:
            self._k.narrow_phase_general(self._pairs, npairs, self._shapes, self._shape_pose, st.body_qd,
                                         m.body_bound_radius, dt, ca, self._narrow_work.scratch,
                                         self._narrow_work.gjk)
        if self._families[1]:
            self._k.narrow_phase_mesh(self._pairs, npairs, self._shapes, self._shape_pose, st.body_qd,
                                      m.body_bound_radius, dt, ca, self._narrow_work.mesh)
            self._narrow_work = fit_narrow_work(self._narrow_work)   # candidate slots doubled past an overflow
        if self._families[2]:
            self._k.narrow_phase_sdf(self._pairs, npairs, self._shapes, self._sdf, self._shape_pose, st.body_qd,
                                     m.body_bound_radius, dt, ca, self._narrow_work.mesh)
        c.count = npairs
        c.active_count = compact_active(ca, npairs)
        if self.rolling_resistance > 0.0:
            _default_rolling_resistance(c.active, c.active_count, c.contact_shape, self._shapes.shape_type,
                                        self._shapes.shape_params, self.rolling_resistance,
                                        c.contact_rolling_friction)
        p = self._prev_contacts
        match_warm_start(p.arrays(), p.count, ca, npairs, self.match_distance)
        if st.step_index[0] == 0:
            self._report_initial_overlaps()

    def _report_initial_overlaps(self):
        c = self.contacts
        act = c.manifolds()
        if len(act) == 0:
            return
        depth = np.min(np.where(np.arange(4)[None, :] < c.contact_point_count[act, None],
                                c.contact_separation[act], np.inf), axis=1)
        deep = act[(depth < -0.005) & ~c.contact_is_sensor[act]]
        if len(deep):
            names = self.model.body_name
            def nm(b):
                return "world" if b < 0 else names[b]
            self.initial_overlaps = [(nm(c.contact_body[i, 0]), nm(c.contact_body[i, 1]),
                                      float(-c.contact_separation[i, :c.contact_point_count[i]].min()))
                                     for i in deep]
            listed = ", ".join(f"{a}/{b} ({d * 1000:.1f} mm)" for a, b, d in self.initial_overlaps[:10])
            warnings.warn(f"{len(deep)} shape pairs start overlapping: {listed}; they are pushed apart at "
                          f"up to push_max_velocity = {self.push_max_velocity} m/s", stacklevel=3)

    def _islands(self) -> int:
        m, st, c = self.model, self.state, self.contacts
        ca = c
        if self.enable_sleep:
            isl.wake_touched(c.active, c.active_count, c.contact_body, c.contact_is_sensor, m.body_type,
                             st.body_awake, st.body_qd, st.body_sleep_time, st.body_sleep_island)
        # constraints: active, non-sensor manifolds with at least one awake dynamic body
        act = c.active[:c.active_count]
        if c.active_count > self._cons_cap:
            self._grow_constraints(2 * c.active_count)
        self._k.world_inverse_inertia(m.body_type, st.body_awake, m.body_inv_mass, m.body_inv_inertia,
                                      st.body_q, self._solver_inv_mass, self._inv_inertia_world)
        n_cons = _select_constraints(act, ca.contact_body, ca.contact_is_sensor, self._solver_inv_mass,
                                     self._cons_manifold)
        sv.colour_constraints(self._cons_manifold, n_cons, ca.contact_body, self._solver_inv_mass,
                              self._body_mask, self._colour_of, self._colour_start, self._colour_items)
        return n_cons

    def _solve(self, n_cons: int) -> None:
        m, st, c, k = self.model, self.state, self.contacts, self._k
        h = self.dt / self.substeps
        hertz = min(self.contact_hertz, 0.25 / h)
        soft = sv.soft_coefficients(hertz, self.contact_damping_ratio, h)
        static_soft = sv.soft_coefficients(2.0 * hertz, self.contact_damping_ratio, h)
        self._body_dp[:] = 0.0
        self._body_dtheta[:] = 0.0
        self._body_q0[:] = st.body_q
        ctx = sv.SolverContext(
            st.body_q, st.body_qd, self._body_dp, self._body_dtheta, self._solver_inv_mass, self._inv_inertia_world,
            c.contact_body, c.contact_point_count, c.contact_normal, c.contact_tangent, c.contact_friction,
            c.contact_restitution, c.contact_rolling_friction, c.contact_normal_impulse,
            c.contact_tangent_impulse, c.contact_rolling_impulse, c.contact_max_normal_impulse,
            c.contact_total_normal_impulse, c.contact_relative_velocity, self._cons_manifold, self._cons_anchor,
            self._cons_base_sep, self._cons_normal_mass, self._cons_tangent_mass, self._cons_rolling_mass,
            self._cons_soft, self._cons_twist)
        k.prepare_contacts(ctx, st.body_q, n_cons, c.contact_point, c.contact_separation, h, soft, static_soft,
                           self.twist_radius)
        ctl = self.control
        if self.restitution_iterations:
            sv.collide(ctx, n_cons, self.dt, h, self.restitution_threshold, self.restitution_iterations, m.gravity,
                       ctl.body_force, self._body_impact_time)
        cs, ci = self._colour_start, self._colour_items
        if not self.parallel:
            sv.substeps_serial(ctx, cs, ci, self.substeps, h, self.push_max_velocity, m.body_type, st.body_awake,
                               m.body_inv_mass, m.body_inertia, m.body_inv_inertia, m.body_linear_damping,
                               m.body_angular_damping, ctl.body_force, ctl.body_torque, m.gravity)
        for _ in range(self.substeps if self.parallel else 0):
            k.integrate_velocities(m.body_type, st.body_awake, m.body_inv_mass, m.body_inertia,
                                   m.body_inv_inertia, m.body_linear_damping, m.body_angular_damping,
                                   ctl.body_force, ctl.body_torque, m.gravity, st.body_q, st.body_qd, h)
            k.warm_start(ctx, cs, ci)
            k.solve_contacts(ctx, cs, ci, True, 1.0 / h, self.push_max_velocity)
            k.integrate_positions(m.body_type, st.body_awake, st.body_q, st.body_qd, self._body_dp,
                                  self._body_dtheta, h)
            k.solve_contacts(ctx, cs, ci, False, 1.0 / h, self.push_max_velocity)
        k.restitution(ctx, cs, ci, self.restitution_threshold)

    def _time_of_impact(self, npairs: int) -> None:
        """Bullets (``body_bullet``, or a body that moved more than its smallest half extent in this step):
        conservative advancement (``inertia.geometry.toi``) over the broad phase's candidate pairs from the
        start-of-step shape poses to the solved ones; a bullet whose first impact comes at a fraction
        ``toi < 1`` goes back to its pose at ``toi`` (``toi_slop`` short of touching) and keeps its
        velocity, so the next step's contact stops it at the surface (docs/collision.md)."""
        if not self.time_of_impact:
            return
        m, st, sh = self.model, self.state, self._shapes
        if not _mark_fast(m.body_type, self._bullet, self._min_half_extent, m.body_bound_radius, self._body_q0,
                          st.body_q, self._body_fast):
            return
        n = _select_toi_pairs(self._pairs, npairs, sh.shape_body, sh.shape_type, sh.shape_is_sensor,
                              self._body_fast, self._bullet, m.body_type, self._toi_pairs)
        if n == 0:
            return
        self._k.shape_world_bounds(sh, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, 0.0, self._pose1,
                                   self._aabb1)
        self._k.time_of_impact_batch(self._toi_pairs, n, sh.shape_type, sh.shape_params, sh.shape_vert_start,
                                     sh.shape_vert_count, sh.geom_vertices, self._shape_pose, self._pose1,
                                     self.toi_slop, 1e-9, self._toi, self._toi_normal, self._toi_point)
        _clamp_bullets(self._toi_pairs, n, self._toi, sh.shape_body, self._body_fast, self._bullet, m.body_type,
                       self._body_q0, st.body_q, self._body_toi)

    def _finalize(self) -> None:
        m, st, c = self.model, self.state, self.contacts
        n_bad = _first_bad_bodies(st.body_q, st.body_qd, self.max_speed, self._bad)
        if n_bad:
            bad = self._bad[:n_bad].copy()
            names = [m.body_name[b] for b in bad[:10]]
            raise SimulationDiverged(
                f"rigid step {int(st.step_index[0])} (t = {st.time:.6g} s) produced non-finite or faster "
                f"than max_speed = {self.max_speed} m/s motion of bodies {names}; likely cause: a very "
                "large force or torque, a tiny or huge mass ratio, or shapes created deeply overlapping",
                step=int(st.step_index[0]), time=st.time, indices=bad)
        if self.enable_sleep:
            isl.update_sleep(c.active, c.active_count, c.contact_body, c.contact_is_sensor, m.body_type,
                             st.body_awake, st.body_qd, st.body_sleep_time, st.body_sleep_island,
                             self._parent, self._island_min, self.dt, self.linear_sleep_tolerance,
                             self.angular_sleep_tolerance, self.time_to_sleep, m.body_bound_radius)
        st.clock[0] += self.dt
        st.step_index[0] += 1

    # ------------------------------------------------------------------ user API
    def save(self) -> dict:
        """Checkpoint: the state, the controls (forces persist across steps), the contact cache that
        warm-starts the next step, and the state of every attached part (``checkpoint_parts``:
        vehicles)."""
        return {"state": self.state.copy(), "contacts": self.contacts.copy(),
                "control": (self.control.body_force.copy(), self.control.body_torque.copy()),
                "parts": [p.save() for p in self.checkpoint_parts]}

    def restore(self, checkpoint: dict) -> None:
        """Continue bit for bit from a checkpoint made by `save` (on a world of the same model, with the
        same parts attached in the same order)."""
        parts = checkpoint.get("parts", [])
        if len(parts) != len(self.checkpoint_parts):
            raise ValueError(f"checkpoint holds {len(parts)} attached parts (vehicles), this world has "
                             f"{len(self.checkpoint_parts)}: restore on a world built the same way")
        self.state.assign(checkpoint["state"])
        self.contacts.assign(checkpoint["contacts"])
        if "control" in checkpoint:
            self.control.body_force[...] = checkpoint["control"][0]
            self.control.body_torque[...] = checkpoint["control"][1]
        for part, cp in zip(self.checkpoint_parts, parts):
            part.restore(cp)

    def wake(self, body: int) -> None:
        """Wake a sleeping body (for example after setting its velocity or a force)."""
        self.state.body_awake[body] = True
        self.state.body_sleep_time[body] = 0.0

    def contact_events(self, *, touch_slop: float = 0.0):
        """Begin / persist / end touch events of the last step between shapes (sensors included).

        Returns a dict of three ``(K, 2) int32`` arrays of shape index pairs ``begin``, ``persist``,
        ``end``, and ``impulse`` (the total normal impulse, N s, of each ``begin`` and ``persist`` pair
        in the last step). A pair touches when one of its points has separation <= ``touch_slop``.
        Pairs of two sleeping bodies keep touching (they are not re-detected while asleep)."""
        cur, prev = self.contacts, self._prev_contacts

        def touching(c):
            idx = np.arange(c.count)
            npts = c.contact_point_count[:c.count]
            seps = np.where(np.arange(4)[None, :] < npts[:, None], c.contact_separation[:c.count], np.inf)
            t = seps.min(axis=1) <= touch_slop
            return idx[t], c.contact_key[:c.count][t]

        ci, ck = touching(cur)
        pi, pk = touching(prev)
        begin_mask = ~np.isin(ck, pk)
        end_mask = ~np.isin(pk, ck)
        # a pair that vanished because both its bodies fell asleep has not ended
        awake = self.state.body_awake
        bodies = prev.contact_body[pi]

        def asleep(b):
            return (b >= 0) & ~awake[np.maximum(b, 0)] & (self.model.body_type[np.maximum(b, 0)] == S.DYNAMIC)

        still = asleep(bodies[:, 0]) | asleep(bodies[:, 1])
        end_mask &= ~still
        imp = cur.contact_total_normal_impulse[ci].sum(axis=1)
        return {"begin": cur.contact_shape[ci[begin_mask]].copy(),
                "persist": cur.contact_shape[ci[~begin_mask]].copy(),
                "end": prev.contact_shape[pi[end_mask]].copy(),
                "begin_impulse": imp[begin_mask], "persist_impulse": imp[~begin_mask]}

    def max_penetration(self) -> float:
        """Deepest penetration (m, >= 0) among the last step's solid contacts, measured at detection."""
        c = self.contacts
        act = c.manifolds()
        act = act[~c.contact_is_sensor[act]]
        if len(act) == 0:
            return 0.0
        seps = np.where(np.arange(4)[None, :] < c.contact_point_count[act, None], c.contact_separation[act],
                        np.inf)
        return float(max(0.0, -seps.min()))


from numba import njit  # noqa: E402


@njit(cache=True)
def _select_constraints(active, contact_body, contact_is_sensor, solver_inv_mass, out):
    n = 0
    for t in range(active.shape[0]):
        i = active[t]
        if contact_is_sensor[i]:
            continue
        a, b = contact_body[i, 0], contact_body[i, 1]
        if (a >= 0 and solver_inv_mass[a] > 0.0) or (b >= 0 and solver_inv_mass[b] > 0.0):
            out[n] = i
            n += 1
    return n


@njit(cache=True)
def _first_bad_bodies(body_q, body_qd, max_speed, out):
    """Bodies with a non-finite pose or velocity or faster than max_speed, in order, into out (B,) int64;
    returns their count (no allocation)."""
    count = 0
    for b in range(body_q.shape[0]):
        ok = True
        for k in range(7):
            if not math.isfinite(body_q[b, k]):
                ok = False
        s = 0.0
        for k in range(3, 6):
            v = body_qd[b, k]
            if not math.isfinite(v):
                ok = False
            s += v * v
        if not math.isfinite(body_qd[b, 0] + body_qd[b, 1] + body_qd[b, 2]):
            ok = False
        if s > max_speed * max_speed:
            ok = False
        if not ok:
            out[count] = b
            count += 1
    return count


def _body_min_half_extent(model):
    """Smallest half extent (m) of each body's finite shapes (inf for bodies without one): a body that
    moves farther than this in one step is swept for time of impact."""
    out = np.full(model.body_count, np.inf)
    for s in range(model.shape_count):
        b, t, p = model.shape_body[s], model.shape_type[s], model.shape_params[s]
        if b < 0:
            continue
        if t == S.SPHERE or t == S.CAPSULE:
            h = p[0]
        elif t == S.BOX:
            h = min(p[0], p[1], p[2])
        elif t == S.CYLINDER:
            h = min(p[0], p[1])
        elif t == S.CONVEX_HULL:
            v = model.geom_vertices[model.shape_vert_start[s]:model.shape_vert_start[s] + model.shape_vert_count[s]]
            h = 0.5 * float((v.max(axis=0) - v.min(axis=0)).min())
        else:
            continue
        out[b] = min(out[b], float(h))
    return out


@njit(cache=True)
def _mark_fast(body_type, bullet, min_half_extent, bound_radius, body_q0, body_q, fast):
    """fast[b]: dynamic body b is a bullet, or a point of it moved farther than its smallest half extent
    in this step (|dx| + angle * bounding radius). Returns the count."""
    count = 0
    for b in range(body_type.shape[0]):
        f = False
        if body_type[b] == S.DYNAMIC:
            d2 = 0.0
            for k in range(3):
                d = body_q[b, k] - body_q0[b, k]
                d2 += d * d
            c = abs(body_q[b, 3] * body_q0[b, 3] + body_q[b, 4] * body_q0[b, 4] + body_q[b, 5] * body_q0[b, 5]
                    + body_q[b, 6] * body_q0[b, 6])
            angle = 2.0 * math.acos(min(c, 1.0))
            f = bullet[b] or math.sqrt(d2) + angle * bound_radius[b] > min_half_extent[b]
        fast[b] = f
        if f:
            count += 1
    return count


@njit(cache=True)
def _sweeps_against(b, other, fast, bullet, body_type):
    """Body b's sweep covers the other body: a bullet against everything, another fast body only
    against static and kinematic bodies (Box2D v3's rule: between two moving non-bullets the speculative
    contacts suffice, and a settling pile is not paused by sweeps)."""
    if b < 0 or not fast[b]:
        return False
    return bullet[b] or other < 0 or body_type[other] != S.DYNAMIC


@njit(cache=True)
def _select_toi_pairs(pairs, npairs, shape_body, shape_type, shape_is_sensor, fast, bullet, body_type, out):
    """Candidate pairs with a sweeping body and two convex shapes (the TOI sweep's domain), in pair order."""
    n = 0
    for i in range(npairs):
        sa, sb = pairs[i, 0], pairs[i, 1]
        if shape_is_sensor[sa] or shape_is_sensor[sb]:
            continue
        if shape_type[sa] > S.CONVEX_HULL or shape_type[sb] > S.CONVEX_HULL:
            continue
        ba, bb = shape_body[sa], shape_body[sb]
        if _sweeps_against(ba, bb, fast, bullet, body_type) or _sweeps_against(bb, ba, fast, bullet, body_type):
            out[n, 0] = sa
            out[n, 1] = sb
            n += 1
    return n


@njit(cache=True)
def _clamp_bullets(pairs, n, toi, shape_body, fast, bullet, body_type, body_q0, body_q, body_toi):
    """Per fast body the earliest impact fraction in (0, 1) over its pairs (0: touching at the start of
    the step, the contact handles it); the body goes back to its pose at that fraction along the step's
    motion (straight line, constant-axis rotation: the TOI sweep's motion model)."""
    for b in range(body_toi.shape[0]):
        body_toi[b] = 1.0
    for i in range(n):
        t = toi[i]
        if not (0.0 < t < 1.0):
            continue
        for side in range(2):
            b = shape_body[pairs[i, side]]
            other = shape_body[pairs[i, 1 - side]]
            if _sweeps_against(b, other, fast, bullet, body_type) and t < body_toi[b]:
                body_toi[b] = t
    for b in range(body_toi.shape[0]):
        t = body_toi[b]
        if t >= 1.0:
            continue
        for k in range(3):
            body_q[b, k] = body_q0[b, k] + t * (body_q[b, k] - body_q0[b, k])
        q0 = (body_q0[b, 3], body_q0[b, 4], body_q0[b, 5], body_q0[b, 6])
        q1 = (body_q[b, 3], body_q[b, 4], body_q[b, 5], body_q[b, 6])
        # dq = q1 q0*, shortest arc, then q(t) = exp(t log dq) q0
        dw = q1[0] * q0[0] + q1[1] * q0[1] + q1[2] * q0[2] + q1[3] * q0[3]
        dx = -q1[0] * q0[1] + q1[1] * q0[0] - q1[2] * q0[3] + q1[3] * q0[2]
        dy = -q1[0] * q0[2] + q1[1] * q0[3] + q1[2] * q0[0] - q1[3] * q0[1]
        dz = -q1[0] * q0[3] - q1[1] * q0[2] + q1[2] * q0[1] + q1[3] * q0[0]
        if dw < 0.0:
            dw, dx, dy, dz = -dw, -dx, -dy, -dz
        sn = math.sqrt(dx * dx + dy * dy + dz * dz)
        if sn <= 1e-15:
            continue
        half = t * math.atan2(sn, dw)
        c, f = math.cos(half), math.sin(half) / sn
        e = (c, dx * f, dy * f, dz * f)
        rw = e[0] * q0[0] - e[1] * q0[1] - e[2] * q0[2] - e[3] * q0[3]
        rx = e[0] * q0[1] + e[1] * q0[0] + e[2] * q0[3] - e[3] * q0[2]
        ry = e[0] * q0[2] - e[1] * q0[3] + e[2] * q0[0] + e[3] * q0[1]
        rz = e[0] * q0[3] + e[1] * q0[2] - e[2] * q0[1] + e[3] * q0[0]
        inv = 1.0 / math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
        body_q[b, 3] = rw * inv
        body_q[b, 4] = rx * inv
        body_q[b, 5] = ry * inv
        body_q[b, 6] = rz * inv


@njit(cache=True)
def _default_rolling_resistance(active, n_active, contact_shape, shape_type, shape_params, coefficient,
                                contact_rolling_friction):
    """Lever arm of the default rolling resistance: ``coefficient`` times the rolling radius of the round
    shapes of the pair (sphere, capsule, cylinder: params[0]), the larger of the two, unless the
    materials give a larger one. Boxes, hulls and flat shapes do not roll and get none."""
    for t in range(n_active):
        i = active[t]
        r = 0.0
        for side in range(2):
            s = contact_shape[i, side]
            ty = shape_type[s]
            if ty == S.SPHERE or ty == S.CAPSULE or ty == S.CYLINDER:
                r = max(r, shape_params[s, 0])
        lever = coefficient * r
        if lever > contact_rolling_friction[i]:
            contact_rolling_friction[i] = lever
