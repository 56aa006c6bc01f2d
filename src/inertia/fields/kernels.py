"""Numba kernels of the fields package: gradient noise, curl-noise, grids and analytic fields.

Pure functions over arrays (inputs, then the outputs they fill, then scalars); no Python objects
and no allocation per point. The parallel kernels split the points into chunks and give each
chunk its own small scratch arrays, so nothing is allocated inside the per-point loop; they are
``inertia._jit.parallel_kernel`` objects, which run their serial twin (the same code on one
thread) for small batches, where starting threads would cost more than the work.

References
----------
- Perlin, K. (1985), "An image synthesizer", SIGGRAPH: lattice gradient noise.
- Perlin, K. (2002), "Improving noise", SIGGRAPH: the quintic fade 6t^5 - 15t^4 + 10t^3 and
  a fixed set of edge gradients (``perlin`` kind here).
- Perlin, K. (2001), "Noise hardware", SIGGRAPH course notes, and Gustavson, S. (2005/2012),
  "Simplex noise demystified": the skewed simplex lattice, D + 1 corners per point, the radial
  kernel (r^2 - |d|^2)^4 (``simplex`` kind here; r^2 = 0.5 in every dimension so that the noise
  and its derivatives are continuous).
- Bridson, R., Hourihan, J. & Nordenstam, M. (2007), "Curl-noise for procedural fluid flow",
  ACM Trans. Graph. 26(3) (SIGGRAPH): velocity as the curl of a noise potential, the boundary
  ramp and the normal-component blend of the potential near solids. The three potentials of
  3-D curl-noise share one lattice walk per octave (``potential3_block``): same lattice point,
  three gradient tables, three dot products per corner.

Notation used below: ``D`` is the dimension of the noise lattice (2, 3 or 4: the spatial
dimension plus one when time is an axis), ``S`` the spatial dimension of the points.

Limitations
-----------
- The lattice hash uses a 256-entry permutation, so every noise is periodic with period 256
  lattice cells along each axis (256 / frequency in space).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .._jit import parallel_kernel

KIND_SIMPLEX = 0
KIND_PERLIN = 1

# Floating-point contraction (FMA) and reassociation, but NaN and inf keep their IEEE meaning.
_FAST = {"contract", "reassoc", "nsz", "arcp"}

# Points per parallel chunk: large enough to amortise the chunk's scratch arrays.
_CHUNK = 1024

# Elements of the points array (M * S) below which the parallel kernels run their serial twin
# (``inertia._jit``). Measured for 3-D curl-noise (3 octaves, simplex, ~150 ns per point on one
# thread) on the shared 2-core machine with 2 threads (``benchmarks/bench_curl_noise.py
# --threshold``: serial vs parallel build, median and best of many calls): at best (a core free) the parallel
# build pays from about 1,000-2,000 points (2,048: 0.19 against 0.30 ms); under load (load
# average 11) its median call was 32-48 ms at every size up to 16,384 points against 0.08-3 ms
# serially, and still no faster at 65,536. 24,576 elements (8,192 3-D points, ~1.2 ms of work)
# keeps every small batch serial and leaves large ones parallel.
SERIAL_BELOW = 24576

# Simplex kernel radius squared: 0.5 keeps every corner's kernel inside the simplices that share
# that corner in 2-D, 3-D and 4-D, so the noise is C^2. (Gustavson's reference code uses 0.6 in
# 3-D and 4-D, which leaves small discontinuities; tests/fields/test_noise.py checks continuity.)
_SIMPLEX_R2 = 0.5


# ---------------------------------------------------------------------------------------------
# One octave of noise at one lattice point, with its gradient and (order 2) its Hessian.
# x[:D] is the point in lattice units; grad[:D] and hess[:D, :D] are filled.
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def _hash(cell, D, perm):
    """Hash of integer lattice coordinates cell[:D]: perm[c0 + perm[c1 + perm[c2 + ...]]]."""
    h = 0
    for k in range(D - 1, -1, -1):
        h = perm[(cell[k] + h) & 255]
    return h


@njit(cache=True)
def simplex_point(x, D, perm, grads, order, grad, hess, cell, x0, rank, corner, dc):
    """Simplex noise at x[:D] (unscaled: |value| <= the bound in `noise.py`).

    For every corner c of the simplex that holds x, with d = x - corner (unskewed) and
    q = r^2 - |d|^2 > 0:
        n      = sum_c q^4 (g_c . d)
        dn/dx_a = sum_c -8 q^3 d_a (g.d) + q^4 g_a
        d2n/dx_a dx_b = sum_c 48 q^2 d_a d_b (g.d) - 8 q^3 (delta_ab (g.d) + d_a g_b + d_b g_a)
    """
    # Skew x onto the hypercubic lattice to find the cell: F = (sqrt(D+1) - 1) / D.
    F = (math.sqrt(D + 1.0) - 1.0) / D
    G = (1.0 - 1.0 / math.sqrt(D + 1.0)) / D
    s = 0.0
    for k in range(D):
        s += x[k]
    s *= F
    tsum = 0.0
    for k in range(D):
        cell[k] = np.int64(math.floor(x[k] + s))
        tsum += cell[k]
    tsum *= G
    # Position relative to the cell origin in unskewed space.
    for k in range(D):
        x0[k] = x[k] - (cell[k] - tsum)
    # Rank of each coordinate (0 = largest): corner c adds 1 along the c largest axes.
    for k in range(D):
        r = 0
        for j in range(D):
            if x0[j] > x0[k] or (x0[j] == x0[k] and j < k):
                r += 1
        rank[k] = r
    for k in range(D):
        grad[k] = 0.0
        if order >= 2:
            for j in range(D):
                hess[k, j] = 0.0
    value = 0.0
    ng = grads.shape[0]
    for c in range(D + 1):
        q = _SIMPLEX_R2
        for k in range(D):
            o = 1 if rank[k] < c else 0
            corner[k] = cell[k] + o
            dc[k] = x0[k] - o + c * G
            q -= dc[k] * dc[k]
        if q <= 0.0:
            continue
        gi = _hash(corner, D, perm) % ng
        gd = 0.0
        for k in range(D):
            gd += grads[gi, k] * dc[k]
        q2 = q * q
        q3 = q2 * q
        q4 = q2 * q2
        value += q4 * gd
        if order >= 1:
            for a in range(D):
                grad[a] += -8.0 * q3 * dc[a] * gd + q4 * grads[gi, a]
        if order >= 2:
            for a in range(D):
                for b in range(D):
                    h = 48.0 * q2 * dc[a] * dc[b] * gd - 8.0 * q3 * (
                        dc[a] * grads[gi, b] + dc[b] * grads[gi, a])
                    if a == b:
                        h -= 8.0 * q3 * gd
                    hess[a, b] += h
    return value


# ---------------------------------------------------------------------------------------------
# Unrolled simplex noise with gradient (the hot path of curl-noise). Same lattice, hash, ranks
# (ties go to the lower axis) and kernel as `simplex_point`, so the two agree to rounding.
# ---------------------------------------------------------------------------------------------

@njit(cache=True, fastmath=_FAST, inline="always")
def _corner_term(q, gd):
    # Returns q^4 (g.d) and -8 q^3 (g.d): value and the factor of d in the gradient.
    q2 = q * q
    return q2 * q2 * gd, -8.0 * q2 * q * gd, q2 * q2


@njit(cache=True, fastmath=_FAST, inline="always")
def simplex2_grad(x, y, perm, grads):
    """2-D simplex noise and gradient: (n, dn/dx, dn/dy)."""
    F2 = 0.3660254037844386  # (sqrt(3) - 1) / 2
    G2 = 0.21132486540518713  # (3 - sqrt(3)) / 6
    s = (x + y) * F2
    fi = math.floor(x + s)
    fj = math.floor(y + s)
    t = (fi + fj) * G2
    x0 = x - (fi - t)
    y0 = y - (fj - t)
    i = np.int64(fi) & 255
    j = np.int64(fj) & 255
    if x0 >= y0:
        i1, j1 = 1, 0
    else:
        i1, j1 = 0, 1
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    for c in range(3):
        if c == 0:
            dx, dy, oi, oj = x0, y0, 0, 0
        elif c == 1:
            dx, dy, oi, oj = x0 - i1 + G2, y0 - j1 + G2, i1, j1
        else:
            dx, dy, oi, oj = x0 - 1.0 + 2.0 * G2, y0 - 1.0 + 2.0 * G2, 1, 1
        q = _SIMPLEX_R2 - dx * dx - dy * dy
        if q > 0.0:
            h = perm[i + oi + perm[j + oj]] & m
            ax = grads[h, 0]
            ay = grads[h, 1]
            v, f, q4 = _corner_term(q, ax * dx + ay * dy)
            n += v
            gx += f * dx + q4 * ax
            gy += f * dy + q4 * ay
    return n, gx, gy


@njit(cache=True, fastmath=_FAST, inline="always")
def simplex3_grad(x, y, z, perm, grads):
    """3-D simplex noise and gradient: (n, dn/dx, dn/dy, dn/dz)."""
    F3 = 1.0 / 3.0
    G3 = 1.0 / 6.0
    s = (x + y + z) * F3
    fi = math.floor(x + s)
    fj = math.floor(y + s)
    fk = math.floor(z + s)
    t = (fi + fj + fk) * G3
    x0 = x - (fi - t)
    y0 = y - (fj - t)
    z0 = z - (fk - t)
    i = np.int64(fi) & 255
    j = np.int64(fj) & 255
    k = np.int64(fk) & 255
    # Ranks (0 = largest coordinate; ties to the lower axis).
    rx = (1 if y0 > x0 else 0) + (1 if z0 > x0 else 0)
    ry = (1 if x0 >= y0 else 0) + (1 if z0 > y0 else 0)
    rz = (1 if x0 >= z0 else 0) + (1 if y0 >= z0 else 0)
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for c in range(4):
        oi = 1 if rx < c else 0
        oj = 1 if ry < c else 0
        ok = 1 if rz < c else 0
        dx = x0 - oi + c * G3
        dy = y0 - oj + c * G3
        dz = z0 - ok + c * G3
        q = _SIMPLEX_R2 - dx * dx - dy * dy - dz * dz
        if q > 0.0:
            h = perm[i + oi + perm[j + oj + perm[k + ok]]] & m
            ax = grads[h, 0]
            ay = grads[h, 1]
            az = grads[h, 2]
            v, f, q4 = _corner_term(q, ax * dx + ay * dy + az * dz)
            n += v
            gx += f * dx + q4 * ax
            gy += f * dy + q4 * ay
            gz += f * dz + q4 * az
    return n, gx, gy, gz


@njit(cache=True, fastmath=_FAST, inline="always")
def simplex4_grad(x, y, z, w, perm, grads):
    """4-D simplex noise and gradient: (n, dn/dx, dn/dy, dn/dz, dn/dw)."""
    F4 = 0.30901699437494745  # (sqrt(5) - 1) / 4
    G4 = 0.1381966011250105  # (5 - sqrt(5)) / 20
    s = (x + y + z + w) * F4
    fi = math.floor(x + s)
    fj = math.floor(y + s)
    fk = math.floor(z + s)
    fl = math.floor(w + s)
    t = (fi + fj + fk + fl) * G4
    x0 = x - (fi - t)
    y0 = y - (fj - t)
    z0 = z - (fk - t)
    w0 = w - (fl - t)
    i = np.int64(fi) & 255
    j = np.int64(fj) & 255
    k = np.int64(fk) & 255
    l = np.int64(fl) & 255
    rx = (1 if y0 > x0 else 0) + (1 if z0 > x0 else 0) + (1 if w0 > x0 else 0)
    ry = (1 if x0 >= y0 else 0) + (1 if z0 > y0 else 0) + (1 if w0 > y0 else 0)
    rz = (1 if x0 >= z0 else 0) + (1 if y0 >= z0 else 0) + (1 if w0 > z0 else 0)
    rw = (1 if x0 >= w0 else 0) + (1 if y0 >= w0 else 0) + (1 if z0 >= w0 else 0)
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    gw = 0.0
    for c in range(5):
        oi = 1 if rx < c else 0
        oj = 1 if ry < c else 0
        ok = 1 if rz < c else 0
        ol = 1 if rw < c else 0
        dx = x0 - oi + c * G4
        dy = y0 - oj + c * G4
        dz = z0 - ok + c * G4
        dw = w0 - ol + c * G4
        q = _SIMPLEX_R2 - dx * dx - dy * dy - dz * dz - dw * dw
        if q > 0.0:
            h = perm[i + oi + perm[j + oj + perm[k + ok + perm[l + ol]]]] & m
            ax = grads[h, 0]
            ay = grads[h, 1]
            az = grads[h, 2]
            aw = grads[h, 3]
            v, f, q4 = _corner_term(q, ax * dx + ay * dy + az * dz + aw * dw)
            n += v
            gx += f * dx + q4 * ax
            gy += f * dy + q4 * ay
            gz += f * dz + q4 * az
            gw += f * dw + q4 * aw
    return n, gx, gy, gz, gw


@njit(cache=True, fastmath=_FAST)
def _fade(f):
    # s(f) = 6 f^5 - 15 f^4 + 10 f^3, s' = 30 f^2 (f - 1)^2, s'' = 60 f (2f - 1)(f - 1)
    s = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    ds = 30.0 * f * f * (f - 1.0) * (f - 1.0)
    dds = 60.0 * f * (2.0 * f - 1.0) * (f - 1.0)
    return s, ds, dds


@njit(cache=True)
def perlin_point(x, D, perm, grads, order, grad, hess, cell, frac, w, corner, dc):
    """Improved Perlin noise at x[:D] (unscaled). `w` is a (3, 4) scratch: fade weights.

    With f = x - floor(x) and, per axis, w_k = s(f_k) for corners at +1 and 1 - s(f_k) at 0,
    n = sum_corners (prod_k w_k) (g . (f - corner)); derivatives by the product rule.
    """
    for k in range(D):
        fl = math.floor(x[k])
        cell[k] = np.int64(fl)
        frac[k] = x[k] - fl
        s, ds, dds = _fade(frac[k])
        w[0, k] = s
        w[1, k] = ds
        w[2, k] = dds
        grad[k] = 0.0
        if order >= 2:
            for j in range(D):
                hess[k, j] = 0.0
    value = 0.0
    ng = grads.shape[0]
    for bits in range(1 << D):
        for k in range(D):
            o = (bits >> k) & 1
            corner[k] = cell[k] + o
            dc[k] = frac[k] - o
        gi = _hash(corner, D, perm) % ng
        gd = 0.0
        for k in range(D):
            gd += grads[gi, k] * dc[k]
        # Weight and its derivatives; axis factor (b ? s : 1 - s), derivative (b ? s' : -s').
        W = 1.0
        for k in range(D):
            W *= w[0, k] if (bits >> k) & 1 else 1.0 - w[0, k]
        value += W * gd
        if order >= 1:
            for a in range(D):
                # dW/dx_a = w'_a prod_{k != a} w_k
                dWa = 1.0
                for k in range(D):
                    b = (bits >> k) & 1
                    if k == a:
                        dWa *= w[1, k] if b else -w[1, k]
                    else:
                        dWa *= w[0, k] if b else 1.0 - w[0, k]
                grad[a] += dWa * gd + W * grads[gi, a]
                if order >= 2:
                    for c in range(D):
                        # d2W/dx_a dx_c
                        ddW = 1.0
                        for k in range(D):
                            b = (bits >> k) & 1
                            if k == a and k == c:
                                ddW *= w[2, k] if b else -w[2, k]
                            elif k == a or k == c:
                                ddW *= w[1, k] if b else -w[1, k]
                            else:
                                ddW *= w[0, k] if b else 1.0 - w[0, k]
                        dWc = 1.0
                        for k in range(D):
                            b = (bits >> k) & 1
                            if k == c:
                                dWc *= w[1, k] if b else -w[1, k]
                            else:
                                dWc *= w[0, k] if b else 1.0 - w[0, k]
                        hess[a, c] += ddW * gd + dWa * grads[gi, c] + dWc * grads[gi, a]
    return value


# ---------------------------------------------------------------------------------------------
# Improved Perlin noise with gradient, scalar code (same lattice and hash as `perlin_point`).
# ---------------------------------------------------------------------------------------------

@njit(cache=True, fastmath=_FAST, inline="always")
def perlin2_grad(x, y, perm, grads):
    """2-D improved Perlin noise and gradient: (n, dn/dx, dn/dy)."""
    fx = math.floor(x)
    fy = math.floor(y)
    i = np.int64(fx) & 255
    j = np.int64(fy) & 255
    ux = x - fx
    uy = y - fy
    sx, dsx, _ = _fade(ux)
    sy, dsy, _ = _fade(uy)
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    for bits in range(4):
        bx = bits & 1
        by = (bits >> 1) & 1
        dx = ux - bx
        dy = uy - by
        h = perm[i + bx + perm[j + by]] & m
        ax = grads[h, 0]
        ay = grads[h, 1]
        gd = ax * dx + ay * dy
        wx = sx if bx else 1.0 - sx
        wy = sy if by else 1.0 - sy
        dwx = dsx if bx else -dsx
        dwy = dsy if by else -dsy
        W = wx * wy
        n += W * gd
        gx += dwx * wy * gd + W * ax
        gy += wx * dwy * gd + W * ay
    return n, gx, gy


@njit(cache=True, fastmath=_FAST, inline="always")
def perlin3_grad(x, y, z, perm, grads):
    """3-D improved Perlin noise and gradient: (n, dn/dx, dn/dy, dn/dz)."""
    fx = math.floor(x)
    fy = math.floor(y)
    fz = math.floor(z)
    i = np.int64(fx) & 255
    j = np.int64(fy) & 255
    k = np.int64(fz) & 255
    ux = x - fx
    uy = y - fy
    uz = z - fz
    sx, dsx, _ = _fade(ux)
    sy, dsy, _ = _fade(uy)
    sz, dsz, _ = _fade(uz)
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for bits in range(8):
        bx = bits & 1
        by = (bits >> 1) & 1
        bz = (bits >> 2) & 1
        dx = ux - bx
        dy = uy - by
        dz = uz - bz
        h = perm[i + bx + perm[j + by + perm[k + bz]]] & m
        ax = grads[h, 0]
        ay = grads[h, 1]
        az = grads[h, 2]
        gd = ax * dx + ay * dy + az * dz
        wx = sx if bx else 1.0 - sx
        wy = sy if by else 1.0 - sy
        wz = sz if bz else 1.0 - sz
        dwx = dsx if bx else -dsx
        dwy = dsy if by else -dsy
        dwz = dsz if bz else -dsz
        W = wx * wy * wz
        n += W * gd
        gx += dwx * wy * wz * gd + W * ax
        gy += wx * dwy * wz * gd + W * ay
        gz += wx * wy * dwz * gd + W * az
    return n, gx, gy, gz


@njit(cache=True, fastmath=_FAST, inline="always")
def perlin4_grad(x, y, z, w, perm, grads):
    """4-D improved Perlin noise and gradient: (n, dn/dx, dn/dy, dn/dz, dn/dw)."""
    fx = math.floor(x)
    fy = math.floor(y)
    fz = math.floor(z)
    fw = math.floor(w)
    i = np.int64(fx) & 255
    j = np.int64(fy) & 255
    k = np.int64(fz) & 255
    l = np.int64(fw) & 255
    ux = x - fx
    uy = y - fy
    uz = z - fz
    uw = w - fw
    sx, dsx, _ = _fade(ux)
    sy, dsy, _ = _fade(uy)
    sz, dsz, _ = _fade(uz)
    sw, dsw, _ = _fade(uw)
    m = grads.shape[0] - 1
    n = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    gw = 0.0
    for bits in range(16):
        bx = bits & 1
        by = (bits >> 1) & 1
        bz = (bits >> 2) & 1
        bw = (bits >> 3) & 1
        dx = ux - bx
        dy = uy - by
        dz = uz - bz
        dw = uw - bw
        h = perm[i + bx + perm[j + by + perm[k + bz + perm[l + bw]]]] & m
        ax = grads[h, 0]
        ay = grads[h, 1]
        az = grads[h, 2]
        aw = grads[h, 3]
        gd = ax * dx + ay * dy + az * dz + aw * dw
        wx = sx if bx else 1.0 - sx
        wy = sy if by else 1.0 - sy
        wz = sz if bz else 1.0 - sz
        ww = sw if bw else 1.0 - sw
        dwx = dsx if bx else -dsx
        dwy = dsy if by else -dsy
        dwz = dsz if bz else -dsz
        dww = dsw if bw else -dsw
        W = wx * wy * wz * ww
        n += W * gd
        gx += dwx * wy * wz * ww * gd + W * ax
        gy += wx * dwy * wz * ww * gd + W * ay
        gz += wx * wy * dwz * ww * gd + W * az
        gw += wx * wy * wz * dww * gd + W * aw
    return n, gx, gy, gz, gw


@njit(cache=True, fastmath=_FAST)
def octave_grad(kind, D, x, y, z, w, perm, grads):
    """One octave at lattice point (x, y[, z[, w]]): (n, dn/dx, dn/dy, dn/dz, dn/dw), unused = 0."""
    if kind == KIND_SIMPLEX:
        if D == 3:
            n, a, b, c = simplex3_grad(x, y, z, perm, grads)
            return n, a, b, c, 0.0
        if D == 4:
            return simplex4_grad(x, y, z, w, perm, grads)
        n, a, b = simplex2_grad(x, y, perm, grads)
        return n, a, b, 0.0, 0.0
    if D == 3:
        n, a, b, c = perlin3_grad(x, y, z, perm, grads)
        return n, a, b, c, 0.0
    if D == 4:
        return perlin4_grad(x, y, z, w, perm, grads)
    n, a, b = perlin2_grad(x, y, perm, grads)
    return n, a, b, 0.0, 0.0


@njit(cache=True, fastmath=_FAST)
def fractal_grad(p0, p1, p2, S, t, offsets, comp, perm, grads, kind,
                 frequency, lacunarity, gain, octaves, time_frequency, scale):
    """Fractal noise component `comp` at the 2-D or 3-D point (p0, p1[, p2]) and time t.

    Scalar form of `fractal_point` for order 1 (offsets is (components, octaves, 4)):
    returns (N, dN/dx, dN/dy, dN/dz) (dN/dz = 0 in 2-D).
    """
    timed = time_frequency != 0.0
    D = S + 1 if timed else S
    value = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    f = frequency
    ft = time_frequency
    a = scale
    for o in range(octaves):
        x = p0 * f + offsets[comp, o, 0]
        y = p1 * f + offsets[comp, o, 1]
        if S == 3:
            z = p2 * f + offsets[comp, o, 2]
            w = t * ft + offsets[comp, o, 3]
        else:
            z = t * ft + offsets[comp, o, 2]
            w = 0.0
        n, a0, a1, a2, _ = octave_grad(kind, D, x, y, z, w, perm, grads)
        value += a * n
        af = a * f
        gx += af * a0
        gy += af * a1
        if S == 3:
            gz += af * a2
        f *= lacunarity
        ft *= lacunarity
        a *= gain
    return value, gx, gy, gz


@njit(cache=True)
def _noise_point(kind, x, D, perm, grads, order, grad, hess, cell, xa, rank, corner, dc, w):
    # Value and gradient: the scalar kernels; Hessians: the general ones.
    if order <= 1:
        n, grad[0], grad[1], g2, g3 = octave_grad(kind, D, x[0], x[1], x[2] if D > 2 else 0.0,
                                                  x[3] if D > 3 else 0.0, perm, grads)
        if D > 2:
            grad[2] = g2
        if D > 3:
            grad[3] = g3
        return n
    if kind == KIND_SIMPLEX:
        return simplex_point(x, D, perm, grads, order, grad, hess, cell, xa, rank, corner, dc)
    return perlin_point(x, D, perm, grads, order, grad, hess, cell, xa, w, corner, dc)


@njit(cache=True)
def fractal_point(p, S, t, offsets, perm, grads, kind, order, value_grad, hess_out,
                  x, g1, h1, cell, xa, rank, corner, dc, w,
                  frequency, lacunarity, gain, octaves, time_frequency, scale):
    """Fractal sum of noise at spatial point p[:S] and time t.

        N(p, t) = scale * sum_o gain^o n(f_o p + offset_o, f_o tf t + offset_o,t),
        f_o = frequency * lacunarity^o

    Returns N; fills value_grad[:S] with dN/dp and, for order 2, hess_out[:S, :S].
    offsets is (octaves, 4): a lattice offset per octave that decorrelates the octaves.
    """
    D = S + 1 if time_frequency != 0.0 else S
    value = 0.0
    for k in range(S):
        value_grad[k] = 0.0
        if order >= 2:
            for j in range(S):
                hess_out[k, j] = 0.0
    f = frequency
    ft = time_frequency
    a = scale
    for o in range(octaves):
        for k in range(S):
            x[k] = p[k] * f + offsets[o, k]
        if D > S:
            x[S] = t * ft + offsets[o, S]
        n = _noise_point(kind, x, D, perm, grads, order, g1, h1, cell, xa, rank, corner, dc, w)
        value += a * n
        # Chain rule: d/dp n(f p) = f grad n, d2/dp2 = f^2 hess n.
        if order >= 1:
            for k in range(S):
                value_grad[k] += a * f * g1[k]
        if order >= 2:
            af2 = a * f * f
            for k in range(S):
                for j in range(S):
                    hess_out[k, j] += af2 * h1[k, j]
        f *= lacunarity
        ft *= lacunarity
        a *= gain
    return value


# ---------------------------------------------------------------------------------------------
# Scalar fractal noise over many points.
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def fractal_noise_range(start, stop, points, offsets, perm, grads, value_out, grad_out, hess_out,
                        t, kind, order, frequency, lacunarity, gain, octaves, time_frequency, scale):
    """Scalar fractal noise at points[start:stop]: value_out (M,), grad_out (M, S) (order >= 1),
    hess_out (M, S, S) (order 2)."""
    S = points.shape[1]
    x = np.empty(4)
    g1 = np.empty(4)
    h1 = np.empty((4, 4))
    cell = np.empty(4, np.int64)
    xa = np.empty(4)
    rank = np.empty(4, np.int64)
    corner = np.empty(4, np.int64)
    dc = np.empty(4)
    w = np.empty((3, 4))
    vg = np.empty(4)
    hh = np.empty((4, 4))
    for i in range(start, stop):
        v = fractal_point(points[i], S, t, offsets, perm, grads, kind, order, vg, hh,
                          x, g1, h1, cell, xa, rank, corner, dc, w,
                          frequency, lacunarity, gain, octaves, time_frequency, scale)
        value_out[i] = v
        if order >= 1:
            for k in range(S):
                grad_out[i, k] = vg[k]
        if order >= 2:
            for k in range(S):
                for j in range(S):
                    hess_out[i, k, j] = hh[k, j]


@parallel_kernel(serial_below=SERIAL_BELOW)
def fractal_noise(points, offsets, perm, grads, value_out, grad_out, hess_out,
                  t, kind, order, frequency, lacunarity, gain, octaves, time_frequency, scale):
    """`fractal_noise_range` over all points, in parallel chunks."""
    M = points.shape[0]
    nchunks = (M + _CHUNK - 1) // _CHUNK
    for ch in prange(nchunks):
        fractal_noise_range(ch * _CHUNK, min(M, (ch + 1) * _CHUNK), points, offsets, perm, grads,
                            value_out, grad_out, hess_out, t, kind, order, frequency,
                            lacunarity, gain, octaves, time_frequency, scale)


# ---------------------------------------------------------------------------------------------
# Three noises on one lattice walk (3-D curl-noise's vector potential), a block of points at a
# time. The three potentials sample the same lattice point and differ only in their gradient
# tables (`table`, (256, 3, D): table[h, c] is the gradient of potential c at a corner of hash h;
# ``noise.component_gradients``), so the cell, the ranks or fade weights, the hash of every
# corner and the corner weights are computed once, and each corner costs three dot products.
# Each kernel adds one octave, for the points s0 .. s0 + n - 1, to acc (12, _BLOCK):
#   acc[c] += a n_c,   acc[3 + 3 c + b] += af dn_c / dx_b    (c, b = 0, 1, 2)
# with n_c in lattice units (af = a f: the chain rule of x -> f x + s); the time axis'
# derivative is never needed. Per corner with weight W(x) and offset d:
#   n_c += W (g_c . d),   dn_c/dx_b += dW/dx_b (g_c . d) + W g_cb.
# Both kinds work on structures of arrays, in three loops over the block: the first, arithmetic
# only, finds each point's cell (floored, as floats) and its offset and ranks (simplex) or
# fractions, fades and fade derivatives (Perlin) into scratch rows; the second walks the hash
# chain of every corner (the only table reads) and keeps the corner's gradient code
# (``noise.gradient_codes``: the three gradients, 2 bits an entry); then, corner by corner, the
# third adds that corner's terms, decoding the gradients in registers. The per-corner loops
# have no branch and no gather (a simplex corner outside its kernel radius gets weight
# max(q, 0)^4 = 0), so they vectorise across points. (Simplex gathering its gradients from
# `table` in the corner loop measured 1.2-1.6 times slower, a Perlin sweep that gathered them
# slower than one point at a time.)
# ---------------------------------------------------------------------------------------------

# Points per structure-of-arrays block: the scratch rows stay in the L1 cache.
_BLOCK = 128


@njit(cache=True, fastmath=_FAST, inline="always")
def _add_corner(work, e, h, dx, dy, dz, dw, timed, W, Wf, px, py, pz):
    """One lattice corner's share of point e's three potentials and their gradients, for both
    kinds' corner passes: the corner's packed gradient code h (``noise.gradient_codes``: entry
    (c, k) = ((h >> (8 c + 2 k)) & 3) - 1, the time axis k = 3 read only when `timed`) gives
    u_c = g_c . (dx, dy, dz[, dw]); the value rows gain W u_c and gradient row (c, b) gains
    p_b u_c + Wf g_cb, where (px, py, pz) is the derivative of the corner's weight Wf.
    Decoded in registers, so the caller's loop over the block has no gather."""
    B = _BLOCK
    g00 = float(h & 3) - 1.0
    g01 = float((h >> 2) & 3) - 1.0
    g02 = float((h >> 4) & 3) - 1.0
    g10 = float((h >> 8) & 3) - 1.0
    g11 = float((h >> 10) & 3) - 1.0
    g12 = float((h >> 12) & 3) - 1.0
    g20 = float((h >> 16) & 3) - 1.0
    g21 = float((h >> 18) & 3) - 1.0
    g22 = float((h >> 20) & 3) - 1.0
    u0 = g00 * dx + g01 * dy + g02 * dz
    u1 = g10 * dx + g11 * dy + g12 * dz
    u2 = g20 * dx + g21 * dy + g22 * dz
    if timed:
        u0 += (float((h >> 6) & 3) - 1.0) * dw
        u1 += (float((h >> 14) & 3) - 1.0) * dw
        u2 += (float((h >> 22) & 3) - 1.0) * dw
    work[9 * B + e] += W * u0
    work[10 * B + e] += W * u1
    work[11 * B + e] += W * u2
    work[12 * B + e] += px * u0 + Wf * g00
    work[13 * B + e] += py * u0 + Wf * g01
    work[14 * B + e] += pz * u0 + Wf * g02
    work[15 * B + e] += px * u1 + Wf * g10
    work[16 * B + e] += py * u1 + Wf * g11
    work[17 * B + e] += pz * u1 + Wf * g12
    work[18 * B + e] += px * u2 + Wf * g20
    work[19 * B + e] += py * u2 + Wf * g21
    work[20 * B + e] += pz * u2 + Wf * g22


