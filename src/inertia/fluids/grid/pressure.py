"""Pressure Poisson solvers for the MAC grid: multigrid-preconditioned conjugate gradients
(MGPCG), plain conjugate gradients and damped Jacobi, all matrix-free.

The system (one unknown per cell, phi = p dt / rho in m^2/s):

    (L phi)_c = sum over the cell's faces f of a_f (phi_c - phi_nb(f)) = b_c,   a_f = A_f / h^2,

with A_f the face's open fraction (Batty, Bertails and Bridson 2007; 0 on walls, inflow faces
and inside solids, 1 on outflow faces where phi_nb = 0 outside) and b = -div_w(u*). L is
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


# ----------------------------------------------------------------------------- kernels
@njit(cache=True)
def _nbsum(phi, lv, i, j, k, nx, ny, nz):
    s = 0.0
    a = lv.ax[i, j, k]
    if a != 0.0:
        if i > 0:
            s += a * phi[i - 1, j, k]
        elif lv.px:
            s += a * phi[nx - 1, j, k]
    a = lv.ax[i + 1, j, k]
    if a != 0.0:
        if i < nx - 1:
            s += a * phi[i + 1, j, k]
        elif lv.px:
            s += a * phi[0, j, k]
    a = lv.ay[i, j, k]
    if a != 0.0:
        if j > 0:
            s += a * phi[i, j - 1, k]
        elif lv.py:
            s += a * phi[i, ny - 1, k]
    a = lv.ay[i, j + 1, k]
    if a != 0.0:
        if j < ny - 1:
            s += a * phi[i, j + 1, k]
        elif lv.py:
            s += a * phi[i, 0, k]
    a = lv.az[i, j, k]
    if a != 0.0:
        if k > 0:
            s += a * phi[i, j, k - 1]
        elif lv.pz:
            s += a * phi[i, j, nz - 1]
    a = lv.az[i, j, k + 1]
    if a != 0.0:
        if k < nz - 1:
            s += a * phi[i, j, k + 1]
        elif lv.pz:
            s += a * phi[i, j, 0]
    return s


@njit(cache=True, parallel=True)
def apply_operator(phi, lv, out):
    """out = L phi."""
    nx, ny, nz = phi.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                out[i, j, k] = lv.diag[i, j, k] * phi[i, j, k] - _nbsum(phi, lv, i, j, k, nx, ny, nz)


@njit(cache=True, parallel=True)
def residual(phi, rhs, lv, out):
    """out = rhs - L phi."""
    nx, ny, nz = phi.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                out[i, j, k] = rhs[i, j, k] - (lv.diag[i, j, k] * phi[i, j, k]
                                               - _nbsum(phi, lv, i, j, k, nx, ny, nz))


@njit(cache=True, parallel=True)
def gauss_seidel_colour(phi, rhs, lv, colour):
    """One red-black Gauss-Seidel half sweep over cells with (i + j + k) % 2 == colour."""
    nx, ny, nz = phi.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            k0 = (colour + i + j) % 2
            for k in range(k0, nz, 2):
                d = lv.diag[i, j, k]
                if d > 0.0:
                    phi[i, j, k] = (rhs[i, j, k] + _nbsum(phi, lv, i, j, k, nx, ny, nz)) / d


@njit(cache=True, parallel=True)
def jacobi_sweep(phi, rhs, lv, omega, out):
    """Damped Jacobi: out = phi + omega (rhs - L phi) / diag."""
    nx, ny, nz = phi.shape
    for i_ in prange(nx):
        i = np.int64(i_)
        for j in range(ny):
            for k in range(nz):
                d = lv.diag[i, j, k]
                if d > 0.0:
                    r = rhs[i, j, k] - (d * phi[i, j, k] - _nbsum(phi, lv, i, j, k, nx, ny, nz))
                    out[i, j, k] = phi[i, j, k] + omega * r / d
                else:
                    out[i, j, k] = 0.0


@njit(cache=True)
def _p1d(f, c, nc, coarsen, periodic):
    """Prolongation weight of coarse cell c into fine cell f along one axis."""
    if not coarsen:
        return 1.0 if f == c else 0.0
    near = f // 2
    other = near - 1 if f % 2 == 0 else near + 1
    if other < 0 or other >= nc:
        if periodic:
            other = other % nc
        else:
            other = near
    w = 0.0
    if near == c:
        w += 0.75
    if other == c:
        w += 0.25
    return w


@njit(cache=True, parallel=True)
def restrict(fine, cx, cy, cz, px, py, pz, coarse):
    """coarse = P^T fine / 2^d (full weighting, exact transpose of `prolong_add`)."""
    ncx, ncy, ncz = coarse.shape
    nfx, nfy, nfz = fine.shape
    d = (1 if cx else 0) + (1 if cy else 0) + (1 if cz else 0)
    scale = 1.0 / (1 << d)
    for I_ in prange(ncx):
        I = np.int64(I_)
        for J in range(ncy):
            for Kc in range(ncz):
                s = 0.0
                for di in range(-1, 3) if cx else range(0, 1):
                    fi = 2 * I + di if cx else I
                    if fi < 0 or fi >= nfx:
                        if not px:
                            continue
                        fi = fi % nfx
                    wi = _p1d(fi, I, ncx, cx, px)
                    if wi == 0.0:
                        continue
                    for dj in range(-1, 3) if cy else range(0, 1):
                        fj = 2 * J + dj if cy else J
                        if fj < 0 or fj >= nfy:
                            if not py:
                                continue
                            fj = fj % nfy
                        wj = _p1d(fj, J, ncy, cy, py)
                        if wj == 0.0:
                            continue
                        for dk in range(-1, 3) if cz else range(0, 1):
                            fk = 2 * Kc + dk if cz else Kc
                            if fk < 0 or fk >= nfz:
                                if not pz:
                                    continue
                                fk = fk % nfz
                            wk = _p1d(fk, Kc, ncz, cz, pz)
                            s += wi * wj * wk * fine[fi, fj, fk]
                coarse[I, J, Kc] = s * scale


@njit(cache=True, parallel=True)
def prolong_add(coarse, cx, cy, cz, px, py, pz, fine):
    """fine += P coarse (trilinear at cell centres; walls copy the edge cell)."""
    ncx, ncy, ncz = coarse.shape
    nfx, nfy, nfz = fine.shape
    for i_ in prange(nfx):
        i = np.int64(i_)
        for j in range(nfy):
            for k in range(nfz):
                s = 0.0
                ci0 = i // 2 if cx else i
                cj0 = j // 2 if cy else j
                ck0 = k // 2 if cz else k
                for di in range(-1, 2) if cx else range(0, 1):
                    ci = ci0 + di
                    if ci < 0 or ci >= ncx:
                        if not px:
                            continue
                        ci = ci % ncx
                    wi = _p1d(i, ci, ncx, cx, px)
                    if wi == 0.0:
                        continue
                    for dj in range(-1, 2) if cy else range(0, 1):
                        cj = cj0 + dj
                        if cj < 0 or cj >= ncy:
                            if not py:
                                continue
                            cj = cj % ncy
                        wj = _p1d(j, cj, ncy, cy, py)
                        if wj == 0.0:
                            continue
                        for dk in range(-1, 2) if cz else range(0, 1):
                            ck = ck0 + dk
                            if ck < 0 or ck >= ncz:
                                if not pz:
                                    continue
                                ck = ck % ncz
                            wk = _p1d(k, ck, ncz, cz, pz)
                            s += wi * wj * wk * coarse[ci, cj, ck]
                fine[i, j, k] += s


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
    def set_coefficients(self, fu, fv, fw, h, dim):
        """Face open fractions of the finest level (MAC face arrays); builds every level."""
        lv = self.levels[0]
        inv_h2 = 1.0 / (h * h)
        np.multiply(fu, inv_h2, out=lv.ax)
        np.multiply(fv, inv_h2, out=lv.ay)
        if dim == 3:
            np.multiply(fw, inv_h2, out=lv.az)
        else:
            lv.az[...] = 0.0
        for lvl in range(1, len(self.levels)):
            f, c = self.levels[lvl - 1], self.levels[lvl]
            cx, cy, cz = self.coarsen_axes[lvl - 1]
            coarsen_faces(f.ax, 0, cx, cy, cz, c.ax)
            coarsen_faces(f.ay, 1, cx, cy, cz, c.ay)
            coarsen_faces(f.az, 2, cx, cy, cz, c.az)
        for lv in self.levels:
            level_diag(lv.ax, lv.ay, lv.az, lv.diag)
        np.greater(self.levels[0].diag, 0.0, out=self.active)
        self.active_count = int(self.active.sum())
        # outflow faces (open faces on the boundary of a non-periodic axis) make L definite
        lv0 = self.levels[0]
        dirichlet = False
        if not self.periodic[0]:
            dirichlet |= bool(lv0.ax[0].any() or lv0.ax[-1].any())
        if not self.periodic[1]:
            dirichlet |= bool(lv0.ay[:, 0].any() or lv0.ay[:, -1].any())
        if dim == 3 and not self.periodic[2]:
            dirichlet |= bool(lv0.az[:, :, 0].any() or lv0.az[:, :, -1].any())
        self.singular = not dirichlet

    # -- pieces ------------------------------------------------------------------------------
    def _k(self, name, cells):
        """Kernel `name` for a level of `cells` cells: parallel only on large levels of a
        parallel solver (launch overhead dominates on small ones)."""
        if self.parallel and cells >= K.PARALLEL_CELLS // 4:
            return getattr(self._kp, name)
        return getattr(self._ks, name)

    def _dot(self, a, b):
        return self._vk.dot(a, b, self.partial)

    def _remove_mean(self, a):
        if self.singular and self.active_count:
            mean = float(np.sum(a, where=self.active)) / self.active_count
            self._k("masked_shift", a.size)(a, self.active, mean)

    def _vcycle(self, rhs0, out):
        """out = V-cycle applied to rhs0 from a zero guess (the preconditioner M^-1 rhs0)."""
        L = len(self.levels)
        self.rhs[0][...] = rhs0
        for lvl in range(L):
            lv, phi, rhs, res = self.levels[lvl], self.phi[lvl], self.rhs[lvl], self.res[lvl]
            n = phi.size
            phi[...] = 0.0
            gs = self._k("gauss_seidel_colour", n)
            if lvl == L - 1:
                sweeps = max(20, 2 * max(phi.shape))
                for _ in range(sweeps):
                    gs(phi, rhs, lv, 0)
                    gs(phi, rhs, lv, 1)
                for _ in range(sweeps):
                    gs(phi, rhs, lv, 1)
                    gs(phi, rhs, lv, 0)
                break
            for _ in range(2):
                gs(phi, rhs, lv, 0)
                gs(phi, rhs, lv, 1)
            self._k("residual", n)(phi, rhs, lv, res)
            cx, cy, cz = self.coarsen_axes[lvl]
            self._k("restrict", self.rhs[lvl + 1].size)(res, cx, cy, cz, lv.px, lv.py, lv.pz,
                                                   self.rhs[lvl + 1])
        for lvl in range(L - 2, -1, -1):
            lv, phi, rhs = self.levels[lvl], self.phi[lvl], self.rhs[lvl]
            n = phi.size
            cx, cy, cz = self.coarsen_axes[lvl]
            self._k("prolong_add", n)(self.phi[lvl + 1], cx, cy, cz, lv.px, lv.py, lv.pz, phi)
            gs = self._k("gauss_seidel_colour", n)
            for _ in range(2):
                gs(phi, rhs, lv, 1)
                gs(phi, rhs, lv, 0)
        out[...] = self.phi[0]

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
        self._k("residual", r.size)(phi, b, lv, r)
        self._remove_mean(r)
        rnorm = math.sqrt(self._dot(r, r))
        it = 0
        if rnorm > tol:
            self._precondition(r, z)
            p[...] = z
            rz = self._dot(r, z)
            while it < self.max_iterations:
                it += 1
                self._k("apply_operator", r.size)(p, lv, q)
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
            self._k("residual", b.size)(cur, b, lv, self.r)
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
