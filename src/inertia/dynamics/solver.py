"""Soft-step contact solver for rigid bodies (maximal coordinates), with graph colouring.

One step (DESIGN.md "The world step"; each line a kernel here):
```
prepare_contacts()                       # anchors, effective masses, softness, pre-step velocities
collide()                                # restitution > 0: bounce at the time of impact within the step
for each of the n substeps (h = dt / n):
    integrate_velocities()               # gravity, applied force/torque, gyroscopic term, damping
    warm_start()                         # apply the accumulated impulses
    solve(use_bias=True)                 # soft contacts push apart at most push_max_velocity
    integrate_positions()                # x += h v, q <- exp(h w / 2) q
    solve(use_bias=False)                # relax: remove the velocity the bias added
restitution()                            # bounce where the pre-step approach speed > threshold
```
Soft constraint (Catto 2024): a contact is a spring-damper of frequency ``f`` (Hz) and damping ratio
``zeta`` solved implicitly; with ``omega = 2 pi f``, ``a1 = 2 zeta + h omega``, ``a2 = h omega a1``,
``a3 = 1 / (1 + a2)``: bias rate ``omega / a1``, mass scale ``a2 a3``, impulse scale ``a3``. The
impulse of one iteration is ``-m_eff * mass_scale * (v_n + bias) - impulse_scale * lambda`` with the
bias ``max(bias_rate * s, -push_max_velocity)`` for a penetration ``s < 0``. A positive gap ``s`` is a
speculative contact: bias ``s / h`` lets the bodies close it in this substep and no further, which is
the continuous collision of the soft step. The current gap is the detected one plus the anchors' relative
motion since detection (linearised: dp + dtheta x r), so contacts stay valid over the substeps.

Friction is Coulomb at each point with a circular cone |lambda_t| <= mu lambda_n; rolling resistance
limits the relative angular impulse in the tangent plane (rolling; spin about the normal is twisting
friction's) to ``rolling_friction * sum(lambda_n)`` (a lever arm in metres). Its effective mass is the
inverse of the summed world inverse inertias, projected on the tangent plane (exact for isotropic
bodies such as spheres).
Restitution uses the most negative relative normal velocity seen before the step or before a
substep's solve while the gap was closed (so the speed gained under gravity within the step counts),
only where it exceeds the threshold and the point carried an impulse. Before that, the collision pass
(``collide``) bounces the restitution contacts whose gap closes within the step at their time of impact.

Rotation: Euler's equation I dw/dt = tau - w x I w is integrated in the body frame with the gyroscopic
term implicit (one Newton iteration of the implicit midpoint rule, ``_angular_velocity_step``), so a
torque-free body keeps its energy and |L| (to O(h^2) per unit time) instead of gaining energy at O(h).

Parallel solve: constraints are greedily coloured in their (sorted) order so no two constraints of a
colour share a dynamic body (static, kinematic and sleeping bodies are read-only and do not count);
colours run one after another, the constraints of one colour in parallel. Each write hits a different
body, so results are identical at any thread count; the serial twin runs the same order. Constraints
that find no free colour among 63 go to an overflow colour solved serially.

References
- Catto, E. (2024). Solver2D; Box2D v3 "soft step" solver (substepping, soft contacts, relax,
  restitution, speculative contacts, graph colouring).
- Catto, E. (2005). Iterative dynamics with temporal coherence (sequential impulses, warm starting).
- Tonge, R. (2012). Solving rigid body contacts (GDC) -- soft constraints and relax passes.
- Guendelman, E., Bridson, R. and Fedkiw, R. (2003). Nonconvex rigid bodies with stacking (SIGGRAPH),
  section 5: the collision pass before the contact solve.
- Catto, E. (2015). Numerical methods (GDC): the implicit gyroscopic step (one Newton iteration, here on
  the midpoint rule rather than implicit Euler, which dissipates energy at O(h)).

Limitations
- One iteration per substep (the soft step's design): tall stacks need 4-8 substeps.
- Effective masses use the inertia at the start of the step (as Box2D v3 does).
- The gyroscopic step is one Newton iteration: at |w| h comparable to 1 (a body turning a radian per
  substep) it is no longer close to the midpoint rule and the energy drifts.
- The collision pass times an impact from the point's normal motion with constant velocity and linear
  acceleration (gravity, applied force); torques and the turning of the contact point are left out.
- Twisting friction (spin about the normal) models a contact patch of radius ``twist_radius``
  (limit friction * twist_radius * normal impulse; without it a box balanced on one corner spins
  forever and keeps its island awake); it is not warm-started across steps.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .._jit import serial_twin
from ..geometry import shapes as S
from ..geometry._tup import add, cross, dot, mat_vec, qrot, qrot_inv, scale, sub

__all__ = ["SolverContext", "soft_coefficients", "prepare_contacts", "integrate_velocities",
           "integrate_positions", "solve_contacts", "warm_start", "restitution", "collide", "colour_constraints",
           "substeps_serial",
           "MAX_COLOURS"]

MAX_COLOURS = 63   # plus one overflow colour solved serially


def soft_coefficients(hertz: float, damping_ratio: float, h: float):
    """(bias_rate 1/s, mass_scale, impulse_scale) of a soft constraint (Catto 2024)."""
    if hertz == 0.0:
        return 0.0, 1.0, 0.0
    omega = 2.0 * math.pi * hertz
    a1 = 2.0 * damping_ratio + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


class SolverContext(NamedTuple):
    """Arrays every solver stage reads and writes (one bundle, like Box2D's b2StepContext)."""
    # bodies (B rows): state views and per-step scratch
    body_q: np.ndarray            # (B, 7) state, written by integrate_positions
    body_qd: np.ndarray           # (B, 6) state (angular, linear), written by every velocity stage
    body_dp: np.ndarray           # (B, 3) m, displacement since prepare_contacts
    body_dtheta: np.ndarray       # (B, 3) rad, rotation vector sum(h w) since prepare_contacts
    body_inv_mass: np.ndarray     # (B,) 1/kg used by the solver (0: static, kinematic, asleep)
    body_inv_inertia_world: np.ndarray  # (B, 9) 1/(kg m^2), world frame, row-major, from prepare
    # contacts (M rows, indexed by manifold) -- the shared buffer, impulses accumulated in place
    contact_body: np.ndarray
    contact_point_count: np.ndarray
    contact_normal: np.ndarray
    contact_tangent: np.ndarray
    contact_friction: np.ndarray
    contact_restitution: np.ndarray
    contact_rolling_friction: np.ndarray
    contact_normal_impulse: np.ndarray
    contact_tangent_impulse: np.ndarray
    contact_rolling_impulse: np.ndarray
    contact_max_normal_impulse: np.ndarray
    contact_total_normal_impulse: np.ndarray
    contact_relative_velocity: np.ndarray
    # constraints (N rows, one per solved manifold; written by prepare_contacts)
    cons_manifold: np.ndarray     # (N,) int32 manifold row
    cons_anchor: np.ndarray       # (N, 4, 2, 3) m, world offsets from each body's centre at prepare
    cons_base_separation: np.ndarray  # (N, 4) m, separation at detection
    cons_normal_mass: np.ndarray  # (N, 4) kg
    cons_tangent_mass: np.ndarray  # (N, 4, 2) kg
    cons_rolling_mass: np.ndarray  # (N, 9) kg m^2 (inverse of the summed world inverse inertias)
    cons_soft: np.ndarray         # (N, 3) bias_rate, mass_scale, impulse_scale
    cons_twist: np.ndarray        # (N, 3) twist mass kg m^2, accumulated twist impulse N m s (this step),
                                  # limit per unit normal impulse m (friction * twist_radius)


@njit(cache=True)
def _angular_velocity_step(inertia, w, tau, h):
    """Body-frame change dw of the angular velocity over a step h of Euler's equation
    I dw/dt = tau - w x I w (principal moments ``inertia``), implicit in the gyroscopic term: one Newton
    iteration, from w, of the implicit midpoint rule I (w' - w) = h (tau - w_m x I w_m), w_m = (w + w') / 2:
    (I + h/2 (skew(w) I - skew(I w))) dw = h (tau - w x I w). The midpoint rule conserves the kinetic energy
    and |L| of a torque-free body (quadratic invariants); one iteration leaves a drift of O(h^2) per unit
    time, where the explicit step w' = w + h I^-1 (tau - w x I w) gains energy at O(h) (and Bullet's implicit
    Euler Jacobian, h instead of h/2, loses it at O(h))."""
    i0, i1, i2 = inertia
    iw = (i0 * w[0], i1 * w[1], i2 * w[2])
    g = cross(w, iw)
    r0, r1, r2 = h * (tau[0] - g[0]), h * (tau[1] - g[1]), h * (tau[2] - g[2])
    hh = 0.5 * h
    # J = diag(I) + h/2 (skew(w) diag(I) - skew(I w)), row-major
    j01 = hh * (iw[2] - w[2] * i1)
    j02 = hh * (w[1] * i2 - iw[1])
    j10 = hh * (w[2] * i0 - iw[2])
    j12 = hh * (iw[0] - w[0] * i2)
    j20 = hh * (iw[1] - w[1] * i0)
    j21 = hh * (w[0] * i1 - iw[0])
    c00 = i1 * i2 - j12 * j21
    c01 = j12 * j20 - j10 * i2
    c02 = j10 * j21 - i1 * j20
    inv_det = 1.0 / (i0 * c00 + j01 * c01 + j02 * c02)
    # Cramer's rule with the adjugate of J
    return ((c00 * r0 + (j02 * j21 - j01 * i2) * r1 + (j01 * j12 - j02 * i1) * r2) * inv_det,
            (c01 * r0 + (i0 * i2 - j02 * j20) * r1 + (j02 * j10 - i0 * j12) * r2) * inv_det,
            (c02 * r0 + (j01 * j20 - i0 * j21) * r1 + (i0 * i1 - j01 * j10) * r2) * inv_det)


@njit(cache=True)
def _integrate_velocity_one(b, body_type, body_awake, body_inv_mass, body_inertia, body_inv_inertia, lin_damp,
                            ang_damp, force, torque, gravity, body_q, body_qd, h):
    if body_type[b] != S.DYNAMIC or not body_awake[b]:
        return
    qd = body_qd[b]
    im = body_inv_mass[b]
    for k in range(3):
        qd[3 + k] += h * (gravity[k] + im * force[b, k])
    q = (body_q[b, 3], body_q[b, 4], body_q[b, 5], body_q[b, 6])
    wb = qrot_inv(q, (qd[0], qd[1], qd[2]))
    tb = qrot_inv(q, (torque[b, 0], torque[b, 1], torque[b, 2]))
    dw = _angular_velocity_step((body_inertia[b, 0], body_inertia[b, 1], body_inertia[b, 2]), wb, tb, h)
    dww = qrot(q, dw)
    ld = 1.0 / (1.0 + h * lin_damp[b])
    ad = 1.0 / (1.0 + h * ang_damp[b])
    for k in range(3):
        qd[k] = (qd[k] + dww[k]) * ad
        qd[3 + k] *= ld


@njit(cache=True, parallel=True)
def integrate_velocities(body_type, body_awake, body_inv_mass, body_inertia, body_inv_inertia,
                         lin_damp, ang_damp, force, torque, gravity, body_q, body_qd, h):
    """v += h (g + F/m); w += dw, I dw = h (tau - w x I w) with the gyroscopic term implicit (body frame,
    `_angular_velocity_step`); then v /= 1 + h c (damping)."""
    for b in prange(body_q.shape[0]):
        _integrate_velocity_one(b, body_type, body_awake, body_inv_mass, body_inertia, body_inv_inertia, lin_damp,
                                ang_damp, force, torque, gravity, body_q, body_qd, h)


@njit(cache=True)
def _integrate_position_one(b, body_type, body_awake, body_q, body_qd, body_dp, body_dtheta, h):
    if body_type[b] == S.STATIC or (body_type[b] == S.DYNAMIC and not body_awake[b]):
        return
    qd = body_qd[b]
    for k in range(3):
        body_q[b, k] += h * qd[3 + k]
        body_dp[b, k] += h * qd[3 + k]
        body_dtheta[b, k] += h * qd[k]
    _rotate_body(body_q, b, qd[0], qd[1], qd[2], h)


@njit(cache=True)
def _rotate_body(body_q, b, wx, wy, wz, h):
    """q <- exp(h w / 2) q: body b turned by the rotation vector h w (exact for constant w), renormalised."""
    speed = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * speed * h
    if half < 1e-4:
        h2 = half * half
        s = 0.5 * h * (1.0 - h2 / 6.0)
        c = 1.0 - 0.5 * h2
    else:
        s = math.sin(half) / speed
        c = math.cos(half)
    dq = (c, wx * s, wy * s, wz * s)
    q = (body_q[b, 3], body_q[b, 4], body_q[b, 5], body_q[b, 6])
    rw = dq[0] * q[0] - dq[1] * q[1] - dq[2] * q[2] - dq[3] * q[3]
    rx = dq[0] * q[1] + dq[1] * q[0] + dq[2] * q[3] - dq[3] * q[2]
    ry = dq[0] * q[2] - dq[1] * q[3] + dq[2] * q[0] + dq[3] * q[1]
    rz = dq[0] * q[3] + dq[1] * q[2] - dq[2] * q[1] + dq[3] * q[0]
    inv = 1.0 / math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    body_q[b, 3] = rw * inv
    body_q[b, 4] = rx * inv
    body_q[b, 5] = ry * inv
    body_q[b, 6] = rz * inv


@njit(cache=True, parallel=True)
def integrate_positions(body_type, body_awake, body_q, body_qd, body_dp, body_dtheta, h):
    """x += h v; q <- exp(h w / 2) q (exact for constant w), renormalised. Kinematic bodies too."""
    for b in prange(body_q.shape[0]):
        _integrate_position_one(b, body_type, body_awake, body_q, body_qd, body_dp, body_dtheta, h)


@njit(cache=True)
def _world_inverse_inertia_one(b, body_type, body_awake, body_inv_mass, body_inv_inertia, body_q, inv_mass_out,
                               inv_inertia_out):
    if body_type[b] != S.DYNAMIC or not body_awake[b]:
        inv_mass_out[b] = 0.0
        for k in range(9):
            inv_inertia_out[b, k] = 0.0
        return
    inv_mass_out[b] = body_inv_mass[b]
    q = (body_q[b, 3], body_q[b, 4], body_q[b, 5], body_q[b, 6])
    cols = (qrot(q, (1.0, 0.0, 0.0)), qrot(q, (0.0, 1.0, 0.0)), qrot(q, (0.0, 0.0, 1.0)))
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for k in range(3):
                acc += cols[k][r] * body_inv_inertia[b, k] * cols[k][c]
            inv_inertia_out[b, 3 * r + c] = acc


@njit(cache=True, parallel=True)
def world_inverse_inertia(body_type, body_awake, body_inv_mass, body_inv_inertia, body_q,
                          inv_mass_out, inv_inertia_out):
    """Solver masses: R diag(I^-1) R^T for awake dynamic bodies, zero for every other body."""
    for b in prange(body_q.shape[0]):
        _world_inverse_inertia_one(b, body_type, body_awake, body_inv_mass, body_inv_inertia, body_q, inv_mass_out,
                                   inv_inertia_out)


@njit(cache=True)
def _vel(qd, b):
    if b < 0:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    return (qd[b, 3], qd[b, 4], qd[b, 5]), (qd[b, 0], qd[b, 1], qd[b, 2])


@njit(cache=True)
def _inv_i(inv_inertia, b):
    if b < 0:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    m = inv_inertia
    return (m[b, 0], m[b, 1], m[b, 2], m[b, 3], m[b, 4], m[b, 5], m[b, 6], m[b, 7], m[b, 8])


@njit(cache=True)
def _inv_m(inv_mass, b):
    return 0.0 if b < 0 else inv_mass[b]


@njit(cache=True)
def _apply(qd, b, sign, p, r, im, ii):
    """Impulse sign * p at offset r of body b (only dynamic awake bodies have im > 0)."""
    if b < 0 or im == 0.0:
        return
    dw = mat_vec(ii, cross(r, p))
    for k in range(3):
        qd[b, 3 + k] += sign * im * p[k]
        qd[b, k] += sign * dw[k]


@njit(cache=True)
def _apply_angular(qd, b, sign, l, ii):
    if b < 0:
        return
    dw = mat_vec(ii, l)
    for k in range(3):
        qd[b, k] += sign * dw[k]


@njit(cache=True)
def _prepare_block(lo, hi, body_q, contact_point, contact_separation, soft, static_soft, twist_radius, cons_twist,
                   contact_friction, body_inv_inertia_world, body_inv_mass, body_qd, cons_anchor,
                   cons_base_separation, cons_manifold, cons_normal_mass, cons_rolling_mass, cons_soft,
                   cons_tangent_mass, contact_body, contact_max_normal_impulse, contact_normal,
                   contact_point_count, contact_relative_velocity, contact_rolling_friction, contact_tangent,
                   contact_total_normal_impulse):
    for c in range(lo, hi):
        i = cons_manifold[c]
        ba, bb = contact_body[i, 0], contact_body[i, 1]
        n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
        t1 = (contact_tangent[i, 0, 0], contact_tangent[i, 0, 1], contact_tangent[i, 0, 2])
        t2 = (contact_tangent[i, 1, 0], contact_tangent[i, 1, 1], contact_tangent[i, 1, 2])
        ima, imb = _inv_m(body_inv_mass, ba), _inv_m(body_inv_mass, bb)
        iia, iib = _inv_i(body_inv_inertia_world, ba), _inv_i(body_inv_inertia_world, bb)
        va, wa = _vel(body_qd, ba)
        vb, wb = _vel(body_qd, bb)
        sr = static_soft if (ima == 0.0 or imb == 0.0) else soft
        cons_soft[c, 0] = sr[0]
        cons_soft[c, 1] = sr[1]
        cons_soft[c, 2] = sr[2]
        # twisting friction about the normal (a contact patch of radius twist_radius): 1 / n.(Ia^-1 + Ib^-1) n
        kt = dot(n, mat_vec(iia, n)) + dot(n, mat_vec(iib, n))
        cons_twist[c, 0] = 1.0 / kt if kt > 0.0 else 0.0
        cons_twist[c, 1] = 0.0
        cons_twist[c, 2] = contact_friction[i] * twist_radius
        xa = (0.0, 0.0, 0.0)
        qa = (1.0, 0.0, 0.0, 0.0)
        if ba >= 0:
            xa = (body_q[ba, 0], body_q[ba, 1], body_q[ba, 2])
            qa = (body_q[ba, 3], body_q[ba, 4], body_q[ba, 5], body_q[ba, 6])
        xb = (0.0, 0.0, 0.0)
        qb = (1.0, 0.0, 0.0, 0.0)
        if bb >= 0:
            xb = (body_q[bb, 0], body_q[bb, 1], body_q[bb, 2])
            qb = (body_q[bb, 3], body_q[bb, 4], body_q[bb, 5], body_q[bb, 6])
        for k in range(contact_point_count[i]):
            p = (contact_point[i, k, 0], contact_point[i, k, 1], contact_point[i, k, 2])
            ra = sub(p, xa)
            rb = sub(p, xb)
            for m in range(3):
                cons_anchor[c, k, 0, m] = ra[m]
                cons_anchor[c, k, 1, m] = rb[m]
            cons_base_separation[c, k] = contact_separation[i, k]
            # effective mass along a direction d: 1 / (ma + mb + (ra x d).Ia^-1 (ra x d) + ...)
            for ax in range(3):
                d = n if ax == 0 else (t1 if ax == 1 else t2)
                rda = cross(ra, d)
                rdb = cross(rb, d)
                kk = ima + imb + dot(rda, mat_vec(iia, rda)) + dot(rdb, mat_vec(iib, rdb))
                mass = 1.0 / kk if kk > 0.0 else 0.0
                if ax == 0:
                    cons_normal_mass[c, k] = mass
                else:
                    cons_tangent_mass[c, k, ax - 1] = mass
            dv = sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra)))
            contact_relative_velocity[i, k] = dot(dv, n)
            contact_max_normal_impulse[i, k] = 0.0
            contact_total_normal_impulse[i, k] = 0.0
        # rolling: inverse of (Ia^-1 + Ib^-1)
        m = (iia[0] + iib[0], iia[1] + iib[1], iia[2] + iib[2], iia[3] + iib[3], iia[4] + iib[4],
             iia[5] + iib[5], iia[6] + iib[6], iia[7] + iib[7], iia[8] + iib[8])
        det = (m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
               + m[2] * (m[3] * m[7] - m[4] * m[6]))
        if abs(det) > 1e-300 and contact_rolling_friction[i] > 0.0:
            inv = 1.0 / det
            cons_rolling_mass[c, 0] = (m[4] * m[8] - m[5] * m[7]) * inv
            cons_rolling_mass[c, 1] = (m[2] * m[7] - m[1] * m[8]) * inv
            cons_rolling_mass[c, 2] = (m[1] * m[5] - m[2] * m[4]) * inv
            cons_rolling_mass[c, 3] = (m[5] * m[6] - m[3] * m[8]) * inv
            cons_rolling_mass[c, 4] = (m[0] * m[8] - m[2] * m[6]) * inv
            cons_rolling_mass[c, 5] = (m[2] * m[3] - m[0] * m[5]) * inv
            cons_rolling_mass[c, 6] = (m[3] * m[7] - m[4] * m[6]) * inv
            cons_rolling_mass[c, 7] = (m[1] * m[6] - m[0] * m[7]) * inv
            cons_rolling_mass[c, 8] = (m[0] * m[4] - m[1] * m[3]) * inv
        else:
            for k in range(9):
                cons_rolling_mass[c, k] = 0.0


