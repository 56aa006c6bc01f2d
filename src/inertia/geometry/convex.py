"""Convex shapes: hull building, support functions, GJK distance and EPA penetration.

Hull building (``build_convex_hull``) runs once at model build time with Qhull (through
``scipy.spatial.ConvexHull``); it returns outward-wound triangles for mass properties and rendering, and
merged polygonal faces (planes plus counter-clockwise vertex loops, CSR) for contact clipping.

Queries (Numba kernels) take shapes as rows of the shape table: ``(shape_type, params (4,), pose (7,),
vert_start, vert_count)`` plus the shared vertex table ``verts (V, 3)`` (local frames).
- ``support_local``: the farthest point of a shape along a direction (the contract's support function).
- ``gjk_distance``: distance, witness points and normal between convex shapes.  Spheres and capsules enter
  as their cores (a point, a segment) and their radius is added afterwards, so GJK converges exactly and a
  shallow overlap of the rounded parts is still measured exactly (negative distance).
- ``epa_penetration`` / ``shape_distance``: depth and normal when the cores overlap.  EPA runs on the cores
  and adds the radii (exact: the Minkowski difference of the whole shapes is that of the cores grown by
  ra + rb); sphere/capsule pairs whose cores touch have a flat core difference and use a closed form.
Signs: the normal points from A to B; ``shape_distance`` is negative for penetration; witness_b - witness_a
= distance * normal.

References
- Barber, C. B., Dobkin, D. P. and Huhdanpaa, H. (1996). The Quickhull algorithm for convex hulls.
  ACM Transactions on Mathematical Software 22(4), 469-483 (Qhull).
- Gilbert, E. G., Johnson, D. W. and Keerthi, S. S. (1988). A fast procedure for computing the distance
  between complex objects in three-dimensional space. IEEE Journal of Robotics and Automation 4(2).
- van den Bergen, G. (1999). A fast and robust GJK implementation for collision detection of convex objects.
  Journal of Graphics Tools 4(2) (termination test; simplex kept with its support points for witnesses).
- van den Bergen, G. (2001). Proximity queries and penetration depth computation on 3D game objects. GDC
  (the expanding polytope algorithm).
- Ericson, C. (2005). Real-Time Collision Detection. Morgan Kaufmann, 5.1.5 (closest point on a triangle,
  used for the simplex) and 5.1.9 (closest points of two segments).

Limitations
- Hull faces are merged when Qhull reports them on the same plane (its triangulated output keeps one
  hyperplane per merged facet); nearly coplanar faces that Qhull keeps apart stay separate faces.
- Triangle meshes, planes and heightfields are not convex: the queries refuse them (ValueError).
- Cylinders are curved without a core: their EPA depth converges to ``EPA_TOLERANCE`` only within
  ``EPA_MAX_ITERATIONS`` (1e-6 m typical for unit sizes), polytopes and rounded shapes are exact to rounding.
- Work arrays (simplex, EPA polytope ~70 KB, results) live in a `GjkScratch` (``new_gjk_scratch``): the
  narrow phase takes one row per run of pairs from a bank its world makes once (``new_gjk_scratch_bank``,
  ``gjk_scratch_row``) and calls ``gjk_distance_scratch`` / ``_epa``, which allocate
  nothing (except when EPA has to grow a GJK simplex of fewer than 4 points); the public functions
  (``gjk_distance``, ``epa_penetration``, ``shape_distance``) make a scratch per call and return copies.
- Hull ``params`` (scale) are ignored: vertices are used as stored.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from inertia import math as _m

__all__ = ["ConvexHullData", "build_convex_hull", "support_local", "support_core_local", "core_radius",
           "gjk_distance", "epa_penetration", "shape_distance"]


class ConvexHullData(NamedTuple):
    """A convex hull in its shape's local frame (built once; never changes during a step).

    vertices        (V, 3) float64, m: the hull's extreme points only (interior points dropped).
    triangles       (T, 3) int32 into ``vertices``, wound counter-clockwise seen from outside (outward normal
                    by the right-hand rule).
    face_planes     (F, 4) float64: merged polygonal faces as (n, d), unit outward n, n . x = d on the face.
    face_vert_start (F,) int32, face_vert_count (F,) int32: CSR into ``face_verts``.
    face_verts      (K,) int32 into ``vertices``: each face's loop, counter-clockwise seen from outside.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    face_planes: np.ndarray
    face_vert_start: np.ndarray
    face_vert_count: np.ndarray
    face_verts: np.ndarray