@njit(cache=True, fastmath=_FAST, inline="always")
def _simplex_pass(work, codes, n, a, af, timed):
    """The D + 1 corners of each point's simplex (D = 3, or 4 when `timed`), added to the
    accumulators work[9 * _BLOCK:]; see `simplex_block`.

    Rows of `work`: 0-3 the offset x0 from the cell origin (unskewed; row 3 the time axis),
    4-7 each axis' rank (0 = largest offset; as floats). Corner c steps by one along the axes
    of rank < c: its offset is d = x0 - o + c G (o = 1 there, else 0) and its weight
    q^4, q = max(r^2 - |d|^2, 0) (a corner outside the kernel radius weighs 0, so the loop
    has no branch). Row c of `codes` holds the corner's gradient code (`gradient_codes`),
    decoded in registers: no gather, and the loop over the block vectorises.
    """
    B = _BLOCK
    if timed:
        G = 0.1381966011250105  # (5 - sqrt(5)) / 20
    else:
        G = 1.0 / 6.0
    for c in range(5 if timed else 4):
        cf = float(c)
        r = c * B
        for e in range(n):
            dx = work[e] - (1.0 if work[4 * B + e] < cf else 0.0) + cf * G
            dy = work[B + e] - (1.0 if work[5 * B + e] < cf else 0.0) + cf * G
            dz = work[2 * B + e] - (1.0 if work[6 * B + e] < cf else 0.0) + cf * G
            q = _SIMPLEX_R2 - dx * dx - dy * dy - dz * dz
            dw = 0.0
            if timed:
                dw = work[3 * B + e] - (1.0 if work[7 * B + e] < cf else 0.0) + cf * G
                q -= dw * dw
            q = max(q, 0.0)
            q2 = q * q
            s8 = -8.0 * af * q2 * q  # d(af q^4)/dx_b = s8 d_b
            _add_corner(work, e, codes[r + e], dx, dy, dz, dw, timed, a * q2 * q2, af * q2 * q2,
                        s8 * dx, s8 * dy, s8 * dz)