@njit(cache=True)
def _prepare_range(ctx, body_q, lo, hi, contact_point, contact_separation, soft, static_soft, twist_radius):
    _prepare_block(lo, hi, body_q, contact_point, contact_separation, soft, static_soft, twist_radius,
                   ctx.cons_twist,
                   ctx.contact_friction,
                   ctx.body_inv_inertia_world, ctx.body_inv_mass, ctx.body_qd, ctx.cons_anchor,
                   ctx.cons_base_separation, ctx.cons_manifold, ctx.cons_normal_mass, ctx.cons_rolling_mass,
                   ctx.cons_soft, ctx.cons_tangent_mass, ctx.contact_body, ctx.contact_max_normal_impulse,
                   ctx.contact_normal, ctx.contact_point_count, ctx.contact_relative_velocity,
                   ctx.contact_rolling_friction, ctx.contact_tangent, ctx.contact_total_normal_impulse)


@njit(cache=True, parallel=True)
def prepare_contacts(ctx, body_q, n_cons, contact_point, contact_separation, h, soft, static_soft, twist_radius):
    """Anchors, effective masses, softness and pre-step normal velocities of each constraint."""
    nch = min(n_cons, CHUNKS)
    for ch in prange(nch):
        a = n_cons * ch // nch
        b = n_cons * (ch + 1) // nch
        _prepare_range(ctx, body_q, a, b, contact_point, contact_separation, soft, static_soft, twist_radius)


