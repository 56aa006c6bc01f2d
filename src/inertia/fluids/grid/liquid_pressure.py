"""Free-surface pressure solve of `LiquidFluid`: multigrid-preconditioned CG, rigid bodies coupled
implicitly.

The system (see `liquid.build_face_weights` / `liquid.build_operator`) lives on the liquid cells:
couplings w_f / h^2 between liquid cells, a diagonal that also holds the ghost-fluid weights of
liquid-air faces (Dirichlet p = 0 at the free surface, Gibou et al. 2002), Neumann at walls and
solids (face weights = open fractions, Batty, Bertails and Bridson 2007). Air and empty solid
cells are not unknowns (their rows are zero, their values stay 0).

Preconditioner (``method="mgpcg"``): one V-cycle of McAdams, Sifakis and Teran (2010) on the
hierarchy of `pressure.PoissonSolver` (its transfer operators, red-black Gauss-Seidel smoothers,
face-coefficient coarsening) with their Dirichlet rule for coarse cells: a coarse cell is air
(Dirichlet, not an unknown) when any child is air, liquid when any other child is liquid, solid
otherwise; only couplings between two liquid cells are kept on every level and the diagonal of a
liquid cell sums all its face coefficients (so coarse liquid-air faces act as p = 0). Residuals are
masked to the liquid cells before restriction and corrections after prolongation, which keeps the
V-cycle symmetric (P~ = S P, R~ = R S). ``method="jacobi"``: diagonal preconditioner (for comparison).

Rigid bodies (Batty, Bertails and Bridson 2007, Sec. 5, the variational coupling): with B the map
from a body's velocity (v, omega) to the solid-face fluxes' divergence and kappa = rho (face area) h,
the pressure of the coupled step solves (L + kappa B M^-1 B^T) phi = -div(u*, V*) where V* is the
bodies' velocity before the fluid step; then the bodies receive the impulse kappa B^T phi (exactly the
pressure impulse `solver._pressure_impulses` sums) and V = V* + M^-1 kappa B^T phi satisfies the same
divergence-free condition as the liquid. The low-rank term is applied matrix-free inside CG (6 numbers
per dynamic body); the preconditioner ignores it. Implicit coupling is stable for bodies lighter than
the liquid they displace (added mass), where explicit pressure impulses oscillate or blow up.

Limitations: the preconditioner ignores the body term (a light body costs a few extra iterations);
faces' solid velocities are those of V* (the bodies' updated velocity reaches the faces at the next
step); the coarse Dirichlet rule drops liquid layers thinner than a coarse cell from that level
(correct, only a weaker preconditioner).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numba import njit

from ...math import world_inertia_inv_into
from . import pressure as P
from .obstacles import face_cells

METHODS = ("mgpcg", "jacobi")
AIR, LIQUID, SOLID = 0, 1, 2


# ----------------------------------------------------------------------------- level setup
@njit(cache=True)
def fine_cell_types(liquid, cell_solid, types):
    nx, ny, nz = liquid.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if liquid[i, j, k]:
                    types[i, j, k] = LIQUID
                elif cell_solid[i, j, k]:
                    types[i, j, k] = SOLID
                else:
                    types[i, j, k] = AIR


@njit(cache=True)
def coarse_cell_types(fine, cx, cy, cz, coarse):
    """McAdams et al. 2010: air if any child is air, else liquid if any child is liquid, else solid."""
    ncx, ncy, ncz = coarse.shape
    for I in range(ncx):
        for J in range(ncy):
            for Kc in range(ncz):
                air = False
                liq = False
                for di in range(2 if cx else 1):
                    for dj in range(2 if cy else 1):
                        for dk in range(2 if cz else 1):
                            t = fine[I * (2 if cx else 1) + di, J * (2 if cy else 1) + dj,
                                     Kc * (2 if cz else 1) + dk]
                            if t == AIR:
                                air = True
                            elif t == LIQUID:
                                liq = True
                coarse[I, J, Kc] = AIR if air else (LIQUID if liq else SOLID)


@njit(cache=True)
def restrict_to_liquid(ax, ay, az, diag, types, per):
    """Given face coefficients and diag = their sum per cell: keep the diagonal of liquid cells,
    zero it elsewhere, and zero every coupling that does not join two liquid cells (along a
    periodic axis the first and last face join the last and the first cell)."""
    nx, ny, nz = types.shape
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if types[i, j, k] != LIQUID:
                    diag[i, j, k] = 0.0
    for i in range(nx + 1):
        for j in range(ny):
            for k in range(nz):
                if per[0] and (i == 0 or i == nx):
                    if not (types[nx - 1, j, k] == LIQUID and types[0, j, k] == LIQUID):
                        ax[i, j, k] = 0.0
                elif not (0 < i < nx and types[i - 1, j, k] == LIQUID and types[i, j, k] == LIQUID):
                    ax[i, j, k] = 0.0
    for i in range(nx):
        for j in range(ny + 1):
            for k in range(nz):
                if per[1] and (j == 0 or j == ny):
                    if not (types[i, ny - 1, k] == LIQUID and types[i, 0, k] == LIQUID):
                        ay[i, j, k] = 0.0
                elif not (0 < j < ny and types[i, j - 1, k] == LIQUID and types[i, j, k] == LIQUID):
                    ay[i, j, k] = 0.0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz + 1):
                if per[2] and (k == 0 or k == nz):
                    if not (types[i, j, nz - 1] == LIQUID and types[i, j, 0] == LIQUID):
                        az[i, j, k] = 0.0
                elif not (0 < k < nz and types[i, j, k - 1] == LIQUID and types[i, j, k] == LIQUID):
                    az[i, j, k] = 0.0


@njit(cache=True)
def mask_to_liquid(a, types):
    """a = 0 outside the liquid cells."""
    af = a.reshape(a.size)
    tf = types.reshape(types.size)
    for i in range(af.size):
        if tf[i] != LIQUID:
            af[i] = 0.0


@njit(cache=True)
def jacobi_precondition(r, diag, z):
    rf = r.reshape(r.size)
    df = diag.reshape(diag.size)
    zf = z.reshape(z.size)
    for i in range(rf.size):
        zf[i] = rf[i] / df[i] if df[i] > 0.0 else 0.0


# ----------------------------------------------------------------------------- body coupling
@njit(cache=True)
def body_gather(d, types, faces, open_frac, owner, dyn, axis, h, origin, body_q, out):
    """out[b] += B_b^T d: sum over body b's closed faces of (1 - A_f) / h (d_L - d_R) G_f with
    G_f = (e_axis, (x_f - c_b) x e_axis) (linear part in out[b, :3], angular in out[b, 3:]).
    Faces on the domain sides and of non-dynamic bodies are skipped."""
    nx, ny, nz = d.shape
    for m in range(faces.shape[0]):
        b = owner[m]
        if b < 0 or not dyn[b]:
            continue
        i, j, k, il, jl, kl, interior = face_cells(faces[m], axis, nx, ny, nz)
        if not interior:
            continue
        s = (1.0 - open_frac[m]) / h * (d[il, jl, kl] - d[i, j, k])
        x = origin[0] + (i + (0.0 if axis == 0 else 0.5)) * h - body_q[b, 0]
        y = origin[1] + (j + (0.0 if axis == 1 else 0.5)) * h - body_q[b, 1]
        z = origin[2] + (k + (0.0 if axis == 2 else 0.5)) * h - body_q[b, 2]
        out[b, axis] += s
        if axis == 0:      # r x e_x = (0, z, -y)
            out[b, 4] += z * s
            out[b, 5] -= y * s
        elif axis == 1:    # r x e_y = (-z, 0, x)
            out[b, 3] -= z * s
            out[b, 5] += x * s
        else:              # r x e_z = (y, -x, 0)
            out[b, 3] += y * s
            out[b, 4] -= x * s


@njit(cache=True)
def body_scatter(y6, types, faces, open_frac, owner, dyn, axis, h, origin, body_q, q):
    """q += B y: each closed face adds (1 - A_f) / h G_f . y_b to its low-side cell and subtracts
    it from its high-side cell (liquid cells only)."""
    nx, ny, nz = q.shape
    for m in range(faces.shape[0]):
        b = owner[m]
        if b < 0 or not dyn[b]:
            continue
        i, j, k, il, jl, kl, interior = face_cells(faces[m], axis, nx, ny, nz)
        if not interior:
            continue
        x = origin[0] + (i + (0.0 if axis == 0 else 0.5)) * h - body_q[b, 0]
        y = origin[1] + (j + (0.0 if axis == 1 else 0.5)) * h - body_q[b, 1]
        z = origin[2] + (k + (0.0 if axis == 2 else 0.5)) * h - body_q[b, 2]
        g = y6[b, axis]
        if axis == 0:
            g += z * y6[b, 4] - y * y6[b, 5]
        elif axis == 1:
            g += -z * y6[b, 3] + x * y6[b, 5]
        else:
            g += y * y6[b, 3] - x * y6[b, 4]
        s = (1.0 - open_frac[m]) / h * g
        if types[il, jl, kl] == LIQUID:
            q[il, jl, kl] += s
        if types[i, j, k] == LIQUID:
            q[i, j, k] -= s


@njit(cache=True)
def apply_inverse_mass(s6, dyn, inv_mass, inv_inertia, body_q, kappa, y6, rot, iw):
    """y_b = kappa M_b^-1 s_b (world inverse inertia for the angular part); rot, iw: (3, 3)
    scratch for R(q) and R diag(I^-1) R^T (`math.world_inertia_inv`'s operations, written into
    them instead of two new 3x3 arrays per body)."""
    for b in range(s6.shape[0]):
        for c in range(6):
            y6[b, c] = 0.0
        if not dyn[b]:
            continue
        m = inv_mass[b] * kappa
        y6[b, 0] = m * s6[b, 0]
        y6[b, 1] = m * s6[b, 1]
        y6[b, 2] = m * s6[b, 2]
        world_inertia_inv_into(body_q[b, 3:7], inv_inertia[b], rot, iw)
        for r in range(3):
            y6[b, 3 + r] = kappa * (iw[r, 0] * s6[b, 3] + iw[r, 1] * s6[b, 4] + iw[r, 2] * s6[b, 5])


class BodyCoupling:
    """The low-rank body term kappa B M^-1 B^T of the coupled pressure system (see the module
    docstring). cut: per axis (closed flat faces, open fractions, owner body); dyn: (B,) bool, the
    dynamic bodies; inv_mass (B,), inv_inertia (B, 3) (body-frame diagonal); body_q (B, 7);
    origin (3,) grid origin (z shifted so 2-D faces sit at z = 0); kappa = rho (face area) h."""

    def __init__(self, cut, dyn, inv_mass, inv_inertia, body_q, origin, h, kappa, dim):
        self.cut, self.dyn, self.dim = cut, dyn, dim
        self.inv_mass, self.inv_inertia, self.body_q = inv_mass, inv_inertia, body_q
        self.origin, self.h, self.kappa = origin, h, kappa
        nb = dyn.shape[0]
        self.s6 = np.zeros((nb, 6))
        self.y6 = np.zeros((nb, 6))
        self._rot = np.zeros((3, 3))
        self._iw = np.zeros((3, 3))

    def add_to(self, d, types, q):
        """q += kappa B M^-1 B^T d."""
        self.s6[...] = 0.0
        for a in range(self.dim):
            faces, frac, owner = self.cut[a]
            if faces.size:
                body_gather(d, types, faces, frac, owner, self.dyn, a, self.h, self.origin,
                            self.body_q, self.s6)
        apply_inverse_mass(self.s6, self.dyn, self.inv_mass, self.inv_inertia, self.body_q,
                           self.kappa, self.y6, self._rot, self._iw)
        for a in range(self.dim):
            faces, frac, owner = self.cut[a]
            if faces.size:
                body_scatter(self.y6, types, faces, frac, owner, self.dyn, a, self.h, self.origin,
                             self.body_q, q)


# ----------------------------------------------------------------------------- the solver
class LiquidPressure:
    """PCG for the liquid's pressure (see the module docstring).

    shape : (nx, ny, nz) cells; method : "mgpcg" (default) or "jacobi"; tolerance : relative
    residual; max_iterations; parallel : parallel kernels on large levels (None: by size)."""

    def __init__(self, shape, *, method="mgpcg", tolerance=1e-8, max_iterations=2000,
                 parallel=None, periodic=None):
        if method not in METHODS:
            raise ValueError(f"pressure_solver must be one of {METHODS}; got {method!r}")
        self.method = method
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.periodic = np.zeros(3, np.bool_) if periodic is None else np.asarray(periodic, np.bool_)
        self.mg = P.PoissonSolver(shape, tuple(bool(v) for v in self.periodic),
                                  method="mgpcg" if method == "mgpcg" else "cg",
                                  tolerance=tolerance, parallel=parallel)
        self.types = [np.zeros(lv.diag.shape, np.int8) for lv in self.mg.levels]
        self.last_iterations = 0
        self.last_residual = 0.0

    @property
    def level(self):
        """The finest level (face couplings and diagonal of the liquid operator)."""
        return self.mg.levels[0]

    def set_operator(self, liquid, cell_solid, weights, h, dim, surface):
        """Build every level from the face weights (`liquid.build_face_weights`); `surface`:
        whether a liquid-air face exists (else the Neumann problem is singular)."""
        mg = self.mg
        mg.set_coefficients(weights[0], weights[1], weights[2], h, dim)
        fine_cell_types(liquid, cell_solid, self.types[0])
        for lvl in range(1, len(mg.levels)):
            cx, cy, cz = mg.coarsen_axes[lvl - 1]
            coarse_cell_types(self.types[lvl - 1], cx, cy, cz, self.types[lvl])
        for lv, t in zip(mg.levels, self.types):
            restrict_to_liquid(lv.ax, lv.ay, lv.az, lv.diag, t, self.periodic)
        np.greater(mg.levels[0].diag, 0.0, out=mg.active)
        mg.active_count = int(np.count_nonzero(mg.active))
        mg.singular = not surface

    def _vcycle(self, r, z):
        """z = S V S r: one V-cycle from zero (masked to the liquid cells on every level)."""
        mg = self.mg
        L = len(mg.levels)
        mg.rhs[0][...] = r
        for lvl in range(L):
            lv, phi, rhs, res = mg.levels[lvl], mg.phi[lvl], mg.rhs[lvl], mg.res[lvl]
            n = phi.size
            phi[...] = 0.0
            if lvl == L - 1:
                P.coarse_solve(phi, rhs, lv, max(20, 2 * max(phi.shape)))
                break
            mg._smooth(n)(phi, rhs, lv, 0, 2)
            mg._k("operator_kernel", n)(phi, rhs, lv, res, 1)
            mask_to_liquid(res, self.types[lvl])
            pro, rtab, scale = mg.transfer[lvl]
            mg._k("restrict", mg.rhs[lvl + 1].size)(res, *rtab, scale, mg.rhs[lvl + 1])
        for lvl in range(L - 2, -1, -1):
            lv, phi, rhs = mg.levels[lvl], mg.phi[lvl], mg.rhs[lvl]
            n = phi.size
            pro, rtab, scale = mg.transfer[lvl]
            mg._k("prolong_add", n)(mg.phi[lvl + 1], *pro, phi)
            mask_to_liquid(phi, self.types[lvl])
            mg._smooth(n)(phi, rhs, lv, 1, 2)
        z[...] = mg.phi[0]

    def _apply(self, d, q, coupling):
        mg = self.mg
        mg._k("operator_kernel", d.size)(d, d, mg.levels[0], q, 0)
        if coupling is not None:
            coupling.add_to(d, self.types[0], q)

    def _precondition(self, r, z):
        if self.method == "mgpcg":
            self._vcycle(r, z)
        else:
            jacobi_precondition(r, self.mg.levels[0].diag, z)
        self.mg._remove_mean(z)

    def solve(self, b, phi, coupling=None, warm=False, tolerance=None):
        """Solve (L [+ body term]) phi = b (b: zero outside the liquid; modified when the system is
        singular) from phi = 0, or with ``warm=True`` from the phi passed in (masked to the liquid
        cells), to the relative residual `tolerance` (default: the solver's). Returns (iterations,
        relative residual ||b - L phi|| / ||b||)."""
        tolerance = self.tolerance if tolerance is None else tolerance
        mg = self.mg
        dot = mg._dot
        mg._remove_mean(b)
        r, z, p, q = mg.r, mg.z, mg.p, mg.q
        if warm:
            mask_to_liquid(phi, self.types[0])
            mg._remove_mean(phi)
        else:
            phi[...] = 0.0
        bnorm = math.sqrt(dot(b, b))
        if bnorm == 0.0:
            phi[...] = 0.0
            self.last_iterations, self.last_residual = 0, 0.0
            return 0, 0.0
        rf, zf, pf, qf, phif = (a.reshape(-1) for a in (r, z, p, q, phi))
        tol = tolerance * bnorm
        if warm:
            # r = b - A phi0: the solve only works on what changed since phi0
            self._apply(phi, q, coupling)
            np.subtract(b, q, out=r)
            mask_to_liquid(r, self.types[0])
        else:
            r[...] = b
        self._precondition(r, z)
        p[...] = z
        rz = dot(r, z)
        it = 0
        rnorm = bnorm
        while it < self.max_iterations:
            it += 1
            self._apply(p, q, coupling)
            alpha = rz / dot(p, q)
            mg._vk.axpy(alpha, pf, phif)
            mg._vk.axpy(-alpha, qf, rf)
            rnorm = math.sqrt(dot(r, r))
            if rnorm <= tol:
                break
            self._precondition(r, z)
            rz_new = dot(r, z)
            beta = rz_new / rz
            rz = rz_new
            mg._vk.xpby(zf, beta, pf)
        self.last_iterations, self.last_residual = it, rnorm / bnorm
        if rnorm > tol:
            warnings.warn(f"liquid pressure solve ({self.method}) did not converge: relative "
                          f"residual {rnorm / bnorm:.3e} after {it} iterations (tolerance "
                          f"{tolerance:.1e}); raise max_iterations", RuntimeWarning,
                          stacklevel=3)
        return it, rnorm / bnorm


@njit(cache=True)
def set_body_face_velocities(vel_a, solid_a, faces, open_frac, owner, dyn, axis, h, origin, body_q,
                             body_qd):
    """After the coupled solve moved the bodies' velocity: the solid velocity e_axis . (v + w x r)
    of every closed face of a dynamic body, and the face velocity of its fully closed faces
    (body_qd rows: angular (3), linear (3))."""
    sx, sy, sz = vel_a.shape
    for m in range(faces.shape[0]):
        b = owner[m]
        if b < 0 or not dyn[b]:
            continue
        f = faces[m]
        k = f % sz
        j = (f // sz) % sy
        i = f // (sz * sy)
        x = origin[0] + (i + (0.0 if axis == 0 else 0.5)) * h - body_q[b, 0]
        y = origin[1] + (j + (0.0 if axis == 1 else 0.5)) * h - body_q[b, 1]
        z = origin[2] + (k + (0.0 if axis == 2 else 0.5)) * h - body_q[b, 2]
        wx, wy, wz = body_qd[b, 0], body_qd[b, 1], body_qd[b, 2]
        if axis == 0:
            u = body_qd[b, 3] + wy * z - wz * y
        elif axis == 1:
            u = body_qd[b, 4] + wz * x - wx * z
        else:
            u = body_qd[b, 5] + wx * y - wy * x
        solid_a[i, j, k] = u
        if open_frac[m] <= 0.0:
            vel_a[i, j, k] = u
