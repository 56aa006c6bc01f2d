"""Broad phase for the shape table: world poses, swept AABBs and sort-and-sweep pairs.

Stages (read -> write)
- ``shape_world_bounds``: body_q, body_qd, shape table -> ``shape_world_pose (S, 7)``, ``shape_aabb (S, 6)``
  (min xyz, max xyz), each box fattened by the shape's margin and swept by the body's motion over dt
  (linear velocity one-sided, angular velocity times the body's bounding radius on all sides), so a
  fast body's box covers where it will be: speculative contacts need the pair before the impact.
- ``sort_and_sweep_into``: AABBs -> candidate pairs ``(P, 2) int32`` in canonical order (lower shape type
  first, ties by index) sorted by ``shape_a * S + shape_b``. Sorting the box minima along the axis of
  largest spread is O(S log S); the sweep visits each overlapping interval once (O(S + k) for k
  overlaps along that axis). Filters: same body, no dynamic awake endpoint, collision groups/masks.
  Both sorts are a stable bottom-up merge sort into caller-owned scratch (the order of NumPy's
  ``argsort(kind="mergesort")``, NaN last), so a world's step allocates nothing here; ``sort_and_sweep``
  is the same with its scratch allocated per call (tests, one-off use).

References: Baraff, D. (1992). Dynamic simulation of non-penetrating rigid bodies (PhD thesis, Cornell),
ch. 6 "sort and sweep"; Cohen, Lin, Manocha and Ponamgi (1995). I-COLLIDE.
Limitations: one sweep axis (a pile spread along all three axes still tests every box of a slab);
planes and other unbounded shapes get infinite boxes and pair with every dynamic shape.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import shapes as S
from ._tup import qmul, qrot

__all__ = ["shape_world_bounds", "sort_and_sweep", "sort_and_sweep_into"]

_BIG = 1e30


@njit(cache=True)
def _bounds_one(s, geom_vertices, shape_body, shape_local_pose, shape_margin, shape_params, shape_type,
                shape_vert_count, shape_vert_start, body_type, body_bound_radius, body_q, body_qd, dt, pose_out,
                aabb_out):
    b = shape_body[s]
    lp = shape_local_pose[s]
    lq = (lp[3], lp[4], lp[5], lp[6])
    if b >= 0:
        bq = body_q[b]
        q = (bq[3], bq[4], bq[5], bq[6])
        rp = qrot(q, (lp[0], lp[1], lp[2]))
        c = (bq[0] + rp[0], bq[1] + rp[1], bq[2] + rp[2])
        wq = qmul(q, lq)
    else:
        c = (lp[0], lp[1], lp[2])
        wq = lq
    pose_out[s, 0] = c[0]
    pose_out[s, 1] = c[1]
    pose_out[s, 2] = c[2]
    pose_out[s, 3] = wq[0]
    pose_out[s, 4] = wq[1]
    pose_out[s, 5] = wq[2]
    pose_out[s, 6] = wq[3]
    t = shape_type[s]
    p = shape_params[s]
    ex = (0.0, 0.0, 0.0)
    if t == S.SPHERE:
        ex = (p[0], p[0], p[0])
    elif t == S.BOX:
        ax = qrot(wq, (1.0, 0.0, 0.0))
        ay = qrot(wq, (0.0, 1.0, 0.0))
        az = qrot(wq, (0.0, 0.0, 1.0))
        ex = (abs(ax[0]) * p[0] + abs(ay[0]) * p[1] + abs(az[0]) * p[2],
              abs(ax[1]) * p[0] + abs(ay[1]) * p[1] + abs(az[1]) * p[2],
              abs(ax[2]) * p[0] + abs(ay[2]) * p[1] + abs(az[2]) * p[2])
    elif t == S.CAPSULE:
        az = qrot(wq, (0.0, 0.0, 1.0))
        ex = (abs(az[0]) * p[1] + p[0], abs(az[1]) * p[1] + p[0], abs(az[2]) * p[1] + p[0])
    elif t == S.CYLINDER:
        az = qrot(wq, (0.0, 0.0, 1.0))
        ex = (p[0] * math.sqrt(max(0.0, 1.0 - az[0] * az[0])) + abs(az[0]) * p[1],
              p[0] * math.sqrt(max(0.0, 1.0 - az[1] * az[1])) + abs(az[1]) * p[1],
              p[0] * math.sqrt(max(0.0, 1.0 - az[2] * az[2])) + abs(az[2]) * p[1])
    # the box as six scalars (a list here would be a heap allocation per shape)
    lo0, lo1, lo2 = c[0] - ex[0], c[1] - ex[1], c[2] - ex[2]
    hi0, hi1, hi2 = c[0] + ex[0], c[1] + ex[1], c[2] + ex[2]
    if t == S.CONVEX_HULL or t == S.TRIANGLE_MESH or t == S.HEIGHTFIELD or t == S.SDF:
        # vertices (an SDF row's: the 8 corners of its field's box)
        v0 = shape_vert_start[s]
        lo0, lo1, lo2 = _BIG, _BIG, _BIG
        hi0, hi1, hi2 = -_BIG, -_BIG, -_BIG
        for i in range(v0, v0 + shape_vert_count[s]):
            v = geom_vertices[i]
            w = qrot(wq, (v[0], v[1], v[2]))
            x, y, z = c[0] + w[0], c[1] + w[1], c[2] + w[2]
            lo0, lo1, lo2 = min(lo0, x), min(lo1, y), min(lo2, z)
            hi0, hi1, hi2 = max(hi0, x), max(hi1, y), max(hi2, z)
    elif t == S.PLANE:
        # half-space z_local <= 0: bounded only along an axis the normal is aligned with
        n = qrot(wq, (0.0, 0.0, 1.0))
        lo0, lo1, lo2 = -_BIG, -_BIG, -_BIG
        hi0, hi1, hi2 = _BIG, _BIG, _BIG
        if abs(n[0]) > 1.0 - 1e-12:
            if n[0] > 0:
                hi0 = c[0]
            else:
                lo0 = c[0]
        if abs(n[1]) > 1.0 - 1e-12:
            if n[1] > 0:
                hi1 = c[1]
            else:
                lo1 = c[1]
        if abs(n[2]) > 1.0 - 1e-12:
            if n[2] > 0:
                hi2 = c[2]
            else:
                lo2 = c[2]
    m = shape_margin[s]
    ang = 0.0
    lin = (0.0, 0.0, 0.0)
    if b >= 0 and body_type[b] != S.STATIC:
        qd = body_qd[b]
        ang = dt * math.sqrt(qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2]) * body_bound_radius[b]
        ang = min(ang, 2.0 * body_bound_radius[b])
        lin = (qd[3] * dt, qd[4] * dt, qd[5] * dt)
    aabb_out[s, 0] = lo0 - m - ang + min(0.0, lin[0])
    aabb_out[s, 1] = lo1 - m - ang + min(0.0, lin[1])
    aabb_out[s, 2] = lo2 - m - ang + min(0.0, lin[2])
    aabb_out[s, 3] = hi0 + m + ang + max(0.0, lin[0])
    aabb_out[s, 4] = hi1 + m + ang + max(0.0, lin[1])
    aabb_out[s, 5] = hi2 + m + ang + max(0.0, lin[2])


@njit(cache=True)
def _bounds_range(lo, hi, shapes, body_type, body_bound_radius, body_q, body_qd, dt, pose_out, aabb_out):
    # the shape table's arrays as locals (a NamedTuple member read per shape costs a reference count)
    verts, body, local_pose = shapes.geom_vertices, shapes.shape_body, shapes.shape_local_pose
    margin, params, types = shapes.shape_margin, shapes.shape_params, shapes.shape_type
    vstart, vcount = shapes.shape_vert_start, shapes.shape_vert_count
    for s in range(lo, hi):
        _bounds_one(s, verts, body, local_pose, margin, params, types, vcount, vstart, body_type,
                    body_bound_radius,
                    body_q, body_qd, dt, pose_out, aabb_out)


@njit(cache=True, parallel=True)
def shape_world_bounds(shapes, body_type, body_bound_radius, body_q, body_qd, dt, pose_out, aabb_out):
    """World pose and swept, margin-fattened AABB of every shape (one row per iteration)."""
    n = shapes.shape_type.shape[0]
    nch = min(n, 16)
    for ch in prange(nch):
        _bounds_range(n * ch // nch, n * (ch + 1) // nch, shapes, body_type, body_bound_radius, body_q,
                      body_qd, dt, pose_out, aabb_out)


@njit(cache=True)
def _may_collide(sa, sb, shape_body, shape_group, shape_mask, body_type, body_awake):
    ba = shape_body[sa]
    bb = shape_body[sb]
    if ba == bb:
        return False
    a_active = ba >= 0 and body_type[ba] == S.DYNAMIC and body_awake[ba]
    b_active = bb >= 0 and body_type[bb] == S.DYNAMIC and body_awake[bb]
    if not (a_active or b_active):
        return False
    if (shape_group[sa] & shape_mask[sb]) == 0:
        return False
    if (shape_group[sb] & shape_mask[sa]) == 0:
        return False
    return True


@njit(cache=True)
def _less(a, b):
    """NumPy's sort order: NaN after every number."""
    return a < b or (b != b and a == a)


