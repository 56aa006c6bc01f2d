"""Numba kernels of the MAC-grid fluid: sampling with boundary ghosts, advection, forces,
divergence, gradient (the implicit viscosity operator lives in `viscosity.py`).

Every array is 3-D (a 2-D grid is a 3-D grid with one periodic cell in z and ``w = 0``), float64,
C-contiguous. ``u`` is (nx+1, ny, nz) on x-faces, ``v`` (nx, ny+1, nz) on y-faces, ``w``
(nx, ny, nz+1) on z-faces, scalars (nx, ny, nz) at cell centres. Index-space coordinates of an
array's node (i, j, k) are its position divided by the cell size minus the node offset
(0 along the face's own axis, 1/2 along the others; 1/2 along every axis for scalars).

Each field that is sampled has a *slot* (0, 1, 2: the velocity components; 3 + s: scalar s) and,
per slot, axis and side, a ghost rule for nodes outside the grid (``GhostRules``):
``NEUMANN`` (mirror: zero normal derivative; also used to clamp a face component along its own
axis), ``DIRICHLET`` (mirror about the boundary value: ``ghost = 2 * value - inside``, so the
interpolated value on the wall is ``value``), ``PERIODIC`` (wrap). A sample position is first
clamped to the domain box along non-periodic axes, so one ghost layer suffices.

Kernels write each output element from one loop iteration (``prange`` over the first index);
reductions (``dot``) sum fixed per-row partials in order, so results are identical at any
thread count.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..._jit import SizeDispatched, serial_twin

NEUMANN = 0
DIRICHLET = 1
PERIODIC = 2


class GridContext(NamedTuple):
    """What the kernels need to know about the grid (built once by `MACGrid`)."""
    n: np.ndarray          # (3,) int64 cells per axis (nz = 1 in 2-D)
    h: float               # cell size, m
    origin: np.ndarray     # (3,) float64 position of the grid's lower corner, m
    dim: int               # 2 or 3
    periodic: np.ndarray   # (3,) bool, axis wraps around
    ghost_kind: np.ndarray   # (slots, 3, 2) int64 NEUMANN / DIRICHLET / PERIODIC per axis, side
    ghost_value: np.ndarray  # (slots, 3, 2) float64 boundary value of DIRICHLET ghosts


# ----------------------------------------------------------------------------- sampling
@njit(cache=True, inline="always")
def _resolve(m, size, ncell, kind_lo, kind_hi, val_lo, val_hi):
    """Index, multiplier and offset of node m along one axis: value = add + mult * a[index]."""
    if m < 0:
        if kind_lo == PERIODIC:
            return m % ncell, 1.0, 0.0
        if kind_lo == DIRICHLET:
            return -1 - m, -1.0, 2.0 * val_lo
        return -1 - m, 1.0, 0.0
    if m >= size:
        if kind_hi == PERIODIC:
            return m % ncell, 1.0, 0.0
        if kind_hi == DIRICHLET:
            return 2 * size - 1 - m, -1.0, 2.0 * val_hi
        return 2 * size - 1 - m, 1.0, 0.0
    return m, 1.0, 0.0


@njit(cache=True)
def fetch(a, slot, i, j, k, g):
    """a[i, j, k] with the slot's ghost rules for indices outside the array."""
    return _fetch_rules(a, slot, i, j, k, g.ghost_kind, g.ghost_value, g.n)


@njit(cache=True, inline="always")
def _fetch_rules(a, slot, i, j, k, gk, gv, n):
    ii, mi, ai = _resolve(i, a.shape[0], n[0], gk[slot, 0, 0], gk[slot, 0, 1],
                          gv[slot, 0, 0], gv[slot, 0, 1])
    jj, mj, aj = _resolve(j, a.shape[1], n[1], gk[slot, 1, 0], gk[slot, 1, 1],
                          gv[slot, 1, 0], gv[slot, 1, 1])
    kk, mk, ak = _resolve(k, a.shape[2], n[2], gk[slot, 2, 0], gk[slot, 2, 1],
                          gv[slot, 2, 0], gv[slot, 2, 1])
    return ai + mi * (aj + mj * (ak + mk * a[ii, jj, kk]))


@njit(cache=True, inline="always")
def _offset(slot, axis):
    """Node offset (in cells) of a slot along an axis: 0 for a face along its own axis."""
    return 0.0 if slot == axis else 0.5


@njit(cache=True, inline="always")
def _clamp_domain(p, axis, g):
    if g.periodic[axis]:
        return p
    lo = g.origin[axis]
    hi = lo + g.n[axis] * g.h
    if p < lo:
        return lo
    if p > hi:
        return hi
    return p


