"""Rigid bodies as triangle meshes: per-shape surface meshes and OBJ mesh sequences (one file per frame).

The shape table (``inertia.geometry.shapes`` codes; the arrays of ``inertia.model.Model`` or the
``States.model`` dict of a state file) is turned once into local surface meshes (`shape_meshes`);
each frame places them with the body poses ``body_q (B, 7)`` (centre-of-mass position + unit quaternion
w, x, y, z) composed with ``shape_local_pose (S, 7)`` (shapes of body -1 are already in world space).

Tessellation: spheres as UV spheres (``segments`` around, segments/2 rings), capsules as two
hemispheres and a tube, cylinders as capped prisms, boxes as 12 triangles, hulls as the convex hull of
their points (scipy), triangle meshes as stored (the BVH-ordered triangle list), heightfields as the
grid, planes as a square of side ``plane_size`` about the plane origin.

OBJ (Wavefront): ``v x y z`` lines then ``f i j k`` (1-based) per triangle, one ``o`` object per shape
(named ``body NAME`` / ``static S``). Files written atomically.

Limitations: no normals or UVs are written; curved shapes are faceted (``segments`` = 24 default).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..geometry import shapes as S
from ..math import compose_poses, rotate_vectors
from .atomic import atomic_write

__all__ = ["model_arrays", "shape_meshes", "posed_vertices", "write_obj", "write_obj_sequence"]

_KEYS = ("shape_type", "shape_body", "shape_local_pose", "shape_params", "shape_vert_start", "shape_vert_count",
         "geom_vertices")


def model_arrays(model) -> dict:
    """The shape-table arrays of a `Model` (or a ``States.model`` dict) as a plain dict."""
    if isinstance(model, dict):
        return {k: np.asarray(model[k]) for k in _KEYS if k in model} | (
            {"body_name": list(model["body_name"])} if "body_name" in model else {})
    out = {k: np.asarray(getattr(model, k)) for k in _KEYS}
    out["body_name"] = list(getattr(model, "body_name", []))
    return out


def _uv_sphere(radius, segments, z_shift=(0.0, 0.0)):
    """A UV sphere; with z_shift (top, bottom) the upper/lower hemispheres move apart (a capsule)."""
    rings = max(2, segments // 2)
    verts = [(0.0, 0.0, radius + z_shift[0])]
    for i in range(1, rings):
        th = np.pi * i / rings
        z = radius * np.cos(th) + (z_shift[0] if i <= rings // 2 else z_shift[1])
        for j in range(segments):
            ph = 2 * np.pi * j / segments
            verts.append((radius * np.sin(th) * np.cos(ph), radius * np.sin(th) * np.sin(ph), z))
    verts.append((0.0, 0.0, -radius + z_shift[1]))
    faces = []
    ring = lambda i, j: 1 + (i - 1) * segments + (j % segments)  # noqa: E731
    for j in range(segments):
        faces.append((0, ring(1, j), ring(1, j + 1)))
    for i in range(1, rings - 1):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            faces += [(a, c, b), (b, c, d)]
    last = len(verts) - 1
    for j in range(segments):
        faces.append((last, ring(rings - 1, j + 1), ring(rings - 1, j)))
    return np.array(verts, float), np.array(faces, np.int64)


def _cylinder(radius, half, segments):
    ph = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([radius * np.cos(ph), radius * np.sin(ph)], axis=1)
    verts = np.concatenate([np.c_[ring, np.full(segments, half)], np.c_[ring, np.full(segments, -half)],
                            [[0, 0, half], [0, 0, -half]]])
    faces = []
    for j in range(segments):
        k = (j + 1) % segments
        faces += [(j, segments + j, k), (k, segments + j, segments + k),
                  (2 * segments, j, k), (2 * segments + 1, segments + k, segments + j)]
    return verts, np.array(faces, np.int64)


def _box(h):
    verts = np.array([[sx * h[0], sy * h[1], sz * h[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return verts, np.array(faces, np.int64)


def shape_meshes(model, *, segments: int = 24, plane_size: float = 20.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """Local surface mesh (vertices (n, 3) m, triangles (t, 3) int64) of every shape, in shape order."""
    m = model_arrays(model)
    out = []
    for si, t in enumerate(m["shape_type"]):
        p = m["shape_params"][si]
        start, count = int(m["shape_vert_start"][si]), int(m["shape_vert_count"][si])
        pts = m["geom_vertices"][start:start + count]
        if t == S.SPHERE:
            out.append(_uv_sphere(p[0], segments))
        elif t == S.BOX:
            out.append(_box(p[:3]))
        elif t == S.CAPSULE:
            out.append(_uv_sphere(p[0], segments, (p[1], -p[1])))
        elif t == S.CYLINDER:
            out.append(_cylinder(p[0], p[1], segments))
        elif t == S.CONVEX_HULL:
            from scipy.spatial import ConvexHull

            hull = ConvexHull(pts)
            faces = hull.simplices.copy()
            c = pts.mean(axis=0)           # orient every face outwards
            n = np.cross(pts[faces[:, 1]] - pts[faces[:, 0]], pts[faces[:, 2]] - pts[faces[:, 0]])
            flip = np.einsum("ij,ij->i", n, pts[faces[:, 0]] - c) < 0
            faces[flip] = faces[flip][:, ::-1]
            out.append((pts.copy(), faces.astype(np.int64)))
        elif t == S.TRIANGLE_MESH:
            out.append((pts.copy(), np.arange(count, dtype=np.int64).reshape(-1, 3)))
        elif t == S.HEIGHTFIELD:
            nx, ny = int(p[0]), int(p[1])
            idx = np.arange(nx * ny).reshape(nx, ny)
            a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
            out.append((pts.copy(), np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]).astype(np.int64)))
        elif t == S.PLANE:
            h = 0.5 * plane_size
            out.append((np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], float),
                        np.array([[0, 1, 2], [0, 2, 3]], np.int64)))
        else:
            out.append((np.zeros((0, 3)), np.zeros((0, 3), np.int64)))
    return out


def shape_world_pose(model, body_q, si: int) -> np.ndarray:
    """World pose (7,) of shape ``si`` given body poses ``body_q (B, 7)``."""
    m = model if isinstance(model, dict) and "shape_body" in model else model_arrays(model)
    local = np.asarray(m["shape_local_pose"][si], float)
    b = int(m["shape_body"][si])
    return local.copy() if b < 0 else compose_poses(np.asarray(body_q[b], float), local)


def posed_vertices(model, body_q, meshes=None) -> list[np.ndarray]:
    """World vertices of every shape's mesh at the body poses ``body_q (B, 7)``."""
    m = model_arrays(model)
    meshes = shape_meshes(m) if meshes is None else meshes
    out = []
    for si, (v, _) in enumerate(meshes):
        pose = shape_world_pose(m, body_q, si)
        out.append(pose[:3] + rotate_vectors(pose[3:], v))
    return out


