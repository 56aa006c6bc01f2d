"""RigidWorld: the coupled step for rigid bodies (standalone until it merges with ``inertia.world``).

The step reads as the algorithm; each line is a timed stage in ``world.profile`` (seconds, summed):
```
broad_phase()      # shape world poses, swept AABBs, sort-and-sweep -> sorted candidate pairs
narrow_phase()     # manifolds -> Contacts (count, scan), warm-start match against the previous step
islands()          # wake sleeping islands that are touched, colour the constraints
collide()          # restitution > 0: bounce the points whose gap closes within the step (iterated)
for each substep:  # solve stage: integrate_velocities, warm_start, solve, integrate_positions, relax
    ...
restitution()      # inside the solve stage's timer
finalize()         # sleep, finite check, time
```

Parameters (after Box2D v3, stiffer; ranges are guidance). A soft contact of frequency f sags by
W / (m_eff (2 pi f)^2) under a load W, so a stack's contacts sag in proportion to the weight above
them; at Box2D's 30 Hz a 10-box stack of 0.2 m boxes sags ~27 mm and buckles, hence 60 Hz and 8
substeps here (measured: tests/rigid/test_world.py, the 10-box stack).
- ``dt`` 1/60 s; ``substeps`` 8 (one solver iteration each; 4 suffices for piles and low stacks).
- ``contact_hertz`` 60 Hz (capped at a quarter of the substep rate), ``contact_damping_ratio`` 10,
  ``push_max_velocity`` 3 m/s (the fastest overlapping bodies are pushed apart).
- ``restitution_threshold`` 1 m/s (slower impacts do not bounce).
- ``twist_radius`` 0.005 m: twisting friction about the normal, friction * twist_radius * normal
  impulse (MuJoCo's default torsional friction, 0.005 m); 0 turns it off.
- ``restitution_iterations`` 8: passes of the collision pass before the substeps (Guendelman et al.
  2003): bodies with restitution whose gap closes within the step bounce there, pass after pass, so a
  touching chain (Newton's cradle) hands an impact on; 0 leaves only Box2D's post-step restitution.
- Sleep: ``linear_sleep_tolerance`` 0.05 m/s, ``angular_sleep_tolerance`` 2 deg/s (raised per body to
  linear_sleep_tolerance / bounding radius: the farthest point's speed, as Box2D v3),
  ``time_to_sleep`` 0.5 s; ``enable_sleep`` True.
- ``match_distance`` 0.01 m: a contact point without a matching feature key takes the warm-start
  impulse of the previous point nearest to it within this distance.
- ``parallel``: "auto" (serial: see below), True (parallel colour batches), or False (serial twins).
  Both paths compute identical bits. A parallel solve waits at a barrier after every colour (about 14
  colours x 3 passes x 8 substeps per step on the 1000-box pile); on 2 cores shared with other work each
  barrier waits for a time slice: measured 3.2 s per step parallel against 0.1 s serial at load 11, so
  "auto" runs serially until a machine with idle cores shows the parallel path paying.

Continuous collision: speculative contacts (a gap closed within the step is a contact with bias
gap / h) stop fast bodies at thin walls (tests/rigid/test_world.py, 300 m/s through 1 cm). Hook for
bullet bodies: a time-of-impact sweep (rigid-narrow's geometry function, not on main yet) belongs
between ``_solve`` and ``_finalize`` for bodies flagged ``bullet``, clamping their motion to the first
impact against other dynamic bodies (where speculative margins of both movers can miss); not wired yet.

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
from ..geometry.broadphase import shape_world_bounds, sort_and_sweep
from ..geometry.narrowphase import compact_active, match_warm_start, narrow_phase
from ..model import Control, Model, State

__all__ = ["RigidWorld"]

STAGES = ("broad_phase", "narrow_phase", "islands", "solve", "finalize")


class _Kernels:
    def __init__(self, parallel: bool):
        self.shape_world_bounds = shape_world_bounds
        self.narrow_phase = narrow_phase
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
            self.narrow_phase = serial_twin(narrow_phase)


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
                 parallel="auto",
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
        self._allocate()

    # ------------------------------------------------------------------ scratch
    def _allocate(self):
        m = self.model
        nb, ns = m.body_count, m.shape_count
        self._shapes = m.shapes()
        self._shape_pose = np.zeros((ns, 7))
        self._aabb = np.zeros((ns, 6))
        self._order = np.zeros(ns, np.int64)
        self._grow_pairs(max(64, 4 * ns))
        self._body_dp = np.zeros((nb, 3))
        self._body_dtheta = np.zeros((nb, 3))
        self._solver_inv_mass = np.zeros(nb)
        self._inv_inertia_world = np.zeros((nb, 9))
        self._body_mask = np.zeros(nb, np.uint64)
        self._parent = np.zeros(nb, np.int64)
        self._island_min = np.zeros(nb)
        self._colour_start = np.zeros(sv.MAX_COLOURS + 2, np.int64)
        self._grow_constraints(self.contacts.capacity)

    def _grow_pairs(self, cap):
        self._pairs = np.zeros((cap, 2), np.int32)
        self._keys = np.zeros(cap, np.int64)

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
            with self._timed("finalize"):
                self._finalize()

    def _broad_phase(self) -> int:
        m, st = self.model, self.state
        self._k.shape_world_bounds(self._shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd,
                                   self.dt, self._shape_pose, self._aabb)
        while True:
            n = sort_and_sweep(self._aabb, self._shapes, m.body_type, st.body_awake, self._order,
                               self._keys, self._pairs)
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
        self._k.narrow_phase(self._pairs, self._keys, npairs, self._shapes, self._shape_pose, st.body_qd,
                             m.body_bound_radius, self.dt, ca)
        c.count = npairs
        c.active_count = compact_active(ca, npairs)
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
        if self.restitution_iterations:
            sv.collide(ctx, n_cons, self.dt + h, self.restitution_threshold, self.restitution_iterations)
        cs, ci = self._colour_start, self._colour_items
        ctl = self.control
        for _ in range(self.substeps):
            k.integrate_velocities(m.body_type, st.body_awake, m.body_inv_mass, m.body_inertia,
                                   m.body_inv_inertia, m.body_linear_damping, m.body_angular_damping,
                                   ctl.body_force, ctl.body_torque, m.gravity, st.body_q, st.body_qd, h)
            k.warm_start(ctx, cs, ci)
            k.solve_contacts(ctx, cs, ci, True, 1.0 / h, self.push_max_velocity)
            k.integrate_positions(m.body_type, st.body_awake, st.body_q, st.body_qd, self._body_dp,
                                  self._body_dtheta, h)
            k.solve_contacts(ctx, cs, ci, False, 1.0 / h, self.push_max_velocity)
        k.restitution(ctx, cs, ci, self.restitution_threshold)

    def _finalize(self) -> None:
        m, st, c = self.model, self.state, self.contacts
        bad = _first_bad_bodies(st.body_q, st.body_qd, self.max_speed)
        if bad.size:
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
        """Checkpoint: the state and the contact cache that warm-starts the next step."""
        return {"state": self.state.copy(), "contacts": self.contacts.copy()}

    def restore(self, checkpoint: dict) -> None:
        """Continue bit for bit from a checkpoint made by `save` (on a world of the same model)."""
        self.state.assign(checkpoint["state"])
        self.contacts.assign(checkpoint["contacts"])

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
def _first_bad_bodies(body_q, body_qd, max_speed):
    nb = body_q.shape[0]
    bad = np.zeros(nb, np.bool_)
    count = 0
    for b in range(nb):
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
            bad[b] = True
            count += 1
    out = np.empty(count, np.int64)
    j = 0
    for b in range(nb):
        if bad[b]:
            out[j] = b
            j += 1
    return out