def build_convex_hull(points, *, name: str = "points") -> ConvexHullData:
    """Convex hull of a point cloud (N, 3) with N >= 4 points not all on one plane.

    Raises ValueError naming ``name`` for fewer than 4 points, non-finite values, or a flat (coplanar,
    collinear or coincident) cloud, whose hull has no volume."""
    from scipy.spatial import ConvexHull
    from scipy.spatial import QhullError

    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{name} must be an array of shape (N, 3) with N >= 4; got shape {pts.shape}")
    if pts.shape[0] < 4:
        raise ValueError(f"{name} must hold at least 4 points to enclose a volume; got {pts.shape[0]}")
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"{name} must be finite; rows {np.flatnonzero(~np.isfinite(pts).all(1))[:10].tolist()}"
                         " contain NaN or inf")
    # flatness: the smallest singular value of the centred cloud relative to the largest
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] == 0.0 or sv[2] <= 1e-10 * sv[0]:
        raise ValueError(f"{name} are coplanar, collinear or coincident (singular values {sv.tolist()}): "
                         "a convex hull needs 4 points not on one plane")
    try:
        hull = ConvexHull(pts)
    except QhullError as err:  # pragma: no cover - the flatness check above catches the usual causes
        raise ValueError(f"{name}: Qhull could not build a hull ({err})") from None

    # keep only hull vertices, renumbered in ascending original order
    used = np.sort(hull.vertices)
    remap = np.full(pts.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    vertices = np.ascontiguousarray(pts[used])
    tris = remap[hull.simplices]
    normals = hull.equations[:, :3]
    # Qhull's simplex order is arbitrary: flip triangles whose right-hand normal points inward
    a, b, c = vertices[tris[:, 0]], vertices[tris[:, 1]], vertices[tris[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), normals) < 0.0
    tris[flip] = tris[flip][:, ::-1]

    # merge triangles on one plane into polygonal faces (Qhull gives them identical hyperplanes)
    scale = float(np.abs(vertices).max()) or 1.0
    keys = np.round(np.column_stack([normals, hull.equations[:, 3] / scale]), 9)
    _, face_of_tri = np.unique(keys, axis=0, return_inverse=True)
    face_of_tri = face_of_tri.reshape(-1)
    face_count = int(face_of_tri.max()) + 1
    planes = np.empty((face_count, 4))
    loops = []
    for f in range(face_count):
        members = np.flatnonzero(face_of_tri == f)
        n = normals[members].mean(axis=0)
        n /= np.linalg.norm(n)
        idx = np.unique(tris[members])
        fv = vertices[idx]
        centre = fv.mean(axis=0)
        planes[f, :3] = n
        planes[f, 3] = float(np.mean(fv @ n))
        # order the loop counter-clockwise about n (seen from outside)
        u = fv[0] - centre
        u -= n * (u @ n)
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        ang = np.arctan2((fv - centre) @ v, (fv - centre) @ u)
        loops.append(idx[np.argsort(ang, kind="stable")])
    counts = np.array([len(lp) for lp in loops], dtype=np.int32)
    starts = np.zeros(face_count, dtype=np.int32)
    starts[1:] = np.cumsum(counts)[:-1]
    return ConvexHullData(vertices, np.ascontiguousarray(tris, dtype=np.int32), planes, starts, counts,
                          np.concatenate(loops).astype(np.int32))


# =====================================================================================================
# Support functions, GJK and EPA (Numba kernels)
# =====================================================================================================
# shape type codes of the shape table (same values as inertia.geometry.shapes, owned by rigid-core)
SPHERE, BOX, CAPSULE, CYLINDER, CONVEX_HULL, TRIANGLE_MESH, PLANE, HEIGHTFIELD = range(8)

GJK_MAX_ITERATIONS = 64
GJK_REL_TOLERANCE = 1e-12   # stop when |v|^2 - v.w <= tol |v|^2 (van den Bergen 1999)
EPA_MAX_ITERATIONS = 128
EPA_TOLERANCE = 1e-10       # relative gap between the closest face and the support along its normal
_EPA_MAX_VERTS = EPA_MAX_ITERATIONS + 8
_EPA_MAX_FACES = 8 * _EPA_MAX_VERTS
_EPA_MAX_EDGES = 6 * _EPA_MAX_VERTS + 12          # horizon: <= 3 x alive faces <= 6 nv


class GjkScratch(NamedTuple):
    """Work arrays of GJK and EPA, allocated once (per run of pairs in the narrow phase, per call in the
    public wrappers) and reused: only the entries a call writes are read back."""
    pw: np.ndarray      # (_EPA_MAX_VERTS, 3) simplex / polytope vertices on A - B (GJK uses the first 4)
    pa: np.ndarray      # (_EPA_MAX_VERTS, 3) their support points on A
    pb: np.ndarray      # (_EPA_MAX_VERTS, 3) their support points on B
    lam: np.ndarray     # (4,) barycentric weights of GJK's closest point
    bl: np.ndarray      # (4,) weights of the best tetrahedron face in the simplex reduction
    faces: np.ndarray   # (_EPA_MAX_FACES, 3) int64 polytope faces (vertex indices)
    face_n: np.ndarray  # (_EPA_MAX_FACES, 3) their outward unit normals
    face_d: np.ndarray  # (_EPA_MAX_FACES,) their distances from the origin
    alive: np.ndarray   # (_EPA_MAX_FACES,) bool face still on the polytope
    edges: np.ndarray   # (_EPA_MAX_EDGES, 2) int64 horizon edges
    axes: np.ndarray    # (6, 3) the +-coordinate axes (constant)
    tri: np.ndarray     # (4, 3) int64 faces of the initial tetrahedron (constant)
    vec: np.ndarray     # (11, 3) 3-vectors: search direction, local direction, local support, GJK's v,
                        # the support points on A and on B of the current iteration; results: witness on
                        # A, witness on B, unit normal A -> B; EPA's seed: a unit perpendicular, the unit
                        # segment direction
    quat: np.ndarray    # (4,) EPA's seed: the rotation about the segment


@njit(cache=True)
def new_gjk_scratch():
    """A `GjkScratch` for one run of GJK/EPA calls."""
    axes = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [-1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
    tri = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], dtype=np.int64)
    return GjkScratch(np.empty((_EPA_MAX_VERTS, 3)), np.empty((_EPA_MAX_VERTS, 3)), np.empty((_EPA_MAX_VERTS, 3)),
                      np.zeros(4), np.zeros(4), np.empty((_EPA_MAX_FACES, 3), dtype=np.int64),
                      np.empty((_EPA_MAX_FACES, 3)), np.empty(_EPA_MAX_FACES), np.zeros(_EPA_MAX_FACES, dtype=np.bool_),
                      np.empty((_EPA_MAX_EDGES, 2), dtype=np.int64), axes, tri, np.zeros((11, 3)), np.zeros(4))


