"""Two-way coupling of particles and rigid bodies: particle momentum changes go back into the bodies.

The world step moves the bodies first (the rigid stage), then steps the particle groups against the
shape table at the bodies' new poses (``inertia.collision.particle_stage``, body rows as moving
colliders). Whatever momentum a particle gains from a body's surface, the body loses:

- **impacts and projections** (the collision pass of ``end_step``): a particle's change over the pass,
  ``dp = m (v_after - v_before)`` and ``dL = m (x_after x v_after - x_before x v_before)`` (its angular
  momentum about the world origin), is attributed to the body whose shape is nearest to the particle
  (signed distance minus radius at the start or end of the pass, within the contact tolerance plus the
  pass's displacement). The body receives the linear impulse ``J = -dp`` and the angular impulse about
  its centre of mass ``A = -dL - c x J``, so the total linear *and* angular momentum of particles plus
  bodies is unchanged by the pass, to rounding (Newton's third law applied to the measured change);
- **resting contact** (the force filter): the force the filter cancels for a particle resting on a body
  shape (normal load and friction), ``F = f_applied - f_filtered``, acts on the body at the particle's
  position over the substep: ``J = F h``, ``A = (x - c) x J``.

Per contact (the rows of the world's ``Contacts`` buffer): both gathers also add the impulse each
particle received to its contact slot of that row (`ContactSlots`, two per particle and world step;
static rows, which push no body, included), and `fill_particle_contacts` turns the slots, the row a
particle rests on at the end of the step and the sensor rows it overlaps into buffer rows. The slots'
impulses on a body's rows sum to minus what the body received (the same numbers, summed in another order).
In a world whose bodies are all static the particle groups take the fused integrator step, whose near
loop writes the same slots itself (``particle_kernels.step_and_collide``, attribution by the shared
``particle_kernels.pass_row``): the rows are those of the separate pass, bit for bit.
The coupling lists the particles that took a slot or rest on a table row (`TouchedParticles`:
after a fused step from its near particles only, after a separate pass from every particle), and the
world clears the slots and fills the rows of those alone (in particle order: the same rows as a scan
of every particle), so with the fused step a world step's rows cost what its contacts cost; a world
with sensor rows still tests every particle against them.

Impulses are summed per body in particle order, group order and substep order (serial, fixed order:
deterministic at any thread count), then applied once per world step by `apply_body_impulses`:
``dv = J / m``, ``dw = I_world^-1 A`` for dynamic bodies (zero for static and kinematic ones); a
sleeping body is woken when its velocity change exceeds ``wake_speed``.

References
- Newton's third law / conservation of momentum for impulsive contact: Mirtich, B. (1996), *Impulse-based
  dynamic simulation of rigid body systems*, PhD thesis, UC Berkeley, ch. 2-3 (collision impulses
  applied equal and opposite at the contact point).
- Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes: resting contact
  by cancelling the normal force (the cancelled force is the contact's load on the other body).

Limitations
- Explicit (one-way per step) coupling: the body's response to this step's particle impulses is seen by
  the particles from the next step on (a light body under a heavy particle load lags by one step).
- The resting load uses the filter's last force evaluation of the substep (exact for constant forces).
- Attribution is geometric: a particle's change in the pass goes to the nearest shape; particle-particle
  impulses (``self_collisions``) of particles touching a body are attributed to that body.
- 3-D only; particles need a finite mass (pinned particles push nothing).
- Contact rows: at most two rows per particle and step (a third row's impulse is added to the second
  slot); particle-particle impulses of a particle touching a row are part of that row's impulse.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..collision import distance as _d
from ..collision import particle_kernels as _pk
from ..geometry import shapes as S
from ..math import world_inertia_inv_into

__all__ = ["apply_body_impulses", "ParticleBodyCoupling", "gather_pass_impulses", "gather_resting_impulses",
           "PassParticles", "PackedRows", "BodyImpulses", "ContactSlots", "SLOTS", "fill_particle_contacts",
           "TouchedParticles", "note_touched", "clear_touched", "sort_touched"]


@njit(cache=True)
def _apply(body_type, inv_mass, inv_inertia, body_q, body_qd, body_awake, body_sleep_time, linear,
           angular, wake_speed, bound_radius, scratch):
    """The loop of `apply_body_impulses`; ``scratch`` (2, 3, 3): R(q) and I_world^-1 of the body at hand."""
    r, iw = scratch[0], scratch[1]
    applied = 0
    for b in range(body_type.shape[0]):
        if body_type[b] != S.DYNAMIC or inv_mass[b] == 0.0:
            continue
        jx, jy, jz = linear[b, 0], linear[b, 1], linear[b, 2]
        ax, ay, az = angular[b, 0], angular[b, 1], angular[b, 2]
        if jx == 0.0 and jy == 0.0 and jz == 0.0 and ax == 0.0 and ay == 0.0 and az == 0.0:
            continue
        world_inertia_inv_into(body_q[b, 3:7], inv_inertia[b], r, iw)
        dwx = iw[0, 0] * ax + iw[0, 1] * ay + iw[0, 2] * az
        dwy = iw[1, 0] * ax + iw[1, 1] * ay + iw[1, 2] * az
        dwz = iw[2, 0] * ax + iw[2, 1] * ay + iw[2, 2] * az
        m = inv_mass[b]
        if not body_awake[b]:
            dv = math.sqrt((jx * jx + jy * jy + jz * jz)) * m
            dw = math.sqrt(dwx * dwx + dwy * dwy + dwz * dwz) * bound_radius[b]
            if dv + dw <= wake_speed:
                continue          # a sleeping body ignores a negligible push (it acts as static)
            body_awake[b] = True
            body_sleep_time[b] = 0.0
        body_qd[b, 0] += dwx
        body_qd[b, 1] += dwy
        body_qd[b, 2] += dwz
        body_qd[b, 3] += jx * m
        body_qd[b, 4] += jy * m
        body_qd[b, 5] += jz * m
        applied += 1
    return applied


def apply_body_impulses(model_arrays, state, linear_impulse, angular_impulse_about_com, *,
                        wake_speed: float = 1e-4, scratch=None) -> int:
    """Apply impulses to the bodies: ``dv = M^-1 J``, ``dw = I_world^-1 A`` (body_qd written in place).

    Parameters
    ----------
    model_arrays : ``model.bodies()`` (a `BodyArrays` bundle; ``body_type``, ``body_inv_mass``,
        ``body_inv_inertia``, ``body_bound_radius`` are read) or the Model itself.
    state : the rigid `State` (``body_q`` read; ``body_qd``, ``body_awake``, ``body_sleep_time`` written).
    linear_impulse : (B, 3) N s, world frame, through the centre of mass.
    angular_impulse_about_com : (B, 3) N m s, world frame, about the centre of mass.
    wake_speed : m/s; a sleeping body wakes when ``|dv| + |dw| r_bound`` exceeds it (else the impulse is
        dropped: a sleeping body acts as static).
    scratch : optional (2, 3, 3) float64 work array kept by the caller between steps; made here (144
        bytes, whatever the body count) when None. The kernel itself allocates nothing.

    Static and kinematic bodies are unaffected. Returns the number of bodies that changed.
    """
    m = model_arrays
    if scratch is None:
        scratch = np.empty((2, 3, 3))
    elif not (isinstance(scratch, np.ndarray) and scratch.shape == (2, 3, 3) and scratch.dtype == np.float64
              and scratch.flags.c_contiguous):
        raise ValueError(f"scratch must be None or a C-contiguous (2, 3, 3) float64 array; got "
                         f"{getattr(scratch, 'shape', type(scratch).__name__)}")
    return int(_apply(m.body_type, m.body_inv_mass, m.body_inv_inertia, state.body_q, state.body_qd,
                      state.body_awake, state.body_sleep_time, np.ascontiguousarray(linear_impulse, np.float64),
                      np.ascontiguousarray(angular_impulse_about_com, np.float64), float(wake_speed),
                      m.body_bound_radius, scratch))


class PassParticles(NamedTuple):
    """Kernel bundle: the particles around the collision pass (N particles, 3-D)."""
    x_pre: np.ndarray      # (N, 3) m, before the pass
    v_pre: np.ndarray      # (N, 3) m/s, before the pass
    x: np.ndarray          # (N, 3) m, after the pass
    v: np.ndarray          # (N, 3) m/s, after the pass
    inv_mass: np.ndarray   # (N,) 1/kg
    active: np.ndarray     # (N,) bool
    radius: np.ndarray     # (N,) m


class PackedRows(NamedTuple):
    """Kernel bundle: the particle stage's packed collider rows (``particle_kernels`` layout) at the
    end of the (sub)step, the dynamic body of each row (-1 none) and its shape-table row (-1: a
    collider of the system's own, not a table row)."""
    cint: np.ndarray
    cf: np.ndarray
    ci: np.ndarray
    pose: np.ndarray
    ref: np.ndarray
    entry_body: np.ndarray
    entry_shape: np.ndarray


class ContactSlots(NamedTuple):
    """Kernel bundle: per particle, the packed rows it touched during the world step and the impulse
    each gave it (the rows of the ``Contacts`` buffer are made from these, see ``inertia.world``).
    A particle has ``SLOTS`` slots; a third row met in one step adds its impulse to the last slot."""
    entry: np.ndarray      # (N, SLOTS) int64, packed row index, -1 empty
    impulse: np.ndarray    # (N, SLOTS, 3) N s, impulse on the particle over the step


#: contact slots per particle and world step (a particle in a corner touches two rows)
SLOTS = 2


_slot_add = _pk.slot_add  # one home: the fused step (``step_and_collide``) writes the same slots


class TouchedParticles(NamedTuple):
    """Kernel bundle: the particles that may have rows in the world step's Contacts buffer (a contact
    slot taken, or resting on a table row at the end of a substep), so that clearing the slots and
    filling the rows cost what the contacts cost, not what the group costs. Each particle is listed
    once per world step (``listed``); the list is in particle order unless a later substep listed a
    lower index (``state[1]`` 0: ``sort_touched`` puts it back in order before the fill)."""
    index: np.ndarray      # (N,) int64, the listed particles in index[:state[0]]
    listed: np.ndarray     # (N,) bool, True for a listed particle
    state: np.ndarray      # (2,) int64: [count, 1 when index[:count] is ascending]


@njit(cache=True, inline="always")
def _note(i, entry, rest_k, entry_shape, T):
    if T.listed[i]:
        return
    k = rest_k[i]
    if entry[i, 0] < 0 and (k < 0 or entry_shape[k] < 0):
        return
    c = T.state[0]
    if c > 0 and T.index[c - 1] > i:
        T.state[1] = 0
    T.index[c] = i
    T.listed[i] = True
    T.state[0] = c + 1


@njit(cache=True)
def note_touched(near, chunk, entry, rest_k, entry_shape, T):
    """List (`TouchedParticles` T) the particles of a substep that hold a contact slot (``entry``
    (N, SLOTS)) or rest on a table row (``rest_k``, ``entry_shape``). ``near``: the candidates,
    in chunks of ``chunk`` slots, each chunk's list from its first slot and ended by -1 when
    shorter (the fused step's ``near_list``: only those particles were collided); chunk <= 0:
    every particle is a candidate (after the separate pass). Serial, in particle order."""
    n = rest_k.shape[0]
    if chunk <= 0:
        for i in range(n):
            _note(i, entry, rest_k, entry_shape, T)
        return
    for lo in range(0, n, chunk):
        for q in range(lo, min(lo + chunk, n)):
            i = near[q]
            if i < 0:
                break
            _note(i, entry, rest_k, entry_shape, T)


@njit(cache=True)
def clear_touched(entry, impulse, T):
    """Empty the contact slots of the listed particles and the list (the start of a world step):
    every particle with a slot taken is listed, so all slots are empty afterwards."""
    for t in range(T.state[0]):
        i = T.index[t]
        for s in range(entry.shape[1]):
            entry[i, s] = -1
            impulse[i, s, 0] = 0.0
            impulse[i, s, 1] = 0.0
            impulse[i, s, 2] = 0.0
        T.listed[i] = False
    T.state[0] = 0
    T.state[1] = 1


@njit(cache=True)
def sort_touched(T):
    """Put the listed particles in ascending order, in place (heapsort: no allocation)."""
    if T.state[1] != 0:
        return
    a, m = T.index, T.state[0]
    for start in range(m // 2 - 1, -1, -1):
        _sift(a, start, m)
    for end in range(m - 1, 0, -1):
        a[0], a[end] = a[end], a[0]
        _sift(a, 0, end)
    T.state[1] = 1


@njit(cache=True)
def _sift(a, root, end):
    while True:
        child = 2 * root + 1
        if child >= end:
            return
        if child + 1 < end and a[child + 1] > a[child]:
            child += 1
        if a[root] >= a[child]:
            return
        a[root], a[child] = a[child], a[root]
        root = child


class BodyImpulses(NamedTuple):
    """Kernel bundle: body poses (read) and the impulse accumulators (added to)."""
    body_q: np.ndarray     # (B, 7)
    linear: np.ndarray     # (B, 3) N s
    angular: np.ndarray    # (B, 3) N m s about the centre of mass


@njit(cache=True)
def gather_pass_impulses(P, R, out, slots, tol):
    """Add, per body, minus the momentum the collision pass gave the particles near its shapes
    (see the module docstring), and to each such particle's contact slot (`ContactSlots`) of the
    nearest table row -- static rows too -- the momentum it gained. P: `PassParticles`; R:
    `PackedRows`; out: `BodyImpulses` (accumulated serially, in particle order). Returns the number
    of particles attributed to a body."""
    x_pre, v_pre, x, v, inv_mass, active, radius = P.x_pre, P.v_pre, P.x, P.v, P.inv_mass, P.active, P.radius
    cint, cf, ci, pose1, ref, entry_body = R.cint, R.cf, R.ci, R.pose, R.ref, R.entry_body
    entry_shape = R.entry_shape
    body_q, linear_out, angular_out = out.body_q, out.linear, out.angular
    n = x.shape[0]
    count = 0
    for i in range(n):
        if not active[i] or inv_mass[i] == 0.0:
            continue
        dvx, dvy, dvz = v[i, 0] - v_pre[i, 0], v[i, 1] - v_pre[i, 1], v[i, 2] - v_pre[i, 2]
        dxx, dxy, dxz = x[i, 0] - x_pre[i, 0], x[i, 1] - x_pre[i, 1], x[i, 2] - x_pre[i, 2]
        if dvx == 0.0 and dvy == 0.0 and dvz == 0.0 and dxx == 0.0 and dxy == 0.0 and dxz == 0.0:
            continue
        # the nearest row at the start or end of the pass, within reach (``particle_kernels.pass_row``)
        kbest = _pk.pass_row(cint, cf, ci, pose1, ref, entry_body, entry_shape, radius[i], tol, x_pre[i, 0],
                             x_pre[i, 1], x_pre[i, 2], x[i, 0], x[i, 1], x[i, 2], _d.ALL_KINDS, True)
        if kbest < 0:
            continue
        b = entry_body[kbest]
        m = 1.0 / inv_mass[i]
        jx, jy, jz = -m * dvx, -m * dvy, -m * dvz
        if entry_shape[kbest] >= 0:
            _slot_add(slots.entry, slots.impulse, i, kbest, -jx, -jy, -jz)
        if b < 0:
            continue
        # angular momentum of the particle about the origin, before and after the pass
        l1x = m * (x[i, 1] * v[i, 2] - x[i, 2] * v[i, 1])
        l1y = m * (x[i, 2] * v[i, 0] - x[i, 0] * v[i, 2])
        l1z = m * (x[i, 0] * v[i, 1] - x[i, 1] * v[i, 0])
        l0x = m * (x_pre[i, 1] * v_pre[i, 2] - x_pre[i, 2] * v_pre[i, 1])
        l0y = m * (x_pre[i, 2] * v_pre[i, 0] - x_pre[i, 0] * v_pre[i, 2])
        l0z = m * (x_pre[i, 0] * v_pre[i, 1] - x_pre[i, 1] * v_pre[i, 0])
        cx, cy, cz = body_q[b, 0], body_q[b, 1], body_q[b, 2]
        linear_out[b, 0] += jx
        linear_out[b, 1] += jy
        linear_out[b, 2] += jz
        angular_out[b, 0] += -(l1x - l0x) - (cy * jz - cz * jy)
        angular_out[b, 1] += -(l1y - l0y) - (cz * jx - cx * jz)
        angular_out[b, 2] += -(l1z - l0z) - (cx * jy - cy * jx)
        count += 1
    return count


@njit(cache=True)
def gather_resting_impulses(x, reaction, reaction_body, reaction_entry, out, slots, h):
    """Add, per body, the force the resting-contact filter cancelled for particles resting on its
    shapes, times the substep h, applied at the particles' positions x (N, 3); and minus that impulse
    to the particle's contact slot of the row it rests on (`ContactSlots`). reaction (N, 3) N;
    reaction_body (N,) int64 (-1 none); reaction_entry (N,) int64 (the packed table row rested on, -1
    none); out: `BodyImpulses`. Returns the number of particles that pushed a body."""
    body_q, linear_out, angular_out = out.body_q, out.linear, out.angular
    count = 0
    for i in range(x.shape[0]):
        k = reaction_entry[i]
        if k < 0:
            continue
        jx, jy, jz = reaction[i, 0] * h, reaction[i, 1] * h, reaction[i, 2] * h
        _slot_add(slots.entry, slots.impulse, i, k, -jx, -jy, -jz)
        b = reaction_body[i]
        if b < 0:
            continue
        count += 1
        rx, ry, rz = x[i, 0] - body_q[b, 0], x[i, 1] - body_q[b, 1], x[i, 2] - body_q[b, 2]
        linear_out[b, 0] += jx
        linear_out[b, 1] += jy
        linear_out[b, 2] += jz
        angular_out[b, 0] += ry * jz - rz * jy
        angular_out[b, 1] += rz * jx - rx * jz
        angular_out[b, 2] += rx * jy - ry * jx
    return count


@njit(cache=True)
def _filter_reaction(f_before, f_after, inv_mass, rest_k, entry_body, entry_shape, reaction, reaction_body,
                     reaction_entry):
    for i in range(f_after.shape[0]):
        k = rest_k[i]
        b = entry_body[k] if k >= 0 else -1
        if (b < 0 and (k < 0 or entry_shape[k] < 0)) or inv_mass[i] == 0.0:
            reaction_body[i] = -1
            reaction_entry[i] = -1
            reaction[i, 0] = reaction[i, 1] = reaction[i, 2] = 0.0
            continue
        reaction_body[i] = b
        reaction_entry[i] = k
        for c in range(3):
            reaction[i, c] = f_before[i, c] - f_after[i, c]


class ParticleBodyCoupling:
    """The coupling buffers of one particle group (``system._collision.coupling``, set by the world).

    Arrays (N particles of the group, B bodies of the world's model):
    x_pre, v_pre (N, 3)    positions and velocities before the collision pass (end_step)
    f_before (N, 3)        forces before the resting filter (each force evaluation)
    reaction (N, 3) N, reaction_body (N,) int64   the force the filter cancelled on a body shape and that
                           body (written by the last force evaluation of the substep)
    reaction_entry (N,) int64   the packed table row of that force (static rows too; -1 none)
    entry_body (K,) int64  the dynamic body of each packed collider row
    entry_shape (K,) int64 the shape-table row of each packed collider row (-1: the system's own)
    slot_entry (N, SLOTS) int64, slot_impulse (N, SLOTS, 3)   the rows each particle touched in the
                           world step and their impulses on it (`ContactSlots`; zeroed by the world)
    linear, angular (B, 3) the world's impulse accumulators (shared by every group; zeroed by the world)
    """

    def __init__(self, system, entry_body, body_q, linear, angular, tol, entry_shape=None):
        n = system.x.shape[0]
        self.system = system
        self.x_pre, self.v_pre = np.zeros((n, 3)), np.zeros((n, 3))
        self.f_before = np.zeros((n, 3))
        self.reaction, self.reaction_body = np.zeros((n, 3)), np.full(n, -1, np.int64)
        self.reaction_entry = np.full(n, -1, np.int64)
        self.entry_body = entry_body
        self.entry_shape = (np.full(entry_body.shape[0], -1, np.int64) if entry_shape is None
                            else np.asarray(entry_shape, np.int64))
        self.slot_entry = np.full((n, SLOTS), -1, np.int64)
        self.slot_impulse = np.zeros((n, SLOTS, 3))
        self.touched = TouchedParticles(np.zeros(n, np.int64), np.zeros(n, bool), np.array([0, 1], np.int64))
        self.body_q = body_q
        self.linear, self.angular = linear, angular
        self.tol = tol
        self.filter_ran = False
        # diagnostics: particle-substeps that pushed a body through the collision pass / resting contact
        self.counts = {"pass": 0, "resting": 0}

    def before_filter(self, f):
        self.f_before[:] = f

    def after_filter(self, x, f, data):
        _filter_reaction(self.f_before, f, self.system.inv_mass, data.rest_k, self.entry_body, self.entry_shape,
                         self.reaction, self.reaction_body, self.reaction_entry)
        self.filter_ran = True

    def before_collisions(self, system):
        self.x_pre[:] = system.x
        self.v_pre[:] = system.v

    def clear_slots(self):
        """Forget the rows touched (the world calls it at the start of each world step): the slots of
        the listed particles only (`TouchedParticles`), so the cost is that of the last step's contacts."""
        clear_touched(self.slot_entry, self.slot_impulse, self.touched)

    def note_near(self, near_list, chunk, rest_k):
        """After a fused step (``particle_kernels.step_and_collide``): list its near particles
        (``near_list``, chunks of ``chunk``) that took a slot or rest on a table row."""
        note_touched(near_list, chunk, self.slot_entry, rest_k, self.entry_shape, self.touched)

    def row_order(self, every):
        """(order, m) for `fill_particle_contacts`: the listed particles in ascending order, or
        (..., -1) for every particle when ``every`` (sensor rows: any particle may overlap one)."""
        if every:
            return self.touched.index, -1
        sort_touched(self.touched)
        return self.touched.index, int(self.touched.state[0])

    def after_collisions(self, system, data, h):
        out = BodyImpulses(self.body_q, self.linear, self.angular)
        slots = ContactSlots(self.slot_entry, self.slot_impulse)
        if self.filter_ran:
            self.counts["resting"] += gather_resting_impulses(self.x_pre, self.reaction, self.reaction_body,
                                                              self.reaction_entry, out, slots, h)
            self.filter_ran = False
        particles = PassParticles(self.x_pre, self.v_pre, system.x, system.v, system.inv_mass, system.active,
                                  system.radius)
        rows = PackedRows(data.cint, data.cf, data.ci, data.pose1, data.ref, self.entry_body, self.entry_shape)
        self.counts["pass"] += gather_pass_impulses(particles, rows, out, slots,
                                                    max(self.tol, data.distance_tolerance))
        # the separate pass may have collided any particle: every one is a candidate
        note_touched(self.touched.index, 0, self.slot_entry, data.rest_k, self.entry_shape, self.touched)


class SensorRows(NamedTuple):
    """Kernel bundle: the sensor rows of the shape table packed in the particle kernels' format at the
    end of the step (``pose`` from the bodies' poses), their table rows and bodies (-1 world)."""
    cint: np.ndarray       # (Q, 4) int64 kind, moving, cf offset, ci offset
    cf: np.ndarray
    ci: np.ndarray
    pose: np.ndarray       # (Q, 12)
    ref: np.ndarray        # (Q, 3)
    shape: np.ndarray      # (Q,) int64
    body: np.ndarray       # (Q,) int64


@njit(cache=True)
def _row_distance(cint, cf, ci, pose, ref, k, x, y, z):
    """Signed distance and world-frame unit outward normal of packed row k at the world point."""
    if cint[k, 1] & 1:
        lx, ly, lz = _d.to_rest(pose[k], ref[k], x, y, z)
    else:
        lx, ly, lz = x, y, z
    d, gx, gy, gz = _d.sdf(cint[k, 0], cf, cint[k, 2], ci, cint[k, 3], lx, ly, lz)
    if cint[k, 1] & 1:
        gx, gy, gz = _d.rotate(pose[k], gx, gy, gz)
    return d, gx, gy, gz


@njit(cache=True)
def _write_row(ca, r, shape, body, g, i, x, y, z, radius, d, nx, ny, nz, jx, jy, jz, sensor):
    ca.contact_shape[r, 0] = shape
    ca.contact_shape[r, 1] = -1
    ca.contact_body[r, 0] = body
    ca.contact_body[r, 1] = -1
    ca.contact_particle[r, 0] = g
    ca.contact_particle[r, 1] = i
    ca.contact_point_count[r] = 1
    ca.contact_is_sensor[r] = sensor
    ca.contact_key[r] = -1
    ca.contact_normal[r, 0], ca.contact_normal[r, 1], ca.contact_normal[r, 2] = nx, ny, nz
    mid = 0.5 * (d + radius)              # from the particle's centre back to midway between surfaces
    ca.contact_point[r, 0, 0] = x - mid * nx
    ca.contact_point[r, 0, 1] = y - mid * ny
    ca.contact_point[r, 0, 2] = z - mid * nz
    ca.contact_separation[r, 0] = d - radius
    # tangents: t1 perpendicular to n (built from the axis least aligned with n), t2 = n x t1
    if abs(nx) < 0.57735:
        ax, ay, az = 1.0, 0.0, 0.0
    elif abs(ny) < 0.57735:
        ax, ay, az = 0.0, 1.0, 0.0
    else:
        ax, ay, az = 0.0, 0.0, 1.0
    t1x, t1y, t1z = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx
    s = math.sqrt(t1x * t1x + t1y * t1y + t1z * t1z)
    t1x, t1y, t1z = t1x / s, t1y / s, t1z / s
    t2x, t2y, t2z = ny * t1z - nz * t1y, nz * t1x - nx * t1z, nx * t1y - ny * t1x
    ca.contact_tangent[r, 0, 0], ca.contact_tangent[r, 0, 1], ca.contact_tangent[r, 0, 2] = t1x, t1y, t1z
    ca.contact_tangent[r, 1, 0], ca.contact_tangent[r, 1, 1], ca.contact_tangent[r, 1, 2] = t2x, t2y, t2z
    jn = jx * nx + jy * ny + jz * nz
    ca.contact_normal_impulse[r, 0] = jn
    ca.contact_total_normal_impulse[r, 0] = jn
    ca.contact_max_normal_impulse[r, 0] = jn
    ca.contact_tangent_impulse[r, 0, 0] = jx * t1x + jy * t1y + jz * t1z
    ca.contact_tangent_impulse[r, 0, 1] = jx * t2x + jy * t2y + jz * t2z
    for c in range(1, 4):
        ca.contact_normal_impulse[r, c] = 0.0
        ca.contact_total_normal_impulse[r, c] = 0.0
        ca.contact_max_normal_impulse[r, c] = 0.0
        ca.contact_tangent_impulse[r, c, 0] = 0.0
        ca.contact_tangent_impulse[r, c, 1] = 0.0
        ca.contact_separation[r, c] = 0.0
    for c in range(3):
        ca.contact_rolling_impulse[r, c] = 0.0


@njit(cache=True)
def fill_particle_contacts(x, radius, active, rest_k, slots, R, shape_body, Q, group, ca, start, write, order, m):
    """The particle rows of one group (see ``inertia.dynamics.contacts``): per particle in order, its
    contact slots (`ContactSlots`: rows touched in the step, with their impulses), then the table row
    it rests on at the end of the step if no slot holds it (zero impulse), then the sensor rows
    (`SensorRows` Q) it overlaps (distance minus radius <= 0). R: `PackedRows` at the end of the step.
    Rows go to ``ca`` (`ContactArrays` plus ``contact_particle``) from ``start`` on when ``write``;
    returns the number of rows either way (count with write=False, reserve, then write). The
    particles visited: order[:m] (ascending, every particle that can have a row: the coupling's
    `TouchedParticles`, ``ParticleBodyCoupling.row_order``), or all of them when m < 0."""
    entry, impulse = slots.entry, slots.impulse
    cint, cf, ci, pose, ref, entry_shape = R.cint, R.cf, R.ci, R.pose, R.ref, R.entry_shape
    r = start
    for t in range(x.shape[0] if m < 0 else m):
        i = t if m < 0 else order[t]
        if not active[i]:
            continue
        px, py, pz = x[i, 0], x[i, 1], x[i, 2]
        rk = rest_k[i]
        if rk >= 0 and entry_shape[rk] < 0:
            rk = -1
        for s in range(entry.shape[1] + 1):
            if s < entry.shape[1]:
                k = entry[i, s]
                if k < 0:
                    continue
                if k == rk:
                    rk = -1
                jx, jy, jz = impulse[i, s, 0], impulse[i, s, 1], impulse[i, s, 2]
            else:
                k = rk
                if k < 0:
                    continue
                jx, jy, jz = 0.0, 0.0, 0.0
            if write:
                d, nx, ny, nz = _row_distance(cint, cf, ci, pose, ref, k, px, py, pz)
                sh = entry_shape[k]
                _write_row(ca, r, sh, shape_body[sh], group, i, px, py, pz, radius[i], d, nx, ny, nz,
                           jx, jy, jz, False)
            r += 1
        for q in range(Q.cint.shape[0]):
            d, nx, ny, nz = _row_distance(Q.cint, Q.cf, Q.ci, Q.pose, Q.ref, q, px, py, pz)
            if d - radius[i] > 0.0:
                continue
            if write:
                _write_row(ca, r, Q.shape[q], Q.body[q], group, i, px, py, pz, radius[i], d, nx, ny, nz,
                           0.0, 0.0, 0.0, True)
            r += 1
    return r - start
