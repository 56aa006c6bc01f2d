"""Static triangle meshes and heightfields in the shape table, and convex shapes colliding with them.

Storage (no table beyond the contract's): a TRIANGLE_MESH row keeps its triangles as a triangle list in
``geom_vertices`` (three rows per triangle, in BVH order, ``shape_params[0]`` = T) and its BVH nodes in
``geom_bvh_bounds``/``geom_bvh_nodes`` from ``shape_bvh_start`` (`inertia.geometry.bvh`). A HEIGHTFIELD
row keeps its grid points (x, y, height) in ``geom_vertices`` (row ``i * ny + j``), ``shape_params`` =
(nx, ny, dx, dy); cell (i, j) holds the triangles (v00, v10, v11) and (v00, v11, v01), enumerated on the
fly from the cells under a query box.

Narrow phase (stage ``narrow_phase``, called from ``narrowphase.narrow_phase_mesh`` for pairs whose B
is a mesh or heightfield), all in the mesh's local frame, candidates = triangles under A's box fattened
by the speculative distance:
- sphere: the closest point of each candidate triangle (Ericson 2005, 5.1.5), normal from that point to
  the sphere centre (so edges and vertices round correctly; a centre behind the face takes the face
  normal); triangles giving the same normal (shared edge or vertex, coplanar faces) count once, distinct
  normals (a concave crease) give one point each on the blended normal (``_sphere_crease``);
- capsule: the same for its two end spheres (two points, the deeper one's normal);
- box, cylinder (16 rim points), convex hull: vertex-face contacts: each vertex of A projected on the
  candidate triangle containing it, separation along the face normal; the points are reduced to four
  (deepest, farthest, largest triangle, largest quad) by the narrow phase's reduction (Gregorius 2015).
Feature keys: triangle index * 64 + point index.

References
- Ericson, C. (2005). Real-Time Collision Detection. Morgan Kaufmann (5.1.5 closest point on a triangle).
- Gregorius, D. (2015). Robust contact creation for physics simulations. GDC (manifold reduction).
- Moller, T. and Trumbore, B. (1997). Fast, minimum storage ray-triangle intersection. JGT 2(1).

Limitations
- Vertex-face only for polytopes and cylinders: a box edge lying across a sharp terrain ridge, or a mesh
  vertex poking into a box face, is not detected (fine for terrain and ramps; not for spiky meshes).
- One manifold (one normal) per shape pair: a sphere in a crease gets one point per face with the
  blended normal m and separations along m (exact at rest in a symmetric crease); in an asymmetric crease
  the single normal is the weighted bisector, not the two true normals, so the sphere is held partly by
  friction. Capsules and polytopes in creases still take the deepest face's normal.
- A capsule's segment crossing a ridge between its end spheres gets no middle point.
- Meshes are one-sided surfaces seen from the side their face normals point to; no internal-edge
  (ghost collision) smoothing, so a box sliding over a tessellated flat floor may catch on seams rarely.

Memory: a pair works in its run's row of the narrow phase's mesh bank (``narrowphase.MeshScratch``: the
candidate list, the BVH stack, A's vertices, the candidate points, the crease contacts), made once per
world, so a warm step allocates nothing. A pair with more candidate triangles than the bank holds uses a
temporary list that step (same results) and the world doubles the bank after it (``fit_narrow_work``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import shapes as S
from ._tup import add, cross, dot, madd, norm, qconj, qmul, qrot, qrot_inv, scale, sub
from .bvh import STACK_SIZE, build_bvh, bvh_query_box_stack
from .narrowphase import CREASE_MAX, MESH_CANDIDATES, _reduce_and_emit, _set_normal

__all__ = ["mesh_soup", "heightfield_vertices", "triangle_local", "triangle_candidates", "collide_triangles",
           "ray_triangles"]

CREASE_BAND = 0.05      # of the radius: faces this much farther than the deepest stop steering the normal


# ------------------------------------------------------------------------------------------ build (once)
def mesh_soup(vertices, triangles):
    """Validate a mesh and return (triangle list (3T, 3) in BVH order, (bvh bounds, bvh nodes))."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3 or not np.all(np.isfinite(v)):
        raise ValueError(f"vertices must be a finite (V >= 3, 3) array; got shape {v.shape}")
    if t.ndim != 2 or t.shape[1] != 3 or len(t) < 1 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"triangles must be an integer (T >= 1, 3) array; got shape {t.shape}, dtype {t.dtype}")
    if t.min() < 0 or t.max() >= len(v):
        raise ValueError(f"triangles must index vertices in [0, {len(v) - 1}]; got range [{t.min()}, {t.max()}]")
    tv = v[t]
    area2 = np.linalg.norm(np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0]), axis=1)
    if np.any(area2 <= 1e-14 * max(1.0, float(np.abs(v).max()) ** 2)):
        raise ValueError(f"triangles {np.flatnonzero(area2 <= 0)[:10].tolist()} are degenerate (zero area)")
    order, bounds, nodes = build_bvh(tv)
    return tv[order].reshape(-1, 3), (bounds, nodes)


