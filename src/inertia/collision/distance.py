"""Signed distance kernels for the collider shapes (Numba), evaluated in the rest frame.

Every shape is packed into flat arrays so that one compiled kernel serves every collider:
``kind`` selects the formula, the shape's floats live at ``cf[off:]`` and its integers at
``ci[ioff:]`` (layouts below). 2-D shapes are 3-D shapes restricted to the plane z = 0
(a circle is a sphere, a 2-D box has an infinite z extent), so one code path serves both.

Sign convention: negative inside the solid, positive in free space; the gradient is the unit
outward normal (out of the solid, into free space). A ``Container`` is the complement of a box:
its solid is everything outside, so its distance is positive inside the box.

References
----------
- Quilez, I., "Distance functions" (iquilezles.org/articles/distfunctions): exact distances to
  box, capsule and capped cylinder.
- Osher, S. & Fedkiw, R. (2003), *Level Set Methods and Dynamic Implicit Surfaces*, Springer,
  ch. 2: signed distance functions, their gradient as the surface normal, |grad phi| = 1.
- Bridson, R., Fedkiw, R. & Anderson, J. (2002), "Robust treatment of collisions, contact and
  friction for cloth animation", SIGGRAPH: sampled distance fields interpolated trilinearly.

Limitations
-----------
- A grid field (meshes, baked SDFs) is only as fine as its grid: features thinner than a cell
  are smoothed away (meshes add exact triangle tests for time of impact, see ``toi``), and the
  interpolated value is within ``h*sqrt(3)`` of the true distance (h = cell size).
- Outside its grid a grid field returns phi(c) + |x - c| (c the nearest grid point: exact
  along the grid's face normals, an upper bound elsewhere); the segment-rejection test uses
  the distance to the shape's bounding box instead (a lower bound).
- Container distances are exact inside (the free region) and a lower bound outside.

Packed layouts (floats ``cf``, integers ``ci``, all in the collider's rest frame)
-------------------------------------------------------------------------------
PLANE     cf: n(3), c                 d = n.x - c
SPHERE    cf: centre(3), radius
BOX       cf: centre(3), R(9, row-major, columns = box axes), half_extents(3)
CAPSULE   cf: a(3), b(3), radius
CYLINDER  cf: centre(3), axis(3, unit), radius, half_height
CONTAINER ci: m;  cf: m x [n(3) inward, c]   d = min_i (n_i.x - c_i)
GRID      cf: header (G_* below), values, vertices, triangle normals;
          ci: header (GI_* below), faces, triangle-grid CSR (see ``mesh``)
"""

from __future__ import annotations

import math

from numba import njit, prange, types
from numba.extending import overload

from .._jit import parallel_kernel

PLANE, SPHERE, BOX, CAPSULE, CYLINDER, CONTAINER, GRID, CALLABLE = range(8)
KIND_NAMES = ("plane", "sphere", "box", "capsule", "cylinder", "container", "grid", "callable")

# float header of a GRID shape
G_ORIGIN, G_H, G_BMIN, G_BMAX, G_THICK, G_TGORIGIN, G_TGH, G_MARGIN, G_FHEAD = 0, 3, 4, 7, 10, 11, 14, 15, 16
# int header of a GRID shape (offsets are relative to the shape's own cf/ci offset)
(GI_N, GI_SIGNED, GI_NV, GI_NF, GI_HASTRI, GI_TGN, GI_VAL, GI_VERT, GI_TNORM, GI_FACES,
 GI_TSTART, GI_TITEMS, GI_IHEAD) = 0, 3, 4, 5, 6, 7, 10, 11, 12, 13, 14, 15, 16

BIG = 1e300  # "infinite" extent (2-D boxes along z) without inf arithmetic


# --- rigid frames ----------------------------------------------------------------------------
@njit(cache=True)
def to_rest(pose, ref, x, y, z):
    """Rest-frame point of the world point (x, y, z): c + R^T (x - p); pose = [p(3), R(9)]."""
    dx, dy, dz = x - pose[0], y - pose[1], z - pose[2]
    return (ref[0] + pose[3] * dx + pose[6] * dy + pose[9] * dz,
            ref[1] + pose[4] * dx + pose[7] * dy + pose[10] * dz,
            ref[2] + pose[5] * dx + pose[8] * dy + pose[11] * dz)


