"""Time of impact of a particle's straight path with a collider (continuous detection).

Within a step the particle moves from ``s`` to ``e`` (rest frame of the collider; a moving
collider is handled by mapping the start through the collider's pose at the start of the
segment and the end through its pose at the end, which is exact for translations). The path
is ``l(sigma) = s + sigma (e - s)``, sigma in [0, 1], and the contact function is
``f(sigma) = phi(l(sigma)) - r`` (phi the signed distance, r the particle radius). The time of
impact is the first sigma with ``f <= tol``.

- Convex shapes (plane, sphere, box, capsule, cylinder): phi of a convex set is a convex
  function, so f is convex along the line and Newton's iteration started left of the first
  root never overshoots it (the tangent of a convex function lies below it). Planes and box
  faces converge in one step; a non-negative slope proves there is no root ahead. This cannot
  tunnel: thin boxes, at any speed, are found.
- Containers (an intersection of half-spaces): f is the minimum of linear functions, so the
  first root is the smallest root of the planes that are approached; exact.
- Meshes: exact segment-triangle tests (each triangle's plane offset by r towards the side the
  segment starts on), visiting only the triangle-grid cells the segment crosses
  (Amanatides & Woo 1987). A single sheet is never crossed.
- Baked SDF grids without triangles: conservative advancement (sphere tracing, Hart 1996) with
  steps of 0.9 f, at most ``max_iter`` steps (then the search stops conservatively there).

References
----------
- Mirtich, B. (1996), *Impulse-based dynamic simulation of rigid body systems*, PhD thesis,
  UC Berkeley: conservative advancement for time of impact.
- Hart, J. C. (1996), "Sphere tracing", The Visual Computer 12(10).
- Redon, S., Kheddar, A. & Coquillart, S. (2002), "Fast continuous collision detection between
  rigid bodies", Eurographics: straight-line (interpolated) motion within a step.
- Moller, T. & Trumbore, B. (1997), "Fast, minimum storage ray-triangle intersection", JGT 2(1).
- Amanatides, J. & Woo, A. (1987), "A fast voxel traversal algorithm for ray tracing".

From the chord to the time of impact (``path_fraction``)
--------------------------------------------------------
The chord finds *whether* and *where* the particle meets a surface; the *time* of the impact
comes from the particle's path. Over a step (or the rest of it, length H) the collision stage
takes the path as the parabola with the step's average acceleration a through the integrator's
start and end points, ``p(tau) = s + tau (e - s) - a H^2 tau (1 - tau) / 2`` (tau the fraction of
the time step; exact for constant forces with every integrator: the positions of explicit and
symplectic Euler lie on such a parabola too, with a start slope that differs from their stored
velocity by -+ a h / 2). Near the chord's hit point (fraction sigma, normal n) the surface is
its tangent plane, so the contact function along the path is the quadratic

    F(tau) = L (tau - sigma) - A tau (1 - tau),   L = n.(e - s),  A = n.a H^2 / 2,

with F(0) = -L sigma >= 0 and F(1) = L (1 - sigma) <= 0: the time of impact is its first root
in [0, 1] at which the path goes in (exact for planes and container walls; second order in the
chord's deviation a H^2 / 8 for curved surfaces). Taking sigma itself as the time puts the
impact early when the acceleration points into the surface and the impact speed too low, by
a few per cent at the speeds where a bouncing particle comes to rest.

Limitations
-----------
- Detection follows the straight chord from start to end, not the curved trajectory (the
  parabola lies within |a| H^2 / 8 of it: 3.4 um for gravity at dt = 1/600 s); a collider
  rotating during the step is linearised (error O(angle^2) per step).
- Mesh triangle tests do not round the offset triangles' edges: a sphere may clip a mesh edge
  by up to its radius within a step (the end-of-step projection then pushes it out).
- Baked SDFs without triangles can miss features thinner than a grid cell.
"""

from __future__ import annotations

import math

from numba import njit
from numba.extending import overload

from . import distance as _d


@njit(cache=True)
def _convex_toi(kinds, kind, cf, o, ci, io, sx, sy, sz, lx, ly, lz, r, tol, max_iter):
    # f(sigma) = phi(s + sigma L) - r, convex; Newton from the left never passes the first root
    f, gx, gy, gz = _d.sdf_in(kinds, kind, cf, o, ci, io, sx, sy, sz)
    f -= r
    slope = gx * lx + gy * ly + gz * lz
    if f <= tol:
        # already touching: a hit only if the path goes in by more than the tolerance
        if slope < -tol:
            return True, 0.0, gx, gy, gz
        return False, 0.0, gx, gy, gz
    sigma = 0.0
    for _ in range(max_iter):
        if slope >= 0.0:
            return False, 0.0, gx, gy, gz  # convex and not decreasing: no root ahead
        sigma += f / (-slope)
        if sigma > 1.0:
            return False, 0.0, gx, gy, gz
        f, gx, gy, gz = _d.sdf_in(kinds, kind, cf, o, ci, io, sx + sigma * lx, sy + sigma * ly, sz + sigma * lz)
        f -= r
        slope = gx * lx + gy * ly + gz * lz
        if f <= tol:
            return True, sigma, gx, gy, gz
    return True, sigma, gx, gy, gz  # iteration cap (grazing): stop conservatively here


