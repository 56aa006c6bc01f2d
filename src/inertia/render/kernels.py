"""Rasterization kernels: sphere impostors, ray-cast collider primitives, ground grid, shadows.

The renderer (`inertia.render.renderer`) runs them in this order each frame:

1. ``background_3d`` / ``background_2d`` -- per pixel (parallel over rows): sky or paper colour,
   the ground grid, and the analytic collider primitives (``PRIM_*`` below),
   into a colour buffer (H, W, 3) float32 *linear* RGB and a depth buffer (H, W) float32.
   Cached between frames while the camera and the colliders do not move.
2. ``shadow_deposit`` + ``blur_shadow`` -- particles deposited straight down onto a small grid
   over the ground (fading with height) and blurred: a soft contact shadow that grounds them,
   applied to ground pixels in step 5.
3. ``project_spheres`` -- per particle (parallel): pixel centre, depth, pixel and world radius,
   visibility (culled when off screen, behind the eye or inactive).
4. ``back_to_front`` + ``gather_sorted`` -- a counting sort on quantised depth (O(N), stable),
   then the drawn particles' attributes packed contiguously in drawing order.
5. ``bin_bands`` + ``render_bands`` -- the caller copies the cached background (linear
   colour, depth, sRGB bytes) into the frame buffers; then, parallel over horizontal bands of
   rows (each task owns its band's pixels, so writes never race), the shadows are applied and
   the band's particles splatted. Per covered pixel: the sphere's normal from the pixel's
   offset, per-pixel depth ``depth - n_z * radius`` (so intersecting spheres cut each other
   correctly), a z-test, shading from a table over the normal (`shading_table`: Lambert +
   hemisphere ambient + Blinn highlight), and coverage anti-aliasing of the rim (blending over
   what is behind, which back-to-front order makes correct).
6. Still inside the band task, the touched spans of each row go from linear float to sRGB
   bytes through a lookup table.

Everything is deterministic: every pixel is written by one task in a fixed order, and no
reduction depends on thread timing, so the same input gives identical bytes at any thread count.
Every kernel with a ``prange`` is an `inertia._jit.parallel_kernel`: a parallel build
(``.parallel``) and a serial twin (``.serial``, the same code cached under its own name), each
compiled on first use; the renderer picks by problem size (pixels, particles), since a
parallel hand-off costs more than small work and the parallel build compiles ~2 times slower.

Camera vector layout (`Camera.params`): CAM_EYE 0:3, CAM_RIGHT 3:6, CAM_UP 6:9, CAM_FWD 9:12,
CAM_F 12 (focal length in px, or px per unit when orthographic), CAM_CX 13, CAM_CY 14,
CAM_ORTHO 15.

Light vector layout: direction to the light in camera space 0:3, sky ambient 3:6, ground
ambient 6:9, camera-space up 9:12, diffuse 12, specular 13, log2 of the shininess 14, world up
15:18, normalised Blinn half vector (camera space) 18:21.

Primitive table: ``prims`` (P, 16) float64 and ``prim_kind`` (P,) int64, ``prim_color`` (P, 3)
float32 linear RGB:

=========  =================================================================================
PRIM_PLANE point 0:3, unit normal 3:6, grid spacing 6, receives shadows 7 (1/0); drawn with grid
PRIM_SPHERE centre 0:3, radius 3
PRIM_BOX   centre 0:3, half extents 3:6, rotation rows 6:15 (local = R (p - centre))
PRIM_CAPSULE end a 0:3, end b 3:6, radius 6
PRIM_CONTAINER  as PRIM_BOX, seen from inside: the ray's exit point, so the far walls show and
           the near ones do not hide the particles; 2-D: a wall band of thickness 15
PRIM_CYLINDER  end a 0:3, end b 3:6 (axis ends), radius 6 (capped)
=========  =================================================================================

References
----------
Quilez, I. "Intersectors" (ray-sphere, ray-box, ray-capsule, ray-capped cylinder), iquilezles.org.
Green, S. (2010). "Screen Space Fluid Rendering" (sphere impostors with per-pixel depth).
Blinn, J. (1977). "Models of light reflection for computer synthesized pictures", SIGGRAPH.

Limitations: no transparency beyond rim anti-aliasing; shadows fall straight down onto ground
planes only; lighting is one directional light plus hemisphere ambient.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .._jit import parallel_kernel

CAM_EYE, CAM_RIGHT, CAM_UP, CAM_FWD, CAM_F, CAM_CX, CAM_CY, CAM_ORTHO = 0, 3, 6, 9, 12, 13, 14, 15

PRIM_PLANE, PRIM_SPHERE, PRIM_BOX, PRIM_CAPSULE, PRIM_CONTAINER, PRIM_CYLINDER = 0, 1, 2, 3, 4, 5

FAR = np.float32(3.0e38)
# 2-D scenes: colliders sit at this depth, behind every particle (particles have depth ~1).
DEPTH_2D_COLLIDER = np.float32(1.0e20)


# ---------------------------------------------------------------------------------------------
# Small helpers (inlined by Numba)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


@njit(cache=True, inline="always")
def _clamp(x, lo, hi):
    return lo if x < lo else (hi if x > hi else x)


@njit(cache=True)
def _shade(r, g, b, nx, ny, nz, light):
    """Shaded colour of a surface point with camera-space normal n (viewer along +z): Lambert from
    the key light, hemisphere ambient between ground and sky colours, Blinn highlight with the
    precomputed half vector and shininess 2**light[14]."""
    lam = nx * light[0] + ny * light[1] + nz * light[2]
    if lam < 0.0:
        lam = 0.0
    hemi = 0.5 + 0.5 * (nx * light[9] + ny * light[10] + nz * light[11])
    kd = light[12] * lam
    c = nx * light[18] + ny * light[19] + nz * light[20]
    spec = 0.0
    if c > 0.0:
        for _ in range(int(light[14])):
            c = c * c
        spec = light[13] * c
    return (r * (light[6] + (light[3] - light[6]) * hemi + kd) + spec,
            g * (light[7] + (light[4] - light[7]) * hemi + kd) + spec,
            b * (light[8] + (light[5] - light[8]) * hemi + kd) + spec)


@njit(cache=True)
def _grid_intensity(u, v, spacing, footprint):
    """Anti-aliased grid lines at multiples of ``spacing`` (minor) and 5 * spacing (major)."""
    total = 0.0
    for level in range(2):
        g = spacing * (5.0 if level == 1 else 1.0)
        width = footprint * (1.0 if level == 0 else 1.6)
        # Lines thinner than ~1/4 of their spacing on screen fade out instead of aliasing.
        fade = _clamp(1.0 - (footprint / g - 0.08) / 0.25, 0.0, 1.0)
        if fade <= 0.0:
            continue
        du = abs(u / g - math.floor(u / g + 0.5)) * g
        dv = abs(v / g - math.floor(v / g + 0.5)) * g
        line = max(_clamp(1.0 - du / width, 0.0, 1.0), _clamp(1.0 - dv / width, 0.0, 1.0))
        strength = 0.2 if level == 0 else 0.45
        total = max(total, line * fade * strength)
    return total


# ---------------------------------------------------------------------------------------------
# Ray-primitive intersection (world space). Return (t, nx, ny, nz); t < 0 means no hit.
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _hit_plane(ox, oy, oz, dx, dy, dz, p):
    denom = _dot(dx, dy, dz, p[3], p[4], p[5])
    if abs(denom) < 1e-12:
        return -1.0, 0.0, 0.0, 0.0
    t = _dot(p[0] - ox, p[1] - oy, p[2] - oz, p[3], p[4], p[5]) / denom
    s = -1.0 if denom > 0.0 else 1.0  # face the viewer
    return t, s * p[3], s * p[4], s * p[5]


@njit(cache=True)
def _hit_sphere(ox, oy, oz, dx, dy, dz, p):
    lx, ly, lz = ox - p[0], oy - p[1], oz - p[2]
    b = _dot(lx, ly, lz, dx, dy, dz)
    c = _dot(lx, ly, lz, lx, ly, lz) - p[3] * p[3]
    h = b * b - c
    if h < 0.0:
        return -1.0, 0.0, 0.0, 0.0
    h = math.sqrt(h)
    t = -b - h
    if t < 0.0:
        t = -b + h  # eye inside the sphere: see its inside
    x, y, z = ox + t * dx - p[0], oy + t * dy - p[1], oz + t * dz - p[2]
    inv = 1.0 / p[3]
    return t, x * inv, y * inv, z * inv


@njit(cache=True)
def _hit_box(ox, oy, oz, dx, dy, dz, p):
    # Ray into the box frame: local = R (world - centre), R's rows at p[6:15].
    rx, ry, rz = ox - p[0], oy - p[1], oz - p[2]
    lo = (p[6] * rx + p[7] * ry + p[8] * rz, p[9] * rx + p[10] * ry + p[11] * rz, p[12] * rx + p[13] * ry + p[14] * rz)
    ld = (p[6] * dx + p[7] * dy + p[8] * dz, p[9] * dx + p[10] * dy + p[11] * dz, p[12] * dx + p[13] * dy + p[14] * dz)
    t_near, t_far = -1e300, 1e300
    axis_near, sign_near, axis_far, sign_far = 0, 1.0, 0, 1.0
    for k in range(3):
        h = p[3 + k]
        if abs(ld[k]) < 1e-15:
            if abs(lo[k]) > h:
                return -1.0, 0.0, 0.0, 0.0
            continue
        inv = 1.0 / ld[k]
        t1 = (-h - lo[k]) * inv
        t2 = (h - lo[k]) * inv
        s = -1.0
        if t1 > t2:
            t1, t2 = t2, t1
            s = 1.0
        if t1 > t_near:
            t_near, axis_near, sign_near = t1, k, s
        if t2 < t_far:
            t_far, axis_far, sign_far = t2, k, -s
    if t_near > t_far or t_far < 0.0:
        return -1.0, 0.0, 0.0, 0.0
    t, axis, sign = t_near, axis_near, sign_near
    if t < 0.0:
        t, axis, sign = t_far, axis_far, sign_far
    # Local face normal back to world: n_world = R^T n_local = sign * row `axis` of R.
    return t, sign * p[6 + 3 * axis], sign * p[7 + 3 * axis], sign * p[8 + 3 * axis]


@njit(cache=True)
def _hit_container(ox, oy, oz, dx, dy, dz, p):
    """The far side of an oriented box: where the ray leaves it; normal pointing inward."""
    rx, ry, rz = ox - p[0], oy - p[1], oz - p[2]
    lo = (p[6] * rx + p[7] * ry + p[8] * rz, p[9] * rx + p[10] * ry + p[11] * rz, p[12] * rx + p[13] * ry + p[14] * rz)
    ld = (p[6] * dx + p[7] * dy + p[8] * dz, p[9] * dx + p[10] * dy + p[11] * dz, p[12] * dx + p[13] * dy + p[14] * dz)
    t_near, t_far = -1e300, 1e300
    axis_far, sign_far = 0, 1.0
    for k in range(3):
        h = p[3 + k]
        if abs(ld[k]) < 1e-15:
            if abs(lo[k]) > h:
                return -1.0, 0.0, 0.0, 0.0
            continue
        inv = 1.0 / ld[k]
        t1 = (-h - lo[k]) * inv
        t2 = (h - lo[k]) * inv
        s = 1.0
        if t1 > t2:
            t1, t2 = t2, t1
            s = -1.0
        t_near = max(t_near, t1)
        if t2 < t_far:
            t_far, axis_far, sign_far = t2, k, s
    if t_near > t_far or t_far < 0.0:
        return -1.0, 0.0, 0.0, 0.0
    # The exit face's outward normal is sign_far * axis; inward is its opposite.
    return t_far, -sign_far * p[6 + 3 * axis_far], -sign_far * p[7 + 3 * axis_far], -sign_far * p[8 + 3 * axis_far]


@njit(cache=True)
def _hit_cylinder(ox, oy, oz, dx, dy, dz, p):
    """Quilez's ray - capped cylinder intersection."""
    bax, bay, baz = p[3] - p[0], p[4] - p[1], p[5] - p[2]
    ocx, ocy, ocz = ox - p[0], oy - p[1], oz - p[2]
    ra = p[6]
    baba = _dot(bax, bay, baz, bax, bay, baz)
    bard = _dot(bax, bay, baz, dx, dy, dz)
    baoc = _dot(bax, bay, baz, ocx, ocy, ocz)
    k2 = baba - bard * bard
    k1 = baba * _dot(ocx, ocy, ocz, dx, dy, dz) - baoc * bard
    k0 = baba * _dot(ocx, ocy, ocz, ocx, ocy, ocz) - baoc * baoc - ra * ra * baba
    if k2 > 1e-12 * baba:
        h = k1 * k1 - k2 * k0
        if h < 0.0:
            return -1.0, 0.0, 0.0, 0.0
        h = math.sqrt(h)
        t = (-k1 - h) / k2
        y = baoc + t * bard
        if y > 0.0 and y < baba and t > 0.0:
            nx = (ocx + t * dx - bax * y / baba) / ra
            ny = (ocy + t * dy - bay * y / baba) / ra
            nz = (ocz + t * dz - baz * y / baba) / ra
            return t, nx, ny, nz
    elif k0 > 0.0:
        return -1.0, 0.0, 0.0, 0.0  # parallel to the axis and outside the radius
    # The caps: the nearer of the two end discs the ray crosses.
    if abs(bard) < 1e-15:
        return -1.0, 0.0, 0.0, 0.0
    best, best_sign = -1.0, 0.0
    for end in range(2):
        cap = 0.0 if end == 0 else baba
        t = (cap - baoc) / bard
        if t <= 0.0 or (best > 0.0 and t >= best):
            continue
        qx = ocx + t * dx - bax * cap / baba
        qy = ocy + t * dy - bay * cap / baba
        qz = ocz + t * dz - baz * cap / baba
        if _dot(qx, qy, qz, qx, qy, qz) <= ra * ra:
            best, best_sign = t, (-1.0 if end == 0 else 1.0)
    if best < 0.0:
        return -1.0, 0.0, 0.0, 0.0
    inv = best_sign / math.sqrt(baba)
    return best, bax * inv, bay * inv, baz * inv