@njit(cache=True)
def to_world(pose, ref, x, y, z):
    """World point of the rest-frame point: p + R (X - c)."""
    dx, dy, dz = x - ref[0], y - ref[1], z - ref[2]
    return (pose[0] + pose[3] * dx + pose[4] * dy + pose[5] * dz,
            pose[1] + pose[6] * dx + pose[7] * dy + pose[8] * dz,
            pose[2] + pose[9] * dx + pose[10] * dy + pose[11] * dz)


@njit(cache=True)
def rotate(pose, x, y, z):
    """R v for the rotation in pose."""
    return (pose[3] * x + pose[4] * y + pose[5] * z,
            pose[6] * x + pose[7] * y + pose[8] * z,
            pose[9] * x + pose[10] * y + pose[11] * z)


# --- primitive distances ---------------------------------------------------------------------
@njit(cache=True)
def _box(cf, o, x, y, z):
    # local coordinates q = R^T (x - c)
    dx, dy, dz = x - cf[o], y - cf[o + 1], z - cf[o + 2]
    r = o + 3
    qx = cf[r] * dx + cf[r + 3] * dy + cf[r + 6] * dz
    qy = cf[r + 1] * dx + cf[r + 4] * dy + cf[r + 7] * dz
    qz = cf[r + 2] * dx + cf[r + 5] * dy + cf[r + 8] * dz
    ax, ay, az = abs(qx) - cf[o + 12], abs(qy) - cf[o + 13], abs(qz) - cf[o + 14]
    ox, oy, oz = max(ax, 0.0), max(ay, 0.0), max(az, 0.0)
    outside = math.sqrt(ox * ox + oy * oy + oz * oz)
    if outside > 0.0:
        d = outside
        lx = math.copysign(ox, qx) / outside
        ly = math.copysign(oy, qy) / outside
        lz = math.copysign(oz, qz) / outside
    else:
        # inside: the nearest face is the one with the largest (least negative) a
        d = max(ax, max(ay, az))
        lx = ly = lz = 0.0
        if ax >= ay and ax >= az:
            lx = 1.0 if qx >= 0.0 else -1.0
        elif ay >= az:
            ly = 1.0 if qy >= 0.0 else -1.0
        else:
            lz = 1.0 if qz >= 0.0 else -1.0
    gx = cf[r] * lx + cf[r + 1] * ly + cf[r + 2] * lz
    gy = cf[r + 3] * lx + cf[r + 4] * ly + cf[r + 5] * lz
    gz = cf[r + 6] * lx + cf[r + 7] * ly + cf[r + 8] * lz
    return d, gx, gy, gz


@njit(cache=True)
def _capsule(cf, o, x, y, z):
    ax, ay, az = cf[o], cf[o + 1], cf[o + 2]
    ux, uy, uz = cf[o + 3] - ax, cf[o + 4] - ay, cf[o + 5] - az
    wx, wy, wz = x - ax, y - ay, z - az
    uu = ux * ux + uy * uy + uz * uz
    s = 0.0 if uu == 0.0 else min(1.0, max(0.0, (wx * ux + wy * uy + wz * uz) / uu))
    rx, ry, rz = wx - s * ux, wy - s * uy, wz - s * uz
    dist = math.sqrt(rx * rx + ry * ry + rz * rz)
    if dist > 0.0:
        return dist - cf[o + 6], rx / dist, ry / dist, rz / dist
    # on the axis: any direction perpendicular to it
    px, py, pz = _perpendicular(ux, uy, uz)
    return -cf[o + 6], px, py, pz


@njit(cache=True)
def _perpendicular(ux, uy, uz):
    # a unit vector perpendicular to u, stable for any u (including u = 0)
    if abs(ux) <= abs(uy) and abs(ux) <= abs(uz):
        px, py, pz = 0.0, -uz, uy
    elif abs(uy) <= abs(uz):
        px, py, pz = uz, 0.0, -ux
    else:
        px, py, pz = -uy, ux, 0.0
    n = math.sqrt(px * px + py * py + pz * pz)
    if n == 0.0:
        return 0.0, 0.0, 1.0
    return px / n, py / n, pz / n