@njit(cache=True)
def _container_toi(cf, ci, o, io, sx, sy, sz, lx, ly, lz, r, tol):
    # f = min_i (a_i + b_i sigma): the first root is the smallest root of an approached plane
    best = 2.0
    bx = by = bz = 0.0
    for i in range(ci[io]):
        b = o + 4 * i
        nx, ny, nz = cf[b], cf[b + 1], cf[b + 2]
        a = nx * sx + ny * sy + nz * sz - cf[b + 3] - r
        slope = nx * lx + ny * ly + nz * lz
        if a <= tol:
            if slope < -tol and 0.0 < best:
                best, bx, by, bz = 0.0, nx, ny, nz
            continue
        if slope < 0.0:
            sigma = a / (-slope)
            if sigma < best:
                best, bx, by, bz = sigma, nx, ny, nz
    return best <= 1.0, best, bx, by, bz


@njit(cache=True)
def _triangle_hit(cf, ci, o, io, t, sx, sy, sz, lx, ly, lz, rr, tol):
    """Segment vs triangle t offset by rr towards the start side: (sigma or 2.0, normal)."""
    tnorm = o + ci[io + _d.GI_TNORM] + 3 * t
    nx, ny, nz = cf[tnorm], cf[tnorm + 1], cf[tnorm + 2]
    if nx == 0.0 and ny == 0.0 and nz == 0.0:
        return 2.0, 0.0, 0.0, 0.0  # degenerate triangle
    faces = io + ci[io + _d.GI_FACES] + 3 * t
    vert = o + ci[io + _d.GI_VERT]
    a, b, c = vert + 3 * ci[faces], vert + 3 * ci[faces + 1], vert + 3 * ci[faces + 2]
    ax, ay, az = cf[a], cf[a + 1], cf[a + 2]
    ds = nx * (sx - ax) + ny * (sy - ay) + nz * (sz - az)
    de = ds + nx * lx + ny * ly + nz * lz
    side = 1.0 if ds >= 0.0 else -1.0
    fs = side * ds - rr  # distance to the offset plane, positive on the start side
    fe = side * de - rr
    if fe >= 0.0 or fe >= fs:
        return 2.0, 0.0, 0.0, 0.0  # does not go through the offset plane
    # stop half a tolerance before the offset plane, so that the contact point is strictly on
    # the start side (an unsigned sheet has no inside to tell the sides apart later)
    sigma = max(0.0, (fs - 0.5 * tol) / (fs - fe))
    # crossing point projected onto the triangle's plane; barycentric inside test
    px = sx + sigma * lx - ax
    py = sy + sigma * ly - ay
    pz = sz + sigma * lz - az
    dn = nx * px + ny * py + nz * pz
    px, py, pz = px - dn * nx, py - dn * ny, pz - dn * nz
    e1x, e1y, e1z = cf[b] - ax, cf[b + 1] - ay, cf[b + 2] - az
    e2x, e2y, e2z = cf[c] - ax, cf[c + 1] - ay, cf[c + 2] - az
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d12 = e1x * e2x + e1y * e2y + e1z * e2z
    d22 = e2x * e2x + e2y * e2y + e2z * e2z
    dp1 = px * e1x + py * e1y + pz * e1z
    dp2 = px * e2x + py * e2y + pz * e2z
    den = d11 * d22 - d12 * d12
    if den <= 0.0:
        return 2.0, 0.0, 0.0, 0.0
    v = (d22 * dp1 - d12 * dp2) / den
    w = (d11 * dp2 - d12 * dp1) / den
    eps = 1e-9
    if v < -eps or w < -eps or v + w > 1.0 + eps:
        return 2.0, 0.0, 0.0, 0.0
    return sigma, side * nx, side * ny, side * nz