def new_gjk_scratch_bank(runs: int) -> GjkScratch:
    """``runs`` GjkScratch rows in one bundle (each array with a leading axis of length ``runs``), made
    once by a world and handed to the narrow phase: run ``i`` of a parallel loop works in
    ``gjk_scratch_row(bank, i)``, so a step allocates no GJK/EPA work arrays."""
    r = int(runs)
    bank = GjkScratch(np.empty((r, _EPA_MAX_VERTS, 3)), np.empty((r, _EPA_MAX_VERTS, 3)),
                      np.empty((r, _EPA_MAX_VERTS, 3)), np.zeros((r, 4)), np.zeros((r, 4)),
                      np.empty((r, _EPA_MAX_FACES, 3), dtype=np.int64), np.empty((r, _EPA_MAX_FACES, 3)),
                      np.empty((r, _EPA_MAX_FACES)), np.zeros((r, _EPA_MAX_FACES), dtype=np.bool_),
                      np.empty((r, _EPA_MAX_EDGES, 2), dtype=np.int64), np.empty((r, 6, 3)),
                      np.empty((r, 4, 3), dtype=np.int64), np.zeros((r, 11, 3)), np.zeros((r, 4)))
    one = new_gjk_scratch.py_func()      # plain NumPy: a world's build compiles nothing for the constants
    bank.axes[:] = one.axes
    bank.tri[:] = one.tri
    return bank


@njit(cache=True)
def gjk_scratch_row(bank, i):
    """Row ``i`` of a scratch bank (`new_gjk_scratch_bank`) as a `GjkScratch` of views (no allocation)."""
    return GjkScratch(bank.pw[i], bank.pa[i], bank.pb[i], bank.lam[i], bank.bl[i], bank.faces[i], bank.face_n[i],
                      bank.face_d[i], bank.alive[i], bank.edges[i], bank.axes[i], bank.tri[i], bank.vec[i],
                      bank.quat[i])


@njit(cache=True)
def core_radius(shape_type, params):
    """Radius swept around the core of a shape: spheres (core = a point) and capsules (core = a segment)
    are handled by GJK as their core plus this radius, which makes GJK exact and fast for them."""
    if shape_type == SPHERE or shape_type == CAPSULE:
        return params[0]
    return 0.0


@njit(cache=True)
def support_core_local(shape_type, params, verts, vert_start, vert_count, direction):
    """Farthest point of the shape's core (the shape minus ``core_radius``) along ``direction``, local frame."""
    out = np.zeros(3)
    return _support_core_local_into(shape_type, params, verts, vert_start, vert_count, direction, out)


@njit(cache=True)
def _support_core_local_into(shape_type, params, verts, vert_start, vert_count, direction, out):
    """``support_core_local`` written into ``out`` (3,), which is returned."""
    dx, dy, dz = direction[0], direction[1], direction[2]
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    if shape_type == SPHERE:
        return out
    if shape_type == CAPSULE:
        out[2] = params[1] if dz >= 0.0 else -params[1]
        return out
    if shape_type == BOX:
        out[0] = params[0] if dx >= 0.0 else -params[0]
        out[1] = params[1] if dy >= 0.0 else -params[1]
        out[2] = params[2] if dz >= 0.0 else -params[2]
        return out
    if shape_type == CYLINDER:
        r = math.sqrt(dx * dx + dy * dy)
        if r > 0.0:
            out[0] = params[0] * dx / r
            out[1] = params[0] * dy / r
        out[2] = params[1] if dz >= 0.0 else -params[1]
        return out
    if shape_type == CONVEX_HULL:
        best = -np.inf
        best_i = vert_start
        for i in range(vert_start, vert_start + vert_count):
            s = verts[i, 0] * dx + verts[i, 1] * dy + verts[i, 2] * dz
            if s > best:
                best = s
                best_i = i
        out[0] = verts[best_i, 0]
        out[1] = verts[best_i, 1]
        out[2] = verts[best_i, 2]
        return out
    raise ValueError("support_local: shape_type must be SPHERE, BOX, CAPSULE, CYLINDER or CONVEX_HULL "
                     "(meshes, planes and heightfields are not convex)")


@njit(cache=True)
def support_local(shape_type, params, verts, vert_start, vert_count, direction):
    """Farthest point of the whole shape along ``direction`` (any length; a zero direction picks an arbitrary
    extreme point), in the shape's local frame (contract's support function)."""
    out = support_core_local(shape_type, params, verts, vert_start, vert_count, direction)
    r = core_radius(shape_type, params)
    if r > 0.0:
        n = math.sqrt(direction[0] ** 2 + direction[1] ** 2 + direction[2] ** 2)
        if n > 0.0:
            for k in range(3):
                out[k] += r * direction[k] / n
        else:
            out[0] += r
    return out


@njit(cache=True)
def _support_world(shape_type, params, pose, verts, vert_start, vert_count, direction, with_radius):
    d_local = _m.quat_rotate_inv(pose[3:7], direction)
    if with_radius:
        p = support_local(shape_type, params, verts, vert_start, vert_count, d_local)
    else:
        p = support_core_local(shape_type, params, verts, vert_start, vert_count, d_local)
    return _m.transform_point(pose, p)


@njit(cache=True)
def _support_world_into(shape_type, params, pose, verts, vert_start, vert_count, direction, sign, with_radius,
                        out, scr):
    """``_support_world`` along ``sign * direction`` (sign +-1) written into ``out`` (3,), no allocation
    (same arithmetic, so the same bits); uses rows 0-2 of ``scr.vec``."""
    dvec, dloc, p = scr.vec[0], scr.vec[1], scr.vec[2]
    for k in range(3):
        dvec[k] = sign * direction[k]
    _m.quat_rotate_inv_into(pose[3:7], dvec, dloc)
    _support_core_local_into(shape_type, params, verts, vert_start, vert_count, dloc, p)
    if with_radius:
        r = core_radius(shape_type, params)
        if r > 0.0:
            n = math.sqrt(dloc[0] ** 2 + dloc[1] ** 2 + dloc[2] ** 2)
            if n > 0.0:
                for k in range(3):
                    p[k] += r * dloc[k] / n
            else:
                p[0] += r
    _m.quat_rotate_into(pose[3:7], p, out)
    out[0] += pose[0]
    out[1] += pose[1]
    out[2] += pose[2]


