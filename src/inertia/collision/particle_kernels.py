"""Numba kernels of the particle collision stage (see ``particle_stage`` for the algorithm).

Colliders are passed packed (``ParticleCollisionData.pack``):

cint  (K, 4) int64    [kind, flags (MOVING 1; BODY_VELOCITY 2: a body row), cf offset, ci offset]
cnear (K, 5) float64  cheap distance lower bound for the "far from everything" test:
                      [NEAR_PLANE, n, c] | [NEAR_BALL, centre, bounding radius] |
                      [NEAR_PLANES, cf offset, plane count, -, -] | [NEAR_ALWAYS] | [NEAR_NEVER]
cmat  (K, 2) float64  [restitution, friction]
cf, ci                flat shape data (layouts in ``distance``)
pose0, pose1 (K, 18)  [p, R] of each collider at the start / end of the step; a body row's
                      pose1 also holds its body's velocity [w, v] (``body_qd``) in 12:18, and
                      its surface velocity is the material velocity v + w x (x - c) there
                      (``_body_velocity``); other moving colliders take the pose difference
ref   (K, 3)          rest reference point

Per-particle contact state (written by ``classify_contacts`` / ``collide_particles``, read by
the force filter and the next ``collide_particles``):

rest_k (N,) int64     collider the particle rests on, -1 if none
rest_n (N, 3)         its unit outward normal there (world)
rest_u (N, 3)         the collider's surface velocity there (world, m/s)
load   (N,)           normal load per unit mass the filter cancelled (m/s^2), last evaluation
static_ok (N,) bool   the applied tangential force is within the static friction cone

All kernels are pure functions: inputs, then outputs, then scalars, then ``kinds`` and
``motion``; nothing is allocated. ``kinds`` (``distance.kinds_token``) is the set of collider
kinds compiled in: Numba types it by which kinds are present, so each kind set is its own
signature and the distance, bound and time-of-impact code of absent kinds is not compiled
(``distance.sdf_in``, ``toi.segment_toi_in``). ``motion`` (``motion_token``) is None when every
collider is static: the rest-frame transforms and surface velocities of moving colliders are
then pruned before typing. Callers use ``kernels_for(cint)``, which binds both and picks the
serial twin or the parallel build by size (``inertia._jit``).
Particles are independent in ``collide_particles`` and ``step_and_collide`` (parallel,
deterministic: the only reductions are integer counts and a finite flag); the pair solver
processes colour batches (write-disjoint) in parallel.

The per-particle response (``_collide_near`` -> ``_resting_motion``, ``_full_path``) is shared
by the separate pass (``collide_particles``, after any integrator) and the fused one
(``step_and_collide``, inside rk4's and semi-implicit Euler's affine step); both give the same
bits. It reads the colliders only through ``cint``/``cnear``/``cmat``/``cf``/``ci`` and the
poses, so moving it onto a shared shape table means replacing ``_eval``/``segment_toi``
lookups, not the response.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from . import distance as _d
from .._jit import SizeDispatched
from . import broadphase as _bp
from .broadphase import MAX_COLORS
from .response import surface_response
from .toi import may_hit_in, path_fraction, segment_toi_in

NEAR_PLANE, NEAR_BALL, NEAR_PLANES, NEAR_ALWAYS, NEAR_NEVER = 0.0, 1.0, 2.0, 3.0, 4.0
#: Bits of ``cint[k, 1]``: the collider moves (pose0 -> pose1); its surface velocity is its
#: body's (``pose1[k, 12:18]`` = ``body_qd``, written by the world; see ``_body_velocity``)
MOVING, BODY_VELOCITY = 1, 2
#: Columns of the pose rows: [p (3), R (9)] and, for body rows, the body's [w (3), v (3)]
POSE_COLUMNS = 18

#: The decorator of the per-particle helpers of the response (``_collide_near``, ``_full_path``,
#: ``_resting_collider``, ``_eval``, the surface velocities, ``_clear_of_planes_and_spheres``):
#: compiled without Numba's reference counting (``_nrt=False``). They only read and write the
#: arrays their caller holds and allocate nothing, so the counts are pure overhead: with them, every
#: call increments and decrements the count of each array argument (atomic operations, and the
#: collider tables' counts are shared by the threads), which Numba's pruning leaves in place around
#: calls that may raise. Measured on the near pass of the fused semi-implicit a_priori step (the
#: 7294 near particles of 1M in ``bench_collisions``, one thread, load 7): 0.94 -> 0.67 us per
#: particle, the same bits. Its callees in ``toi`` and ``distance`` still count.
_unrefcounted = njit(cache=True, _nrt=False)


@njit(cache=True, parallel=True)
def copy_into(src, dst):
    """dst[:] = src (1-D), in parallel."""
    for i in prange(src.shape[0]):
        dst[i] = src[i]


@_unrefcounted
def _eval(cint, cf, ci, pose, ref, k, x, y, z, kinds, motion):
    """Distance, world normal and rest point of collider k at world point (x, y, z) for `pose`."""
    lx, ly, lz = x, y, z
    if motion is not None:  # compiled only for scenes with moving colliders (``motion_token``)
        if cint[k, 1] & 1:
            lx, ly, lz = _d.to_rest(pose[k], ref[k], x, y, z)
    d, gx, gy, gz = _d.sdf_in(kinds, cint[k, 0], cf, cint[k, 2], ci, cint[k, 3], lx, ly, lz)
    if motion is not None:
        if cint[k, 1] & 1:
            gx, gy, gz = _d.rotate(pose[k], gx, gy, gz)
    return d, gx, gy, gz, lx, ly, lz


@_unrefcounted
def _body_velocity(pose1, ref, k, lx, ly, lz):
    """Material velocity v + w x (x - c) at rest point l of a body row (``BODY_VELOCITY``): the
    body's angular and linear velocity ``pose1[k, 12:18]`` (``body_qd`` after the rigid step) and
    the lever arm x - c = R (l - ref) at the substep's end (pose1, whose position is the centre
    of mass)."""
    rx, ry, rz = _d.rotate(pose1[k], lx - ref[k, 0], ly - ref[k, 1], lz - ref[k, 2])
    wx, wy, wz = pose1[k, 12], pose1[k, 13], pose1[k, 14]
    return (pose1[k, 15] + wy * rz - wz * ry, pose1[k, 16] + wz * rx - wx * rz,
            pose1[k, 17] + wx * ry - wy * rx)


@_unrefcounted
def _surface_velocity(cint, pose0, pose1, ref, k, lx, ly, lz, inv_dt, motion):
    """Velocity of the collider material at rest point l: a body row's material velocity
    (``_body_velocity``), or the average over the step from the pose difference (moving
    colliders driven by a motion)."""
    if motion is None:
        return 0.0, 0.0, 0.0
    if not (cint[k, 1] & MOVING):
        return 0.0, 0.0, 0.0
    if cint[k, 1] & BODY_VELOCITY:
        return _body_velocity(pose1, ref, k, lx, ly, lz)
    ax, ay, az = _d.to_world(pose0[k], ref[k], lx, ly, lz)
    bx, by, bz = _d.to_world(pose1[k], ref[k], lx, ly, lz)
    return (bx - ax) * inv_dt, (by - ay) * inv_dt, (bz - az) * inv_dt


@_unrefcounted
def _resting_collider(i, x, y, z, vx, vy, vz, r, cint, cf, ci, pose_at, pose0, pose1, ref, inv_dt, tol,
                      rest_speed, keep, near, rest_n, rest_u, kinds, motion):
    """The collider particle i rests on (-1 if none): within tol of its surface and not moving along
    its normal; `keep` wins ties, `near` is a bitmask of the colliders to consider (-1: all).
    Writes that contact's normal and surface velocity into rest_n[i], rest_u[i]."""
    kbest = -1
    for k in range(cint.shape[0]):
        if cint[k, 0] == _d.CALLABLE or not (near >> min(k, 62)) & 1:
            continue
        d, nx, ny, nz, lx, ly, lz = _eval(cint, cf, ci, pose_at, ref, k, x, y, z, kinds, motion)
        if d - r > tol:
            continue
        ux, uy, uz = _surface_velocity(cint, pose0, pose1, ref, k, lx, ly, lz, inv_dt, motion)
        wn = (vx - ux) * nx + (vy - uy) * ny + (vz - uz) * nz
        if abs(wn) > rest_speed:
            continue
        if kbest < 0 or k == keep:
            kbest = k
            rest_n[i, 0], rest_n[i, 1], rest_n[i, 2] = nx, ny, nz
            rest_u[i, 0], rest_u[i, 1], rest_u[i, 2] = ux, uy, uz
    return kbest


@njit(cache=True)
def _classify_one(i, x, y, z, vx, vy, vz, r, cint, cf, ci, pose_at, pose0, pose1, ref, inv_dt, tol,
                  rest_speed, keep, rest_k, rest_n, rest_u, kinds, motion):
    every = cint.shape[0] * 0 - 1  # all colliders, as an int64 (a literal -1 is another signature)
    rest_k[i] = _resting_collider(i, x, y, z, vx, vy, vz, r, cint, cf, ci, pose_at, pose0, pose1, ref,
                                  inv_dt, tol, rest_speed, keep, every, rest_n, rest_u, kinds, motion)


@njit(cache=True, parallel=True)
def classify_contacts(x, v, radius, inv_mass, active, cint, cf, ci, pose_at, pose0, pose1, ref,
                      rest_k, rest_n, rest_u, dt, tol, rest_speed, kinds, motion):
    """Resting-contact state of every particle at positions x (colliders at ``pose_at``).
    Returns the number of resting particles."""
    n, dim = x.shape
    inv_dt = 1.0 / dt
    resting = 0
    for i in prange(n):
        if not active[i] or inv_mass[i] == 0.0:
            rest_k[i] = -1
            continue
        z = x[i, 2] if dim == 3 else 0.0
        vz = v[i, 2] if dim == 3 else 0.0
        _classify_one(i, x[i, 0], x[i, 1], z, v[i, 0], v[i, 1], vz, radius[i], cint, cf, ci,
                      pose_at, pose0, pose1, ref, inv_dt, tol, rest_speed, rest_k[i], rest_k, rest_n,
                      rest_u, kinds, motion)
        if rest_k[i] >= 0:
            resting += 1
    return resting