@njit(cache=True)
def _hit_capsule(ox, oy, oz, dx, dy, dz, p):
    # Quilez's ray-capsule intersection.
    bax, bay, baz = p[3] - p[0], p[4] - p[1], p[5] - p[2]
    oax, oay, oaz = ox - p[0], oy - p[1], oz - p[2]
    r = p[6]
    baba = _dot(bax, bay, baz, bax, bay, baz)
    bard = _dot(bax, bay, baz, dx, dy, dz)
    baoa = _dot(bax, bay, baz, oax, oay, oaz)
    rdoa = _dot(dx, dy, dz, oax, oay, oaz)
    oaoa = _dot(oax, oay, oaz, oax, oay, oaz)
    a = baba - bard * bard
    b = baba * rdoa - baoa * bard
    c = baba * oaoa - baoa * baoa - r * r * baba
    t = -1.0
    if a > 1e-15:
        h = b * b - a * c
        if h >= 0.0:
            tt = (-b - math.sqrt(h)) / a
            y = baoa + tt * bard
            if y > 0.0 and y < baba and tt > 0.0:
                t = tt
    if t < 0.0:
        # The end caps: spheres at a and b.
        best = -1.0
        for end in range(2):
            cx, cy, cz = (p[0], p[1], p[2]) if end == 0 else (p[3], p[4], p[5])
            lx, ly, lz = ox - cx, oy - cy, oz - cz
            bb = _dot(lx, ly, lz, dx, dy, dz)
            cc = _dot(lx, ly, lz, lx, ly, lz) - r * r
            hh = bb * bb - cc
            if hh >= 0.0:
                tt = -bb - math.sqrt(hh)
                if tt > 0.0 and (best < 0.0 or tt < best):
                    best = tt
        t = best
    if t < 0.0:
        return -1.0, 0.0, 0.0, 0.0
    # Normal: from the closest point on the segment.
    px, py, pz = ox + t * dx, oy + t * dy, oz + t * dz
    s = 0.0
    if baba > 0.0:
        s = _clamp(_dot(px - p[0], py - p[1], pz - p[2], bax, bay, baz) / baba, 0.0, 1.0)
    nx, ny, nz = px - (p[0] + s * bax), py - (p[1] + s * bay), pz - (p[2] + s * baz)
    n = math.sqrt(nx * nx + ny * ny + nz * nz)
    if n > 0.0:
        nx, ny, nz = nx / n, ny / n, nz / n
    return t, nx, ny, nz


