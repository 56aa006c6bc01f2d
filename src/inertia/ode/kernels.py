"""Numba kernels for the integrators: fused vector updates and a deterministic CG solve.

All kernels are pure functions over flat float64 arrays (inputs first, then outputs, then
scalars) and allocate nothing. Reductions (dot products) are summed over a fixed number of
chunks, so the result does not depend on the Numba thread count.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .._jit import SizeDispatched, parallel_kernel

# Fixed chunk count for reductions: the chunking, hence the rounding, is the same at any
# thread count, which keeps runs bit-identical at 1 and at N threads.
REDUCTION_CHUNKS = 64


@parallel_kernel
def axpy_into(y, k, a, out):
    """out = y + a * k."""
    for i in prange(y.shape[0]):
        out[i] = y[i] + a * k[i]


@parallel_kernel
def axpy_inplace(y, k, a):
    """y += a * k."""
    for i in prange(y.shape[0]):
        y[i] += a * k[i]


@parallel_kernel
def rk_stage(y, stages, coefficients, count, h, out):
    """out = y + h * sum_j coefficients[j] * stages[j] for j < count (explicit Runge-Kutta stage)."""
    n = y.shape[0]
    for i in prange(n):
        acc = 0.0
        for j in range(count):
            c = coefficients[j]
            if c != 0.0:
                acc += c * stages[j, i]
        out[i] = y[i] + h * acc


@parallel_kernel
def rk4_finish(y, k1, k2, k3, k4, h):
    """y += h/6 (k1 + 2 k2 + 2 k3 + k4)."""
    s = h / 6.0
    for i in prange(y.shape[0]):
        y[i] += s * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True)
def scaled_error_norm(y0, y1, err, atol, rtol, h):
    """RMS of h*err / (atol + rtol * max(|y0|, |y1|)) (Hairer, Norsett & Wanner, II.4)."""
    n = y0.shape[0]
    acc = 0.0
    for i in range(n):
        scale = atol + rtol * max(abs(y0[i]), abs(y1[i]))
        e = h * err[i] / scale
        acc += e * e
    return np.sqrt(acc / max(n, 1))


@parallel_kernel
def kick_drift(x, v, a, h):
    """Semi-implicit Euler: v += h a; x += h v (new velocity)."""
    for i in prange(x.shape[0]):
        v[i] += h * a[i]
        x[i] += h * v[i]


@parallel_kernel
def verlet_advance(x, x_prev, v, a, a_prev, h):
    """Position Verlet (Stormer): x_{n+1} = 2 x_n - x_{n-1} + h^2 a_n.

    `x_prev` receives x_n; `v` receives the second-order velocity estimate at t_{n+1},
    v_{n+1} = (x_{n+1} - x_n)/h + h a_n / 2, which the next acceleration evaluation uses.
    `a_prev` receives a_n.
    """
    h2 = h * h
    for i in prange(x.shape[0]):
        xn = x[i]
        xnew = 2.0 * xn - x_prev[i] + h2 * a[i]
        x_prev[i] = xn
        x[i] = xnew
        v[i] = (xnew - xn) / h + 0.5 * h * a[i]
        a_prev[i] = a[i]


def _all_finite(y):
    """True when every entry of y is finite: sum(y * 0) is 0, or NaN as soon as one entry is NaN/inf."""
    acc = 0.0
    for i in prange(y.shape[0]):
        acc += y[i] * 0.0
    return acc == 0.0


# Reassociation (only) lets the reduction vectorise; NaN and inf keep their IEEE meaning, which the
# check relies on (the full fastmath set would assume them away).
all_finite = SizeDispatched(njit(cache=True, parallel=True, fastmath={"reassoc"})(_all_finite))


# ---------------------------------------------------------------------------------------
# Block-sparse (BSR) matrices with D x D blocks, rows = nodes. Row i holds blocks
# columns[row_start[i]:row_start[i+1]] with values blocks[slot, :, :]; diag_slot[i] is the
# slot of block (i, i). Products are gathered per row, so they are parallel and deterministic.
# ---------------------------------------------------------------------------------------

@parallel_kernel
def implicit_euler_matrix(node_mass, diag_slot, dfdx, dfdv, h, out):
    """out = M - h df/dv - h^2 df/dx, block by block (Baraff & Witkin 1998, eq. 6)."""
    nnz = out.shape[0]
    d = out.shape[1]
    h2 = h * h
    for s in prange(nnz):
        for r in range(d):
            for c in range(d):
                out[s, r, c] = -h * dfdv[s, r, c] - h2 * dfdx[s, r, c]
    for i in prange(diag_slot.shape[0]):
        m = node_mass[i]
        if np.isfinite(m):
            for r in range(d):
                out[diag_slot[i], r, r] += m


@njit(cache=True, parallel=True)
def bsr_matvec(row_start, columns, blocks, u, out):
    """out = A u for a BSR matrix; u and out are flat (nodes * D)."""
    d = blocks.shape[1]
    n = row_start.shape[0] - 1
    for i in prange(n):
        for r in range(d):
            out[i * d + r] = 0.0
        for s in range(row_start[i], row_start[i + 1]):
            j = columns[s]
            for r in range(d):
                acc = 0.0
                for c in range(d):
                    acc += blocks[s, r, c] * u[j * d + c]
                out[i * d + r] += acc


@njit(cache=True, parallel=True)
def _chunked_dot(a, b, partial):
    n = a.shape[0]
    chunks = partial.shape[0]
    size = (n + chunks - 1) // chunks
    for c in prange(chunks):
        lo = c * size
        hi = min(n, lo + size)
        acc = 0.0
        for i in range(lo, hi):
            acc += a[i] * b[i]
        partial[c] = acc
    total = 0.0
    for c in range(chunks):
        total += partial[c]
    return total


@njit(cache=True, parallel=True)
def _filter(u, free, d):
    """Zero the entries of constrained (pinned) nodes: the filter S of Baraff & Witkin (1998)."""
    for i in prange(free.shape[0]):
        if not free[i]:
            for r in range(d):
                u[i * d + r] = 0.0


@njit(cache=True, parallel=True)
def invert_diagonal_blocks(blocks, diag_slot, free, out):
    """out[i] = inverse of the diagonal block (i, i) for free nodes, 0 for filtered ones (block Jacobi)."""
    d = blocks.shape[1]
    for i in prange(diag_slot.shape[0]):
        if not free[i]:
            out[i, :, :] = 0.0
            continue
        a = blocks[diag_slot[i]]
        if d == 2:
            det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
            out[i, 0, 0] = a[1, 1] / det
            out[i, 0, 1] = -a[0, 1] / det
            out[i, 1, 0] = -a[1, 0] / det
            out[i, 1, 1] = a[0, 0] / det
        else:
            c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
            c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
            c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
            det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
            out[i, 0, 0] = c00 / det
            out[i, 1, 0] = c01 / det
            out[i, 2, 0] = c02 / det
            out[i, 0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) / det
            out[i, 1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) / det
            out[i, 2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) / det
            out[i, 0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) / det
            out[i, 1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) / det
            out[i, 2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) / det


@njit(cache=True, parallel=True)
def _apply_block_diagonal(inv_blocks, r, z):
    d = inv_blocks.shape[1]
    for i in prange(inv_blocks.shape[0]):
        for a in range(d):
            acc = 0.0
            for b in range(d):
                acc += inv_blocks[i, a, b] * r[i * d + b]
            z[i * d + a] = acc


@njit(cache=True, parallel=True)
def _cg_update(x, r, p, q, alpha):
    for i in prange(x.shape[0]):
        x[i] += alpha * p[i]
        r[i] -= alpha * q[i]


@njit(cache=True, parallel=True)
def _cg_direction(p, z, beta):
    for i in prange(p.shape[0]):
        p[i] = z[i] + beta * p[i]


@njit(cache=True)
def pcg_solve(row_start, columns, blocks, diag_slot, b, free, x, tolerance, max_iterations,
              r, z, p, q, inv_blocks, partial):
    """Solve A x = b by block-Jacobi preconditioned conjugate gradients, pinned nodes filtered.

    `x` holds the initial guess and receives the solution; `b` is overwritten (filtered).
    Stops when |r| <= tolerance * |b|. Returns the number of iterations taken.
    """
    d = blocks.shape[1]
    invert_diagonal_blocks(blocks, diag_slot, free, inv_blocks)
    _filter(x, free, d)
    bsr_matvec(row_start, columns, blocks, x, q)
    for i in range(b.shape[0]):
        r[i] = b[i] - q[i]
    _filter(r, free, d)
    _filter(b, free, d)  # pinned rows carry no equation
    b_norm = np.sqrt(_chunked_dot(b, b, partial))
    if b_norm == 0.0:
        b_norm = 1.0
    _apply_block_diagonal(inv_blocks, r, z)
    p[:] = z
    rz = _chunked_dot(r, z, partial)
    it = 0
    while it < max_iterations:
        if np.sqrt(_chunked_dot(r, r, partial)) <= tolerance * b_norm:
            break
        bsr_matvec(row_start, columns, blocks, p, q)
        _filter(q, free, d)
        pq = _chunked_dot(p, q, partial)
        if pq <= 0.0:
            break
        alpha = rz / pq
        _cg_update(x, r, p, q, alpha)
        _apply_block_diagonal(inv_blocks, r, z)
        rz_new = _chunked_dot(r, z, partial)
        _cg_direction(p, z, rz_new / rz)
        rz = rz_new
        it += 1
    return it