@njit(cache=True, parallel=True)
def push_out(x, v, radius, inv_mass, active, cint, cf, ci, pose, ref, tol, inside_count, kinds, motion):
    """Project particles that lie inside a collider onto its surface and remove their inward
    normal velocity (relative to a static surface). inside_count (K,) int64 receives, per
    collider, how many particles were inside it. Returns the number of particles moved."""
    n, dim = x.shape
    moved = 0
    for k in range(cint.shape[0]):
        if cint[k, 0] == _d.CALLABLE:
            inside_count[k] = 0
            continue
        count = 0
        for i in prange(n):
            if not active[i] or inv_mass[i] == 0.0:
                continue
            z = x[i, 2] if dim == 3 else 0.0
            d, nx, ny, nz, lx, ly, lz = _eval(cint, cf, ci, pose, ref, k, x[i, 0], x[i, 1], z, kinds, motion)
            f = d - radius[i]
            if f >= -tol:
                continue
            count += 1
            x[i, 0] -= f * nx
            x[i, 1] -= f * ny
            vn = v[i, 0] * nx + v[i, 1] * ny
            if dim == 3:
                x[i, 2] -= f * nz
                vn += v[i, 2] * nz
            if vn < 0.0:
                v[i, 0] -= vn * nx
                v[i, 1] -= vn * ny
                if dim == 3:
                    v[i, 2] -= vn * nz
        inside_count[k] = count
        moved += count
    return moved


@njit(cache=True)
def _resting_motion(x0x, x0y, x0z, v0x, v0y, v0z, ax, ay, az, nx, ny, nz, ux, uy, uz, mu, dt,
                    rest_speed):
    """End of step (x, v) of a particle resting on a surface when the force filter did not run
    (a fused integrator step): the same physics applied to the step's average acceleration a.

    Relative to the surface (velocity u): the normal part of a pushing in is cancelled (load
    -a.N); at rest, static friction holds while |a_T| <= mu load, else the particle starts to
    slide with a_T (1 - mu load / |a_T|); sliding, kinetic friction mu load opposes the sliding
    direction, and if it stops the particle within the step it stays (static) or restarts.
    Constant acceleration over the step: x = x0 + (u + w0) t + a_c t^2 / 2 (exact for constant
    forces, like the filter with any Runge-Kutta method).
    """
    an = ax * nx + ay * ny + az * nz  # < 0: the caller checked that a pushes into the surface
    # no motion into the surface at the start
    wx, wy, wz = v0x - ux, v0y - uy, v0z - uz
    wn = wx * nx + wy * ny + wz * nz
    if wn < 0.0:
        wx, wy, wz = wx - wn * nx, wy - wn * ny, wz - wn * nz
        wn = 0.0
    # F' = F_T: cancel the push into the surface
    tax, tay, taz = ax - an * nx, ay - an * ny, az - an * nz
    load = -an
    limit = mu * load
    at = math.sqrt(tax * tax + tay * tay + taz * taz)
    tx, ty, tz = wx - wn * nx, wy - wn * ny, wz - wn * nz
    speed = math.sqrt(tx * tx + ty * ty + tz * tz)
    px = py = pz = 0.0  # displacement relative to the surface
    rem = dt
    if speed > rest_speed:
        # kinetic friction against the sliding direction
        dx, dy, dz = tx / speed, ty / speed, tz / speed
        cx, cy, cz = tax - limit * dx, tay - limit * dy, taz - limit * dz
        decel = -(cx * dx + cy * dy + cz * dz)
        tau = dt
        if decel > 0.0 and speed < decel * dt:
            tau = speed / decel  # friction stops the sliding at tau
        px, py, pz = wx * tau + 0.5 * cx * tau * tau, wy * tau + 0.5 * cy * tau * tau, wz * tau + 0.5 * cz * tau * tau
        wx, wy, wz = wx + cx * tau, wy + cy * tau, wz + cz * tau
        rem = dt - tau
        if rem > 0.0:
            # stopped: drop the residual tangential velocity
            wn = wx * nx + wy * ny + wz * nz
            wx, wy, wz = wn * nx, wn * ny, wn * nz
    if rem > 0.0:
        if at <= limit:
            cx = cy = cz = 0.0       # static friction holds
            wx, wy, wz = wn * nx, wn * ny, wn * nz
        else:
            s = 1.0 - limit / at    # starts to slide along a_T
            cx, cy, cz = s * tax, s * tay, s * taz
        px += wx * rem + 0.5 * cx * rem * rem
        py += wy * rem + 0.5 * cy * rem * rem
        pz += wz * rem + 0.5 * cz * rem * rem
        wx, wy, wz = wx + cx * rem, wy + cy * rem, wz + cz * rem
    return (x0x + ux * dt + px, x0y + uy * dt + py, x0z + uz * dt + pz, ux + wx, uy + wy, uz + wz)