# ---------------------------------------------------------------------------------------------
# 1. Backgrounds
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _primary_ray(cam, px, py):
    """World ray (origin, unit direction) through the centre of pixel (px, py)."""
    f, cx, cy = cam[CAM_F], cam[CAM_CX], cam[CAM_CY]
    sx = (px + 0.5 - cx) / f
    sy = (cy - (py + 0.5)) / f
    if cam[CAM_ORTHO] > 0.5:
        ox = cam[0] + sx * cam[3] + sy * cam[6]
        oy = cam[1] + sx * cam[4] + sy * cam[7]
        oz = cam[2] + sx * cam[5] + sy * cam[8]
        return ox, oy, oz, cam[9], cam[10], cam[11]
    dx = cam[9] + sx * cam[3] + sy * cam[6]
    dy = cam[10] + sx * cam[4] + sy * cam[7]
    dz = cam[11] + sx * cam[5] + sy * cam[8]
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    return cam[0], cam[1], cam[2], dx / n, dy / n, dz / n


@njit(cache=True)
def _write_surface(py, px, ox, oy, oz, dx, dy, dz, t, nx, ny, nz, kind, p, albedo, cam, light, sky_horizon,
                   fog_distance, grid_line, color_out, depth_out, ground_out):
    """Shade the hit of the ray at distance t (normal n) on a primitive of ``kind`` (row p) and
    write colour, depth and, for shadow-receiving planes and container floors, the hit point."""
    hx, hy, hz = ox + t * dx, oy + t * dy, oz + t * dz
    # Camera-space normal for shading.
    cnx = _dot(nx, ny, nz, cam[3], cam[4], cam[5])
    cny = _dot(nx, ny, nz, cam[6], cam[7], cam[8])
    cnz = -_dot(nx, ny, nz, cam[9], cam[10], cam[11])
    r, g, b = _shade(albedo[0], albedo[1], albedo[2], cnx, cny, cnz, light)
    if kind == PRIM_PLANE or kind == PRIM_CONTAINER:
        # Grid lines in the plane's (wall's) own coordinates, then fog towards the horizon.
        if kind == PRIM_PLANE:
            nx, ny, nz = p[3], p[4], p[5]
        if abs(nx) < 0.9:
            ax, ay, az = 0.0, -nz, ny  # n x (1, 0, 0)
        else:
            ax, ay, az = nz, 0.0, -nx  # n x (0, 1, 0)
        an = math.sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax / an, ay / an, az / an
        bx, by, bz = ny * az - nz * ay, nz * ax - nx * az, nx * ay - ny * ax
        u = _dot(hx, hy, hz, ax, ay, az)
        v = _dot(hx, hy, hz, bx, by, bz)
        cosine = max(abs(_dot(dx, dy, dz, nx, ny, nz)), 0.12)
        f = cam[CAM_F]
        footprint = (1.0 / f if cam[CAM_ORTHO] > 0.5 else t / f) / cosine
        line = _grid_intensity(u, v, p[6] if kind == PRIM_PLANE else p[15], footprint)
        r = r + (grid_line[0] - r) * line * 0.35
        g = g + (grid_line[1] - g) * line * 0.35
        b = b + (grid_line[2] - b) * line * 0.35
        fog = 1.0 - math.exp(-t / fog_distance) if fog_distance > 0.0 else 0.0
        fog = fog * fog
        r = r + (sky_horizon[0] - r) * fog
        g = g + (sky_horizon[1] - g) * fog
        b = b + (sky_horizon[2] - b) * fog
        receives = p[7] > 0.5 if kind == PRIM_PLANE else _dot(nx, ny, nz, light[15], light[16], light[17]) > 0.95
        if receives:
            ground_out[py, px, 0] = hx
            ground_out[py, px, 1] = hy
            ground_out[py, px, 2] = hz
        else:
            ground_out[py, px, 0] = np.nan
            ground_out[py, px, 1] = np.nan
            ground_out[py, px, 2] = np.nan
    else:
        ground_out[py, px, 0] = np.nan
        ground_out[py, px, 1] = np.nan
        ground_out[py, px, 2] = np.nan
    color_out[py, px, 0] = r
    color_out[py, px, 1] = g
    color_out[py, px, 2] = b
    depth_out[py, px] = t * _dot(dx, dy, dz, cam[9], cam[10], cam[11])