@njit(cache=True)
def _mesh_toi(cf, ci, o, io, sx, sy, sz, lx, ly, lz, r, tol):
    rr = min(r + cf[o + _d.G_THICK], cf[o + _d.G_MARGIN])
    h = cf[o + _d.G_TGH]
    gx0, gy0, gz0 = cf[o + _d.G_TGORIGIN], cf[o + _d.G_TGORIGIN + 1], cf[o + _d.G_TGORIGIN + 2]
    nx, ny, nz = ci[io + _d.GI_TGN], ci[io + _d.GI_TGN + 1], ci[io + _d.GI_TGN + 2]
    start = io + ci[io + _d.GI_TSTART]
    items = io + ci[io + _d.GI_TITEMS]
    # clip the segment to the triangle grid's box (slabs)
    t0, t1 = 0.0, 1.0
    for axis in range(3):
        s = sx if axis == 0 else (sy if axis == 1 else sz)
        d = lx if axis == 0 else (ly if axis == 1 else lz)
        lo = gx0 if axis == 0 else (gy0 if axis == 1 else gz0)
        n = nx if axis == 0 else (ny if axis == 1 else nz)
        hi = lo + n * h
        if d == 0.0:
            if s < lo or s > hi:
                return False, 0.0, 0.0, 0.0, 0.0
        else:
            ta, tb = (lo - s) / d, (hi - s) / d
            if ta > tb:
                ta, tb = tb, ta
            t0, t1 = max(t0, ta), min(t1, tb)
    if t0 > t1:
        return False, 0.0, 0.0, 0.0, 0.0
    # 3-D DDA over the cells the clipped segment crosses
    px, py, pz = sx + t0 * lx, sy + t0 * ly, sz + t0 * lz
    i = min(max(int(math.floor((px - gx0) / h)), 0), nx - 1)
    j = min(max(int(math.floor((py - gy0) / h)), 0), ny - 1)
    k = min(max(int(math.floor((pz - gz0) / h)), 0), nz - 1)
    inf = 1e300
    si = 1 if lx > 0 else -1
    sj = 1 if ly > 0 else -1
    sk = 1 if lz > 0 else -1
    tmx = ((gx0 + (i + (1 if si > 0 else 0)) * h) - sx) / lx if lx != 0.0 else inf
    tmy = ((gy0 + (j + (1 if sj > 0 else 0)) * h) - sy) / ly if ly != 0.0 else inf
    tmz = ((gz0 + (k + (1 if sk > 0 else 0)) * h) - sz) / lz if lz != 0.0 else inf
    tdx = h / abs(lx) if lx != 0.0 else inf
    tdy = h / abs(ly) if ly != 0.0 else inf
    tdz = h / abs(lz) if lz != 0.0 else inf
    best = 2.0
    bx = by = bz = 0.0
    for _ in range(nx + ny + nz + 3):
        cell = (i * ny + j) * nz + k
        for q in range(ci[start + cell], ci[start + cell + 1]):
            sigma, hx, hy, hz = _triangle_hit(cf, ci, o, io, ci[items + q], sx, sy, sz, lx, ly, lz, rr, tol)
            if sigma < best:
                best, bx, by, bz = sigma, hx, hy, hz
        t_exit = min(tmx, min(tmy, tmz))
        if best <= t_exit or t_exit > t1:
            break
        if tmx <= tmy and tmx <= tmz:
            i += si
            tmx += tdx
            if i < 0 or i >= nx:
                break
        elif tmy <= tmz:
            j += sj
            tmy += tdy
            if j < 0 or j >= ny:
                break
        else:
            k += sk
            tmz += tdz
            if k < 0 or k >= nz:
                break
    return best <= 1.0, best, bx, by, bz


@njit(cache=True)
def _march_toi(kinds, kind, cf, o, ci, io, sx, sy, sz, lx, ly, lz, r, tol, max_iter):
    # conservative advancement: |grad phi| <= 1, so a step of f / |L| cannot pass a root
    length = math.sqrt(lx * lx + ly * ly + lz * lz)
    sigma = 0.0
    f, gx, gy, gz = _d.sdf_in(kinds, kind, cf, o, ci, io, sx, sy, sz)
    f -= r
    if f <= tol:
        if gx * lx + gy * ly + gz * lz < -tol:
            return True, 0.0, gx, gy, gz
        return False, 0.0, gx, gy, gz
    for _ in range(max_iter):
        sigma += 0.9 * f / length
        if sigma > 1.0:
            return False, 0.0, gx, gy, gz
        f, gx, gy, gz = _d.sdf_in(kinds, kind, cf, o, ci, io, sx + sigma * lx, sy + sigma * ly, sz + sigma * lz)
        f -= r
        if f <= tol:
            return True, sigma, gx, gy, gz
    return True, sigma, gx, gy, gz