@_unrefcounted
def _full_path(i, radius, cint, cmat, cf, ci, pose0, pose1, ref, rest_k, rest_n, rest_u, load,
               static_ok, near, kr, sx, sy, sz, svx, svy, svz, ex, ey, ez, evx, evy, evz, ax, ay, az,
               dt, tol, rest_speed, a_priori, max_sub, max_iter, classify, unfiltered, resting_done,
               started, kinds, motion):
    """Steps 1-4 of ``collide_particles`` for one particle near a collider (kept out of the hot
    loop so that the far-from-everything path stays small). Returns the final (x, v), whether
    anything changed and whether the particle rests afterwards.

    The path of the step (see ``toi``): the parabola with the step's average acceleration a
    through the integrator's start and end points, p(t) = s + w t + a t^2 / 2 with slope
    w = (e - s) / h - a h / 2 at the start. The integrator's stored velocity differs from the
    slope by ``lag = v0 - w`` (0 for the second-order methods and rk4 under constant forces,
    -a h / 2 for symplectic and implicit Euler, a h / 2 for explicit Euler); responses act on the
    path's velocity, and the lag is added back to the velocity handed to the next step, so a
    bounce continues the integrator's own trajectory (apex heights do not drift with the method).
    """
    ncol = cint.shape[0]
    inv_dt = 1.0 / dt
    r = radius[i]
    modified = resting_done
    # the integrator's lag behind its path (zero for a particle without a path this step)
    lagx = lagy = lagz = 0.0
    if started:
        lagx = svx - ((ex - sx) * inv_dt - 0.5 * ax * dt)
        lagy = svy - ((ey - sy) * inv_dt - 0.5 * ay * dt)
        lagz = svz - ((ez - sz) * inv_dt - 0.5 * az * dt)
    # 1. resting contact (unless the caller applied the resting motion already)
    if kr >= 0 and not resting_done:
        nx, ny, nz = rest_n[i, 0], rest_n[i, 1], rest_n[i, 2]
        ux, uy, uz = rest_u[i, 0], rest_u[i, 1], rest_u[i, 2]
        body = False
        if motion is not None:  # a body row: its material velocity (``_body_velocity``)
            body = (cint[kr, 1] & BODY_VELOCITY) != 0
        fused_rest = False
        if unfiltered is not None:  # compiled in only where the force filter may not have run
            fused_rest = ax * nx + ay * ny + az * nz < 0.0
        if fused_rest:
            if body:
                # carried by the material point under the particle at the start: its displacement
                # over the step (pose0 -> pose1), so that rotation keeps the distance to the axis
                lx, ly, lz = _d.to_rest(pose0[kr], ref[kr], sx, sy, sz)
                px0, py0, pz0 = _d.to_world(pose0[kr], ref[kr], lx, ly, lz)
                px1, py1, pz1 = _d.to_world(pose1[kr], ref[kr], lx, ly, lz)
                ux, uy, uz = (px1 - px0) * inv_dt, (py1 - py0) * inv_dt, (pz1 - pz0) * inv_dt
            ex, ey, ez, evx, evy, evz = _resting_motion(sx, sy, sz, svx, svy, svz, ax, ay, az, nx, ny, nz,
                                                        ux, uy, uz, cmat[kr, 1], dt, rest_speed)
            if body:
                # the end velocity: the body's material velocity where the particle ends, plus
                # the particle's own velocity relative to the surface
                lx, ly, lz = _d.to_rest(pose1[kr], ref[kr], ex, ey, ez)
                bx, by, bz = _body_velocity(pose1, ref, kr, lx, ly, lz)
                evx, evy, evz = evx - ux + bx, evy - uy + by, evz - uz + bz
            ax, ay, az = (evx - svx) * inv_dt, (evy - svy) * inv_dt, (evz - svz) * inv_dt
            modified = True
            lagx = lagy = lagz = 0.0  # the resting motion is its own path
        else:
            if body:
                # a body carries the particle at its material velocity where the particle ends
                lx, ly, lz = _d.to_rest(pose1[kr], ref[kr], ex, ey, ez)
                ux, uy, uz = _body_velocity(pose1, ref, kr, lx, ly, lz)
            wx, wy, wz = evx - ux, evy - uy, evz - uz
            wn = wx * nx + wy * ny + wz * nz
            tx, ty, tz = wx - wn * nx, wy - wn * ny, wz - wn * nz
            tl = math.sqrt(tx * tx + ty * ty + tz * tz)
            stop = static_ok[i] and tl > 0.0 and tl <= cmat[kr, 1] * load[i] * dt + rest_speed
            if wn < 0.0 or stop:
                if stop:
                    tx = ty = tz = 0.0
                wn = max(wn, 0.0)
                evx, evy, evz = ux + tx + wn * nx, uy + ty + wn * ny, uz + tz + wn * nz
                modified = True
            # a held contact: no lag along its normal
            ln = lagx * nx + lagy * ny + lagz * nz
            lagx, lagy, lagz = lagx - ln * nx, lagy - ln * ny, lagz - ln * nz
    elif resting_done:
        lagx = lagy = lagz = 0.0

    # the path's velocity at the segment start (w) and at the end (p)
    wsx, wsy, wsz = svx - lagx, svy - lagy, svz - lagz
    pvx, pvy, pvz = evx - lagx, evy - lagy, evz - lagz

    # 2. continuous detection: the chord finds the contact, the parabolic path its time
    s_start = 0.0
    if a_priori:
        for _ in range(max_sub):
            best = 2.0
            bk = -1
            bsig = 0.0
            bgx = bgy = bgz = 0.0
            blsx = blsy = blsz = blex = bley = blez = 0.0
            span = (1.0 - s_start) * dt  # H: the rest of the step
            for k in range(ncol):
                kind = cint[k, 0]
                if kind == _d.CALLABLE or not (near >> min(k, 62)) & 1:
                    continue
                o, io = cint[k, 2], cint[k, 3]
                lsx, lsy, lsz, lex, ley, lez = sx, sy, sz, ex, ey, ez
                if motion is not None:  # moving colliders (compiled only when a scene has them)
                    if cint[k, 1] & 1:
                        # rest frame: start through the pose at s_start (interpolated), end at 1
                        a0x, a0y, a0z = _d.to_rest(pose0[k], ref[k], sx, sy, sz)
                        a1x, a1y, a1z = _d.to_rest(pose1[k], ref[k], sx, sy, sz)
                        lsx = a0x + s_start * (a1x - a0x)
                        lsy = a0y + s_start * (a1y - a0y)
                        lsz = a0z + s_start * (a1z - a0z)
                        lex, ley, lez = _d.to_rest(pose1[k], ref[k], ex, ey, ez)
                if not may_hit_in(kinds, kind, cf, o, ci, io, lsx, lsy, lsz, lex, ley, lez, r, tol):
                    continue
                hit, sig, gx, gy, gz = segment_toi_in(kinds, kind, cf, o, ci, io, lsx, lsy, lsz, lex, ley,
                                                   lez, r, tol, max_iter)
                if hit:
                    # chord fraction -> time fraction on the path (tangent plane at the hit)
                    wnx, wny, wnz = gx, gy, gz
                    if motion is not None:
                        if cint[k, 1] & 1:
                            wnx, wny, wnz = _d.rotate(pose0[k], gx, gy, gz)
                    chord_in = gx * (lex - lsx) + gy * (ley - lsy) + gz * (lez - lsz)
                    accel_in = 0.5 * (wnx * ax + wny * ay + wnz * az) * span * span
                    tau = path_fraction(chord_in, accel_in, sig)
                    s_abs = s_start + tau * (1.0 - s_start)
                    if s_abs < best:
                        best, bk, bsig, bgx, bgy, bgz = s_abs, k, sig, gx, gy, gz
                        blsx, blsy, blsz, blex, bley, blez = lsx, lsy, lsz, lex, ley, lez
            if bk < 0:
                break
            # time of impact from the segment start, the contact on the path and its velocity
            t_hit = (best - s_start) * dt
            cx = sx + wsx * t_hit + 0.5 * ax * t_hit * t_hit
            cy = sy + wsy * t_hit + 0.5 * ay * t_hit * t_hit
            cz = sz + wsz * t_hit + 0.5 * az * t_hit * t_hit
            cvx, cvy, cvz = wsx + t_hit * ax, wsy + t_hit * ay, wsz + t_hit * az
            # normal and surface velocity at the chord's contact point (rest frame -> world)
            lcx = blsx + bsig * (blex - blsx)
            lcy = blsy + bsig * (bley - blsy)
            lcz = blsz + bsig * (blez - blsz)
            ux = uy = uz = 0.0
            nx, ny, nz = bgx, bgy, bgz
            if motion is not None:
                if cint[bk, 1] & 1:
                    ux, uy, uz = _surface_velocity(cint, pose0, pose1, ref, bk, lcx, lcy, lcz, inv_dt, motion)
                    n0x, n0y, n0z = _d.rotate(pose0[bk], bgx, bgy, bgz)
                    n1x, n1y, n1z = _d.rotate(pose1[bk], bgx, bgy, bgz)
                    nx, ny, nz = n0x + best * (n1x - n0x), n0y + best * (n1y - n0y), n0z + best * (n1z - n0z)
                    nl = math.sqrt(nx * nx + ny * ny + nz * nz)
                    nx, ny, nz = nx / nl, ny / nl, nz / nl
            an = ax * nx + ay * ny + az * nz
            threshold = 2.0 * max(0.0, -an) * dt + rest_speed
            # a slow impact is inelastic and the contact holds the particle: the acceleration
            # into the surface and the integrator's lag along the normal are cancelled for the
            # rest of the step. A real bounce keeps both (it leaves under gravity).
            held = an < 0.0 and -((cvx - ux) * nx + (cvy - uy) * ny + (cvz - uz) * nz) <= threshold
            cvx, cvy, cvz, _hit = surface_response(cvx, cvy, cvz, ux, uy, uz, nx, ny, nz,
                                                   cmat[bk, 0], cmat[bk, 1], threshold)
            if held:
                ax, ay, az = ax - an * nx, ay - an * ny, az - an * nz
                ln = lagx * nx + lagy * ny + lagz * nz
                lagx, lagy, lagz = lagx - ln * nx, lagy - ln * ny, lagz - ln * nz
            # finish the step from the contact on the path: x = xc + v rem + a rem^2 / 2
            rem = (1.0 - best) * dt
            ex = cx + rem * cvx + 0.5 * rem * rem * ax
            ey = cy + rem * cvy + 0.5 * rem * rem * ay
            ez = cz + rem * cvz + 0.5 * rem * rem * az
            pvx, pvy, pvz = cvx + rem * ax, cvy + rem * ay, cvz + rem * az
            sx, sy, sz, wsx, wsy, wsz = cx, cy, cz, cvx, cvy, cvz
            s_start = best
            modified = True
            near = -1  # the path changed: every collider is a candidate now

    if modified:
        near = -1
    # 3. end-of-step projection (the a-posteriori response; a safety net a priori)
    span = (1.0 - s_start) * dt
    for _ in range(3):
        pushed = False
        for k in range(ncol):
            if cint[k, 0] == _d.CALLABLE or not (near >> min(k, 62)) & 1:
                continue
            d, nx, ny, nz, lx, ly, lz = _eval(cint, cf, ci, pose1, ref, k, ex, ey, ez, kinds, motion)
            f = d - r
            if f >= tol:
                continue
            # Witkin & Baraff: (X - P).N < eps and N.V < 0 (relative to the surface)
            ux, uy, uz = _surface_velocity(cint, pose0, pose1, ref, k, lx, ly, lz, inv_dt, motion)
            heading_in = (pvx - ux) * nx + (pvy - uy) * ny + (pvz - uz) * nz < 0.0
            deep = f < -tol or (f < 0.0 and k == kr)
            if not (deep or heading_in):
                continue
            if f < 0.0:
                ex, ey, ez = ex - f * nx, ey - f * ny, ez - f * nz
            if heading_in:
                an = ax * nx + ay * ny + az * nz
                cvx, cvy, cvz = pvx, pvy, pvz
                if not a_priori and an < 0.0 and f < 0.0 and span > 0.0:
                    # detected after the fact: the velocity the particle gained inside the
                    # collider is not kept. The impact time on the path from the signed
                    # distances at the segment's start and end; remove a_N (time inside).
                    fs = _eval(cint, cf, ci, pose0, ref, k, sx, sy, sz, kinds, motion)[0] - r
                    inside = span  # started inside: the whole step
                    if fs > 0.0:
                        tau = path_fraction(f - fs, 0.5 * an * span * span, fs / (fs - f))
                        inside = (1.0 - tau) * span
                    cvx, cvy, cvz = cvx - an * inside * nx, cvy - an * inside * ny, cvz - an * inside * nz
                threshold = 2.0 * max(0.0, -an) * dt + rest_speed
                held = an < 0.0 and -((cvx - ux) * nx + (cvy - uy) * ny + (cvz - uz) * nz) <= threshold
                pvx, pvy, pvz, _hit = surface_response(cvx, cvy, cvz, ux, uy, uz, nx, ny, nz,
                                                       cmat[k, 0], cmat[k, 1], threshold)
                if held:
                    ln = lagx * nx + lagy * ny + lagz * nz
                    lagx, lagy, lagz = lagx - ln * nx, lagy - ln * ny, lagz - ln * nz
            pushed = True
            modified = True
        if not pushed:
            break
        near = -1
    if modified:
        # the velocity handed to the next step: the path's plus the integrator's lag
        evx, evy, evz = pvx + lagx, pvy + lagy, pvz + lagz

    # 4. resting-contact state for the next step (only near colliders can hold it)
    if classify:
        kbest = _resting_collider(i, ex, ey, ez, evx, evy, evz, r, cint, cf, ci, pose1, pose0, pose1,
                                  ref, inv_dt, tol, rest_speed, kr, near, rest_n, rest_u, kinds, motion)
        if kbest != kr:
            rest_k[i] = kbest
        return ex, ey, ez, evx, evy, evz, modified, kbest >= 0
    return ex, ey, ez, evx, evy, evz, modified, False


@njit(cache=True, inline="always")
def _near_mask(cnear, cf, kr, r, tol, ex, ey, ez, dx, dy, dz):
    """Bit k set for each collider k the step's path (displacement d, ending at e) may reach: a
    lower bound of its distance at the end point (exact for planes and containers, the bounding
    sphere otherwise) beyond r + 2 tol + |d| proves the path cannot reach the surface.

    Cheap bound first, in registers: |d|_1 >= |d| decides for every particle farther than
    r + 2 tol + |d|_1 without a square root; only the others compute |d| and apply the exact
    test (so the mask is the same bits as the exact test alone). This runs for every particle."""
    reach0 = r + 2.0 * tol
    l1 = abs(dx) + abs(dy) + abs(dz)  # >= the path's length
    length = -1.0  # the path's length, computed when the cheap bound does not decide
    near = cnear.shape[0] * 0  # an int64 variable (a literal 0 would type the callers twice)
    for k in range(cnear.shape[0]):
        kind = cnear[k, 0]
        if kind == NEAR_NEVER:
            continue
        if k < 62 and k != kr:
            if kind == NEAR_PLANE:
                f = cnear[k, 1] * ex + cnear[k, 2] * ey + cnear[k, 3] * ez - cnear[k, 4]
                if f - reach0 > l1:
                    continue
                if length < 0.0:
                    length = math.sqrt(dx * dx + dy * dy + dz * dz)
                if f > reach0 + length:
                    continue
            elif kind == NEAR_BALL:
                bx, by, bz = ex - cnear[k, 1], ey - cnear[k, 2], ez - cnear[k, 3]
                d2 = bx * bx + by * by + bz * bz
                far = cnear[k, 4] + (reach0 + l1)
                if far > 0.0 and d2 > far * far:
                    continue
                if length < 0.0:
                    length = math.sqrt(dx * dx + dy * dy + dz * dz)
                far = cnear[k, 4] + (reach0 + length)
                if far > 0.0 and d2 > far * far:
                    continue
            elif kind == NEAR_PLANES:
                o, m = int(cnear[k, 1]), int(cnear[k, 2])
                lb = 1e300
                for p in range(m):
                    b = o + 4 * p
                    lb = min(lb, cf[b] * ex + cf[b + 1] * ey + cf[b + 2] * ez - cf[b + 3])
                if lb - reach0 > l1:
                    continue
                if length < 0.0:
                    length = math.sqrt(dx * dx + dy * dy + dz * dz)
                if lb > reach0 + length:
                    continue
            # NEAR_ALWAYS (moving colliders): always a candidate
        near |= 1 << min(k, 62)
    return near


