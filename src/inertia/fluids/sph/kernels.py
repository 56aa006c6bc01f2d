"""Numba kernels of the SPH step: density, DFSPH pressure iterations, WCSPH pressure, viscosity,
XSPH, surface tension, advection, body wrenches and fixed-chunk reductions.

All kernels work in sorted space (see ``neighbours``) on the bundles ``FluidArrays``,
``Neighbours`` and ``BoundaryArrays``; every parallel loop writes only row i of its outputs
(gathers over the CSR neighbour lists), so results are the same at any thread count.

Notation: ``m`` fluid particle mass [kg], ``rho0`` rest density [kg/m^3], ``psi_b = rho0 V_b``
the boundary particle's "mass" [kg] (Akinci et al. 2012), ``g_ij = grad_i W(x_i - x_j)``.
The pressure is carried as ``k_i = p_i / rho_i^2`` [m^5/(kg s^2)]: the symmetric pressure
acceleration is ``a_i = -sum_j m (k_i + k_j) g_ij - bfac k_i sum_b psi_b g_ib`` for both WCSPH
and DFSPH: ``bfac = 1`` Akinci et al. 2012's boundary force, ``bfac = 2`` the pressure mirrored
into the symmetric sum (k_b = k_i; ``SPHFluid(boundary_pressure=...)``).

References: see the module docstring of ``inertia.fluids.sph.fluid``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ...collision import distance as _dist
from .neighbours import _min_image


class FluidArrays(NamedTuple):
    """Per fluid particle, in sorted space; rows [0, n) are live (capacity rows allocated)."""
    x: np.ndarray        # (cap, D) [m] position; advect
    v: np.ndarray        # (cap, D) [m/s] velocity; every velocity stage
    rho: np.ndarray      # (cap,) [kg/m^3] summed density; density_and_factor
    factor: np.ndarray   # (cap,) [1/kg^2 m^...] DFSPH factor 1/(|sum m g|^2 + sum |m g|^2); density_and_factor
    k_dens: np.ndarray   # (cap,) [m^5/(kg s^2)] p / rho^2 of the density solve (WCSPH: Tait); kept for warm start
    k_div: np.ndarray    # (cap,) [m^5/(kg s^2)] p / rho^2 of the divergence solve; kept for warm start
    kappa: np.ndarray    # (cap,) the k increment of the current iteration
    err: np.ndarray      # (cap,) per-particle error of the current iteration [kg/m^3 or kg/(m^3 s)]
    accel: np.ndarray    # (cap, D) [m/s^2] non-pressure acceleration; nonpressure_accel
    normal: np.ndarray   # (cap, D) [1] Akinci 2013 surface normal (support * grad colour); surface_normals
    scratch: np.ndarray  # (cap, D) scratch velocities (XSPH)


class Neighbours(NamedTuple):
    """CSR neighbour lists of the fluid particles (sorted space), written by fill_neighbours."""
    start: np.ndarray    # (cap + 1,) int64: neighbours of i are start[i]:start[i+1]
    j: np.ndarray        # (M,) int32 neighbour index (fluid or boundary set)
    w: np.ndarray        # (M,) [1/m^D] W_ij
    g: np.ndarray        # (M, D) [1/m^(D+1)] grad_i W_ij


class BoundaryArrays(NamedTuple):
    """Boundary particles (sorted by cell), written by SPHFluid when bodies move."""
    x: np.ndarray        # (Nb, D) [m] position
    v: np.ndarray        # (Nb, D) [m/s] velocity of the solid at the particle
    psi: np.ndarray      # (Nb,) [kg] rho0 * volume of the particle
    body: np.ndarray     # (Nb,) int64 owning body (-1 static)
    noslip: np.ndarray   # (Nb,) [m^2/s] viscosity towards this particle (0 = slip)


REDUCE_CHUNKS = 64

# Boundary pressure (``bfac``, ``SPHFluid(boundary_pressure=...)``): "akinci" (bfac = 1) pushes with
# k_i psi_b g_ib (Akinci et al. 2012, as SPlisHSPlasH); "mirror" (bfac = 2) enters the mirrored
# pressure p_b = p_i in the symmetric term, m (k_i + k_b) = 2 m k_i. With k_i alone a uniform pressure
# pushes every particle next to a wall into it (the fluid-fluid sum gives 2 k_i, the wall 1 k_i), so
# the solver inflates k near walls and a held submerged box felt 0.87 of rho0 g V. In the mirrored
# mode the wall's hydrostatic share is added once per step (``boundary_hydrostatic_kick``, Adami,
# Hu & Adams 2012) and given back to bodies (``body_hydrostatic_wrench``).


@njit(cache=True, parallel=True)
def chunk_sum_max(values, n, partial, out):
    """out[0] = sum(values[:n]), out[1] = max(values[:n]) in REDUCE_CHUNKS fixed chunks (the
    same bits at any thread count); partial (REDUCE_CHUNKS, 2) scratch."""
    chunk = (n + REDUCE_CHUNKS - 1) // REDUCE_CHUNKS
    for c in prange(REDUCE_CHUNKS):
        s = 0.0
        m = 0.0
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            s += values[i]
            if values[i] > m:
                m = values[i]
        partial[c, 0] = s
        partial[c, 1] = m
    s = 0.0
    m = 0.0
    for c in range(REDUCE_CHUNKS):
        s += partial[c, 0]
        m = max(m, partial[c, 1])
    out[0] = s
    out[1] = m


@njit(cache=True, parallel=True)
def speed_squared(v, n, out):
    """out[i] = |v_i|^2 (NaN stays NaN)."""
    dim = v.shape[1]
    for i in prange(n):
        s = 0.0
        for d in range(dim):
            s += v[i, d] * v[i, d]
        out[i] = s if s == s else np.inf


@njit(cache=True, parallel=True)
def density_and_factor(F, nf, nb, B, n, mass, w0, factor_eps, bfac):
    """rho_i = m W(0) + sum_j m W_ij + sum_b psi_b W_ib; DFSPH factor (Bender & Koschier 2017,
    eq. 8 with the mass inside the sums), the exact diagonal d rho_i / d k_i of the pressure
    system with the boundary weight bfac: 1 / ((a + bfac b) . (a + b) + sum_j |m g_ij|^2) with
    a = sum_j m g_ij, b = sum_b psi_b g_ib (bfac = 1: |a + b|^2 as in the paper); 0 where the
    denominator is below factor_eps (isolated particles)."""
    F_factor = F.factor  # unpacked: Numba drops writes through a named tuple inside prange
    F_rho = F.rho
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        rho = mass * w0
        gx = 0.0
        gy = 0.0
        gz = 0.0
        bx = 0.0
        by = 0.0
        bz = 0.0
        s = 0.0
        for k in range(nf.start[i], nf.start[i + 1]):
            rho += mass * nf.w[k]
            ax = mass * nf.g[k, 0]
            ay = mass * nf.g[k, 1]
            az = mass * nf.g[k, 2] if dim == 3 else 0.0
            gx += ax
            gy += ay
            gz += az
            s += ax * ax + ay * ay + az * az
        for k in range(nb.start[i], nb.start[i + 1]):
            psi = B.psi[nb.j[k]]
            rho += psi * nb.w[k]
            bx += psi * nb.g[k, 0]
            by += psi * nb.g[k, 1]
            if dim == 3:
                bz += psi * nb.g[k, 2]
        F_rho[i] = rho
        # d rho_i / d k_i: the own push (fluid a + bfac x boundary b) against both sums (a + b)
        denom = (gx + bfac * bx) * (gx + bx) + (gy + bfac * by) * (gy + by) + (gz + bfac * bz) * (gz + bz) + s
        F_factor[i] = 1.0 / denom if denom > factor_eps else 0.0


@njit(cache=True, parallel=True)
def pressure_increment(F, nf, nb, B, n, mass, rho0, dt, density_mode, relaxation, momentum, total, beta, partial,
                       out):
    """One DFSPH iteration, first half (Bender & Koschier 2017, algorithms 2 and 3).

    density_mode: predicted density rho*_i = rho_i + dt drho_i/dt must reach rho0:
        kappa_i = omega e_i / dt^2 * factor_i;  e_i = beta (rho_i - rho0) + dt drho_i/dt,
        beta <= 1 the share of the present compression removed within this step (1: all of it,
        as the paper; SPHFluid lowers it for steps shorter than the CFL step at the flow's
        speed scale, so that removing old compression never needs more than that speed).
    divergence mode: drho_i/dt must vanish:
        kappa_i = omega (drho_i/dt) / dt * factor_i;  e_i = drho_i/dt.
    err_i = |e_i| where the particle is compressed or carries pressure, else 0 (the residual
    of the complementarity problem p >= 0, rho* <= rho0, p (rho* - rho0) = 0).
    omega = relaxation: the factor is the exact diagonal of the pressure system, whose
    off-diagonal sum exceeds it (not diagonally dominant), so plain Jacobi (omega = 1) lets the
    checkerboard mode grow when iterated to convergence; omega = 0.5 is the relaxed Jacobi of
    Ihmsen et al. (2014), "Implicit incompressible SPH", IEEE TVCG 20(3), and converges.
    momentum: kappa_i += momentum * (the previous iteration's kappa_i, read from F.kappa: the
    caller zeroes it before the first iteration), the heavy ball of ``SPHFluid._solve``.
    The pressure stays non-negative (free surfaces): kappa_i is projected so that the running
    total (k_dens or k_div, passed as ``total``, added to by apply_pressure) stays >= 0.
    Fused with the reduction of err (``chunk_sum_max``'s fixed chunks, the same bits): out[0] =
    sum(err[:n]), out[1] = max(err[:n]); partial (REDUCE_CHUNKS, 2) scratch. One parallel
    region per half-iteration instead of two (each region is a barrier)."""
    F_err = F.err  # unpacked: Numba drops writes through a named tuple inside prange
    F_factor = F.factor
    F_kappa = F.kappa
    F_rho = F.rho
    F_v = F.v
    dim = F_v.shape[1]
    f_start = nf.start
    f_j = nf.j
    f_g = nf.g
    b_start = nb.start
    b_j = nb.j
    b_g = nb.g
    B_psi = B.psi
    B_v = B.v
    chunk = (n + REDUCE_CHUNKS - 1) // REDUCE_CHUNKS
    for c in prange(REDUCE_CHUNKS):
        s_err = 0.0
        m_err = 0.0
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            # d rho_i / dt = sum_j m (v_i - v_j) . g_ij + sum_b psi_b (v_i - v_b) . g_ib (one running
            # sum in the order of a loop over the axes)
            vix = F_v[i, 0]
            viy = F_v[i, 1]
            viz = F_v[i, 2] if dim == 3 else 0.0
            rate = 0.0
            for k in range(f_start[i], f_start[i + 1]):
                j = f_j[k]
                rate += mass * (vix - F_v[j, 0]) * f_g[k, 0]
                rate += mass * (viy - F_v[j, 1]) * f_g[k, 1]
                if dim == 3:
                    rate += mass * (viz - F_v[j, 2]) * f_g[k, 2]
            for k in range(b_start[i], b_start[i + 1]):
                b = b_j[k]
                psi = B_psi[b]
                rate += psi * (vix - B_v[b, 0]) * b_g[k, 0]
                rate += psi * (viy - B_v[b, 1]) * b_g[k, 1]
                if dim == 3:
                    rate += psi * (viz - B_v[b, 2]) * b_g[k, 2]
            if density_mode:
                e = beta * (F_rho[i] - rho0) + dt * rate
                kap = relaxation * e * F_factor[i] / (dt * dt)
            else:
                e = rate
                kap = relaxation * e * F_factor[i] / dt
            kap += momentum * F_kappa[i]   # heavy ball: the previous increment (0 in the first iteration)
            # complementarity residual: compressed particles, and pressurised ones in either sign
            ei = abs(e) if (e > 0.0 or total[i] > 0.0) else 0.0
            F_err[i] = ei
            s_err += ei
            if ei > m_err:
                m_err = ei
            if total[i] + kap < 0.0:
                kap = -total[i]
            F_kappa[i] = kap
        partial[c, 0] = s_err
        partial[c, 1] = m_err
    s_err = 0.0
    m_err = 0.0
    for c in range(REDUCE_CHUNKS):
        s_err += partial[c, 0]
        m_err = max(m_err, partial[c, 1])
    out[0] = s_err
    out[1] = m_err


@njit(cache=True, parallel=True)
def apply_pressure(F, nf, nb, B, n, mass, dt, kappa, total, accumulate, bfac):
    """v_i += dt a_i with a_i = -sum_j m (kappa_i + kappa_j) g_ij - bfac kappa_i sum_b psi_b g_ib
    (the symmetric SPH pressure acceleration, kappa = p / rho^2; bfac see the module docstring);
    with accumulate, total_i += kappa_i (row i only: the sums read kappa, never total)."""
    F_v = F.v  # unpacked: Numba drops writes through a named tuple inside prange
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        ki = kappa[i]
        ax = 0.0
        ay = 0.0
        az = 0.0
        for k in range(nf.start[i], nf.start[i + 1]):
            s = mass * (ki + kappa[nf.j[k]])
            ax -= s * nf.g[k, 0]
            ay -= s * nf.g[k, 1]
            if dim == 3:
                az -= s * nf.g[k, 2]
        if ki != 0.0:
            for k in range(nb.start[i], nb.start[i + 1]):
                s = bfac * ki * B.psi[nb.j[k]]
                ax -= s * nb.g[k, 0]
                ay -= s * nb.g[k, 1]
                if dim == 3:
                    az -= s * nb.g[k, 2]
        F_v[i, 0] += dt * ax
        F_v[i, 1] += dt * ay
        if dim == 3:
            F_v[i, 2] += dt * az
        if accumulate:
            total[i] += ki


@njit(cache=True, parallel=True)
def tait_pressure(F, n, rho0, stiffness, exponent):
    """WCSPH (Becker & Teschner 2007, eq. 6): p = B ((rho/rho0)^gamma - 1), clamped at 0 (no
    tension at the free surface); stored as k_dens = p / rho^2."""
    F_k_dens = F.k_dens  # unpacked: Numba drops writes through a named tuple inside prange
    F_rho = F.rho
    for i in prange(n):
        rho = F_rho[i]
        p = stiffness * ((rho / rho0) ** exponent - 1.0)
        F_k_dens[i] = p / (rho * rho) if p > 0.0 else 0.0


@njit(cache=True, parallel=True)
def surface_normals(F, nf, n, mass, support):
    """Akinci et al. 2013, eq. 4: n_i = support * sum_j (m / rho_j) g_ij."""
    F_normal = F.normal  # unpacked: Numba drops writes through a named tuple inside prange
    F_rho = F.rho
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        for d in range(dim):
            F_normal[i, d] = 0.0
        for k in range(nf.start[i], nf.start[i + 1]):
            s = support * mass / F_rho[nf.j[k]]
            for d in range(dim):
                F_normal[i, d] += s * nf.g[k, d]


@njit(cache=True, inline="always")
def _cohesion_spline(r, support):
    # Akinci et al. 2013, eq. 2: C(r) = 32 / (pi H^9) {(H - r)^3 r^3 if 2r > H; 2 (H - r)^3 r^3 - H^6/64 if 0 < 2r <= H}
    if r >= support or r <= 0.0:
        return 0.0
    c = 32.0 / (np.pi * support ** 9)
    t = (support - r) ** 3 * r ** 3
    if 2.0 * r > support:
        return c * t
    return c * (2.0 * t - support ** 6 / 64.0)


@njit(cache=True, parallel=True)
def nonpressure_accel(F, nf, nb, B, grid, n, mass, rho0, h, viscosity, wall_viscosity, tension, gravity):
    """accel_i = gravity + viscosity + surface tension (non-pressure accelerations); the wall
    viscous term only with wall_viscosity (off when the viscosity is solved implicitly).

    Viscosity (laminar, Monaghan 2005 / Morris et al. 1997 form, as used by Weiler et al. 2018):
        a_i = 2 (D + 2) nu sum_j (m / rho_ij) (v_ij . x_ij) / (|x_ij|^2 + 0.01 h^2) g_ij
    with rho_ij = (rho_i + rho_j) / 2, so that the pair forces are equal and opposite (momentum)
    and against no-slip boundary particles the same with (psi_b / rho0, B.noslip[b]) and the
    mirrored velocity 2 v_b - v_i (Morris et al. 1997), which puts the no-slip condition on the wall.
    Surface tension (Akinci, Akinci & Teschner 2013, eqs. 1-6), per unit mass:
        a_i = sum_j 2 rho0 / (rho_i + rho_j) [-tension m C(|x_ij|) x_ij / |x_ij| - tension (n_i - n_j)]."""
    F_accel = F.accel  # unpacked: Numba drops writes through a named tuple inside prange
    F_k_dens = F.k_dens
    F_normal = F.normal
    F_rho = F.rho
    F_v = F.v
    F_x = F.x
    dim = F_x.shape[1]
    support = 2.0 * h
    visc_scale = 2.0 * (dim + 2)
    eps = 0.01 * h * h
    for i in prange(n):
        ax = gravity[0]
        ay = gravity[1]
        az = gravity[2] if dim == 3 else 0.0
        x2 = F_x[i, 2] if dim == 3 else 0.0
        for k in range(nf.start[i], nf.start[i + 1]):
            j = nf.j[k]
            rx = _min_image(F_x[i, 0] - F_x[j, 0], 0, grid)
            ry = _min_image(F_x[i, 1] - F_x[j, 1], 1, grid)
            rz = _min_image(x2 - F_x[j, 2], 2, grid) if dim == 3 else 0.0
            r2 = rx * rx + ry * ry + rz * rz
            if viscosity > 0.0:
                vx = F_v[i, 0] - F_v[j, 0]
                vy = F_v[i, 1] - F_v[j, 1]
                vz = (F_v[i, 2] - F_v[j, 2]) if dim == 3 else 0.0
                s = visc_scale * viscosity * 2.0 * mass / (F_rho[i] + F_rho[j]) * (vx * rx + vy * ry + vz * rz) / (r2 + eps)
                ax += s * nf.g[k, 0]
                ay += s * nf.g[k, 1]
                if dim == 3:
                    az += s * nf.g[k, 2]
            if tension > 0.0:
                kij = 2.0 * rho0 / (F_rho[i] + F_rho[j])
                r = np.sqrt(r2)
                coh = -tension * mass * _cohesion_spline(r, support) / r if r > 0.0 else 0.0
                ax += kij * (coh * rx - tension * (F_normal[i, 0] - F_normal[j, 0]))
                ay += kij * (coh * ry - tension * (F_normal[i, 1] - F_normal[j, 1]))
                if dim == 3:
                    az += kij * (coh * rz - tension * (F_normal[i, 2] - F_normal[j, 2]))
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            nu_b = B.noslip[b]
            if nu_b <= 0.0 or not wall_viscosity:
                continue
            rx = F_x[i, 0] - B.x[b, 0]
            ry = F_x[i, 1] - B.x[b, 1]
            rz = (x2 - B.x[b, 2]) if dim == 3 else 0.0
            vx = F_v[i, 0] - B.v[b, 0]
            vy = F_v[i, 1] - B.v[b, 1]
            vz = (F_v[i, 2] - B.v[b, 2]) if dim == 3 else 0.0
            r2 = rx * rx + ry * ry + rz * rz
            # mirrored no-slip velocity v_b* = 2 v_b - v_i (Morris et al. 1997): v_i - v_b* = 2 (v_i - v_b)
            s = 2.0 * visc_scale * nu_b * B.psi[b] / rho0 * (vx * rx + vy * ry + vz * rz) / (r2 + eps)
            ax += s * nb.g[k, 0]
            ay += s * nb.g[k, 1]
            if dim == 3:
                az += s * nb.g[k, 2]
        F_accel[i, 0] = ax
        F_accel[i, 1] = ay
        if dim == 3:
            F_accel[i, 2] = az


@njit(cache=True, parallel=True)
def kick(F, n, dt):
    """v_i += dt accel_i."""
    F_accel = F.accel  # unpacked: Numba drops writes through a named tuple inside prange
    F_v = F.v
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        for d in range(dim):
            F_v[i, d] += dt * F_accel[i, d]


@njit(cache=True, parallel=True)
def xsph(F, nf, n, mass, epsilon):
    """XSPH velocity smoothing (Monaghan 1989, "On the problem of penetration in particle methods";
    symmetric form): v_i += epsilon sum_j 2 m / (rho_i + rho_j) (v_j - v_i) W_ij. Conserves
    momentum (antisymmetric exchange). Reads v, writes scratch, then copies back."""
    F_rho = F.rho  # unpacked: Numba drops writes through a named tuple inside prange
    F_scratch = F.scratch
    F_v = F.v
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        for d in range(dim):
            F_scratch[i, d] = F_v[i, d]
        for k in range(nf.start[i], nf.start[i + 1]):
            j = nf.j[k]
            s = epsilon * 2.0 * mass / (F_rho[i] + F_rho[j]) * nf.w[k]
            for d in range(dim):
                F_scratch[i, d] += s * (F_v[j, d] - F_v[i, d])
    for i in prange(n):
        for d in range(dim):
            F_v[i, d] = F_scratch[i, d]


@njit(cache=True, parallel=True)
def advect(F, grid, n, dt):
    """x_i += dt v_i (symplectic Euler: the new velocity), wrapped into the periodic axes."""
    F_v = F.v  # unpacked: Numba drops writes through a named tuple inside prange
    F_x = F.x
    dim = F_x.shape[1]
    for i in prange(n):
        for d in range(dim):
            xd = F_x[i, d] + dt * F_v[i, d]
            if grid.periodic[d]:
                L = grid.length[d]
                xd = grid.lo[d] + (xd - grid.lo[d]) - L * np.floor((xd - grid.lo[d]) / L)
            F_x[i, d] = xd


@njit(cache=True)
def body_wrench(F, nb, B, n, mass, rho0, h, com, force, torque, bfac):
    """Force and torque of the fluid on each body (serial, fixed order: deterministic).

    The reaction of the pressure acceleration on fluid particle i from boundary particle b
    (Akinci et al. 2012, eq. 10): f_b = bfac m (k_dens_i + k_div_i) psi_b g_ib, plus the reaction of
    the no-slip viscous term; torque about com[body]: (x_b - com) x f_b. force, torque (nbody, 3)."""
    dim = F.x.shape[1]
    force[:] = 0.0
    torque[:] = 0.0
    visc_scale = 2.0 * (dim + 2)
    eps = 0.01 * h * h
    for i in range(n):
        ki = F.k_dens[i] + F.k_div[i]
        x2 = F.x[i, 2] if dim == 3 else 0.0
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            body = B.body[b]
            if body < 0:
                continue
            s = bfac * mass * ki * B.psi[b]
            nu_b = B.noslip[b]
            if nu_b > 0.0:
                rx = F.x[i, 0] - B.x[b, 0]
                ry = F.x[i, 1] - B.x[b, 1]
                rz = (x2 - B.x[b, 2]) if dim == 3 else 0.0
                vx = F.v[i, 0] - B.v[b, 0]
                vy = F.v[i, 1] - B.v[b, 1]
                vz = (F.v[i, 2] - B.v[b, 2]) if dim == 3 else 0.0
                s -= 2.0 * mass * visc_scale * nu_b * B.psi[b] / rho0 * (vx * rx + vy * ry + vz * rz) / (
                    rx * rx + ry * ry + rz * rz + eps)
            fx = s * nb.g[k, 0]
            fy = s * nb.g[k, 1]
            fz = s * nb.g[k, 2] if dim == 3 else 0.0
            px = B.x[b, 0] - com[body, 0]
            py = B.x[b, 1] - com[body, 1]
            pz = (B.x[b, 2] - com[body, 2]) if dim == 3 else 0.0
            force[body, 0] += fx
            force[body, 1] += fy
            force[body, 2] += fz
            torque[body, 0] += py * fz - pz * fy
            torque[body, 1] += pz * fx - px * fz
            torque[body, 2] += px * fy - py * fx


@njit(cache=True, inline="always")
def _wall_body_force_share(gravity, bx, fx, b, i, normal, grid):
    # the wall-normal part of g . (x_b - x_i): (g . n_b)(n_b . (x_b - x_i)) (extrapolated mode)
    dim = fx.shape[1]
    gn = gravity[0] * normal[b, 0] + gravity[1] * normal[b, 1]
    dn = normal[b, 0] * _min_image(bx[b, 0] - fx[i, 0], 0, grid) + normal[b, 1] * _min_image(bx[b, 1] - fx[i, 1], 1, grid)
    if dim == 3:
        gn += gravity[2] * normal[b, 2]
        dn += normal[b, 2] * _min_image(bx[b, 2] - fx[i, 2], 2, grid)
    return gn * dn


@njit(cache=True, inline="always")
def _hydrostatic_share(gravity, bx, fx, b, i, normal, grid, k_i):
    # rho_i times the wall's hydrostatic share of k_b seen from fluid particle i. Under pressure
    # (k_i > 0): g . (x_b - x_i), on periodic axes with the minimum image (a boundary particle a
    # period away is its image next to i: without it the body force along a periodic channel gave
    # the walls the share of a whole period). Without pressure (k_i <= 0: free surface, free fall):
    # only the wall-normal part (g . n_b)(n_b . (x_b - x_i)), and never below 0 (no suction): the
    # part along the wall stands for the fluid's pressure gradient, which a fluid without pressure
    # does not have; taken pairwise it pushed a particle in free fall up a vertical slip wall (a
    # falling droplet reached 0.965 g t) and the fluid of a body-force-driven channel off its walls.
    if k_i > 0.0:
        dim = fx.shape[1]
        s = gravity[0] * _min_image(bx[b, 0] - fx[i, 0], 0, grid) + gravity[1] * _min_image(bx[b, 1] - fx[i, 1], 1, grid)
        if dim == 3:
            s += gravity[2] * _min_image(bx[b, 2] - fx[i, 2], 2, grid)
        return s
    s = _wall_body_force_share(gravity, bx, fx, b, i, normal, grid)
    return s if s > 0.0 else 0.0


@njit(cache=True, parallel=True)
def boundary_hydrostatic_kick(F, nb, B, grid, n, dt, gravity, normal, k_floor):
    """The hydrostatic part of the boundary pressure (Adami, Hu & Adams 2012, "A generalized wall
    boundary condition for smoothed particle hydrodynamics", J. Comput. Phys. 231: the wall
    pressure extrapolated from the fluid with the body force; here taken pairwise, without the
    wall's own acceleration): a boundary particle seen from fluid particle i carries
    p_b = p_i + rho_i g . (x_b - x_i), i.e. k_b = k_i + g . (x_b - x_i) / rho_i. The k_i parts act
    in the pressure solve (``apply_pressure``: k_i + k_b = 2 k_i, the mirror); this kernel adds the
    rest once per step: v_i -= dt sum_b psi_b h_ib g_ib with h_ib = ``_hydrostatic_share`` / rho_i
    (periodic axes: the minimum image; where k_i <= 0 only the wall-normal part, >= 0: no suction,
    no push up a wall beside a falling particle). k_i is the pressure at the time of the kick
    (k_dens of the last step + k_div of this one), written to ``k_floor`` for
    ``body_hydrostatic_wrench``. (Clamping k_b >= 0 with this k_i instead cut the ceiling's
    share at depth too: a held submerged box then felt 1.07 of rho0 g V.) Without this term a wall above the
    fluid (the underside of a submerged body) is pushed by the pressure at the fluid particle's
    depth instead of its own."""
    F_v = F.v  # unpacked: Numba drops writes through a named tuple inside prange
    F_x = F.x
    F_rho = F.rho
    F_k_dens = F.k_dens
    F_k_div = F.k_div
    dim = F_x.shape[1]
    for i in prange(n):
        ki = F_k_dens[i] + F_k_div[i]
        k_floor[i] = ki
        ax = 0.0
        ay = 0.0
        az = 0.0
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            h_ib = _hydrostatic_share(gravity, B.x, F_x, b, i, normal, grid, ki) / F_rho[i]
            s = B.psi[b] * h_ib
            ax -= s * nb.g[k, 0]
            ay -= s * nb.g[k, 1]
            if dim == 3:
                az -= s * nb.g[k, 2]
        F_v[i, 0] += dt * ax
        F_v[i, 1] += dt * ay
        if dim == 3:
            F_v[i, 2] += dt * az


@njit(cache=True)
def body_hydrostatic_wrench(F, nb, B, grid, n, mass, com, gravity, normal, k_floor, force, torque):
    """Adds to force, torque (nbody, 3) the reaction of ``boundary_hydrostatic_kick`` on the
    bodies' particles: f_b = m psi_b h_ib g_ib (h_ib as there, from k_floor), torque
    (x_b - com) x f_b (serial, fixed order; the positions, densities and k_floor of the kick of
    this step)."""
    dim = F.x.shape[1]
    for i in range(n):
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            body = B.body[b]
            if body < 0:
                continue
            h_ib = _hydrostatic_share(gravity, B.x, F.x, b, i, normal, grid, k_floor[i]) / F.rho[i]
            s = mass * B.psi[b] * h_ib
            fx = s * nb.g[k, 0]
            fy = s * nb.g[k, 1]
            fz = s * nb.g[k, 2] if dim == 3 else 0.0
            px = B.x[b, 0] - com[body, 0]
            py = B.x[b, 1] - com[body, 1]
            pz = (B.x[b, 2] - com[body, 2]) if dim == 3 else 0.0
            force[body, 0] += fx
            force[body, 1] += fy
            force[body, 2] += fz
            torque[body, 0] += py * fz - pz * fy
            torque[body, 1] += pz * fx - px * fz
            torque[body, 2] += px * fy - py * fx


@njit(cache=True, parallel=True)
def move_boundary(local, body, rest_x, body_x, body_rot, body_v, body_omega, x, v):
    """Boundary particles of moving bodies: x_b = c + R r_b, v_b = v_c + omega x (x_b - c);
    static particles (body -1) keep rest_x and zero velocity. body_rot (nbody, 3, 3),
    body_omega (nbody, 3) (2D: only the z component is used)."""
    nb, dim = x.shape
    for b in prange(nb):
        k = body[b]
        if k < 0:
            for d in range(dim):
                x[b, d] = rest_x[b, d]
                v[b, d] = 0.0
            continue
        r0 = body_rot[k, 0, 0] * local[b, 0] + body_rot[k, 0, 1] * local[b, 1]
        r1 = body_rot[k, 1, 0] * local[b, 0] + body_rot[k, 1, 1] * local[b, 1]
        r2 = 0.0
        if dim == 3:
            r0 += body_rot[k, 0, 2] * local[b, 2]
            r1 += body_rot[k, 1, 2] * local[b, 2]
            r2 = body_rot[k, 2, 0] * local[b, 0] + body_rot[k, 2, 1] * local[b, 1] + body_rot[k, 2, 2] * local[b, 2]
        wx, wy, wz = body_omega[k, 0], body_omega[k, 1], body_omega[k, 2]
        cx = wy * r2 - wz * r1
        cy = wz * r0 - wx * r2
        cz = wx * r1 - wy * r0
        x[b, 0] = body_x[k, 0] + r0
        x[b, 1] = body_x[k, 1] + r1
        v[b, 0] = body_v[k, 0] + cx
        v[b, 1] = body_v[k, 1] + cy
        if dim == 3:
            x[b, 2] = body_x[k, 2] + r2
            v[b, 2] = body_v[k, 2] + cz


# --------------------------------------------------------------------------- size dispatch
_PARALLEL_KERNELS = ("chunk_sum_max", "speed_squared", "density_and_factor", "pressure_increment",
                     "apply_pressure", "tait_pressure", "surface_normals", "nonpressure_accel", "kick",
                     "xsph", "advect", "move_boundary", "boundary_hydrostatic_kick")
_SETS = {}


# An SPH pass does 10-40 pair interactions per particle (2D-3D), and a step ~25 passes: about 16
# times the work per element of the flat particle kernels ``inertia._jit.SERIAL_BELOW`` (elements)
# was measured on, so the SPH kernels go parallel from SERIAL_BELOW / SPH_WORK_PER_ELEMENT
# particles (8192 by default: the 20 000-particle 2D dam break runs on both cores, the test scenes
# of a few thousand particles serially; INERTIA_SERIAL_BELOW=0 still means always parallel).
SPH_WORK_PER_ELEMENT = 16


def kernel_set(n: int):
    """The kernels to run for n particles: the parallel ones, or their serial twins (same code,
    compiled without ``parallel``; see ``inertia._jit``) below ``SERIAL_BELOW /
    SPH_WORK_PER_ELEMENT`` particles, where launching a parallel region costs more than the
    work. Twins compile on first use."""
    from types import SimpleNamespace

    from ..._jit import SERIAL_BELOW, serial_twin
    from . import neighbours as nb
    serial = n < SERIAL_BELOW // SPH_WORK_PER_ELEMENT
    if serial not in _SETS:
        g = globals()
        ns = {name: (serial_twin(g[name]) if serial else g[name]) for name in _PARALLEL_KERNELS}
        for name in ("bin_cells", "count_neighbours", "fill_neighbours", "fill_strided", "compact"):
            kern = getattr(nb, name)
            ns[name] = serial_twin(kern) if serial else kern
        from ...collision import broadphase as bp
        ns["gather"] = bp.gather_serial if serial else bp.gather
        _SETS[serial] = SimpleNamespace(**ns)
    return _SETS[serial]


# --------------------------------------------------------------------------- implicit viscosity
@njit(cache=True, parallel=True)
def viscosity_operator(F, nf, nb, B, grid, n, mass, rho0, h, nu, dt, p, out, diag, rhs_wall):
    """out_i = p_i - dt (L p)_i, the implicit viscosity matrix (Weiler, Koschier, Brand & Bender
    2018, "A physically consistent implicit viscosity solver for SPH fluids", CGF 37(2), with the
    laminar operator of ``nonpressure_accel``):
        (L p)_i = 2 (D + 2) [nu sum_j (m / rho_ij) (p_ij . x_ij) / (r^2 + 0.01 h^2) g_ij
                             + sum_b 2 nu_b (psi_b / rho0) (p_i . x_ib) / (r^2 + 0.01 h^2) g_ib].
    The pair blocks g_ij x_ij^T are symmetric (g_ij is parallel to x_ij) and negative semi-
    definite, so I - dt L is symmetric positive definite: conjugate gradients apply. Also
    writes diag_i = 1 - dt trace(L_ii) / D (Jacobi preconditioner) and rhs_wall_i =
    -dt sum_b 2 (D + 2) 2 nu_b (psi_b / rho0) (v_b . x_ib) / (r^2 + eps) g_ib (the known wall
    velocities moved to the right-hand side)."""
    F_rho = F.rho
    F_x = F.x
    dim = F_x.shape[1]
    scale = 2.0 * (dim + 2)
    eps = 0.01 * h * h
    for i in prange(n):
        x2 = F_x[i, 2] if dim == 3 else 0.0
        lx = 0.0
        ly = 0.0
        lz = 0.0
        tr = 0.0
        for k in range(nf.start[i], nf.start[i + 1]):
            j = nf.j[k]
            rx = _min_image(F_x[i, 0] - F_x[j, 0], 0, grid)
            ry = _min_image(F_x[i, 1] - F_x[j, 1], 1, grid)
            rz = _min_image(x2 - F_x[j, 2], 2, grid) if dim == 3 else 0.0
            c = scale * nu * 2.0 * mass / (F_rho[i] + F_rho[j]) / (rx * rx + ry * ry + rz * rz + eps)
            px = p[i, 0] - p[j, 0]
            py = p[i, 1] - p[j, 1]
            pz = (p[i, 2] - p[j, 2]) if dim == 3 else 0.0
            s = c * (px * rx + py * ry + pz * rz)
            lx += s * nf.g[k, 0]
            ly += s * nf.g[k, 1]
            if dim == 3:
                lz += s * nf.g[k, 2]
            tr += c * (rx * nf.g[k, 0] + ry * nf.g[k, 1] + (rz * nf.g[k, 2] if dim == 3 else 0.0))
        wx = 0.0
        wy = 0.0
        wz = 0.0
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            nu_b = B.noslip[b]
            if nu_b <= 0.0:
                continue
            rx = F_x[i, 0] - B.x[b, 0]
            ry = F_x[i, 1] - B.x[b, 1]
            rz = (x2 - B.x[b, 2]) if dim == 3 else 0.0
            c = scale * 2.0 * nu_b * B.psi[b] / rho0 / (rx * rx + ry * ry + rz * rz + eps)
            s = c * (p[i, 0] * rx + p[i, 1] * ry + (p[i, 2] * rz if dim == 3 else 0.0))
            sb = c * (B.v[b, 0] * rx + B.v[b, 1] * ry + (B.v[b, 2] * rz if dim == 3 else 0.0))
            lx += s * nb.g[k, 0]
            ly += s * nb.g[k, 1]
            wx -= sb * nb.g[k, 0]
            wy -= sb * nb.g[k, 1]
            if dim == 3:
                lz += s * nb.g[k, 2]
                wz -= sb * nb.g[k, 2]
            tr += c * (rx * nb.g[k, 0] + ry * nb.g[k, 1] + (rz * nb.g[k, 2] if dim == 3 else 0.0))
        out[i, 0] = p[i, 0] - dt * lx
        out[i, 1] = p[i, 1] - dt * ly
        rhs_wall[i, 0] = dt * wx
        rhs_wall[i, 1] = dt * wy
        if dim == 3:
            out[i, 2] = p[i, 2] - dt * lz
            rhs_wall[i, 2] = dt * wz
        diag[i] = 1.0 - dt * tr / dim


@njit(cache=True, parallel=True)
def dot_rows(a, b, n, partial):
    """sum over rows < n and columns of a * b, in REDUCE_CHUNKS fixed chunks (same bits at any
    thread count); partial (REDUCE_CHUNKS, 2) scratch."""
    dim = a.shape[1]
    chunk = (n + REDUCE_CHUNKS - 1) // REDUCE_CHUNKS
    for c in prange(REDUCE_CHUNKS):
        s = 0.0
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            for d in range(dim):
                s += a[i, d] * b[i, d]
        partial[c, 0] = s
    s = 0.0
    for c in range(REDUCE_CHUNKS):
        s += partial[c, 0]
    return s


@njit(cache=True, parallel=True)
def cg_update(n, alpha, p, ap, x, r, diag, z):
    """x += alpha p; r -= alpha A p; z = r / diag."""
    dim = x.shape[1]
    for i in prange(n):
        for d in range(dim):
            x[i, d] += alpha * p[i, d]
            r[i, d] -= alpha * ap[i, d]
            z[i, d] = r[i, d] / diag[i]


@njit(cache=True, parallel=True)
def cg_direction(n, beta, z, p):
    """p = z + beta p."""
    dim = p.shape[1]
    for i in prange(n):
        for d in range(dim):
            p[i, d] = z[i, d] + beta * p[i, d]


_PARALLEL_KERNELS = _PARALLEL_KERNELS + ("viscosity_operator", "dot_rows", "cg_update", "cg_direction")


# --------------------------------------------------------------------------- extrapolated boundary pressure
# Adami, S., Hu, X. Y. & Adams, N. A. (2012), "A generalized wall boundary condition for smoothed particle
# hydrodynamics", J. Comput. Phys. 231: every boundary particle b carries the pressure extrapolated from
# the fluid around it, the Shepard average plus the body force's share along the wall normal n_b,
#     p_b = sum_f W_bf (p_f + rho_f (g . n_b) (n_b . (x_b - x_f))) / sum_f W_bf,   p_b >= 0,
# (Adami et al. use the full offset x_b - x_f; only its normal part is implied by the momentum balance at
# a wall, and the tangential part pushed the fluid up a vertical wall in the dam break), and the fluid's
# pressure acceleration takes it into the symmetric sum,
#     a_i = -sum_j m (k_i + k_j) g_ij - sum_b psi_b (k_i + k_b) g_ib,  k_b = p_b / rho0^2,
# so that the fluid row on a wall feels the pressure gradient of a row inside the fluid (Band, Gissler,
# Peer & Teschner 2018, "MLS pressure boundaries for divergence-free and viscous SPH fluids", C&G 76,
# extrapolate with a linear MLS fit instead: with the cubic spline at h = dx a boundary particle sees
# one row of fluid, the fit is degenerate or nearly so, and it ran away in the hydrostatic column).
# In the DFSPH solves the extrapolated p_b enters with the warm start (the previous step's total,
# ``boundary_extrapolated_pressure`` and ``boundary_pressure_kick``); the solver's increments kappa are
# mirrored, k_b = k_i (``apply_pressure`` with bfac = 2; the factor keeps Akinci's diagonal). Extrapolated
# increments (a Shepard average of the neighbours' kappa) are not in the Jacobi diagonal: in the film
# between a sinking body and the floor that iteration diverged. At rest the increments vanish and the
# walls carry the extrapolated pressure; the divergence solve (not warm-started) is mirrored throughout.


@njit(cache=True)
def boundary_transpose(nb, n, nbound, bt_start, bt_i, bt_w):
    """The boundary->fluid lists from the fluid->boundary CSR ``nb`` (serial, fixed order:
    deterministic): fluid neighbours of boundary particle b are bt_i[bt_start[b]:bt_start[b+1]]
    (ascending fluid index) with W_bf in bt_w. bt_start (nbound + 1,) int64."""
    for b in range(nbound + 1):
        bt_start[b] = 0
    for k in range(nb.start[0], nb.start[n]):
        bt_start[nb.j[k] + 1] += 1
    for b in range(nbound):
        bt_start[b + 1] += bt_start[b]
    for i in range(n):
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            q = bt_start[b]
            bt_i[q] = i
            bt_w[q] = nb.w[k]
            bt_start[b] = q + 1
    for b in range(nbound, 0, -1):  # the fill advanced every start to its end: shift back
        bt_start[b] = bt_start[b - 1]
    bt_start[0] = 0


@njit(cache=True, parallel=True)
def boundary_extrapolated_pressure(F, B, grid, nbound, bt_start, bt_i, bt_w, normal, k_fluid, rho0, gravity, kb):
    """kb_b = p_b / rho0^2 from the fluid's k (p_f = k_f rho_f^2): the Shepard average of
    p_f + rho_f (g . n_b)(n_b . (x_b - x_f)) over the fluid neighbours, clamped at 0 (see the
    section comment); 0 for boundary particles without fluid neighbours."""
    F_rho = F.rho
    F_x = F.x
    dim = F_x.shape[1]
    inv = 1.0 / (rho0 * rho0)
    for b in prange(nbound):
        gn = gravity[0] * normal[b, 0] + gravity[1] * normal[b, 1]
        if dim == 3:
            gn += gravity[2] * normal[b, 2]
        p = 0.0
        wsum = 0.0
        for q in range(bt_start[b], bt_start[b + 1]):
            f = bt_i[q]
            dn = normal[b, 0] * _min_image(B.x[b, 0] - F_x[f, 0], 0, grid)
            dn += normal[b, 1] * _min_image(B.x[b, 1] - F_x[f, 1], 1, grid)
            if dim == 3:
                dn += normal[b, 2] * _min_image(B.x[b, 2] - F_x[f, 2], 2, grid)
            p += bt_w[q] * (k_fluid[f] * F_rho[f] * F_rho[f] + F_rho[f] * gn * dn)
            wsum += bt_w[q]
        k = p / wsum * inv if wsum > 0.0 else 0.0
        kb[b] = k if k > 0.0 else 0.0


@njit(cache=True, inline="always")
def _kb_seen_by(kb_b, k_i, rho_i, gravity, normal, bx, fx, b, i, grid):
    # the extrapolated k_b as fluid particle i sees it: at most the mirror's k_i + the wall-normal
    # hydrostatic share (and >= 0). The Shepard average smears the pressure along a wall over a
    # support, so a wall beside the free surface carried the pressure of the rows below and pushed
    # the top particles up the wall (the coarse dam break's water clung 0.06 x 2a high at T = 3).
    lim = k_i + _wall_body_force_share(gravity, bx, fx, b, i, normal, grid) / rho_i
    if lim < 0.0:
        lim = 0.0
    return kb_b if kb_b < lim else lim


@njit(cache=True, parallel=True)
def boundary_pressure_kick(F, nb, B, grid, n, dt, kb, k_fluid, gravity, normal):
    """v_i -= dt sum_b psi_b k_ib g_ib: the boundary particles' own pressure share of the symmetric
    sum (the k_i share is in ``apply_pressure`` with bfac = 1), k_ib = min(kb_b, k_i + the
    wall-normal hydrostatic share) (``_kb_seen_by``; k_fluid the total kb was extrapolated from)."""
    F_v = F.v  # unpacked: Numba drops writes through a named tuple inside prange
    F_x = F.x
    F_rho = F.rho
    dim = F_x.shape[1]
    for i in prange(n):
        ax = 0.0
        ay = 0.0
        az = 0.0
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            s = B.psi[b] * _kb_seen_by(kb[b], k_fluid[i], F_rho[i], gravity, normal, B.x, F_x, b, i, grid)
            ax -= s * nb.g[k, 0]
            ay -= s * nb.g[k, 1]
            if dim == 3:
                az -= s * nb.g[k, 2]
        F_v[i, 0] += dt * ax
        F_v[i, 1] += dt * ay
        if dim == 3:
            F_v[i, 2] += dt * az


@njit(cache=True)
def body_boundary_pressure_wrench(F, nb, B, grid, n, mass, com, kb_dens, kb_div, k0_dens, k0_div, gravity, normal,
                                  force, torque):
    """Adds to force, torque (nbody, 3) the reaction of the boundary particles' own pressure on the
    bodies' particles in the "extrapolated" mode: f_b = m psi_b (k_ib + k_i - k0_i) g_ib, k_ib the
    extrapolated warm-start totals as i saw them (``boundary_pressure_kick``, from k0 of both
    solves; kb_div is 0 without the divergence warm start), k_i - k0_i the solves' mirrored
    increments (k_dens + k_div now minus at the start of the solves); torque (x_b - com) x f_b
    (serial, fixed order). The k_i share itself is in ``body_wrench`` (bfac = 1)."""
    dim = F.x.shape[1]
    for i in range(n):
        inc = F.k_dens[i] + F.k_div[i] - k0_dens[i] - k0_div[i]
        for k in range(nb.start[i], nb.start[i + 1]):
            b = nb.j[k]
            body = B.body[b]
            if body < 0:
                continue
            kib = _kb_seen_by(kb_dens[b], k0_dens[i], F.rho[i], gravity, normal, B.x, F.x, b, i, grid)
            if kb_div[b] > 0.0:
                kib += _kb_seen_by(kb_div[b], k0_div[i], F.rho[i], gravity, normal, B.x, F.x, b, i, grid)
            s = mass * B.psi[b] * (kib + inc)
            fx = s * nb.g[k, 0]
            fy = s * nb.g[k, 1]
            fz = s * nb.g[k, 2] if dim == 3 else 0.0
            px = B.x[b, 0] - com[body, 0]
            py = B.x[b, 1] - com[body, 1]
            pz = (B.x[b, 2] - com[body, 2]) if dim == 3 else 0.0
            force[body, 0] += fx
            force[body, 1] += fy
            force[body, 2] += fz
            torque[body, 0] += py * fz - pz * fy
            torque[body, 1] += pz * fx - px * fz
            torque[body, 2] += px * fy - py * fx


_PARALLEL_KERNELS = _PARALLEL_KERNELS + ("boundary_extrapolated_pressure", "boundary_pressure_kick")


@njit(cache=True)
def rotate_boundary_normals(nrest, body, body_rot, normal):
    """World normals of the boundary particles: body particles n = R n_local, static ones n_rest."""
    nb, dim = normal.shape
    for b in range(nb):
        k = body[b]
        for d in range(dim):
            if k < 0:
                normal[b, d] = nrest[b, d]
            else:
                s = 0.0
                for e in range(dim):
                    s += body_rot[k, d, e] * nrest[b, e]
                normal[b, d] = s


# --------------------------------------------------------------------------- hollow body cores
# The solids whose core push_out_of_cores keeps free, packed as the collision layer's distance kinds
# (``inertia.collision.distance``, layouts in its docstring) in the body frame: sphere, box, capsule,
# cylinder as the shape table's rows pack them (``collision.shapes.BodyShape``), a convex hull as the
# CONTAINER of its face planes (the hull's solid is the complement of that region: d_hull = -d).
CORE_KINDS = _dist.kinds_token((_dist.SPHERE, _dist.BOX, _dist.CAPSULE, _dist.CYLINDER, _dist.CONTAINER))


@njit(cache=True)
def push_out_of_cores(F, n, kinds, core_body, core_kind, core_off, core_ioff, core_cf, core_ci, body_x, body_rot,
                      body_v, body_w, depth, offset):
    """Fluid particles inside a body's solid deeper than ``depth`` (its boundary band is one kernel
    support thick; the core beyond it holds no boundary particles, and fluid that got through the
    band, e.g. squeezed between a sinking box and the floor, stayed there) are moved along the
    outward normal of the nearest surface point (the gradient of the signed distance d) to the
    signed distance ``offset`` (half a spacing, where the first fluid row sits): b += (offset - d) n
    in the body frame, and take the body's velocity there, v = v_body + w x (x - body_x). Core s
    belongs to body core_body[s]; its distance is ``collision.distance.sdf_in(kinds,
    core_kind[s], core_cf, core_off[s], core_ci, core_ioff[s], .)`` in the body frame (CONTAINER:
    a convex hull, sign flipped; see the section comment). Serial, no allocation (few particles
    move; the same bits at any thread count). Returns the number of particles moved."""
    dim = F.x.shape[1]
    moved = 0
    for i in range(n):
        for s in range(core_body.shape[0]):
            k = core_body[s]
            d0 = F.x[i, 0] - body_x[k, 0]
            d1 = F.x[i, 1] - body_x[k, 1]
            d2 = (F.x[i, 2] - body_x[k, 2]) if dim == 3 else 0.0
            # world -> body frame: b = R^T d
            b0 = body_rot[k, 0, 0] * d0 + body_rot[k, 1, 0] * d1 + body_rot[k, 2, 0] * d2
            b1 = body_rot[k, 0, 1] * d0 + body_rot[k, 1, 1] * d1 + body_rot[k, 2, 1] * d2
            b2 = body_rot[k, 0, 2] * d0 + body_rot[k, 1, 2] * d1 + body_rot[k, 2, 2] * d2
            kind = core_kind[s]
            d, g0, g1, g2 = _dist.sdf_in(kinds, kind, core_cf, core_off[s], core_ci, core_ioff[s], b0, b1, b2)
            if kind == _dist.CONTAINER:   # a convex hull: the complement of its planes' region
                d, g0, g1, g2 = -d, -g0, -g1, -g2
            if d >= -depth:
                continue
            if dim == 2 and g0 == 0.0 and g1 == 0.0:   # a disc's centre (its normal there is +z)
                g1 = 1.0
            # out along the normal to the distance offset (exact for the closed forms; the hull's
            # nearest face plane): b + (offset - d) n
            step = offset - d
            b0 += step * g0
            b1 += step * g1
            b2 = b2 + step * g2 if dim == 3 else b2
            # back to the world: x = body_x + R b, v = v_body + w x (x - body_x)
            r0 = body_rot[k, 0, 0] * b0 + body_rot[k, 0, 1] * b1 + body_rot[k, 0, 2] * b2
            r1 = body_rot[k, 1, 0] * b0 + body_rot[k, 1, 1] * b1 + body_rot[k, 1, 2] * b2
            r2 = body_rot[k, 2, 0] * b0 + body_rot[k, 2, 1] * b1 + body_rot[k, 2, 2] * b2
            F.x[i, 0] = body_x[k, 0] + r0
            F.x[i, 1] = body_x[k, 1] + r1
            wx, wy, wz = body_w[k, 0], body_w[k, 1], body_w[k, 2]
            F.v[i, 0] = body_v[k, 0] + wy * r2 - wz * r1
            F.v[i, 1] = body_v[k, 1] + wz * r0 - wx * r2
            if dim == 3:
                F.x[i, 2] = body_x[k, 2] + r2
                F.v[i, 2] = body_v[k, 2] + wx * r1 - wy * r0
            moved += 1
            break
    return moved
