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
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..collision import distance as _d
from ..geometry import shapes as S
from ..math import world_inertia_inv

__all__ = ["apply_body_impulses", "ParticleBodyCoupling", "gather_pass_impulses", "gather_resting_impulses",
           "PassParticles", "PackedRows", "BodyImpulses"]


@njit(cache=True)
def _apply(body_type, inv_mass, inv_inertia, body_q, body_qd, body_awake, body_sleep_time, linear,
           angular, wake_speed, bound_radius):
    applied = 0
    for b in range(body_type.shape[0]):
        if body_type[b] != S.DYNAMIC or inv_mass[b] == 0.0:
            continue
        jx, jy, jz = linear[b, 0], linear[b, 1], linear[b, 2]
        ax, ay, az = angular[b, 0], angular[b, 1], angular[b, 2]
        if jx == 0.0 and jy == 0.0 and jz == 0.0 and ax == 0.0 and ay == 0.0 and az == 0.0:
            continue
        iw = world_inertia_inv(body_q[b, 3:7], inv_inertia[b])
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
                        wake_speed: float = 1e-4) -> int:
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

    Static and kinematic bodies are unaffected. Returns the number of bodies that changed.
    """
    m = model_arrays
    return int(_apply(m.body_type, m.body_inv_mass, m.body_inv_inertia, state.body_q, state.body_qd,
                      state.body_awake, state.body_sleep_time, np.ascontiguousarray(linear_impulse, np.float64),
                      np.ascontiguousarray(angular_impulse_about_com, np.float64), float(wake_speed),
                      m.body_bound_radius))


@njit(cache=True)
def _signed_distance(cint, cf, ci, pose, ref, k, x, y, z):
    if cint[k, 1] & 1:
        lx, ly, lz = _d.to_rest(pose[k], ref[k], x, y, z)
    else:
        lx, ly, lz = x, y, z
    d, gx, gy, gz = _d.sdf(cint[k, 0], cf, cint[k, 2], ci, cint[k, 3], lx, ly, lz)
    return d


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
    end of the (sub)step, and the dynamic body of each row (-1 none)."""
    cint: np.ndarray
    cf: np.ndarray
    ci: np.ndarray
    pose: np.ndarray
    ref: np.ndarray
    entry_body: np.ndarray


class BodyImpulses(NamedTuple):
    """Kernel bundle: body poses (read) and the impulse accumulators (added to)."""
    body_q: np.ndarray     # (B, 7)
    linear: np.ndarray     # (B, 3) N s
    angular: np.ndarray    # (B, 3) N m s about the centre of mass


@njit(cache=True)
def gather_pass_impulses(P, R, out, tol):
    """Add, per body, minus the momentum the collision pass gave the particles near its shapes
    (see the module docstring). P: `PassParticles`; R: `PackedRows`; out: `BodyImpulses`
    (accumulated serially, in particle order). Returns the number of particles attributed to a body."""
    x_pre, v_pre, x, v, inv_mass, active, radius = P.x_pre, P.v_pre, P.x, P.v, P.inv_mass, P.active, P.radius
    cint, cf, ci, pose1, ref, entry_body = R.cint, R.cf, R.ci, R.pose, R.ref, R.entry_body
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
        # the nearest shape at the start or end of the pass
        best, kbest = 1e300, -1
        for k in range(cint.shape[0]):
            if cint[k, 0] == _d.CALLABLE:
                continue
            d0 = _signed_distance(cint, cf, ci, pose1, ref, k, x_pre[i, 0], x_pre[i, 1], x_pre[i, 2])
            d1 = _signed_distance(cint, cf, ci, pose1, ref, k, x[i, 0], x[i, 1], x[i, 2])
            d = min(d0, d1)
            if d < best:
                best, kbest = d, k
        if kbest < 0:
            continue
        b = entry_body[kbest]
        if b < 0:
            continue
        reach = tol + math.sqrt(dxx * dxx + dxy * dxy + dxz * dxz) + 1e-9
        if best - radius[i] > reach:
            continue
        m = 1.0 / inv_mass[i]
        jx, jy, jz = -m * dvx, -m * dvy, -m * dvz
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
def gather_resting_impulses(x, reaction, reaction_body, out, h):
    """Add, per body, the force the resting-contact filter cancelled for particles resting on its
    shapes, times the substep h, applied at the particles' positions x (N, 3). reaction (N, 3) N;
    reaction_body (N,) int64 (-1 none); out: `BodyImpulses`. Returns the number of particles that
    pushed a body."""
    body_q, linear_out, angular_out = out.body_q, out.linear, out.angular
    count = 0
    for i in range(x.shape[0]):
        b = reaction_body[i]
        if b < 0:
            continue
        count += 1
        jx, jy, jz = reaction[i, 0] * h, reaction[i, 1] * h, reaction[i, 2] * h
        rx, ry, rz = x[i, 0] - body_q[b, 0], x[i, 1] - body_q[b, 1], x[i, 2] - body_q[b, 2]
        linear_out[b, 0] += jx
        linear_out[b, 1] += jy
        linear_out[b, 2] += jz
        angular_out[b, 0] += ry * jz - rz * jy
        angular_out[b, 1] += rz * jx - rx * jz
        angular_out[b, 2] += rx * jy - ry * jx
    return count