#: A far-test plane row that no particle passes (0 x - 1e300 < 0): stands for the colliders the
#: cheap test cannot bound (more than 62 colliders, moving ones), so every particle is sent to the
#: exact mask
ALWAYS_NEAR_PLANE = (0.0, 0.0, 0.0, 1e300)


#: Far-test rows that every path of finite length below 1e150 passes (1e300 above the plane; a
#: unit ball 1e300 away, whose squared distance overflows to inf): they stand for the row a scene
#: does not have when ``step_and_collide`` tests one plane row and one ball row as scalars. They
#: only narrow the cheap test (a particle they call near takes the exact test); a NaN end point
#: or path fails them, as it fails every row.
NEVER_NEAR_PLANE = (0.0, 0.0, 0.0, -1e300)
NEVER_NEAR_BALL = (1e300, 0.0, 0.0, 1.0)


def far_slots(cnear, cf):
    """The rows of the cheap far test (``_far_from_slots``) for a packed ``cnear``/``cf``: (P, 4)
    planes [n, c] (every ``NEAR_PLANE`` row and each wall of a ``NEAR_PLANES`` row, the
    container) and (B, 4) balls [centre, bounding radius] (``NEAR_BALL`` rows). Built once when
    the colliders are packed (NumPy, outside the step)."""
    import numpy as np

    planes, balls = [], []
    k_count = cnear.shape[0]
    for k in range(k_count):
        kind = cnear[k, 0]
        if kind == NEAR_NEVER:
            continue
        if k_count > 62 or kind == NEAR_ALWAYS:
            planes.append(ALWAYS_NEAR_PLANE)
        elif kind == NEAR_PLANE:
            planes.append(tuple(cnear[k, 1:5]))
        elif kind == NEAR_BALL:
            balls.append(tuple(cnear[k, 1:5]))
        elif kind == NEAR_PLANES:
            o, m = int(cnear[k, 1]), int(cnear[k, 2])
            planes.extend(tuple(cf[o + 4 * p:o + 4 * p + 4]) for p in range(m))
        else:
            planes.append(ALWAYS_NEAR_PLANE)
    return (np.array(planes, np.float64).reshape(-1, 4), np.array(balls, np.float64).reshape(-1, 4))


@njit(cache=True, inline="always")
def _far_from_slots(planes, balls, r, tol, ex, ey, ez, dx, dy, dz):
    """True when the step's path (displacement d, ending at e) provably reaches no collider: the
    cheap half of ``_near_mask`` (the path's length bounded by |d|_1, no square root) over the
    rows of ``far_slots`` (planes and container walls, then bounding balls), with no branch on
    the collider kind. It implies ``_near_mask(...) == 0``: the same products and comparisons,
    rounded the same way (a container's minimum over its walls passes ``lb - reach0 > l1`` exactly
    when every wall does, subtraction being monotone), so it may only send a far particle to the
    exact test, never miss a near one (NaN fails every comparison: near). The integrating loop of
    ``step_and_collide`` runs it per particle."""
    reach0 = r + 2.0 * tol
    l1 = abs(dx) + abs(dy) + abs(dz)
    far = True
    for p in range(planes.shape[0]):
        far &= _plane_far(planes[p, 0], planes[p, 1], planes[p, 2], planes[p, 3], reach0, l1, ex, ey, ez)
    for b in range(balls.shape[0]):
        far &= _ball_far(balls[b, 0], balls[b, 1], balls[b, 2], balls[b, 3], reach0, l1, ex, ey, ez)
    return far


@njit(cache=True, inline="always")
def _plane_far(nx, ny, nz, off, reach0, l1, ex, ey, ez):
    """One plane row of ``_far_from_slots``: the end point's height above the plane beyond the
    reach (r + 2 tol) plus |d|_1."""
    lin = nx * ex + ny * ey + nz * ez - off
    return lin - reach0 > l1


@njit(cache=True, inline="always")
def _ball_far(cx, cy, cz, rad, reach0, l1, ex, ey, ez):
    """One ball row of ``_far_from_slots``: the end point outside the ball grown by the reach and
    |d|_1 (compared squared: no square root)."""
    bx, by, bz = ex - cx, ey - cy, ez - cz
    reach = rad + (reach0 + l1)
    return (reach > 0.0) & (bx * bx + by * by + bz * bz > reach * reach)


@njit(cache=True, inline="always")
def _far_from_one_each(p0, p1, p2, p3, b0, b1, b2, b3, r, tol, ex, ey, ez, dx, dy, dz):
    """``_far_from_slots`` for one plane row (p) and one ball row (b) passed as scalars (the
    common scene: a ground and one obstacle; a scene with only one of them passes the other as
    ``NEVER_NEAR_PLANE`` / ``NEVER_NEAR_BALL``). The same operations, so the same result; with
    the rows in registers and no loop over rows, the fused semi-implicit step at 1M particles
    took about 0.82x the time of the loop over rows (kernel timed on a saved state, load 2-5)."""
    reach0 = r + 2.0 * tol
    l1 = abs(dx) + abs(dy) + abs(dz)
    return (_plane_far(p0, p1, p2, p3, reach0, l1, ex, ey, ez)
            & _ball_far(b0, b1, b2, b3, reach0, l1, ex, ey, ez))


@_unrefcounted
def _clear_of_planes_and_spheres(cint, cnear, near, r, tol, sx, sy, sz, ex, ey, ez):
    """True when every collider in ``near`` is a static plane or sphere and the chord s -> e
    stays more than r + 2 tol from it (planes: the end point, the chord being straight; spheres:
    the chord's closest point to the centre)."""
    lx, ly, lz = ex - sx, ey - sy, ez - sz
    l2 = lx * lx + ly * ly + lz * lz
    for k in range(min(cnear.shape[0], 62)):
        if not (near >> k) & 1:
            continue
        kind = cnear[k, 0]
        if kind == NEAR_PLANE:
            f = cnear[k, 1] * ex + cnear[k, 2] * ey + cnear[k, 3] * ez - cnear[k, 4]
            # f at the start is larger (heading in) or the chord moves away: the end decides
            fs = cnear[k, 1] * sx + cnear[k, 2] * sy + cnear[k, 3] * sz - cnear[k, 4]
            if min(f, fs) - r <= 2.0 * tol:
                return False
        elif kind == NEAR_BALL and cint[k, 0] == _d.SPHERE:
            cx, cy, cz = cnear[k, 1] - sx, cnear[k, 2] - sy, cnear[k, 3] - sz
            t = 0.0
            if l2 > 0.0:
                t = min(max((cx * lx + cy * ly + cz * lz) / l2, 0.0), 1.0)
            dx, dy, dz = cx - t * lx, cy - t * ly, cz - t * lz
            reach = cnear[k, 4] + r + 2.0 * tol
            if dx * dx + dy * dy + dz * dz <= reach * reach:
                return False
        else:
            return False
    return near >> 62 == 0


@_unrefcounted
def _collide_near(i, radius, cint, cnear, cmat, cf, ci, pose0, pose1, ref, rest_k, rest_n, rest_u, load,
                  static_ok, near, kr, sx, sy, sz, svx, svy, svz, ex, ey, ez, evx, evy, evz, dt, tol,
                  rest_speed, a_priori, max_sub, max_iter, classify, unfiltered, started, kinds, motion):
    """Steps 1-4 of ``collide_particles`` for particle i, whose path may reach a collider (or
    which rests on one). Start (s, sv) and end (e, ev) of the integrator's step in, final
    (x, v) out, with whether they changed and whether the particle rests afterwards."""
    inv_dt = 1.0 / dt
    r = radius[i]
    # the start velocity and the step's average acceleration (exact for constant forces)
    if not started:
        sx, sy, sz, svx, svy, svz = ex, ey, ez, evx, evy, evz
    # near only static planes and spheres, and clear of them: the chord stays more than 2 tol
    # from every surface, so the general path would find no impact, project nothing and find no
    # resting contact (the margin keeps rounding out of it): nothing to do
    if kr < 0 and _clear_of_planes_and_spheres(cint, cnear, near, r, tol, sx, sy, sz, ex, ey, ez):
        return ex, ey, ez, evx, evy, evz, False, False
    ax, ay, az = (evx - svx) * inv_dt, (evy - svy) * inv_dt, (evz - svz) * inv_dt

    # 1. resting on a static plane and near nothing else (a floor, the bottom of a pile):
    #    the resting motion, and if the particle is still on the plane without normal motion,
    #    done without the general path
    modified = False
    resting_done = False
    if unfiltered is not None:  # the force filter did not run (a fused step): compiled in only then
        if kr >= 0 and near == (1 << kr) and cnear[kr, 0] == NEAR_PLANE and kr < 62:
            nx, ny, nz = cnear[kr, 1], cnear[kr, 2], cnear[kr, 3]
            if ax * nx + ay * ny + az * nz < 0.0:
                ex, ey, ez, evx, evy, evz = _resting_motion(sx, sy, sz, svx, svy, svz, ax, ay, az, nx, ny, nz,
                                                            0.0, 0.0, 0.0, cmat[kr, 1], dt, rest_speed)
                ax, ay, az = (evx - svx) * inv_dt, (evy - svy) * inv_dt, (evz - svz) * inv_dt
                modified = resting_done = True
            f = nx * ex + ny * ey + nz * ez - cnear[kr, 4] - r
            wn = evx * nx + evy * ny + evz * nz
            if -tol <= f <= tol and abs(wn) <= rest_speed:
                if f < 0.0:
                    ex, ey, ez = ex - f * nx, ey - f * ny, ez - f * nz
                    modified = True
                # resting: rest_k, rest_n (the plane's normal) and rest_u (0) stay
                return ex, ey, ez, evx, evy, evz, modified, classify

    # 2-4. near a collider: the general path
    return _full_path(i, radius, cint, cmat, cf, ci, pose0, pose1, ref, rest_k, rest_n, rest_u, load,
                      static_ok, near, kr, sx, sy, sz, svx, svy, svz, ex, ey, ez, evx, evy, evz, ax, ay,
                      az, dt, tol, rest_speed, a_priori, max_sub, max_iter, classify, unfiltered,
                      resting_done, started, kinds, motion)