def heightfield_vertices(heights, spacing):
    """Grid points (nx * ny, 3) of a heightfield and its params (nx, ny, dx, dy)."""
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2 or not np.all(np.isfinite(h)):
        raise ValueError(f"heights must be a finite (nx >= 2, ny >= 2) array; got shape {h.shape}")
    sp = np.asarray(spacing, dtype=np.float64).reshape(-1)
    if sp.shape != (2,) or not np.all(sp > 0) or not np.all(np.isfinite(sp)):
        raise ValueError(f"spacing must be two positive numbers (dx, dy) in m; got {spacing!r}")
    nx, ny = h.shape
    x = (np.arange(nx) - 0.5 * (nx - 1)) * sp[0]
    y = (np.arange(ny) - 0.5 * (ny - 1)) * sp[1]
    X, Y = np.meshgrid(x, y, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), h.ravel()], axis=1), (float(nx), float(ny), sp[0], sp[1])


# ------------------------------------------------------------------------------------------ triangles
@njit(cache=True)
def _vtx(verts, r):
    return (verts[r, 0], verts[r, 1], verts[r, 2])


@njit(cache=True)
def triangle_local(shapes, s, k):
    """Vertices (3 tuples, the shape's local frame) of triangle ``k`` of mesh or heightfield row ``s``."""
    v0 = shapes.shape_vert_start[s]
    V = shapes.geom_vertices
    if shapes.shape_type[s] == S.TRIANGLE_MESH:
        return _vtx(V, v0 + 3 * k), _vtx(V, v0 + 3 * k + 1), _vtx(V, v0 + 3 * k + 2)
    ny = int(shapes.shape_params[s, 1])
    cell = k // 2
    i = cell // (ny - 1)
    j = cell - i * (ny - 1)
    r00 = v0 + i * ny + j
    r10 = r00 + ny
    if k % 2 == 0:
        return _vtx(V, r00), _vtx(V, r10), _vtx(V, r10 + 1)
    return _vtx(V, r00), _vtx(V, r10 + 1), _vtx(V, r00 + 1)


@njit(cache=True)
def triangle_candidates(shapes, s, lo, hi, out, stack):
    """Triangles of mesh/heightfield row ``s`` that may touch the local box [lo, hi] (three floats each);
    returns the count (entries past ``len(out)`` are not written: grow and repeat). ``stack``: a BVH
    traversal stack (``bvh.STACK_SIZE`` int32)."""
    if shapes.shape_type[s] == S.TRIANGLE_MESH:
        return bvh_query_box_stack(shapes.geom_bvh_bounds, shapes.geom_bvh_nodes, shapes.shape_bvh_start[s], lo,
                                   hi, out, stack)
    p = shapes.shape_params[s]
    nx, ny, dx, dy = int(p[0]), int(p[1]), p[2], p[3]
    x0 = -0.5 * (nx - 1) * dx
    y0 = -0.5 * (ny - 1) * dy
    i0 = max(0, int(math.floor((lo[0] - x0) / dx)))
    i1 = min(nx - 2, int(math.floor((hi[0] - x0) / dx)))
    j0 = max(0, int(math.floor((lo[1] - y0) / dy)))
    j1 = min(ny - 2, int(math.floor((hi[1] - y0) / dy)))
    V = shapes.geom_vertices
    v0 = shapes.shape_vert_start[s]
    n = 0
    cap = out.shape[0]
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            r = v0 + i * ny + j
            zmin = min(min(V[r, 2], V[r + 1, 2]), min(V[r + ny, 2], V[r + ny + 1, 2]))
            zmax = max(max(V[r, 2], V[r + 1, 2]), max(V[r + ny, 2], V[r + ny + 1, 2]))
            if zmin > hi[2] or zmax < lo[2]:
                continue
            for half in range(2):
                if n < cap:
                    out[n] = 2 * (i * (ny - 1) + j) + half
                n += 1
    return n