@njit(cache=True)
def _filter_reaction(f_before, f_after, inv_mass, rest_k, entry_body, reaction, reaction_body):
    for i in range(f_after.shape[0]):
        k = rest_k[i]
        b = entry_body[k] if k >= 0 else -1
        if b < 0 or inv_mass[i] == 0.0:
            reaction_body[i] = -1
            reaction[i, 0] = reaction[i, 1] = reaction[i, 2] = 0.0
            continue
        reaction_body[i] = b
        for c in range(3):
            reaction[i, c] = f_before[i, c] - f_after[i, c]


class ParticleBodyCoupling:
    """The coupling buffers of one particle group (``system._collision.coupling``, set by the world).

    Arrays (N particles of the group, B bodies of the world's model):
    x_pre, v_pre (N, 3)    positions and velocities before the collision pass (end_step)
    f_before (N, 3)        forces before the resting filter (each force evaluation)
    reaction (N, 3) N, reaction_body (N,) int64   the force the filter cancelled on a body shape and that
                           body (written by the last force evaluation of the substep)
    entry_body (K,) int64  the dynamic body of each packed collider row
    linear, angular (B, 3) the world's impulse accumulators (shared by every group; zeroed by the world)
    """

    def __init__(self, system, entry_body, body_q, linear, angular, tol):
        n = system.x.shape[0]
        self.system = system
        self.x_pre, self.v_pre = np.zeros((n, 3)), np.zeros((n, 3))
        self.f_before = np.zeros((n, 3))
        self.reaction, self.reaction_body = np.zeros((n, 3)), np.full(n, -1, np.int64)
        self.entry_body = entry_body
        self.body_q = body_q
        self.linear, self.angular = linear, angular
        self.tol = tol
        self.filter_ran = False
        # diagnostics: particle-substeps that pushed a body through the collision pass / resting contact
        self.counts = {"pass": 0, "resting": 0}

    def before_filter(self, f):
        self.f_before[:] = f

    def after_filter(self, x, f, data):
        _filter_reaction(self.f_before, f, self.system.inv_mass, data.rest_k, self.entry_body, self.reaction,
                         self.reaction_body)
        self.filter_ran = True

    def before_collisions(self, system):
        self.x_pre[:] = system.x
        self.v_pre[:] = system.v

    def after_collisions(self, system, data, h):
        out = BodyImpulses(self.body_q, self.linear, self.angular)
        if self.filter_ran:
            self.counts["resting"] += gather_resting_impulses(self.x_pre, self.reaction, self.reaction_body,
                                                              out, h)
            self.filter_ran = False
        particles = PassParticles(self.x_pre, self.v_pre, system.x, system.v, system.inv_mass, system.active,
                                  system.radius)
        rows = PackedRows(data.cint, data.cf, data.ci, data.pose1, data.ref, self.entry_body)
        self.counts["pass"] += gather_pass_impulses(particles, rows, out,
                                                    max(self.tol, data.distance_tolerance))