# --- the hot loops. Each range kernel unpacks the context bundle once into local arrays: reading a
# NamedTuple member inside the loop makes Numba take and drop a reference to the array every time
# (measured: 15 us per manifold instead of 0.3 us), so the per-constraint code below sees only locals.

@njit(cache=True)
def _warm_block(items, lo, hi, qd, inv_mass, inv_inertia, cons_manifold, contact_body, contact_point_count,
                contact_normal, contact_tangent, normal_impulse, tangent_impulse, rolling_impulse, cons_anchor,
                cons_twist):
    for t in range(lo, hi):
        c = items[t]
        i = cons_manifold[c]
        ba, bb = contact_body[i, 0], contact_body[i, 1]
        ima, imb = _inv_m(inv_mass, ba), _inv_m(inv_mass, bb)
        iia, iib = _inv_i(inv_inertia, ba), _inv_i(inv_inertia, bb)
        n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
        t1 = (contact_tangent[i, 0, 0], contact_tangent[i, 0, 1], contact_tangent[i, 0, 2])
        t2 = (contact_tangent[i, 1, 0], contact_tangent[i, 1, 1], contact_tangent[i, 1, 2])
        for k in range(contact_point_count[i]):
            ra = (cons_anchor[c, k, 0, 0], cons_anchor[c, k, 0, 1], cons_anchor[c, k, 0, 2])
            rb = (cons_anchor[c, k, 1, 0], cons_anchor[c, k, 1, 1], cons_anchor[c, k, 1, 2])
            p = add(add(scale(n, normal_impulse[i, k]), scale(t1, tangent_impulse[i, k, 0])),
                    scale(t2, tangent_impulse[i, k, 1]))
            _apply(qd, ba, -1.0, p, ra, ima, iia)
            _apply(qd, bb, 1.0, p, rb, imb, iib)
        l = (rolling_impulse[i, 0], rolling_impulse[i, 1], rolling_impulse[i, 2])
        tw = cons_twist[c, 1]
        if tw != 0.0:
            l = add(l, scale(n, tw))
        if l[0] != 0.0 or l[1] != 0.0 or l[2] != 0.0:
            _apply_angular(qd, ba, -1.0, l, iia)
            _apply_angular(qd, bb, 1.0, l, iib)