@njit(cache=True)
def _gather(shapes, s, lo, hi, cand, stack, need):
    """(candidate list, count): the triangles under [lo, hi] in ``cand``; when they overflow it, in a
    temporary list of the full count (this call only: the count goes to ``need[0]`` and the world grows
    the bank it keeps, ``narrowphase.fit_narrow_work``)."""
    n = triangle_candidates(shapes, s, lo, hi, cand, stack)
    if n > cand.shape[0]:
        need[0] = max(need[0], n)
        cand = np.empty(n, np.int64)
        n = triangle_candidates(shapes, s, lo, hi, cand, stack)
    return cand, n


@njit(cache=True)
def _closest_point_triangle(p, a, b, c):
    """Point of triangle abc closest to p (Ericson 2005, 5.1.5)."""
    ab = sub(b, a)
    ac = sub(c, a)
    ap = sub(p, a)
    d1 = dot(ab, ap)
    d2 = dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a
    bp = sub(p, b)
    d3 = dot(ab, bp)
    d4 = dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return madd(a, ab, d1 / (d1 - d3))
    cp = sub(p, c)
    d5 = dot(ab, cp)
    d6 = dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return madd(a, ac, d2 / (d2 - d6))
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return madd(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)))
    denom = 1.0 / (va + vb + vc)
    return add(a, add(scale(ab, vb * denom), scale(ac, vc * denom)))


@njit(cache=True)
def _face_normal(a, b, c):
    n = cross(sub(b, a), sub(c, a))
    return scale(n, 1.0 / norm(n))


@njit(cache=True)
def _sphere_triangles(c, r, shapes, s, cand, n):
    """Nearest candidate triangle to a sphere: (separation, outward normal at the contact, triangle)."""
    best_sep = np.inf
    best_n = (0.0, 0.0, 1.0)
    best_k = -1
    for t in range(n):
        k = cand[t]
        a, b, cc = triangle_local(shapes, s, k)
        q = _closest_point_triangle(c, a, b, cc)
        d = sub(c, q)
        dist = norm(d)
        fn = _face_normal(a, b, cc)
        if dot(d, fn) < 0.0:
            sep = -dist - r          # centre behind the face
            nrm = fn
        else:
            sep = dist - r
            nrm = scale(d, 1.0 / dist) if dist > 1e-12 else fn
        if sep < best_sep:
            best_sep, best_n, best_k = sep, nrm, k
    return best_sep, best_n, best_k