@njit(cache=True, fastmath=_FAST, inline="always")
def _simplex_walk(points, s0, n, f, o0, o1, o2, w, perm, codes, a, af, work, hashes, timed):
    """The body of `simplex_block`, `timed` a compile-time constant (no branch in its loops)."""
    B = _BLOCK
    for e in range(n):
        x = points[s0 + e, 0] * f + o0
        y = points[s0 + e, 1] * f + o1
        z = points[s0 + e, 2] * f + o2
        if timed:
            # Skew (F4 = (sqrt(5) - 1) / 4) and unskew (G4 = (5 - sqrt(5)) / 20).
            s = (x + y + z + w) * 0.30901699437494745
            fl = np.floor(w + s)
        else:
            s = (x + y + z) * (1.0 / 3.0)
            fl = 0.0
        fi = np.floor(x + s)
        fj = np.floor(y + s)
        fk = np.floor(z + s)
        if timed:
            t = (fi + fj + fk + fl) * 0.1381966011250105
        else:
            t = (fi + fj + fk) * (1.0 / 6.0)
        x0 = x - (fi - t)
        y0 = y - (fj - t)
        z0 = z - (fk - t)
        w0 = w - (fl - t) if timed else -1.0  # -1: the time axis never ranks first in 3-D
        work[e] = x0
        work[B + e] = y0
        work[2 * B + e] = z0
        work[3 * B + e] = w0
        # Rank of each axis' offset (0 = largest; ties to the lower axis).
        rx = (1 if y0 > x0 else 0) + (1 if z0 > x0 else 0) + (1 if w0 > x0 else 0)
        ry = (1 if x0 >= y0 else 0) + (1 if z0 > y0 else 0) + (1 if w0 > y0 else 0)
        rz = (1 if x0 >= z0 else 0) + (1 if y0 >= z0 else 0) + (1 if w0 > z0 else 0)
        rw = (1 if x0 >= w0 else 0) + (1 if y0 >= w0 else 0) + (1 if z0 >= w0 else 0)
        work[4 * B + e] = rx
        work[5 * B + e] = ry
        work[6 * B + e] = rz
        work[7 * B + e] = rw
        work[21 * B + e] = fi
        work[22 * B + e] = fj
        work[23 * B + e] = fk
        work[24 * B + e] = fl
    # The hash chains (table reads: scalar). Corner codes, row c: corner c steps along the
    # axes of rank < c.
    for e in range(n):
        i = np.int64(work[21 * B + e]) & 255
        j = np.int64(work[22 * B + e]) & 255
        k = np.int64(work[23 * B + e]) & 255
        l = np.int64(work[24 * B + e]) & 255
        for c in range(5 if timed else 4):
            cf = float(c)
            oi = 1 if work[4 * B + e] < cf else 0
            oj = 1 if work[5 * B + e] < cf else 0
            ok = 1 if work[6 * B + e] < cf else 0
            hw = perm[l + (1 if work[7 * B + e] < cf else 0)] if timed else 0
            hashes[c * B + e] = codes[i + oi + perm[j + oj + perm[k + ok + hw]]]
    _simplex_pass(work, hashes, n, a, af, timed)


