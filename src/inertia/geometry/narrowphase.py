"""Narrow phase: closed-form contact manifolds (up to four points, with feature keys) per candidate pair.

Stage ``narrow_phase`` (read -> write): candidate pairs, shape world poses, body velocities ->
`inertia.dynamics.contacts.Contacts` rows (``contact_point_count``, normal A->B, points midway between
the surfaces, separations, feature keys, combined material, tangent basis). Manifold ``i`` belongs to
pair ``i``; each iteration writes only its own row, so the parallel loop is deterministic.

Speculative contacts (continuous collision): a pair keeps every point whose gap is below
``max(margin_a, margin_b) + dt * (|v_b - v_a| + |w_a| r_a + |w_b| r_b)`` -- the distance the bodies can
close in one step -- and the solver lets the gap close to zero but not beyond (Catto 2024, "soft step"
speculative contacts). A fast sphere therefore stops at a thin wall instead of passing it.

Convex shapes against baked signed-distance rows (``SDF``): sampled surface points against the distance
grid, ``inertia.geometry.sdf_collide`` (``narrow_phase_sdf``).

Closed-form pairs (A has the lower type code): sphere-sphere, sphere-box, sphere-capsule, sphere-plane,
box-box, box-plane, capsule-capsule, capsule-plane, cylinder-plane, hull-plane. Every other pair of convex
shapes (sphere, box, capsule, cylinder, hull; box-capsule included) takes the general path
``_convex_general``: GJK on the cores gives the exact distance and witnesses when separated (spheres and
capsules are a point/segment plus radius), EPA on the cores the depth and normal when they overlap; the
support features of both shapes along that normal (vertex, segment, polygon) give the manifold by
clipping the incident feature against the side planes of the reference one (the feature facing the
normal better; a polygon before a segment), the normal snapped to the reference face's, separations
measured to the reference plane, at most four points kept, feature key = incident vertex / clip plane.
Box-capsule is therefore exact: the closest points of segment and box by GJK, two clipped points when the
capsule lies parallel to a face.
Box-box is the separating-axis test over the 15 axes with a hysteresis that prefers faces to edges,
reference/incident face clipping (Sutherland-Hodgman), and reduction to four points (deepest point,
farthest point, largest triangle, largest quad) after Gregorius (2015).

References
- Gregorius, D. (2013). The separating axis test between convex polyhedra. GDC.
- Gregorius, D. (2015). Robust contact creation for physics simulations. GDC.
- Catto, E. (2024). Solver2D / Box2D v3: speculative contacts, feature ids for warm starting.
- Ericson, C. (2005). Real-Time Collision Detection, 5.1.9 (closest points of two segments).
- Gilbert, Johnson and Keerthi (1988) GJK; van den Bergen (2001) EPA: see ``inertia.geometry.convex``.

Kernels and compilation: pairs fall in families (``pair_family``): closed forms, the general convex path
(GJK/EPA), triangle meshes/heightfields and baked SDFs (``sdf_collide.narrow_phase_sdf``).
``narrow_phase_closed`` writes every pair's row (shapes, bodies, key, combined material, zeroed impulses)
and the closed-form manifolds; ``narrow_phase_general``, ``narrow_phase_mesh`` and ``narrow_phase_sdf``
then fill their own pairs' manifolds. A world calls the last three only when its shape types can form
such pairs (``scene_families``), so a scene of boxes, spheres and planes never compiles GJK/EPA, the
triangle or the SDF routines (the largest part of the narrow phase's cold compile). Within the closed
forms, ``narrow_phase_closed`` compiles the pair routines of the scene's shape types only (its ``closed``
argument, ``closed_token``: sphere and plane pairs; sphere, box and plane pairs; or every closed form), so
a pile of boxes never compiles the capsule, cylinder and hull routines. The helpers are ordinary compiled
functions, not forced inline (``inline="always"`` re-types a helper's body at every call site: the solver
and narrow phase compiled about twice as long with it, and LLVM inlines the small ones anyway). Each run of pairs
unpacks the bundles into locals once and hands the pair routines a four-array ``ManifoldOut``, not the
whole contact buffer (passing and reading members of a large bundle per pair cost half the stage's
time). ``narrow_phase`` runs the four in that order.

Limitations
- Scratch: clipping, point reduction and the general path's features work in a `NarrowScratch`, GJK/EPA
  in a `GjkScratch` (``inertia.geometry.convex``), the mesh, heightfield and SDF pairs in a `MeshScratch`
  (candidate triangles, BVH stack, vertex and sample rows): one row per run of pairs of banks a world
  makes once (`NarrowWork`, ``new_narrow_work``), so no family allocates per pair nor per step
  (test_narrowphase, test_sdf_collide and tests/rigid/test_step_allocations*.py count Numba's NRT
  allocations). The mesh bank's candidate slots are doubled after a step that overflowed them
  (``fit_narrow_work``; that step's pair used a temporary list), so that growth is amortised.
- Curved cylinder sides converge in EPA only to its tolerance (~1e-6 m) when a cylinder's side is deep in
  a shape that is not a polytope face (parallel round sides and faces snap the normal exactly).
- A support feature is flat within ~2 degrees (``FEATURE_SIN``); a cylinder cap is a 12-gon on its rim.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from . import shapes as S
from . import convex as CV
from .bvh import STACK_SIZE
from ._tup import add, cross, dot, madd, norm, normalize, orthonormal_basis, qrot, qrot_inv, scale, sub

__all__ = ["narrow_phase", "narrow_phase_closed", "narrow_phase_general", "narrow_phase_mesh", "scene_families",
           "closed_token", "CLOSED_PAIRS",
           "match_warm_start", "NarrowWork", "new_narrow_work", "fit_narrow_work", "scene_mesh_rows"]

_inl = njit(cache=True)

# Counters and feature codes handed to other kernels start as ``np.int64(0)`` (typed int64), not the
# literal 0: a literal types as Literal[int](0) (a global int64 constant too), and every kernel the call
# reaches then compiles once more for the literal (measured: _box_face_manifold, _reduce_and_emit and
# _emit twice each).

# Rows of the per-run scratch (module docstring, "Scratch"): enough for every clip in this module (a box
# face: 4 + 2 * 4 points; the general path: a feature of at most _MAX_FEATURE points clipped by at most
# _MAX_FEATURE side planes: _MAX_FEATURE + 2 * _MAX_FEATURE + 4); a hull with more vertices against a
# plane allocates.
SCRATCH_ROWS = 128

# contiguous runs of pairs, one call each (passing the bundles costs once per run, not per pair); one row
# of the scratch banks (`NarrowWork`) per run
_RUNS = 16


class NarrowScratch(NamedTuple):
    """Work arrays of one run of pairs (allocated once per run, reused by every pair of the run)."""
    poly: np.ndarray      # (SCRATCH_ROWS, 4) clip polygon: x, y, z, feature id
    tmp: np.ndarray       # (SCRATCH_ROWS, 4) clip output
    pts: np.ndarray       # (SCRATCH_ROWS, 3) candidate contact points
    seps: np.ndarray      # (SCRATCH_ROWS,) their separations
    feats: np.ndarray     # (SCRATCH_ROWS,) int64 their feature keys
    feat_a: np.ndarray    # (SCRATCH_ROWS, 3) support feature of A (general path)
    feat_b: np.ndarray    # (SCRATCH_ROWS, 3) support feature of B
    side: np.ndarray      # (SCRATCH_ROWS, 4) side planes of the reference feature
    hull_xy: np.ndarray   # (SCRATCH_ROWS, 2) a support feature projected on its plane
    hull_idx: np.ndarray  # (3 * SCRATCH_ROWS + 1,) int64 sort order, then hull chain


@njit(cache=True)
def new_scratch():
    """A `NarrowScratch` of ``SCRATCH_ROWS`` rows."""
    r = SCRATCH_ROWS
    return NarrowScratch(np.empty((r, 4)), np.empty((r, 4)), np.empty((r, 3)), np.empty(r), np.empty(r, np.int64),
                         np.empty((r, 3)), np.empty((r, 3)), np.empty((r, 4)), np.empty((r, 2)),
                         np.empty(3 * r + 1, np.int64))


def new_scratch_bank(runs: int) -> NarrowScratch:
    """``runs`` `NarrowScratch` rows in one bundle (a leading axis of length ``runs`` on every array), made
    once by a world: run ``i`` of the narrow phase's parallel loop works in ``scratch_row(bank, i)``, so a
    step allocates no scratch (module docstring, "Scratch")."""
    r, n = int(runs), SCRATCH_ROWS
    return NarrowScratch(np.empty((r, n, 4)), np.empty((r, n, 4)), np.empty((r, n, 3)), np.empty((r, n)),
                         np.empty((r, n), np.int64), np.empty((r, n, 3)), np.empty((r, n, 3)), np.empty((r, n, 4)),
                         np.empty((r, n, 2)), np.empty((r, 3 * n + 1), np.int64))


@_inl
def scratch_row(bank, i):
    """Row ``i`` of a scratch bank (`new_scratch_bank`) as a `NarrowScratch` of views (no allocation)."""
    return NarrowScratch(bank.poly[i], bank.tmp[i], bank.pts[i], bank.seps[i], bank.feats[i], bank.feat_a[i],
                         bank.feat_b[i], bank.side[i], bank.hull_xy[i], bank.hull_idx[i])


# Vertex rows of the mesh/SDF bank at least (a box's 8 corners, a cylinder's 16 rim points, the 26 SDF
# samples of a box or cylinder); a scene's hulls with more vertices get more (``mesh_rows``)
MESH_ROWS = 32
# candidate triangles per run at first; the world doubles the bank past the largest count a step met
MESH_CANDIDATES = 256
# a concave crease keeps at most this many sphere contacts (``trimesh_collide._sphere_crease``)
CREASE_MAX = 4


class MeshScratch(NamedTuple):
    """Work arrays of the triangle-mesh, heightfield and SDF narrow phases (``trimesh_collide``,
    ``sdf_collide``). In a bank (`new_mesh_bank`) every array has a leading axis of length ``runs``, one
    row per run of pairs; ``mesh_scratch_row`` gives run ``i``'s views. V = ``scene_mesh_rows``,
    C = candidate capacity (grown by ``fit_narrow_work``)."""
    cand: np.ndarray        # (C,) int64 candidate triangles of the pair (mesh-local indices)
    stack: np.ndarray       # (bvh.STACK_SIZE,) int32 BVH traversal stack
    need: np.ndarray        # (1,) int64 the largest candidate count the run met (0 after a grow)
    verts: np.ndarray       # (V, 3) m: shape A's vertices in the mesh frame; SDF: sample gradients
    pts: np.ndarray         # (V, 3) m: candidate contact points (world frame)
    seps: np.ndarray        # (V,) m: their separations
    feats: np.ndarray       # (V,) int64: their feature keys
    crease_sep: np.ndarray  # (CREASE_MAX,) m: a sphere's distinct contacts with a mesh: separation,
    crease_n: np.ndarray    # (CREASE_MAX, 3) normal (mesh frame),
    crease_tri: np.ndarray  # (CREASE_MAX,) int64 triangle,
    crease_foot: np.ndarray  # (CREASE_MAX, 3) m closest point on the triangle,
    crease_face: np.ndarray  # (CREASE_MAX,) bool whether that point is inside the face


def new_mesh_bank(runs: int, rows: int = MESH_ROWS, candidates: int = MESH_CANDIDATES) -> MeshScratch:
    """``runs`` `MeshScratch` rows of ``rows`` vertex rows and ``candidates`` candidate slots."""
    r, v, c, m = int(runs), max(int(rows), MESH_ROWS), int(candidates), CREASE_MAX
    return MeshScratch(np.empty((r, c), np.int64), np.empty((r, STACK_SIZE), np.int32), np.zeros((r, 1), np.int64),
                       np.empty((r, v, 3)), np.empty((r, v, 3)), np.empty((r, v)), np.empty((r, v), np.int64),
                       np.empty((r, m)), np.empty((r, m, 3)), np.empty((r, m), np.int64), np.empty((r, m, 3)),
                       np.empty((r, m), np.bool_))


@_inl
def mesh_scratch_row(bank, i):
    """Row ``i`` of a `MeshScratch` bank as a `MeshScratch` of views (no allocation)."""
    return MeshScratch(bank.cand[i], bank.stack[i], bank.need[i], bank.verts[i], bank.pts[i], bank.seps[i],
                       bank.feats[i], bank.crease_sep[i], bank.crease_n[i], bank.crease_tri[i], bank.crease_foot[i],
                       bank.crease_face[i])


def scene_mesh_rows(shape_type, shape_vert_count) -> int:
    """Vertex rows a scene's mesh/SDF pairs need: ``MESH_ROWS``, or its largest convex hull's vertex count."""
    hulls = np.asarray(shape_vert_count)[np.asarray(shape_type) == S.CONVEX_HULL]
    return max(MESH_ROWS, int(hulls.max(initial=0)))


class NarrowWork(NamedTuple):
    """The narrow phase's scratch banks, one row per run of pairs (``RUNS``): clipping (`NarrowScratch`),
    GJK/EPA (`inertia.geometry.convex.GjkScratch`; one row when the scene has no general pairs) and the
    mesh/SDF pairs' (`MeshScratch`; one row when the scene has none)."""
    scratch: NarrowScratch
    gjk: CV.GjkScratch
    mesh: MeshScratch