@njit(cache=True)
def _cylinder(cf, o, x, y, z):
    dx, dy, dz = x - cf[o], y - cf[o + 1], z - cf[o + 2]
    ux, uy, uz = cf[o + 3], cf[o + 4], cf[o + 5]
    h = dx * ux + dy * uy + dz * uz
    wx, wy, wz = dx - h * ux, dy - h * uy, dz - h * uz
    rho = math.sqrt(wx * wx + wy * wy + wz * wz)
    if rho > 0.0:
        ex, ey, ez = wx / rho, wy / rho, wz / rho
    else:
        ex, ey, ez = _perpendicular(ux, uy, uz)
    sgn = 1.0 if h >= 0.0 else -1.0
    dr = rho - cf[o + 6]
    dh = abs(h) - cf[o + 7]
    if dr > 0.0 and dh > 0.0:
        # outside past the rim: distance to the rim circle
        d = math.sqrt(dr * dr + dh * dh)
        return d, (dr * ex + dh * sgn * ux) / d, (dr * ey + dh * sgn * uy) / d, (dr * ez + dh * sgn * uz) / d
    if dr > dh:
        return dr, ex, ey, ez
    return dh, sgn * ux, sgn * uy, sgn * uz


@njit(cache=True)
def _container(cf, ci, o, io, x, y, z):
    m = ci[io]
    best = BIG
    gx = gy = gz = 0.0
    for i in range(m):
        b = o + 4 * i
        d = cf[b] * x + cf[b + 1] * y + cf[b + 2] * z - cf[b + 3]
        if d < best:
            best, gx, gy, gz = d, cf[b], cf[b + 1], cf[b + 2]
    return best, gx, gy, gz


@njit(cache=True)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle abc to p (Ericson 5.1.5)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w



@njit(cache=True)
def _mesh_exact(cf, ci, o, io, x, y, z):
    """Exact distance to the triangles registered in the triangle-grid cell of (x, y, z).

    Every triangle within the grid margin of the cell is registered there, so a distance below
    the margin is the true one. Returns (found, unsigned distance, unit direction away from the
    surface, side): side = sign((p - q).n) of the closest triangle (ties: the most face-aligned).
    """
    h = cf[o + G_TGH]
    nx, ny, nz = ci[io + GI_TGN], ci[io + GI_TGN + 1], ci[io + GI_TGN + 2]
    i = int(math.floor((x - cf[o + G_TGORIGIN]) / h))
    j = int(math.floor((y - cf[o + G_TGORIGIN + 1]) / h))
    k = int(math.floor((z - cf[o + G_TGORIGIN + 2]) / h))
    if i < 0 or j < 0 or k < 0 or i >= nx or j >= ny or k >= nz:
        return False, 0.0, 0.0, 0.0, 1.0, 1.0
    cell = (i * ny + j) * nz + k
    start = io + ci[io + GI_TSTART]
    items = io + ci[io + GI_TITEMS]
    faces = io + ci[io + GI_FACES]
    vert = o + ci[io + GI_VERT]
    tnorm = o + ci[io + GI_TNORM]
    best = cf[o + G_MARGIN]
    best2 = best * best
    align = -1.0
    found = False
    bx = by = 0.0
    bz = 1.0
    side = 1.0
    for q in range(ci[start + cell], ci[start + cell + 1]):
        t = ci[items + q]
        a = vert + 3 * ci[faces + 3 * t]
        b = vert + 3 * ci[faces + 3 * t + 1]
        c = vert + 3 * ci[faces + 3 * t + 2]
        qx, qy, qz = closest_on_triangle(x, y, z, cf[a], cf[a + 1], cf[a + 2], cf[b], cf[b + 1], cf[b + 2],
                                         cf[c], cf[c + 1], cf[c + 2])
        rx, ry, rz = x - qx, y - qy, z - qz
        d2 = rx * rx + ry * ry + rz * rz
        if d2 > best2 * (1.0 + 1e-12) + 1e-300:
            continue
        tn = tnorm + 3 * t
        dn = rx * cf[tn] + ry * cf[tn + 1] + rz * cf[tn + 2]
        dist = math.sqrt(d2)
        al = abs(dn) / dist if dist > 0.0 else 1.0
        if d2 < best2 * (1.0 - 1e-12) or al > align:
            best2, align, found = d2, al, True
            if dist > 0.0:
                bx, by, bz = rx / dist, ry / dist, rz / dist
            else:
                bx, by, bz = cf[tn], cf[tn + 1], cf[tn + 2]
            side = 1.0 if dn >= 0.0 else -1.0
    return found, math.sqrt(best2), bx, by, bz, side