@njit(cache=True)
def _anchor_motion(dp, dtheta, b, r):
    """Displacement of the anchor at offset r since prepare, linearised in the rotation:
    dp + dtheta x r. It is exact for a rolling sphere (its surface point under the centre does not
    move along n) and first-order for corners; rotating the anchor instead would lift a rolling ball
    off the ground by r (1 - cos(w dt))."""
    if b < 0:
        return (0.0, 0.0, 0.0)
    d = (dp[b, 0], dp[b, 1], dp[b, 2])
    th = (dtheta[b, 0], dtheta[b, 1], dtheta[b, 2])
    return add(d, cross(th, r))


@njit(cache=True)
def _solve_block(items, lo, hi, use_bias, inv_h, push_max, qd, dp, dtheta, inv_mass, inv_inertia,
                 cons_manifold, contact_body, contact_point_count, contact_normal, contact_tangent,
                 contact_friction, contact_rolling_friction, normal_impulse, tangent_impulse, rolling_impulse,
                 max_normal_impulse, total_normal_impulse, relative_velocity, cons_anchor, cons_base_separation,
                 cons_normal_mass, cons_tangent_mass, cons_rolling_mass, cons_soft, cons_twist):
    for t in range(lo, hi):
        c = items[t]
        i = cons_manifold[c]
        ba, bb = contact_body[i, 0], contact_body[i, 1]
        ima, imb = _inv_m(inv_mass, ba), _inv_m(inv_mass, bb)
        iia, iib = _inv_i(inv_inertia, ba), _inv_i(inv_inertia, bb)
        n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
        t1 = (contact_tangent[i, 0, 0], contact_tangent[i, 0, 1], contact_tangent[i, 0, 2])
        t2 = (contact_tangent[i, 1, 0], contact_tangent[i, 1, 1], contact_tangent[i, 1, 2])
        bias_rate, soft_mass, soft_imp = cons_soft[c, 0], cons_soft[c, 1], cons_soft[c, 2]
        npts = contact_point_count[i]
        total_normal = 0.0
        # -- non-penetration
        for k in range(npts):
            ra = (cons_anchor[c, k, 0, 0], cons_anchor[c, k, 0, 1], cons_anchor[c, k, 0, 2])
            rb = (cons_anchor[c, k, 1, 0], cons_anchor[c, k, 1, 1], cons_anchor[c, k, 1, 2])
            # current gap: detected gap plus the relative motion of the anchors since detection
            s = dot(n, sub(_anchor_motion(dp, dtheta, bb, rb), _anchor_motion(dp, dtheta, ba, ra))) \
                + cons_base_separation[c, k]
            bias, mscale, iscale = 0.0, 1.0, 0.0
            if s > 0.0:
                bias = s * inv_h                 # speculative: close the gap, no further
            elif use_bias:
                bias = max(bias_rate * s, -push_max)
                mscale, iscale = soft_mass, soft_imp
            va, wa = _vel(qd, ba)
            vb, wb = _vel(qd, bb)
            vn = dot(sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra))), n)
            if vn + max(s, 0.0) * inv_h < 0.0 and vn < relative_velocity[i, k]:
                # approach speed at impact (for restitution): the fastest approach of any pass in
                # which the contact acts, so the speed gained within the step and the speed a
                # speculative contact is about to remove both count
                relative_velocity[i, k] = vn
            old = normal_impulse[i, k]
            lam = -cons_normal_mass[c, k] * mscale * (vn + bias) - iscale * old
            new = max(old + lam, 0.0)
            lam = new - old
            normal_impulse[i, k] = new
            if new > max_normal_impulse[i, k]:
                max_normal_impulse[i, k] = new
            if not use_bias:
                # relax is the substep's last pass: its accumulated impulse is what the substep applied
                total_normal_impulse[i, k] += new
            total_normal += new
            p = scale(n, lam)
            _apply(qd, ba, -1.0, p, ra, ima, iia)
            _apply(qd, bb, 1.0, p, rb, imb, iib)
        # -- Coulomb friction, circular cone at each point
        mu = contact_friction[i]
        for k in range(npts):
            o1 = tangent_impulse[i, k, 0]
            o2 = tangent_impulse[i, k, 1]
            if normal_impulse[i, k] == 0.0 and o1 == 0.0 and o2 == 0.0:
                continue                     # a speculative point: the cone is a point, nothing changes
            ra = (cons_anchor[c, k, 0, 0], cons_anchor[c, k, 0, 1], cons_anchor[c, k, 0, 2])
            rb = (cons_anchor[c, k, 1, 0], cons_anchor[c, k, 1, 1], cons_anchor[c, k, 1, 2])
            va, wa = _vel(qd, ba)
            vb, wb = _vel(qd, bb)
            dv = sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra)))
            n1 = o1 - cons_tangent_mass[c, k, 0] * dot(dv, t1)
            n2 = o2 - cons_tangent_mass[c, k, 1] * dot(dv, t2)
            lim = mu * normal_impulse[i, k]
            mag = math.sqrt(n1 * n1 + n2 * n2)
            if mag > lim:
                f = lim / mag
                n1 *= f
                n2 *= f
            tangent_impulse[i, k, 0] = n1
            tangent_impulse[i, k, 1] = n2
            p = add(scale(t1, n1 - o1), scale(t2, n2 - o2))
            _apply(qd, ba, -1.0, p, ra, ima, iia)
            _apply(qd, bb, 1.0, p, rb, imb, iib)
        # -- twisting friction: |impulse about n| <= friction * twist_radius * total normal impulse
        tlim = cons_twist[c, 2] * total_normal
        if cons_twist[c, 0] > 0.0 and (tlim > 0.0 or cons_twist[c, 1] != 0.0):
            va, wa = _vel(qd, ba)
            vb, wb = _vel(qd, bb)
            old = cons_twist[c, 1]
            new = old - cons_twist[c, 0] * dot(sub(wb, wa), n)
            new = min(max(new, -tlim), tlim)
            cons_twist[c, 1] = new
            l = scale(n, new - old)
            _apply_angular(qd, ba, -1.0, l, iia)
            _apply_angular(qd, bb, 1.0, l, iib)
        # -- rolling resistance: |angular impulse| <= rolling_friction * total normal impulse
        rr = contact_rolling_friction[i]
        if rr > 0.0:
            va, wa = _vel(qd, ba)
            vb, wb = _vel(qd, bb)
            dw = sub(wb, wa)
            dw = sub(dw, scale(n, dot(dw, n)))           # rolling only: spin about n is twisting friction's
            rm = (cons_rolling_mass[c, 0], cons_rolling_mass[c, 1], cons_rolling_mass[c, 2],
                  cons_rolling_mass[c, 3], cons_rolling_mass[c, 4], cons_rolling_mass[c, 5],
                  cons_rolling_mass[c, 6], cons_rolling_mass[c, 7], cons_rolling_mass[c, 8])
            d = mat_vec(rm, dw)
            d = sub(d, scale(n, dot(d, n)))
            old3 = (rolling_impulse[i, 0], rolling_impulse[i, 1], rolling_impulse[i, 2])
            new3 = sub(old3, d)
            lim = rr * total_normal
            mag = math.sqrt(dot(new3, new3))
            if mag > lim:
                new3 = scale(new3, lim / mag)
            for m in range(3):
                rolling_impulse[i, m] = new3[m]
            l = sub(new3, old3)
            _apply_angular(qd, ba, -1.0, l, iia)
            _apply_angular(qd, bb, 1.0, l, iib)