def new_narrow_work(general: bool = True, mesh_rows: int = 0) -> NarrowWork:
    """The banks of `NarrowWork` (~1.2 MB with ``general``: 16 EPA polytopes; ~0.3 MB without). ``mesh_rows``
    > 0: a mesh/SDF bank of that many vertex rows per run (``scene_mesh_rows(shape_type, shape_vert_count)`` for a
    scene with mesh or SDF pairs, ~0.1 MB); 0: a one-row placeholder."""
    mesh = new_mesh_bank(_RUNS, mesh_rows) if mesh_rows > 0 else new_mesh_bank(1, MESH_ROWS, 1)
    return NarrowWork(new_scratch_bank(_RUNS), CV.new_gjk_scratch_bank(_RUNS if general else 1), mesh)


def fit_narrow_work(work: NarrowWork) -> NarrowWork:
    """``work``, with its mesh bank's candidate slots doubled past the largest count the last mesh narrow
    phase met when that overflowed them (that step's pairs used a temporary list: same results); call after
    ``narrow_phase_mesh``. Amortised: a run of steps grows O(log n) times."""
    need = int(work.mesh.need.max())
    if need <= work.mesh.cand.shape[1]:
        return work
    m = work.mesh
    return work._replace(mesh=m._replace(cand=np.empty((m.cand.shape[0], 2 * need), np.int64),
                                         need=np.zeros_like(m.need)))


@_inl
def _emit(ca, i, k, p, sep, feature):
    ca.contact_point[i, k, 0] = p[0]
    ca.contact_point[i, k, 1] = p[1]
    ca.contact_point[i, k, 2] = p[2]
    ca.contact_separation[i, k] = sep
    ca.contact_feature[i, k] = feature


@_inl
def _set_normal(ca, i, n):
    ca.contact_normal[i, 0] = n[0]
    ca.contact_normal[i, 1] = n[1]
    ca.contact_normal[i, 2] = n[2]


@_inl
def _pose(pose, s):
    r = pose[s]
    return (r[0], r[1], r[2]), (r[3], r[4], r[5], r[6])


# ------------------------------------------------------------------------------------------- spheres
@njit(cache=True)
def _sphere_sphere(ca, i, ca_, ra, cb, rb, spec):
    d = sub(cb, ca_)
    dist = norm(d)
    sep = dist - ra - rb
    if sep > spec:
        return 0
    n = scale(d, 1.0 / dist) if dist > 1e-12 else (0.0, 0.0, 1.0)
    _set_normal(ca, i, n)
    # midway between the two surface points
    p = madd(ca_, n, ra + 0.5 * sep)
    _emit(ca, i, np.int64(0), p, sep, np.int64(0))
    return 1


@njit(cache=True)
def _sphere_plane(ca, i, c, r, pp, pq, spec):
    n = qrot(pq, (0.0, 0.0, 1.0))
    sep = dot(sub(c, pp), n) - r
    if sep > spec:
        return 0
    _set_normal(ca, i, scale(n, -1.0))
    _emit(ca, i, np.int64(0), madd(c, n, -(r + 0.5 * sep)), sep, np.int64(0))
    return 1


@njit(cache=True)
def _sphere_box(ca, i, c, r, pb, qb, h, spec):
    # sphere centre in the box frame; closest box point by clamping
    lc = qrot_inv(qb, sub(c, pb))
    cl = (min(max(lc[0], -h[0]), h[0]), min(max(lc[1], -h[1]), h[1]), min(max(lc[2], -h[2]), h[2]))
    d = sub(lc, cl)
    dist = norm(d)
    if dist > 1e-12:
        sep = dist - r
        if sep > spec:
            return 0
        nl = scale(d, 1.0 / dist)                          # box -> sphere, box frame
        feature = 0
    else:
        # centre inside: leave through the nearest face
        best, axis, sgn = 1e300, 0, 1.0
        for k in range(3):
            gap = h[k] - abs(lc[k])
            if gap < best:
                best, axis = gap, k
                sgn = 1.0 if lc[k] >= 0 else -1.0
        nl = (sgn if axis == 0 else 0.0, sgn if axis == 1 else 0.0, sgn if axis == 2 else 0.0)
        sep = -best - r
        cl = (lc[0] + nl[0] * best, lc[1] + nl[1] * best, lc[2] + nl[2] * best)
        feature = 1 + axis
    nw = qrot(qb, nl)
    surf_box = add(pb, qrot(qb, cl))
    _set_normal(ca, i, scale(nw, -1.0))                    # A = sphere -> B = box
    _emit(ca, i, np.int64(0), madd(surf_box, nw, 0.5 * sep), sep, feature)
    return 1