# --- sampled grid ----------------------------------------------------------------------------
@njit(cache=True)
def grid_sample(cf, ci, o, io, x, y, z):
    """Trilinear value and gradient of a GRID shape; outside the grid, the distance to the
    shape's bounding box (a lower bound). Returns (value, gx, gy, gz, inside_grid)."""
    nx, ny, nz = ci[io + GI_N], ci[io + GI_N + 1], ci[io + GI_N + 2]
    h = cf[o + G_H]
    fx = (x - cf[o + G_ORIGIN]) / h
    fy = (y - cf[o + G_ORIGIN + 1]) / h
    fz = (z - cf[o + G_ORIGIN + 2]) / h if nz > 1 else 0.0
    if fx < 0.0 or fy < 0.0 or fz < 0.0 or fx > nx - 1 or fy > ny - 1 or fz > nz - 1:
        # distance to the shape's bounding box, gradient pointing away from it
        qx = min(max(x, cf[o + G_BMIN]), cf[o + G_BMAX])
        qy = min(max(y, cf[o + G_BMIN + 1]), cf[o + G_BMAX + 1])
        qz = min(max(z, cf[o + G_BMIN + 2]), cf[o + G_BMAX + 2]) if nz > 1 else z
        rx, ry, rz = x - qx, y - qy, z - qz
        d = math.sqrt(rx * rx + ry * ry + rz * rz)
        if d == 0.0:
            return 0.0, 0.0, 0.0, 1.0, False
        return d, rx / d, ry / d, rz / d, False
    i = min(int(fx), nx - 2)
    j = min(int(fy), ny - 2)
    k = min(int(fz), nz - 2) if nz > 1 else 0
    tx, ty, tz = fx - i, fy - j, fz - k
    vals = o + ci[io + GI_VAL]
    sy, sz = nz, ny * nz  # value index = (i * ny + j) * nz + k
    base = vals + (i * ny + j) * nz + k
    if nz > 1:
        c000, c001 = cf[base], cf[base + 1]
        c010, c011 = cf[base + sy], cf[base + sy + 1]
        c100, c101 = cf[base + sz], cf[base + sz + 1]
        c110, c111 = cf[base + sz + sy], cf[base + sz + sy + 1]
    else:
        c000 = c001 = cf[base]
        c010 = c011 = cf[base + sy]
        c100 = c101 = cf[base + sz]
        c110 = c111 = cf[base + sz + sy]
    # interpolate along z, then y, then x; derivatives of the trilinear interpolant
    c00 = c000 + tz * (c001 - c000)
    c01 = c010 + tz * (c011 - c010)
    c10 = c100 + tz * (c101 - c100)
    c11 = c110 + tz * (c111 - c110)
    c0 = c00 + ty * (c01 - c00)
    c1 = c10 + ty * (c11 - c10)
    value = c0 + tx * (c1 - c0)
    dvx = (c1 - c0) / h
    dvy = ((1.0 - tx) * (c01 - c00) + tx * (c11 - c10)) / h
    if nz > 1:
        d0 = (1.0 - ty) * (c001 - c000) + ty * (c011 - c010)
        d1 = (1.0 - ty) * (c101 - c100) + ty * (c111 - c110)
        dvz = ((1.0 - tx) * d0 + tx * d1) / h
    else:
        dvz = 0.0
    g = math.sqrt(dvx * dvx + dvy * dvy + dvz * dvz)
    if g > 0.0:
        return value, dvx / g, dvy / g, dvz / g, True
    return value, 0.0, 0.0, 1.0, True


@njit(cache=True)
def _grid(cf, ci, o, io, x, y, z):
    value, gx, gy, gz, inside = grid_sample(cf, ci, o, io, x, y, z)
    if not inside:
        # outside the grid: phi(c) + |x - c| at the nearest grid point c (exact along the
        # grid's face normals, an upper bound otherwise)
        nx, ny, nz = ci[io + GI_N], ci[io + GI_N + 1], ci[io + GI_N + 2]
        h = cf[o + G_H]
        cx = min(max(x, cf[o + G_ORIGIN]), cf[o + G_ORIGIN] + (nx - 1) * h)
        cy = min(max(y, cf[o + G_ORIGIN + 1]), cf[o + G_ORIGIN + 1] + (ny - 1) * h)
        cz = min(max(z, cf[o + G_ORIGIN + 2]), cf[o + G_ORIGIN + 2] + (nz - 1) * h) if nz > 1 else z
        vc, gcx, gcy, gcz, _in = grid_sample(cf, ci, o, io, cx, cy, cz)
        if ci[io + GI_SIGNED] == 0:
            vc = abs(vc) - cf[o + G_THICK]
        rx, ry, rz = x - cx, y - cy, z - cz
        out = math.sqrt(rx * rx + ry * ry + rz * rz)
        if out == 0.0:
            return vc, gcx, gcy, gcz
        gx, gy, gz = rx / out + gcx, ry / out + gcy, rz / out + gcz
        g = math.sqrt(gx * gx + gy * gy + gz * gz)
        if g == 0.0:
            return vc + out, rx / out, ry / out, rz / out
        return vc + out, gx / g, gy / g, gz / g
    if inside and ci[io + GI_HASTRI] != 0 and abs(value) < cf[o + G_MARGIN] + 2.0 * cf[o + G_H]:
        # near a mesh: the exact distance to its triangles (the grid smooths thin features)
        found, dist, ux, uy, uz, side = _mesh_exact(cf, ci, o, io, x, y, z)
        if found:
            if ci[io + GI_SIGNED] == 0:
                return dist - cf[o + G_THICK], ux, uy, uz
            if dist == 0.0:
                return 0.0, ux, uy, uz
            return side * dist, side * ux, side * uy, side * uz
    if inside and ci[io + GI_SIGNED] == 0:
        # unsigned field of an open surface (a sheet): a shell of half-thickness `thickness`
        if value < 0.0:
            value, gx, gy, gz = -value, -gx, -gy, -gz
        value -= cf[o + G_THICK]
    return value, gx, gy, gz


