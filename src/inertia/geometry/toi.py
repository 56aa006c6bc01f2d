"""Time of impact of two moving convex shapes by conservative advancement (continuous collision for bullets).

Stage: called after the broad phase for pairs with a fast ("bullet") body, on the shapes' poses at the
start (``pose0``) and end (``pose1``) of the step; the world then moves the bullet to its pose at the
returned fraction (or clamps its velocity) so it cannot pass through a thin wall in one step.

Motion model over the step fraction ``t`` in [0, 1]: the shape's origin moves on the straight line
``p0 + t (p1 - p0)`` and its orientation turns at a constant rate about one axis from ``q0`` to ``q1``
(``q(t) = exp(t log(q1 q0*)) q0``, the shortest arc).

Algorithm: conservative advancement (Mirtich 1996, ch. 4; as used by Catto 2013 for bullets). At the current
``t`` GJK gives the distance ``d`` and the normal ``n`` (``inertia.geometry.convex.gjk_distance``, exact for
polytopes and, through their cores, spheres and capsules). The distance cannot fall faster than
``mu = (v_b - v_a) . (-n)`` plus ``|w_a| rmax_a + |w_b| rmax_b`` (rates per unit ``t``; ``rmax`` the largest
distance of the shape from its origin): for translation alone this is exact because the distance between
two convex sets moving on lines is a convex function of ``t``. So ``t += (d - target) / mu`` never steps past
the first contact; it stops when ``d <= target + tolerance`` (hit) or ``t`` passes 1 (no hit).

Returns ``(toi, normal, point)``: the fraction of the step at first contact (1.0 and a zero normal when the
shapes never touch within the step; 0.0 when they already overlap at ``t = 0``), the unit normal from A to B
and the point midway between the surfaces at that time.

References
- Mirtich, B. (1996). Impulse-based dynamic simulation of rigid body systems. PhD thesis, UC Berkeley
  (conservative advancement).
- Catto, E. (2013). Continuous collision. Game Developers Conference.
- Gilbert, E. G., Johnson, D. W. and Keerthi, S. S. (1988). GJK (see ``inertia.geometry.convex``).

Limitations
- Convex shapes only (sphere, box, capsule, cylinder, hull); against a plane use a large box, against a
  mesh the speculative contacts of the narrow phase.
- The motion between poses is the straight line + constant rotation above, not the body's true path about
  its centre of mass when a shape is offset from it (the caller can pass the body pose and the shape's
  local pose folded in: the error is then O(|w| dt)^2 of the offset).
- A grazing approach converges linearly (many GJK calls); ``max_iterations`` caps it, returning the last
  safe (not yet touching) fraction.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from inertia import math as _m

from . import convex as CV

__all__ = ["time_of_impact", "time_of_impact_batch", "toi_kernel", "shape_bound_radius"]

TOI_MAX_ITERATIONS = 64


@njit(cache=True)
def shape_bound_radius(shape_type, params, verts, vert_start, vert_count):
    """Largest distance of the shape's points from its local origin (m)."""
    if shape_type == CV.SPHERE:
        return params[0]
    if shape_type == CV.BOX:
        return math.sqrt(params[0] ** 2 + params[1] ** 2 + params[2] ** 2)
    if shape_type == CV.CAPSULE:
        return params[0] + params[1]
    if shape_type == CV.CYLINDER:
        return math.sqrt(params[0] ** 2 + params[1] ** 2)
    r = 0.0
    for i in range(vert_start, vert_start + vert_count):
        r = max(r, math.sqrt(verts[i, 0] ** 2 + verts[i, 1] ** 2 + verts[i, 2] ** 2))
    return r


@njit(cache=True)
def _rotation_step(q0, q1):
    """Axis (unit) and angle (rad, in [0, pi]) of the shortest rotation taking q0 to q1."""
    dq = _m.quat_mul(q1, _m.quat_conj(q0))
    if dq[0] < 0.0:
        dq = -dq
    s = math.sqrt(dq[1] ** 2 + dq[2] ** 2 + dq[3] ** 2)
    axis = np.array([0.0, 0.0, 1.0])
    if s <= 1e-15:
        return axis, 0.0
    axis = dq[1:4] / s
    return axis, 2.0 * math.atan2(s, dq[0])