@njit(cache=True)
def _restitution_block(items, lo, hi, threshold, qd, inv_mass, inv_inertia, cons_manifold, contact_body,
                       contact_point_count, contact_normal, contact_restitution, normal_impulse,
                       max_normal_impulse, total_normal_impulse, relative_velocity, cons_anchor, cons_normal_mass):
    for t in range(lo, hi):
        c = items[t]
        i = cons_manifold[c]
        e = contact_restitution[i]
        if e == 0.0:
            continue
        ba, bb = contact_body[i, 0], contact_body[i, 1]
        ima, imb = _inv_m(inv_mass, ba), _inv_m(inv_mass, bb)
        iia, iib = _inv_i(inv_inertia, ba), _inv_i(inv_inertia, bb)
        n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
        for k in range(contact_point_count[i]):
            vrel = relative_velocity[i, k]
            if vrel > -threshold or max_normal_impulse[i, k] == 0.0:
                continue
            ra = (cons_anchor[c, k, 0, 0], cons_anchor[c, k, 0, 1], cons_anchor[c, k, 0, 2])
            rb = (cons_anchor[c, k, 1, 0], cons_anchor[c, k, 1, 1], cons_anchor[c, k, 1, 2])
            va, wa = _vel(qd, ba)
            vb, wb = _vel(qd, bb)
            vn = dot(sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra))), n)
            old = normal_impulse[i, k]
            # drive the normal velocity to -e times the approach velocity
            lam = -cons_normal_mass[c, k] * (vn + e * vrel)
            new = max(old + lam, 0.0)
            lam = new - old
            normal_impulse[i, k] = new
            total_normal_impulse[i, k] += lam
            if new > max_normal_impulse[i, k]:
                max_normal_impulse[i, k] = new
            p = scale(n, lam)
            _apply(qd, ba, -1.0, p, ra, ima, iia)
            _apply(qd, bb, 1.0, p, rb, imb, iib)