@njit(cache=True, parallel=True)
def collide_particles(x, v, x0, v0, radius, inv_mass, active, active0, cint, cnear, cmat, cf, ci, pose0,
                      pose1, ref, rest_k, rest_n, rest_u, load, static_ok, dv_step,
                      dt, tol, rest_speed, a_priori, max_sub, max_iter, classify, write_dv,
                      unfiltered, save_next, kinds, motion):
    """Detect and respond to particle-collider contacts for one step, in place on x and v.

    x0, v0: the state at the start of the step (rows valid where active0). For each particle
    (independently, in parallel):
    0. colliders that provably cannot be reached from the step's path are skipped (one distance
       evaluation at the end point each);
    1. resting contact (rest_k >= 0): if the force filter ran (``unfiltered`` None), remove
       normal velocity into the surface and stop sliding that friction stops within the step;
       if it did not run (``unfiltered`` True: a fused integrator), recompute the step's motion
       with the filtered acceleration (``_resting_motion``). ``unfiltered`` is a compile-time
       token like ``motion``: a scene whose filter runs does not compile the resting motion;
    2. a priori: the earliest time of impact on the step's path (the chord finds the contact,
       the parabola with the step's acceleration its time), move there, respond, finish the
       step from the contact; up to ``max_sub`` impacts;
    3. the end position is projected out of any collider it is inside (the whole response in
       a-posteriori mode, without the velocity gained inside; a safety net a priori);
    4. (classify) the resting-contact state for the next step;
    5. (save_next) x0, v0 = the final x, v (the next step's start, saving begin_step a copy).
    Returns (number of particles changed, number resting, finite): finite is False when a value
    this kernel wrote is NaN or infinite.
    """
    n, dim = x.shape
    changed = 0
    resting = 0
    check = 0.0  # sum of (written value) * 0: NaN as soon as one is NaN or infinite
    for i in prange(n):
        if not active[i] or inv_mass[i] == 0.0:
            if rest_k[i] != -1:
                rest_k[i] = -1
            continue
        ex, ey = x[i, 0], x[i, 1]
        ez = x[i, 2] if dim == 3 else 0.0
        evx, evy = v[i, 0], v[i, 1]
        evz = v[i, 2] if dim == 3 else 0.0
        started = active0[i]
        if started:
            sx, sy = x0[i, 0], x0[i, 1]
            sz = x0[i, 2] if dim == 3 else 0.0
        else:  # became active during the step: no path to sweep
            sx, sy, sz = ex, ey, ez
        if write_dv:
            if started:
                dv_step[i, 0], dv_step[i, 1] = evx - v0[i, 0], evy - v0[i, 1]
                dv_step[i, 2] = (evz - v0[i, 2]) if dim == 3 else 0.0
            else:
                dv_step[i, 0] = dv_step[i, 1] = dv_step[i, 2] = 0.0
        kr = rest_k[i]
        # 0. colliders near the path
        dx, dy, dz = ex - sx, ey - sy, ez - sz
        near = _near_mask(cnear, cf, kr, radius[i], tol, ex, ey, ez, dx, dy, dz)
        if near != 0 or kr >= 0:
            if started:
                svx, svy = v0[i, 0], v0[i, 1]
                svz = v0[i, 2] if dim == 3 else 0.0
            else:
                svx, svy, svz = evx, evy, evz
            ex, ey, ez, evx, evy, evz, mod, rests = _collide_near(
                i, radius, cint, cnear, cmat, cf, ci, pose0, pose1, ref, rest_k, rest_n, rest_u, load,
                static_ok, near, kr, sx, sy, sz, svx, svy, svz, ex, ey, ez, evx, evy, evz, dt, tol,
                rest_speed, a_priori, max_sub, max_iter, classify, unfiltered, started, kinds, motion)
            if mod:
                changed += 1
                check += (ex + ey + ez + evx + evy + evz) * 0.0
                x[i, 0], x[i, 1] = ex, ey
                v[i, 0], v[i, 1] = evx, evy
                if dim == 3:
                    x[i, 2], v[i, 2] = ez, evz
            if rests:
                resting += 1
        # 5. the next step's start (far from every collider: the state as it is)
        if save_next:
            x0[i, 0], x0[i, 1], v0[i, 0], v0[i, 1] = ex, ey, evx, evy
            if dim == 3:
                x0[i, 2], v0[i, 2] = ez, evz
    return changed, resting, check == 0.0


@njit(cache=True, inline="always")
def _affine_step(x, v, g, f, k, w, h, rk4):
    """One step of one coordinate under the affine force f = m g + F - k v (1/m = w): the
    arithmetic of ``particles.kernels.affine_rk4`` (rk4) or ``affine_kick_drift``, so that the
    fused step gives the same bits as the integrator followed by ``collide_particles``."""
    if rk4:
        base = g + f * w
        kw = k * w
        a1 = base - kw * v
        v1 = v + 0.5 * h * a1
        a2 = base - kw * v1
        v2 = v + 0.5 * h * a2
        a3 = base - kw * v2
        v3 = v + h * a3
        a4 = base - kw * v3
        return x + h / 6.0 * (v + 2.0 * v1 + 2.0 * v2 + v3), v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    vc = v + h * (g + (f - k * v) * w)
    return x + h * vc, vc


@njit(cache=True)
def _step_far(xs, vs, rs, ws, acs, rks, flags, dim, rk4, one_each, gx, gy, gz, fx, fy, fz, damping, dt, tol,
              planes, balls, p0, p1, p2, p3, b0, b1, b2, b3):
    """The first loop of ``step_and_collide`` over one chunk of particles: integrate, run the cheap
    far test, write x, v (the end of step where far, the start where not: the same values) and
    flags[j] = 1 where the particle needs the second loop (0 where it is done). Returns the
    number of far particles whose end of step holds a NaN or infinite value.

    Arguments are the chunk's views: xs, vs (m * dim,) flat rows of x, v; rs, ws, acs, rks,
    flags (m,) its radius, 1/m, active, rest_k and flag slots. Every iteration reads and writes
    only its own slots, at indices counted from 0 with unit or constant stride (no running
    index, no negative-index fix-up), and picks the values it writes with selects: called with
    ``dim``, ``rk4`` and ``one_each`` constant, the loop is straight-line code that the compiler
    vectorises (AVX2: four particles per instruction); the arithmetic per particle is unchanged,
    so the bits are the same."""
    bad = 0
    for j in range(rs.shape[0]):
        w = ws[j]
        sx, svx = xs[dim * j], vs[dim * j]
        sy, svy = xs[dim * j + 1], vs[dim * j + 1]
        sz = xs[dim * j + 2] if dim == 3 else 0.0
        svz = vs[dim * j + 2] if dim == 3 else 0.0
        ex, evx = _affine_step(sx, svx, gx, fx, damping, w, dt, rk4)
        ey, evy = _affine_step(sy, svy, gy, fy, damping, w, dt, rk4)
        ez, evz = _affine_step(sz, svz, gz, fz, damping, w, dt, rk4)
        if one_each:
            far_c = _far_from_one_each(p0, p1, p2, p3, b0, b1, b2, b3, rs[j], tol, ex, ey, ez,
                                       ex - sx, ey - sy, ez - sz)
        else:
            far_c = _far_from_slots(planes, balls, rs[j], tol, ex, ey, ez, ex - sx, ey - sy, ez - sz)
        far = acs[j] & (w != 0.0) & (rks[j] < 0) & far_c
        # the end of step where far, the start (unchanged) otherwise
        ox, ovx = (ex, evx) if far else (sx, svx)
        oy, ovy = (ey, evy) if far else (sy, svy)
        oz, ovz = (ez, evz) if far else (sz, svz)
        bad += far & ((ex + ey + ez + evx + evy + evz) * 0.0 != 0.0)
        xs[dim * j], xs[dim * j + 1] = ox, oy
        vs[dim * j], vs[dim * j + 1] = ovx, ovy
        if dim == 3:
            xs[dim * j + 2], vs[dim * j + 2] = oz, ovz
        flags[j] = not far
    return bad


#: Flags per block of ``_list_near``: a block whose flags are all 0 is passed over with one test
NEAR_BLOCK = 16


@njit(cache=True, inline="always")
def _list_near(near_list, lo, hi):
    """Turn the flags near_list[lo:hi] (1: near, 0: done) into the indices of the flagged
    particles, in order, from slot lo, ended by -1 when fewer than hi - lo; returns the end of the
    list (the slot of the -1, or hi). In place: the slot written (count) is never after the flag
    being read (i), and a block's flags are read before any slot of it is written.

    Blocks of ``NEAR_BLOCK`` flags are OR-ed first (a fixed-length loop: a few vector
    instructions) and only a block holding a flag is compacted: near particles are rare (0.7 % of
    the rain in ``bench_collisions``) and the flag-by-flag pass over every slot, a chain of
    dependent stores, cost about 1.5 ns per particle (1.6 ms of the 13.8 ms fused semi-implicit
    step at 1M particles, one thread). The list is the same as that pass's."""
    count = lo
    b = lo
    while b + NEAR_BLOCK <= hi:
        seen = near_list[b]
        for j in range(1, NEAR_BLOCK):
            seen |= near_list[b + j]
        if seen != 0:
            for i in range(b, b + NEAR_BLOCK):
                flag = near_list[i]
                near_list[count] = i
                count += flag
        b += NEAR_BLOCK
    for i in range(b, hi):  # the partial block at the end of the last chunk
        flag = near_list[i]
        near_list[count] = i
        count += flag
    if count < hi:
        near_list[count] = -1
    return count


#: Particles per chunk of ``step_and_collide``: each chunk is integrated in a tight loop that sets
#: the particles near a collider aside, then those are collided while the chunk is in cache. A
#: fixed size (not one per thread) keeps the work of each particle the same at any thread count.
STEP_CHUNK = 1024