@parallel_kernel
def background_3d(cam, width, height, prims, prim_kind, prim_color, light, sky_top, sky_horizon, fog_distance,
                  grid_line, color_out, depth_out, ground_out):
    """Sky and grid planes for a 3-D view (the rows of ``prims`` are all PRIM_PLANE; the other
    primitives are traced over this by the ``trace_<kind>s`` kernels, one per kind, so that a scene
    compiles only the intersectors it draws).

    grid_line (3,): linear colour the grid lines blend towards.
    ground_out (H, W, 3) float32: world hit point of shadow-receiving planes, NaN elsewhere.
    """
    ortho = cam[CAM_ORTHO] > 0.5
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            # Nearest plane along the ray.
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_plane(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k >= 0:
                _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_PLANE, prims[best_k],
                               prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                               color_out, depth_out, ground_out)
                continue
            # Sky: a vertical gradient from the horizon colour to the top colour.
            if ortho:
                up_dot = 0.45 - (py + 0.5) / height
            else:
                up_dot = _dot(dx, dy, dz, light[15], light[16], light[17])
            s = _clamp(up_dot * 1.6 + 0.1, 0.0, 1.0)
            color_out[py, px, 0] = sky_horizon[0] + (sky_top[0] - sky_horizon[0]) * s
            color_out[py, px, 1] = sky_horizon[1] + (sky_top[1] - sky_horizon[1]) * s
            color_out[py, px, 2] = sky_horizon[2] + (sky_top[2] - sky_horizon[2]) * s
            depth_out[py, px] = FAR
            ground_out[py, px, 0] = np.nan
            ground_out[py, px, 1] = np.nan
            ground_out[py, px, 2] = np.nan


@parallel_kernel
def trace_spheres(cam, width, height, prims, prim_color, light, sky_horizon, fog_distance, grid_line,
                  color_out, depth_out, ground_out):
    """Ray-cast the PRIM_SPHERE rows ``prims`` over the buffers (z-tested against ``depth_out``)."""
    fwd_x, fwd_y, fwd_z = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_sphere(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k < 0 or best_t * _dot(dx, dy, dz, fwd_x, fwd_y, fwd_z) >= depth_out[py, px]:
                continue
            _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_SPHERE, prims[best_k],
                           prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                           color_out, depth_out, ground_out)


@parallel_kernel
def trace_boxes(cam, width, height, prims, prim_color, light, sky_horizon, fog_distance, grid_line,
                  color_out, depth_out, ground_out):
    """Ray-cast the PRIM_BOX rows ``prims`` over the buffers (z-tested against ``depth_out``)."""
    fwd_x, fwd_y, fwd_z = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_box(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k < 0 or best_t * _dot(dx, dy, dz, fwd_x, fwd_y, fwd_z) >= depth_out[py, px]:
                continue
            _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_BOX, prims[best_k],
                           prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                           color_out, depth_out, ground_out)


@parallel_kernel
def trace_capsules(cam, width, height, prims, prim_color, light, sky_horizon, fog_distance, grid_line,
                  color_out, depth_out, ground_out):
    """Ray-cast the PRIM_CAPSULE rows ``prims`` over the buffers (z-tested against ``depth_out``)."""
    fwd_x, fwd_y, fwd_z = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_capsule(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k < 0 or best_t * _dot(dx, dy, dz, fwd_x, fwd_y, fwd_z) >= depth_out[py, px]:
                continue
            _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_CAPSULE, prims[best_k],
                           prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                           color_out, depth_out, ground_out)


@parallel_kernel
def trace_cylinders(cam, width, height, prims, prim_color, light, sky_horizon, fog_distance, grid_line,
                  color_out, depth_out, ground_out):
    """Ray-cast the PRIM_CYLINDER rows ``prims`` over the buffers (z-tested against ``depth_out``)."""
    fwd_x, fwd_y, fwd_z = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_cylinder(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k < 0 or best_t * _dot(dx, dy, dz, fwd_x, fwd_y, fwd_z) >= depth_out[py, px]:
                continue
            _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_CYLINDER, prims[best_k],
                           prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                           color_out, depth_out, ground_out)