@njit(cache=True)
def _stable_argsort_into(vals, idx, tmp, n):
    """idx[:n] = the permutation that sorts vals[:n], stable (ties in index order), as
    ``np.argsort(vals[:n], kind="mergesort")`` gives it; tmp (>= n,) int64 is scratch. Bottom-up merge
    sort (O(n log n), no allocation)."""
    for i in range(n):
        idx[i] = i
    src, dst = idx, tmp
    in_tmp = False              # whether src is tmp (the merged runs alternate between the two)
    width = 1
    while width < n:
        lo = 0
        while lo < n:
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            a, b, k = lo, mid, lo
            while a < mid and b < hi:
                if _less(vals[src[b]], vals[src[a]]):
                    dst[k] = src[b]
                    b += 1
                else:
                    dst[k] = src[a]
                    a += 1
                k += 1
            while a < mid:
                dst[k] = src[a]
                a += 1
                k += 1
            while b < hi:
                dst[k] = src[b]
                b += 1
                k += 1
            lo = hi
        src, dst = dst, src
        in_tmp = not in_tmp
        width *= 2
    if in_tmp:
        for i in range(n):
            idx[i] = tmp[i]


@njit(cache=True)
def sort_and_sweep(aabb, shapes, body_type, body_awake, order, keys, pairs_out):
    """`sort_and_sweep_into` with its scratch allocated here (for tests and one-off calls; a world keeps
    the scratch and calls `sort_and_sweep_into`)."""
    n = max(aabb.shape[0], keys.shape[0])
    return sort_and_sweep_into(aabb, shapes, body_type, body_awake, order, keys, pairs_out,
                               np.empty(n, np.int64), np.empty(n, np.int64))