@njit(cache=True)
def _acceleration(inv_mass, gravity, force, b):
    """Linear acceleration gravity + F/m of a body the solver moves (0 for static, kinematic, asleep)."""
    if b < 0 or inv_mass[b] == 0.0:
        return (0.0, 0.0, 0.0)
    im = inv_mass[b]
    return (gravity[0] + im * force[b, 0], gravity[1] + im * force[b, 1], gravity[2] + im * force[b, 2])


@njit(cache=True)
def _impact_time(gap, vn, an, horizon):
    """First time t in [0, horizon] at which gap + vn t + an t^2 / 2 reaches 0 (0 for a closed gap);
    -1 when it stays open over the horizon."""
    if gap <= 0.0:
        return 0.0
    disc = vn * vn - 2.0 * an * gap
    if disc < 0.0:
        return -1.0
    den = math.sqrt(disc) - vn          # the smaller root 2 gap / (-vn + sqrt(disc)), free of cancellation
    if den <= 0.0:
        return -1.0
    t = 2.0 * gap / den
    return t if t <= horizon else -1.0


@njit(cache=True)
def _shift_back(body_q, dp, dtheta, b, dv, dw, t):
    """Move body b by -t times its velocity change (dv, dw): the pose it has at the start of the step on the
    trajectory that leaves the impact at time t with the new velocity."""
    for k in range(3):
        body_q[b, k] -= t * dv[k]
        dp[b, k] -= t * dv[k]
        dtheta[b, k] -= t * dw[k]
    _rotate_body(body_q, b, -dw[0], -dw[1], -dw[2], t)