@parallel_kernel
def trace_containers(cam, width, height, prims, prim_color, light, sky_horizon, fog_distance, grid_line,
                  color_out, depth_out, ground_out):
    """Ray-cast the PRIM_CONTAINER rows ``prims`` over the buffers (z-tested against ``depth_out``)."""
    fwd_x, fwd_y, fwd_z = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            best_t, best_k = 1e300, -1
            bnx, bny, bnz = 0.0, 0.0, 0.0
            for k in range(prims.shape[0]):
                t, nx, ny, nz = _hit_container(ox, oy, oz, dx, dy, dz, prims[k])
                if t > 1e-9 and t < best_t:
                    best_t, best_k, bnx, bny, bnz = t, k, nx, ny, nz
            if best_k < 0 or best_t * _dot(dx, dy, dz, fwd_x, fwd_y, fwd_z) >= depth_out[py, px]:
                continue
            _write_surface(py, px, ox, oy, oz, dx, dy, dz, best_t, bnx, bny, bnz, PRIM_CONTAINER, prims[best_k],
                           prim_color[best_k], cam, light, sky_horizon, fog_distance, grid_line,
                           color_out, depth_out, ground_out)


#: The trace kernel of each non-plane primitive kind.
TRACE_KERNELS = {PRIM_SPHERE: "trace_spheres", PRIM_BOX: "trace_boxes", PRIM_CAPSULE: "trace_capsules",
                 PRIM_CYLINDER: "trace_cylinders", PRIM_CONTAINER: "trace_containers"}


@njit(cache=True)
def _sd_2d(kind, p, x, y):
    """Signed distance of the 2-D primitive ``p`` at (x, y)."""
    if kind == PRIM_PLANE:
        return (x - p[0]) * p[3] + (y - p[1]) * p[4]
    if kind == PRIM_SPHERE:
        return math.sqrt((x - p[0]) ** 2 + (y - p[1]) ** 2) - p[3]
    if kind == PRIM_BOX or kind == PRIM_CONTAINER:
        rx, ry = x - p[0], y - p[1]
        qx = abs(p[6] * rx + p[7] * ry) - p[3]
        qy = abs(p[9] * rx + p[10] * ry) - p[4]
        outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2)
        sd = outside + min(max(qx, qy), 0.0)
        if kind == PRIM_CONTAINER:
            return max(-sd, sd - p[15])  # a wall band of thickness p[15] around the free space
        return sd
    # Capsule: distance to the segment minus the radius.
    bx, by = p[3] - p[0], p[4] - p[1]
    ax, ay = x - p[0], y - p[1]
    bb = bx * bx + by * by
    s = _clamp((ax * bx + ay * by) / bb, 0.0, 1.0) if bb > 0.0 else 0.0
    return math.sqrt((ax - s * bx) ** 2 + (ay - s * by) ** 2) - p[6]


@parallel_kernel
def background_2d(cam, width, height, prims, prim_kind, prim_color, paper, grid_color, grid_spacing,
                  extra_sd, extra_color, color_out, depth_out):
    """Paper colour, world grid with axes, and filled collider shapes for a 2-D view.

    extra_sd (H, W) float32: signed distance of colliders without an analytic primitive
    (sampled by the caller), or an empty (0, 0) array.
    """
    f, cx, cy = cam[CAM_F], cam[CAM_CX], cam[CAM_CY]
    pixel = 1.0 / f
    has_extra = extra_sd.shape[0] == height
    for py in prange(height):
        for px in range(width):
            x = cam[0] + (px + 0.5 - cx) * pixel
            y = cam[1] + (cy - (py + 0.5)) * pixel
            r, g, b = paper[0], paper[1], paper[2]
            # Minor and major grid lines, and the two axes drawn stronger.
            line = _grid_intensity(x, y, grid_spacing, pixel)
            axis = max(_clamp(1.0 - abs(x) / (1.5 * pixel), 0.0, 1.0), _clamp(1.0 - abs(y) / (1.5 * pixel), 0.0, 1.0))
            line = max(line, 0.8 * axis)
            r += (grid_color[0] - r) * line
            g += (grid_color[1] - g) * line
            b += (grid_color[2] - b) * line
            depth = FAR
            # Colliders: filled interior, darker anti-aliased outline.
            for k in range(prims.shape[0] + (1 if has_extra else 0)):
                if k < prims.shape[0]:
                    sd = _sd_2d(prim_kind[k], prims[k], x, y)
                    cr, cg, cb = prim_color[k, 0], prim_color[k, 1], prim_color[k, 2]
                else:
                    sd = extra_sd[py, px]
                    cr, cg, cb = extra_color[0], extra_color[1], extra_color[2]
                fill = _clamp(0.5 - sd / pixel, 0.0, 1.0)
                edge = _clamp(1.0 - abs(sd) / (1.25 * pixel), 0.0, 1.0)
                if fill > 0.0 or edge > 0.0:
                    a = 0.85 * fill
                    r += (cr - r) * a
                    g += (cg - g) * a
                    b += (cb - b) * a
                    r += (0.35 * cr - r) * edge
                    g += (0.35 * cg - g) * edge
                    b += (0.35 * cb - b) * edge
                    depth = DEPTH_2D_COLLIDER
            color_out[py, px, 0] = r
            color_out[py, px, 1] = g
            color_out[py, px, 2] = b
            depth_out[py, px] = depth


@parallel_kernel
def composite_surface(hit_depth, hit_normal, color, cam, light, color_buf, depth_buf):
    """Merge a ray-traced surface (depth (H, W), NaN = miss; world normals (H, W, 3)) into the
    buffers with a z-test. Used for colliders without an analytic primitive."""
    height, width = hit_depth.shape
    for py in prange(height):
        for px in range(width):
            d = hit_depth[py, px]
            if not (d < depth_buf[py, px]):
                continue
            nx, ny, nz = hit_normal[py, px, 0], hit_normal[py, px, 1], hit_normal[py, px, 2]
            cnx = _dot(nx, ny, nz, cam[3], cam[4], cam[5])
            cny = _dot(nx, ny, nz, cam[6], cam[7], cam[8])
            cnz = -_dot(nx, ny, nz, cam[9], cam[10], cam[11])
            r, g, b = _shade(color[0], color[1], color[2], cnx, cny, cnz, light)
            color_buf[py, px, 0] = r
            color_buf[py, px, 1] = g
            color_buf[py, px, 2] = b
            depth_buf[py, px] = d