def segment_toi_in(kinds, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol, max_iter):
    """``segment_toi`` compiled for the kind set ``kinds`` only (Numba; see
    ``distance.kinds_token``)."""
    raise NotImplementedError("segment_toi_in runs inside Numba kernels only")


@overload(segment_toi_in, jit_options={"cache": True})
def _segment_toi_in(kinds, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol, max_iter):
    present = _d._present(kinds)
    has_container, has_grid = present[_d.CONTAINER], present[_d.GRID]
    has_convex = any(present[k] for k in (_d.PLANE, _d.SPHERE, _d.BOX, _d.CAPSULE, _d.CYLINDER))

    def impl(kinds, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol, max_iter):
        lx, ly, lz = ex - sx, ey - sy, ez - sz
        if lx == 0.0 and ly == 0.0 and lz == 0.0:
            return False, 0.0, 0.0, 0.0, 0.0
        if has_container:
            if kind == _d.CONTAINER:
                return _container_toi(cf, ci, o, io, sx, sy, sz, lx, ly, lz, r, tol)
        if has_grid:
            if kind == _d.GRID:
                if ci[io + _d.GI_HASTRI] != 0:
                    return _mesh_toi(cf, ci, o, io, sx, sy, sz, lx, ly, lz, r, tol)
                return _march_toi(kinds, kind, cf, o, ci, io, sx, sy, sz, lx, ly, lz, r, tol, 4 * max_iter)
        if kind == _d.CALLABLE:
            return False, 0.0, 0.0, 0.0, 0.0
        if has_convex:
            return _convex_toi(kinds, kind, cf, o, ci, io, sx, sy, sz, lx, ly, lz, r, tol, max_iter)
        return False, 0.0, 0.0, 0.0, 0.0

    return impl


@njit(cache=True)
def segment_toi(kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol, max_iter):
    """First contact of the segment s -> e (rest frame) with one shape.

    Returns (hit, sigma in [0, 1], nx, ny, nz): the unit outward normal at the contact.
    A path that starts touching (f <= tol) hits at sigma = 0 only if it heads in by more than
    ``tol`` over the segment.
    """
    return segment_toi_in(_d.ALL_KINDS, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol, max_iter)


@njit(cache=True)
def may_hit_in(kinds, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol):
    """False when the segment provably cannot come within r + tol of the surface.

    With lower bounds a, b of the surface distance at the ends and L the segment length, every
    point of the segment is at least max(a - sigma L, b - (1 - sigma) L) >= (a + b - L) / 2 from
    the surface (1-Lipschitz distance). ``kinds``: the kind set compiled in (``distance.kinds_token``)."""
    a = _d.lower_bound_in(kinds, kind, cf, o, ci, io, sx, sy, sz) - r
    b = _d.lower_bound_in(kinds, kind, cf, o, ci, io, ex, ey, ez) - r
    length = math.sqrt((ex - sx) ** 2 + (ey - sy) ** 2 + (ez - sz) ** 2)
    return a + b - length <= 2.0 * tol


@njit(cache=True)
def may_hit(kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol):
    """``may_hit_in`` for every kind."""
    return may_hit_in(_d.ALL_KINDS, kind, cf, o, ci, io, sx, sy, sz, ex, ey, ez, r, tol)


@njit(cache=True)
def path_fraction(chord_in, accel_in, sigma):
    """Time of impact, as a fraction of the (remaining) step, on the parabolic path.

    chord_in = n.(e - s) (< 0: the chord heads in), accel_in = n.a H^2 / 2, sigma = the chord's
    hit fraction (see the module docstring). Returns the first root in [0, 1] of
    F(tau) = accel_in tau^2 + (chord_in - accel_in) tau - chord_in sigma at which the path heads
    in; a path that starts on the surface moving out returns at its second root.
    """
    qa = accel_in
    qb = chord_in - accel_in
    qc = -chord_in * sigma
    if chord_in >= 0.0 or abs(qa) <= 1e-12 * abs(chord_in):
        return sigma  # no curvature (the chord is the path), or no inward chord to refine
    disc = max(qb * qb - 4.0 * qa * qc, 0.0)
    q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
    r1 = q / qa
    r2 = qc / q if q != 0.0 else r1
    lo, hi = min(r1, r2), max(r1, r2)
    eps = 1e-12
    # starting on the surface and moving out (F(0) = 0, F'(0) > 0): the root at 0 is a departure
    departing = qc == 0.0 and qb > 0.0
    if -eps <= lo <= 1.0 + eps and not (departing and lo <= eps):
        return min(max(lo, 0.0), 1.0)
    if -eps <= hi <= 1.0 + eps:
        return min(max(hi, 0.0), 1.0)
    return sigma