@njit(cache=True, fastmath=_FAST, inline="never")
def simplex_block(points, s0, n, f, o0, o1, o2, w, timed, perm, codes, a, af, work, hashes):
    """One octave of three simplex noises at points s0 .. s0 + n - 1 (3-D, or 4-D at lattice
    time w when `timed`), added to the accumulators of `work` (see `potential3_block`).

    A first loop (arithmetic only) skews each point onto the hypercubic lattice, finds its cell
    (rows 21-24 of `work`), its offset x0 from the cell origin (rows 0-3) and the ranks of x0's
    coordinates (rows 4-7; ties to the lower axis: `simplex_point`'s order); a second, scalar
    loop walks the hash chain perm[i + perm[j + perm[k + perm[l]]]] of each of the D + 1
    corners and keeps the corner's gradient code (`codes`, as in `perlin_block`) in `hashes`;
    then `_simplex_pass` adds the corners.
    """
    # `timed` a constant in each call: the loops over the block then have no branch.
    if timed:
        _simplex_walk(points, s0, n, f, o0, o1, o2, w, perm, codes, a, af, work, hashes, True)
    else:
        _simplex_walk(points, s0, n, f, o0, o1, o2, w, perm, codes, a, af, work, hashes, False)


@njit(cache=True, fastmath=_FAST, inline="always")
def _perlin_pass(work, codes, row, n, a, af, dw, timed):
    """The 8 corners of one lattice slice (codes rows row .. row + 7) for the points of the
    block, added to the accumulators work[9 * _BLOCK:]; see `perlin_block`.

    Corner (bx, by, bz) has the weight W = w_x w_y w_z, w = s or 1 - s (s the fade), so
    w = o + q s with o = 1 - b, q = 2 b - 1 per axis, and dW/dx = q s'_x w_y w_z; its
    offset is d = u - b (u the fraction in the cell), d_w = dw on the time axis (`timed`).
    Gradient entry (c, k) is unit * (((code >> (8 c + 2 k)) & 3) - 1): decoded in registers,
    so the loop over the block has no table gather and no branch, and vectorises.
    """
    B = _BLOCK
    for c in range(8):
        bx = float(c & 1)
        by = float((c >> 1) & 1)
        bz = float((c >> 2) & 1)
        qx = 2.0 * bx - 1.0
        qy = 2.0 * by - 1.0
        qz = 2.0 * bz - 1.0
        r = (row + c) * B
        for e in range(n):
            dx = work[e] - bx
            dy = work[B + e] - by
            dz = work[2 * B + e] - bz
            wx = 1.0 - bx + qx * work[3 * B + e]
            wy = 1.0 - by + qy * work[4 * B + e]
            wz = 1.0 - bz + qz * work[5 * B + e]
            wyz = wy * wz
            W = wx * wyz
            _add_corner(work, e, codes[r + e], dx, dy, dz, dw, timed, a * W, af * W,
                        af * qx * work[6 * B + e] * wyz, af * qy * work[7 * B + e] * wx * wz,
                        af * qz * work[8 * B + e] * wx * wy)