@njit(cache=True)
def _pose_at(pose0, pose1, axis, angle, t, out):
    for k in range(3):
        out[k] = pose0[k] + t * (pose1[k] - pose0[k])
    if angle == 0.0:
        out[3:7] = pose0[3:7]
    else:
        out[3:7] = _m.quat_normalize(_m.quat_mul(_m.quat_from_axis_angle(axis, angle * t), pose0[3:7]))


@njit(cache=True)
def toi_kernel(type_a, params_a, start_a, count_a, pose_a0, pose_a1, type_b, params_b, start_b, count_b,
               pose_b0, pose_b1, verts, target, tolerance, max_iterations):
    """Conservative advancement (module docstring). Returns (toi, normal (3,), point (3,), witness_b (3,),
    hit): ``point`` midway between the surfaces, ``witness_b`` on B's surface, ``hit`` False when the shapes
    do not come within ``target + tolerance`` in the step (then toi = 1.0 and zero vectors)."""
    axis_a, ang_a = _rotation_step(pose_a0[3:7], pose_a1[3:7])
    axis_b, ang_b = _rotation_step(pose_b0[3:7], pose_b1[3:7])
    va = pose_a1[0:3] - pose_a0[0:3]
    vb = pose_b1[0:3] - pose_b0[0:3]
    spin = ang_a * shape_bound_radius(type_a, params_a, verts, start_a, count_a) + \
        ang_b * shape_bound_radius(type_b, params_b, verts, start_b, count_b)
    pa = np.empty(7)
    pb = np.empty(7)
    t = 0.0
    normal = np.zeros(3)
    point = np.zeros(3)
    witness_b = np.zeros(3)
    for _ in range(max_iterations):
        _pose_at(pose_a0, pose_a1, axis_a, ang_a, t, pa)
        _pose_at(pose_b0, pose_b1, axis_b, ang_b, t, pb)
        d, wa, wb, n, separated = CV.gjk_distance(type_a, params_a, pa, start_a, count_a, type_b, params_b, pb,
                                                  start_b, count_b, verts)
        if not separated or d <= target + tolerance:
            if separated:
                normal[:] = n
                point[:] = 0.5 * (wa + wb)
                witness_b[:] = wb
            else:
                # cores overlap (only at t = 0, or a deep start): report the shape centres' direction
                c = pb[0:3] - pa[0:3]
                ln = math.sqrt(_m.dot(c, c))
                if ln > 0.0:
                    normal[:] = c / ln
                point[:] = 0.5 * (pa[0:3] + pb[0:3])
                witness_b[:] = point
            return t, normal, point, witness_b, True
        approach = -((vb[0] - va[0]) * n[0] + (vb[1] - va[1]) * n[1] + (vb[2] - va[2]) * n[2]) + spin
        if approach <= 0.0:
            break
        t_next = t + (d - target) / approach
        if t_next > 1.0:
            break
        t = t_next
    else:
        # out of iterations: the last t is safe (the shapes do not touch before it)
        return t, normal, point, witness_b, True
    return 1.0, normal, point, witness_b, False


def _shape_args(shape, name):
    if len(shape) == 2:
        shape_type, params = shape
        verts = None
    elif len(shape) == 3:
        shape_type, params, verts = shape
    else:
        raise ValueError(f"{name} must be (shape_type, params) or (shape_type, params, hull_vertices); "
                         f"got {len(shape)} items")
    from . import shapes as S
    if isinstance(shape_type, str):
        if shape_type not in S.SHAPE_NAMES:
            raise ValueError(f"{name} type must be one of {sorted(S.SHAPE_NAMES)}; got {shape_type!r}")
        shape_type = S.SHAPE_NAMES[shape_type]
    if int(shape_type) not in (S.SPHERE, S.BOX, S.CAPSULE, S.CYLINDER, S.CONVEX_HULL):
        raise ValueError(f"{name} type must be a convex shape (sphere, box, capsule, cylinder, convex_hull); "
                         f"got {shape_type!r}")
    p = np.zeros(4)
    flat = np.asarray(params, dtype=np.float64).reshape(-1)
    p[:flat.size] = flat[:4]
    v = np.zeros((0, 3)) if verts is None else np.ascontiguousarray(verts, dtype=np.float64).reshape(-1, 3)
    if int(shape_type) == S.CONVEX_HULL and v.shape[0] < 4:
        raise ValueError(f"{name}: a convex_hull needs its vertices (N >= 4, shape (N, 3))")
    return int(shape_type), p, v


