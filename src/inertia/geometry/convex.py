"""Convex shapes: hull building, support functions, GJK distance and EPA penetration.

Hull building (``build_convex_hull``) runs once at model build time with Qhull (through
``scipy.spatial.ConvexHull``); it returns outward-wound triangles for mass properties and rendering, and
merged polygonal faces (planes plus counter-clockwise vertex loops, CSR) for contact clipping.

References
- Barber, C. B., Dobkin, D. P. and Huhdanpaa, H. (1996). The Quickhull algorithm for convex hulls.
  ACM Transactions on Mathematical Software 22(4), 469-483 (Qhull).

Limitations
- Hull faces are merged when Qhull reports them on the same plane (its triangulated output keeps one
  hyperplane per merged facet); nearly coplanar faces that Qhull keeps apart stay separate faces.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ConvexHullData", "build_convex_hull"]


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