@njit(cache=True, parallel=True)
def step_and_collide(x, v, radius, inv_mass, active, gravity, force, damping, rk4, cint, cnear, cmat, cf,
                     ci, far_planes, far_balls, pose, ref, rest_k, rest_n, rest_u, load, static_ok,
                     near_list, chunk_counts, rec, record, dt, tol, rest_speed, a_priori, max_sub, max_iter,
                     kinds, motion):
    """The fused integrator step (rk4 or semi-implicit Euler, affine forces) and the collision
    pass against static colliders, in one pass over memory.

    Each particle's start (x, v) and end of step stay in registers: no start-of-step copy is
    written or read (the separate path moves x0, v0 through memory twice). The particles go in
    chunks of ``STEP_CHUNK`` (in parallel): a first, tight loop (``_step_far``) integrates the
    chunk and tests each path against the colliders (``_far_from_slots`` over ``far_planes``
    (P, 4) and ``far_balls`` (B, 4), the rows of ``far_slots``: a few flops per row, no branch on
    the collider kind). That loop has no data-dependent branch and no running index: every
    particle's slot of x, v gets its end of step when it is far (and moves: active, 1/m > 0,
    resting on nothing) and its start otherwise (the same values: nothing changes), and its slot
    of ``near_list`` (N,) int64 (a preallocated scratch array) a flag, 1 when it is near. It runs
    over flat views of the chunk's rows of x, v (C-contiguous, as the system's state is), and for
    3-D particles and at most one plane row and one ball row (a ground, an obstacle) it is compiled
    with the dimension, the method and the rows constant: the compiler vectorises it (AVX2: four
    particles per instruction; at 1M particles on one thread the fused semi-implicit step took
    about 0.4x, rk4 about 0.45x the time of the scalar loop, same bits). A short pass turns the
    flags into the chunk's near particles from the chunk's first slot, ended by -1
    (``_list_near``: it looks at blocks of flags, and slot by slot only in a block with a flag).
    A second loop over that short list integrates them again (the same arithmetic: the same
    bits) and runs the same ``_collide_near`` as ``collide_particles``, so the results are the
    same bits as the integrator's fused kernel followed by ``collide_particles``. The far path
    thus stays a small loop free of the response code. pose (K, 12): the static colliders'
    poses (unused by static shapes). chunk_counts (>= chunks, 3) int64: scratch for each chunk's
    (changed, resting, non-finite values) counts, summed in chunk order after the parallel loop
    (no scalar reduction inside it). rec (``PassRecord``), record: when ``record`` (a world that
    wants its Contacts rows, decided once), the near loop also adds each particle's momentum change
    over the collision pass to its contact slot of the row ``pass_row`` credits -- what
    ``gather_pass_impulses`` adds after a separate pass, the same bits -- so impacts get their rows
    with the impulse (a particle's slots are its own: no write is shared between chunks; the
    world's ``fill_particle_contacts`` then lists the rows in particle order, as after the separate
    pass). Far particles do not change in the pass and have nothing to record. Returns (changed,
    resting, finite), finite False when any value of the state (pinned and inactive particles
    included) is NaN or infinite.
    """
    n, dim = x.shape
    chunks = (n + STEP_CHUNK - 1) // STEP_CHUNK
    unfiltered = cint.shape[0] >= 0  # True (no force filter runs), typed as collide_particles' token
    gx, gy = gravity[0], gravity[1]
    gz = gravity[2] if dim == 3 else 0.0
    fx, fy = force[0], force[1]
    fz = force[2] if dim == 3 else 0.0
    # at most one plane row and one ball row (a ground, an obstacle, or both): the rows as
    # scalars, a missing one replaced by a row that every finite path passes (``NEVER_NEAR_*``)
    planes_n, balls_n = far_planes.shape[0], far_balls.shape[0]
    one_each = (planes_n <= 1) & (balls_n <= 1) & (planes_n + balls_n >= 1)
    has_plane = one_each & (planes_n == 1)
    has_ball = one_each & (balls_n == 1)
    p0 = far_planes[0, 0] if has_plane else NEVER_NEAR_PLANE[0]
    p1 = far_planes[0, 1] if has_plane else NEVER_NEAR_PLANE[1]
    p2 = far_planes[0, 2] if has_plane else NEVER_NEAR_PLANE[2]
    p3 = far_planes[0, 3] if has_plane else NEVER_NEAR_PLANE[3]
    b0 = far_balls[0, 0] if has_ball else NEVER_NEAR_BALL[0]
    b1 = far_balls[0, 1] if has_ball else NEVER_NEAR_BALL[1]
    b2 = far_balls[0, 2] if has_ball else NEVER_NEAR_BALL[2]
    b3 = far_balls[0, 3] if has_ball else NEVER_NEAR_BALL[3]
    for c in prange(chunks):
        lo = c * STEP_CHUNK
        hi = min(lo + STEP_CHUNK, n)
        chunk_changed = 0
        chunk_resting = 0
        # 1. integrate; far particles are done, the others flagged in near_list[lo:hi] (no
        #    branch, no running index: see ``_step_far``); the common cases call it with constant
        #    dim / method / rows, so that the compiler's copy of the loop has no switch inside it
        m = hi - lo
        xs, vs = x[lo:hi].reshape(m * dim), v[lo:hi].reshape(m * dim)  # views: no copy
        rs, ws, acs, rks, fl = radius[lo:hi], inv_mass[lo:hi], active[lo:hi], rest_k[lo:hi], near_list[lo:hi]
        if dim == 3 and one_each and rk4:
            chunk_bad = _step_far(xs, vs, rs, ws, acs, rks, fl, 3, True, True, gx, gy, gz, fx, fy, fz, damping,
                                  dt, tol, far_planes, far_balls, p0, p1, p2, p3, b0, b1, b2, b3)
        elif dim == 3 and one_each:
            chunk_bad = _step_far(xs, vs, rs, ws, acs, rks, fl, 3, False, True, gx, gy, gz, fx, fy, fz, damping,
                                  dt, tol, far_planes, far_balls, p0, p1, p2, p3, b0, b1, b2, b3)
        else:
            chunk_bad = _step_far(xs, vs, rs, ws, acs, rks, fl, dim, rk4, one_each, gx, gy, gz, fx, fy, fz,
                                  damping, dt, tol, far_planes, far_balls, p0, p1, p2, p3, b0, b1, b2, b3)
        # the flags become the list of the chunk's near particles, in place, ended by -1
        count = _list_near(near_list, lo, hi)
        # 2. the particles near a collider: the step again, then the collision response
        for q in range(lo, count):
            i = near_list[q]
            w = inv_mass[i]
            if not active[i] or w == 0.0:  # not moved: no contact; its values checked as they are
                if rest_k[i] != -1:
                    rest_k[i] = -1
                for d in range(dim):
                    chunk_bad += x[i, d] * 0.0 + v[i, d] * 0.0 != 0.0
            else:  # (an else, not a continue: Numba's parfor reductions trip over the latter here)
                sx, svx = x[i, 0], v[i, 0]
                sy, svy = x[i, 1], v[i, 1]
                sz = x[i, 2] if dim == 3 else 0.0
                svz = v[i, 2] if dim == 3 else 0.0
                ex, evx = _affine_step(sx, svx, gravity[0], force[0], damping, w, dt, rk4)
                ey, evy = _affine_step(sy, svy, gravity[1], force[1], damping, w, dt, rk4)
                if dim == 3:
                    ez, evz = _affine_step(sz, svz, gravity[2], force[2], damping, w, dt, rk4)
                else:
                    ez, evz = 0.0, 0.0
                kr = rest_k[i]
                near = _near_mask(cnear, cf, kr, radius[i], tol, ex, ey, ez, ex - sx, ey - sy, ez - sz)
                mod = rests = False
                if near != 0 or kr >= 0:  # the exact test (the first loop's may send far particles)
                    ix, iy, iz, ivx, ivy, ivz = ex, ey, ez, evx, evy, evz  # the integrator's end
                    ex, ey, ez, evx, evy, evz, mod, rests = _collide_near(
                        i, radius, cint, cnear, cmat, cf, ci, pose, pose, ref, rest_k, rest_n, rest_u, load,
                        static_ok, near, kr, sx, sy, sz, svx, svy, svz, ex, ey, ez, evx, evy, evz, dt, tol,
                        rest_speed, a_priori, max_sub, max_iter, True, unfiltered, True, kinds, motion)
                    if record and mod:  # the contact row of the pass's impulse (Contacts rows wanted)
                        _record_pass(i, w, radius, cint, cf, ci, pose, ref, rec, ix, iy, iz, ivx, ivy, ivz,
                                     ex, ey, ez, evx, evy, evz, kinds, motion)
                chunk_changed += mod
                chunk_resting += rests
                chunk_bad += (ex + ey + ez + evx + evy + evz) * 0.0 != 0.0
                x[i, 0], x[i, 1] = ex, ey
                v[i, 0], v[i, 1] = evx, evy
                if dim == 3:
                    x[i, 2], v[i, 2] = ez, evz
        chunk_counts[c, 0] = chunk_changed
        chunk_counts[c, 1] = chunk_resting
        chunk_counts[c, 2] = chunk_bad
    changed = resting = bad = 0
    for c in range(chunks):
        changed += chunk_counts[c, 0]
        resting += chunk_counts[c, 1]
        bad += chunk_counts[c, 2]
    return changed, resting, bad == 0


class PassRecord(NamedTuple):
    """Kernel bundle: where ``step_and_collide`` records the rows the collision pass credits (the
    world's contact slots, ``inertia.dynamics.particle_coupling.ContactSlots``), when ``record``.

    slot_entry (N, S) int64, slot_impulse (N, S, 3) N s: per particle the packed rows it touched in
    the world step and the impulse each gave it (``slot_add``); entry_body, entry_shape (K,) int64:
    the dynamic body and shape-table row of each packed row (-1 none); tol: the attribution
    tolerance (``pass_row``). ``no_record(k)`` is the 1-particle placeholder when nothing is recorded.
    """
    slot_entry: np.ndarray
    slot_impulse: np.ndarray
    entry_body: np.ndarray
    entry_shape: np.ndarray
    tol: float


def no_record(k: int) -> PassRecord:
    """A placeholder ``PassRecord`` (nothing is written to it: ``record`` False)."""
    return PassRecord(np.full((1, 2), -1, np.int64), np.zeros((1, 2, 3)), np.full(max(k, 1), -1, np.int64),
                      np.full(max(k, 1), -1, np.int64), 0.0)


@njit(cache=True)
def pass_row(cint, cf, ci, pose, ref, entry_body, entry_shape, r, tol, x0, y0, z0, x1, y1, z1, kinds, motion):
    """The packed row a particle's change over the collision pass is credited to: the row nearest to
    the particle at the start (x0) or end (x1) of the pass (signed distance at ``pose``), if it is a
    table row or a body's row and within tol + |x1 - x0| (+ 1e-9 m) of the particle's surface; -1
    otherwise. One rule for the coupling (``particle_coupling.gather_pass_impulses``) and the fused
    step's contact rows (``step_and_collide``)."""
    best, kbest = 1e300, -1
    for k in range(cint.shape[0]):
        if cint[k, 0] == _d.CALLABLE:
            continue
        d0 = _eval(cint, cf, ci, pose, ref, k, x0, y0, z0, kinds, motion)[0]
        d1 = _eval(cint, cf, ci, pose, ref, k, x1, y1, z1, kinds, motion)[0]
        d = min(d0, d1)
        if d < best:
            best, kbest = d, k
    if kbest < 0:
        return -1
    if entry_body[kbest] < 0 and entry_shape[kbest] < 0:
        return -1
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    reach = tol + math.sqrt(dx * dx + dy * dy + dz * dz) + 1e-9
    if best - r > reach:
        return -1
    return kbest