@njit(cache=True)
def _closest_on_triangle(a, b, c):
    """Barycentric weights (u, v, w) of the point of triangle abc closest to the origin (Ericson 2005,
    Real-Time Collision Detection, 5.1.5: Voronoi regions of vertices, edges, face)."""
    return _closest_on_triangle_xyz(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2])


@njit(cache=True)
def _closest_on_triangle_xyz(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """``_closest_on_triangle`` of the corners given by coordinates (no arrays)."""
    a = (a0, a1, a2)
    b = (b0, b1, b2)
    c = (c0, c1, c2)
    ab = (b0 - a0, b1 - a1, b2 - a2)
    ac = (c0 - a0, c1 - a1, c2 - a2)
    d1 = -(ab[0] * a[0] + ab[1] * a[1] + ab[2] * a[2])
    d2 = -(ac[0] * a[0] + ac[1] * a[1] + ac[2] * a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        return 1.0, 0.0, 0.0
    d3 = -(ab[0] * b[0] + ab[1] * b[1] + ab[2] * b[2])
    d4 = -(ac[0] * b[0] + ac[1] * b[1] + ac[2] * b[2])
    if d3 >= 0.0 and d4 <= d3:
        return 0.0, 1.0, 0.0
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return 1.0 - v, v, 0.0
    d5 = -(ab[0] * c[0] + ab[1] * c[1] + ab[2] * c[2])
    d6 = -(ac[0] * c[0] + ac[1] * c[1] + ac[2] * c[2])
    if d6 >= 0.0 and d5 <= d6:
        return 0.0, 0.0, 1.0
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return 1.0 - w, 0.0, w
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return 0.0, 1.0 - w, w
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return 1.0 - v - w, v, w


@njit(cache=True)
def _barycentric_rows(pw, ia, ib, ic, p0, p1, p2):
    """Unclamped barycentric coordinates of the projection of the point (p0, p1, p2) onto the plane of the
    triangle of rows ia, ib, ic of ``pw``."""
    v0 = (pw[ib, 0] - pw[ia, 0], pw[ib, 1] - pw[ia, 1], pw[ib, 2] - pw[ia, 2])
    v1 = (pw[ic, 0] - pw[ia, 0], pw[ic, 1] - pw[ia, 1], pw[ic, 2] - pw[ia, 2])
    v2 = (p0 - pw[ia, 0], p1 - pw[ia, 1], p2 - pw[ia, 2])
    d00 = _m.dot(v0, v0)
    d01 = _m.dot(v0, v1)
    d11 = _m.dot(v1, v1)
    d20 = _m.dot(v2, v0)
    d21 = _m.dot(v2, v1)
    den = d00 * d11 - d01 * d01
    if den <= 0.0:
        return -np.inf, -np.inf, -np.inf
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return 1.0 - v - w, v, w


@njit(cache=True)
def _cross3(a, b):
    """a x b of 3-tuples, the same arithmetic as ``inertia.math.cross`` without an array."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def _reduce_simplex(sw, sa, sb, n, lam, bl):
    """Closest point of the simplex sw[:n] to the origin; keeps only the vertices that support it (their
    weights in lam) and returns the new count; count 4 means the origin is inside the tetrahedron."""
    if n == 1:
        lam[0] = 1.0
        return 1
    if n == 2:
        e = (sw[1, 0] - sw[0, 0], sw[1, 1] - sw[0, 1], sw[1, 2] - sw[0, 2])
        ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        t = -(e[0] * sw[0, 0] + e[1] * sw[0, 1] + e[2] * sw[0, 2]) / ee if ee > 0.0 else 0.0
        if t <= 0.0:
            lam[0] = 1.0
            return 1
        if t >= 1.0:
            for k in range(3):
                sw[0, k] = sw[1, k]
                sa[0, k] = sa[1, k]
                sb[0, k] = sb[1, k]
            lam[0] = 1.0
            return 1
        lam[0] = 1.0 - t
        lam[1] = t
        return 2
    if n == 3:
        u, v, w = _closest_on_triangle_xyz(sw[0, 0], sw[0, 1], sw[0, 2], sw[1, 0], sw[1, 1], sw[1, 2],
                                           sw[2, 0], sw[2, 1], sw[2, 2])
        lam[0], lam[1], lam[2] = u, v, w
        return _compact(sw, sa, sb, 3, lam)
    # tetrahedron: the origin is outside a face when it lies on the other side from the opposite vertex
    best = np.inf
    bl[:] = 0.0
    inside = True
    faces = ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 3, 1), (1, 2, 3, 0))
    # a flat tetrahedron (support ties of flat shapes put four points on one plane) encloses nothing:
    # then the closest point of its faces decides, and GJK goes on with (at most) a triangle
    e1 = (sw[1, 0] - sw[0, 0], sw[1, 1] - sw[0, 1], sw[1, 2] - sw[0, 2])
    e2 = (sw[2, 0] - sw[0, 0], sw[2, 1] - sw[0, 1], sw[2, 2] - sw[0, 2])
    e3 = (sw[3, 0] - sw[0, 0], sw[3, 1] - sw[0, 1], sw[3, 2] - sw[0, 2])
    vol = _m.dot(_cross3(e1, e2), e3)
    flat = abs(vol) <= 1e-10 * math.sqrt(_m.dot(e1, e1) * _m.dot(e2, e2) * _m.dot(e3, e3))
    for f in faces:
        i, j, k, o = f
        nrm = _cross3((sw[j, 0] - sw[i, 0], sw[j, 1] - sw[i, 1], sw[j, 2] - sw[i, 2]),
                      (sw[k, 0] - sw[i, 0], sw[k, 1] - sw[i, 1], sw[k, 2] - sw[i, 2]))
        s_origin = -(nrm[0] * sw[i, 0] + nrm[1] * sw[i, 1] + nrm[2] * sw[i, 2])
        s_opp = nrm[0] * (sw[o, 0] - sw[i, 0]) + nrm[1] * (sw[o, 1] - sw[i, 1]) + nrm[2] * (sw[o, 2] - sw[i, 2])
        if flat or s_origin * s_opp < 0.0:
            inside = False
            u, v, w = _closest_on_triangle_xyz(sw[i, 0], sw[i, 1], sw[i, 2], sw[j, 0], sw[j, 1], sw[j, 2],
                                               sw[k, 0], sw[k, 1], sw[k, 2])
            p = (u * sw[i, 0] + v * sw[j, 0] + w * sw[k, 0], u * sw[i, 1] + v * sw[j, 1] + w * sw[k, 1],
                 u * sw[i, 2] + v * sw[j, 2] + w * sw[k, 2])
            d = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
            if d < best:
                best = d
                bl[:] = 0.0
                bl[i] = u
                bl[j] = v
                bl[k] = w
    if inside:
        return 4
    lam[:4] = bl
    return _compact(sw, sa, sb, 4, lam)


@njit(cache=True)
def _compact(sw, sa, sb, n, lam):
    m = 0
    for i in range(n):
        if lam[i] > 0.0:
            for k in range(3):
                sw[m, k] = sw[i, k]
                sa[m, k] = sa[i, k]
                sb[m, k] = sb[i, k]
            lam[m] = lam[i]
            m += 1
    return m


@njit(cache=True)
def _gjk(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b, verts,
         with_radius, sw, sa, sb, scr):
    """GJK (Gilbert, Johnson and Keerthi 1988; van den Bergen 1999 termination) on A - B.

    Returns (distance, count, lam): distance between the shapes (0 when they overlap), the final simplex
    size (4 = origin enclosed) with vertices sw (A - B), sa, sb and weights lam (``scr.lam``).  Works in
    the `GjkScratch` ``scr``: allocates nothing."""
    lam, bl = scr.lam, scr.bl
    lam[:] = 0.0
    d, v, qa, qb = scr.vec[3], scr.vec[3], scr.vec[4], scr.vec[5]
    for k in range(3):
        d[k] = pose_b[k] - pose_a[k]
    if d[0] == 0.0 and d[1] == 0.0 and d[2] == 0.0:
        d[0] = 1.0
    # first vertex: support of A - B along the direction from B to A
    _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, d, -1.0, with_radius, qa, scr)
    _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, d, 1.0, with_radius, qb, scr)
    for k in range(3):
        sa[0, k] = qa[k]
        sb[0, k] = qb[k]
        sw[0, k] = qa[k] - qb[k]
    n = 1
    lam[0] = 1.0
    for k in range(3):
        v[k] = sw[0, k]
    for _ in range(GJK_MAX_ITERATIONS):
        vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if vv <= 1e-30:
            return 0.0, n, lam
        _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, v, -1.0, with_radius, qa, scr)
        _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, v, 1.0, with_radius, qb, scr)
        w0, w1, w2 = qa[0] - qb[0], qa[1] - qb[1], qa[2] - qb[2]
        # no progress: v is the closest point (within the relative tolerance)
        if vv - (v[0] * w0 + v[1] * w1 + v[2] * w2) <= GJK_REL_TOLERANCE * vv:
            return math.sqrt(vv), n, lam
        # a repeated vertex also means no progress
        for i in range(n):
            if sw[i, 0] == w0 and sw[i, 1] == w1 and sw[i, 2] == w2:
                return math.sqrt(vv), n, lam
        sw[n, 0], sw[n, 1], sw[n, 2] = w0, w1, w2
        for k in range(3):
            sa[n, k] = qa[k]
            sb[n, k] = qb[k]
        n += 1
        n = _reduce_simplex(sw, sa, sb, n, lam, bl)
        if n == 4:
            return 0.0, 4, lam
        v[:] = 0.0
        for i in range(n):
            for k in range(3):
                v[k] += lam[i] * sw[i, k]
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), n, lam


@njit(cache=True)
def gjk_distance(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b,
                 verts):
    """Distance between two convex shapes with witness points and the unit normal from A to B.

    Shapes: (type, params (4,), pose (7,), vert_start, vert_count) rows of the shape table; ``verts`` the
    shared vertex table (V, 3).  Spheres and capsules are their cores (point, segment) plus radius, so a
    negative distance (shallow overlap of the rounded parts) is still exact.  Returns
    (distance, witness_a (3,), witness_b (3,), normal (3,), separated) where ``separated`` is False when the
    cores overlap (then distance = 0 and the witnesses are meaningless: call ``epa_penetration``)."""
    scr = new_gjk_scratch()
    dist, separated = gjk_distance_scratch(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b,
                                           start_b, count_b, verts, scr)
    return dist, scr.vec[6].copy(), scr.vec[7].copy(), scr.vec[8].copy(), separated


@njit(cache=True)
def gjk_distance_scratch(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b,
                         count_b, verts, scr):
    """``gjk_distance`` working in the `GjkScratch` ``scr``, allocating nothing: returns (distance,
    separated) and writes witness_a, witness_b and the normal into ``scr.vec[6]``, ``[7]``, ``[8]``."""
    sw, sa, sb = scr.pw, scr.pa, scr.pb
    dist, n, lam = _gjk(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b,
                        count_b, verts, False, sw, sa, sb, scr)
    pa, pb, normal = scr.vec[6], scr.vec[7], scr.vec[8]
    pa[:] = 0.0
    pb[:] = 0.0
    normal[:] = 0.0
    if n == 4 or dist <= 1e-12:
        return 0.0, False
    for i in range(n):
        for k in range(3):
            pa[k] += lam[i] * sa[i, k]
            pb[k] += lam[i] * sb[i, k]
    ra = core_radius(type_a, params_a)
    rb = core_radius(type_b, params_b)
    for k in range(3):
        normal[k] = (pb[k] - pa[k]) / dist
        pa[k] = pa[k] + ra * normal[k]
        pb[k] = pb[k] - rb * normal[k]
    return dist - ra - rb, True


@njit(cache=True)
def _epa_face(pw, i, j, k, faces, face_n, face_d, f):
    """Store face (i, j, k) with its outward unit normal and distance from the origin; False if degenerate."""
    a0, a1, a2 = pw[j, 0] - pw[i, 0], pw[j, 1] - pw[i, 1], pw[j, 2] - pw[i, 2]
    b0, b1, b2 = pw[k, 0] - pw[i, 0], pw[k, 1] - pw[i, 1], pw[k, 2] - pw[i, 2]
    n0 = a1 * b2 - a2 * b1
    n1 = a2 * b0 - a0 * b2
    n2 = a0 * b1 - a1 * b0
    ln = math.sqrt(n0 ** 2 + n1 ** 2 + n2 ** 2)
    if ln <= 1e-300:
        return False
    n0 /= ln
    n1 /= ln
    n2 /= ln
    faces[f, 0] = i
    faces[f, 1] = j
    faces[f, 2] = k
    face_n[f, 0], face_n[f, 1], face_n[f, 2] = n0, n1, n2
    face_d[f] = n0 * pw[i, 0] + n1 * pw[i, 1] + n2 * pw[i, 2]
    return True


@njit(cache=True)
def _set_vertex(pw, pa, pb, i, p1, p2):
    """Polytope vertex i: the support points p1 on A and p2 on B, and p1 - p2 on A - B."""
    for k in range(3):
        pw[i, k] = p1[k] - p2[k]
        pa[i, k] = p1[k]
        pb[i, k] = p2[k]


@njit(cache=True)
def epa_penetration(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b,
                    verts):
    """Penetration depth, witness points and unit normal from A to B of two overlapping convex shapes by the
    expanding polytope algorithm on the whole shapes (see ``_epa``; ``shape_distance`` is usually better: it
    runs EPA on the cores of spheres and capsules and adds their radii, which is exact)."""
    scr = new_gjk_scratch()
    depth, ok = _epa(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b,
                     verts, True, scr)
    return depth, scr.vec[6].copy(), scr.vec[7].copy(), scr.vec[8].copy(), ok


@njit(cache=True)
def _epa(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b, verts,
         with_radius, scr):
    """Penetration depth, witness points and unit normal from A to B of two overlapping convex shapes by the
    expanding polytope algorithm (van den Bergen 2001) on the Minkowski difference A - B.

    Returns (depth, ok) and writes witness_a, witness_b, normal into ``scr.vec[6]``, ``[7]``, ``[8]``
    (zeros when not ok): translating B by depth * normal separates the shapes
    (touching); witness_a is A's deepest point inside B, witness_b B's deepest inside A.  ok is False when
    the shapes do not overlap (use ``gjk_distance``) or the polytope degenerated.  Works in the
    `GjkScratch` ``scr``: only the entries below nv / nf are ever read."""
    pw, pa, pb = scr.pw, scr.pa, scr.pb
    dist, n, lam = _gjk(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b,
                        count_b, verts, with_radius, pw, pa, pb, scr)
    wa, wb, normal = scr.vec[6], scr.vec[7], scr.vec[8]
    wa[:] = 0.0
    wb[:] = 0.0
    normal[:] = 0.0
    if dist > 1e-12:
        return 0.0, False
    # grow the GJK simplex into a tetrahedron (or bipyramid) that encloses the origin (in the scratch:
    # support points into vec[4], vec[5], directions in vec[3], vec[9], vec[10] and quat)
    axes = scr.axes
    p1, p2, d = scr.vec[4], scr.vec[5], scr.vec[3]
    nv = n
    if nv == 1:
        for a in range(6):
            _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, axes[a], 1.0, with_radius, p1,
                                scr)
            _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, axes[a], -1.0, with_radius, p2,
                                scr)
            w0, w1, w2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
            if (w0 - pw[0, 0]) ** 2 + (w1 - pw[0, 1]) ** 2 + (w2 - pw[0, 2]) ** 2 > 1e-20:
                _set_vertex(pw, pa, pb, 1, p1, p2)
                nv = 2
                break
    if nv == 2:
        e0, e1, e2 = pw[1, 0] - pw[0, 0], pw[1, 1] - pw[0, 1], pw[1, 2] - pw[0, 2]
        # a direction perpendicular to the segment, rotated about it in 60 degree steps
        k = 0 if abs(e0) <= abs(e1) and abs(e0) <= abs(e2) else (1 if abs(e1) <= abs(e2) else 2)
        ax = axes[k]
        perp, e_unit, q = scr.vec[9], scr.vec[10], scr.quat
        perp[0] = e1 * ax[2] - e2 * ax[1]
        perp[1] = e2 * ax[0] - e0 * ax[2]
        perp[2] = e0 * ax[1] - e1 * ax[0]
        ln = math.sqrt(perp[0] ** 2 + perp[1] ** 2 + perp[2] ** 2)
        ee = e0 ** 2 + e1 ** 2 + e2 ** 2
        le = math.sqrt(ee)
        e_unit[0], e_unit[1], e_unit[2] = e0 / le, e1 / le, e2 / le
        for c in range(3):
            perp[c] /= ln
        for step in range(6):
            _m.quat_from_axis_angle_into(e_unit, step * math.pi / 3.0, q)
            _m.quat_rotate_into(q, perp, d)
            _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, d, 1.0, with_radius, p1, scr)
            _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, d, -1.0, with_radius, p2, scr)
            # area of the triangle (pw0, pw1, w): (pw1 - pw0) x (w - pw0)
            f0, f1, f2 = p1[0] - p2[0] - pw[0, 0], p1[1] - p2[1] - pw[0, 1], p1[2] - p2[2] - pw[0, 2]
            c0, c1, c2 = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
            if c0 ** 2 + c1 ** 2 + c2 ** 2 > 1e-20 * ee ** 2:
                _set_vertex(pw, pa, pb, 2, p1, p2)
                nv = 3
                break
    if nv == 3:
        # apex: the support along +-normal farther from the triangle's plane.  The tetrahedron then holds the
        # origin (inside or on its boundary) and its centroid is strictly inside, which orients the faces.
        a0, a1, a2 = pw[1, 0] - pw[0, 0], pw[1, 1] - pw[0, 1], pw[1, 2] - pw[0, 2]
        b0, b1, b2 = pw[2, 0] - pw[0, 0], pw[2, 1] - pw[0, 1], pw[2, 2] - pw[0, 2]
        d[0], d[1], d[2] = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        best_height = 0.0
        for sgn in (1.0, -1.0):
            _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, d, sgn, with_radius, p1, scr)
            _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, d, -sgn, with_radius, p2, scr)
            height = abs((p1[0] - p2[0] - pw[0, 0]) * d[0] + (p1[1] - p2[1] - pw[0, 1]) * d[1]
                         + (p1[2] - p2[2] - pw[0, 2]) * d[2])
            if height > best_height:
                best_height = height
                _set_vertex(pw, pa, pb, 3, p1, p2)
        if best_height <= 1e-12 * (d[0] ** 2 + d[1] ** 2 + d[2] ** 2):
            return 0.0, False
        nv = 4
    faces, face_n, face_d, alive = scr.faces, scr.face_n, scr.face_d, scr.alive
    alive[:] = False
    nf = 0
    # initial faces, each oriented away from the polytope's interior point
    c0, c1, c2 = 0.0, 0.0, 0.0
    for i in range(nv):
        c0 += pw[i, 0]
        c1 += pw[i, 1]
        c2 += pw[i, 2]
    c0 /= nv
    c1 /= nv
    c2 /= nv
    tri = scr.tri
    for t in range(tri.shape[0]):
        i, j, k = tri[t, 0], tri[t, 1], tri[t, 2]
        a0, a1, a2 = pw[j, 0] - pw[i, 0], pw[j, 1] - pw[i, 1], pw[j, 2] - pw[i, 2]
        b0, b1, b2 = pw[k, 0] - pw[i, 0], pw[k, 1] - pw[i, 1], pw[k, 2] - pw[i, 2]
        n0 = a1 * b2 - a2 * b1
        n1 = a2 * b0 - a0 * b2
        n2 = a0 * b1 - a1 * b0
        if n0 * (pw[i, 0] - c0) + n1 * (pw[i, 1] - c1) + n2 * (pw[i, 2] - c2) < 0.0:
            j, k = k, j
        if not _epa_face(pw, i, j, k, faces, face_n, face_d, nf):
            return 0.0, False
        alive[nf] = True
        nf += 1
    edges = scr.edges
    best = 0
    for _ in range(EPA_MAX_ITERATIONS):
        # the face closest to the origin
        best = -1
        bd = np.inf
        for f in range(nf):
            if alive[f] and face_d[f] < bd:
                bd = face_d[f]
                best = f
        if best < 0:
            return 0.0, False
        nrm, p1, p2 = scr.vec[3], scr.vec[4], scr.vec[5]
        for k in range(3):
            nrm[k] = face_n[best, k]
        _support_world_into(type_a, params_a, pose_a, verts, start_a, count_a, nrm, 1.0, with_radius, p1, scr)
        _support_world_into(type_b, params_b, pose_b, verts, start_b, count_b, nrm, -1.0, with_radius, p2, scr)
        w0, w1, w2 = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
        gap = (w0 * nrm[0] + w1 * nrm[1] + w2 * nrm[2]) - bd
        if gap <= EPA_TOLERANCE * max(1.0, abs(bd)) or nv >= _EPA_MAX_VERTS or nf + 2 * nv >= _EPA_MAX_FACES:
            break
        pw[nv, 0], pw[nv, 1], pw[nv, 2] = w0, w1, w2
        for k in range(3):
            pa[nv, k] = p1[k]
            pb[nv, k] = p2[k]
        # remove the faces the new vertex sees; their unshared edges form the horizon
        # (a tolerance keeps faces coplanar with w: removing only some of a flat patch, by rounding, would
        # leave a horizon that is not a simple loop and fold the polytope)
        ne = 0
        see_tol = 1e-10 * max(1.0, math.sqrt(w0 * w0 + w1 * w1 + w2 * w2))
        for f in range(nf):
            g0 = faces[f, 0]
            if alive[f] and (face_n[f, 0] * (w0 - pw[g0, 0]) + face_n[f, 1] * (w1 - pw[g0, 1])
                             + face_n[f, 2] * (w2 - pw[g0, 2])) > see_tol:
                alive[f] = False
                for e in range(3):
                    u = faces[f, e]
                    v = faces[f, (e + 1) % 3]
                    shared = -1
                    for g in range(ne):
                        if edges[g, 0] == v and edges[g, 1] == u:
                            shared = g
                            break
                    if shared >= 0:
                        # element-wise: a row-to-row slice assignment within one array makes a temporary copy
                        edges[shared, 0] = edges[ne - 1, 0]
                        edges[shared, 1] = edges[ne - 1, 1]
                        ne -= 1
                    else:
                        edges[ne, 0] = u
                        edges[ne, 1] = v
                        ne += 1
        for g in range(ne):
            if _epa_face(pw, edges[g, 0], edges[g, 1], nv, faces, face_n, face_d, nf):
                alive[nf] = True
                nf += 1
        nv += 1
    # witnesses: barycentric coordinates of the origin's projection onto the closest face.  Coplanar
    # neighbours tie with it (face-face contacts split a polygon into triangles); take the one whose
    # triangle holds the foot point, else the closest point of the best face
    depth = face_d[best]
    p0, p1, p2 = depth * face_n[best, 0], depth * face_n[best, 1], depth * face_n[best, 2]
    chosen = best
    best_margin = -np.inf
    for f in range(nf):
        if alive[f] or f == best:
            if abs(face_d[f] - depth) <= 1e-9 * max(1.0, abs(depth)) and _m.dot(face_n[f], face_n[best]) > 0.999999:
                b0, b1, b2 = _barycentric_rows(pw, faces[f, 0], faces[f, 1], faces[f, 2], p0, p1, p2)
                margin = min(b0, min(b1, b2))
                if margin > best_margin:
                    best_margin = margin
                    chosen = f
    i, j, k = faces[chosen, 0], faces[chosen, 1], faces[chosen, 2]
    u, v, w3 = _closest_on_triangle_xyz(pw[i, 0] - p0, pw[i, 1] - p1, pw[i, 2] - p2, pw[j, 0] - p0, pw[j, 1] - p1,
                                        pw[j, 2] - p2, pw[k, 0] - p0, pw[k, 1] - p1, pw[k, 2] - p2)
    for c in range(3):
        wa[c] = u * pa[i, c] + v * pa[j, c] + w3 * pa[k, c]
        wb[c] = u * pb[i, c] + v * pb[j, c] + w3 * pb[k, c]
        normal[c] = face_n[best, c]
    return depth, True


@njit(cache=True)
def _closest_segment_params(p1, q1, p2, q2):
    """Parameters (s, t) in [0, 1] of the closest points p1 + s (q1 - p1), p2 + t (q2 - p2) of two segments
    (Ericson 2005, Real-Time Collision Detection, 5.1.9); degenerate segments (points) allowed."""
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = _m.dot(d1, d1)
    e = _m.dot(d2, d2)
    f = _m.dot(d2, r)
    if a <= 1e-300 and e <= 1e-300:
        return 0.0, 0.0
    if a <= 1e-300:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = _m.dot(d1, r)
    if e <= 1e-300:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = _m.dot(d1, d2)
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0.0 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((b - c) / a, 0.0), 1.0)
    return s, t


@njit(cache=True)
def _rounded_core_overlap(type_a, params_a, pose_a, type_b, params_b, pose_b):
    """Sphere/capsule pairs whose cores (points, segments) touch: the Minkowski difference of the cores is
    flat, so the penetration leaves along the normal of that flat set with depth ra + rb."""
    ha = params_a[1] if type_a == CAPSULE else 0.0
    hb = params_b[1] if type_b == CAPSULE else 0.0
    za = _m.quat_rotate(pose_a[3:7], np.array([0.0, 0.0, 1.0]))
    zb = _m.quat_rotate(pose_b[3:7], np.array([0.0, 0.0, 1.0]))
    p1 = pose_a[0:3] - ha * za
    q1 = pose_a[0:3] + ha * za
    p2 = pose_b[0:3] - hb * zb
    q2 = pose_b[0:3] + hb * zb
    s, t = _closest_segment_params(p1, q1, p2, q2)
    ca = p1 + s * (q1 - p1)
    cb = p2 + t * (q2 - p2)
    # normal: across both segments if they cross, else perpendicular to the segment(s), towards B's centre
    n = _m.cross(q1 - p1, q2 - p2)
    if _m.dot(n, n) <= 1e-24 * (1.0 + _m.dot(q1 - p1, q1 - p1) * _m.dot(q2 - p2, q2 - p2)):
        axis = q1 - p1 if ha > 0.0 else q2 - p2
        n = pose_b[0:3] - pose_a[0:3]
        if ha > 0.0 or hb > 0.0:
            u = axis / math.sqrt(_m.dot(axis, axis))
            n = n - _m.dot(n, u) * u
            if _m.dot(n, n) <= 1e-24:
                k = 0 if abs(u[0]) <= abs(u[1]) and abs(u[0]) <= abs(u[2]) else (1 if abs(u[1]) <= abs(u[2]) else 2)
                e = np.zeros(3)
                e[k] = 1.0
                n = _m.cross(u, e)
        elif _m.dot(n, n) <= 1e-24:
            n = np.array([0.0, 0.0, 1.0])
    n = n / math.sqrt(_m.dot(n, n))
    if _m.dot(n, pose_b[0:3] - pose_a[0:3]) < 0.0:
        n = -n
    ra = params_a[0]
    rb = params_b[0]
    return -(ra + rb), ca + ra * n, cb - rb * n, n


@njit(cache=True)
def shape_distance(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b,
                   verts):
    """Signed distance between two convex shapes (negative: penetration depth), witness points on A and B
    and the unit normal from A to B.

    GJK on the cores (spheres: points, capsules: segments) gives separated and shallow cases exactly; when
    the cores overlap, EPA runs on the cores and the radii are added (exact for polytopes, spheres and
    capsules; cylinders converge to ``EPA_TOLERANCE`` or the iteration cap)."""
    scr = new_gjk_scratch()
    d, separated = gjk_distance_scratch(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b,
                                        start_b, count_b, verts, scr)
    if separated:
        return d, scr.vec[6].copy(), scr.vec[7].copy(), scr.vec[8].copy()
    rounded_a = type_a == SPHERE or type_a == CAPSULE
    rounded_b = type_b == SPHERE or type_b == CAPSULE
    if rounded_a and rounded_b:
        return _rounded_core_overlap(type_a, params_a, pose_a, type_b, params_b, pose_b)
    depth, ok = _epa(type_a, params_a, pose_a, start_a, count_a, type_b, params_b, pose_b, start_b, count_b,
                     verts, False, scr)
    wa, wb, nrm = scr.vec[6].copy(), scr.vec[7].copy(), scr.vec[8].copy()
    ra = core_radius(type_a, params_a)
    rb = core_radius(type_b, params_b)
    return -(depth + ra + rb), wa + ra * nrm, wb - rb * nrm, nrm