@njit(cache=True)
def _sphere_triangle_contacts(c, r, shapes, s, cand, n, spec, out_sep, out_n, out_k, out_q, out_face):
    """Distinct contacts of a sphere with the candidate triangles within ``spec``: one per contact normal
    (Voronoi-region test on triangle features, Ericson 2005, 5.1.5: triangles whose closest points share an
    edge or vertex give the same normal from the centre and count once; only faces of a concave crease give
    different normals). Keeps the ``CREASE_MAX`` smallest separations; returns the count."""
    m = 0
    for t in range(n):
        k = cand[t]
        a, b, cc = triangle_local(shapes, s, k)
        q = _closest_point_triangle(c, a, b, cc)
        d = sub(c, q)
        dist = norm(d)
        fn = _face_normal(a, b, cc)
        if dot(d, fn) < 0.0:
            sep = -dist - r
            nrm = fn
        else:
            sep = dist - r
            nrm = scale(d, 1.0 / dist) if dist > 1e-12 else fn
        if sep > spec:
            continue
        dup = -1
        for j in range(m):
            if dot(nrm, (out_n[j, 0], out_n[j, 1], out_n[j, 2])) > 1.0 - 1e-9:
                dup = j
                break
        if dup < 0 and m < CREASE_MAX:
            dup = m
            m += 1
            out_sep[dup] = np.inf
        elif dup < 0:
            worst = 0
            for j in range(1, m):
                if out_sep[j] > out_sep[worst]:
                    worst = j
            if sep >= out_sep[worst]:
                continue
            dup = worst
            out_sep[dup] = np.inf
        if sep < out_sep[dup] or (sep == out_sep[dup] and k < out_k[dup]):
            out_sep[dup] = sep
            out_n[dup, 0], out_n[dup, 1], out_n[dup, 2] = nrm
            out_k[dup] = k
            out_q[dup, 0], out_q[dup, 1], out_q[dup, 2] = q
            out_face[dup] = dot(nrm, fn) > 1.0 - 1e-9
    # Voronoi test: an edge/vertex contact whose closest point lies on or above the plane of a face contact
    # is that face's contact seen from a neighbour (coplanar floor, the near edge of a crease): drop it
    keep = 0
    for j in range(m):
        drop = False
        if not out_face[j]:
            qj = (out_q[j, 0], out_q[j, 1], out_q[j, 2])
            for f in range(m):
                if f != j and out_face[f]:
                    if dot(sub(qj, (out_q[f, 0], out_q[f, 1], out_q[f, 2])),
                           (out_n[f, 0], out_n[f, 1], out_n[f, 2])) >= -1e-9 * (1.0 + r):
                        drop = True
                        break
        if not drop:
            out_sep[keep] = out_sep[j]
            out_k[keep] = out_k[j]
            out_face[keep] = out_face[j]
            for a in range(3):
                out_n[keep, a] = out_n[j, a]
                out_q[keep, a] = out_q[j, a]
            keep += 1
    return keep


@njit(cache=True)
def _vertex_triangles(v, shapes, s, cand, n):
    """Separation of a point along the face normal of the candidate triangle whose prism contains it
    (the smallest |separation| if several do): (separation, face normal, triangle), inf if none."""
    best_sep = np.inf
    best_n = (0.0, 0.0, 1.0)
    best_k = -1
    for t in range(n):
        k = cand[t]
        a, b, c = triangle_local(shapes, s, k)
        fn = _face_normal(a, b, c)
        # inside the prism over the triangle: the point is on the inner side of the three edge planes
        if (dot(cross(sub(b, a), sub(v, a)), fn) < -1e-12 or dot(cross(sub(c, b), sub(v, b)), fn) < -1e-12
                or dot(cross(sub(a, c), sub(v, c)), fn) < -1e-12):
            continue
        sep = dot(sub(v, a), fn)
        if abs(sep) < abs(best_sep):
            best_sep, best_n, best_k = sep, fn, k
    return best_sep, best_n, best_k