@njit(cache=True)
def slot_add(entry, impulse, i, k, jx, jy, jz):
    """Add the impulse (jx, jy, jz) on particle i from packed row k to i's contact slot of k (the
    first free slot when k has none; the last slot when all are taken)."""
    s = -1
    for c in range(entry.shape[1]):
        if entry[i, c] == k:
            s = c
            break
        if entry[i, c] < 0:
            entry[i, c] = k
            s = c
            break
    if s < 0:
        s = entry.shape[1] - 1
    impulse[i, s, 0] += jx
    impulse[i, s, 1] += jy
    impulse[i, s, 2] += jz


@njit(cache=True)
def _record_pass(i, w, radius, cint, cf, ci, pose, ref, rec, x0, y0, z0, u0, v0, w0, x1, y1, z1, u1, v1, w1,
                 kinds, motion):
    """The fused step's twin of ``gather_pass_impulses`` for one particle (static rows only: no body
    is pushed): its momentum change over the collision pass, from (x0, u0) to (x1, u1), added to its
    contact slot of the row ``pass_row`` credits."""
    dvx, dvy, dvz = u1 - u0, v1 - v0, w1 - w0
    if dvx == 0.0 and dvy == 0.0 and dvz == 0.0 and x1 - x0 == 0.0 and y1 - y0 == 0.0 and z1 - z0 == 0.0:
        return
    k = pass_row(cint, cf, ci, pose, ref, rec.entry_body, rec.entry_shape, radius[i], rec.tol, x0, y0, z0,
                 x1, y1, z1, kinds, motion)
    if k < 0 or rec.entry_shape[k] < 0:
        return
    m = 1.0 / w
    slot_add(rec.slot_entry, rec.slot_impulse, i, k, m * dvx, m * dvy, m * dvz)


@njit(cache=True, parallel=True)
def resting_filter(v, f, inv_mass, rest_k, rest_n, rest_u, cmat, rest_speed, load, static_ok):
    """Resting-contact force filter (Witkin & Baraff): for a particle resting on a surface, cancel
    the normal component of the applied force that pushes into it (F' = F_T) and apply Coulomb
    friction: static (cancel F_T) while the particle is at rest and |F_T| <= mu |F_N|, kinetic
    (mu |F_N| against the sliding velocity) otherwise. f (N, D) is modified in place."""
    n, dim = f.shape
    for i in prange(n):
        k = rest_k[i]
        if k < 0 or inv_mass[i] == 0.0:
            continue
        nx, ny, nz = rest_n[i, 0], rest_n[i, 1], rest_n[i, 2]
        fx, fy = f[i, 0], f[i, 1]
        fz = f[i, 2] if dim == 3 else 0.0
        fn = fx * nx + fy * ny + fz * nz
        if fn >= 0.0:
            # pulling away: the contact lets go
            load[i] = 0.0
            static_ok[i] = True
            continue
        # F' = F - (F.N) N: the contact force cancels the push into the surface
        fx, fy, fz = fx - fn * nx, fy - fn * ny, fz - fn * nz
        normal_load = -fn
        mu = cmat[k, 1]
        vx, vy = v[i, 0] - rest_u[i, 0], v[i, 1] - rest_u[i, 1]
        vz = (v[i, 2] if dim == 3 else 0.0) - rest_u[i, 2]
        vn = vx * nx + vy * ny + vz * nz
        tx, ty, tz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        speed = math.sqrt(tx * tx + ty * ty + tz * tz)
        ft = math.sqrt(fx * fx + fy * fy + fz * fz)
        limit = mu * normal_load
        static_ok[i] = ft <= limit
        if speed <= rest_speed:
            if ft <= limit:
                fx = fy = fz = 0.0  # static friction holds it
            else:
                s = limit / ft     # starts to slide along F_T
                fx, fy, fz = fx - s * fx, fy - s * fy, fz - s * fz
        else:
            s = limit / speed      # kinetic friction against the sliding velocity
            fx, fy, fz = fx - s * tx, fy - s * ty, fz - s * tz
        load[i] = normal_load * inv_mass[i]
        f[i, 0], f[i, 1] = fx, fy
        if dim == 3:
            f[i, 2] = fz


@njit(cache=True, parallel=True)
def mark_pairs(pair_i, pair_j, color_start, color_order, ncolors, in_pair):
    """in_pair[p] = 1 for every particle in a pair (colour batches are write-disjoint); int8."""
    for c in range(ncolors):
        if c == MAX_COLORS - 1:
            for q in range(color_start[c], color_start[c + 1]):
                p = color_order[q]
                in_pair[pair_i[p]] = 1
                in_pair[pair_j[p]] = 1
        else:
            for q in prange(color_start[c], color_start[c + 1]):
                p = color_order[q]
                in_pair[pair_i[p]] = 1
                in_pair[pair_j[p]] = 1


@njit(cache=True)
def _pair_velocity(x, v, inv_mass, dv_step, support, pair_i, pair_j, p, restitution, friction, rest_speed):
    """Pair impulse (``response.pair_impulse``, written out here: this runs per pair and pass)
    with shock propagation: in a resting contact, a supported particle lying where its
    neighbour is pushed (within 60 degrees of its applied acceleration) acts as infinitely
    heavy for it and passes its support on."""
    i, j = pair_i[p], pair_j[p]
    dim = x.shape[1]
    rx = x[j, 0] - x[i, 0]
    ry = x[j, 1] - x[i, 1]
    rz = (x[j, 2] - x[i, 2]) if dim == 3 else 0.0
    dist = math.sqrt(rx * rx + ry * ry + rz * rz)
    if dist > 0.0:
        nx, ny, nz = rx / dist, ry / dist, rz / dist
    else:
        nx, ny, nz = 1.0, 0.0, 0.0  # coincident: any fixed direction (deterministic)
    wx = v[j, 0] - v[i, 0]
    wy = v[j, 1] - v[i, 1]
    wz = (v[j, 2] - v[i, 2]) if dim == 3 else 0.0
    vn = wx * nx + wy * ny + wz * nz
    if vn >= 0.0:
        return
    # resting speed: twice what the step's forces add to either particle along the normal
    ain = dv_step[i, 0] * nx + dv_step[i, 1] * ny + dv_step[i, 2] * nz
    ajn = dv_step[j, 0] * nx + dv_step[j, 1] * ny + dv_step[j, 2] * nz
    threshold = 2.0 * max(abs(ain), abs(ajn)) + rest_speed
    wi, wj = inv_mass[i], inv_mass[j]
    side = 0
    if -vn <= threshold:
        # i below j: -n along j's pull; j below i: n along i's pull (|a| cos 60 = |a| / 2)
        if support[i] and -ajn > 0.0 and 4.0 * ajn * ajn > (dv_step[j, 0] ** 2 + dv_step[j, 1] ** 2
                                                            + dv_step[j, 2] ** 2):
            wi, side = 0.0, 1
        elif support[j] and ain > 0.0 and 4.0 * ain * ain > (dv_step[i, 0] ** 2 + dv_step[i, 1] ** 2
                                                              + dv_step[i, 2] ** 2):
            wj, side = 0.0, 2
    w = wi + wj
    if w == 0.0:
        return
    e = restitution if -vn > threshold else 0.0
    impulse = -(1.0 + e) * vn / w
    # tangential impulse: stop the relative sliding, bounded by mu * impulse
    tx, ty, tz = wx - vn * nx, wy - vn * ny, wz - vn * nz
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    q = 0.0
    if tl > 0.0:
        q = min(friction * impulse, tl / w) / tl
    px = impulse * nx - q * tx
    py = impulse * ny - q * ty
    pz = impulse * nz - q * tz
    v[i, 0] -= wi * px
    v[i, 1] -= wi * py
    v[j, 0] += wj * px
    v[j, 1] += wj * py
    if dim == 3:
        v[i, 2] -= wi * pz
        v[j, 2] += wj * pz
    # the supported side passes its support on
    if side == 1:
        support[j] = True
    elif side == 2:
        support[i] = True


@njit(cache=True)
def _pair_position(x, inv_mass, radius, dv_step, support, pair_i, pair_j, p):
    """Overlap projection of one pair: mass-weighted (the centre of mass stays), or all on the
    supported particle's neighbour (see ``_pair_velocity``)."""
    dim = x.shape[1]
    i, j = pair_i[p], pair_j[p]
    rx = x[j, 0] - x[i, 0]
    ry = x[j, 1] - x[i, 1]
    rz = (x[j, 2] - x[i, 2]) if dim == 3 else 0.0
    dist = math.sqrt(rx * rx + ry * ry + rz * rz)
    overlap = radius[i] + radius[j] - dist
    if overlap <= 0.0:
        return
    if dist > 0.0:
        nx, ny, nz = rx / dist, ry / dist, rz / dist
    else:
        nx, ny, nz = 1.0, 0.0, 0.0
    wi, wj = inv_mass[i], inv_mass[j]
    ain = dv_step[i, 0] * nx + dv_step[i, 1] * ny + dv_step[i, 2] * nz
    ajn = dv_step[j, 0] * nx + dv_step[j, 1] * ny + dv_step[j, 2] * nz
    if support[i] and -ajn > 0.0 and 4.0 * ajn * ajn > dv_step[j, 0] ** 2 + dv_step[j, 1] ** 2 + dv_step[j, 2] ** 2:
        wi = 0.0
    elif support[j] and ain > 0.0 and 4.0 * ain * ain > dv_step[i, 0] ** 2 + dv_step[i, 1] ** 2 + dv_step[i, 2] ** 2:
        wj = 0.0
    w = wi + wj
    if w == 0.0:
        return
    si, sj = overlap * wi / w, overlap * wj / w
    x[i, 0] -= si * nx
    x[i, 1] -= si * ny
    x[j, 0] += sj * nx
    x[j, 1] += sj * ny
    if dim == 3:
        x[i, 2] -= si * nz
        x[j, 2] += sj * nz


@njit(cache=True)
def _near_lower_bound(cnear, cf, k, x, y, z):
    """The ``cnear`` lower bound of collider k's distance at (x, y, z) (scalars only)."""
    kind = cnear[k, 0]
    if kind == NEAR_PLANE:
        return cnear[k, 1] * x + cnear[k, 2] * y + cnear[k, 3] * z - cnear[k, 4]
    if kind == NEAR_BALL:
        return math.sqrt((x - cnear[k, 1]) ** 2 + (y - cnear[k, 2]) ** 2 + (z - cnear[k, 3]) ** 2) - cnear[k, 4]
    if kind == NEAR_PLANES:
        o, m = int(cnear[k, 1]), int(cnear[k, 2])
        lb = 1e300
        for p in range(m):
            b = o + 4 * p
            lb = min(lb, cf[b] * x + cf[b + 1] * y + cf[b + 2] * z - cf[b + 3])
        return lb
    if kind == NEAR_NEVER:
        return 1e300
    return -1e300


