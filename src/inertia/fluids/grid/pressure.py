"""Pressure Poisson solvers for the MAC grid: multigrid-preconditioned conjugate gradients
(MGPCG), plain conjugate gradients and damped Jacobi, all matrix-free.

The system (one unknown per cell, phi = p dt / rho in m^2/s):

    (L phi)_c = sum over the cell's faces f of a_f (phi_c - phi_nb(f)) = b_c,   a_f = A_f / h^2,

with A_f the face's open fraction (Batty, Bertails and Bridson 2007; 0 on walls, inflow faces
and inside solids, 1 on outflow faces where phi_nb = 0 outside) and b = -div_w(u*). On a side
whose pressure is prescribed on the side itself (``dirichlet_sides`` of `set_coefficients`) the
known value lies half a cell from the cell centre: a_f = 2 A_f / h^2 there, and the value's
share 2 A_f phi_b / h^2 goes to b (the caller's). L is
symmetric positive (semi-)definite; without an outflow face it is singular (constants), and
the solvers then work in the mean-free subspace.

References
----------
- A. McAdams, E. Sifakis and J. Teran, "A parallel multigrid Poisson solver for fluids
  simulation on large grids", SCA 2010: the MGPCG idea (a V-cycle as CG preconditioner,
  iterations independent of the grid size).
- W. L. Briggs, V. E. Henson and S. F. McCormick, "A Multigrid Tutorial", SIAM 2000: cell-centred
  transfer operators.

Method: V(2,2) cycle, red-black Gauss-Seidel smoothing (red-black before the coarse correction,
black-red after, so the cycle is a symmetric operator), trilinear cell-centred prolongation P
and restriction R = P^T / 2^d (the exact transpose, also at walls), coarse operators by
averaging the fine face fractions over each coarse face (rediscretisation), and many
red-black sweeps on the coarsest level.

Limitations
-----------
- Axes coarsen together while every coarsened axis has an even cell count >= 4; grid sizes
  with a large odd factor leave a big coarsest level (slower, still correct). Periodic axes
  need an even cell count (the red-black colouring must alternate across the wrap).
- Separate fluid regions sealed from every outflow face make the system singular per region;
  only the global constant is removed.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from . import kernels as K

SOLVERS = ("mgpcg", "cg", "jacobi")


class Level(NamedTuple):
    """One multigrid level: face coefficients a_f = A_f / h^2 (1/m^2) and their sum per cell."""
    ax: np.ndarray     # (nx+1, ny, nz)
    ay: np.ndarray     # (nx, ny+1, nz)
    az: np.ndarray     # (nx, ny, nz+1)
    diag: np.ndarray   # (nx, ny, nz)
    px: bool
    py: bool
    pz: bool
    # c > 0 when every face between two cells (wrap faces included) has a_f = c: the 3-D kernels
    # then read c instead of ax, ay, az (half the memory traffic; same products, same sums, so
    # bit-identical results). 0: general coefficients.
    uniform: float = 0.0


# ----------------------------------------------------------------------------- kernels
# Each kernel unpacks the Level bundle once and runs a loop without calls: a 2-D grid
# (nz = 1) loops over (i, j) with j innermost, a 3-D grid over (i, j, k) with k innermost
# (contiguous). Neighbours across a periodic side wrap; across a non-periodic side they do not
# exist (walls have a zero face coefficient; outflow faces see phi = 0 outside).
@njit(cache=True, inline="always")
def _nb(i, n, periodic, d):
    """Index of the neighbour i + d (d = +-1) along an axis of n cells, or -1 if none."""
    m = i + d
    if m < 0:
        return n - 1 if periodic else -1
    if m >= n:
        return 0 if periodic else -1
    return m


# The neighbour sum s = sum_f a_f phi_nb(f) is written out in each loop body: a helper
# function taking arrays, even inlined, costs reference-count updates per call (measured 5x
# slower than the written-out loop).
@njit(cache=True, parallel=True)
def operator_kernel(phi, rhs, lv, out, mode):
    """mode 0: out = L phi; mode 1: out = rhs - L phi (the residual)."""
    nx, ny, nz = phi.shape
    ax, ay, az, diag = lv.ax, lv.ay, lv.az, lv.diag
    px, py, pz = lv.px, lv.py, lv.pz
    c = lv.uniform
    for i_ in prange(nx):
        i = np.int64(i_)
        im = _nb(i, nx, px, -1)
        ip = _nb(i, nx, px, 1)
        for j in range(ny):
            jm = _nb(j, ny, py, -1)
            jp = _nb(j, ny, py, 1)
            if nz == 1:
                s = 0.0
                if im >= 0:
                    s += ax[i, j, 0] * phi[im, j, 0]
                if ip >= 0:
                    s += ax[i + 1, j, 0] * phi[ip, j, 0]
                if jm >= 0:
                    s += ay[i, j, 0] * phi[i, jm, 0]
                if jp >= 0:
                    s += ay[i, j + 1, 0] * phi[i, jp, 0]
                lp = diag[i, j, 0] * phi[i, j, 0] - s
                out[i, j, 0] = lp if mode == 0 else rhs[i, j, 0] - lp
                continue
            if c > 0.0:
                for k in range(nz):
                    km = _nb(k, nz, pz, -1)
                    kp = _nb(k, nz, pz, 1)
                    s = 0.0
                    if im >= 0:
                        s += c * phi[im, j, k]
                    if ip >= 0:
                        s += c * phi[ip, j, k]
                    if jm >= 0:
                        s += c * phi[i, jm, k]
                    if jp >= 0:
                        s += c * phi[i, jp, k]
                    if km >= 0:
                        s += c * phi[i, j, km]
                    if kp >= 0:
                        s += c * phi[i, j, kp]
                    lp = diag[i, j, k] * phi[i, j, k] - s
                    out[i, j, k] = lp if mode == 0 else rhs[i, j, k] - lp
                continue
            for k in range(nz):
                km = _nb(k, nz, pz, -1)
                kp = _nb(k, nz, pz, 1)
                s = 0.0
                if im >= 0:
                    s += ax[i, j, k] * phi[im, j, k]
                if ip >= 0:
                    s += ax[i + 1, j, k] * phi[ip, j, k]
                if jm >= 0:
                    s += ay[i, j, k] * phi[i, jm, k]
                if jp >= 0:
                    s += ay[i, j + 1, k] * phi[i, jp, k]
                if km >= 0:
                    s += az[i, j, k] * phi[i, j, km]
                if kp >= 0:
                    s += az[i, j, k + 1] * phi[i, j, kp]
                lp = diag[i, j, k] * phi[i, j, k] - s
                out[i, j, k] = lp if mode == 0 else rhs[i, j, k] - lp


@njit(cache=True, parallel=True)
def gauss_seidel_colour(phi, rhs, lv, colour):
    """One red-black Gauss-Seidel half sweep over cells with (i + j + k) % 2 == colour."""
    nx, ny, nz = phi.shape
    ax, ay, az, diag = lv.ax, lv.ay, lv.az, lv.diag
    px, py, pz = lv.px, lv.py, lv.pz
    c = lv.uniform
    for i_ in prange(nx):
        i = np.int64(i_)
        im = _nb(i, nx, px, -1)
        ip = _nb(i, nx, px, 1)
        if nz == 1:
            for j in range((colour + i) % 2, ny, 2):
                jm = _nb(j, ny, py, -1)
                jp = _nb(j, ny, py, 1)
                d = diag[i, j, 0]
                if d > 0.0:
                    s = 0.0
                    if im >= 0:
                        s += ax[i, j, 0] * phi[im, j, 0]
                    if ip >= 0:
                        s += ax[i + 1, j, 0] * phi[ip, j, 0]
                    if jm >= 0:
                        s += ay[i, j, 0] * phi[i, jm, 0]
                    if jp >= 0:
                        s += ay[i, j + 1, 0] * phi[i, jp, 0]
                    phi[i, j, 0] = (rhs[i, j, 0] + s) / d
            continue
        for j in range(ny):
            jm = _nb(j, ny, py, -1)
            jp = _nb(j, ny, py, 1)
            if c > 0.0:
                for k in range((colour + i + j) % 2, nz, 2):
                    km = _nb(k, nz, pz, -1)
                    kp = _nb(k, nz, pz, 1)
                    d = diag[i, j, k]
                    if d > 0.0:
                        s = 0.0
                        if im >= 0:
                            s += c * phi[im, j, k]
                        if ip >= 0:
                            s += c * phi[ip, j, k]
                        if jm >= 0:
                            s += c * phi[i, jm, k]
                        if jp >= 0:
                            s += c * phi[i, jp, k]
                        if km >= 0:
                            s += c * phi[i, j, km]
                        if kp >= 0:
                            s += c * phi[i, j, kp]
                        phi[i, j, k] = (rhs[i, j, k] + s) / d
                continue
            for k in range((colour + i + j) % 2, nz, 2):
                km = _nb(k, nz, pz, -1)
                kp = _nb(k, nz, pz, 1)
                d = diag[i, j, k]
                if d > 0.0:
                    s = 0.0
                    if im >= 0:
                        s += ax[i, j, k] * phi[im, j, k]
                    if ip >= 0:
                        s += ax[i + 1, j, k] * phi[ip, j, k]
                    if jm >= 0:
                        s += ay[i, j, k] * phi[i, jm, k]
                    if jp >= 0:
                        s += ay[i, j + 1, k] * phi[i, jp, k]
                    if km >= 0:
                        s += az[i, j, k] * phi[i, j, km]
                    if kp >= 0:
                        s += az[i, j, k + 1] * phi[i, j, kp]
                    phi[i, j, k] = (rhs[i, j, k] + s) / d


@njit(cache=True, parallel=True)
def gauss_seidel_from_zero(phi, rhs, lv, colour):
    """phi = 0, then a red-black half sweep of `colour`, in one pass: colour cells take
    (rhs + 0) / diag (their neighbours are 0; the + 0.0 keeps the rounding of the general sweep,
    -0.0 included), the others 0."""
    nx, ny, nz = phi.shape
    diag = lv.diag
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                d = diag[i, j, k]
                if (i + j + k) % 2 == colour and d > 0.0:
                    phi[i, j, k] = (rhs[i, j, k] + 0.0) / d
                else:
                    phi[i, j, k] = 0.0


def apply_operator(phi, lv, out):
    """out = L phi (Python wrapper kept for callers; see `operator_kernel`)."""
    operator_kernel(phi, phi, lv, out, 0)


def residual(phi, rhs, lv, out):
    """out = rhs - L phi."""
    operator_kernel(phi, rhs, lv, out, 1)


@njit(cache=True, parallel=True)
def jacobi_sweep(phi, rhs, lv, omega, out):
    """Damped Jacobi: out = phi + omega (rhs - L phi) / diag."""
    nx, ny, nz = phi.shape
    ax, ay, az, diag = lv.ax, lv.ay, lv.az, lv.diag
    px, py, pz = lv.px, lv.py, lv.pz
    for i_ in prange(nx):
        i = np.int64(i_)
        im = _nb(i, nx, px, -1)
        ip = _nb(i, nx, px, 1)
        for j in range(ny):
            jm = _nb(j, ny, py, -1)
            jp = _nb(j, ny, py, 1)
            for k in range(nz):
                km = _nb(k, nz, pz, -1)
                kp = _nb(k, nz, pz, 1)
                d = diag[i, j, k]
                if d > 0.0:
                    s = 0.0
                    if im >= 0:
                        s += ax[i, j, k] * phi[im, j, k]
                    if ip >= 0:
                        s += ax[i + 1, j, k] * phi[ip, j, k]
                    if jm >= 0:
                        s += ay[i, j, k] * phi[i, jm, k]
                    if jp >= 0:
                        s += ay[i, j + 1, k] * phi[i, jp, k]
                    if km >= 0:
                        s += az[i, j, k] * phi[i, j, km]
                    if kp >= 0:
                        s += az[i, j, k + 1] * phi[i, j, kp]
                    r = rhs[i, j, k] - (d * phi[i, j, k] - s)
                    out[i, j, k] = phi[i, j, k] + omega * r / d
                else:
                    out[i, j, k] = 0.0


def transfer_tables(n_fine, coarsen, periodic):
    """1-D transfer weights between a fine axis of n_fine cells and its coarse axis.

    Prolongation (cell-centred linear, Briggs et al. 2000): fine cell f takes 3/4 of its parent
    coarse cell f // 2 and 1/4 of the coarse neighbour on f's side; at a wall the missing
    neighbour's share goes to the parent. Returns (pro_idx (n_fine, 2) int64, pro_w (n_fine, 2),
    res_idx (n_coarse, 4) int64, res_w (n_coarse, 4)) with the restriction the exact transpose
    of the prolongation (before the 1/2^d scale). A non-coarsened axis maps f to f with weight 1."""
    if not coarsen:
        idx = np.zeros((n_fine, 2), dtype=np.int64)
        idx[:, 0] = np.arange(n_fine)
        idx[:, 1] = np.arange(n_fine)
        w = np.zeros((n_fine, 2))
        w[:, 0] = 1.0
        ridx = np.zeros((n_fine, 4), dtype=np.int64)
        ridx[:, 0] = np.arange(n_fine)
        rw = np.zeros((n_fine, 4))
        rw[:, 0] = 1.0
        return idx, w, ridx, rw
    nc = n_fine // 2
    pro_idx = np.zeros((n_fine, 2), dtype=np.int64)
    pro_w = np.zeros((n_fine, 2))
    for f in range(n_fine):
        near = f // 2
        other = near - 1 if f % 2 == 0 else near + 1
        if other < 0 or other >= nc:
            other = other % nc if periodic else near
        pro_idx[f] = (near, other)
        pro_w[f] = (0.75, 0.25)
    res_idx = np.zeros((nc, 4), dtype=np.int64)
    res_w = np.zeros((nc, 4))
    fill = np.zeros(nc, dtype=np.int64)
    for f in range(n_fine):
        for c, w in zip(pro_idx[f], pro_w[f]):
            # merge repeated (f, c) pairs (a wall cell's two shares go to one coarse cell)
            row = res_idx[c, :fill[c]]
            hit = np.flatnonzero(row == f)
            if hit.size:
                res_w[c, hit[0]] += w
            else:
                res_idx[c, fill[c]] = f
                res_w[c, fill[c]] = w
                fill[c] += 1
    return pro_idx, pro_w, res_idx, res_w


@njit(cache=True, parallel=True)
def restrict(fine, ti, tw, tj, uw, tk, vw, scale, coarse):
    """coarse = P^T fine * scale from the 1-D restriction tables (`transfer_tables`) per axis
    (zero weights pad a table row; they add exact zeros)."""
    ncx, ncy, ncz = coarse.shape
    for I_ in prange(ncx):
        I = np.int64(I_)
        for J in range(ncy):
            if ncz == 1 and fine.shape[2] == 1:
                s = 0.0
                for a in range(4):
                    fi = ti[I, a]
                    wa = tw[I, a]
                    s += wa * (uw[J, 0] * fine[fi, tj[J, 0], 0] + uw[J, 1] * fine[fi, tj[J, 1], 0]
                               + uw[J, 2] * fine[fi, tj[J, 2], 0] + uw[J, 3] * fine[fi, tj[J, 3], 0])
                coarse[I, J, 0] = s * scale
                continue
            for Kc in range(ncz):
                s = 0.0
                for a in range(4):
                    fi = ti[I, a]
                    wa = tw[I, a]
                    for b in range(4):
                        fj = tj[J, b]
                        wab = wa * uw[J, b]
                        s += wab * (vw[Kc, 0] * fine[fi, fj, tk[Kc, 0]]
                                    + vw[Kc, 1] * fine[fi, fj, tk[Kc, 1]]
                                    + vw[Kc, 2] * fine[fi, fj, tk[Kc, 2]]
                                    + vw[Kc, 3] * fine[fi, fj, tk[Kc, 3]])
                coarse[I, J, Kc] = s * scale


gauss_seidel_colour_serial_body = K.version(gauss_seidel_colour, False)
gauss_seidel_from_zero_serial_body = K.version(gauss_seidel_from_zero, False)


@njit(cache=True)
def smooth_serial(phi, rhs, lv, first, sweeps):
    """`sweeps` red-black Gauss-Seidel sweeps, colour `first` then the other, in one call
    (a Python-level call per half sweep costs more than the sweep on small levels)."""
    for _ in range(sweeps):
        gauss_seidel_colour_serial_body(phi, rhs, lv, first)
        gauss_seidel_colour_serial_body(phi, rhs, lv, 1 - first)


@njit(cache=True)
def smooth_from_zero_serial(phi, rhs, lv, sweeps):
    """`smooth_serial` (colour 0 first) from phi = 0 (phi's old content is ignored)."""
    gauss_seidel_from_zero_serial_body(phi, rhs, lv, 0)
    gauss_seidel_colour_serial_body(phi, rhs, lv, 1)
    for _ in range(sweeps - 1):
        gauss_seidel_colour_serial_body(phi, rhs, lv, 0)
        gauss_seidel_colour_serial_body(phi, rhs, lv, 1)


@njit(cache=True)
def smooth_from_zero_parallel(phi, rhs, lv, sweeps):
    """`smooth_from_zero_serial` with the parallel half sweeps."""
    gauss_seidel_from_zero(phi, rhs, lv, 0)
    gauss_seidel_colour(phi, rhs, lv, 1)
    for _ in range(sweeps - 1):
        gauss_seidel_colour(phi, rhs, lv, 0)
        gauss_seidel_colour(phi, rhs, lv, 1)


@njit(cache=True)
def smooth_parallel(phi, rhs, lv, first, sweeps):
    """`smooth_serial` with the parallel half sweeps."""
    for _ in range(sweeps):
        gauss_seidel_colour(phi, rhs, lv, first)
        gauss_seidel_colour(phi, rhs, lv, 1 - first)


@njit(cache=True)
def coarse_solve(phi, rhs, lv, sweeps):
    """`sweeps` symmetric red-black Gauss-Seidel sweeps (red-black, then black-red) on the
    coarsest level, in one call."""
    for _ in range(sweeps):
        gauss_seidel_colour_serial_body(phi, rhs, lv, 0)
        gauss_seidel_colour_serial_body(phi, rhs, lv, 1)
    for _ in range(sweeps):
        gauss_seidel_colour_serial_body(phi, rhs, lv, 1)
        gauss_seidel_colour_serial_body(phi, rhs, lv, 0)


@njit(cache=True, parallel=True)
def prolong_add(coarse, ti, tw, tj, uw, tk, vw, fine):
    """fine += P coarse from the 1-D prolongation tables (`transfer_tables`) per axis."""
    nfx, nfy, nfz = fine.shape
    for i_ in prange(nfx):
        i = np.int64(i_)
        ci0, ci1 = ti[i, 0], ti[i, 1]
        wi0, wi1 = tw[i, 0], tw[i, 1]
        for j in range(nfy):
            cj0, cj1 = tj[j, 0], tj[j, 1]
            wj0, wj1 = uw[j, 0], uw[j, 1]
            if nfz == 1:
                fine[i, j, 0] += (wi0 * (wj0 * coarse[ci0, cj0, 0] + wj1 * coarse[ci0, cj1, 0])
                                  + wi1 * (wj0 * coarse[ci1, cj0, 0] + wj1 * coarse[ci1, cj1, 0]))
                continue
            for k in range(nfz):
                ck0, ck1 = tk[k, 0], tk[k, 1]
                wk0, wk1 = vw[k, 0], vw[k, 1]
                fine[i, j, k] += (
                    wi0 * (wj0 * (wk0 * coarse[ci0, cj0, ck0] + wk1 * coarse[ci0, cj0, ck1])
                           + wj1 * (wk0 * coarse[ci0, cj1, ck0] + wk1 * coarse[ci0, cj1, ck1]))
                    + wi1 * (wj0 * (wk0 * coarse[ci1, cj0, ck0] + wk1 * coarse[ci1, cj0, ck1])
                             + wj1 * (wk0 * coarse[ci1, cj1, ck0] + wk1 * coarse[ci1, cj1, ck1])))


@njit(cache=True)
def coarsen_faces(fine_a, axis, cx, cy, cz, coarse_a):
    """Coarse face coefficient: a_f = A_f / h^2 with A_f the mean open fraction of the fine faces
    the coarse face covers and h doubled, so coarse a = mean(fine a) / 4."""
    ncx, ncy, ncz = coarse_a.shape
    for I_ in prange(ncx):
        I = np.int64(I_)
        for J in range(ncy):
            for Kc in range(ncz):
                s = 0.0
                cnt = 0
                ni = 1 if (axis == 0 or not cx) else 2
                nj = 1 if (axis == 1 or not cy) else 2
                nk = 1 if (axis == 2 or not cz) else 2
                fi0 = I * (2 if cx else 1)
                fj0 = J * (2 if cy else 1)
                fk0 = Kc * (2 if cz else 1)
                for di in range(ni):
                    for dj in range(nj):
                        for dk in range(nk):
                            s += fine_a[fi0 + di, fj0 + dj, fk0 + dk]
                            cnt += 1
                coarse_a[I, J, Kc] = s / cnt * 0.25


def _uniform_coefficient(lv, dim):
    """c if every face coefficient between two cells (wrap faces on periodic axes) equals one
    c > 0 (3-D levels only), else 0."""
    if dim != 3 or lv.ax.shape[0] < 3:
        return 0.0
    c = float(lv.ax[1, 0, 0])
    if c <= 0.0:
        return 0.0
    inner = (lv.ax if lv.px else lv.ax[1:-1], lv.ay if lv.py else lv.ay[:, 1:-1],
             lv.az if lv.pz else lv.az[:, :, 1:-1])
    for a in inner:
        if a.size and not (a.min() == c and a.max() == c):
            return 0.0
    return c


@njit(cache=True)
def level_diag(ax, ay, az, diag):
    nx, ny, nz = diag.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                diag[i, j, k] = (ax[i, j, k] + ax[i + 1, j, k] + ay[i, j, k] + ay[i, j + 1, k]
                                 + az[i, j, k] + az[i, j, k + 1])


@njit(cache=True, parallel=True)
def masked_shift(a, mask, shift):
    """a -= shift where mask (remove a constant from the active cells)."""
    nx = a.shape[0]
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(a.shape[1]):
            for k in range(a.shape[2]):
                if mask[i, j, k]:
                    a[i, j, k] -= shift
                else:
                    a[i, j, k] = 0.0




# ----------------------------------------------------------------------------- solver
class PoissonSolver:
    """Matrix-free solver of L phi = b on a MAC grid (see the module docstring).

    Parameters
    ----------
    shape : (nx, ny, nz) cell counts (nz = 1 for 2-D).
    periodic : (3,) bools.
    method : "mgpcg" (default), "cg" or "jacobi".
    tolerance : relative residual ||b - L phi||_2 / ||b||_2 to reach; default 1e-6
        (1e-4..1e-8 sensible: the divergence left after projection is this fraction of the
        divergence before it).
    max_iterations : default 200 for the CG methods, 20000 for Jacobi.
    """

    def __init__(self, shape, periodic, *, method="mgpcg", tolerance=1e-6, max_iterations=None,
                 parallel=None):
        if method not in SOLVERS:
            raise ValueError(f"pressure_solver must be one of {SOLVERS}; got {method!r}")
        self.method = method
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations if max_iterations is not None
                                  else (20000 if method == "jacobi" else 200))
        self.shape = tuple(int(s) for s in shape)
        if parallel is None:
            parallel = int(np.prod(self.shape)) >= K.PARALLEL_CELLS
        self.parallel = bool(parallel)
        import sys
        self._kp = K.KernelSet(sys.modules[__name__], True)
        self._ks = K.KernelSet(sys.modules[__name__], False)
        self._vk = K.KernelSet(K, self.parallel)
        self.periodic = tuple(bool(p) for p in periodic)
        self.last_iterations = 0
        self.last_residual = 0.0
        nx, ny, nz = self.shape
        self.levels = []        # Level bundles, finest first
        self.coarsen_axes = []  # per level below the finest: which axes halved
        shapes = [self.shape]
        while True:
            s = shapes[-1]
            axes = tuple(n > 1 for n in s)
            if not all((n % 2 == 0 and n >= 4) for n, c in zip(s, axes) if c):
                break
            if method != "mgpcg":
                break
            shapes.append(tuple(n // 2 if c else n for n, c in zip(s, axes)))
            self.coarsen_axes.append(axes)
        px, py, pz = self.periodic
        for s in shapes:
            x, y, z = s
            self.levels.append(Level(np.zeros((x + 1, y, z)), np.zeros((x, y + 1, z)),
                                     np.zeros((x, y, z + 1)), np.zeros(s), px, py, pz))
        # 1-D transfer tables per level below the finest: (prolongation x, y, z, restriction
        # x, y, z), each (idx, w)
        self.transfer = []
        for lvl, axes in enumerate(self.coarsen_axes):
            fine = shapes[lvl]
            tabs = [transfer_tables(fine[a], axes[a], self.periodic[a]) for a in range(3)]
            pro = tuple(x for t in tabs for x in t[:2])
            res = tuple(x for t in tabs for x in t[2:])
            scale = 1.0 / (1 << sum(1 for c in axes if c))
            self.transfer.append((pro, res, scale))
        self.phi = [np.zeros(s) for s in shapes]
        self.rhs = [np.zeros(s) for s in shapes]
        self.res = [np.zeros(s) for s in shapes]
        # CG vectors on the finest level
        self.r = np.zeros(self.shape)
        self.z = np.zeros(self.shape)
        self.p = np.zeros(self.shape)
        self.q = np.zeros(self.shape)
        self.partial = np.zeros(nx)
        self.active = np.zeros(self.shape, dtype=np.bool_)
        self.singular = True
        self.active_count = 0

    # -- setup (when the face fractions change) ---------------------------------------------
    def set_coefficients(self, fu, fv, fw, h, dim, dirichlet_sides=()):
        """Face open fractions of the finest level (MAC face arrays); builds every level.
        dirichlet_sides: (axis, side) pairs (side 0 low, 1 high) of non-periodic sides whose
        boundary faces carry a value on the face itself (a prescribed pressure): their
        coefficient doubles (distance h / 2 from the cell centre)."""
        lv = self.levels[0]
        inv_h2 = 1.0 / (h * h)
        np.multiply(fu, inv_h2, out=lv.ax)
        np.multiply(fv, inv_h2, out=lv.ay)
        if dim == 3:
            np.multiply(fw, inv_h2, out=lv.az)
        else:
            lv.az[...] = 0.0
        for axis, side in dirichlet_sides:
            a = (lv.ax, lv.ay, lv.az)[axis]
            idx = [slice(None)] * 3
            idx[axis] = 0 if side == 0 else -1
            a[tuple(idx)] *= 2.0
        for lvl in range(1, len(self.levels)):
            f, c = self.levels[lvl - 1], self.levels[lvl]
            cx, cy, cz = self.coarsen_axes[lvl - 1]
            coarsen_faces(f.ax, 0, cx, cy, cz, c.ax)
            coarsen_faces(f.ay, 1, cx, cy, cz, c.ay)
            coarsen_faces(f.az, 2, cx, cy, cz, c.az)
        for i, lv in enumerate(self.levels):
            level_diag(lv.ax, lv.ay, lv.az, lv.diag)
            self.levels[i] = lv._replace(uniform=_uniform_coefficient(lv, dim))
        np.greater(self.levels[0].diag, 0.0, out=self.active)
        self.active_count = int(np.count_nonzero(self.active))   # (no temporary, unlike .sum())
        # outflow faces (open faces on the boundary of a non-periodic axis) make L definite
        lv0 = self.levels[0]
        dirichlet = False
        nz = np.count_nonzero   # any(), without the buffered cast of a strided face layer
        if not self.periodic[0]:
            dirichlet |= bool(nz(lv0.ax[0]) or nz(lv0.ax[-1]))
        if not self.periodic[1]:
            dirichlet |= bool(nz(lv0.ay[:, 0]) or nz(lv0.ay[:, -1]))
        if dim == 3 and not self.periodic[2]:
            dirichlet |= bool(nz(lv0.az[:, :, 0]) or nz(lv0.az[:, :, -1]))
        self.singular = not dirichlet

    # -- pieces ------------------------------------------------------------------------------
    def _k(self, name, cells):
        """Kernel `name` for a level of `cells` cells: parallel only on large levels of a
        parallel solver (launch overhead dominates on small ones)."""
        if self.parallel and cells >= K.PARALLEL_CELLS // 4:
            return getattr(self._kp, name)
        return getattr(self._ks, name)

    def _smooth(self, cells):
        if self.parallel and cells >= K.PARALLEL_CELLS // 4:
            return smooth_parallel
        return smooth_serial

    def _smooth_from_zero(self, cells):
        if self.parallel and cells >= K.PARALLEL_CELLS // 4:
            return smooth_from_zero_parallel
        return smooth_from_zero_serial

    def _dot(self, a, b):
        return self._vk.dot(a, b, self.partial)

    def _remove_mean(self, a):
        if self.singular and self.active_count:
            mean = float(np.sum(a, where=self.active)) / self.active_count
            self._k("masked_shift", a.size)(a, self.active, mean)

    def _vcycle(self, rhs0, out):
        """out = V-cycle applied to rhs0 from a zero guess (the preconditioner M^-1 rhs0)."""
        L = len(self.levels)
        # the finest level works on rhs0 and out directly (no copies in and out)
        phis = [out] + self.phi[1:]
        rhss = [rhs0] + self.rhs[1:]
        for lvl in range(L):
            lv, phi, rhs, res = self.levels[lvl], phis[lvl], rhss[lvl], self.res[lvl]
            n = phi.size
            if lvl == L - 1:
                phi[...] = 0.0
                coarse_solve(phi, rhs, lv, max(20, 2 * max(phi.shape)))
                break
            self._smooth_from_zero(n)(phi, rhs, lv, 2)
            self._k("operator_kernel", n)(phi, rhs, lv, res, 1)
            pro, rtab, scale = self.transfer[lvl]
            self._k("restrict", self.rhs[lvl + 1].size)(res, *rtab, scale, self.rhs[lvl + 1])
        for lvl in range(L - 2, -1, -1):
            lv, phi, rhs = self.levels[lvl], phis[lvl], rhss[lvl]
            n = phi.size
            pro, rtab, scale = self.transfer[lvl]
            self._k("prolong_add", n)(phis[lvl + 1], *pro, phi)
            self._smooth(n)(phi, rhs, lv, 1, 2)

    # -- solve -------------------------------------------------------------------------------
    def solve(self, b, phi):
        """Solve L phi = b (b is modified when singular: its mean over active cells is removed).
        phi: initial guess in, solution out. Returns the iteration count."""
        self._remove_mean(b)
        bnorm = math.sqrt(self._dot(b, b))
        lv = self.levels[0]
        if bnorm == 0.0:
            phi[...] = 0.0
            self.last_iterations, self.last_residual = 0, 0.0
            return 0
        tol = self.tolerance * bnorm
        if self.method == "jacobi":
            return self._jacobi(b, phi, bnorm, tol)
        r, z, p, q = self.r, self.z, self.p, self.q
        rf, zf, pf, qf, phif = (a.reshape(-1) for a in (r, z, p, q, phi))
        self._k("operator_kernel", r.size)(phi, b, lv, r, 1)
        self._remove_mean(r)
        rnorm = math.sqrt(self._dot(r, r))
        it = 0
        if rnorm > tol:
            self._precondition(r, z)
            p[...] = z
            rz = self._dot(r, z)
            while it < self.max_iterations:
                it += 1
                self._k("operator_kernel", r.size)(p, p, lv, q, 0)
                alpha = rz / self._dot(p, q)
                self._vk.axpy(alpha, pf, phif)
                self._vk.axpy(-alpha, qf, rf)
                rnorm = math.sqrt(self._dot(r, r))
                if rnorm <= tol:
                    break
                self._precondition(r, z)
                rz_new = self._dot(r, z)
                beta = rz_new / rz
                rz = rz_new
                self._vk.xpby(zf, beta, pf)
        self._finish(it, rnorm / bnorm)
        return it

    def _precondition(self, r, z):
        if self.method == "mgpcg":
            self._vcycle(r, z)
            self._remove_mean(z)
        else:
            z[...] = r

    def _jacobi(self, b, phi, bnorm, tol):
        lv = self.levels[0]
        it = 0
        rnorm = np.inf
        cur, nxt = phi, self.q
        sweep = self._k("jacobi_sweep", b.size)
        while it < self.max_iterations:
            # check the residual every 10 sweeps (it costs a sweep itself)
            for _ in range(10):
                sweep(cur, b, lv, 2.0 / 3.0, nxt)
                cur, nxt = nxt, cur
                it += 1
            self._k("operator_kernel", b.size)(cur, b, lv, self.r, 1)
            self._remove_mean(self.r)
            rnorm = math.sqrt(self._dot(self.r, self.r))
            if rnorm <= tol:
                break
        if cur is not phi:
            phi[...] = cur
        self._finish(it, rnorm / bnorm)
        return it

    def _finish(self, it, rel):
        self.last_iterations = it
        self.last_residual = rel
        if rel > self.tolerance:
            warnings.warn(f"pressure solve ({self.method}) did not converge: relative residual "
                          f"{rel:.3e} after {it} iterations (tolerance {self.tolerance:.1e}); raise "
                          f"max_iterations or use pressure_solver='mgpcg'", RuntimeWarning,
                          stacklevel=4)