# --- dispatch --------------------------------------------------------------------------------
# A kind set is passed to the collision kernels as a tuple ``kinds`` of GRID + 1 entries, True
# for a kind the scene uses and None for one it does not (``kinds_token``). Numba types that
# tuple by which entries are None, so each kind set is its own compiled signature, and the
# dispatchers below (``sdf_in``, ``lower_bound_in``) are generated per kind set at typing time
# with the branches of absent kinds removed before they are compiled: a scene of planes
# compiles no box, capsule, cylinder, container or grid code into its kernels (the grid and
# mesh distances are most of the collision kernels' compile time). ``ALL_KINDS`` keeps every
# branch (the generic ``sdf`` / ``distance_lower_bound``); every kind set computes the same bits.
ALL_KINDS = (True,) * (GRID + 1)


def kinds_token(kinds) -> tuple:
    """The ``kinds`` argument of the collision kernels for a collection of kind codes (CALLABLE
    and unknown codes are ignored: the kernels skip CALLABLE rows)."""
    present = {int(k) for k in kinds}
    return tuple(True if k in present else None for k in range(GRID + 1))


def _present(kinds):
    """Which kinds a ``kinds`` token type holds (typing time), as GRID + 1 booleans."""
    if not isinstance(kinds, types.BaseTuple) or len(kinds.types) != GRID + 1:
        raise TypeError(f"kinds must be a tuple of {GRID + 1} entries (True or None); see kinds_token")
    return tuple(not isinstance(t, (types.NoneType, types.Omitted)) for t in kinds.types)


def sdf_in(kinds, kind, cf, o, ci, io, x, y, z):
    """Signed distance and unit outward normal (gradient) of one packed shape at a rest point,
    compiled for the kind set ``kinds`` only (Numba; shapes of other kinds give BIG, like
    CALLABLE)."""
    raise NotImplementedError("sdf_in runs inside Numba kernels only")


@overload(sdf_in, jit_options={"cache": True})
def _sdf_in(kinds, kind, cf, o, ci, io, x, y, z):
    has_plane, has_sphere, has_box, has_capsule, has_cylinder, has_container, has_grid = _present(kinds)

    def impl(kinds, kind, cf, o, ci, io, x, y, z):
        if has_plane:
            if kind == PLANE:
                return cf[o] * x + cf[o + 1] * y + cf[o + 2] * z - cf[o + 3], cf[o], cf[o + 1], cf[o + 2]
        if has_sphere:
            if kind == SPHERE:
                rx, ry, rz = x - cf[o], y - cf[o + 1], z - cf[o + 2]
                dist = math.sqrt(rx * rx + ry * ry + rz * rz)
                if dist > 0.0:
                    return dist - cf[o + 3], rx / dist, ry / dist, rz / dist
                return -cf[o + 3], 0.0, 0.0, 1.0
        if has_box:
            if kind == BOX:
                return _box(cf, o, x, y, z)
        if has_capsule:
            if kind == CAPSULE:
                return _capsule(cf, o, x, y, z)
        if has_cylinder:
            if kind == CYLINDER:
                return _cylinder(cf, o, x, y, z)
        if has_container:
            if kind == CONTAINER:
                return _container(cf, ci, o, io, x, y, z)
        if has_grid:
            if kind == GRID:
                return _grid(cf, ci, o, io, x, y, z)
        return BIG, 0.0, 0.0, 1.0  # CALLABLE shapes are evaluated outside the kernels

    return impl


