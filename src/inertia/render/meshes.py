"""Shaded triangle meshes with shadows, and anti-aliased lines, for the offline renderer.

What is drawn here (the renderer calls these after the background and before the particles, so
particles z-test against the meshes and lines):

- **Triangle meshes** (`TriangleMesh`: world vertices, per-vertex normals, triangles, colours):
  rigid bodies (the shape table of a state file's ``model``, tessellated once by
  `tessellate_shape` and moved per frame by ``fields["body_q"]``), cloth surfaces
  (``model["surface_triangles"]`` over the particle positions, smooth normals per frame).
- **Lines** (`LineSet`): springs (``model["spring_pairs"]``), drawn with analytic coverage.
- **Shadows** from one directional light onto the ground, the colliders and the meshes
  themselves, through a shadow map.

Stages per frame (kernels below, serial: the meshes of the bundled scenes are small, and a
serial kernel compiles once and quickly):

1. ``shadow_map_depth`` -- every triangle rasterised in the light's orthographic view
   (axes U, V perpendicular to the direction L towards the light, texel size ``texel``); each
   texel keeps the largest ``p . L`` (the surface nearest the light).
2. ``draw_triangles`` -- screen rasterisation with a z-buffer (perspective-correct
   interpolation of depth and normal), two-sided Lambert + hemisphere ambient:
   ``c = albedo (ambient(n) + k_d max(0, n . L) visibility)``,
   ``ambient(n) = ground + (sky - ground) (1 + n . up) / 2``; visibility by 3 x 3 percentage
   closer filtering of the shadow map. Covered pixels are marked in ``mask``.
3. ``shadow_background`` -- the pixels the background drew (ground, colliders) and no mesh
   covers: world point from the depth buffer, the same shadow-map test, the direct share of
   the light taken away (``c *= 1 - strength (1 - visibility)``).
4. ``draw_lines`` -- per segment, pixels within half the width of the projected segment get
   coverage ``clamp(w/2 + 1/2 - d, 0, 1)`` (d the pixel centre's distance to the segment),
   depth interpolated along it, z-tested and blended.

References
----------
Williams, L. (1978). "Casting curved shadows on curved surfaces", SIGGRAPH (shadow maps).
Reeves, W., Salesin, D., Cook, R. (1987). "Rendering antialiased shadows with depth maps",
SIGGRAPH (percentage closer filtering).
Pineda, J. (1988). "A parallel algorithm for polygon rasterization", SIGGRAPH (edge functions).
Heckbert, P., Moreton, H. (1991). "Interpolation for polygon texture mapping and shading"
(perspective-correct interpolation by 1/z).

Limitations: triangles with a vertex behind the camera's near distance are skipped (the
bundled cameras are outside the scene); no anti-aliasing of triangle edges (lines and
particles are anti-aliased); one directional light; shadows of particles on meshes are not
drawn (particles have their own contact shadows on the ground); the shadow map has a fixed
1024 x 1024 texels over the casters' extent, so shadows of a very wide scene are blurrier.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .kernels import CAM_F, CAM_CX, CAM_CY, CAM_ORTHO, FAR

__all__ = ["TriangleMesh", "LineSet", "tessellate_shape", "vertex_normals", "shadow_map_depth",
           "draw_triangles", "shadow_background", "draw_lines", "light_frame", "SHADOW_MAP_SIZE"]

#: Texels per side of the shadow map.
SHADOW_MAP_SIZE = 1024
# Mesh light vector layout (float64): direction towards the light (world, unit) 0:3, world up
# 3:6, sky ambient 6:9, ground ambient 9:12, diffuse 12, shadow strength on the background 13.
LIGHT_SIZE = 14
# Shadow frame layout (float64): origin 0:3, axis U 3:6, axis V 6:9, direction L 9:12,
# texel size 12, depth bias 13.
SHADOW_FRAME_SIZE = 14


class TriangleMesh(NamedTuple):
    """A triangle mesh in world space: ``vertices (V, 3)`` m, ``normals (V, 3)`` unit (or None to
    compute smooth normals), ``triangles (T, 3)`` int vertex indices, ``color`` sRGB in [0, 1]:
    (3,) for the whole mesh or (T, 3) per triangle."""

    vertices: np.ndarray
    normals: np.ndarray | None
    triangles: np.ndarray
    color: np.ndarray


class LineSet(NamedTuple):
    """Segments between ``points (V, 3)`` m given by ``pairs (P, 2)`` int, drawn ``width_px``
    pixels wide in sRGB ``color`` (3,) or (P, 3), with ``opacity`` (P,) in [0, 1] (None: 1)."""

    points: np.ndarray
    pairs: np.ndarray
    color: np.ndarray
    width_px: float = 1.5
    opacity: np.ndarray | None = None


# ---------------------------------------------------------------------------------------------
# Tessellation (once per shape, in the shape's own frame)
# ---------------------------------------------------------------------------------------------
def _uv_sphere(radius: float, half_length: float, n_lat: int = 12, n_lon: int = 24):
    """Sphere (half_length 0) or capsule (hemispheres at z = +-half_length): smooth normals."""
    verts, norms = [], []
    # Rings from the north pole to the south; the equator is doubled for a capsule's core.
    lats = list(np.linspace(0.5 * np.pi, 0.0, n_lat // 2 + 1)) + list(np.linspace(0.0, -0.5 * np.pi, n_lat // 2 + 1))
    offsets = [half_length] * (n_lat // 2 + 1) + [-half_length] * (n_lat // 2 + 1)
    lon = np.linspace(0.0, 2 * np.pi, n_lon, endpoint=False)
    for lat, off in zip(lats, offsets, strict=True):
        n = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.full(n_lon, np.sin(lat))], axis=1)
        norms.append(n)
        verts.append(radius * n + np.array([0.0, 0.0, off]))
    verts, norms = np.concatenate(verts), np.concatenate(norms)
    tris = []
    rings = len(lats)
    for r in range(rings - 1):
        for k in range(n_lon):
            a, b = r * n_lon + k, r * n_lon + (k + 1) % n_lon
            c, d = a + n_lon, b + n_lon
            tris += [(a, c, b), (b, c, d)]
    return verts, norms, np.array(tris, np.int64)


def _box(h):
    verts, norms, tris = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.zeros(3), np.zeros(3)
            u[(axis + 1) % 3], v[(axis + 2) % 3] = 1.0, 1.0
            if sign < 0:
                u, v = v, u  # counter-clockwise seen from outside
            base = len(verts)
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                verts.append(h * (n + su * u + sv * v))
                norms.append(n)
            tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(verts), np.array(norms), np.array(tris, np.int64)


def _cylinder(radius: float, half_height: float, n_lon: int = 32):
    lon = np.linspace(0.0, 2 * np.pi, n_lon, endpoint=False)
    ring = np.stack([np.cos(lon), np.sin(lon), np.zeros(n_lon)], axis=1)
    up = np.array([0.0, 0.0, 1.0])
    verts = [radius * ring + half_height * up, radius * ring - half_height * up,
             radius * ring + half_height * up, radius * ring - half_height * up,
             np.array([half_height * up, -half_height * up])]
    norms = [ring, ring, np.tile(up, (n_lon, 1)), np.tile(-up, (n_lon, 1)), np.array([up, -up])]
    tris = []
    centre = 4 * n_lon
    for k in range(n_lon):
        j = (k + 1) % n_lon
        tris += [(k, n_lon + k, j), (j, n_lon + k, n_lon + j)]
        tris += [(centre, 2 * n_lon + k, 2 * n_lon + j), (centre + 1, 3 * n_lon + j, 3 * n_lon + k)]
    return np.concatenate(verts), np.concatenate(norms), np.array(tris, np.int64)


def _flat(vertices, triangles):
    """Flat shading: each triangle gets its own three vertices with the face normal."""
    v = np.asarray(vertices, np.float64)[np.asarray(triangles, np.int64).reshape(-1)]
    tri = v.reshape(-1, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return v, np.repeat(n, 3, axis=0), np.arange(v.shape[0], dtype=np.int64).reshape(-1, 3)


def _hull_triangles(points):
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    tris = hull.simplices.astype(np.int64)
    # Outward winding: the face normal points away from the centroid.
    centre = points.mean(axis=0)
    a, b, c = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - centre) < 0
    tris[flip] = tris[flip][:, ::-1]
    return tris


def tessellate_shape(model: dict, s: int):
    """Local vertices (V, 3), normals (V, 3) and triangles (T, 3) of shape row ``s`` of a model
    dict (the contract's shape table), in the shape's own frame; None for planes (drawn as the
    renderer's analytic ground) and unknown types."""
    from ..geometry import shapes as S

    kind = int(model["shape_type"][s])
    p = np.asarray(model["shape_params"][s], np.float64)
    if kind == S.SPHERE:
        return _uv_sphere(p[0], 0.0)
    if kind == S.CAPSULE:
        return _uv_sphere(p[0], p[1])
    if kind == S.BOX:
        return _box(p[:3])
    if kind == S.CYLINDER:
        return _cylinder(p[0], p[1])
    if kind not in (S.CONVEX_HULL, S.TRIANGLE_MESH, S.HEIGHTFIELD):
        return None
    start, count = int(model["shape_vert_start"][s]), int(model["shape_vert_count"][s])
    verts = np.asarray(model["geom_vertices"][start:start + count], np.float64)
    tri_start = model.get("shape_tri_start")
    if tri_start is not None and "geom_triangles" in model and int(model["shape_tri_count"][s]) > 0:
        t0, tc = int(tri_start[s]), int(model["shape_tri_count"][s])
        return _flat(verts, np.asarray(model["geom_triangles"][t0:t0 + tc], np.int64))
    if kind == S.CONVEX_HULL:
        return _flat(verts, _hull_triangles(verts))
    if kind == S.TRIANGLE_MESH:  # a triangle soup, three vertices per triangle
        return _flat(verts, np.arange(verts.shape[0], dtype=np.int64).reshape(-1, 3))
    # Heightfield: grid points (nx * ny) in i-major order, two triangles per cell, smooth normals.
    nx, ny = int(p[0]), int(p[1])
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    tris = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)]).astype(np.int64)
    normals = np.zeros_like(verts)
    vertex_normals(verts, tris, normals)
    return verts, normals, tris