@njit(cache=True, fastmath=_FAST, inline="never")
def perlin_block(points, s0, n, f, o0, o1, o2, w, timed, perm, codes, a, af, work, hashes):
    """One octave of three improved Perlin noises at points s0 .. s0 + n - 1 (3-D, or 4-D at
    lattice time w when `timed`), added to the accumulators of `work` (see `potential3_block`).

    `codes` (512,) int64 is the gradient code of the corner reached through each entry of the
    permutation: codes[x] = code[perm[x]], with bits 8 c + 2 k .. + 1 holding
    table[h, c, k] / unit + 1 (`gradient_codes`). A first loop (arithmetic only) finds each
    point's cell (rows 21-23 of `work`), its fractions u, fades s and fade derivatives s' (rows
    0-8); a second, scalar loop walks the hash chain perm[i + perm[j + perm[k + perm[l]]]] once
    per corner (its inner lookups shared: 14 reads for 8 corners), keeping the corner codes in
    `hashes`; the time axis' cell, fade
    and first lookups are the same for every point and computed once. Then `_perlin_pass`
    adds the corners, one lattice slice at a time (one in 3-D; two in 4-D, weighted by the
    time fade 1 - s_w and s_w), each a branch-free loop over the block.
    """
    B = _BLOCK
    fw = np.floor(w)
    l = np.int64(fw) & 255
    uw = w - fw
    sw = uw * uw * uw * (uw * (uw * 6.0 - 15.0) + 10.0)
    hw0 = perm[l] if timed else 0
    hw1 = perm[l + 1] if timed else 0
    # Cells (floored, as floats: rows 21-23), fractions, fades: arithmetic only, so this
    # loop vectorises.
    for e in range(n):
        x = points[s0 + e, 0] * f + o0
        y = points[s0 + e, 1] * f + o1
        z = points[s0 + e, 2] * f + o2
        fx = np.floor(x)
        fy = np.floor(y)
        fz = np.floor(z)
        work[21 * B + e] = fx
        work[22 * B + e] = fy
        work[23 * B + e] = fz
        ux = x - fx
        uy = y - fy
        uz = z - fz
        # s(u) = 6 u^5 - 15 u^4 + 10 u^3, s'(u) = 30 u^2 (u - 1)^2
        work[e] = ux
        work[B + e] = uy
        work[2 * B + e] = uz
        work[3 * B + e] = ux * ux * ux * (ux * (ux * 6.0 - 15.0) + 10.0)
        work[4 * B + e] = uy * uy * uy * (uy * (uy * 6.0 - 15.0) + 10.0)
        work[5 * B + e] = uz * uz * uz * (uz * (uz * 6.0 - 15.0) + 10.0)
        work[6 * B + e] = 30.0 * ux * ux * (ux - 1.0) * (ux - 1.0)
        work[7 * B + e] = 30.0 * uy * uy * (uy - 1.0) * (uy - 1.0)
        work[8 * B + e] = 30.0 * uz * uz * (uz - 1.0) * (uz - 1.0)
    # The hash chains (table reads: scalar). Corner codes, rows 8 bw + 4 bz + 2 by + bx.
    for e in range(n):
        i = np.int64(work[21 * B + e]) & 255
        j = np.int64(work[22 * B + e]) & 255
        k = np.int64(work[23 * B + e]) & 255
        for bw in range(2 if timed else 1):
            hw = hw1 if bw else hw0
            hz0 = perm[k + hw]
            hz1 = perm[k + 1 + hw]
            h00 = perm[j + hz0]
            h10 = perm[j + 1 + hz0]
            h01 = perm[j + hz1]
            h11 = perm[j + 1 + hz1]
            r = 8 * bw * B + e
            hashes[r] = codes[i + h00]
            hashes[r + B] = codes[i + 1 + h00]
            hashes[r + 2 * B] = codes[i + h10]
            hashes[r + 3 * B] = codes[i + 1 + h10]
            hashes[r + 4 * B] = codes[i + h01]
            hashes[r + 5 * B] = codes[i + 1 + h01]
            hashes[r + 6 * B] = codes[i + h11]
            hashes[r + 7 * B] = codes[i + 1 + h11]
    if timed:
        # n = (1 - s_w) n(slice l, d_w = u_w) + s_w n(slice l + 1, d_w = u_w - 1)
        _perlin_pass(work, hashes, 0, n, a * (1.0 - sw), af * (1.0 - sw), uw, True)
        _perlin_pass(work, hashes, 8, n, a * sw, af * sw, uw - 1.0, True)
    else:
        _perlin_pass(work, hashes, 0, n, a, af, 0.0, False)


@njit(cache=True, fastmath=_FAST)
def potential3_block(points, s0, n, t, offsets, perm, table, simplex_codes, perlin_codes,
                     frequency, lacunarity, gain, octaves, time_frequency, scale, work, ints):
    """Fractal vector potential psi and its Jacobian at the 3-D points s0 .. s0 + n - 1 and
    time t, into rows 9-20 of the flat scratch work (25 _BLOCK,): row 9 + c = psi_c,
    row 12 + 3 c + b = d psi_c / d x_b (rows 0-8 and 21-24 are scratch; ints (16 _BLOCK,) int64 too).

        psi_c = scale * sum_o gain^o n_c(f_o p + s_o, f_o tf t + s_o,t),  f_o = frequency lacunarity^o

    offsets is (octaves, 4): one lattice offset per octave, shared by the components. Every
    octave's lattice walk serves all three components (the ``*_block`` kernels above).
    One of simplex_codes / perlin_codes is the table's gradient codes (``noise.gradient_codes``,
    which the ``*_block`` kernels decode, scaled by `unit`, the magnitude of the table's nonzero
    entries), the other None: simplex noise, or improved Perlin noise.
    """
    B = _BLOCK
    timed = time_frequency != 0.0
    for r in range(9 * B, 21 * B):
        work[r] = 0.0
    # The gradients are +-unit or 0 (1/sqrt 2 in 3-D, 1/sqrt 3 in 4-D: ``noise.py``); the codes
    # hold them in units of `unit`.
    unit = 0.0
    for h in range(table.shape[0]):
        for c in range(table.shape[1]):
            for b in range(table.shape[2]):
                unit = max(unit, abs(table[h, c, b]))
    f = frequency
    ft = time_frequency
    a = scale
    # Numba drops a branch on `x is not None` when x is None: a scene compiles one kind's walk.
    if simplex_codes is not None:
        for o in range(octaves):
            w = t * ft + offsets[o, 3]
            simplex_block(points, s0, n, f, offsets[o, 0], offsets[o, 1], offsets[o, 2], w, timed,
                          perm, simplex_codes, a * unit, a * f * unit, work, ints)
            f *= lacunarity
            ft *= lacunarity
            a *= gain
    if perlin_codes is not None:
        for o in range(octaves):
            w = t * ft + offsets[o, 3]
            perlin_block(points, s0, n, f, offsets[o, 0], offsets[o, 1], offsets[o, 2], w, timed,
                         perm, perlin_codes, a * unit, a * f * unit, work, ints)
            f *= lacunarity
            ft *= lacunarity
            a *= gain


# ---------------------------------------------------------------------------------------------
# Curl-noise (Bridson et al. 2007).
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def ramp(r):
    """Bridson's smooth ramp: 1 for r >= 1, -1 for r <= -1, else (15 r - 10 r^3 + 3 r^5) / 8.

    Returns (ramp(r), dramp/dr, d2ramp/dr2); the ramp is odd and C^2 at |r| = 1.
    """
    if r >= 1.0:
        return 1.0, 0.0, 0.0
    if r <= -1.0:
        return -1.0, 0.0, 0.0
    r2 = r * r
    return ((15.0 - 10.0 * r2 + 3.0 * r2 * r2) * r / 8.0,
            (15.0 - 30.0 * r2 + 15.0 * r2 * r2) / 8.0,
            (-60.0 * r + 60.0 * r2 * r) / 8.0)


@njit(cache=True, inline="always")
def _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, base, m, skip, key, mode, S,
                  grad_out):
    """Product of the walls' ramps over a subset of the m walls at rows base.., and its gradient.

    mode 0: every wall but `skip`; mode 1: the walls of collider `key`; mode 2: all others.
    grad (prod_j a_j) = sum_j a_j' n_j prod_{l != j} a_l, accumulated by the product rule.
    """
    prod = 1.0
    for x in range(S):
        grad_out[x] = 0.0
    for j in range(m):
        if mode == 0:
            take = j != skip
        elif mode == 1:
            take = bnd_collider[base + j] == key
        else:
            take = bnd_collider[base + j] != key
        if take:
            for x in range(S):
                grad_out[x] = grad_out[x] * ramp_value[j] + prod * ramp_slope[j] * bnd_normal[base + j, x]
            prod *= ramp_value[j]
    return prod