@njit(cache=True)
def collide_triangles(ca, i, ta, sa, sb, shapes, pose, spec, scr):
    """Manifold ``i`` for convex shape ``sa`` against mesh/heightfield ``sb``; returns the point count.
    ``scr``: a `narrowphase.MeshScratch` row (the run's views of the mesh bank)."""
    pb = (pose[sb, 0], pose[sb, 1], pose[sb, 2])
    qb = (pose[sb, 3], pose[sb, 4], pose[sb, 5], pose[sb, 6])
    pa = qrot_inv(qb, (pose[sa, 0] - pb[0], pose[sa, 1] - pb[1], pose[sa, 2] - pb[2]))
    qa = qmul(qconj(qb), (pose[sa, 3], pose[sa, 4], pose[sa, 5], pose[sa, 6]))
    A = shapes.shape_params[sa]
    if ta == S.SPHERE or ta == S.CAPSULE:
        r = A[0]
        h = A[1] if ta == S.CAPSULE else 0.0
        e0 = madd(pa, qrot(qa, (0.0, 0.0, 1.0)), -h)
        e1 = madd(pa, qrot(qa, (0.0, 0.0, 1.0)), h)
        lo = (min(e0[0], e1[0]) - r - spec, min(e0[1], e1[1]) - r - spec, min(e0[2], e1[2]) - r - spec)
        hi = (max(e0[0], e1[0]) + r + spec, max(e0[1], e1[1]) + r + spec, max(e0[2], e1[2]) + r + spec)
        cand, n = _gather(shapes, sb, lo, hi, scr.cand, scr.stack, scr.need)
        if ta == S.SPHERE:
            return _sphere_crease(ca, i, e0, r, shapes, sb, cand, n, spec, pb, qb, scr)
        s0, n0, k0 = _sphere_triangles(e0, r, shapes, sb, cand, n)
        cnt = 0
        s1, n1, k1 = _sphere_triangles(e1, r, shapes, sb, cand, n)
        nrm = n0 if s0 <= s1 else n1
        if min(s0, s1) > spec:
            return 0
        _set_normal(ca, i, qrot(qb, scale(nrm, -1.0)))
        if s0 <= spec:
            _write(ca, i, cnt, add(pb, qrot(qb, madd(e0, n0, -(r + 0.5 * s0)))), s0, k0 * 64)
            cnt += 1
        if s1 <= spec:
            _write(ca, i, cnt, add(pb, qrot(qb, madd(e1, n1, -(r + 0.5 * s1)))), s1, k1 * 64 + 1)
            cnt += 1
        return cnt
    # polytopes and cylinders: vertex-face contacts
    if ta == S.BOX:
        nv = 8
    elif ta == S.CYLINDER:
        nv = 16
    elif ta == S.CONVEX_HULL:
        nv = shapes.shape_vert_count[sa]
    else:
        return 0
    if nv <= scr.verts.shape[0]:
        local, pts, seps, feats = scr.verts, scr.pts, scr.seps, scr.feats
    else:                   # a bank made for smaller hulls (a caller's own NarrowWork): this pair's rows
        local, pts, seps, feats = np.empty((nv, 3)), np.empty((nv, 3)), np.empty(nv), np.empty(nv, np.int64)
    x0, y0, z0 = np.inf, np.inf, np.inf
    x1, y1, z1 = -np.inf, -np.inf, -np.inf
    for v in range(nv):
        if ta == S.BOX:
            lv = (A[0] if v & 1 else -A[0], A[1] if v & 2 else -A[1], A[2] if v & 4 else -A[2])
        elif ta == S.CYLINDER:
            ang = 2.0 * math.pi * (v % 8) / 8.0
            lv = (A[0] * math.cos(ang), A[0] * math.sin(ang), A[1] if v >= 8 else -A[1])
        else:
            lv = _vtx(shapes.geom_vertices, shapes.shape_vert_start[sa] + v)
        w = add(pa, qrot(qa, lv))
        local[v, 0], local[v, 1], local[v, 2] = w
        x0, y0, z0 = min(x0, w[0]), min(y0, w[1]), min(z0, w[2])
        x1, y1, z1 = max(x1, w[0]), max(y1, w[1]), max(z1, w[2])
    cand, n = _gather(shapes, sb, (x0 - spec, y0 - spec, z0 - spec), (x1 + spec, y1 + spec, z1 + spec), scr.cand,
                      scr.stack, scr.need)
    cnt = np.int64(0)  # int64 from the start (narrowphase: a literal 0 compiles callees twice)
    deepest = np.inf
    normal = (0.0, 0.0, -1.0)
    for v in range(nv):
        w = (local[v, 0], local[v, 1], local[v, 2])
        sep, fn, k = _vertex_triangles(w, shapes, sb, cand, n)
        if sep > spec:
            continue
        p = add(pb, qrot(qb, madd(w, fn, -0.5 * sep)))
        pts[cnt, 0], pts[cnt, 1], pts[cnt, 2] = p
        seps[cnt] = sep
        feats[cnt] = k * 64 + v
        cnt += 1
        if sep < deepest:
            deepest = sep
            normal = qrot(qb, scale(fn, -1.0))
    if cnt == 0:
        return 0
    _set_normal(ca, i, normal)
    return _reduce_and_emit(ca, i, pts, seps, feats, cnt, normal)