def _pose_arg(pose, name):
    p = np.asarray(pose, dtype=np.float64).reshape(-1)
    if p.size != 7 or not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be 7 finite numbers (px, py, pz, qw, qx, qy, qz); got {pose!r}")
    nq = float(np.linalg.norm(p[3:]))
    if abs(nq - 1.0) > 1e-6:
        raise ValueError(f"{name} quaternion must be unit length; got |q| = {nq}")
    return p


def time_of_impact(shape_a, pose_a0, pose_a1, shape_b, pose_b0, pose_b1, *, target: float = 0.0,
                   tolerance: float = 1e-9, max_iterations: int = TOI_MAX_ITERATIONS):
    """First contact of two convex shapes moving from their poses ``*0`` to ``*1`` over one step.

    ``shape_a``/``shape_b``: ``(shape_type, params)`` or ``(shape_type, params, hull_vertices)`` with
    ``shape_type`` a name ("sphere", "box", "capsule", "cylinder", "convex_hull") or code and ``params`` as in
    the shape table. Poses: 7 numbers (position, unit quaternion w, x, y, z). ``target`` (m): stop this far
    apart (e.g. a linear slop); ``tolerance`` (m): accepted distance above ``target``.
    Returns ``(toi, normal, point)``: step fraction in [0, 1] (1.0 = no contact within the step), unit normal
    A -> B and the midpoint between the surfaces at that time."""
    ta, pa, va = _shape_args(shape_a, "shape_a")
    tb, pb, vb = _shape_args(shape_b, "shape_b")
    verts = np.concatenate([va, vb]) if (va.size or vb.size) else np.zeros((1, 3))
    if target < 0.0 or tolerance <= 0.0:
        raise ValueError(f"target must be >= 0 and tolerance > 0; got target={target}, tolerance={tolerance}")
    toi, n, p, _, _ = toi_kernel(ta, pa, 0, va.shape[0], _pose_arg(pose_a0, "pose_a0"), _pose_arg(pose_a1, "pose_a1"),
                              tb, pb, va.shape[0], vb.shape[0], _pose_arg(pose_b0, "pose_b0"),
                              _pose_arg(pose_b1, "pose_b1"), verts, float(target), float(tolerance),
                              int(max_iterations))
    return float(toi), n, p


@njit(cache=True, parallel=True)
def time_of_impact_batch(pairs, npairs, shape_type, shape_params, shape_vert_start, shape_vert_count,
                         geom_vertices, pose0, pose1, target, tolerance, out_toi, out_normal, out_point):
    """Time of impact for candidate pairs ``pairs[:npairs]`` (shape indices into the shape table) with
    shape world poses ``pose0``/``pose1 (S, 7)`` at the start/end of the step. Writes ``out_toi (P,)``
    (fraction, 1.0 = no contact), ``out_normal (P, 3)`` (A -> B) and ``out_point (P, 3)``; each pair writes
    only its own row (deterministic under any thread count). Only convex shape types are valid."""
    for i in prange(npairs):
        sa = pairs[i, 0]
        sb = pairs[i, 1]
        toi, n, p, _, _ = toi_kernel(shape_type[sa], shape_params[sa], shape_vert_start[sa], shape_vert_count[sa],
                                  pose0[sa], pose1[sa], shape_type[sb], shape_params[sb], shape_vert_start[sb],
                                  shape_vert_count[sb], pose0[sb], pose1[sb], geom_vertices, target, tolerance,
                                  TOI_MAX_ITERATIONS)
        out_toi[i] = toi
        for k in range(3):
            out_normal[i, k] = n[k]
            out_point[i, k] = p[k]