@njit(cache=True, fastmath=_FAST)
def curl_noise3_range(start, stop, points, offsets, perm, grads, table, simplex_codes, perlin_codes,
                     slot, bnd_count, bnd_distance, bnd_normal, bnd_hessian, bnd_collider,
                     rigid_velocity, rigid_spin, rigid_center, rigid_radius2, mean_velocity,
                     out,
                     t, kind, frequency, lacunarity, gain, octaves, time_frequency, scale,
                     boundary_width):
    """Velocity of 3-D curl-noise at points start .. stop - 1, with optional boundaries (2-D:
    `curl_noise2_range`, the same formulas).

    Potentials (unit-range noise times `scale`; offsets (1, octaves, 4), one lattice offset
    per octave):
      2-D: scalar psi, the noise with gradients `grads` (256, 2);   v = (dpsi/dy, -dpsi/dx)
      3-D: psi = (psi0, psi1, psi2), three noises on the same lattice points with the gradient
           tables table[:, c] (256, 3, D), read as codes (512,) int64 of
           ``noise.gradient_codes``: simplex_codes for simplex, perlin_codes for Perlin, the
           other None (both None in 2-D), so that a scene compiles only its own kind's
           lattice walk; one lattice walk per octave (`potential3_block`);
           v = curl psi
    Boundaries: point i has bnd_count[i] walls within `boundary_width` = d0, at rows
    slot[i] .. slot[i] + bnd_count[i] - 1 of the bnd_* arrays (slot[i] = -1: none). Wall k has
    the signed distance d_k, normal n_k = grad d_k, H_k = grad n_k, ramp a_k = ramp(d_k / d0),
    grad a_k = a_k' n_k / d0, and belongs to collider K(k). With alpha = prod_k a_k,
    c_k = (1 - a_k) prod_{j != k} a_j and, per collider K, gamma_K = (1 - prod_{k in K} a_k)
    prod_{k not in K} a_k:
      2-D: psi' = alpha psi + sum_K gamma_K psi_R,K
      3-D: psi' = alpha psi + sum_k c_k n_k (n_k . psi) + sum_K gamma_K psi_R,K
           curl psi' = grad alpha x psi + alpha curl psi
                       + sum_k [grad c_k x n_k (n_k . psi) + c_k grad(n_k . psi) x n_k]
                       + sum_K [grad gamma_K x psi_R,K + gamma_K u_R,K],
           grad(n . psi) = H psi + (grad psi)^T n      (curl n = 0 because n = grad d)
    On wall k (a_k = 0) only c_k survives, so psi' - psi_R is along n_k and the flow through
    the wall is the wall's own; every weight is a product of C^2 ramps, so the velocity is
    continuous where the closest wall changes (a box's edges, two colliders). One wall gives
    Bridson's psi' = a psi + (1 - a) n (n . psi) + (1 - a) psi_R.
    A mean flow U (mean_velocity) is added to v away from boundaries and, near them, to psi
    as psi_U = U x (x - c) / 2 (3-D), U_x (y - c_y) - U_y (x - c_x) (2-D) about the centre c
    of the nearest wall's collider, before the ramp, so that it too goes around the collider.
    psi_R is the potential of collider K's rigid motion u_R = V + W x (x - c):
      2-D: psi_R = V_x (y - c_y) - V_y (x - c_x) - W (|x - c|^2 - R^2) / 2
      3-D: psi_R = V x (x - c) / 2 + W (R^2 - |x - c|^2) / 2
    (rigid_radius2 holds R^2; rigid_center c; for static colliders V = W = 0).
    """
    S = points.shape[1]
    shared = offsets[0]
    bounded = slot.shape[0] > 0  # an empty slot array means: no boundaries
    curved = bnd_hessian.shape[0] > 0  # an empty Hessian array means: every wall is flat
    psi = np.empty(3)
    J = np.empty((3, 3))  # J[c, j] = d psi_c / d x_j
    g = np.empty(3)
    gb = np.empty(3)
    most = 1
    if bounded:
        for i in range(start, stop):
            most = max(most, bnd_count[i])
    ramp_value = np.empty(most)
    ramp_slope = np.empty(most)
    # 3-D: the potential and its Jacobian a block of points at a time (`potential3_block`).
    work = np.empty(25 * _BLOCK)
    ints = np.empty(16 * _BLOCK, np.int64)
    acc = work[9 * _BLOCK:21 * _BLOCK].reshape((12, _BLOCK))
    for s0 in range(start, stop, _BLOCK):
        n_block = min(_BLOCK, stop - s0)
        potential3_block(points, s0, n_block, t, shared, perm, table, simplex_codes, perlin_codes,
                         frequency, lacunarity, gain, octaves, time_frequency, scale, work, ints)
        for e in range(n_block):
            i = s0 + e
            p = points[i]
            psi[0] = acc[0, e]
            psi[1] = acc[1, e]
            psi[2] = acc[2, e]
            for c in range(3):
                for b in range(3):
                    J[c, b] = acc[3 + 3 * c + b, e]
            sl = slot[i] if bounded else -1
            if sl < 0:
                # Free flow: v = curl psi + U.
                out[i, 0] = J[2, 1] - J[1, 2] + mean_velocity[0]
                out[i, 1] = J[0, 2] - J[2, 0] + mean_velocity[1]
                out[i, 2] = J[1, 0] - J[0, 1] + mean_velocity[2]
                continue
            m = bnd_count[i]
            # Ramps of the walls within d0, and the nearest wall's collider (for the mean flow).
            nearest = 0
            for j in range(m):
                al, dal, _ = ramp(bnd_distance[sl + j] / boundary_width)
                ramp_value[j] = al
                ramp_slope[j] = dal / boundary_width
                if bnd_distance[sl + j] < bnd_distance[sl + nearest]:
                    nearest = j
            kn = bnd_collider[sl + nearest]
            cx = p[0] - rigid_center[kn, 0]
            cy = p[1] - rigid_center[kn, 1]
            alpha = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, 0, 0, S, g)
            # 3-D. Mean flow U, as a potential about c: psi_U = U x (x - c) / 2, grad psi_U = [U]_x / 2.
            cz = p[2] - rigid_center[kn, 2]
            U0 = 0.5 * mean_velocity[0]
            U1 = 0.5 * mean_velocity[1]
            U2 = 0.5 * mean_velocity[2]
            psi[0] += U1 * cz - U2 * cy
            psi[1] += U2 * cx - U0 * cz
            psi[2] += U0 * cy - U1 * cx
            J[0, 1] -= U2
            J[0, 2] += U1
            J[1, 0] += U2
            J[1, 2] -= U0
            J[2, 0] -= U1
            J[2, 1] += U0
            # grad alpha x psi + alpha curl psi
            v0 = g[1] * psi[2] - g[2] * psi[1] + alpha * (J[2, 1] - J[1, 2])
            v1 = g[2] * psi[0] - g[0] * psi[2] + alpha * (J[0, 2] - J[2, 0])
            v2 = g[0] * psi[1] - g[1] * psi[0] + alpha * (J[1, 0] - J[0, 1])
            # Normal blends: c_k n_k (n_k . psi).
            for j in range(m):
                row = sl + j
                n0 = bnd_normal[row, 0]
                n1 = bnd_normal[row, 1]
                n2 = bnd_normal[row, 2]
                others = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, j, 0, 0, S, g)
                b = 1.0 - ramp_value[j]
                ck = b * others
                # grad c_k = -a_k' n_k prod + (1 - a_k) grad prod; the first term is parallel to n_k.
                s = n0 * psi[0] + n1 * psi[1] + n2 * psi[2]
                gc0 = b * g[0] * s
                gc1 = b * g[1] * s
                gc2 = b * g[2] * s
                # gs = grad(n . psi) = H psi + J^T n (H = 0 for planes: no Hessian rows at all)
                gs0 = n0 * J[0, 0] + n1 * J[1, 0] + n2 * J[2, 0]
                gs1 = n0 * J[0, 1] + n1 * J[1, 1] + n2 * J[2, 1]
                gs2 = n0 * J[0, 2] + n1 * J[1, 2] + n2 * J[2, 2]
                if curved:
                    gs0 += (bnd_hessian[row, 0, 0] * psi[0] + bnd_hessian[row, 0, 1] * psi[1]
                            + bnd_hessian[row, 0, 2] * psi[2])
                    gs1 += (bnd_hessian[row, 1, 0] * psi[0] + bnd_hessian[row, 1, 1] * psi[1]
                            + bnd_hessian[row, 1, 2] * psi[2])
                    gs2 += (bnd_hessian[row, 2, 0] * psi[0] + bnd_hessian[row, 2, 1] * psi[1]
                            + bnd_hessian[row, 2, 2] * psi[2])
                v0 += gc1 * n2 - gc2 * n1 + ck * (gs1 * n2 - gs2 * n1)
                v1 += gc2 * n0 - gc0 * n2 + ck * (gs2 * n0 - gs0 * n2)
                v2 += gc0 * n1 - gc1 * n0 + ck * (gs0 * n1 - gs1 * n0)
            # Rigid motion of each collider with a wall here: gamma_K psi_R,K.
            for j in range(m):
                k = bnd_collider[sl + j]
                first = True
                for l in range(j):
                    if bnd_collider[sl + l] == k:
                        first = False
                if not first:
                    continue
                V0 = rigid_velocity[k, 0]
                V1 = rigid_velocity[k, 1]
                V2 = rigid_velocity[k, 2]
                W0 = rigid_spin[k, 0]
                W1 = rigid_spin[k, 1]
                W2 = rigid_spin[k, 2]
                if V0 == 0.0 and V1 == 0.0 and V2 == 0.0 and W0 == 0.0 and W1 == 0.0 and W2 == 0.0:
                    continue  # static: psi_R = 0
                ak = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, k, 1, S, gb)
                bk = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, k, 2, S, g)
                gamma = (1.0 - ak) * bk
                gg0 = -gb[0] * bk + (1.0 - ak) * g[0]
                gg1 = -gb[1] * bk + (1.0 - ak) * g[1]
                gg2 = -gb[2] * bk + (1.0 - ak) * g[2]
                kx = p[0] - rigid_center[k, 0]
                ky = p[1] - rigid_center[k, 1]
                kz = p[2] - rigid_center[k, 2]
                half = 0.5 * (rigid_radius2[k] - (kx * kx + ky * ky + kz * kz))
                pr0 = 0.5 * (V1 * kz - V2 * ky) + half * W0
                pr1 = 0.5 * (V2 * kx - V0 * kz) + half * W1
                pr2 = 0.5 * (V0 * ky - V1 * kx) + half * W2
                ur0 = V0 + W1 * kz - W2 * ky
                ur1 = V1 + W2 * kx - W0 * kz
                ur2 = V2 + W0 * ky - W1 * kx
                v0 += gg1 * pr2 - gg2 * pr1 + gamma * ur0
                v1 += gg2 * pr0 - gg0 * pr2 + gamma * ur1
                v2 += gg0 * pr1 - gg1 * pr0 + gamma * ur2
            out[i, 0] = v0
            out[i, 1] = v1
            out[i, 2] = v2