@_inl
def _segment_point(c, u, h, p):
    """Closest point to p on the segment c + s u, |s| <= h."""
    s = min(max(dot(sub(p, c), u), -h), h)
    return madd(c, u, s)


@njit(cache=True)
def _sphere_capsule(ca, i, c, r, pc, qc, rc, hc, spec):
    u = qrot(qc, (0.0, 0.0, 1.0))
    q = _segment_point(pc, u, hc, c)
    return _sphere_sphere(ca, i, c, r, q, rc, spec)


# ------------------------------------------------------------------------------------------ capsules
@_inl
def _segments_closest(c1, u1, h1, c2, u2, h2):
    """Parameters (s, t) of the closest points c1 + s u1, c2 + t u2 (unit directions, |s|<=h1, |t|<=h2)."""
    r = sub(c1, c2)
    b = dot(u1, u2)
    c = dot(u1, r)
    f = dot(u2, r)
    denom = 1.0 - b * b
    s = 0.0
    if denom > 1e-12:
        s = min(max((b * f - c) / denom, -h1), h1)
    t = f + b * s
    if t < -h2 or t > h2:
        t = min(max(t, -h2), h2)
        s = min(max(b * t - c, -h1), h1)
    return s, t


@njit(cache=True)
def _capsule_capsule(ca, i, pa, qa, ra, ha, pb, qb, rb, hb, spec):
    ua = qrot(qa, (0.0, 0.0, 1.0))
    ub = qrot(qb, (0.0, 0.0, 1.0))
    b = dot(ua, ub)
    if abs(b) > 0.999:
        # near-parallel: overlap interval of B's segment projected on A's gives two points
        s0 = dot(sub(pb, pa), ua)
        lo = max(-ha, s0 - hb * abs(b))
        hi = min(ha, s0 + hb * abs(b))
        perp = sub(sub(pb, pa), scale(ua, s0))
        pn = norm(perp)
        if hi - lo > 1e-6 * (ha + hb) and pn > 1e-9:
            n = scale(perp, 1.0 / pn)
            cnt = np.int64(0)
            for k in range(2):
                s = lo if k == 0 else hi
                p1 = madd(pa, ua, s)
                p2 = _segment_point(pb, ub, hb, p1)
                sep = dot(sub(p2, p1), n) - ra - rb
                if sep <= spec:
                    _emit(ca, i, cnt, madd(p1, n, ra + 0.5 * sep), sep, k)
                    cnt += 1
            if cnt > 0:
                _set_normal(ca, i, n)
            return cnt
    s, t = _segments_closest(pa, ua, ha, pb, ub, hb)
    return _sphere_sphere(ca, i, madd(pa, ua, s), ra, madd(pb, ub, t), rb, spec)


@njit(cache=True)
def _capsule_plane(ca, i, pc, qc, r, h, pp, pq, spec):
    u = qrot(qc, (0.0, 0.0, 1.0))
    n = qrot(pq, (0.0, 0.0, 1.0))
    cnt = np.int64(0)
    for k in range(2):
        e = madd(pc, u, h if k == 0 else -h)
        sep = dot(sub(e, pp), n) - r
        if sep <= spec:
            _emit(ca, i, cnt, madd(e, n, -(r + 0.5 * sep)), sep, k)
            cnt += 1
    if cnt > 0:
        _set_normal(ca, i, scale(n, -1.0))
    return cnt


# ----------------------------------------------------------------------------- four-point reduction
@njit(cache=True)
def _reduce_and_emit(ca, i, pts, seps, feats, n_in, normal):
    """Keep at most four of ``n_in`` candidate points: the deepest, the farthest from it, then the two
    that add the most area (Gregorius 2015), in that order."""
    if n_in <= 4:
        for k in range(n_in):
            _emit(ca, i, k, (pts[k, 0], pts[k, 1], pts[k, 2]), seps[k], feats[k])
        return n_in
    best = 0
    for k in range(1, n_in):
        if seps[k] < seps[best]:
            best = k
    p0 = (pts[best, 0], pts[best, 1], pts[best, 2])
    far, far_d = -1, -1.0
    for k in range(n_in):
        d = sub((pts[k, 0], pts[k, 1], pts[k, 2]), p0)
        dd = dot(d, d)
        if k != best and dd > far_d:
            far, far_d = k, dd
    p1 = (pts[far, 0], pts[far, 1], pts[far, 2])
    third, third_a = -1, -1e300
    for k in range(n_in):
        if k == best or k == far:
            continue
        pk = (pts[k, 0], pts[k, 1], pts[k, 2])
        a = dot(cross(sub(p1, p0), sub(pk, p0)), normal)
        if abs(a) > third_a:
            third, third_a = k, abs(a)
    p2 = (pts[third, 0], pts[third, 1], pts[third, 2])
    # orient the triangle, then the point most outside one of its edges
    sgn = 1.0 if dot(cross(sub(p1, p0), sub(p2, p0)), normal) >= 0 else -1.0
    fourth, fourth_a = -1, 0.0
    for k in range(n_in):
        if k == best or k == far or k == third:
            continue
        pk = (pts[k, 0], pts[k, 1], pts[k, 2])
        a0 = sgn * dot(cross(sub(p1, p0), sub(pk, p0)), normal)
        a1 = sgn * dot(cross(sub(p2, p1), sub(pk, p1)), normal)
        a2 = sgn * dot(cross(sub(p0, p2), sub(pk, p2)), normal)
        a = min(a0, min(a1, a2))
        if a < fourth_a:
            fourth, fourth_a = k, a
    cnt = np.int64(0)
    for c in range(4):
        k = best if c == 0 else (far if c == 1 else (third if c == 2 else fourth))
        if k < 0:
            continue
        _emit(ca, i, cnt, (pts[k, 0], pts[k, 1], pts[k, 2]), seps[k], feats[k])
        cnt += 1
    return cnt


# ---------------------------------------------------------------------------------------- box-plane
@njit(cache=True)
def _box_plane(ca, i, pb, qb, h, pp, pq, spec, scr):
    n = qrot(pq, (0.0, 0.0, 1.0))
    pts, seps, feats = scr.pts, scr.seps, scr.feats
    cnt = np.int64(0)
    for v in range(8):
        lv = (h[0] if v & 1 else -h[0], h[1] if v & 2 else -h[1], h[2] if v & 4 else -h[2])
        w = add(pb, qrot(qb, lv))
        sep = dot(sub(w, pp), n)
        if sep <= spec:
            p = madd(w, n, -0.5 * sep)
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
            seps[cnt] = sep
            feats[cnt] = v
            cnt += 1
    normal = scale(n, -1.0)
    if cnt > 0:
        _set_normal(ca, i, normal)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, normal)


# -------------------------------------------------------------------------------------- cylinder/hull
@njit(cache=True)
def _cylinder_plane(ca, i, pc, qc, r, h, pp, pq, spec, scr):
    n = qrot(pq, (0.0, 0.0, 1.0))
    u = qrot(qc, (0.0, 0.0, 1.0))
    pts, seps, feats = scr.pts, scr.seps, scr.feats
    cnt = np.int64(0)
    # rim direction of each cap pointing most into the plane: -n with its axial part removed
    m = madd(scale(n, -1.0), u, dot(n, u))
    mn = norm(m)
    if mn < 1e-3:
        # cap flat on the plane: four rim points of each cap along the cylinder's own x, y axes
        ex = qrot(qc, (1.0, 0.0, 0.0))
        ey = qrot(qc, (0.0, 1.0, 0.0))
        for cap in range(2):
            cc = madd(pc, u, h if cap == 0 else -h)
            for k in range(4):
                d = ex if k < 2 else ey
                w = madd(cc, d, r if k % 2 == 0 else -r)
                sep = dot(sub(w, pp), n)
                if sep <= spec:
                    p = madd(w, n, -0.5 * sep)
                    pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
                    seps[cnt] = sep
                    feats[cnt] = cap * 4 + k
                    cnt += 1
    else:
        m = scale(m, 1.0 / mn)
        for cap in range(2):
            w = madd(madd(pc, u, h if cap == 0 else -h), m, r)
            sep = dot(sub(w, pp), n)
            if sep <= spec:
                p = madd(w, n, -0.5 * sep)
                pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
                seps[cnt] = sep
                feats[cnt] = 8 + cap
                cnt += 1
    normal = scale(n, -1.0)
    if cnt > 0:
        _set_normal(ca, i, normal)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, normal)


@njit(cache=True)
def _hull_plane(ca, i, ph, qh, verts, v0, nv, pp, pq, spec, scr):
    n = qrot(pq, (0.0, 0.0, 1.0))
    if nv <= SCRATCH_ROWS:
        pts, seps, feats = scr.pts, scr.seps, scr.feats
    else:
        pts, seps, feats = np.empty((nv, 3)), np.empty(nv), np.empty(nv, np.int64)
    cnt = np.int64(0)
    for k in range(nv):
        v = verts[v0 + k]
        w = add(ph, qrot(qh, (v[0], v[1], v[2])))
        sep = dot(sub(w, pp), n)
        if sep <= spec:
            p = madd(w, n, -0.5 * sep)
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
            seps[cnt] = sep
            feats[cnt] = k
            cnt += 1
    normal = scale(n, -1.0)
    if cnt > 0:
        _set_normal(ca, i, normal)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, normal)