@njit(cache=True)
def sample(a, slot, px, py, pz, g):
    """Linear interpolation of the slot's array at physical point (px, py, pz).

    Interior points (every node of the stencil inside the array) read the nodes directly; the
    rest go through the ghost rules (`_sample_ghost`). Both paths evaluate the same expression,
    so the result does not depend on which one ran."""
    x = (_clamp_domain(px, 0, g) - g.origin[0]) / g.h - _offset(slot, 0)
    y = (_clamp_domain(py, 1, g) - g.origin[1]) / g.h - _offset(slot, 1)
    i0 = int(math.floor(x))
    j0 = int(math.floor(y))
    fx = x - i0
    fy = y - j0
    if g.dim == 2:
        if 0 <= i0 and i0 + 1 < a.shape[0] and 0 <= j0 and j0 + 1 < a.shape[1]:
            c00 = a[i0, j0, 0]
            c10 = a[i0 + 1, j0, 0]
            c01 = a[i0, j0 + 1, 0]
            c11 = a[i0 + 1, j0 + 1, 0]
            return (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
        return _sample_ghost(a, slot, i0, j0, fx, fy, 0.0, g.ghost_kind, g.ghost_value, g.n, g.dim)
    z = (_clamp_domain(pz, 2, g) - g.origin[2]) / g.h - _offset(slot, 2)
    k0 = int(math.floor(z))
    fz = z - k0
    if (0 <= i0 and i0 + 1 < a.shape[0] and 0 <= j0 and j0 + 1 < a.shape[1]
            and 0 <= k0 and k0 + 1 < a.shape[2]):
        r = 0.0
        for dk in range(2):
            wz = fz if dk else 1.0 - fz
            kk = k0 + dk
            c00 = a[i0, j0, kk]
            c10 = a[i0 + 1, j0, kk]
            c01 = a[i0, j0 + 1, kk]
            c11 = a[i0 + 1, j0 + 1, kk]
            r += wz * ((1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11))
        return r
    return _sample_ghost(a, slot, i0, j0, fx, fy, z, g.ghost_kind, g.ghost_value, g.n, g.dim)


@njit(cache=True)
def _sample_ghost(a, slot, i0, j0, fx, fy, z, gk, gv, n, dim):
    """`sample` for stencils that reach outside the array (ghost rules per node). Takes the
    context's arrays one by one: passing the whole context to a call in a hot loop costs a
    reference-count update per member and blocks optimisation of the fast path."""
    # resolve the two nodes per axis once: value = add + mult * a[index]
    ia, mia, aia = _resolve(i0, a.shape[0], n[0], gk[slot, 0, 0], gk[slot, 0, 1], gv[slot, 0, 0], gv[slot, 0, 1])
    ib, mib, aib = _resolve(i0 + 1, a.shape[0], n[0], gk[slot, 0, 0], gk[slot, 0, 1], gv[slot, 0, 0], gv[slot, 0, 1])
    ja, mja, aja = _resolve(j0, a.shape[1], n[1], gk[slot, 1, 0], gk[slot, 1, 1], gv[slot, 1, 0], gv[slot, 1, 1])
    jb, mjb, ajb = _resolve(j0 + 1, a.shape[1], n[1], gk[slot, 1, 0], gk[slot, 1, 1], gv[slot, 1, 0], gv[slot, 1, 1])
    if dim == 2:
        c00 = aia + mia * (aja + mja * a[ia, ja, 0])
        c10 = aib + mib * (aja + mja * a[ib, ja, 0])
        c01 = aia + mia * (ajb + mjb * a[ia, jb, 0])
        c11 = aib + mib * (ajb + mjb * a[ib, jb, 0])
        return (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
    k0 = int(math.floor(z))
    fz = z - k0
    r = 0.0
    for dk in range(2):
        wz = fz if dk else 1.0 - fz
        kk, mk, ak = _resolve(k0 + dk, a.shape[2], n[2], gk[slot, 2, 0], gk[slot, 2, 1], gv[slot, 2, 0], gv[slot, 2, 1])
        c00 = aia + mia * (aja + mja * (ak + mk * a[ia, ja, kk]))
        c10 = aib + mib * (aja + mja * (ak + mk * a[ib, ja, kk]))
        c01 = aia + mia * (ajb + mjb * (ak + mk * a[ia, jb, kk]))
        c11 = aib + mib * (ajb + mjb * (ak + mk * a[ib, jb, kk]))
        r += wz * ((1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11))
    return r


@njit(cache=True)
def sample_range(a, slot, px, py, pz, g):
    """Minimum and maximum of the nodes that `sample` interpolates at the point."""
    x = (_clamp_domain(px, 0, g) - g.origin[0]) / g.h - _offset(slot, 0)
    y = (_clamp_domain(py, 1, g) - g.origin[1]) / g.h - _offset(slot, 1)
    i0 = int(math.floor(x))
    j0 = int(math.floor(y))
    nk = 1
    k0 = 0
    if dim == 3:
        z = (_clamp_domain(pz, 2, g) - g.origin[2]) / g.h - _offset(slot, 2)
        k0 = int(math.floor(z))
        nk = 2
    lo = np.inf
    hi = -np.inf
    for dk in range(nk):
        for dj in range(2):
            for di in range(2):
                c = fetch(a, slot, i0 + di, j0 + dj, k0 + dk, g)
                lo = min(lo, c)
                hi = max(hi, c)
    return lo, hi


@njit(cache=True)
def velocity_at(u, v, w, px, py, pz, g):
    vx = sample(u, 0, px, py, pz, g)
    vy = sample(v, 1, px, py, pz, g)
    vz = sample(w, 2, px, py, pz, g) if g.dim == 3 else 0.0
    return vx, vy, vz


@njit(cache=True)
def _node_position(slot, i, j, k, g):
    px = g.origin[0] + (i + _offset(slot, 0)) * g.h
    py = g.origin[1] + (j + _offset(slot, 1)) * g.h
    pz = g.origin[2] + (k + _offset(slot, 2)) * g.h
    return px, py, pz


@njit(cache=True)
def _backtrace(px, py, pz, u, v, w, dt, g):
    """Second-order Runge-Kutta (midpoint) back-trace x - dt u(x - dt/2 u(x))."""
    vx, vy, vz = velocity_at(u, v, w, px, py, pz, g)
    mx = px - 0.5 * dt * vx
    my = py - 0.5 * dt * vy
    mz = pz - 0.5 * dt * vz
    vx, vy, vz = velocity_at(u, v, w, mx, my, mz, g)
    return px - dt * vx, py - dt * vy, pz - dt * vz


@njit(cache=True, parallel=True)
def sample_points(u, v, w, points, g, out):
    """Velocity at (M, D) points into out (M, D)."""
    m = points.shape[0]
    d = points.shape[1]
    for p_ in prange(m):
        p = np.int64(p_)
        pz = points[p, 2] if d == 3 else g.origin[2] + 0.5 * g.h
        vx, vy, vz = velocity_at(u, v, w, points[p, 0], points[p, 1], pz, g)
        out[p, 0] = vx
        out[p, 1] = vy
        if d == 3:
            out[p, 2] = vz


@njit(cache=True, parallel=True)
def sample_scalar_points(a, slot, points, g, out):
    """Scalar (slot >= 3) at (M, D) points into out (M,)."""
    m = points.shape[0]
    d = points.shape[1]
    for p_ in prange(m):
        p = np.int64(p_)
        pz = points[p, 2] if d == 3 else g.origin[2] + 0.5 * g.h
        out[p] = sample(a, slot, points[p, 0], points[p, 1], pz, g)


# ----------------------------------------------------------------------------- advection
# Advection samples *padded* copies of the fields: one ghost layer on every side of the grid's
# axes (not along z in 2-D) filled once per field and step from the ghost rules (`pad`), so
# the sampling loop has no boundary cases, no calls and no context lookups: a call with arrays
# inside a Numba loop costs reference-count updates and blocks optimisation (measured 10x
# slower per interpolation). Positions are in index space: X = (position - origin) / h, cell
# corners at integers, node (i, j, k) of slot s at X = (i, j, k) + offset(s); padded index =
# node index + 1 along padded axes.
@njit(cache=True)
def pad(a, slot, g, out):
    """out = a with one ghost layer (slot's ghost rules) along x, y (and z in 3-D).
    out: (a.shape[0] + 2, a.shape[1] + 2, a.shape[2] + 2 in 3-D or 1 in 2-D)."""
    px, py, pz = out.shape
    kz = 1 if g.dim == 3 else 0
    out[1:px - 1, 1:py - 1, kz:pz - kz] = a
    for I in range(px):
        for J in range(py):
            edge = I == 0 or I == px - 1 or J == 0 or J == py - 1
            if edge:
                for K in range(pz):
                    out[I, J, K] = fetch(a, slot, I - 1, J - 1, K - kz, g)
            elif kz == 1:
                out[I, J, 0] = fetch(a, slot, I - 1, J - 1, -1, g)
                out[I, J, pz - 1] = fetch(a, slot, I - 1, J - 1, pz - 2, g)


@njit(cache=True, inline="always")
def _place(x, n, periodic):
    """An index-space coordinate mapped into the domain: wrapped onto [0, n) on a periodic
    axis, clamped to [0, n] otherwise."""
    if periodic:
        return x - n * math.floor(x / n)
    if x < 0.0:
        return 0.0
    if x > n:
        return float(n)
    return x


# Interpolation is written out in the loop body (no helper taking arrays: see above).
@njit(cache=True, parallel=True)
def advect_padded(src, u, v, w, s, offset, n, periodic, dim, dst, lo, hi, want_range):
    """Semi-Lagrangian advection (Stam 1999) with an RK2 (midpoint) back-trace in index space,
    X_back = X - s u(X - s/2 u(X)), s = dt / h: dst(X) = src(X_back), (bi/tri)linear
    interpolation. src, u, v, w are padded (`pad`); dst, lo, hi are unpadded like the field.
    With `want_range` also the minimum and maximum of the src nodes interpolated at X_back go
    into lo, hi (MacCormack's limiter)."""
    nx, ny, nz = dst.shape
    ox, oy, oz = offset[0], offset[1], offset[2]
    gx, gy, gz = n[0], n[1], n[2]
    qx, qy, qz = periodic[0], periodic[1], periodic[2]
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                x = i + ox
                y = j + oy
                if dim == 2:
                    xx = x + 1.0
                    yy = y + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vx = ((1 - fy) * ((1 - fx) * u[i0, j0, 0] + fx * u[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, 0] + fx * u[i0 + 1, j0 + 1, 0]))
                    xx = x + 0.5
                    yy = y + 1.0
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vy = ((1 - fy) * ((1 - fx) * v[i0, j0, 0] + fx * v[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, 0] + fx * v[i0 + 1, j0 + 1, 0]))
                    mx = _place(x - 0.5 * s * vx, gx, qx)
                    my = _place(y - 0.5 * s * vy, gy, qy)
                    xx = mx + 1.0
                    yy = my + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vx = ((1 - fy) * ((1 - fx) * u[i0, j0, 0] + fx * u[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, 0] + fx * u[i0 + 1, j0 + 1, 0]))
                    xx = mx + 0.5
                    yy = my + 1.0
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vy = ((1 - fy) * ((1 - fx) * v[i0, j0, 0] + fx * v[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, 0] + fx * v[i0 + 1, j0 + 1, 0]))
                    bx = _place(x - s * vx, gx, qx) - ox + 1.0
                    by = _place(y - s * vy, gy, qy) - oy + 1.0
                    xx = bx
                    yy = by
                    i0 = min(int(xx), src.shape[0] - 2)
                    j0 = min(int(yy), src.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    val = ((1 - fy) * ((1 - fx) * src[i0, j0, 0] + fx * src[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * src[i0, j0 + 1, 0] + fx * src[i0 + 1, j0 + 1, 0]))
                    dst[i, j, k] = val
                    if want_range:
                        c0 = src[i0, j0, 0]
                        c1 = src[i0 + 1, j0, 0]
                        c2 = src[i0, j0 + 1, 0]
                        c3 = src[i0 + 1, j0 + 1, 0]
                        lo[i, j, k] = min(min(c0, c1), min(c2, c3))
                        hi[i, j, k] = max(max(c0, c1), max(c2, c3))
                else:
                    z = k + oz
                    xx = x + 1.0
                    yy = y + 0.5
                    zz = z + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    k0 = min(int(zz), u.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vx = (1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vx = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * u[i0, j0, k1] + fx * u[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k1] + fx * u[i0 + 1, j0 + 1, k1]))
                        vx = (1 - fz) * b0 + fz * b1
                    xx = x + 0.5
                    yy = y + 1.0
                    zz = z + 0.5
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    k0 = min(int(zz), v.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vy = (1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vy = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * v[i0, j0, k1] + fx * v[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k1] + fx * v[i0 + 1, j0 + 1, k1]))
                        vy = (1 - fz) * b0 + fz * b1
                    xx = x + 0.5
                    yy = y + 0.5
                    zz = z + 1.0
                    i0 = min(int(xx), w.shape[0] - 2)
                    j0 = min(int(yy), w.shape[1] - 2)
                    k0 = min(int(zz), w.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vz = (1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vz = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * w[i0, j0, k1] + fx * w[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k1] + fx * w[i0 + 1, j0 + 1, k1]))
                        vz = (1 - fz) * b0 + fz * b1
                    mx = _place(x - 0.5 * s * vx, gx, qx)
                    my = _place(y - 0.5 * s * vy, gy, qy)
                    mz = _place(z - 0.5 * s * vz, gz, qz)
                    xx = mx + 1.0
                    yy = my + 0.5
                    zz = mz + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    k0 = min(int(zz), u.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * u[i0, j0, k1] + fx * u[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * u[i0, j0 + 1, k1] + fx * u[i0 + 1, j0 + 1, k1]))
                    vx = (1 - fz) * b0 + fz * b1
                    xx = mx + 0.5
                    yy = my + 1.0
                    zz = mz + 0.5
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    k0 = min(int(zz), v.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * v[i0, j0, k1] + fx * v[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * v[i0, j0 + 1, k1] + fx * v[i0 + 1, j0 + 1, k1]))
                    vy = (1 - fz) * b0 + fz * b1
                    xx = mx + 0.5
                    yy = my + 0.5
                    zz = mz + 1.0
                    i0 = min(int(xx), w.shape[0] - 2)
                    j0 = min(int(yy), w.shape[1] - 2)
                    k0 = min(int(zz), w.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * w[i0, j0, k1] + fx * w[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * w[i0, j0 + 1, k1] + fx * w[i0 + 1, j0 + 1, k1]))
                    vz = (1 - fz) * b0 + fz * b1
                    bx = _place(x - s * vx, gx, qx) - ox + 1.0
                    by = _place(y - s * vy, gy, qy) - oy + 1.0
                    bz = _place(z - s * vz, gz, qz) - oz + 1.0
                    xx = bx
                    yy = by
                    zz = bz
                    i0 = min(int(xx), src.shape[0] - 2)
                    j0 = min(int(yy), src.shape[1] - 2)
                    k0 = min(int(zz), src.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * src[i0, j0, k0] + fx * src[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * src[i0, j0 + 1, k0] + fx * src[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * src[i0, j0, k1] + fx * src[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * src[i0, j0 + 1, k1] + fx * src[i0 + 1, j0 + 1, k1]))
                    val = (1 - fz) * b0 + fz * b1
                    dst[i, j, k] = val
                    if want_range:
                        a = src[i0, j0, k0]
                        b = a
                        for dk in range(2):
                            for dj in range(2):
                                for di in range(2):
                                    c = src[i0 + di, j0 + dj, k0 + dk]
                                    a = min(a, c)
                                    b = max(b, c)
                        lo[i, j, k] = a
                        hi[i, j, k] = b


@njit(cache=True, parallel=True)
def advect_padded_pair(src, src2, u, v, w, s, offset, n, periodic, dim, dst, dst2, lo, hi, lo2,
                       hi2, want_range):
    """`advect_padded` for two fields of the same slot kind (two cell scalars) along one
    back-trace: the trace (six velocity interpolations) is shared, each field adds one
    interpolation. Same arithmetic per field as `advect_padded`, so identical results."""
    nx, ny, nz = dst.shape
    ox, oy, oz = offset[0], offset[1], offset[2]
    gx, gy, gz = n[0], n[1], n[2]
    qx, qy, qz = periodic[0], periodic[1], periodic[2]
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                x = i + ox
                y = j + oy
                if dim == 2:
                    xx = x + 1.0
                    yy = y + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vx = ((1 - fy) * ((1 - fx) * u[i0, j0, 0] + fx * u[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, 0] + fx * u[i0 + 1, j0 + 1, 0]))
                    xx = x + 0.5
                    yy = y + 1.0
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vy = ((1 - fy) * ((1 - fx) * v[i0, j0, 0] + fx * v[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, 0] + fx * v[i0 + 1, j0 + 1, 0]))
                    mx = _place(x - 0.5 * s * vx, gx, qx)
                    my = _place(y - 0.5 * s * vy, gy, qy)
                    xx = mx + 1.0
                    yy = my + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vx = ((1 - fy) * ((1 - fx) * u[i0, j0, 0] + fx * u[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, 0] + fx * u[i0 + 1, j0 + 1, 0]))
                    xx = mx + 0.5
                    yy = my + 1.0
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    vy = ((1 - fy) * ((1 - fx) * v[i0, j0, 0] + fx * v[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, 0] + fx * v[i0 + 1, j0 + 1, 0]))
                    bx = _place(x - s * vx, gx, qx) - ox + 1.0
                    by = _place(y - s * vy, gy, qy) - oy + 1.0
                    xx = bx
                    yy = by
                    i0 = min(int(xx), src.shape[0] - 2)
                    j0 = min(int(yy), src.shape[1] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    val = ((1 - fy) * ((1 - fx) * src[i0, j0, 0] + fx * src[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * src[i0, j0 + 1, 0] + fx * src[i0 + 1, j0 + 1, 0]))
                    dst[i, j, k] = val
                    if want_range:
                        c0 = src[i0, j0, 0]
                        c1 = src[i0 + 1, j0, 0]
                        c2 = src[i0, j0 + 1, 0]
                        c3 = src[i0 + 1, j0 + 1, 0]
                        lo[i, j, k] = min(min(c0, c1), min(c2, c3))
                        hi[i, j, k] = max(max(c0, c1), max(c2, c3))
                    val = ((1 - fy) * ((1 - fx) * src2[i0, j0, 0] + fx * src2[i0 + 1, j0, 0])
                          + fy * ((1 - fx) * src2[i0, j0 + 1, 0] + fx * src2[i0 + 1, j0 + 1, 0]))
                    dst2[i, j, k] = val
                    if want_range:
                        c0 = src2[i0, j0, 0]
                        c1 = src2[i0 + 1, j0, 0]
                        c2 = src2[i0, j0 + 1, 0]
                        c3 = src2[i0 + 1, j0 + 1, 0]
                        lo2[i, j, k] = min(min(c0, c1), min(c2, c3))
                        hi2[i, j, k] = max(max(c0, c1), max(c2, c3))
                else:
                    z = k + oz
                    xx = x + 1.0
                    yy = y + 0.5
                    zz = z + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    k0 = min(int(zz), u.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vx = (1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vx = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * u[i0, j0, k1] + fx * u[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * u[i0, j0 + 1, k1] + fx * u[i0 + 1, j0 + 1, k1]))
                        vx = (1 - fz) * b0 + fz * b1
                    xx = x + 0.5
                    yy = y + 1.0
                    zz = z + 0.5
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    k0 = min(int(zz), v.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vy = (1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vy = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * v[i0, j0, k1] + fx * v[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * v[i0, j0 + 1, k1] + fx * v[i0 + 1, j0 + 1, k1]))
                        vy = (1 - fz) * b0 + fz * b1
                    xx = x + 0.5
                    yy = y + 0.5
                    zz = z + 1.0
                    i0 = min(int(xx), w.shape[0] - 2)
                    j0 = min(int(yy), w.shape[1] - 2)
                    k0 = min(int(zz), w.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    # at a node the fractions are 0 or 1/2: skip the zero-weight rows
                    if fz == 0.0 and fy == 0.0:
                        vz = (1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0]
                    elif fz == 0.0:
                        vz = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                    else:
                        b0 = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                        b1 = ((1 - fy) * ((1 - fx) * w[i0, j0, k1] + fx * w[i0 + 1, j0, k1])
                              + fy * ((1 - fx) * w[i0, j0 + 1, k1] + fx * w[i0 + 1, j0 + 1, k1]))
                        vz = (1 - fz) * b0 + fz * b1
                    mx = _place(x - 0.5 * s * vx, gx, qx)
                    my = _place(y - 0.5 * s * vy, gy, qy)
                    mz = _place(z - 0.5 * s * vz, gz, qz)
                    xx = mx + 1.0
                    yy = my + 0.5
                    zz = mz + 0.5
                    i0 = min(int(xx), u.shape[0] - 2)
                    j0 = min(int(yy), u.shape[1] - 2)
                    k0 = min(int(zz), u.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * u[i0, j0, k0] + fx * u[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * u[i0, j0 + 1, k0] + fx * u[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * u[i0, j0, k1] + fx * u[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * u[i0, j0 + 1, k1] + fx * u[i0 + 1, j0 + 1, k1]))
                    vx = (1 - fz) * b0 + fz * b1
                    xx = mx + 0.5
                    yy = my + 1.0
                    zz = mz + 0.5
                    i0 = min(int(xx), v.shape[0] - 2)
                    j0 = min(int(yy), v.shape[1] - 2)
                    k0 = min(int(zz), v.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * v[i0, j0, k0] + fx * v[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * v[i0, j0 + 1, k0] + fx * v[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * v[i0, j0, k1] + fx * v[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * v[i0, j0 + 1, k1] + fx * v[i0 + 1, j0 + 1, k1]))
                    vy = (1 - fz) * b0 + fz * b1
                    xx = mx + 0.5
                    yy = my + 0.5
                    zz = mz + 1.0
                    i0 = min(int(xx), w.shape[0] - 2)
                    j0 = min(int(yy), w.shape[1] - 2)
                    k0 = min(int(zz), w.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * w[i0, j0, k0] + fx * w[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * w[i0, j0 + 1, k0] + fx * w[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * w[i0, j0, k1] + fx * w[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * w[i0, j0 + 1, k1] + fx * w[i0 + 1, j0 + 1, k1]))
                    vz = (1 - fz) * b0 + fz * b1
                    bx = _place(x - s * vx, gx, qx) - ox + 1.0
                    by = _place(y - s * vy, gy, qy) - oy + 1.0
                    bz = _place(z - s * vz, gz, qz) - oz + 1.0
                    xx = bx
                    yy = by
                    zz = bz
                    i0 = min(int(xx), src.shape[0] - 2)
                    j0 = min(int(yy), src.shape[1] - 2)
                    k0 = min(int(zz), src.shape[2] - 2)
                    fx = xx - i0
                    fy = yy - j0
                    fz = zz - k0
                    k1 = k0 + 1
                    b0 = ((1 - fy) * ((1 - fx) * src[i0, j0, k0] + fx * src[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * src[i0, j0 + 1, k0] + fx * src[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * src[i0, j0, k1] + fx * src[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * src[i0, j0 + 1, k1] + fx * src[i0 + 1, j0 + 1, k1]))
                    val = (1 - fz) * b0 + fz * b1
                    dst[i, j, k] = val
                    if want_range:
                        a = src[i0, j0, k0]
                        b = a
                        for dk in range(2):
                            for dj in range(2):
                                for di in range(2):
                                    c = src[i0 + di, j0 + dj, k0 + dk]
                                    a = min(a, c)
                                    b = max(b, c)
                        lo[i, j, k] = a
                        hi[i, j, k] = b
                    b0 = ((1 - fy) * ((1 - fx) * src2[i0, j0, k0] + fx * src2[i0 + 1, j0, k0])
                          + fy * ((1 - fx) * src2[i0, j0 + 1, k0] + fx * src2[i0 + 1, j0 + 1, k0]))
                    b1 = ((1 - fy) * ((1 - fx) * src2[i0, j0, k1] + fx * src2[i0 + 1, j0, k1])
                          + fy * ((1 - fx) * src2[i0, j0 + 1, k1] + fx * src2[i0 + 1, j0 + 1, k1]))
                    val = (1 - fz) * b0 + fz * b1
                    dst2[i, j, k] = val
                    if want_range:
                        a = src2[i0, j0, k0]
                        b = a
                        for dk in range(2):
                            for dj in range(2):
                                for di in range(2):
                                    c = src2[i0 + di, j0 + dj, k0 + dk]
                                    a = min(a, c)
                                    b = max(b, c)
                        lo2[i, j, k] = a
                        hi2[i, j, k] = b


@njit(cache=True, parallel=True)
def maccormack_combine(src, forward, backward, lo, hi, dst):
    """MacCormack step (Selle et al. 2008): dst = forward + (src - backward) / 2, clamped to
    [lo, hi], the range of the src nodes the forward step interpolated (keeps it bounded)."""
    nx, ny, nz = src.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                val = forward[i, j, k] + 0.5 * (src[i, j, k] - backward[i, j, k])
                if val < lo[i, j, k]:
                    val = lo[i, j, k]
                elif val > hi[i, j, k]:
                    val = hi[i, j, k]
                dst[i, j, k] = val


# ----------------------------------------------------------------------------- boundaries
@njit(cache=True, parallel=True)
def enforce_faces(vel, open_frac, solid_vel, axis, periodic):
    """Faces closed to the fluid (open fraction 0: inside obstacles, walls, inflow) take the
    solid's (or inflow's) velocity; a periodic axis copies face 0 to face n."""
    nx, ny, nz = vel.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                if open_frac[i, j, k] == 0.0:
                    vel[i, j, k] = solid_vel[i, j, k]
    if periodic:
        if axis == 0:
            vel[nx - 1, :, :] = vel[0, :, :]
        elif axis == 1:
            vel[:, ny - 1, :] = vel[:, 0, :]
        else:
            vel[:, :, nz - 1] = vel[:, :, 0]


@njit(cache=True)
def enforce_closed(vel, closed, solid_vel):
    """`enforce_faces` from the list of closed faces (flat indices into the C-order face
    array): vel[f] = solid_vel[f]. Touches only those faces (the domain sides' and the
    obstacles'), not the whole array."""
    for m in range(closed.shape[0]):
        f = closed[m]
        vel[f] = solid_vel[f]


# ----------------------------------------------------------------------------- projection
@njit(cache=True, parallel=True)
def weighted_divergence(u, v, w, fu, fv, fw, su, sv, sw, g, out):
    """Divergence of the face velocities blended with the solid's: on each face the flux is
    A u + (1 - A) u_solid (Batty, Bertails and Bridson 2007), divided by h. out (nx, ny, nz), 1/s."""
    nx, ny, nz = out.shape
    inv_h = 1.0 / g.h
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                d = (fu[i + 1, j, k] * u[i + 1, j, k] + (1 - fu[i + 1, j, k]) * su[i + 1, j, k]
                     - fu[i, j, k] * u[i, j, k] - (1 - fu[i, j, k]) * su[i, j, k]
                     + fv[i, j + 1, k] * v[i, j + 1, k] + (1 - fv[i, j + 1, k]) * sv[i, j + 1, k]
                     - fv[i, j, k] * v[i, j, k] - (1 - fv[i, j, k]) * sv[i, j, k])
                if g.dim == 3:
                    d += (fw[i, j, k + 1] * w[i, j, k + 1] + (1 - fw[i, j, k + 1]) * sw[i, j, k + 1]
                          - fw[i, j, k] * w[i, j, k] - (1 - fw[i, j, k]) * sw[i, j, k])
                out[i, j, k] = d * inv_h


@njit(cache=True)
def _cell_or_ghost(phi, i, j, k, nx, ny, nz, px, py, pz):
    """phi at a cell index that may be one outside: wrapped if periodic, else 0 (outflow)."""
    if i < 0 or i >= nx:
        if not px:
            return 0.0
        i = i % nx
    if j < 0 or j >= ny:
        if not py:
            return 0.0
        j = j % ny
    if k < 0 or k >= nz:
        if not pz:
            return 0.0
        k = k % nz
    return phi[i, j, k]


@njit(cache=True, parallel=True)
def subtract_gradient(phi, fu, fv, fw, g, u, v, w):
    """u -= grad(phi) on faces open to the fluid (phi = p dt / rho, m^2/s; outside an outflow
    face phi = 0; a periodic axis wraps)."""
    nx, ny, nz = phi.shape
    px, py, pz = g.periodic[0], g.periodic[1], g.periodic[2]
    inv_h = 1.0 / g.h
    dim = g.dim
    for i_ in prange(nx + 1):
        i = np.int64(i_)
        # x-faces: cells i - 1 and i (wrapped or outside)
        il = i - 1
        ir = i
        il_ok = il >= 0
        ir_ok = ir < nx
        if px:
            il = il % nx
            ir = ir % nx
            il_ok = True
            ir_ok = True
        for j in range(ny + 1):
            for k in range(nz + 1):
                if j < ny and k < nz and fu[i, j, k] > 0.0:
                    a = phi[ir, j, k] if ir_ok else 0.0
                    b = phi[il, j, k] if il_ok else 0.0
                    u[i, j, k] -= (a - b) * inv_h
                if i < nx and k < nz and fv[i, j, k] > 0.0:
                    jl = j - 1
                    jr = j
                    a = 0.0
                    b = 0.0
                    if py:
                        a = phi[i, jr % ny, k]
                        b = phi[i, jl % ny, k]
                    else:
                        if jr < ny:
                            a = phi[i, jr, k]
                        if jl >= 0:
                            b = phi[i, jl, k]
                    v[i, j, k] -= (a - b) * inv_h
                if dim == 3 and i < nx and j < ny and fw[i, j, k] > 0.0:
                    kl = k - 1
                    kr = k
                    a = 0.0
                    b = 0.0
                    if pz:
                        a = phi[i, j, kr % nz]
                        b = phi[i, j, kl % nz]
                    else:
                        if kr < nz:
                            a = phi[i, j, kr]
                        if kl >= 0:
                            b = phi[i, j, kl]
                    w[i, j, k] -= (a - b) * inv_h


@njit(cache=True)
def cell_node_kinds(solid, solid_kind, fluid_kind, kind):
    """kind = solid_kind where a cell centre is inside a solid, fluid_kind elsewhere (the scalar
    diffusion's node kinds, `viscosity.FREE` / `AIR`)."""
    sf = solid.reshape(-1)
    kf = kind.reshape(-1)
    for m in range(sf.shape[0]):
        kf[m] = solid_kind if sf[m] else fluid_kind


@njit(cache=True)
def held_cell_kinds(solid, best, near, held, free, insulated, fixed, kind, sdf, wall):
    """Node kinds of a scalar held on some obstacles (held[o]: its value, NaN: insulating): a
    solid cell whose nearest obstacle holds a value is `fixed` with wall = that value, other
    solid cells `insulated`, fluid cells `free` (wall = the value of their nearest obstacle, the
    surface value the ghost-fluid interpolation reads); sdf = the nearest obstacle's signed
    distance at the cell centre (flat arrays)."""
    for m in range(solid.shape[0]):
        v = held[near[m]]
        sdf[m] = best[m]
        wall[m] = v if v == v else 0.0
        if not solid[m]:
            kind[m] = free
        elif v == v:
            kind[m] = fixed
        else:
            kind[m] = insulated


@njit(cache=True)
def copy_where_kind(kind, k, src, dst):
    """dst[m] = src[m] where kind[m] == k (flat arrays)."""
    for m in range(kind.shape[0]):
        if kind[m] == k:
            dst[m] = src[m]


@njit(cache=True, inline="always")
def _side_face(axis, side, a, b, nface):
    """(face index, adjacent cell index) of entry (a, b) of a side's face layer: faces are
    (i, j, k) with the `axis` index 0 (side 0) or nface - 1 (side 1), a and b the other two
    indices in order."""
    m = 0 if side == 0 else nface - 1
    c = 0 if side == 0 else nface - 2
    if axis == 0:
        return m, a, b, c, a, b
    if axis == 1:
        return a, m, b, a, c, b
    return a, b, m, a, b, c


@njit(cache=True)
def pressure_side_rhs(frac, axis, side, value, inv_h2, rhs):
    """Dirichlet data of a prescribed-pressure side in the Poisson right-hand side: the cell next
    to each open face of the side gets 2 A_f value / h^2 (value = phi on the face, p dt / rho;
    the face coefficient is 2 A_f / h^2, `PoissonSolver.set_coefficients`)."""
    n0, n1 = (frac.shape[1], frac.shape[2]) if axis == 0 else (
        (frac.shape[0], frac.shape[2]) if axis == 1 else (frac.shape[0], frac.shape[1]))
    for a in range(n0):
        for b in range(n1):
            fi, fj, fk, ci, cj, ck = _side_face(axis, side, a, b, frac.shape[axis])
            rhs[ci, cj, ck] += 2.0 * frac[fi, fj, fk] * value * inv_h2


@njit(cache=True)
def pressure_side_gradient(phi, frac, axis, side, value, inv_h, vel):
    """Complete `subtract_gradient` on the open faces of a prescribed-pressure side: it took
    phi = 0 one cell outside; the value sits on the face, half a cell from the cell centre, so
    the face's gradient is 2 (value - phi_c) / h outward. Low side: vel -= (phi_c - 2 value) / h
    more; high side: vel -= (2 value - phi_c) / h more."""
    n0, n1 = (frac.shape[1], frac.shape[2]) if axis == 0 else (
        (frac.shape[0], frac.shape[2]) if axis == 1 else (frac.shape[0], frac.shape[1]))
    for a in range(n0):
        for b in range(n1):
            fi, fj, fk, ci, cj, ck = _side_face(axis, side, a, b, frac.shape[axis])
            if frac[fi, fj, fk] > 0.0:
                pc = phi[ci, cj, ck]
                if side == 0:
                    vel[fi, fj, fk] -= (pc - 2.0 * value) * inv_h
                else:
                    vel[fi, fj, fk] -= (2.0 * value - pc) * inv_h


# ----------------------------------------------------------------------------- forces
@njit(cache=True, parallel=True)
def cell_velocity_and_vorticity(u, v, w, g, vort):
    """Vorticity at cell centres from central differences of the cell-averaged velocity.
    vort (nx, ny, nz, 3), 1/s (2-D: only component 2 is used)."""
    nx, ny, nz = vort.shape[0], vort.shape[1], vort.shape[2]
    inv2h = 0.5 / g.h
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                # cell-centred velocities of neighbours via sample (ghost rules apply)
                px, py, pz = _node_position(3, i, j, k, g)
                h = g.h
                vyp = sample(v, 1, px + h, py, pz, g)
                vym = sample(v, 1, px - h, py, pz, g)
                uxp = sample(u, 0, px, py + h, pz, g)
                uxm = sample(u, 0, px, py - h, pz, g)
                wz = (vyp - vym - uxp + uxm) * inv2h
                wx = 0.0
                wy = 0.0
                if g.dim == 3:
                    wyp = sample(w, 2, px, py + h, pz, g)
                    wym = sample(w, 2, px, py - h, pz, g)
                    vzp = sample(v, 1, px, py, pz + h, g)
                    vzm = sample(v, 1, px, py, pz - h, g)
                    uzp = sample(u, 0, px, py, pz + h, g)
                    uzm = sample(u, 0, px, py, pz - h, g)
                    wxp = sample(w, 2, px + h, py, pz, g)
                    wxm = sample(w, 2, px - h, py, pz, g)
                    wx = (wyp - wym - vzp + vzm) * inv2h
                    wy = (uzp - uzm - wxp + wxm) * inv2h
                vort[i, j, k, 0] = wx
                vort[i, j, k, 1] = wy
                vort[i, j, k, 2] = wz


@njit(cache=True, parallel=True)
def confinement_force(vort, epsilon, g, force):
    """Vorticity confinement (Fedkiw, Stam and Jensen 2001): f = epsilon h (N x omega) with
    N = grad|omega| / |grad|omega||, at cell centres. force (nx, ny, nz, 3), m/s^2."""
    nx, ny, nz = vort.shape[0], vort.shape[1], vort.shape[2]
    inv2h = 0.5 / g.h
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                ip = min(i + 1, nx - 1)
                im = max(i - 1, 0)
                jp = min(j + 1, ny - 1)
                jm = max(j - 1, 0)
                if g.periodic[0]:
                    ip = (i + 1) % nx
                    im = (i - 1) % nx
                if g.periodic[1]:
                    jp = (j + 1) % ny
                    jm = (j - 1) % ny
                gx = (_mag(vort, ip, j, k) - _mag(vort, im, j, k)) * inv2h
                gy = (_mag(vort, i, jp, k) - _mag(vort, i, jm, k)) * inv2h
                gz = 0.0
                if g.dim == 3:
                    kp = min(k + 1, nz - 1)
                    km = max(k - 1, 0)
                    if g.periodic[2]:
                        kp = (k + 1) % nz
                        km = (k - 1) % nz
                    gz = (_mag(vort, i, j, kp) - _mag(vort, i, j, km)) * inv2h
                norm = math.sqrt(gx * gx + gy * gy + gz * gz) + 1e-12 / g.h
                nxv = gx / norm
                nyv = gy / norm
                nzv = gz / norm
                ox = vort[i, j, k, 0]
                oy = vort[i, j, k, 1]
                oz = vort[i, j, k, 2]
                s = epsilon * g.h
                force[i, j, k, 0] = s * (nyv * oz - nzv * oy)
                force[i, j, k, 1] = s * (nzv * ox - nxv * oz)
                force[i, j, k, 2] = s * (nxv * oy - nyv * ox)


@njit(cache=True)
def _mag(vort, i, j, k):
    return math.sqrt(vort[i, j, k, 0] ** 2 + vort[i, j, k, 1] ** 2 + vort[i, j, k, 2] ** 2)


@njit(cache=True, parallel=True)
def add_cell_force(force, dt, axis, open_frac, g, vel):
    """vel += dt * (average of the two cells' force component `axis`) on open faces; a cell
    index one outside wraps on a periodic axis and clamps to the edge cell otherwise (written
    out: a helper taking the force array would cost a reference-count update per face)."""
    nx, ny, nz = force.shape[0], force.shape[1], force.shape[2]
    fx, fy, fz = vel.shape
    per = g.periodic[axis]
    na = nx if axis == 0 else (ny if axis == 1 else nz)
    for i_ in prange(fx):
        i = np.int64(i_)
        for j in range(fy):
            for k in range(fz):
                if open_frac[i, j, k] == 0.0:
                    continue
                m = i if axis == 0 else (j if axis == 1 else k)
                lo = m - 1
                hi = m
                if lo < 0:
                    lo = lo % na if per else 0
                if hi >= na:
                    hi = hi % na if per else na - 1
                if axis == 0:
                    a = force[lo, j, k, 0]
                    b = force[hi, j, k, 0]
                elif axis == 1:
                    a = force[i, lo, k, 1]
                    b = force[i, hi, k, 1]
                else:
                    a = force[i, j, lo, 2]
                    b = force[i, j, hi, 2]
                vel[i, j, k] += dt * 0.5 * (a + b)


@njit(cache=True)
def _cell_force(force, i, j, k, axis, nx, ny, nz, g):
    # one cell outside: periodic wrap, else the inside cell's force
    if i < 0 or i >= nx:
        i = i % nx if g.periodic[0] else min(max(i, 0), nx - 1)
    if j < 0 or j >= ny:
        j = j % ny if g.periodic[1] else min(max(j, 0), ny - 1)
    if k < 0 or k >= nz:
        k = k % nz if g.periodic[2] else min(max(k, 0), nz - 1)
    return force[i, j, k, axis]


@njit(cache=True, parallel=True)
def buoyancy_force(density, temperature, alpha, beta, ambient, up, force):
    """Boussinesq buoyancy (Fedkiw, Stam and Jensen 2001): f = (-alpha d + beta (T - T_amb)) up,
    added to force (nx, ny, nz, 3), m/s^2."""
    nx, ny, nz = density.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                b = -alpha * density[i, j, k] + beta * (temperature[i, j, k] - ambient)
                force[i, j, k, 0] += b * up[0]
                force[i, j, k, 1] += b * up[1]
                force[i, j, k, 2] += b * up[2]


# ----------------------------------------------------------------------------- vector algebra
@njit(cache=True, parallel=True)
def dot(a, b, partial):
    """Sum of a * b with fixed per-row partial sums (deterministic at any thread count)."""
    nx, ny, nz = a.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        s = 0.0
        for j in range(ny):
            for k in range(nz):
                s += a[i, j, k] * b[i, j, k]
        partial[i] = s
    t = 0.0
    for i in range(nx):
        t += partial[i]
    return t


@njit(cache=True, parallel=True)
def axpy(alpha, x, y):
    """y += alpha * x."""
    nx = x.shape[0]
    for i_ in prange(nx):
        i = np.int64(i_)
        y[i] += alpha * x[i]


@njit(cache=True, parallel=True)
def xpby(x, beta, y):
    """y = x + beta * y."""
    nx = x.shape[0]
    for i_ in prange(nx):
        i = np.int64(i_)
        y[i] = x[i] + beta * y[i]


@njit(cache=True, parallel=True)
def scale_decay(a, factor):
    """a *= factor (scalar dissipation)."""
    nx = a.shape[0]
    for i_ in prange(nx):
        i = np.int64(i_)
        a[i] *= factor


@njit(cache=True, parallel=True)
def max_abs(a, partial):
    """Largest |a| (inf if any entry is NaN), deterministic."""
    nx = a.shape[0]
    for i_ in prange(nx):
        i = np.int64(i_)
        m = 0.0
        for j in range(a.shape[1]):
            for k in range(a.shape[2]):
                x = abs(a[i, j, k])
                if x > m:
                    m = x
                elif not x <= m:  # NaN
                    m = np.inf
        partial[i] = m
    r = 0.0
    for i in range(nx):
        r = max(r, partial[i])
    return r


# ----------------------------------------------------------------------------- dispatch
_TWINS = {}

# Grids with at least this many cells run the parallel kernels by default; below it the
# serial twins (same code, prange as range) win: a parallel launch costs microseconds on an
# idle machine and milliseconds on a loaded one.
PARALLEL_CELLS = 65536


def version(kernel, parallel: bool):
    """The parallel kernel or its (lazily compiled) serial twin (a size-dispatched kernel's own twin)."""
    if isinstance(kernel, SizeDispatched):
        return kernel.parallel if parallel else kernel.serial
    if parallel:
        return kernel
    twin = _TWINS.get(kernel)
    if twin is None:
        twin = _TWINS[kernel] = serial_twin(kernel)
    return twin


class KernelSet:
    """Attribute access to a module's kernels in one flavour (parallel or serial)."""

    def __init__(self, module, parallel: bool):
        self._module = module
        self.parallel = bool(parallel)

    def __getattr__(self, name):
        kernel = version(getattr(self._module, name), self.parallel)
        setattr(self, name, kernel)
        return kernel