@njit(cache=True, fastmath=_FAST)
def curl_noise2_range(start, stop, points, offsets, perm, grads, table, simplex_codes, perlin_codes,
                     slot, bnd_count, bnd_distance, bnd_normal, bnd_hessian, bnd_collider,
                     rigid_velocity, rigid_spin, rigid_center, rigid_radius2, mean_velocity,
                     out,
                     t, kind, frequency, lacunarity, gain, octaves, time_frequency, scale,
                     boundary_width):
    """Velocity of 2-D curl-noise at points start .. stop - 1: v = (dpsi'/dy, -dpsi'/dx) with
    the boundary-modified stream function psi' of `curl_noise3_range` (no normal blend in
    2-D). A kernel of its own so that a 3-D scene never compiles the 2-D path and the reverse."""
    S = points.shape[1]
    bounded = slot.shape[0] > 0  # an empty slot array means: no boundaries
    psi = np.empty(3)
    J = np.empty((3, 3))  # J[c, j] = d psi_c / d x_j
    g = np.empty(3)
    most = 1
    if bounded:
        for i in range(start, stop):
            most = max(most, bnd_count[i])
    ramp_value = np.empty(most)
    ramp_slope = np.empty(most)
    for i in range(start, stop):
        p = points[i]
        psi[0], J[0, 0], J[0, 1], J[0, 2] = fractal_grad(
            p[0], p[1], 0.0, S, t, offsets, 0, perm, grads, kind, frequency, lacunarity,
            gain, octaves, time_frequency, scale)
        sl = slot[i] if bounded else -1
        if sl < 0:
            # Free flow: v = curl psi + U.
            out[i, 0] = J[0, 1] + mean_velocity[0]
            out[i, 1] = -J[0, 0] + mean_velocity[1]
            continue
        m = bnd_count[i]
        # Ramps of the walls within d0, and the nearest wall's collider (for the mean flow).
        nearest = 0
        for j in range(m):
            al, dal, _ = ramp(bnd_distance[sl + j] / boundary_width)
            ramp_value[j] = al
            ramp_slope[j] = dal / boundary_width
            if bnd_distance[sl + j] < bnd_distance[sl + nearest]:
                nearest = j
        kn = bnd_collider[sl + nearest]
        cx = p[0] - rigid_center[kn, 0]
        cy = p[1] - rigid_center[kn, 1]
        alpha = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, 0, 0, S, g)
        # Mean flow U, as a potential about c: psi_U = U_x (y - c_y) - U_y (x - c_x).
        psi[0] += mean_velocity[0] * cy - mean_velocity[1] * cx
        J[0, 0] -= mean_velocity[1]
        J[0, 1] += mean_velocity[0]
        # grad psi' = grad alpha psi + alpha grad psi + sum_K (grad gamma psi_R + gamma grad psi_R)
        gx = g[0] * psi[0] + alpha * J[0, 0]
        gy = g[1] * psi[0] + alpha * J[0, 1]
        for j in range(m):
            k = bnd_collider[sl + j]
            first = True
            for l in range(j):
                if bnd_collider[sl + l] == k:
                    first = False
            if not first:
                continue
            ak = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, k, 1, S, g)
            gax = g[0]
            gay = g[1]
            bk = _wall_product(ramp_value, ramp_slope, bnd_normal, bnd_collider, sl, m, -1, k, 2, S, g)
            gamma = (1.0 - ak) * bk
            ggx = -gax * bk + (1.0 - ak) * g[0]
            ggy = -gay * bk + (1.0 - ak) * g[1]
            kx = p[0] - rigid_center[k, 0]
            ky = p[1] - rigid_center[k, 1]
            vx = rigid_velocity[k, 0]
            vy = rigid_velocity[k, 1]
            om = rigid_spin[k, 0]
            psir = vx * ky - vy * kx - 0.5 * om * (kx * kx + ky * ky - rigid_radius2[k])
            gx += ggx * psir + gamma * (-vy - om * kx)
            gy += ggy * psir + gamma * (vx - om * ky)
        out[i, 0] = gy
        out[i, 1] = -gx


@parallel_kernel(serial_below=SERIAL_BELOW)
def curl_noise3(points, offsets, perm, grads, table, simplex_codes, perlin_codes,
                slot, bnd_count, bnd_distance, bnd_normal, bnd_hessian, bnd_collider,
                rigid_velocity, rigid_spin, rigid_center, rigid_radius2, mean_velocity,
                out,
                t, kind, frequency, lacunarity, gain, octaves, time_frequency, scale,
                boundary_width):
    """Velocity of 3-D curl-noise at every point (see `curl_noise3_range`), in parallel chunks."""
    M = points.shape[0]
    nchunks = (M + _CHUNK - 1) // _CHUNK
    for ch in prange(nchunks):
        curl_noise3_range(ch * _CHUNK, min(M, (ch + 1) * _CHUNK), points, offsets, perm, grads,
                          table, simplex_codes, perlin_codes, slot, bnd_count, bnd_distance,
                          bnd_normal, bnd_hessian, bnd_collider, rigid_velocity, rigid_spin,
                          rigid_center, rigid_radius2,
                          mean_velocity, out, t, kind, frequency, lacunarity, gain, octaves,
                          time_frequency, scale, boundary_width)


@parallel_kernel(serial_below=SERIAL_BELOW)
def curl_noise2(points, offsets, perm, grads, table, simplex_codes, perlin_codes,
                slot, bnd_count, bnd_distance, bnd_normal, bnd_hessian, bnd_collider,
                rigid_velocity, rigid_spin, rigid_center, rigid_radius2, mean_velocity,
                out,
                t, kind, frequency, lacunarity, gain, octaves, time_frequency, scale,
                boundary_width):
    """Velocity of 2-D curl-noise at every point (see `curl_noise2_range`), in parallel chunks."""
    M = points.shape[0]
    nchunks = (M + _CHUNK - 1) // _CHUNK
    for ch in prange(nchunks):
        curl_noise2_range(ch * _CHUNK, min(M, (ch + 1) * _CHUNK), points, offsets, perm, grads,
                          table, simplex_codes, perlin_codes, slot, bnd_count, bnd_distance,
                          bnd_normal, bnd_hessian, bnd_collider, rigid_velocity, rigid_spin,
                          rigid_center, rigid_radius2,
                          mean_velocity, out, t, kind, frequency, lacunarity, gain, octaves,
                          time_frequency, scale, boundary_width)


@njit(cache=True)
def curl_noise_jacobian(points, offsets, perm, grads, out,
                        t, kind, frequency, lacunarity, gain, octaves, time_frequency, scale):
    """Analytic Jacobian dv_i/dx_j of boundary-free curl-noise, out (M, S, S).

    grads is (components, 256, D): potential c is the noise with gradient table grads[c],
    evaluated one component at a time by the general kernels (`fractal_point`), a second
    implementation independent of `potential3_block`. offsets is (1, octaves, 4).

      2-D: v = (psi_y, -psi_x)          -> dv/dx = [[psi_yx, psi_yy], [-psi_xx, -psi_xy]]
      3-D: v_i = eps_ijk d_j psi_k      -> dv_i/dx_l = eps_ijk d_l d_j psi_k
    The trace (the divergence) vanishes because each Hessian is symmetric.
    One thread: this is a verification tool, and a parallel twin would double its compile time.
    """
    M, S = points.shape
    ncomp = 1 if S == 2 else 3
    x = np.empty(4)
    g1 = np.empty(4)
    h1 = np.empty((4, 4))
    cell = np.empty(4, np.int64)
    xa = np.empty(4)
    rank = np.empty(4, np.int64)
    corner = np.empty(4, np.int64)
    dc = np.empty(4)
    w = np.empty((3, 4))
    vg = np.empty(4)
    H = np.empty((3, 3, 3))  # H[c] = Hessian of psi_c
    hh = np.empty((4, 4))
    for i in range(M):
        p = points[i]
        for c in range(ncomp):
            fractal_point(p, S, t, offsets[0], perm, grads[c], kind, 2, vg, hh,
                          x, g1, h1, cell, xa, rank, corner, dc, w,
                          frequency, lacunarity, gain, octaves, time_frequency, scale)
            for a in range(S):
                for b in range(S):
                    H[c, a, b] = hh[a, b]
        if S == 2:
            for l in range(2):
                out[i, 0, l] = H[0, 1, l]
                out[i, 1, l] = -H[0, 0, l]
        else:
            for l in range(3):
                out[i, 0, l] = H[2, 1, l] - H[1, 2, l]
                out[i, 1, l] = H[0, 2, l] - H[2, 0, l]
                out[i, 2, l] = H[1, 0, l] - H[0, 1, l]


# ---------------------------------------------------------------------------------------------
# Sampled grids: multilinear interpolation.
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def _grid_axis(u, n):
    """Cell index, fraction and slope factor (0 when clamped) of grid coordinate u on n nodes."""
    inside = 1.0
    if u < 0.0:
        u = 0.0
        inside = 0.0
    elif u > n - 1.0:
        u = n - 1.0
        inside = 0.0
    b = min(int(math.floor(u)), n - 2)
    return b, u - b, inside


@njit(cache=True)
def grid_sample(points, values, origin, inv_spacing, out, order, zero_outside):
    """Multilinear (bilinear / trilinear) interpolation of node values (n0, n1, n2, C)
    (2-D grids are passed as (n0, n1, 1, C)).

    With u = (x - origin) / h split into cell b and fraction f per axis,
        v(x) = sum_corners prod_k (f_k or 1 - f_k) values[b + corner]
    order 0: out (M, C, 1) values; order 1: out (M, C, S) = dv_c/dx_j (0 along clamped axes).
    Points outside the grid take the nearest boundary value (zero_outside False) or 0.
    """
    M, S = points.shape
    C = values.shape[-1]
    for i in range(M):
        b0, f0, in0 = _grid_axis((points[i, 0] - origin[0]) * inv_spacing[0], values.shape[0])
        b1, f1, in1 = _grid_axis((points[i, 1] - origin[1]) * inv_spacing[1], values.shape[1])
        b2, f2, in2 = 0, 0.0, 1.0
        if S == 3:
            b2, f2, in2 = _grid_axis((points[i, 2] - origin[2]) * inv_spacing[2], values.shape[2])
        for c in range(C):
            for j in range(out.shape[2]):
                out[i, c, j] = 0.0
        if zero_outside and in0 * in1 * in2 == 0.0:
            continue
        for bits in range(1 << S):
            o0 = bits & 1
            o1 = (bits >> 1) & 1
            o2 = (bits >> 2) & 1
            w0 = f0 if o0 else 1.0 - f0
            w1 = f1 if o1 else 1.0 - f1
            w2 = (f2 if o2 else 1.0 - f2) if S == 3 else 1.0
            # d w_k / d x_k = +-1 / h_k inside the grid, 0 where the axis is clamped
            d0 = (1.0 if o0 else -1.0) * inv_spacing[0] * in0
            d1 = (1.0 if o1 else -1.0) * inv_spacing[1] * in1
            d2 = (1.0 if o2 else -1.0) * inv_spacing[2] * in2 if S == 3 else 0.0
            for c in range(C):
                val = values[b0 + o0, b1 + o1, b2 + o2, c]
                if order == 0:
                    out[i, c, 0] += w0 * w1 * w2 * val
                else:
                    out[i, c, 0] += d0 * w1 * w2 * val
                    out[i, c, 1] += w0 * d1 * w2 * val
                    if S == 3:
                        out[i, c, 2] += w0 * w1 * d2 * val