# ------------------------------------------------------------------------------------------- box-box
@njit(cache=True)
def _box_face_manifold(ca, i, ref_p, ref_ax, ref_h, k, n, inc_p, inc_ax, inc_h, spec, ref_is_a, code, scr):
    """Clip the incident box's face most opposed to ``n`` (reference -> incident) against the side
    planes of the reference face ``k`` and keep the points within ``spec`` of the reference plane."""
    cf = madd(ref_p, n, ref_h[k])
    k1, k2 = (k + 1) % 3, (k + 2) % 3
    u, v = ref_ax[k1], ref_ax[k2]
    hu, hv = ref_h[k1], ref_h[k2]
    # incident face: the face whose outward normal is most anti-parallel to n
    j, best = 0, -1.0
    for a in range(3):
        d = abs(dot(n, inc_ax[a]))
        if d > best:
            best, j = d, a
    sj = -1.0 if dot(n, inc_ax[j]) > 0 else 1.0
    ci = madd(inc_p, inc_ax[j], sj * inc_h[j])
    e1, e2 = inc_ax[(j + 1) % 3], inc_ax[(j + 2) % 3]
    h1, h2 = inc_h[(j + 1) % 3], inc_h[(j + 2) % 3]
    # polygon in reference-face coordinates (x along u, y along v, z along n) + feature ids
    poly, tmp = scr.poly, scr.tmp
    for c in range(4):
        s1 = 1.0 if (c == 0 or c == 3) else -1.0
        s2 = 1.0 if c < 2 else -1.0
        w = sub(madd(madd(ci, e1, s1 * h1), e2, s2 * h2), cf)
        poly[c, 0], poly[c, 1], poly[c, 2], poly[c, 3] = dot(w, u), dot(w, v), dot(w, n), c
    count = 4
    for plane in range(4):
        ax = 0 if plane < 2 else 1
        sg = 1.0 if plane % 2 == 0 else -1.0
        lim = hu if ax == 0 else hv
        out = 0
        for c in range(count):
            d = (c + 1) % count
            dp = sg * poly[c, ax] - lim
            dq = sg * poly[d, ax] - lim
            if dp <= 0.0:
                for m in range(4):
                    tmp[out, m] = poly[c, m]
                out += 1
            if (dp < 0.0 and dq > 0.0) or (dp > 0.0 and dq < 0.0):
                t = dp / (dp - dq)
                for m in range(3):
                    tmp[out, m] = poly[c, m] + t * (poly[d, m] - poly[c, m])
                tmp[out, 3] = 8 * (plane + 1) + (int(poly[c, 3]) & 7)
                out += 1
        count = out
        for c in range(count):
            for m in range(4):
                poly[c, m] = tmp[c, m]
        if count == 0:
            return 0
    pts, seps, feats = scr.pts, scr.seps, scr.feats
    cnt = np.int64(0)
    for c in range(count):
        z = poly[c, 2]
        if z <= spec:
            p = madd(madd(madd(cf, u, poly[c, 0]), v, poly[c, 1]), n, 0.5 * z)
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
            seps[cnt] = z
            feats[cnt] = ((code * 6 + j * 2 + (1 if sj > 0 else 0)) << 8) + int(poly[c, 3])
            cnt += 1
    if cnt == 0:
        return 0
    normal = n if ref_is_a else scale(n, -1.0)
    _set_normal(ca, i, normal)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, normal)


@njit(cache=True)
def _box_box(ca, i, pa, qa, ha, pb, qb, hb, spec, scr):
    A = (qrot(qa, (1.0, 0.0, 0.0)), qrot(qa, (0.0, 1.0, 0.0)), qrot(qa, (0.0, 0.0, 1.0)))
    B = (qrot(qb, (1.0, 0.0, 0.0)), qrot(qb, (0.0, 1.0, 0.0)), qrot(qb, (0.0, 0.0, 1.0)))
    d = sub(pb, pa)
    # face axes of A and of B
    sa, ka = -1e300, np.int64(0)
    for k in range(3):
        s = abs(dot(d, A[k])) - (ha[k] + hb[0] * abs(dot(A[k], B[0])) + hb[1] * abs(dot(A[k], B[1]))
                                 + hb[2] * abs(dot(A[k], B[2])))
        if s > spec:
            return 0
        if s > sa:
            sa, ka = s, k
    sb, kb = -1e300, np.int64(0)
    for k in range(3):
        s = abs(dot(d, B[k])) - (hb[k] + ha[0] * abs(dot(B[k], A[0])) + ha[1] * abs(dot(B[k], A[1]))
                                 + ha[2] * abs(dot(B[k], A[2])))
        if s > spec:
            return 0
        if s > sb:
            sb, kb = s, k
    # edge-edge axes
    se, ie, je = -1e300, -1, -1
    ne = (0.0, 0.0, 1.0)
    for a in range(3):
        for b in range(3):
            c = cross(A[a], B[b])
            ln = norm(c)
            if ln < 1e-6:
                continue
            c = scale(c, 1.0 / ln)
            s = abs(dot(d, c)) - (ha[0] * abs(dot(A[0], c)) + ha[1] * abs(dot(A[1], c)) + ha[2] * abs(dot(A[2], c))
                                  + hb[0] * abs(dot(B[0], c)) + hb[1] * abs(dot(B[1], c)) + hb[2] * abs(dot(B[2], c)))
            if s > spec:
                return 0
            if s > se:
                se, ie, je, ne = s, a, b, c
    # hysteresis: faces of A, then faces of B, then edges, each only when clearly better
    scale_len = min(min(ha[0], ha[1]), min(ha[2], min(hb[0], min(hb[1], hb[2]))))
    tol = 0.005 * scale_len
    use_b = sb > sa + tol
    face_sep = sb if use_b else sa
    if ie >= 0 and se > face_sep + 2.0 * tol:
        # edge-edge: closest points of the two edges nearest each other along n (A -> B)
        if dot(d, ne) < 0:
            ne = scale(ne, -1.0)
        ca_ = pa
        for k in range(3):
            if k != ie:
                ca_ = madd(ca_, A[k], ha[k] if dot(ne, A[k]) > 0 else -ha[k])
        cb_ = pb
        for k in range(3):
            if k != je:
                cb_ = madd(cb_, B[k], -hb[k] if dot(ne, B[k]) > 0 else hb[k])
        s, t = _segments_closest(ca_, A[ie], ha[ie], cb_, B[je], hb[je])
        p1 = madd(ca_, A[ie], s)
        p2 = madd(cb_, B[je], t)
        sep = dot(sub(p2, p1), ne)
        if sep > spec:
            return 0
        _set_normal(ca, i, ne)
        _emit(ca, i, np.int64(0), scale(add(p1, p2), 0.5), sep, (1 << 20) + ie * 3 + je)
        return 1
    # one call site with runtime arguments: a literal True / False per branch would compile the clipper
    # once per literal (Numba specialises on literal arguments)
    ref_is_a = not use_b
    if use_b:
        n = B[kb] if dot(d, B[kb]) < 0 else scale(B[kb], -1.0)      # B -> A
        ref_p, ref_ax, ref_h, k, inc_p, inc_ax, inc_h, code = pb, B, hb, kb, pa, A, ha, 3 + kb
    else:
        n = A[ka] if dot(d, A[ka]) > 0 else scale(A[ka], -1.0)      # A -> B
        ref_p, ref_ax, ref_h, k, inc_p, inc_ax, inc_h, code = pa, A, ha, ka, pb, B, hb, ka
    return _box_face_manifold(ca, i, ref_p, ref_ax, ref_h, k, n, inc_p, inc_ax, inc_h, spec, ref_is_a, code, scr)



# ------------------------------------------------------------------- general convex pairs (GJK/EPA)
# A support feature is "flat" along a direction when it lies within this sine of the angle (about 2 deg):
# polytope vertices within FEATURE_SIN * extent of the support plane, a cylinder cap/side within that tilt.
FEATURE_SIN = 0.035
_CAP_POINTS = 12          # rim points of a cylinder cap used as its contact polygon
_MAX_FEATURE = 32         # at most this many vertices in one support feature