# ---------------------------------------------------------------------------------------------
# Kernels
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def vertex_normals(vertices, triangles, out):
    """Smooth unit normals (V, 3): the area-weighted sum of the adjacent faces' normals (serial,
    so the sum is in a fixed order)."""
    out[:] = 0.0
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ux, uy, uz = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
        vx, vy, vz = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        for k in (a, b, c):
            out[k, 0] += nx
            out[k, 1] += ny
            out[k, 2] += nz
    for k in range(out.shape[0]):
        n = math.sqrt(out[k, 0] ** 2 + out[k, 1] ** 2 + out[k, 2] ** 2)
        if n > 0.0:
            out[k, 0] /= n
            out[k, 1] /= n
            out[k, 2] /= n
        else:
            out[k, 2] = 1.0


def light_frame(direction, vertices, texel_count: int = SHADOW_MAP_SIZE) -> np.ndarray:
    """Shadow frame (``SHADOW_FRAME_SIZE``,) of a light towards ``direction`` (world, unit)
    covering ``vertices`` (the casters): origin at the lower corner of their light-space box."""
    L = np.asarray(direction, np.float64)
    L = L / np.linalg.norm(L)
    helper = np.array([1.0, 0.0, 0.0]) if abs(L[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    U = np.cross(helper, L)
    U /= np.linalg.norm(U)
    V = np.cross(L, U)
    pts = np.asarray(vertices, np.float64).reshape(-1, 3)
    u, v = pts @ U, pts @ V
    extent = max(float(u.max() - u.min()), float(v.max() - v.min()), 1e-6) * 1.02
    texel = extent / (texel_count - 4)
    origin = (u.min() - 2 * texel) * U + (v.min() - 2 * texel) * V
    frame = np.zeros(SHADOW_FRAME_SIZE)
    frame[0:3], frame[3:6], frame[6:9], frame[9:12] = origin, U, V, L
    frame[12] = texel
    frame[13] = 1.5 * texel  # depth bias (scaled up on grazing surfaces): a surface does not shadow itself
    return frame


@njit(cache=True)
def shadow_map_depth(vertices, triangles, frame, depth_map):
    """Rasterise every triangle in the light's view: ``depth_map (R, R)`` float32 keeps, per
    texel, the largest ``p . L`` (the nearest surface to the light); -inf where nothing is."""
    size_u, size_v = depth_map.shape[0], depth_map.shape[1]
    depth_map[:] = -np.inf
    inv = 1.0 / frame[12]
    for t in range(triangles.shape[0]):
        us = np.empty(3)
        vs = np.empty(3)
        ds = np.empty(3)
        for k in range(3):
            i = triangles[t, k]
            x, y, z = vertices[i, 0] - frame[0], vertices[i, 1] - frame[1], vertices[i, 2] - frame[2]
            us[k] = (x * frame[3] + y * frame[4] + z * frame[5]) * inv
            vs[k] = (x * frame[6] + y * frame[7] + z * frame[8]) * inv
            ds[k] = vertices[i, 0] * frame[9] + vertices[i, 1] * frame[10] + vertices[i, 2] * frame[11]
        area = (us[1] - us[0]) * (vs[2] - vs[0]) - (us[2] - us[0]) * (vs[1] - vs[0])
        if abs(area) < 1e-12:
            continue
        i0 = max(int(math.floor(min(us[0], us[1], us[2]))), 0)
        i1 = min(int(math.ceil(max(us[0], us[1], us[2]))), size_u - 1)
        j0 = max(int(math.floor(min(vs[0], vs[1], vs[2]))), 0)
        j1 = min(int(math.ceil(max(vs[0], vs[1], vs[2]))), size_v - 1)
        for i in range(i0, i1 + 1):
            pu = i + 0.5
            for j in range(j0, j1 + 1):
                pv = j + 0.5
                w0 = ((us[1] - pu) * (vs[2] - pv) - (us[2] - pu) * (vs[1] - pv)) / area
                w1 = ((us[2] - pu) * (vs[0] - pv) - (us[0] - pu) * (vs[2] - pv)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                d = w0 * ds[0] + w1 * ds[1] + w2 * ds[2]
                if d > depth_map[i, j]:
                    depth_map[i, j] = d


@njit(cache=True)
def _visibility(x, y, z, frame, depth_map, slope):
    """Fraction of the light reaching world point (x, y, z): 3 x 3 percentage closer filter.
    ``slope`` = tan of the angle between the surface normal and the light (0 for the
    background): the depth bias grows with it, as a texel spans more depth on a grazing surface."""
    if depth_map.shape[0] < 2:
        return 1.0
    inv = 1.0 / frame[12]
    rx, ry, rz = x - frame[0], y - frame[1], z - frame[2]
    u = (rx * frame[3] + ry * frame[4] + rz * frame[5]) * inv
    v = (rx * frame[6] + ry * frame[7] + rz * frame[8]) * inv
    d = x * frame[9] + y * frame[10] + z * frame[11] + frame[13] * (1.0 + min(slope, 8.0))
    iu, iv = int(math.floor(u)), int(math.floor(v))
    lit = 0.0
    for a in range(-1, 2):
        for b in range(-1, 2):
            i, j = iu + a, iv + b
            if i < 0 or j < 0 or i >= depth_map.shape[0] or j >= depth_map.shape[1] or depth_map[i, j] <= d:
                lit += 1.0
    return lit / 9.0


@njit(cache=True)
def _eye_ray(cam, px, py):
    """World ray of the pixel centre (px + 1/2, py + 1/2): origin and direction with unit
    forward component (so a point of depth z is origin + z * direction)."""
    f = cam[CAM_F]
    sx = (px + 0.5 - cam[CAM_CX]) / f
    sy = (cam[CAM_CY] - (py + 0.5)) / f
    if cam[CAM_ORTHO] > 0.5:
        return (cam[0] + sx * cam[3] + sy * cam[6], cam[1] + sx * cam[4] + sy * cam[7],
                cam[2] + sx * cam[5] + sy * cam[8], cam[9], cam[10], cam[11])
    return (cam[0], cam[1], cam[2], cam[9] + sx * cam[3] + sy * cam[6], cam[10] + sx * cam[4] + sy * cam[7],
            cam[11] + sx * cam[5] + sy * cam[8])


@njit(cache=True)
def _project(cam, x, y, z):
    """Pixel coordinates and depth (along the camera's forward axis) of a world point."""
    rx, ry, rz = x - cam[0], y - cam[1], z - cam[2]
    cx = rx * cam[3] + ry * cam[4] + rz * cam[5]
    cy = rx * cam[6] + ry * cam[7] + rz * cam[8]
    depth = rx * cam[9] + ry * cam[10] + rz * cam[11]
    f = cam[CAM_F]
    if cam[CAM_ORTHO] > 0.5:
        return cam[CAM_CX] + f * cx, cam[CAM_CY] - f * cy, depth
    if depth <= 0.0:
        return 0.0, 0.0, depth
    return cam[CAM_CX] + f * cx / depth, cam[CAM_CY] - f * cy / depth, depth


@njit(cache=True)
def draw_triangles(vertices, normals, triangles, tri_color, cam, light, frame, depth_map, near,
                   color_buf, depth_buf, mask):
    """Rasterise triangles into linear ``color_buf (H, W, 3)`` float32 / ``depth_buf (H, W)``
    float32 with a z-test; ``tri_color (T, 3)`` float32 linear albedo; ``light`` (LIGHT_SIZE,);
    the shadow map ``depth_map`` in ``frame`` (a (1, 1) map: no shadows). Written pixels get
    ``mask`` = 1. Triangles with a vertex nearer than ``near`` are skipped."""
    height, width = depth_buf.shape
    ortho = cam[CAM_ORTHO] > 0.5
    sx = np.empty(3)
    sy = np.empty(3)
    sz = np.empty(3)
    for t in range(triangles.shape[0]):
        skip = False
        for k in range(3):
            i = triangles[t, k]
            sx[k], sy[k], sz[k] = _project(cam, vertices[i, 0], vertices[i, 1], vertices[i, 2])
            if not ortho and sz[k] < near:
                skip = True
        if skip:
            continue
        area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0])
        if abs(area) < 1e-12:
            continue
        x0 = max(int(math.floor(min(sx[0], sx[1], sx[2]) - 0.5)), 0)
        x1 = min(int(math.ceil(max(sx[0], sx[1], sx[2]) - 0.5)), width - 1)
        y0 = max(int(math.floor(min(sy[0], sy[1], sy[2]) - 0.5)), 0)
        y1 = min(int(math.ceil(max(sy[0], sy[1], sy[2]) - 0.5)), height - 1)
        ia, ib, ic = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        for py in range(y0, y1 + 1):
            cy = py + 0.5
            for px in range(x0, x1 + 1):
                cx = px + 0.5
                # Screen-space barycentric weights (edge functions over the signed area).
                w0 = ((sx[1] - cx) * (sy[2] - cy) - (sx[2] - cx) * (sy[1] - cy)) / area
                w1 = ((sx[2] - cx) * (sy[0] - cy) - (sx[0] - cx) * (sy[2] - cy)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                # Perspective: 1/z is linear on screen; attribute weights b_k = (w_k / z_k) z.
                if ortho:
                    z = w0 * sz[0] + w1 * sz[1] + w2 * sz[2]
                    b0, b1, b2 = w0, w1, w2
                else:
                    inv_z = w0 / sz[0] + w1 / sz[1] + w2 / sz[2]
                    z = 1.0 / inv_z
                    b0, b1, b2 = w0 / sz[0] * z, w1 / sz[1] * z, w2 / sz[2] * z
                if z >= depth_buf[py, px]:
                    continue
                # World point and interpolated normal, turned towards the viewer (two-sided).
                wx = b0 * vertices[ia, 0] + b1 * vertices[ib, 0] + b2 * vertices[ic, 0]
                wy = b0 * vertices[ia, 1] + b1 * vertices[ib, 1] + b2 * vertices[ic, 1]
                wz = b0 * vertices[ia, 2] + b1 * vertices[ib, 2] + b2 * vertices[ic, 2]
                nx = b0 * normals[ia, 0] + b1 * normals[ib, 0] + b2 * normals[ic, 0]
                ny = b0 * normals[ia, 1] + b1 * normals[ib, 1] + b2 * normals[ic, 1]
                nz = b0 * normals[ia, 2] + b1 * normals[ib, 2] + b2 * normals[ic, 2]
                nn = math.sqrt(nx * nx + ny * ny + nz * nz)
                if nn > 0.0:
                    nx, ny, nz = nx / nn, ny / nn, nz / nn
                if ortho:
                    vx, vy, vz = cam[9], cam[10], cam[11]
                else:
                    vx, vy, vz = wx - cam[0], wy - cam[1], wz - cam[2]
                if nx * vx + ny * vy + nz * vz > 0.0:
                    nx, ny, nz = -nx, -ny, -nz
                lam = nx * light[0] + ny * light[1] + nz * light[2]
                vis = 0.0
                if lam > 0.0:
                    # Normal offset (one texel) plus a slope-scaled bias: no self-shadowing acne.
                    off = frame[12]
                    slope = math.sqrt(max(1.0 - lam * lam, 0.0)) / max(lam, 1e-3)
                    vis = _visibility(wx + off * nx, wy + off * ny, wz + off * nz, frame, depth_map, slope)
                else:
                    lam = 0.0
                hemi = 0.5 + 0.5 * (nx * light[3] + ny * light[4] + nz * light[5])
                direct = light[12] * lam * vis
                for c in range(3):
                    ambient = light[9 + c] + (light[6 + c] - light[9 + c]) * hemi
                    color_buf[py, px, c] = tri_color[t, c] * (ambient + direct)
                depth_buf[py, px] = z
                mask[py, px] = 1


@njit(cache=True)
def shadow_background(cam, frame, depth_map, strength, depth_buf, mask, color_buf):
    """Darken the background's pixels (depth < FAR, ``mask`` 0) that the shadow map hides from
    the light: ``c *= 1 - strength (1 - visibility)``."""
    height, width = depth_buf.shape
    for py in range(height):
        for px in range(width):
            z = depth_buf[py, px]
            if mask[py, px] != 0 or not z < FAR:
                continue
            ox, oy, oz, dx, dy, dz = _eye_ray(cam, px, py)
            vis = _visibility(ox + z * dx, oy + z * dy, oz + z * dz, frame, depth_map, 0.0)
            if vis < 1.0:
                keep = 1.0 - strength * (1.0 - vis)
                for c in range(3):
                    color_buf[py, px, c] *= keep


@njit(cache=True)
def draw_lines(points, pairs, color, opacity, width_px, cam, near, color_buf, depth_buf):
    """Anti-aliased segments ``pairs (P, 2)`` between ``points (V, 3)``, linear ``color (P, 3)``,
    ``opacity (P,)``: coverage clamp(w/2 + 1/2 - d, 0, 1) per pixel (d: distance of the pixel
    centre to the projected segment) times the opacity, depth interpolated along the segment
    (linearly on screen), z-tested against ``depth_buf`` and blended over ``color_buf``; depth
    written where the coverage is >= 1/2 and the segment opaque."""
    height, width = depth_buf.shape
    half = 0.5 * width_px
    reach = half + 1.0
    for s in range(pairs.shape[0]):
        a, b = pairs[s, 0], pairs[s, 1]
        ax, ay, az = _project(cam, points[a, 0], points[a, 1], points[a, 2])
        bx, by, bz = _project(cam, points[b, 0], points[b, 1], points[b, 2])
        if az < near or bz < near or not (ax == ax and bx == bx):
            continue
        ex, ey = bx - ax, by - ay
        len2 = ex * ex + ey * ey
        x0 = max(int(math.floor(min(ax, bx) - reach)), 0)
        x1 = min(int(math.ceil(max(ax, bx) + reach)), width - 1)
        y0 = max(int(math.floor(min(ay, by) - reach)), 0)
        y1 = min(int(math.ceil(max(ay, by) + reach)), height - 1)
        for py in range(y0, y1 + 1):
            cy = py + 0.5
            for px in range(x0, x1 + 1):
                cx = px + 0.5
                u = 0.0 if len2 <= 1e-12 else ((cx - ax) * ex + (cy - ay) * ey) / len2
                u = 0.0 if u < 0.0 else (1.0 if u > 1.0 else u)
                qx, qy = ax + u * ex - cx, ay + u * ey - cy
                d = math.sqrt(qx * qx + qy * qy)
                alpha = half + 0.5 - d
                if alpha <= 0.0:
                    continue
                if alpha > 1.0:
                    alpha = 1.0
                z = az + u * (bz - az)
                if z >= depth_buf[py, px]:
                    continue
                if alpha >= 0.5 and opacity[s] >= 1.0:
                    depth_buf[py, px] = z
                alpha *= opacity[s]
                for c in range(3):
                    color_buf[py, px, c] += (color[s, c] - color_buf[py, px, c]) * alpha