# ---------------------------------------------------------------------------------------------
# 2. Contact shadows on the ground
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def shadow_deposit(positions, radius, active, up, axis_a, axis_b, ground_level, origin_a, origin_b, texel,
                   strength, fade_height, out):
    """Deposit each particle's shadow 'optical depth' on the ground grid ``out`` (Sa, Sb) float32.

    A particle of radius r at height h above the ground adds strength * (1 - h / fade_height)
    spread over its disc (small discs: bilinearly onto the 4 nearest texels). Summation in
    index order, so the result is deterministic. Blur with `blur_shadow`, then the ground
    darkens by 1 - exp(-value).
    """
    size_a, size_b = out.shape[0], out.shape[1]
    out[:, :] = 0.0
    for i in range(positions.shape[0]):
        if not active[i]:
            continue
        x, y, z = positions[i, 0], positions[i, 1], positions[i, 2]
        h = _dot(x, y, z, up[0], up[1], up[2]) - ground_level
        r = radius[i]
        if not (h > -r and h < fade_height):
            continue
        s = strength * (1.0 - max(h, 0.0) / fade_height)
        ca = (_dot(x, y, z, axis_a[0], axis_a[1], axis_a[2]) - origin_a) / texel - 0.5
        cb = (_dot(x, y, z, axis_b[0], axis_b[1], axis_b[2]) - origin_b) / texel - 0.5
        rt = r / texel
        if rt < 1.5:
            # Small: the disc's area (in texels) times s, split bilinearly.
            amount = s * math.pi * max(rt * rt, 0.25)
            ia, jb = int(math.floor(ca)), int(math.floor(cb))
            fa, fb = ca - ia, cb - jb
            for di in range(2):
                for dj in range(2):
                    ii, jj = ia + di, jb + dj
                    if ii >= 0 and jj >= 0 and ii < size_a and jj < size_b:
                        out[ii, jj] += amount * (fa if di else 1.0 - fa) * (fb if dj else 1.0 - fb)
        else:
            i0, i1 = max(int(math.floor(ca - rt)), 0), min(int(math.ceil(ca + rt)) + 1, size_a)
            j0, j1 = max(int(math.floor(cb - rt)), 0), min(int(math.ceil(cb + rt)) + 1, size_b)
            for ii in range(i0, i1):
                for jj in range(j0, j1):
                    d2 = ((ii - ca) ** 2 + (jj - cb) ** 2) / (rt * rt)
                    if d2 < 1.0:
                        out[ii, jj] += s


def _blur_shadow(values, scratch, taps):
    """Separable blur of ``values`` in place with the normalised 1-D kernel ``taps`` (odd length)."""
    size_a, size_b = values.shape
    half = taps.shape[0] // 2
    for i in prange(size_a):
        for j in range(size_b):
            acc = 0.0
            for k in range(taps.shape[0]):
                jj = j + k - half
                if jj >= 0 and jj < size_b:
                    acc += taps[k] * values[i, jj]
            scratch[i, j] = acc
    for i in prange(size_a):
        for j in range(size_b):
            acc = 0.0
            for k in range(taps.shape[0]):
                ii = i + k - half
                if ii >= 0 and ii < size_a:
                    acc += taps[k] * scratch[ii, j]
            values[i, j] = acc


blur_shadow = parallel_kernel(_blur_shadow)


@parallel_kernel
def ground_texels(ground, axis_a, axis_b, origin_a, origin_b, texel, out):
    """Shadow-map coordinates (H, W, 2) float32 of the ground hit points; NaN off the ground."""
    height, width = ground.shape[0], ground.shape[1]
    for py in prange(height):
        for px in range(width):
            x, y, z = ground[py, px, 0], ground[py, px, 1], ground[py, px, 2]
            if x == x:
                out[py, px, 0] = (_dot(x, y, z, axis_a[0], axis_a[1], axis_a[2]) - origin_a) / texel - 0.5
                out[py, px, 1] = (_dot(x, y, z, axis_b[0], axis_b[1], axis_b[2]) - origin_b) / texel - 0.5
            else:
                out[py, px, 0] = np.nan
                out[py, px, 1] = np.nan


# ---------------------------------------------------------------------------------------------
# 3-5. Particles
# ---------------------------------------------------------------------------------------------
def _project_spheres(positions, radius, active, cam, width, height, min_radius_px,
                    sx, sy, depth, radius_px, radius_world, visible):
    """Screen position, depth and radii of every particle; ``visible`` False when culled."""
    f, cx, cy = cam[CAM_F], cam[CAM_CX], cam[CAM_CY]
    ortho = cam[CAM_ORTHO] > 0.5
    for i in prange(positions.shape[0]):
        visible[i] = False
        if not active[i]:
            continue
        rx = positions[i, 0] - cam[0]
        ry = positions[i, 1] - cam[1]
        rz = positions[i, 2] - cam[2]
        x = _dot(rx, ry, rz, cam[3], cam[4], cam[5])
        y = _dot(rx, ry, rz, cam[6], cam[7], cam[8])
        z = _dot(rx, ry, rz, cam[9], cam[10], cam[11])
        r = radius[i]
        if not (x == x and y == y and z == z and r == r):
            continue  # NaN positions are not drawn
        if ortho:
            scale = f
        else:
            if z <= max(r, 1e-6):
                continue  # behind the eye or around it
            scale = f / z
        px, py, rp = cx + scale * x, cy - scale * y, scale * r
        if rp < min_radius_px:
            rp = min_radius_px
        if px + rp < 0.0 or px - rp > width or py + rp < 0.0 or py - rp > height:
            continue
        sx[i], sy[i], depth[i] = px, py, z
        radius_px[i] = rp
        radius_world[i] = rp / scale
        visible[i] = True


project_spheres = parallel_kernel(_project_spheres)


@njit(cache=True)
def back_to_front(visible, depth, buckets, order):
    """Indices of the visible particles, farthest first, into ``order``; returns their count.

    A counting sort on depth quantised to ``buckets`` (65536 is plenty) levels: O(N), stable
    (equal levels keep index order), so the result is deterministic.
    """
    n = visible.shape[0]
    lo, hi, m = np.inf, -np.inf, 0
    for i in range(n):
        if visible[i]:
            m += 1
            if depth[i] < lo:
                lo = depth[i]
            if depth[i] > hi:
                hi = depth[i]
    if m == 0:
        return 0
    scale = (buckets - 1) / (hi - lo) if hi > lo else 0.0
    counts = np.zeros(buckets + 1, np.int64)
    for i in range(n):
        if visible[i]:
            counts[int((hi - depth[i]) * scale) + 1] += 1
    for b in range(buckets):
        counts[b + 1] += counts[b]
    for i in range(n):
        if visible[i]:
            b = int((hi - depth[i]) * scale)
            order[counts[b]] = i
            counts[b] += 1
    return m