@njit(cache=True)
def _support_feature(t, params, pose_row, verts, vs, vc, d, out, scr):
    """The support feature of a shape's core along the world unit direction ``d``: world points in
    ``out[:m]``, returns ``m`` (1 vertex, 2 segment, >= 3 convex polygon counter-clockwise about ``d``)."""
    p = (pose_row[0], pose_row[1], pose_row[2])
    q = (pose_row[3], pose_row[4], pose_row[5], pose_row[6])
    dl = qrot_inv(q, d)
    m = 0
    if t == CV.SPHERE:
        out[0, 0], out[0, 1], out[0, 2] = p
        return 1
    if t == CV.CAPSULE or t == CV.CYLINDER:
        h = params[1]
        radial = math.sqrt(dl[0] * dl[0] + dl[1] * dl[1])
        if t == CV.CAPSULE or radial > FEATURE_SIN:
            # rim (cylinder) or axis (capsule) points at the radial direction
            rx, ry = 0.0, 0.0
            if t == CV.CYLINDER and radial > 0.0:
                rx, ry = params[0] * dl[0] / radial, params[0] * dl[1] / radial
            if abs(dl[2]) <= FEATURE_SIN:
                for k in range(2):
                    w = add(p, qrot(q, (rx, ry, h if k == 0 else -h)))
                    out[k, 0], out[k, 1], out[k, 2] = w
                return 2
            w = add(p, qrot(q, (rx, ry, h if dl[2] >= 0.0 else -h)))
            out[0, 0], out[0, 1], out[0, 2] = w
            return 1
        # cylinder cap facing d: a regular polygon on the rim
        z = h if dl[2] >= 0.0 else -h
        for k in range(_CAP_POINTS):
            a = 2.0 * math.pi * k / _CAP_POINTS
            lv = (params[0] * math.cos(a), params[0] * math.sin(a), z)
            w = add(p, qrot(q, lv))
            out[k, 0], out[k, 1], out[k, 2] = w
        m = _CAP_POINTS
    else:
        # polytopes: the vertices within FEATURE_SIN * extent of the support plane
        nv = 8 if t == CV.BOX else vc
        hmax, ext = -1e300, 0.0
        for k in range(nv):
            lv = _poly_vertex(t, params, verts, vs, k)
            hmax = max(hmax, dot(lv, dl))
            ext = max(ext, norm(lv))
        tol = FEATURE_SIN * ext
        for k in range(nv):
            lv = _poly_vertex(t, params, verts, vs, k)
            if dot(lv, dl) >= hmax - tol and m < _MAX_FEATURE:
                w = add(p, qrot(q, lv))
                out[m, 0], out[m, 1], out[m, 2] = w
                m += 1
        if m <= 2:
            if m == 2 and norm(sub((out[0, 0], out[0, 1], out[0, 2]), (out[1, 0], out[1, 1], out[1, 2]))) \
                    <= 1e-9 * (1.0 + ext):
                m = 1
            return m
    return _convex_polygon(out, m, d, scr)


@_inl
def _poly_vertex(t, params, verts, vs, k):
    if t == CV.BOX:
        return (params[0] if k & 1 else -params[0], params[1] if k & 2 else -params[1],
                params[2] if k & 4 else -params[2])
    v = verts[vs + k]
    return (v[0], v[1], v[2])


@njit(cache=True)
def _convex_polygon(pts, m, d, scr):
    """Reorder ``pts[:m]`` in place as their convex hull projected along ``d``, counter-clockwise about
    ``d`` (Andrew's monotone chain); returns the hull's vertex count (collinear points dropped). Works in
    the scratch ``scr`` (m <= _MAX_FEATURE)."""
    t1, t2 = orthonormal_basis(d)
    xy = scr.hull_xy
    order = scr.hull_idx[:m]
    for k in range(m):
        w = (pts[k, 0], pts[k, 1], pts[k, 2])
        xy[k, 0] = dot(w, t1)
        xy[k, 1] = dot(w, t2)
        order[k] = k
    # insertion sort by (x, y)
    for a in range(1, m):
        b = a
        while b > 0 and (xy[order[b], 0] < xy[order[b - 1], 0] or
                         (xy[order[b], 0] == xy[order[b - 1], 0] and xy[order[b], 1] < xy[order[b - 1], 1])):
            order[b], order[b - 1] = order[b - 1], order[b]
            b -= 1
    hull = scr.hull_idx[m:3 * m + 1]
    k = 0
    scale2 = 0.0
    for a in range(m):
        scale2 = max(scale2, xy[a, 0] * xy[a, 0] + xy[a, 1] * xy[a, 1])
    eps = 1e-14 * (1.0 + scale2)
    for a in range(m):                                   # lower chain
        o = order[a]
        while k >= 2:
            i0, i1 = hull[k - 2], hull[k - 1]
            c = (xy[i1, 0] - xy[i0, 0]) * (xy[o, 1] - xy[i0, 1]) - (xy[i1, 1] - xy[i0, 1]) * (xy[o, 0] - xy[i0, 0])
            if c > eps:
                break
            k -= 1
        hull[k] = o
        k += 1
    lower = k + 1
    for a in range(m - 2, -1, -1):                       # upper chain
        o = order[a]
        while k >= lower:
            i0, i1 = hull[k - 2], hull[k - 1]
            c = (xy[i1, 0] - xy[i0, 0]) * (xy[o, 1] - xy[i0, 1]) - (xy[i1, 1] - xy[i0, 1]) * (xy[o, 0] - xy[i0, 0])
            if c > eps:
                break
            k -= 1
        hull[k] = o
        k += 1
    k -= 1                                               # last point repeats the first
    if k < 1:
        k = 1
    tmp = scr.tmp                                        # (rows, 4): the first 3 columns
    for a in range(k):
        for c in range(3):
            tmp[a, c] = pts[hull[a], c]
    for a in range(k):
        for c in range(3):
            pts[a, c] = tmp[a, c]
    return k


@_inl
def _row(a, k):
    return (a[k, 0], a[k, 1], a[k, 2])


@njit(cache=True)
def _polygon_normal(pts, m, d):
    """Unit normal of the polygon pts[:m] (Newell's method), on the side of ``d``."""
    nx, ny, nz = 0.0, 0.0, 0.0
    for k in range(m):
        a = _row(pts, k)
        b = _row(pts, (k + 1) % m)
        nx += (a[1] - b[1]) * (a[2] + b[2])
        ny += (a[2] - b[2]) * (a[0] + b[0])
        nz += (a[0] - b[0]) * (a[1] + b[1])
    n = (nx, ny, nz)
    ln = norm(n)
    if ln <= 0.0:
        return d
    n = scale(n, 1.0 / ln)
    return n if dot(n, d) >= 0.0 else scale(n, -1.0)