def lower_bound_in(kinds, kind, cf, o, ci, io, x, y, z):
    """``distance_lower_bound`` compiled for the kind set ``kinds`` only (Numba)."""
    raise NotImplementedError("lower_bound_in runs inside Numba kernels only")


@overload(lower_bound_in, jit_options={"cache": True})
def _lower_bound_in(kinds, kind, cf, o, ci, io, x, y, z):
    has_grid = _present(kinds)[GRID]

    def impl(kinds, kind, cf, o, ci, io, x, y, z):
        if has_grid:
            if kind == GRID:
                value, gx, gy, gz, inside = grid_sample(cf, ci, o, io, x, y, z)
                if not inside:
                    return value - cf[o + G_THICK]
                if ci[io + GI_HASTRI] != 0 and abs(value) < cf[o + G_MARGIN] + 2.0 * cf[o + G_H]:
                    d, gx, gy, gz = _grid(cf, ci, o, io, x, y, z)  # exact near the triangles
                    return abs(d)
                return abs(value) - cf[o + G_H] * 1.7320508075688772 - cf[o + G_THICK]
        d, gx, gy, gz = sdf_in(kinds, kind, cf, o, ci, io, x, y, z)
        return abs(d)

    return impl


@njit(cache=True)
def sdf(kind, cf, o, ci, io, x, y, z):
    """Signed distance and unit outward normal (gradient) of one packed shape at a rest point."""
    return sdf_in(ALL_KINDS, kind, cf, o, ci, io, x, y, z)


@njit(cache=True)
def distance_lower_bound(kind, cf, o, ci, io, x, y, z):
    """A lower bound of the distance from a rest point to the shape's surface, used to reject
    segments that cannot reach it: exact |d| for the analytic shapes, |d| - h sqrt(3) for grids
    (each grid sample is within |x - node| of the true value, and interpolation averages them)."""
    return lower_bound_in(ALL_KINDS, kind, cf, o, ci, io, x, y, z)


# Elements of ``points`` below which ``query_points`` runs its serial twin: the threshold the
# curl-noise kernels measured (``fields/kernels.py``, 8,192 3-D points), since a query per point
# costs about as much as a noise sample (grids and meshes more) and curl-noise boundaries are
# its main caller. Never above ``inertia._jit.SERIAL_BELOW``.
QUERY_SERIAL_BELOW = 24576


@parallel_kernel(serial_below=QUERY_SERIAL_BELOW)
def query_points(points, kinds, kind, cf, ci, pose, ref, moving, lin_vel, ang_vel, distance_out,
                 normal_out, velocity_out):
    """Distance, outward normal and surface velocity of one collider at many world points.

    points (M, D); kinds: ``kinds_token((kind,))`` (only that kind's distance is compiled; a
    kind set holding ``kind`` gives the same bits); pose (12,) = [p, R] at the query time;
    lin_vel (3,) velocity of the reference point; ang_vel (3,) angular velocity; outputs (M,),
    (M, D), (M, D). Calls from Python run the serial twin below ``QUERY_SERIAL_BELOW`` points
    (same bits: each point is written by one iteration).
    """
    m, dim = points.shape
    for i in prange(m):
        x = points[i, 0]
        y = points[i, 1]
        z = points[i, 2] if dim == 3 else 0.0
        if moving:
            lx, ly, lz = to_rest(pose, ref, x, y, z)
        else:
            lx, ly, lz = x, y, z
        d, gx, gy, gz = sdf_in(kinds, kind, cf, 0, ci, 0, lx, ly, lz)
        if moving:
            gx, gy, gz = rotate(pose, gx, gy, gz)
        distance_out[i] = d
        # surface velocity v_p + w x (x - p)
        rx, ry, rz = x - pose[0], y - pose[1], z - pose[2]
        vx = lin_vel[0] + ang_vel[1] * rz - ang_vel[2] * ry
        vy = lin_vel[1] + ang_vel[2] * rx - ang_vel[0] * rz
        vz = lin_vel[2] + ang_vel[0] * ry - ang_vel[1] * rx
        normal_out[i, 0] = gx
        normal_out[i, 1] = gy
        velocity_out[i, 0] = vx
        velocity_out[i, 1] = vy
        if dim == 3:
            normal_out[i, 2] = gz
            velocity_out[i, 2] = vz