def _gather_sorted(order, m, sx, sy, depth, radius_px, radius_world, colors, packed, packed_colors, row_range):
    """Copy the drawn particles' attributes into contiguous arrays in drawing order.

    packed (M, 5) float64: x, y, depth, radius px, radius world; packed_colors (M, 3) float32;
    row_range (M, 2) int32: first and last+1 pixel rows the particle touches.
    """
    for s in prange(m):
        i = order[s]
        packed[s, 0] = sx[i]
        packed[s, 1] = sy[i]
        packed[s, 2] = depth[i]
        packed[s, 3] = radius_px[i]
        packed[s, 4] = radius_world[i]
        packed_colors[s, 0] = colors[i, 0]
        packed_colors[s, 1] = colors[i, 1]
        packed_colors[s, 2] = colors[i, 2]
        # Rows whose pixel centres lie within the disc (plus its half-pixel rim).
        rr = radius_px[i] + 0.5
        row_range[s, 0] = int(math.floor(sy[i] - rr - 0.5)) + 1
        row_range[s, 1] = int(math.ceil(sy[i] + rr - 0.5))


gather_sorted = parallel_kernel(_gather_sorted)


SHADE_LUT_SIZE = 128


@njit(cache=True)
def bin_bands(row_range, m, band, n_bands, band_start):
    """CSR lists of the drawn particles touching each band of rows, in drawing order.

    band_start (n_bands + 1,) int64 is filled; returns the items (total,) int64.
    """
    band_start[:] = 0
    for s in range(m):
        b0 = max(row_range[s, 0], 0) // band
        b1 = min((row_range[s, 1] - 1) // band, n_bands - 1)
        for b in range(b0, b1 + 1):
            band_start[b + 1] += 1
    for b in range(n_bands):
        band_start[b + 1] += band_start[b]
    items = np.empty(band_start[n_bands], np.int64)
    cursor = band_start[:n_bands].copy()
    for s in range(m):
        b0 = max(row_range[s, 0], 0) // band
        b1 = min((row_range[s, 1] - 1) // band, n_bands - 1)
        for b in range(b0, b1 + 1):
            items[cursor[b]] = s
            cursor[b] += 1
    return items


@njit(cache=True)
def shading_table(light, size, out):
    """Tabulate `_shade` over sphere normals: out (size, size, 8) float32 holds, for the normal
    with camera-space (nx, ny) at the cell centre, the colour multipliers (r, g, b), the
    additive highlight and n_z (the sphere's height towards the viewer, for per-pixel depth).
    Row index from ny (top = +1), column from nx."""
    for iy in range(size):
        ny = 1.0 - (iy + 0.5) * 2.0 / size
        for ix in range(size):
            nx = (ix + 0.5) * 2.0 / size - 1.0
            q = nx * nx + ny * ny
            if q >= 1.0:
                sq = math.sqrt(q)
                nx2, ny2, nz = nx / sq, ny / sq, 0.0
            else:
                nx2, ny2, nz = nx, ny, math.sqrt(1.0 - q)
            white_r, white_g, white_b = _shade(1.0, 1.0, 1.0, nx2, ny2, nz, light)
            black_r, _, _ = _shade(0.0, 0.0, 0.0, nx2, ny2, nz, light)
            out[iy, ix, 0] = white_r - black_r
            out[iy, ix, 1] = white_g - black_r
            out[iy, ix, 2] = white_b - black_r
            out[iy, ix, 3] = black_r
            out[iy, ix, 4] = nz
            out[iy, ix, 5] = 0.0
            out[iy, ix, 6] = 0.0
            out[iy, ix, 7] = 0.0


@njit(cache=True, inline="always")
def _to_byte(v, lut, top):
    if not (v > 0.0):
        v = 0.0
    elif v > 1.0:
        v = 1.0
    return lut[int(v * top + 0.5)]


def _render_bands(ground_tex, shadow, shadow_box, packed, packed_colors, row_range, band_start, band_items,
                  table, band, stride, lut, color_buf, depth_buf, out):
    """Draw shadows and particles over a frame whose buffers already hold the background.

    ``color_buf`` (H, W, 3) float32 linear and ``depth_buf`` (H, W) float32 hold the
    background, ``out`` (H, W, 3) uint8 its sRGB bytes. One task per band of ``band`` rows
    (race-free): darken the band's ground pixels inside ``shadow_box`` (x0, x1, y0, y1 pixel
    bounds of the shadowed ground; empty for none) by the shadow map, then splat the band's
    particles (`bin_bands`) in back-to-front order with a z-test, per-pixel sphere depth,
    shading from ``table`` (`shading_table`) and rim coverage blending. The pixels written are
    marked and converted to ``out`` once, at the end of the band, so untouched pixels cost
    nothing and overdrawn pixels are converted once.
    """
    height, width = depth_buf.shape
    n_bands = (height + band - 1) // band
    top = lut.shape[0] - 1
    size_a, size_b = shadow.shape[0], shadow.shape[1]
    tsize = table.shape[0]
    half_t = 0.5 * tsize
    for k in prange(n_bands):
        # Interleave bands across the threads' contiguous index ranges for load balance.
        bi = (k * stride) % n_bands
        y0 = bi * band
        y1 = min(y0 + band, height)
        # Contact shadows on ground pixels (NaN texel coordinates elsewhere).
        for py in range(max(y0, shadow_box[2]), min(y1, shadow_box[3])):
            for px in range(max(0, shadow_box[0]), min(width, shadow_box[1])):
                a = ground_tex[py, px, 0]
                if not (a == a):
                    continue
                b = ground_tex[py, px, 1]
                ia, jb = int(math.floor(a)), int(math.floor(b))
                if ia < 0 or jb < 0 or ia + 1 >= size_a or jb + 1 >= size_b:
                    continue
                s00, s01 = shadow[ia, jb], shadow[ia, jb + 1]
                s10, s11 = shadow[ia + 1, jb], shadow[ia + 1, jb + 1]
                if s00 + s01 + s10 + s11 <= 1e-4:
                    continue
                fa, fb = a - ia, b - jb
                v = (1.0 - fa) * ((1.0 - fb) * s00 + fb * s01) + fa * ((1.0 - fb) * s10 + fb * s11)
                keep = math.exp(-v)
                for c in range(3):
                    color_buf[py, px, c] *= keep
                    out[py, px, c] = _to_byte(color_buf[py, px, c], lut, top)
        # Particles touching the band, farthest first. Each row remembers the span of columns
        # the particles touched, converted to bytes once at the end.
        span_lo = np.full(y1 - y0, width, np.int64)
        span_hi = np.zeros(y1 - y0, np.int64)
        dirty = np.zeros((y1 - y0, width), np.uint8)
        for item in range(band_start[bi], band_start[bi + 1]):
            s = band_items[item]
            pcx, pcy, zc, r, rw = packed[s, 0], packed[s, 1], packed[s, 2], packed[s, 3], packed[s, 4]
            cr, cg, cb = packed_colors[s, 0], packed_colors[s, 1], packed_colors[s, 2]
            rr = r + 0.5
            rr2 = rr * rr
            inner2 = (r - 0.5) * (r - 0.5) if r > 0.5 else 0.0
            inv_r = 1.0 / r
            # Rim coverage rr - d ~ (rr^2 - d^2) / (2 r) near the rim: no square root per pixel.
            inv_2r = 0.5 / r if r > 0.5 else 1.0
            ya = max(y0, row_range[s, 0])
            yb = min(y1, row_range[s, 1])
            for py in range(ya, yb):
                dy = py + 0.5 - pcy
                dy2 = dy * dy
                span2 = rr2 - dy2
                if span2 <= 0.0:
                    continue
                span = math.sqrt(span2)
                # Exactly the pixels whose centres lie inside the disc: |px + 0.5 - pcx| < span.
                xa = max(0, int(math.floor(pcx - span - 0.5)) + 1)
                xb = min(width, int(math.ceil(pcx + span - 0.5)))
                if xa < span_lo[py - y0]:
                    span_lo[py - y0] = xa
                if xb > span_hi[py - y0]:
                    span_hi[py - y0] = xb
                iy = int((dy * inv_r + 1.0) * half_t)
                iy = 0 if iy < 0 else (tsize - 1 if iy >= tsize else iy)
                for px in range(xa, xb):
                    dx = px + 0.5 - pcx
                    d2 = dx * dx + dy2
                    ix = int((dx * inv_r + 1.0) * half_t)
                    ix = 0 if ix < 0 else (tsize - 1 if ix >= tsize else ix)
                    # Sphere depth at this pixel: the centre's depth minus the cap height.
                    z = zc - table[iy, ix, 4] * rw
                    if z >= depth_buf[py, px]:
                        continue
                    dirty[py - y0, px] = 1
                    sr = cr * table[iy, ix, 0] + table[iy, ix, 3]
                    sg = cg * table[iy, ix, 1] + table[iy, ix, 3]
                    sb = cb * table[iy, ix, 2] + table[iy, ix, 3]
                    if d2 <= inner2:
                        color_buf[py, px, 0] = sr
                        color_buf[py, px, 1] = sg
                        color_buf[py, px, 2] = sb
                        depth_buf[py, px] = z
                    else:
                        alpha = (rr2 - d2) * inv_2r
                        if alpha > 1.0:
                            alpha = 1.0
                        elif alpha < 0.0:
                            alpha = 0.0
                        sr = color_buf[py, px, 0] + (sr - color_buf[py, px, 0]) * alpha
                        sg = color_buf[py, px, 1] + (sg - color_buf[py, px, 1]) * alpha
                        sb = color_buf[py, px, 2] + (sb - color_buf[py, px, 2]) * alpha
                        color_buf[py, px, 0] = sr
                        color_buf[py, px, 1] = sg
                        color_buf[py, px, 2] = sb
                        if alpha >= 0.5:
                            depth_buf[py, px] = z

        # Linear float -> sRGB bytes for the pixels the particles wrote (scanning each row's span).
        for py in range(y0, y1):
            for px in range(span_lo[py - y0], span_hi[py - y0]):
                if dirty[py - y0, px] == 0:
                    continue
                out[py, px, 0] = _to_byte(color_buf[py, px, 0], lut, top)
                out[py, px, 1] = _to_byte(color_buf[py, px, 1], lut, top)
                out[py, px, 2] = _to_byte(color_buf[py, px, 2], lut, top)


# A parallel build for big frames and a serial one for small ones (a parallel region costs a
# thread hand-off, which dominates when there is little to draw).
render_bands = parallel_kernel(_render_bands)


def _srgb_to_linear(colors, lut, out):
    """sRGB floats in [0, 1] (M, 3) -> linear through ``lut`` (L,) float32 indexed by round(c (L-1))."""
    top = lut.shape[0] - 1
    for i in prange(colors.shape[0]):
        for c in range(3):
            v = colors[i, c]
            if not (v > 0.0):
                v = 0.0
            elif v > 1.0:
                v = 1.0
            out[i, c] = lut[int(v * top + 0.5)]


srgb_to_linear = parallel_kernel(_srgb_to_linear)


def _speed_colors_linear(velocities, vmax, table, out):
    """Colour by speed: |v| / vmax indexes ``table`` (L, 3) float32 of *linear* RGB colours."""
    top = table.shape[0] - 1
    scale = top / vmax if vmax > 0.0 else 0.0
    for i in prange(velocities.shape[0]):
        s2 = 0.0
        for c in range(velocities.shape[1]):
            s2 += velocities[i, c] * velocities[i, c]
        x = math.sqrt(s2) * scale
        k = 0 if not (x > 0.0) else (top if x > top else int(x + 0.5))
        out[i, 0] = table[k, 0]
        out[i, 1] = table[k, 1]
        out[i, 2] = table[k, 2]


speed_colors_linear = parallel_kernel(_speed_colors_linear)


@parallel_kernel
def to_srgb8(color_buf, lut, out):
    """Linear float RGB (H, W, 3) -> sRGB uint8 through ``lut`` (L,) indexed by round(v (L - 1))."""
    height, width = color_buf.shape[0], color_buf.shape[1]
    top = lut.shape[0] - 1
    for py in prange(height):
        for px in range(width):
            for c in range(3):
                out[py, px, c] = _to_byte(color_buf[py, px, c], lut, top)