@njit(cache=True)
def _convex_general(ca, i, ta, tb, sa, sb, shapes, pose, spec, scr, gscr):
    """Any two convex shapes: GJK on the cores (exact distance when separated), EPA when the cores overlap,
    then the manifold by clipping the incident support feature against the reference feature's side
    planes (Gregorius 2015), reduced to four points. Normal A -> B. GJK/EPA work in the `GjkScratch`
    ``gscr`` of the run (no work arrays allocated per pair)."""
    verts = shapes.geom_vertices
    par_a, par_b = shapes.shape_params[sa], shapes.shape_params[sb]
    pose_a, pose_b = pose[sa], pose[sb]
    vs_a, vc_a = shapes.shape_vert_start[sa], shapes.shape_vert_count[sa]
    vs_b, vc_b = shapes.shape_vert_start[sb], shapes.shape_vert_count[sb]
    ra = CV.core_radius(ta, par_a)
    rb = CV.core_radius(tb, par_b)
    dist, separated = CV.gjk_distance_scratch(ta, par_a, pose_a, vs_a, vc_a, tb, par_b, pose_b, vs_b, vc_b, verts,
                                              gscr)
    wa, wb, nrm = gscr.vec[6], gscr.vec[7], gscr.vec[8]
    if separated:
        if dist > spec:
            return 0
    else:
        depth, ok = CV._epa(ta, par_a, pose_a, vs_a, vc_a, tb, par_b, pose_b, vs_b, vc_b, verts, False, gscr)
        if not ok:
            return 0
        dist = -(depth + ra + rb)
        for k in range(3):
            wa[k] = wa[k] + ra * nrm[k]
            wb[k] = wb[k] - rb * nrm[k]
    n = (nrm[0], nrm[1], nrm[2])
    fa, fb = scr.feat_a, scr.feat_b
    ma = _support_feature(ta, par_a, pose_a, verts, vs_a, vc_a, n, fa, scr)
    mb = _support_feature(tb, par_b, pose_b, verts, vs_b, vc_b, scale(n, -1.0), fb, scr)
    single = ma == 1 or mb == 1
    if ma == 2 and mb == 2:
        ua = normalize(sub(_row(fa, 1), _row(fa, 0)))
        ub = normalize(sub(_row(fb, 1), _row(fb, 0)))
        single = abs(dot(ua, ub)) < 1.0 - 0.5 * FEATURE_SIN * FEATURE_SIN
    if single:
        _set_normal(ca, i, n)
        _emit(ca, i, np.int64(0), (0.5 * (wa[0] + wb[0]), 0.5 * (wa[1] + wb[1]), 0.5 * (wa[2] + wb[2])), dist,
              np.int64(0))
        return 1
    # reference feature: a polygon before a segment; of two polygons the one facing the normal better
    ref_is_a = True
    if ma >= 3 and mb >= 3:
        ref_is_a = dot(_polygon_normal(fa, ma, n), n) >= dot(_polygon_normal(fb, mb, scale(n, -1.0)), scale(n, -1.0)) - 1e-12
    elif mb >= 3:
        ref_is_a = False
    if ref_is_a:
        ref, mr, inc, mi, dref = fa, ma, fb, mb, n
    else:
        ref, mr, inc, mi, dref = fb, mb, fa, ma, scale(n, -1.0)
    # reference plane: outward normal nr (the contact normal is snapped to it), through the centroid c
    if mr >= 3:
        nr = _polygon_normal(ref, mr, dref)
    else:
        u = normalize(sub(_row(ref, 1), _row(ref, 0)))
        nr = normalize(madd(dref, u, -dot(dref, u)))
        round_a = ta == CV.CYLINDER or ta == CV.CAPSULE
        round_b = tb == CV.CYLINDER or tb == CV.CAPSULE
        if round_a and round_b:
            # parallel round sides: the exact normal is the axes' common perpendicular (EPA's normal on a
            # curved side is only converged to its tolerance)
            d_ab = sub((pose_b[0], pose_b[1], pose_b[2]), (pose_a[0], pose_a[1], pose_a[2]))
            perp = madd(d_ab, u, -dot(d_ab, u))
            if norm(perp) > 1e-12:
                nr = normalize(perp) if ref_is_a else scale(normalize(perp), -1.0)
    c = (0.0, 0.0, 0.0)
    for k in range(mr):
        c = add(c, _row(ref, k))
    c = scale(c, 1.0 / mr)
    n_ab = nr if ref_is_a else scale(nr, -1.0)
    # side planes of the reference feature (outward normals s_k, offsets)
    nplanes = mr if mr >= 3 else 2
    side = scr.side
    if mr >= 3:
        for k in range(mr):
            e = sub(_row(ref, (k + 1) % mr), _row(ref, k))
            s = normalize(cross(e, nr))
            side[k, 0], side[k, 1], side[k, 2] = s
            side[k, 3] = dot(s, _row(ref, k))
    else:
        u = normalize(sub(_row(ref, 1), _row(ref, 0)))
        side[0, 0], side[0, 1], side[0, 2] = u
        side[0, 3] = dot(u, _row(ref, 1))
        side[1, 0], side[1, 1], side[1, 2] = scale(u, -1.0)
        side[1, 3] = -dot(u, _row(ref, 0))
    # Sutherland-Hodgman clip of the incident feature; column 3 carries a feature id per point
    poly, tmp = scr.poly, scr.tmp            # mi + 2 * nplanes + 4 <= SCRATCH_ROWS rows
    for k in range(mi):
        poly[k, 0], poly[k, 1], poly[k, 2] = _row(inc, k)
        poly[k, 3] = k
    count = mi
    closed = mi >= 3
    for pl in range(nplanes):
        sn = (side[pl, 0], side[pl, 1], side[pl, 2])
        out = 0
        last = count if closed else count - 1
        for k in range(count):
            a = (poly[k, 0], poly[k, 1], poly[k, 2])
            da = dot(sn, a) - side[pl, 3]
            if da <= 0.0:
                for m in range(4):
                    tmp[out, m] = poly[k, m]
                out += 1
            if k < last:
                k2 = (k + 1) % count
                b = (poly[k2, 0], poly[k2, 1], poly[k2, 2])
                db = dot(sn, b) - side[pl, 3]
                if (da < 0.0 and db > 0.0) or (da > 0.0 and db < 0.0):
                    t = da / (da - db)
                    for m in range(3):
                        tmp[out, m] = poly[k, m] + t * (poly[k2, m] - poly[k, m])
                    tmp[out, 3] = 64 * (pl + 1) + (int(poly[k, 3]) & 63)
                    out += 1
        count = out
        for k in range(count):
            for m in range(4):
                poly[k, m] = tmp[k, m]
        if count == 0:
            break
    pts, seps, feats = scr.pts, scr.seps, scr.feats
    cnt = np.int64(0)
    for k in range(count):
        x = (poly[k, 0], poly[k, 1], poly[k, 2])
        sep = dot(sub(x, c), nr) - ra - rb
        if sep <= spec:
            if ref_is_a:
                pk = madd(x, n_ab, -(rb + 0.5 * sep))
            else:
                pk = madd(x, n_ab, ra + 0.5 * sep)
            pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = pk
            seps[cnt] = sep
            feats[cnt] = (0 if ref_is_a else 1 << 12) + int(poly[k, 3])
            cnt += 1
    if cnt == 0:
        if dist > spec:
            return 0
        _set_normal(ca, i, n)
        _emit(ca, i, np.int64(0), (0.5 * (wa[0] + wb[0]), 0.5 * (wa[1] + wb[1]), 0.5 * (wa[2] + wb[2])), dist,
              np.int64(0))
        return 1
    _set_normal(ca, i, n_ab)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, n_ab)


# ------------------------------------------------------------------------------------------ dispatch
# Pair families, each with its own kernel so a scene compiles only the pair routines it can meet (module
# docstring, "Compilation"): closed forms, the general convex path (GJK/EPA), meshes and heightfields.
FAMILY_CLOSED, FAMILY_GENERAL, FAMILY_MESH, FAMILY_NONE, FAMILY_SDF = 0, 1, 2, 3, 4


@njit(cache=True)
def pair_family(ta, tb):
    """Family of the canonical pair (ta <= tb) of shape types."""
    if tb == S.TRIANGLE_MESH or tb == S.HEIGHTFIELD:
        return FAMILY_MESH
    if tb == S.SDF:
        return FAMILY_SDF if ta <= S.CONVEX_HULL else FAMILY_NONE
    if ta == S.SPHERE:
        if tb == S.SPHERE or tb == S.BOX or tb == S.CAPSULE or tb == S.PLANE:
            return FAMILY_CLOSED
    elif ta == S.BOX or ta == S.CAPSULE:
        if tb == ta or tb == S.PLANE:
            return FAMILY_CLOSED
    elif ta == S.CYLINDER or ta == S.CONVEX_HULL:
        if tb == S.PLANE:
            return FAMILY_CLOSED
    if tb <= S.CONVEX_HULL:
        return FAMILY_GENERAL
    return FAMILY_NONE


def scene_families(shape_type) -> tuple[bool, bool, bool]:
    """(general, mesh, sdf): whether any pair of the shape types present can take the general convex path,
    the mesh path or the SDF path (conservative: every type pair, same body or not)."""
    types = sorted({int(t) for t in np.asarray(shape_type)})
    fams = {pair_family.py_func(ta, tb) for i, ta in enumerate(types) for tb in types[i:]}
    return FAMILY_GENERAL in fams, FAMILY_MESH in fams, FAMILY_SDF in fams


#: The closed-form pair kinds (canonical: ta <= tb), in the order of a ``closed_token``'s entries.
CLOSED_PAIRS = ((S.SPHERE, S.SPHERE), (S.SPHERE, S.BOX), (S.SPHERE, S.CAPSULE), (S.SPHERE, S.PLANE),
                (S.BOX, S.BOX), (S.BOX, S.PLANE), (S.CAPSULE, S.CAPSULE), (S.CAPSULE, S.PLANE),
                (S.CYLINDER, S.PLANE), (S.CONVEX_HULL, S.PLANE))
#: The shape-type sets a closed-form kernel is compiled for: the smallest that holds a scene's types.
#: Nested, not one per combination, so that a process meeting many scenes (a test suite, a sweep)
#: compiles the closed-form kernels at most three times.
CLOSED_TYPE_SETS = (frozenset((S.SPHERE, S.PLANE)), frozenset((S.SPHERE, S.BOX, S.PLANE)),
                    frozenset((S.SPHERE, S.BOX, S.CAPSULE, S.CYLINDER, S.CONVEX_HULL, S.PLANE)))


def closed_token(shape_type) -> tuple:
    """The ``closed`` argument of ``narrow_phase_closed`` for a scene's shape types: one entry per
    ``CLOSED_PAIRS`` kind, True when compiled in, None when not. Compiled in are the pairs among the
    smallest ``CLOSED_TYPE_SETS`` entry holding every type present (a scene of boxes and planes compiles
    the sphere, box and plane pairs; one of spheres and planes only the sphere-sphere and sphere-plane
    pairs), so the capsule, cylinder and hull routines compile only for scenes that have those shapes."""
    present = {int(t) for t in np.asarray(shape_type).ravel()} & CLOSED_TYPE_SETS[-1]
    kept = next(s for s in CLOSED_TYPE_SETS if present <= s)
    return tuple(True if ta in kept and tb in kept else None for ta, tb in CLOSED_PAIRS)


#: Every closed-form pair compiled in (the token of a scene with every shape type).
ALL_CLOSED = tuple(True for _ in CLOSED_PAIRS)