@njit(cache=True)
def _collide_block(n_cons, dt, h, threshold, iterations, gravity, force, body_q, dp, dtheta, impact_time, qd,
                   inv_mass, inv_inertia, cons_manifold, contact_body, contact_point_count, contact_normal,
                   contact_restitution, total_normal_impulse, relative_velocity, cons_anchor, cons_base_separation,
                   cons_normal_mass):
    horizon = dt + h
    for b in range(impact_time.shape[0]):
        impact_time[b] = 0.0
    passes = 0
    for it in range(iterations):
        applied = False
        for c in range(n_cons):
            i = cons_manifold[c]
            e = contact_restitution[i]
            if e == 0.0:
                continue
            ba, bb = contact_body[i, 0], contact_body[i, 1]
            ima, imb = _inv_m(inv_mass, ba), _inv_m(inv_mass, bb)
            iia, iib = _inv_i(inv_inertia, ba), _inv_i(inv_inertia, bb)
            n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
            an = dot(sub(_acceleration(inv_mass, gravity, force, bb), _acceleration(inv_mass, gravity, force, ba)), n)
            # the latest impact either body already took in this pass: a point touches no earlier
            tau = 0.0
            if ba >= 0 and ima > 0.0:
                tau = impact_time[ba]
            if bb >= 0 and imb > 0.0:
                tau = max(tau, impact_time[bb])
            for k in range(contact_point_count[i]):
                ra = (cons_anchor[c, k, 0, 0], cons_anchor[c, k, 0, 1], cons_anchor[c, k, 0, 2])
                rb = (cons_anchor[c, k, 1, 0], cons_anchor[c, k, 1, 1], cons_anchor[c, k, 1, 2])
                va, wa = _vel(qd, ba)
                vb, wb = _vel(qd, bb)
                # the stored velocity is the last substep's (symplectic Euler: half a substep back); the
                # motion the positions follow has vn + an h / 2 now
                vn = dot(sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra))), n) + 0.5 * an * h
                gap = 0.0
                if total_normal_impulse[i, k] > 0.0:
                    t = tau                      # bounced already in this pass: touching since then
                else:
                    gap = dot(n, sub(_anchor_motion(dp, dtheta, bb, rb), _anchor_motion(dp, dtheta, ba, ra))) \
                        + cons_base_separation[c, k]
                    t = _impact_time(gap, vn, an, horizon)
                    if t < 0.0:
                        continue
                    t = max(t, tau)
                v_impact = vn + an * t
                # approaching faster than the threshold at the impact
                if v_impact >= -threshold:
                    continue
                # leave the surface at te with -e v_impact: the normal velocity now becomes -e v_impact - an te.
                # te = t, and the bodies move back by te times their velocity change. An impact due in the
                # substep after the step leaves at the step's end instead (up to one substep early), the
                # bodies moved back so that the point is at the surface then: gap -> e v_impact te + an te^2 / 2
                te = min(t, dt)
                dvn = -e * v_impact - an * te - vn
                if dvn <= 0.0:
                    continue
                t_back = te if te == t else (gap - e * v_impact * te - 0.5 * an * te * te) / dvn
                lam = cons_normal_mass[c, k] * dvn     # -(1 + e) m_n v_impact when te = t
                total_normal_impulse[i, k] += lam
                # the bounce is done: the post-step pass must not bounce this point again
                relative_velocity[i, k] = 0.0
                p = scale(n, lam)
                if ba >= 0 and ima > 0.0:
                    dva, dwa = scale(p, -ima), scale(mat_vec(iia, cross(ra, p)), -1.0)
                    _apply(qd, ba, -1.0, p, ra, ima, iia)
                    _shift_back(body_q, dp, dtheta, ba, dva, dwa, t_back)
                    impact_time[ba] = max(impact_time[ba], te)
                if bb >= 0 and imb > 0.0:
                    dvb, dwb = scale(p, imb), mat_vec(iib, cross(rb, p))
                    _apply(qd, bb, 1.0, p, rb, imb, iib)
                    _shift_back(body_q, dp, dtheta, bb, dvb, dwb, t_back)
                    impact_time[bb] = max(impact_time[bb], te)
                # the contact's own gap reads as before the shifts (the solver must not push the separating
                # bodies apart over the virtual overlap); its other points and every other contact see them
                cons_base_separation[c, k] += dvn * t_back
                tau = max(tau, te)
                applied = True
        if not applied:
            break
        passes += 1
    return passes


def collide(ctx, n_cons, dt, h, threshold, iterations, gravity, force, impact_time):
    """Collision pass before the substeps (Guendelman, Bridson and Fedkiw 2003, section 5), with each bounce
    placed at its time of impact.

    Every point with restitution e > 0 whose gap closes within the step ``dt`` plus one substep ``h`` (the
    last relax pass would otherwise start to stop a speculative contact that closes early in the next step,
    and the bounce would lose that speed) at a time t, and approaches faster than ``threshold`` then, gets
    the two-body impulse ``-(1 + e) m_n v_n(t)``. The time and the speed at impact follow the point's motion
    with the bodies' accelerations (``gravity`` + ``force`` / m, (B, 3) world; ``h`` also turns the stored
    velocity, half a substep back, into the current one): gap + v_n t + a_n t^2 / 2 = 0. Each body then moves
    back by t times its velocity change (linear and angular), so from the start of the step on it follows
    the trajectory that left the impact at t with the new velocity: the rebound has e^2 times the impact's
    energy and starts at the surface, independent of the step. An impact due after the end of the step
    leaves the surface at the end of the step instead (no overlap; at most one substep early). A point of a body that
    already bounced in this pass touches no earlier than that bounce (``impact_time (B,)`` scratch, per
    body), so a touching chain (Newton's cradle) hands the impact on ball by ball at the right times.
    Passes repeat (up to ``iterations``) until no point approaches; momentum is conserved exactly, and
    energy at e = 1. Serial: a few restitution contacts per step. Returns the number of passes that
    applied an impulse."""
    return _collide_block(n_cons, dt, h, threshold, iterations, gravity, force, ctx.body_q, ctx.body_dp,
                          ctx.body_dtheta, impact_time, ctx.body_qd, ctx.body_inv_mass,
                          ctx.body_inv_inertia_world, ctx.cons_manifold, ctx.contact_body, ctx.contact_point_count,
                          ctx.contact_normal, ctx.contact_restitution, ctx.contact_total_normal_impulse,
                          ctx.contact_relative_velocity, ctx.cons_anchor, ctx.cons_base_separation,
                          ctx.cons_normal_mass)


@njit(cache=True)
def _warm_range(ctx, items, lo, hi):
    _warm_block(items, lo, hi, ctx.body_qd, ctx.body_inv_mass, ctx.body_inv_inertia_world, ctx.cons_manifold,
                ctx.contact_body, ctx.contact_point_count, ctx.contact_normal, ctx.contact_tangent,
                ctx.contact_normal_impulse, ctx.contact_tangent_impulse, ctx.contact_rolling_impulse,
                ctx.cons_anchor, ctx.cons_twist)


@njit(cache=True)
def _solve_range(ctx, items, lo, hi, use_bias, inv_h, push_max):
    _solve_block(items, lo, hi, use_bias, inv_h, push_max, ctx.body_qd, ctx.body_dp, ctx.body_dtheta,
                 ctx.body_inv_mass, ctx.body_inv_inertia_world, ctx.cons_manifold, ctx.contact_body,
                 ctx.contact_point_count, ctx.contact_normal, ctx.contact_tangent, ctx.contact_friction,
                 ctx.contact_rolling_friction, ctx.contact_normal_impulse, ctx.contact_tangent_impulse,
                 ctx.contact_rolling_impulse, ctx.contact_max_normal_impulse, ctx.contact_total_normal_impulse,
                 ctx.contact_relative_velocity, ctx.cons_anchor, ctx.cons_base_separation, ctx.cons_normal_mass,
                 ctx.cons_tangent_mass, ctx.cons_rolling_mass, ctx.cons_soft, ctx.cons_twist)


@njit(cache=True)
def _restitution_range(ctx, items, lo, hi, threshold):
    _restitution_block(items, lo, hi, threshold, ctx.body_qd, ctx.body_inv_mass, ctx.body_inv_inertia_world,
                       ctx.cons_manifold, ctx.contact_body, ctx.contact_point_count, ctx.contact_normal,
                       ctx.contact_restitution, ctx.contact_normal_impulse, ctx.contact_max_normal_impulse,
                       ctx.contact_total_normal_impulse, ctx.contact_relative_velocity, ctx.cons_anchor,
                       ctx.cons_normal_mass)