@njit(cache=True)
def sort_and_sweep_into(aabb, shapes, body_type, body_awake, order, keys, pairs_out, perm, tmp):
    """Candidate pairs of overlapping AABBs into ``pairs_out`` (capacity rows), sorted by key.

    ``order`` (S,) int64 and ``keys`` (capacity,) int64 are outputs used as scratch; ``perm`` and ``tmp``
    (>= max(S, capacity),) int64 are scratch: nothing is allocated. Returns the pair count; if it
    exceeds the capacity nothing is written past it and the caller grows the buffers and calls again.
    """
    # the shape table's arrays as locals: a NamedTuple member read inside the loop costs a reference count
    shape_body, shape_group, shape_mask, shape_type = (shapes.shape_body, shapes.shape_group, shapes.shape_mask,
                                                       shapes.shape_type)
    ns = aabb.shape[0]
    # sweep axis: largest spread of the finite box centres
    best_axis, best_var = 0, -1.0
    for k in range(3):
        n, s1, s2 = 0, 0.0, 0.0
        for i in range(ns):
            if aabb[i, k] > -_BIG * 0.5 and aabb[i, 3 + k] < _BIG * 0.5:
                c = 0.5 * (aabb[i, k] + aabb[i, 3 + k])
                n += 1
                s1 += c
                s2 += c * c
        if n > 0:
            var = s2 / n - (s1 / n) ** 2
            if var > best_var:
                best_var, best_axis = var, k
    # box minima along the axis, stable order (ties by shape index)
    _stable_argsort_into(aabb[:, best_axis], order, tmp, ns)
    cap = pairs_out.shape[0]
    count = np.int64(0)  # int64 from the start: a literal 0 would compile _stable_argsort_into twice
    for ii in range(ns):
        i = order[ii]
        hi_i = aabb[i, 3 + best_axis]
        for jj in range(ii + 1, ns):
            j = order[jj]
            if aabb[j, best_axis] > hi_i:
                break
            if (aabb[i, 0] > aabb[j, 3] or aabb[j, 0] > aabb[i, 3] or aabb[i, 1] > aabb[j, 4]
                    or aabb[j, 1] > aabb[i, 4] or aabb[i, 2] > aabb[j, 5] or aabb[j, 2] > aabb[i, 5]):
                continue
            if not _may_collide(i, j, shape_body, shape_group, shape_mask, body_type, body_awake):
                continue
            a, b = i, j
            ta, tb = shape_type[a], shape_type[b]
            if ta > tb or (ta == tb and a > b):
                a, b = b, a
            if count < cap:
                keys[count] = np.int64(a) * ns + b
            count += 1
    if count > cap:
        return count
    # canonical order: by key (unique per pair), so the narrow phase output and the warm-start merge
    # do not depend on the sweep axis; the pair is the key decoded (a = key // S, b = key % S)
    _stable_argsort_into(keys, perm, tmp, count)
    for r in range(count):
        tmp[r] = keys[perm[r]]
    for r in range(count):
        key = tmp[r]
        keys[r] = key
        pairs_out[r, 0] = key // ns
        pairs_out[r, 1] = key % ns
    return count