def collide_closed_in(closed, out, i, ta, tb, sa, sb, shapes, pose, spec, scr):
    """The manifold of a closed-form pair (``pair_family`` FAMILY_CLOSED) of the kinds compiled in
    (``closed``, a ``closed_token``); 0 for any other pair. Numba only."""
    raise NotImplementedError("collide_closed_in runs inside Numba kernels only")


@overload(collide_closed_in, jit_options={"cache": True})
def _collide_closed_in(closed, out, i, ta, tb, sa, sb, shapes, pose, spec, scr):
    if not isinstance(closed, types.BaseTuple) or len(closed.types) != len(CLOSED_PAIRS):
        raise TypeError(f"closed must be a tuple of {len(CLOSED_PAIRS)} entries (True or None); see closed_token")
    (sphere_sphere, sphere_box, sphere_capsule, sphere_plane, box_box, box_plane, capsule_capsule, capsule_plane,
     cylinder_plane, hull_plane) = (not isinstance(t, (types.NoneType, types.Omitted)) for t in closed.types)

    # the kinds left out are pruned before typing (constant conditions): their routines never compile
    def impl(closed, out, i, ta, tb, sa, sb, shapes, pose, spec, scr):
        pa, qa = _pose(pose, sa)
        pb, qb = _pose(pose, sb)
        A = shapes.shape_params[sa]
        B = shapes.shape_params[sb]
        if sphere_sphere:
            if ta == S.SPHERE and tb == S.SPHERE:
                return _sphere_sphere(out, i, pa, A[0], pb, B[0], spec)
        if sphere_box:
            if ta == S.SPHERE and tb == S.BOX:
                return _sphere_box(out, i, pa, A[0], pb, qb, (B[0], B[1], B[2]), spec)
        if sphere_capsule:
            if ta == S.SPHERE and tb == S.CAPSULE:
                return _sphere_capsule(out, i, pa, A[0], pb, qb, B[0], B[1], spec)
        if sphere_plane:
            if ta == S.SPHERE and tb == S.PLANE:
                return _sphere_plane(out, i, pa, A[0], pb, qb, spec)
        if box_box:
            if ta == S.BOX and tb == S.BOX:
                return _box_box(out, i, pa, qa, (A[0], A[1], A[2]), pb, qb, (B[0], B[1], B[2]), spec, scr)
        if box_plane:
            if ta == S.BOX and tb == S.PLANE:
                return _box_plane(out, i, pa, qa, (A[0], A[1], A[2]), pb, qb, spec, scr)
        if capsule_capsule:
            if ta == S.CAPSULE and tb == S.CAPSULE:
                return _capsule_capsule(out, i, pa, qa, A[0], A[1], pb, qb, B[0], B[1], spec)
        if capsule_plane:
            if ta == S.CAPSULE and tb == S.PLANE:
                return _capsule_plane(out, i, pa, qa, A[0], A[1], pb, qb, spec)
        if cylinder_plane:
            if ta == S.CYLINDER and tb == S.PLANE:
                return _cylinder_plane(out, i, pa, qa, A[0], A[1], pb, qb, spec, scr)
        if hull_plane:
            if ta == S.CONVEX_HULL and tb == S.PLANE:
                return _hull_plane(out, i, pa, qa, shapes.geom_vertices, shapes.shape_vert_start[sa],
                                   shapes.shape_vert_count[sa], pb, qb, spec, scr)
        return 0
    return impl


@njit(cache=True)
def _body_speed(b, body_qd, radius):
    if b < 0:
        return (0.0, 0.0, 0.0), 0.0
    qd = body_qd[b]
    w = math.sqrt(qd[0] * qd[0] + qd[1] * qd[1] + qd[2] * qd[2])
    return (qd[3], qd[4], qd[5]), w * radius[b]


@njit(cache=True)
def _speculative_distance(ba, bb, margin_a, margin_b, body_qd, body_bound_radius, dt):
    """What the pair can close within the step, plus the larger margin."""
    va, wa = _body_speed(ba, body_qd, body_bound_radius)
    vb, wb = _body_speed(bb, body_qd, body_bound_radius)
    return max(margin_a, margin_b) + dt * (norm(sub(vb, va)) + wa + wb)


@njit(cache=True)
def _tangents(i, contact_normal, contact_tangent):
    n = (contact_normal[i, 0], contact_normal[i, 1], contact_normal[i, 2])
    t1, t2 = orthonormal_basis(n)
    for m in range(3):
        contact_tangent[i, 0, m] = t1[m]
        contact_tangent[i, 1, m] = t2[m]


class ManifoldOut(NamedTuple):
    """The four contact arrays a pair routine writes (``_emit``, ``_set_normal``): a small bundle, so a
    call per pair does not pass (and reference-count) the whole contact buffer."""
    contact_normal: np.ndarray
    contact_point: np.ndarray
    contact_separation: np.ndarray
    contact_feature: np.ndarray


@njit(cache=True)
def _narrow_range(lo, hi, pairs, keys, shapes, pose, body_qd, body_bound_radius, dt, ca, bank, run, closed):
    """Every pair of ``lo:hi``: materials, keys, zeroed impulses, and the manifold of the closed-form
    pairs (the other families' kernels fill theirs afterwards), clipping in row ``run`` of the scratch
    bank. The bundles' arrays are unpacked once into locals: reading a NamedTuple member inside the loop
    takes and drops a reference each time."""
    scr = scratch_row(bank, run)
    out = ManifoldOut(ca.contact_normal, ca.contact_point, ca.contact_separation, ca.contact_feature)
    shape_body, shape_type, shape_margin = shapes.shape_body, shapes.shape_type, shapes.shape_margin
    shape_friction, shape_restitution = shapes.shape_friction, shapes.shape_restitution
    shape_rolling_friction, shape_is_sensor = shapes.shape_rolling_friction, shapes.shape_is_sensor
    contact_shape, contact_body, contact_key = ca.contact_shape, ca.contact_body, ca.contact_key
    contact_friction, contact_restitution = ca.contact_friction, ca.contact_restitution
    contact_rolling_friction, contact_is_sensor = ca.contact_rolling_friction, ca.contact_is_sensor
    contact_point_count, contact_normal, contact_tangent = (ca.contact_point_count, ca.contact_normal,
                                                            ca.contact_tangent)
    contact_rolling_impulse, contact_normal_impulse = ca.contact_rolling_impulse, ca.contact_normal_impulse
    contact_tangent_impulse, contact_max_normal_impulse = (ca.contact_tangent_impulse,
                                                           ca.contact_max_normal_impulse)
    contact_total_normal_impulse = ca.contact_total_normal_impulse
    for i in range(lo, hi):
        sa, sb = pairs[i, 0], pairs[i, 1]
        ba, bb = shape_body[sa], shape_body[sb]
        contact_shape[i, 0] = sa
        contact_shape[i, 1] = sb
        contact_body[i, 0] = ba
        contact_body[i, 1] = bb
        contact_key[i] = keys[i]
        contact_friction[i] = math.sqrt(shape_friction[sa] * shape_friction[sb])
        contact_restitution[i] = max(shape_restitution[sa], shape_restitution[sb])
        contact_rolling_friction[i] = max(shape_rolling_friction[sa], shape_rolling_friction[sb])
        contact_is_sensor[i] = shape_is_sensor[sa] or shape_is_sensor[sb]
        ta, tb = shape_type[sa], shape_type[sb]
        cnt = np.int64(0)
        if pair_family(ta, tb) == FAMILY_CLOSED:
            spec = _speculative_distance(ba, bb, shape_margin[sa], shape_margin[sb], body_qd, body_bound_radius,
                                         dt)
            cnt = collide_closed_in(closed, out, i, ta, tb, sa, sb, shapes, pose, spec, scr)
        contact_point_count[i] = cnt
        _tangents(i, contact_normal, contact_tangent)
        for m in range(3):
            contact_rolling_impulse[i, m] = 0.0
        for k in range(4):
            contact_normal_impulse[i, k] = 0.0
            contact_tangent_impulse[i, k, 0] = 0.0
            contact_tangent_impulse[i, k, 1] = 0.0
            contact_max_normal_impulse[i, k] = 0.0
            contact_total_normal_impulse[i, k] = 0.0


@njit(cache=True)
def _narrow_range_general(lo, hi, pairs, shapes, pose, body_qd, body_bound_radius, dt, ca, bank, gjk_bank, run):
    """The general convex pairs of ``lo:hi`` (after ``_narrow_range``): manifold, count, tangents; row
    ``run`` of the clipping and GJK/EPA scratch banks."""
    scr = scratch_row(bank, run)
    gscr = CV.gjk_scratch_row(gjk_bank, run)
    out = ManifoldOut(ca.contact_normal, ca.contact_point, ca.contact_separation, ca.contact_feature)
    shape_body, shape_type, shape_margin = shapes.shape_body, shapes.shape_type, shapes.shape_margin
    contact_point_count, contact_normal, contact_tangent = (ca.contact_point_count, ca.contact_normal,
                                                            ca.contact_tangent)
    for i in range(lo, hi):
        sa, sb = pairs[i, 0], pairs[i, 1]
        ta, tb = shape_type[sa], shape_type[sb]
        if pair_family(ta, tb) != FAMILY_GENERAL:
            continue
        spec = _speculative_distance(shape_body[sa], shape_body[sb], shape_margin[sa], shape_margin[sb], body_qd,
                                     body_bound_radius, dt)
        contact_point_count[i] = _convex_general(out, i, ta, tb, sa, sb, shapes, pose, spec, scr, gscr)
        _tangents(i, contact_normal, contact_tangent)