# Each colour is cut into at most CHUNKS contiguous runs; a parallel iteration solves one run through
# a single call (passing the context bundle costs a reference count per array, so once per run, not
# once per constraint). Runs of one colour touch disjoint bodies, so any split gives the same bits.
CHUNKS = 16


@njit(cache=True, parallel=True)
def warm_start(ctx, colour_start, colour_items):
    """Apply the accumulated impulses (colour by colour; the overflow colour serially)."""
    ncol = colour_start.shape[0] - 1
    for col in range(ncol - 1):
        lo, hi = colour_start[col], colour_start[col + 1]
        nch = min(hi - lo, CHUNKS)
        for ch in prange(nch):
            a = lo + (hi - lo) * ch // nch
            b = lo + (hi - lo) * (ch + 1) // nch
            _warm_range(ctx, colour_items, a, b)
    _warm_range(ctx, colour_items, colour_start[ncol - 1], colour_start[ncol])


@njit(cache=True, parallel=True)
def solve_contacts(ctx, colour_start, colour_items, use_bias, inv_h, push_max):
    """One soft-step iteration over every contact (with bias) or the relax iteration (without)."""
    ncol = colour_start.shape[0] - 1
    for col in range(ncol - 1):
        lo, hi = colour_start[col], colour_start[col + 1]
        nch = min(hi - lo, CHUNKS)
        for ch in prange(nch):
            a = lo + (hi - lo) * ch // nch
            b = lo + (hi - lo) * (ch + 1) // nch
            _solve_range(ctx, colour_items, a, b, use_bias, inv_h, push_max)
    _solve_range(ctx, colour_items, colour_start[ncol - 1], colour_start[ncol], use_bias, inv_h, push_max)


@njit(cache=True, parallel=True)
def restitution(ctx, colour_start, colour_items, threshold):
    """Restitution pass after the substeps."""
    ncol = colour_start.shape[0] - 1
    for col in range(ncol - 1):
        lo, hi = colour_start[col], colour_start[col + 1]
        nch = min(hi - lo, CHUNKS)
        for ch in prange(nch):
            a = lo + (hi - lo) * ch // nch
            b = lo + (hi - lo) * (ch + 1) // nch
            _restitution_range(ctx, colour_items, a, b, threshold)
    _restitution_range(ctx, colour_items, colour_start[ncol - 1], colour_start[ncol], threshold)


@njit(cache=True)
def colour_constraints(cons_manifold, n_cons, contact_body, body_inv_mass, body_mask, colour_of,
                       colour_start, colour_items):
    """Greedy colouring in constraint order: the lowest colour free at both dynamic endpoints
    (bitmask per body); overflow colour ``MAX_COLOURS`` when none is free. Then a counting sort
    (stable) into ``colour_items`` with CSR ``colour_start (MAX_COLOURS + 2,)``. Allocates nothing."""
    body_mask[:] = 0
    ncol = colour_start.shape[0] - 1
    for c in range(n_cons):
        i = cons_manifold[c]
        ba, bb = contact_body[i, 0], contact_body[i, 1]
        da = ba >= 0 and body_inv_mass[ba] > 0.0
        db = bb >= 0 and body_inv_mass[bb] > 0.0
        used = np.uint64(0)
        if da:
            used |= body_mask[ba]
        if db:
            used |= body_mask[bb]
        col = ncol - 1
        for k in range(ncol - 1):
            if (used >> np.uint64(k)) & np.uint64(1) == 0:
                col = k
                break
        colour_of[c] = col
        if col < ncol - 1:
            bit = np.uint64(1) << np.uint64(col)
            if da:
                body_mask[ba] |= bit
            if db:
                body_mask[bb] |= bit
    # counting sort without a fill array: colour_start[k + 1] first holds the start of colour k and
    # advances as its items are placed, ending at the start of colour k + 1 (the CSR offsets)
    colour_start[:] = 0
    for c in range(n_cons):
        colour_start[colour_of[c] + 1] += 1
    run = 0
    for k in range(ncol):
        cnt = colour_start[k + 1]
        colour_start[k + 1] = run
        run += cnt
    for c in range(n_cons):
        col = colour_of[c]
        colour_items[colour_start[col + 1]] = c
        colour_start[col + 1] += 1


@njit(cache=True)
def substeps_serial(ctx, colour_start, colour_items, substeps, h, push_max, body_type, body_awake, body_inv_mass,
                    body_inertia, body_inv_inertia, lin_damp, ang_damp, force, torque, gravity):
    """The substep loop of the module docstring in one call (serial): per substep integrate_velocities,
    warm_start, solve, integrate_positions, relax. The same code and order as the stage kernels'
    serial twins called one by one (colours in order, the overflow colour last, which is the order of
    ``colour_items``), so the bits are identical; one call instead of five per substep saves the
    unboxing of the context bundle (~30 arrays) at each call."""
    nb = ctx.body_q.shape[0]
    body_q, body_qd, body_dp, body_dtheta = ctx.body_q, ctx.body_qd, ctx.body_dp, ctx.body_dtheta
    n_items = colour_start[colour_start.shape[0] - 1]
    inv_h = 1.0 / h
    # use_bias as a runtime bool (True inside the loop): literal True / False arguments would compile the
    # solve block twice (Numba specialises on literals)
    use_bias = substeps > 0
    for _ in range(substeps):
        for b in range(nb):
            _integrate_velocity_one(b, body_type, body_awake, body_inv_mass, body_inertia, body_inv_inertia,
                                    lin_damp, ang_damp, force, torque, gravity, body_q, body_qd, h)
        _warm_range(ctx, colour_items, 0, n_items)
        _solve_range(ctx, colour_items, 0, n_items, use_bias, inv_h, push_max)
        for b in range(nb):
            _integrate_position_one(b, body_type, body_awake, body_q, body_qd, body_dp, body_dtheta, h)
        _solve_range(ctx, colour_items, 0, n_items, not use_bias, inv_h, push_max)


def serial_versions():
    """The serial twins of the parallel stage kernels (same code and order; prange runs as range)."""
    return dict(integrate_velocities=serial_twin(integrate_velocities),
                integrate_positions=serial_twin(integrate_positions),
                world_inverse_inertia=serial_twin(world_inverse_inertia),
                prepare_contacts=serial_twin(prepare_contacts),
                warm_start=serial_twin(warm_start), solve_contacts=serial_twin(solve_contacts),
                restitution=serial_twin(restitution))