# ---------------------------------------------------------------------------------------------
# Analytic primitives (Sims 1990; Wejchert & Haumann 1991).
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def vortex_field(points, center, axis, out, jac, circulation, core2, order):
    """Regularised line vortex (Kaufmann-Scully core): with r the offset from the axis a,
        v = Gamma / (2 pi) (a x r) / (|r|^2 + rc^2)
    2-D: a = z, so a x r = (-r_y, r_x). Divergence-free for every rc.
    order 1 also fills jac (M, S, S) = dv/dx:
        dv_p/dx_q = k ([a]_x[p, q] / den - 2 (a x r)_p r_q / den^2)
    (dr/dx = I - a a^T and [a]_x (I - a a^T) = [a]_x, d|r|^2/dx = 2 r).
    """
    M, S = points.shape
    k = circulation / (2.0 * math.pi)
    a0 = axis[0]
    a1 = axis[1]
    a2 = axis[2]
    if S == 2:
        a0 = 0.0
        a1 = 0.0
        a2 = 1.0
    for i in range(M):
        d0 = points[i, 0] - center[0]
        d1 = points[i, 1] - center[1]
        d2 = points[i, 2] - center[2] if S == 3 else 0.0
        da = d0 * a0 + d1 * a1 + d2 * a2
        r0 = d0 - da * a0
        r1 = d1 - da * a1
        r2 = d2 - da * a2
        c0 = a1 * r2 - a2 * r1
        c1 = a2 * r0 - a0 * r2
        c2 = a0 * r1 - a1 * r0
        den = r0 * r0 + r1 * r1 + r2 * r2 + core2
        out[i, 0] = k * c0 / den
        out[i, 1] = k * c1 / den
        if S == 3:
            out[i, 2] = k * c2 / den
        if order >= 1:
            g = 2.0 * k / (den * den)
            kd = k / den
            # [a]_x = [[0, -a2, a1], [a2, 0, -a0], [-a1, a0, 0]]
            jac[i, 0, 0] = -g * c0 * r0
            jac[i, 0, 1] = -kd * a2 - g * c0 * r1
            jac[i, 1, 0] = kd * a2 - g * c1 * r0
            jac[i, 1, 1] = -g * c1 * r1
            if S == 3:
                jac[i, 0, 2] = kd * a1 - g * c0 * r2
                jac[i, 1, 2] = -kd * a0 - g * c1 * r2
                jac[i, 2, 0] = -kd * a1 - g * c2 * r0
                jac[i, 2, 1] = kd * a0 - g * c2 * r1
                jac[i, 2, 2] = -g * c2 * r2


@njit(cache=True)
def source_field(points, center, out, jac, strength, core2, order):
    """Regularised point source (sink for negative strength), with r = x - c:
        3-D: v = Q / (4 pi) r / (|r|^2 + rc^2)^(3/2)
        2-D: v = Q / (2 pi) r / (|r|^2 + rc^2)
    Volume flux Q through any sphere (circle) enclosing the core in the limit rc -> 0.
    """
    M, S = points.shape
    for i in range(M):
        r2 = core2
        for a in range(S):
            d = points[i, a] - center[a]
            r2 += d * d
        if S == 3:
            k = strength / (4.0 * math.pi)
            f = k / (r2 * math.sqrt(r2))
            df = -3.0 * f / r2  # d f / d(|r|^2) * 2
        else:
            k = strength / (2.0 * math.pi)
            f = k / r2
            df = -2.0 * f / r2
        for a in range(S):
            out[i, a] = f * (points[i, a] - center[a])
        if order >= 1:
            for a in range(S):
                da = points[i, a] - center[a]
                for b in range(S):
                    db = points[i, b] - center[b]
                    jac[i, a, b] = df * da * db + (f if a == b else 0.0)


# ---------------------------------------------------------------------------------------------
# Boundary geometry: per point, the walls within the boundary width (curl.py's _Boundaries).
# ---------------------------------------------------------------------------------------------

@njit(cache=True, fastmath=_FAST, inline="always")
def _wall_distance(x0, x1, x2, i, w, wall_plane, plane_point, plane_normal, query_distance):
    """Signed distance of point i (x0, x1, x2) to wall w: a plane's (x - p) . n (planes are
    stored with 3 columns, zero-padded in 2-D), or a collider's query distance."""
    r = wall_plane[w]
    if r < 0:
        return query_distance[-r - 1, i]
    return ((x0 - plane_point[r, 0]) * plane_normal[r, 0] + (x1 - plane_point[r, 1]) * plane_normal[r, 1]
            + (x2 - plane_point[r, 2]) * plane_normal[r, 2])


@njit(cache=True, fastmath=_FAST)
def wall_counts(points, wall_plane, plane_point, plane_normal, query_distance, width, slot, count):
    """How many walls lie within `width` of each point: count (M,), slot (M,) (the point's first
    row in the lists `wall_rows` fills, -1 where none); returns the number of rows.

    Wall w is plane wall_plane[w] >= 0 (a point and a unit normal: a container's face, whose
    distance (x - p) . n is computed here; plane_point and plane_normal have 3 columns,
    zero-padded in 2-D) or, for wall_plane[w] < 0, the distances
    query_distance[-wall_plane[w] - 1] (M,) that a collider's query gave.
    """
    M, S = points.shape
    nw = wall_plane.shape[0]
    total = 0
    for i in range(M):
        x2 = points[i, 2] if S == 3 else 0.0
        m = 0
        for w in range(nw):
            if _wall_distance(points[i, 0], points[i, 1], x2, i, w, wall_plane, plane_point,
                              plane_normal, query_distance) < width:
                m += 1
        count[i] = m
        slot[i] = total if m > 0 else -1
        total += m
    return total


@njit(cache=True, fastmath=_FAST)
def wall_rows(points, wall_plane, wall_collider, plane_point, plane_normal, query_distance,
              width, distance, normal, collider, wall_of_row, point_of_row):
    """The rows counted by `wall_counts`, point by point and, per point, in wall order
    (collider, then plane: independent of the thread count): distance, collider, wall_of_row,
    point_of_row and, for planes, normal (rows of query walls are left to the caller)."""
    M = points.shape[0]
    S = points.shape[1]
    nw = wall_plane.shape[0]
    row = 0
    for i in range(M):
        x2 = points[i, 2] if S == 3 else 0.0
        for w in range(nw):
            d = _wall_distance(points[i, 0], points[i, 1], x2, i, w, wall_plane, plane_point,
                               plane_normal, query_distance)
            if d < width:
                distance[row] = d
                collider[row] = wall_collider[w]
                wall_of_row[row] = w
                point_of_row[row] = i
                r = wall_plane[w]
                if r >= 0:
                    for a in range(S):
                        normal[row, a] = plane_normal[r, a]
                row += 1


@njit(cache=True, fastmath=_FAST)
def collider_wall_normals(wall_of_row, point_of_row, w, point_normal, normal):
    """The rows of collider wall w take the normals its query gave at their points:
    normal[r] = point_normal[point_of_row[r]] (one pass, no index arrays)."""
    D = normal.shape[1]
    for r in range(wall_of_row.shape[0]):
        if wall_of_row[r] == w:
            i = point_of_row[r]
            for a in range(D):
                normal[r, a] = point_normal[i, a]


@njit(cache=True, fastmath=_FAST)
def sphere_hessian(points, wall_of_row, point_of_row, w, normal, center, hessian, small):
    """grad n of a sphere's signed distance on the rows of wall w (normals filled):
    hessian[r] = (I - n n^T) / |x - c| at x = points[point_of_row[r]] (the curvature of the
    sphere through x about c), zero within `small` of the centre."""
    D = points.shape[1]
    for r in range(wall_of_row.shape[0]):
        if wall_of_row[r] != w:
            continue
        i = point_of_row[r]
        r2 = 0.0
        for a in range(D):
            d = points[i, a] - center[a]
            r2 += d * d
        dist = math.sqrt(r2)
        inv = 1.0 / dist if dist > small else 0.0
        for a in range(D):
            for b in range(D):
                hessian[r, a, b] = ((1.0 if a == b else 0.0) - normal[r, a] * normal[r, b]) * inv


# ---------------------------------------------------------------------------------------------
# Boundary geometry: the Hessian of a signed distance from normals at shifted points.
# ---------------------------------------------------------------------------------------------

@njit(cache=True)
def hessian_from_normals(normal, shifted, rows, out, h, kink):
    """grad n at m points from their normals (m, D) and those at x +- h e_a.

    shifted is (2 D, R, D): shifted[2a, rows[i]] = n(x_i + h e_a), shifted[2a + 1, rows[i]] =
    n(x_i - h e_a). Central differences (n(x + h e_a) - n(x - h e_a)) / 2h where the normal
    is smooth across the stencil; one-sided where it turns by more than `kink` over one step
    (an edge of the distance field), zero if on both sides. out (m, D, D) is symmetrised.
    """
    m, D = normal.shape
    for i in range(m):
        r = rows[i]
        for a in range(D):
            jf = 0.0
            jb = 0.0
            for b in range(D):
                df = shifted[2 * a, r, b] - normal[i, b]
                db = normal[i, b] - shifted[2 * a + 1, r, b]
                jf += df * df
                jb += db * db
            kf = math.sqrt(jf) > kink
            kb = math.sqrt(jb) > kink
            for b in range(D):
                df = (shifted[2 * a, r, b] - normal[i, b]) / h
                db = (normal[i, b] - shifted[2 * a + 1, r, b]) / h
                if kf and kb:
                    out[i, a, b] = 0.0
                elif kf:
                    out[i, a, b] = db
                elif kb:
                    out[i, a, b] = df
                else:
                    out[i, a, b] = 0.5 * (df + db)
        for a in range(D):
            for b in range(a + 1, D):
                sym = 0.5 * (out[i, a, b] + out[i, b, a])
                out[i, a, b] = sym
                out[i, b, a] = sym