def write_obj(path, model, body_q, *, meshes=None, include_static: bool = True) -> Path:
    """One OBJ file of every shape at the poses ``body_q (B, 7)``."""
    m = model_arrays(model)
    meshes = shape_meshes(m) if meshes is None else meshes
    names = m.get("body_name", [])
    lines = ["# inertia rigid bodies"]
    base = 1
    for si, v in enumerate(posed_vertices(m, body_q, meshes)):
        b = int(m["shape_body"][si])
        if b < 0 and not include_static:
            continue
        label = f"body_{names[b] if b < len(names) else b}_shape{si}" if b >= 0 else f"static_shape{si}"
        lines.append(f"o {label.replace(' ', '_')}")
        lines.extend(f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v)
        lines.extend(f"f {a + base} {b_ + base} {c + base}" for a, b_, c in meshes[si][1])
        base += len(v)
    with atomic_write(path, mode="w") as fh:
        fh.write("\n".join(lines) + "\n")
    return Path(path)


def write_obj_sequence(directory, model, body_q_frames, *, include_static: bool = True) -> Path:
    """``frame_00000.obj`` ... one per frame of ``body_q_frames (F, B, 7)``."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    m = model_arrays(model)
    meshes = shape_meshes(m)
    for f, q in enumerate(np.asarray(body_q_frames)):
        write_obj(d / f"frame_{f:05d}.obj", m, q, meshes=meshes, include_static=include_static)
    return d