@njit(cache=True)
def _sphere_crease(ca, i, c, r, shapes, sb, cand, n, spec, pb, qb, scr):
    """Sphere manifold against a mesh (mesh frame centre ``c``): one point per distinct contact normal.
    With several (a crease), the manifold normal is the weighted mean m of the normals, weights falling
    linearly from 1 for the deepest to 0 at CREASE_BAND * r above it (continuous, so no flip-flop), and each
    point's separation is measured along m: sep_k / (n_k . m), the gap the sphere closes moving along m
    before touching face k. In a symmetric crease m is the bisector and the sphere rests on both faces.
    The contacts live in ``scr``'s crease rows (a `narrowphase.MeshScratch` row)."""
    seps, nrms, tris, foot, face = scr.crease_sep, scr.crease_n, scr.crease_tri, scr.crease_foot, scr.crease_face
    m = _sphere_triangle_contacts(c, r, shapes, sb, cand, n, spec, seps, nrms, tris, foot, face)
    if m == 0:
        return 0
    lowest = seps[0]
    for j in range(1, m):
        lowest = min(lowest, seps[j])
    band = CREASE_BAND * r
    mx, my, mz = 0.0, 0.0, 0.0
    for j in range(m):
        w = max(0.0, 1.0 - (seps[j] - lowest) / band)
        mx += w * nrms[j, 0]
        my += w * nrms[j, 1]
        mz += w * nrms[j, 2]
    mn = (mx, my, mz)
    ln = norm(mn)
    if ln < 1e-9:
        mn = (nrms[0, 0], nrms[0, 1], nrms[0, 2])
    else:
        mn = scale(mn, 1.0 / ln)
    _set_normal(ca, i, qrot(qb, scale(mn, -1.0)))
    cnt = 0
    for j in range(m):
        nk = (nrms[j, 0], nrms[j, 1], nrms[j, 2])
        cosk = dot(nk, mn)
        if cosk <= 0.05:
            continue
        sep = seps[j] / cosk
        if sep > spec:
            continue
        p = add(pb, qrot(qb, madd(c, nk, -(r + 0.5 * seps[j]))))
        _write(ca, i, cnt, p, sep, tris[j] * 64)
        cnt += 1
    return cnt


@njit(cache=True)
def _write(ca, i, k, p, sep, feature):
    ca.contact_point[i, k, 0] = p[0]
    ca.contact_point[i, k, 1] = p[1]
    ca.contact_point[i, k, 2] = p[2]
    ca.contact_separation[i, k] = sep
    ca.contact_feature[i, k] = feature


# ------------------------------------------------------------------------------------------ rays
@njit(cache=True)
def ray_triangles(shapes, s, pose, origin, translation):
    """First hit of the segment origin + t translation, t in [0, 1], on mesh/heightfield row ``s`` (two-sided,
    Moller-Trumbore 1997): (t, unit world normal facing the ray), t = inf for a miss."""
    pb = (pose[0], pose[1], pose[2])
    qb = (pose[3], pose[4], pose[5], pose[6])
    o = qrot_inv(qb, (origin[0] - pb[0], origin[1] - pb[1], origin[2] - pb[2]))
    d = qrot_inv(qb, (translation[0], translation[1], translation[2]))
    lo = (min(o[0], o[0] + d[0]), min(o[1], o[1] + d[1]), min(o[2], o[2] + d[2]))
    hi = (max(o[0], o[0] + d[0]), max(o[1], o[1] + d[1]), max(o[2], o[2] + d[2]))
    # a query, not a step: its own candidate list and stack
    cand, n = _gather(shapes, s, lo, hi, np.empty(MESH_CANDIDATES, np.int64), np.empty(STACK_SIZE, np.int32),
                      np.zeros(1, np.int64))
    best = np.inf
    best_n = (0.0, 0.0, 0.0)
    for t in range(n):
        a, b, c = triangle_local(shapes, s, cand[t])
        e1 = sub(b, a)
        e2 = sub(c, a)
        pv = cross(d, e2)
        det = dot(e1, pv)
        if abs(det) < 1e-300:
            continue
        inv = 1.0 / det
        tv = sub(o, a)
        u = dot(tv, pv) * inv
        if u < 0.0 or u > 1.0:
            continue
        qv = cross(tv, e1)
        v = dot(d, qv) * inv
        if v < 0.0 or u + v > 1.0:
            continue
        th = dot(e2, qv) * inv
        if 0.0 <= th <= 1.0 and th < best:
            best = th
            fn = _face_normal(a, b, c)
            best_n = fn if dot(fn, d) < 0.0 else scale(fn, -1.0)
    return best, qrot(qb, best_n)