@njit(cache=True)
def _narrow_range_mesh(lo, hi, pairs, shapes, pose, body_qd, body_bound_radius, dt, ca, bank, run):
    """The pairs of ``lo:hi`` with a triangle mesh or heightfield (``geometry/trimesh_collide.py``), in row
    ``run`` of the mesh bank (a `NarrowWork`'s ``mesh``)."""
    scr = mesh_scratch_row(bank, run)
    out = ManifoldOut(ca.contact_normal, ca.contact_point, ca.contact_separation, ca.contact_feature)
    shape_body, shape_type, shape_margin = shapes.shape_body, shapes.shape_type, shapes.shape_margin
    contact_point_count, contact_normal, contact_tangent = (ca.contact_point_count, ca.contact_normal,
                                                            ca.contact_tangent)
    for i in range(lo, hi):
        sa, sb = pairs[i, 0], pairs[i, 1]
        ta, tb = shape_type[sa], shape_type[sb]
        if pair_family(ta, tb) != FAMILY_MESH:
            continue
        spec = _speculative_distance(shape_body[sa], shape_body[sb], shape_margin[sa], shape_margin[sb], body_qd,
                                     body_bound_radius, dt)
        contact_point_count[i] = _tm.collide_triangles(out, i, ta, sa, sb, shapes, pose, spec, scr)
        _tangents(i, contact_normal, contact_tangent)




@njit(cache=True, parallel=True)
def narrow_phase_closed(pairs, keys, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, bank, closed):
    """Every candidate pair's row, and the manifolds of the closed-form pairs (runs in parallel; run
    ``ch`` clips in row ``ch`` of ``bank``, a `NarrowWork`'s ``scratch``). ``closed``: the pair kinds
    compiled in, ``closed_token(shape_type)`` of the scene (pairs of kinds left out get no points)."""
    nch = min(npairs, _RUNS)
    for ch in prange(nch):
        _narrow_range(npairs * ch // nch, npairs * (ch + 1) // nch, pairs, keys, shapes, pose, body_qd,
                      body_bound_radius, dt, ca, bank, ch, closed)


@njit(cache=True, parallel=True)
def narrow_phase_general(pairs, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, bank, gjk_bank):
    """The manifolds of the general convex pairs (GJK/EPA), after ``narrow_phase_closed``; run ``ch``
    works in row ``ch`` of both banks (a `NarrowWork` made with ``general=True``: its ``scratch`` and
    ``gjk``; passed apart because a parallel loop cannot take a nested bundle)."""
    nch = min(npairs, _RUNS)
    for ch in prange(nch):
        _narrow_range_general(npairs * ch // nch, npairs * (ch + 1) // nch, pairs, shapes, pose, body_qd,
                              body_bound_radius, dt, ca, bank, gjk_bank, ch)


@njit(cache=True, parallel=True)
def narrow_phase_mesh(pairs, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, mesh_bank):
    """The manifolds of the mesh and heightfield pairs, after ``narrow_phase_closed``; run ``ch`` works in
    row ``ch`` of ``mesh_bank`` (a `NarrowWork`'s ``mesh`` with a row per run; ``fit_narrow_work`` after)."""
    nch = min(npairs, _RUNS)
    for ch in prange(nch):
        _narrow_range_mesh(npairs * ch // nch, npairs * (ch + 1) // nch, pairs, shapes, pose, body_qd,
                           body_bound_radius, dt, ca, mesh_bank, ch)


def narrow_phase(pairs, keys, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, families=None, sdf=None,
                 work=None):
    """Fill manifold ``i`` of ``ca`` for candidate pair ``i`` (see the module docstring): the closed-form
    kernel, then the general, mesh and SDF kernels when the scene's shape types can form such pairs
    (``families = (general, mesh, sdf)``, default ``scene_families(shapes.shape_type)``). ``sdf``: the
    baked SDF rows (`inertia.geometry.sdf_collide.SdfArrays`; needed when the scene has SDF pairs).
    ``work``: a `NarrowWork` kept between calls (``new_narrow_work(general, scene_mesh_rows(...))``, the mesh
    bank with a row per run when the scene has mesh or SDF pairs); made here when None. Returns the work to
    keep (``fit_narrow_work``: its candidate slots grown when a mesh pair overflowed them)."""
    general, mesh, with_sdf = scene_families(shapes.shape_type) if families is None else families
    if work is None:
        work = new_narrow_work(general, scene_mesh_rows(shapes.shape_type, shapes.shape_vert_count)
                               if mesh or with_sdf else 0)
    elif (mesh or with_sdf) and work.mesh.cand.shape[0] < _RUNS:
        raise ValueError(f"work must have a mesh bank of {_RUNS} runs for a scene with mesh or SDF pairs "
                         "(new_narrow_work(general, mesh_rows=scene_mesh_rows(shape_type, shape_vert_count)))")
    narrow_phase_closed(pairs, keys, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, work.scratch,
                        closed_token(shapes.shape_type))
    if general:
        narrow_phase_general(pairs, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, work.scratch,
                             work.gjk)
    if mesh:
        narrow_phase_mesh(pairs, npairs, shapes, pose, body_qd, body_bound_radius, dt, ca, work.mesh)
    if with_sdf:
        if sdf is None:
            raise ValueError("sdf must be the model's SdfArrays (inertia.geometry.sdf_collide.sdf_arrays(model)) "
                             "when the shapes include SDF rows")
        from .sdf_collide import narrow_phase_sdf
        narrow_phase_sdf(pairs, npairs, shapes, sdf, pose, body_qd, body_bound_radius, dt, ca, work.mesh)
    return fit_narrow_work(work)


@njit(cache=True)
def compact_active(ca, npairs):
    """Scan: indices of manifolds with points, in pair order. Returns their count."""
    count, active = ca.contact_point_count, ca.active
    n = 0
    for i in range(npairs):
        if count[i] > 0:
            active[n] = i
            n += 1
    return n


@njit(cache=True)
def match_warm_start(prev, prev_count, cur, cur_count, match_distance):
    """Copy the previous step's impulses onto this step's points of the same pair (both lists sorted by
    key: a linear merge). A point takes the impulse of the previous point with the same feature key,
    else of the nearest previous point within ``match_distance`` (m) -- clipping can rename a corner
    when a face tilts past a side plane or the reference face swaps, and losing its impulse would make
    a stack jitter. Tangent impulses are re-projected on the new tangent basis."""
    # the bundles' arrays as locals (a member read inside the loop costs a reference count)
    p_key, p_count, p_feature, p_point = prev.contact_key, prev.contact_point_count, prev.contact_feature, \
        prev.contact_point
    p_rolling, p_normal_imp, p_tangent_imp, p_tangent = prev.contact_rolling_impulse, \
        prev.contact_normal_impulse, prev.contact_tangent_impulse, prev.contact_tangent
    c_key, c_count, c_feature, c_point = cur.contact_key, cur.contact_point_count, cur.contact_feature, \
        cur.contact_point
    c_rolling, c_normal_imp, c_tangent_imp, c_tangent = cur.contact_rolling_impulse, \
        cur.contact_normal_impulse, cur.contact_tangent_impulse, cur.contact_tangent
    j = 0
    md2 = match_distance * match_distance
    for i in range(cur_count):
        key = c_key[i]
        while j < prev_count and p_key[j] < key:
            j += 1
        if j >= prev_count:
            break
        if p_key[j] != key or c_count[i] == 0:
            continue
        for m in range(3):
            c_rolling[i, m] = p_rolling[j, m]
        for k in range(c_count[i]):
            f = c_feature[i, k]
            found = -1
            for kp in range(p_count[j]):
                if p_feature[j, kp] == f:
                    found = kp
                    break
            if found < 0:
                best = md2
                for kp in range(p_count[j]):
                    d2 = 0.0
                    for m in range(3):
                        d = c_point[i, k, m] - p_point[j, kp, m]
                        d2 += d * d
                    if d2 < best:
                        best, found = d2, kp
            if found < 0:
                continue
            kp = found
            c_normal_imp[i, k] = p_normal_imp[j, kp]
            # old tangent impulse vector, expressed in the new tangent basis
            g0 = p_tangent_imp[j, kp, 0]
            g1 = p_tangent_imp[j, kp, 1]
            for ax in range(2):
                acc = 0.0
                for m in range(3):
                    acc += (g0 * p_tangent[j, 0, m] + g1 * p_tangent[j, 1, m]) * c_tangent[i, ax, m]
                c_tangent_imp[i, k, ax] = acc


from . import trimesh_collide as _tm  # noqa: E402  (imports this module's manifold helpers)