@njit(cache=True)
def _collider_clamp(i, x, v, radius, dv_step, cint, cnear, cmat, cf, ci, pose0, pose1, ref, inv_dt,
                    rest_speed, project, kinds, motion):
    """Project particle i out of the colliders (``project``) and remove its velocity into them
    (inelastic, with the collider's friction). Returns True when it touches a collider that
    holds it up (the surface normal within 60 degrees of the particle's applied pull, reversed)."""
    dim = x.shape[1]
    touching = False
    a = math.sqrt(dv_step[i, 0] ** 2 + dv_step[i, 1] ** 2 + dv_step[i, 2] ** 2)
    for _sweep in range(3):
        pushed = False
        for k in range(cint.shape[0]):
            if cint[k, 0] == _d.CALLABLE:
                continue
            z = x[i, 2] if dim == 3 else 0.0
            if _near_lower_bound(cnear, cf, k, x[i, 0], x[i, 1], z) - radius[i] > 1e-3 * radius[i]:
                continue
            d, nx, ny, nz, lx, ly, lz = _eval(cint, cf, ci, pose1, ref, k, x[i, 0], x[i, 1], z, kinds, motion)
            f = d - radius[i]
            if f > 1e-3 * radius[i]:
                continue
            if nx * dv_step[i, 0] + ny * dv_step[i, 1] + nz * dv_step[i, 2] < -0.5 * a:
                touching = True
            if f < 0.0 and project:
                pushed = True
                x[i, 0] -= f * nx
                x[i, 1] -= f * ny
                if dim == 3:
                    x[i, 2] -= f * nz
            ux, uy, uz = _surface_velocity(cint, pose0, pose1, ref, k, lx, ly, lz, inv_dt, motion)
            vz = v[i, 2] if dim == 3 else 0.0
            vx2, vy2, vz2, _hit = surface_response(v[i, 0], v[i, 1], vz, ux, uy, uz, nx, ny, nz,
                                                   0.0, cmat[k, 1], rest_speed)
            v[i, 0], v[i, 1] = vx2, vy2
            if dim == 3:
                v[i, 2] = vz2
        if not pushed:
            break
    return touching


@njit(cache=True, parallel=True)
def solve_pairs(x, v, inv_mass, radius, dv_step, pair_i, pair_j, color_start, color_order, ncolors,
                in_pair, support, cint, cnear, cmat, cf, ci, pose0, pose1, ref,
                dt, restitution, friction, rest_speed, iterations, kinds, motion):
    """Sphere-sphere contacts: Gauss-Seidel over colour batches (each batch in parallel).

    0. support: particles in pairs that touch a collider are supported; support persists while a
       particle stays in a pair and spreads through contacts (shock propagation, Guendelman et al.
       2003): a supported particle lying where its neighbour is pushed acts as infinitely heavy
       for it, so a pile rests in one sweep instead of sinking through slow iterations;
    1. velocity passes: pair impulses (restitution, friction; momentum conserving between free
       particles);
    2. position passes: remove overlaps by (mass-weighted) projection, no velocity change; then
       push the particles in pairs back out of the colliders, without velocity into them.
    """
    n = x.shape[0]
    inv_dt = 1.0 / dt
    for i in prange(n):
        if in_pair[i] == 0 or inv_mass[i] == 0.0:
            support[i] = inv_mass[i] == 0.0 and in_pair[i] != 0  # pinned particles support others
            continue
        if _collider_clamp(i, x, v, radius, dv_step, cint, cnear, cmat, cf, ci, pose0, pose1, ref, inv_dt,
                           rest_speed, False, kinds, motion):
            support[i] = True
        # particles within a radius of a collider are the ones the position passes may push in
        z = x[i, 2] if x.shape[1] == 3 else 0.0
        for k in range(cint.shape[0]):
            if cint[k, 0] != _d.CALLABLE and _near_lower_bound(cnear, cf, k, x[i, 0], x[i, 1], z) < 2.0 * radius[i]:
                in_pair[i] = 2
    for _ in range(iterations):
        for c in range(ncolors):
            if c == MAX_COLORS - 1:
                for q in range(color_start[c], color_start[c + 1]):
                    _pair_velocity(x, v, inv_mass, dv_step, support, pair_i, pair_j, color_order[q], restitution,
                                   friction, rest_speed)
            else:
                for q in prange(color_start[c], color_start[c + 1]):
                    _pair_velocity(x, v, inv_mass, dv_step, support, pair_i, pair_j, color_order[q], restitution,
                                   friction, rest_speed)
    for _ in range(iterations):
        for c in range(ncolors):
            if c == MAX_COLORS - 1:
                for q in range(color_start[c], color_start[c + 1]):
                    _pair_position(x, inv_mass, radius, dv_step, support, pair_i, pair_j, color_order[q])
            else:
                for q in prange(color_start[c], color_start[c + 1]):
                    _pair_position(x, inv_mass, radius, dv_step, support, pair_i, pair_j, color_order[q])
        # colliders win over pairs
        for i in prange(n):
            if in_pair[i] == 2 and inv_mass[i] != 0.0:
                _collider_clamp(i, x, v, radius, dv_step, cint, cnear, cmat, cf, ci, pose0, pose1, ref, inv_dt,
                                rest_speed, True, kinds, motion)


# --- the kernels a scene runs: one bundle per kind set (see ``kernels_for``) -------------------
_DISPATCHED = {name: SizeDispatched(globals()[name]) for name in (
    "copy_into", "classify_contacts", "push_out", "collide_particles", "step_and_collide",
    "resting_filter", "mark_pairs", "solve_pairs")}
_BROADPHASE = {name: SizeDispatched(getattr(_bp, name), serial=getattr(_bp, name + "_serial"))
               for name in ("bin_particles", "gather", "scatter", "count_pairs", "fill_pairs")}
_TAKES_KINDS = ("classify_contacts", "push_out", "collide_particles", "step_and_collide", "solve_pairs")


class _WithKinds:
    """A size-dispatched kernel with the bundle's ``kinds`` and ``motion`` appended to its arguments."""

    __slots__ = ("dispatched", "kinds", "motion")

    def __init__(self, dispatched, kinds, motion):
        self.dispatched, self.kinds, self.motion = dispatched, kinds, motion

    def __call__(self, *args):
        return self.dispatched(*args, self.kinds, self.motion)

    def pick(self, n):
        """The build for a first argument of n elements (``SizeDispatched.pick``), kinds bound."""
        build, kinds, motion = self.dispatched.pick(n), self.kinds, self.motion
        return lambda *args: build(*args, kinds, motion)


class ParticleKernels:
    """The particle collision kernels of one kind set (``kernels_for``).

    Attributes: ``copy_into``, ``classify_contacts``, ``push_out``, ``collide_particles``,
    ``step_and_collide``, ``resting_filter``, ``mark_pairs``, ``solve_pairs`` (this module) and
    the broad phase's ``bin_particles``, ``gather``, ``scatter``, ``count_pairs``,
    ``fill_pairs``: each called with the arguments documented on the kernel (without
    ``kinds`` and ``motion``), running its serial twin below ``inertia._jit.SERIAL_BELOW``
    elements of its first argument and its parallel build above (``.pick(n)`` chooses by
    another count, e.g. the pair solver by the number of pairs). ``kinds``: the kind codes
    compiled in; ``moving``: whether the moving-collider code (rest-frame transforms, surface
    velocities) is compiled in.
    """

    def __init__(self, kinds: frozenset, moving: bool = True):
        self.kinds = kinds
        self.moving = bool(moving)
        token = _d.kinds_token(kinds)
        motion = motion_token(moving)
        for name, dispatched in _DISPATCHED.items():
            setattr(self, name, _WithKinds(dispatched, token, motion) if name in _TAKES_KINDS else dispatched)
        for name, dispatched in _BROADPHASE.items():
            setattr(self, name, dispatched)

    def __repr__(self):
        names = ", ".join(_d.KIND_NAMES[k] for k in sorted(self.kinds)) or "none"
        return f"ParticleKernels({names}{', moving' if self.moving else ''})"


_BUNDLES: dict = {}

#: The kind sets compiled: scenes whose colliders are all planes (a ground: the fountain, most
#: particle examples) get kernels with only the plane's distance and time of impact; scenes of
#: planes, spheres and containers (a ground, a ball, a room) get those three; any other scene
#: gets every kind. Three nested sets, not one per combination, so that a process (a test
#: suite, a sweep of scenes) compiles each kernel at most three times.
PLANE_KINDS = frozenset((_d.PLANE,))
LIGHT_KINDS = frozenset((_d.PLANE, _d.SPHERE, _d.CONTAINER))
ALL_KINDS = frozenset(range(_d.GRID + 1))


def motion_token(moving: bool):
    """The ``motion`` argument of the collision kernels: True when some collider moves, None when
    all are static. Numba types None apart, and the kernels test ``motion is not None`` before
    any rest-frame transform or surface velocity, so with None that code is pruned before typing
    (a scene of static colliders compiles about a quarter less; both give the same bits, the
    flags column of ``cint`` deciding at run time which colliders move)."""
    return True if moving else None


def kernels_for(kinds, moving: bool = True) -> ParticleKernels:
    """The collision kernels compiled for the collider kinds a scene uses.

    ``kinds``: kind codes (``distance.PLANE`` ...; ``moving``: whether to compile the
    moving-collider code in), or the packed ``cint`` (K, 4) table whose first column holds them
    (the moving-collider code is then compiled in when some row's flags mark it moving, see
    ``motion_token``). The kernels
    are compiled for ``LIGHT_KINDS`` when every kind is in it and for ``ALL_KINDS`` otherwise;
    the signed distances and times of impact of the kinds left out are not compiled (a scene of
    planes compiles about 60 % of the code of one with every shape, and the first frame of the
    fountain comes 35 % sooner), and both give the same bits. Bundles are cached; the lookup
    from a ``cint`` table reads every row's kind (a list of K ints), so a stepping caller keeps
    the bundle until its table changes (``ParticleCollisionData.kernels``, set by ``_pack``).
    """
    if hasattr(kinds, "ndim") and kinds.ndim == 2:
        moving = bool((kinds[:, 1] & 1).any())
        kinds = kinds[:, 0].tolist()
    used = {int(k) for k in kinds if 0 <= int(k) <= _d.GRID}
    compiled = next(k for k in (PLANE_KINDS, LIGHT_KINDS, ALL_KINDS) if used <= k)
    key = (compiled, bool(moving))
    bundle = _BUNDLES.get(key)
    if bundle is None:
        bundle = _BUNDLES[key] = ParticleKernels(*key)
    return bundle
