"""Liquids with a free surface on a MAC grid: PIC/FLIP blend and APIC particles, 2-D and 3-D.

The liquid is carried by particles; the grid only solves for pressure. One step
(``LiquidFluid.step(dt)``) runs these stages (arrays named are written by the stage):

0. ``obstacles``  (when an obstacle or body moves) open face fractions and solid face velocities
   v + w x r from the colliders and the rigid shape rows (`obstacles.CutCells`, the cut cells
   of `GridFluid`; Batty, Bertails and Bridson 2007), cells whose centre lies in a solid.
1. ``p2g``        particles -> face velocities u, v, w and weights (multilinear "tent" kernel;
   APIC adds the particle's affine velocity C_p (x_face - x_p)). Serial scatter: deterministic.
2. ``surface``    liquid cells (cells holding a particle) and the level set ``phi`` at cell centres,
   phi = min_p |x_c - x_p| - r over particles within one cell (Zhu and Bridson 2005, without their
   smoothing), forced negative in liquid cells and positive in air cells; an empty cell centred
   in a solid with an open face to a liquid cell is liquid (`wet_solid_cells`).
3. ``forces``     u_old saved for FLIP; u += g dt on faces next to liquid.
4. ``project``    pressure on liquid cells, p = 0 at the free surface placed by the ghost-fluid
   method (Gibou, Fedkiw, Cheng and Kang 2002; Enright et al. 2003): a liquid-air face adds
   A_f / (h^2 theta) to the diagonal, theta = phi_liquid / (phi_liquid - phi_air), clamped to
   >= 0.01; faces between liquid cells couple with their open fraction A_f / h^2 and the
   divergence uses A_f u + (1 - A_f) u_solid (`build_face_weights`, `liquid_divergence`).
   Multigrid-preconditioned CG (McAdams, Sifakis and Teran 2010) to a relative residual
   ``tolerance`` (`liquid_pressure`; ``pressure_solver="jacobi"`` for comparison), warm-started
   from the last step's pressure rescaled to this dt (restarted from zero, the solve made the
   same residual error every step and the particles summed it: still water drifted to 4e-8 m/s
   in 4 s; warm-started it stays below 1e-9 m/s), with the
   dynamic bodies' velocities as unknowns of the same solve (Batty et al. 2007): their pressure
   impulses go through `inertia.dynamics.particle_coupling.apply_body_impulses`. Domain sides
   are walls or inflows (closed faces, which take the solid's or the inflow's normal velocity),
   outflows (open: p = 0 in the ghost cell beyond, weight A_f) or periodic (the first and last
   face layer are one face joining the last and the first cell; the transfers, the level set,
   the particle density and the particle positions wrap around).
4a. ``volume``    (volume_correction > 0, Kugelstadt, Longva, Thuerey and Bender 2019 on the grid)
   the particles per cell rho from the tent weights at the cell centres (mirrored at walls), s =
   beta (rho / rho_0 - 1) with rho_0 = particles_per_cell, kept where positive and, inside the
   liquid (`_inner_cell`), also where negative; -Lap q = s with the same operator (q = 0 at
   the free surface) and the displacement d = -grad q (extrapolated like the velocity), which
   the particles follow after their advection: div d = s spreads over-full cells. Velocities
   are not changed. Skipped when no cell deviates.
4b. ``viscosity`` (viscosity > 0) backward Euler (I - nu dt Lap) u = u per component on the faces
   next to liquid, CG (`viscosity.py`, shared with `GridFluid`): zero viscous stress across the
   free surface (separate-component form of the traction-free condition, Batty and Bridson 2008
   simplified: see `viscosity`), slip or no-slip domain walls (``walls``), no-slip obstacles and
   shape rows as Dirichlet data at the cut point (ghost fluid, Gibou et al. 2002) whose link
   momenta are the viscous force on each (`obstacle_viscous_force`; an impulse on bodies), slip
   obstacles only their normal velocity. After the pressure solve, so a liquid at rest keeps its
   hydrostatic pressure exactly.
5. ``extrapolate`` face velocities into the air, ``extrapolation_layers`` cells deep (average of
   valid neighbours, layer by layer).
6. ``g2p``        grid -> particles: PIC v_p = I(u); FLIP v_p += I(u - u_old); blend
   v = (1 - flip_ratio) PIC + flip_ratio FLIP; APIC v_p = I(u) and C_p = sum_i grad(w_ip) u_i
   (Jiang et al. 2015, multilinear weights).
7. ``advect``     particles move by RK2 (midpoint) in the grid velocity (and then in d), clamped
   inside the domain ``margin`` from closed sides; particles beyond an open side are removed
   (``drain``), inflow sides emit rows of particles (``emit``: a row on the h/2 lattice each time
   the liquid has entered h/2, at the inflow velocity); then particles are pushed out of solids
   along the solid's normal to 0.1 h, losing their velocity into the solid (relative to its
   surface velocity).
8. ``reseed``     (reseed=True) an empty cell inside the liquid (it reads under rho_0 / 2, its
   neighbours 3/4 rho_0 or more) gets one particle per h/2 sub-cell at the grid velocity; a cell
   holding more than 3 particles_per_cell loses the rest (serial: deterministic).

``advance(frame_dt)`` takes CFL substeps dt = cfl h / max|v_p| (capped by ``max_dt``).

References
----------
- F. H. Harlow, "The particle-in-cell computing method for fluid dynamics", Methods Comput.
  Phys. 3, 1964 (PIC).
- J. U. Brackbill and H. M. Ruppel, "FLIP: a method for adaptively zoned, particle-in-cell
  calculations of fluid flows in two dimensions", J. Comput. Phys. 65, 1986 (FLIP).
- Y. Zhu and R. Bridson, "Animating sand as a fluid", SIGGRAPH 2005 (PIC/FLIP blend for
  graphics, particle level set).
- C. Jiang, C. Schroeder, A. Selle, J. Teran and A. Stomakhin, "The affine particle-in-cell
  method", SIGGRAPH 2015 (APIC).
- F. Gibou, R. Fedkiw, L.-T. Cheng and M. Kang, "A second-order-accurate symmetric
  discretization of the Poisson equation on irregular domains", J. Comput. Phys. 176, 2002
  (ghost-fluid free-surface pressure).
- C. Batty, F. Bertails and R. Bridson, "A fast variational framework for accurate solid-fluid
  coupling", SIGGRAPH 2007 (face-fraction weights, rigid bodies in the pressure solve).
- C. Batty and R. Bridson, "Accurate viscous free surfaces for buckling, coiling, and rotating
  liquids", SCA 2008 (the traction-free surface; used in its separate-component simplification).
- A. McAdams, E. Sifakis and J. Teran, "A parallel multigrid Poisson solver for fluids
  simulation on large grids", SCA 2010 (MGPCG).
- T. Kugelstadt, A. Longva, N. Thuerey and J. Bender, "Implicit density projection for volume
  conserving liquids", IEEE TVCG 27, 2019 (the volume stage: a position correction from a
  Poisson solve on the density deviation).

Limitations
-----------
- Domain sides: slip or no-slip walls, inflow (a whole side at one velocity), outflow and
  periodic (not with viscosity; the velocity extrapolation into the air does not wrap around).
  Constant density, no surface tension.
- Volume stage: the density is read with the tent weights, so a cell next to a solid or at the
  free surface reads less than it holds and only gives volume back; bodies do not feel the
  correction (it moves particles only). Reseeding adds a cell of volume per hole it fills (off
  by default). A step allocates when particles are emitted, drained, reseeded or removed.
- Still water on the particle lattice stays at rest to 1e-9 m/s over 4 s (60 Hz steps); a
  grid-scale surface mode seeded by the solver's residual grows slowly beyond that (measured
  2.6e-9 m/s after 10 s at h = 1/32).
- Viscosity: applied after the pressure solve, so the velocity handed to the particles is not
  exactly divergence-free (the next step's projection removes the rest; first order in dt).
  The free surface is traction-free only in the separate-component sense (rotating or coiling
  viscous liquids are damped wrongly; Batty and Bridson 2008 give the full stress form). The
  viscous force on bodies is explicit (added after the implicit pressure coupling). FLIP damps
  a shear mode about 3 % slower than the grid (its transfers at k h = 0.39), APIC within 0.6 %.
- Bodies: the pressure reaches a body through its closed faces, i.e. at the centre of the fluid
  cell next to them: along an axis the body's surface is placed to within h/2 (exact for
  surfaces through cell centres; a floating body's equilibrium draft is within +-h/2). 2-D: the
  bodies' z = 0 cross-sections in a slab ``depth`` thick; they should move in the x-y plane.
  The world advances the liquid before its rigid stage (``advance_before_rigid``): the liquid
  sees the bodies at their start-of-step poses with gravity's g dt added to their velocities
  (removed again after the step; the rigid stage adds it), its impulses change the velocities,
  and the rigid stage then integrates the positions (symplectic Euler). The bodies' cut cells
  are rebuilt once per substep at the start-of-step pose. Called outside a world, `advance`
  expects the caller's rigid step to follow it (it leaves gravity to the rigid world).
- Momentum between liquid and bodies is exchanged on the grid (face masses rho h^d); at a
  struck free surface the particles carry less than that (measured: 5.7 % of the momentum lost
  in a body's impact step, tests/fluids/grid/test_liquid_coupling.py).
- The level set is a union of particle spheres (radius ``surface_radius``): the surface is as
  bumpy as the particles; fine for rendering through marching cubes, first-order in h.
- Particles that the flow leaves in thin sheets can drift apart; reseeding fills only holes
  enclosed by liquid, not sheets.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..._jit import parallel_kernel
from ..._validate import as_vector, positive_scalar
from ...errors import SimulationDiverged, check_substep_runaway
from . import kernels as K
from . import viscosity as V
from .boundaries import Inflow, Outflow, Periodic, Wall, parse_boundaries, side_velocity
from .liquid_pressure import BodyCoupling, LiquidPressure, set_body_face_velocities
from .obstacles import low_cell

METHODS = ("apic", "flip", "pic")
WALLS = ("slip", "no-slip")
SIDES = ("x-", "x+", "y-", "y+", "z-", "z+")
OVERFULL = 3    # reseeding removes the particles of a cell beyond OVERFULL x particles_per_cell
# relative residual of the volume stage's solve: a position correction of a few percent of a cell
# per step needs no more (the pressure solve keeps ``tolerance``)
VOLUME_TOLERANCE = 1e-3


def parse_walls(walls, dim):
    """(3, 2) bool, True where a domain side is a no-slip wall, from "slip", "no-slip" or a dict
    side -> "slip" / "no-slip" (sides not named are slip)."""
    out = np.zeros((3, 2), dtype=np.bool_)
    sides = SIDES[:2 * dim]
    if isinstance(walls, str):
        if walls not in WALLS:
            raise ValueError(f"walls must be one of {WALLS} or a dict side -> one of them; got {walls!r}")
        out[:dim] = walls == "no-slip"
        return out
    if not isinstance(walls, dict):
        raise ValueError(f"walls must be one of {WALLS} or a dict side -> one of them; got {walls!r}")
    for side, kind in walls.items():
        if side not in sides:
            raise ValueError(f"walls: unknown side {side!r}; the sides are {sides}")
        if kind not in WALLS:
            raise ValueError(f"walls[{side!r}] must be one of {WALLS}; got {kind!r}")
        out[sides.index(side) // 2, sides.index(side) % 2] = kind == "no-slip"
    return out


# ----------------------------------------------------------------------------- kernels
@njit(cache=True)
def _tent(x, n_nodes):
    """Node index i0 (clamped to [0, n_nodes - 2]) and weight of node i0 + 1 for coordinate x
    (in node units); weight of i0 is 1 - f."""
    i0 = int(math.floor(x))
    if i0 < 0:
        return 0, 0.0
    if i0 > n_nodes - 2:
        return n_nodes - 2, 1.0
    return i0, x - i0


@njit(cache=True)
def particles_to_grid(x, v, c, affine, origin, h, dim, vel, wsum, per):
    """Scatter particle velocities to the faces of each component a (serial: deterministic).
    x, v (N, 3) (z = 0 in 2-D); c (N, 3, 3) APIC matrices (row a: gradient of component a);
    vel[a], wsum[a] face arrays. Writes vel = sum w (v + C (x_f - x_p)) / sum w (0 where no
    particle reaches). Along a periodic axis (per) node indices wrap and the last face layer is a
    copy of the first."""
    for a in range(dim):
        vel[a][...] = 0.0
        wsum[a][...] = 0.0
    n = x.shape[0]
    for a in range(dim):
        va = vel[a]
        wa = wsum[a]
        sx, sy, sz = va.shape
        ox = 0.0 if a == 0 else 0.5
        oy = 0.0 if a == 1 else 0.5
        oz = 0.0 if a == 2 else 0.5
        # periods of the wrapped axes (the face-normal axis has one node more than its period)
        px = sx - 1 if a == 0 else sx
        py = sy - 1 if a == 1 else sy
        pz = sz - 1 if a == 2 else sz
        for p in range(n):
            X = (x[p, 0] - origin[0]) / h - ox
            Y = (x[p, 1] - origin[1]) / h - oy
            i0 = int(math.floor(X))
            j0 = int(math.floor(Y))
            fx = X - i0
            fy = Y - j0
            if dim == 2:
                for dj in range(2):
                    jj = j0 + dj
                    jw = jj % py if per[1] else jj
                    if jw < 0 or jw >= sy:
                        continue
                    wy = fy if dj else 1.0 - fy
                    for di in range(2):
                        ii = i0 + di
                        iw = ii % px if per[0] else ii
                        if iw < 0 or iw >= sx:
                            continue
                        w = (fx if di else 1.0 - fx) * wy
                        val = v[p, a]
                        if affine:
                            dxf = (ii + ox) * h + origin[0] - x[p, 0]
                            dyf = (jj + oy) * h + origin[1] - x[p, 1]
                            val += c[p, a, 0] * dxf + c[p, a, 1] * dyf
                        va[iw, jw, 0] += w * val
                        wa[iw, jw, 0] += w
            else:
                Z = (x[p, 2] - origin[2]) / h - oz
                k0 = int(math.floor(Z))
                fz = Z - k0
                for dk in range(2):
                    kk = k0 + dk
                    kw = kk % pz if per[2] else kk
                    if kw < 0 or kw >= sz:
                        continue
                    wz = fz if dk else 1.0 - fz
                    for dj in range(2):
                        jj = j0 + dj
                        jw = jj % py if per[1] else jj
                        if jw < 0 or jw >= sy:
                            continue
                        wy = (fy if dj else 1.0 - fy) * wz
                        for di in range(2):
                            ii = i0 + di
                            iw = ii % px if per[0] else ii
                            if iw < 0 or iw >= sx:
                                continue
                            w = (fx if di else 1.0 - fx) * wy
                            val = v[p, a]
                            if affine:
                                dxf = (ii + ox) * h + origin[0] - x[p, 0]
                                dyf = (jj + oy) * h + origin[1] - x[p, 1]
                                dzf = (kk + oz) * h + origin[2] - x[p, 2]
                                val += c[p, a, 0] * dxf + c[p, a, 1] * dyf + c[p, a, 2] * dzf
                            va[iw, jw, kw] += w * val
                            wa[iw, jw, kw] += w
        for i in range(sx):
            for j in range(sy):
                for k in range(sz):
                    if wa[i, j, k] > 0.0:
                        va[i, j, k] /= wa[i, j, k]
        if per[a]:
            _copy_first_layer(va, a)
            _copy_first_layer(wa, a)


@njit(cache=True)
def build_surface(x, origin, h, radius, dim, liquid, phi, per):
    """Liquid cells (holding a particle) and the particle level set at cell centres (serial;
    neighbours wrap along periodic axes per)."""
    nx, ny, nz = phi.shape
    phi[...] = 3.0 * h
    liquid[...] = False
    for p in range(x.shape[0]):
        X = (x[p, 0] - origin[0]) / h
        Y = (x[p, 1] - origin[1]) / h
        Z = (x[p, 2] - origin[2]) / h if dim == 3 else 0.5
        ci = min(max(int(math.floor(X)), 0), nx - 1)
        cj = min(max(int(math.floor(Y)), 0), ny - 1)
        ck = min(max(int(math.floor(Z)), 0), nz - 1)
        liquid[ci, cj, ck] = True
        k_lo = ck - 1 if dim == 3 else 0
        k_hi = ck + 1 if dim == 3 else 0
        for i in range(ci - 1, ci + 2):
            iw = i % nx if per[0] else i
            if iw < 0 or iw >= nx:
                continue
            for j in range(cj - 1, cj + 2):
                jw = j % ny if per[1] else j
                if jw < 0 or jw >= ny:
                    continue
                for k in range(k_lo, k_hi + 1):
                    kw = k % nz if per[2] else k
                    if kw < 0 or kw >= nz:
                        continue
                    dx = (i + 0.5) * h + origin[0] - x[p, 0]
                    dy = (j + 0.5) * h + origin[1] - x[p, 1]
                    d2 = dx * dx + dy * dy
                    if dim == 3:
                        dz = (k + 0.5) * h + origin[2] - x[p, 2]
                        d2 += dz * dz
                    d = math.sqrt(d2) - radius
                    if d < phi[iw, jw, kw]:
                        phi[iw, jw, kw] = d
    eps = 1e-3 * h
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if liquid[i, j, k]:
                    if phi[i, j, k] > -eps:
                        phi[i, j, k] = -eps
                elif phi[i, j, k] < eps:
                    phi[i, j, k] = eps


@njit(cache=True)
def wet_solid_cells(liquid, phi, cell_solid, frac, dim, h, scratch):
    """An empty cell whose centre lies inside a solid but which an open face (A_f > 0) joins to a
    liquid cell becomes liquid: the sliver of fluid between the solid and the liquid, which the
    particles (kept 0.1 h outside solids) need not reach. Without it the pressure under a body
    whose surface lies just above a face would not reach the body's closed faces."""
    nx, ny, nz = liquid.shape
    scratch[...] = liquid
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if liquid[i, j, k] or not cell_solid[i, j, k]:
                    continue
                wet = False
                if i > 0 and frac[0][i, j, k] > 0.0 and liquid[i - 1, j, k]:
                    wet = True
                if i < nx - 1 and frac[0][i + 1, j, k] > 0.0 and liquid[i + 1, j, k]:
                    wet = True
                if j > 0 and frac[1][i, j, k] > 0.0 and liquid[i, j - 1, k]:
                    wet = True
                if j < ny - 1 and frac[1][i, j + 1, k] > 0.0 and liquid[i, j + 1, k]:
                    wet = True
                if dim == 3:
                    if k > 0 and frac[2][i, j, k] > 0.0 and liquid[i, j, k - 1]:
                        wet = True
                    if k < nz - 1 and frac[2][i, j, k + 1] > 0.0 and liquid[i, j, k + 1]:
                        wet = True
                if wet:
                    scratch[i, j, k] = True
                    phi[i, j, k] = -1e-3 * h
    liquid[...] = scratch


@njit(cache=True, inline="always")
def _wrap_cell(a, i, j, k, n):
    """Cell (i, j, k) with its index along axis a wrapped into [0, n)."""
    if a == 0:
        return i % n, j, k
    if a == 1:
        return i, j % n, k
    return i, j, k % n


@njit(cache=True, inline="always")
def _copy_first_layer(arr, a):
    """The last layer of face array arr along axis a = its first (the same faces, periodic)."""
    sx, sy, sz = arr.shape
    for i in range(sx if a != 0 else 1):
        for j in range(sy if a != 1 else 1):
            for k in range(sz if a != 2 else 1):
                if a == 0:
                    arr[sx - 1, j, k] = arr[0, j, k]
                elif a == 1:
                    arr[i, sy - 1, k] = arr[i, 0, k]
                else:
                    arr[i, j, sz - 1] = arr[i, j, 0]


@njit(cache=True, inline="always")
def _pair_weight(liquid, phi, cell_solid, A, i0, j0, k0, i1, j1, k1):
    """Pressure weight of an open face between cells 0 (low) and 1 (high): A between two liquid
    cells, A / theta (ghost fluid, theta >= 0.01) between a liquid and an air cell, else 0."""
    lo = liquid[i0, j0, k0]
    hi = liquid[i1, j1, k1]
    if lo and hi:
        return A
    if lo and not cell_solid[i1, j1, k1]:
        return A / max(phi[i0, j0, k0] / (phi[i0, j0, k0] - phi[i1, j1, k1]), 0.01)
    if hi and not cell_solid[i0, j0, k0]:
        return A / max(phi[i1, j1, k1] / (phi[i1, j1, k1] - phi[i0, j0, k0]), 0.01)
    return 0.0


@njit(cache=True, inline="always")
def _pair_dp(p, phi, lo, hi, i0, j0, k0, i1, j1, k1):
    """p_high - p_low across a face, with the ghost-fluid value p = 0 at the surface."""
    if lo and hi:
        return p[i1, j1, k1] - p[i0, j0, k0]
    if lo:
        return -p[i0, j0, k0] / max(phi[i0, j0, k0] / (phi[i0, j0, k0] - phi[i1, j1, k1]), 0.01)
    return p[i1, j1, k1] / max(phi[i1, j1, k1] / (phi[i1, j1, k1] - phi[i0, j0, k0]), 0.01)


@njit(cache=True)
def add_gravity_and_walls(vel, liquid, g, dt, dim, closed, side_vel, per):
    """u += g dt on faces next to a liquid cell; faces on a closed domain side (closed[a, side]:
    a wall or an inflow) get the side's normal velocity side_vel[a, side] (0 on walls); faces on
    an open side count as interior faces of their one cell."""
    nx, ny, nz = liquid.shape
    for a in range(dim):
        va = vel[a]
        sx, sy, sz = va.shape
        n = nx if a == 0 else (ny if a == 1 else nz)
        for i in range(sx):
            for j in range(sy):
                for k in range(sz):
                    c = i if a == 0 else (j if a == 1 else k)
                    side = 0 if c == 0 else (1 if c == n else -1)
                    if side >= 0 and closed[a, side]:
                        va[i, j, k] = side_vel[a, side]
                        continue
                    i1, j1, k1 = low_cell(a, i, j, k)
                    if side >= 0 and per[a]:   # the face joining cell n - 1 and cell 0
                        lo_i, lo_j, lo_k = _wrap_cell(a, i1, j1, k1, n)
                        hi_i, hi_j, hi_k = _wrap_cell(a, i, j, k, n)
                        if liquid[lo_i, lo_j, lo_k] or liquid[hi_i, hi_j, hi_k]:
                            va[i, j, k] += g[a] * dt
                        continue
                    wet = False
                    if side != 1 and liquid[i, j, k]:
                        wet = True
                    if side != 0 and liquid[i1, j1, k1]:
                        wet = True
                    if wet:
                        va[i, j, k] += g[a] * dt


@njit(cache=True)
def build_face_weights(liquid, phi, frac, cell_solid, dim, weights, per):
    """Pressure weights of the faces (Batty, Bertails and Bridson 2007 with the ghost-fluid free
    surface): A_f between two liquid cells; A_f / theta between a liquid cell and an air cell,
    theta = phi_liquid / (phi_liquid - phi_air) >= 0.01 (Gibou et al. 2002); A_f on an open domain
    side (outflow: p = 0 in the ghost cell beyond it; closed sides have A_f = 0); 0 on every other
    face (closed solid faces, air-air, and a liquid cell next to an empty cell whose centre lies
    inside a solid: no flux through the solid, so no Dirichlet condition there). Returns whether
    any liquid-air face exists (else the system is a pure Neumann problem)."""
    nx, ny, nz = liquid.shape
    surface = False
    for a in range(3):
        weights[a][...] = 0.0
    for a in range(dim):
        wa = weights[a]
        fa = frac[a]
        sx, sy, sz = wa.shape
        for i in range(sx):
            for j in range(sy):
                for k in range(sz):
                    A = fa[i, j, k]
                    if A <= 0.0:
                        continue
                    i0, j0, k0 = low_cell(a, i, j, k)
                    n = nx if a == 0 else (ny if a == 1 else nz)
                    c = i if a == 0 else (j if a == 1 else k)
                    if per[a] and (c == 0 or c == n):
                        i0, j0, k0 = _wrap_cell(a, i0, j0, k0, n)
                        ih, jh, kh = _wrap_cell(a, i, j, k, n)
                        wa[i, j, k] = _pair_weight(liquid, phi, cell_solid, A, i0, j0, k0,
                                                   ih, jh, kh)
                        if wa[i, j, k] > 0.0 and not (liquid[i0, j0, k0] and liquid[ih, jh, kh]):
                            surface = True
                        continue
                    if i0 < 0 or j0 < 0 or k0 < 0:
                        # an open low side (closed walls have A = 0): p = 0 in the ghost cell
                        if liquid[i, j, k]:
                            wa[i, j, k] = A
                            surface = True
                        continue
                    if i >= nx or j >= ny or k >= nz:
                        if liquid[i0, j0, k0]:
                            wa[i, j, k] = A
                            surface = True
                        continue
                    lo = liquid[i0, j0, k0]
                    hi = liquid[i, j, k]
                    if lo and hi:
                        wa[i, j, k] = A
                    elif lo and not cell_solid[i, j, k]:
                        theta = phi[i0, j0, k0] / (phi[i0, j0, k0] - phi[i, j, k])
                        wa[i, j, k] = A / max(theta, 0.01)
                        surface = True
                    elif hi and not cell_solid[i0, j0, k0]:
                        theta = phi[i, j, k] / (phi[i, j, k] - phi[i0, j0, k0])
                        wa[i, j, k] = A / max(theta, 0.01)
                        surface = True
    return surface


@njit(cache=True)
def liquid_divergence(vel, frac, solid, liquid, h, dim, rhs):
    """rhs = -div(u) on liquid cells (0 elsewhere), with the flux of each face weighted by its
    open fraction: A_f u_f + (1 - A_f) u_solid,f (Batty et al. 2007), 1/s."""
    nx, ny, nz = liquid.shape
    inv_h = 1.0 / h
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if not liquid[i, j, k]:
                    rhs[i, j, k] = 0.0
                    continue
                dv = 0.0
                for a in range(dim):
                    va = vel[a]
                    fa = frac[a]
                    sa = solid[a]
                    i1, j1, k1 = i, j, k
                    if a == 0:
                        i1 = i + 1
                    elif a == 1:
                        j1 = j + 1
                    else:
                        k1 = k + 1
                    A1 = fa[i1, j1, k1]
                    A0 = fa[i, j, k]
                    dv += A1 * va[i1, j1, k1] + (1.0 - A1) * sa[i1, j1, k1]
                    dv -= A0 * va[i, j, k] + (1.0 - A0) * sa[i, j, k]
                rhs[i, j, k] = -dv * inv_h


@njit(cache=True)
def subtract_pressure_gradient(vel, p, liquid, phi, weights, frac, solid, h, dim, valid, per):
    """u -= grad p on faces with a pressure weight (ghost-fluid value across the surface);
    closed faces (open fraction 0: domain walls, solids) take the solid's velocity; open faces
    next to a liquid cell without a weight (beside an empty solid cell) keep their velocity.
    valid[a] marks all of these; other faces are left for extrapolation."""
    nx, ny, nz = liquid.shape
    inv_h = 1.0 / h
    for a in range(dim):
        va = vel[a]
        ok = valid[a]
        wa = weights[a]
        fa = frac[a]
        sa = solid[a]
        sx, sy, sz = va.shape
        for i in range(sx):
            for j in range(sy):
                for k in range(sz):
                    ok[i, j, k] = False
                    if fa[i, j, k] <= 0.0:
                        va[i, j, k] = sa[i, j, k]
                        ok[i, j, k] = True
                        continue
                    i0, j0, k0 = low_cell(a, i, j, k)
                    n = nx if a == 0 else (ny if a == 1 else nz)
                    c = i if a == 0 else (j if a == 1 else k)
                    if per[a] and (c == 0 or c == n):
                        i0, j0, k0 = _wrap_cell(a, i0, j0, k0, n)
                        ih, jh, kh = _wrap_cell(a, i, j, k, n)
                        lo = liquid[i0, j0, k0]
                        hi = liquid[ih, jh, kh]
                        if lo or hi:
                            ok[i, j, k] = True
                            if wa[i, j, k] != 0.0:
                                va[i, j, k] -= _pair_dp(p, phi, lo, hi, i0, j0, k0, ih, jh, kh) * inv_h
                        continue
                    if i0 < 0 or j0 < 0 or k0 < 0:
                        # an open low side: p = 0 in the ghost cell
                        if liquid[i, j, k]:
                            ok[i, j, k] = True
                            if wa[i, j, k] != 0.0:
                                va[i, j, k] -= p[i, j, k] * inv_h
                        continue
                    if i >= nx or j >= ny or k >= nz:
                        if liquid[i0, j0, k0]:
                            ok[i, j, k] = True
                            if wa[i, j, k] != 0.0:
                                va[i, j, k] += p[i0, j0, k0] * inv_h
                        continue
                    lo = liquid[i0, j0, k0]
                    hi = liquid[i, j, k]
                    if not (lo or hi):
                        continue
                    ok[i, j, k] = True
                    if wa[i, j, k] == 0.0:
                        continue
                    if lo and hi:
                        dp = p[i, j, k] - p[i0, j0, k0]
                    elif lo:
                        theta = max(phi[i0, j0, k0] / (phi[i0, j0, k0] - phi[i, j, k]), 0.01)
                        dp = -p[i0, j0, k0] / theta
                    else:
                        theta = max(phi[i, j, k] / (phi[i, j, k] - phi[i0, j0, k0]), 0.01)
                        dp = p[i, j, k] / theta
                    va[i, j, k] -= dp * inv_h


@njit(cache=True)
def push_out_of_solids(x, v, d, nrm, vs, idx, dim, clearance):
    """Particles idx[m] with signed distance d[m] < clearance to a solid move out along the
    solid's normal nrm[m] to the clearance, and lose the velocity component into the solid
    relative to its surface velocity vs[m] (no penetration; tangential motion kept)."""
    for m in range(idx.shape[0]):
        p = idx[m]
        push = clearance - d[m]
        vn = 0.0
        for a in range(dim):
            x[p, a] += push * nrm[m, a]
            vn += (v[p, a] - vs[m, a]) * nrm[m, a]
        if vn < 0.0:
            for a in range(dim):
                v[p, a] -= vn * nrm[m, a]


@njit(cache=True)
def extrapolate(vel, valid, scratch_valid, dim, layers):
    """Extend face velocities into invalid faces, one layer per pass: a face next to valid
    faces (same component, along the axes) takes their average."""
    for a in range(dim):
        va = vel[a]
        ok = valid[a]
        nk = scratch_valid[a]
        sx, sy, sz = va.shape
        for _ in range(layers):
            nk[...] = ok
            changed = False
            for i in range(sx):
                for j in range(sy):
                    for k in range(sz):
                        if ok[i, j, k]:
                            continue
                        s = 0.0
                        cnt = 0
                        for ax in range(dim):
                            for sd in range(2):
                                ii, jj, kk = i, j, k
                                if ax == 0:
                                    ii += 2 * sd - 1
                                elif ax == 1:
                                    jj += 2 * sd - 1
                                else:
                                    kk += 2 * sd - 1
                                if ii < 0 or ii >= sx or jj < 0 or jj >= sy or kk < 0 or kk >= sz:
                                    continue
                                if ok[ii, jj, kk]:
                                    s += va[ii, jj, kk]
                                    cnt += 1
                        if cnt:
                            va[i, j, k] = s / cnt
                            nk[i, j, k] = True
                            changed = True
            ok[...] = nk
            if not changed:
                break
        # faces still invalid: zero
        for i in range(sx):
            for j in range(sy):
                for k in range(sz):
                    if not ok[i, j, k]:
                        va[i, j, k] = 0.0


@njit(cache=True, inline="always")
def _nodes(x, n_nodes, periodic):
    """The two nodes around index-space coordinate x on an axis of n_nodes nodes, the weight of
    the second and whether x lies within the outer nodes: clamped (`_tent`), or wrapped on a
    periodic axis (its period is n_nodes cells for cell-centred samples; for the face-normal
    component the last face is the first one again, so the caller passes n_nodes - 1)."""
    if periodic:
        i = int(math.floor(x))
        return i % n_nodes, (i + 1) % n_nodes, x - i, 1.0
    i0, f = _tent(x, n_nodes)
    return i0, i0 + 1, f, (1.0 if 0.0 <= x <= n_nodes - 1 else 0.0)


@njit(cache=True)
def _interp_face(va, a, X, Y, Z, dim, per):
    """Multilinear interpolation of face component a at index-space point (X, Y, Z) (clamped
    to the face array: constant beyond the outer nodes; wrapped along periodic axes per[axis]),
    with the weight gradient (per unit index) for APIC: zero along an axis where the point lies
    beyond the outer nodes, so that an APIC particle there carries the constant it was given (a
    gradient taken from the inner segment would bias the wall nodes in the next transfer)."""
    sx, sy, sz = va.shape
    x = X - (0.0 if a == 0 else 0.5)
    y = Y - (0.0 if a == 1 else 0.5)
    i0, i1, fx, inx = _nodes(x, sx - 1 if (a == 0 and per[0]) else sx, per[0])
    j0, j1, fy, iny = _nodes(y, sy - 1 if (a == 1 and per[1]) else sy, per[1])
    if dim == 2:
        c00 = va[i0, j0, 0]
        c10 = va[i1, j0, 0]
        c01 = va[i0, j1, 0]
        c11 = va[i1, j1, 0]
        val = (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11)
        gx = inx * ((1 - fy) * (c10 - c00) + fy * (c11 - c01))
        gy = iny * ((1 - fx) * (c01 - c00) + fx * (c11 - c10))
        return val, gx, gy, 0.0
    z = Z - (0.0 if a == 2 else 0.5)
    k0, k1, fz, inz = _nodes(z, sz - 1 if (a == 2 and per[2]) else sz, per[2])
    val = 0.0
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for dk in range(2):
        wz = fz if dk else 1.0 - fz
        sgz = 1.0 if dk else -1.0
        kk = k1 if dk else k0
        for dj in range(2):
            wy = fy if dj else 1.0 - fy
            sgy = 1.0 if dj else -1.0
            jj = j1 if dj else j0
            for di in range(2):
                wx = fx if di else 1.0 - fx
                sgx = 1.0 if di else -1.0
                cval = va[i1 if di else i0, jj, kk]
                val += wx * wy * wz * cval
                gx += sgx * wy * wz * cval
                gy += wx * sgy * wz * cval
                gz += wx * wy * sgz * cval
    return val, inx * gx, iny * gy, inz * gz


@parallel_kernel
def grid_to_particles(x, v, c, vel, vel_old, origin, h, dim, method, flip_ratio, per):
    """Gather grid velocities to particles (method 0 APIC, 1 FLIP blend, 2 PIC); for FLIP
    vel_old holds the grid's velocity change of the step."""
    n = x.shape[0]
    inv_h = 1.0 / h
    for p in prange(n):
        X = (x[p, 0] - origin[0]) * inv_h
        Y = (x[p, 1] - origin[1]) * inv_h
        Z = (x[p, 2] - origin[2]) * inv_h if dim == 3 else 0.5
        for a in range(dim):
            val, gx, gy, gz = _interp_face(vel[a], a, X, Y, Z, dim, per)
            if method == 1:
                delta, _, _, _ = _interp_face(vel_old[a], a, X, Y, Z, dim, per)
                v[p, a] = (1.0 - flip_ratio) * val + flip_ratio * (v[p, a] + delta)
            else:
                v[p, a] = val
            if method == 0:
                c[p, a, 0] = gx * inv_h
                c[p, a, 1] = gy * inv_h
                c[p, a, 2] = gz * inv_h


@parallel_kernel
def advect_particles(x, vel, origin, h, dim, dt, lo, hi, per, length):
    """RK2 (midpoint) particle motion through the grid velocity; clamped into [lo, hi], wrapped
    into [origin, origin + length) along periodic axes (per)."""
    n = x.shape[0]
    inv_h = 1.0 / h
    for p in prange(n):
        X = (x[p, 0] - origin[0]) * inv_h
        Y = (x[p, 1] - origin[1]) * inv_h
        Z = (x[p, 2] - origin[2]) * inv_h if dim == 3 else 0.5
        vx, _, _, _ = _interp_face(vel[0], 0, X, Y, Z, dim, per)
        vy, _, _, _ = _interp_face(vel[1], 1, X, Y, Z, dim, per)
        vz = 0.0
        if dim == 3:
            vz, _, _, _ = _interp_face(vel[2], 2, X, Y, Z, dim, per)
        Xm = X + 0.5 * dt * vx * inv_h
        Ym = Y + 0.5 * dt * vy * inv_h
        Zm = Z + 0.5 * dt * vz * inv_h if dim == 3 else Z
        vx, _, _, _ = _interp_face(vel[0], 0, Xm, Ym, Zm, dim, per)
        vy, _, _, _ = _interp_face(vel[1], 1, Xm, Ym, Zm, dim, per)
        if dim == 3:
            vz, _, _, _ = _interp_face(vel[2], 2, Xm, Ym, Zm, dim, per)
        x[p, 0] = min(max(x[p, 0] + dt * vx, lo[0]), hi[0])
        x[p, 1] = min(max(x[p, 1] + dt * vy, lo[1]), hi[1])
        if dim == 3:
            x[p, 2] = min(max(x[p, 2] + dt * vz, lo[2]), hi[2])
        for c in range(dim):
            if per[c]:
                r = (x[p, c] - origin[c]) % length[c]
                x[p, c] = origin[c] + (r if r < length[c] else 0.0)


# ----------------------------------------------------------------------------- volume
@njit(cache=True, inline="always")
def _fold(i, n, lo_closed, hi_closed, periodic):
    """Cell index i of an axis with n cells: itself inside, the cell next to a closed side for the
    ghost cell beyond it (the mirror image), -1 beyond an open side; wrapped on a periodic axis."""
    if periodic:
        return i % n
    if i < 0:
        return 0 if lo_closed else -1
    if i >= n:
        return n - 1 if hi_closed else -1
    return i


@njit(cache=True)
def particle_density(x, origin, h, dim, closed, per, density):
    """Particles per cell measured with the tent weights at the cell centres (serial scatter:
    deterministic): a lattice of spacing h/2 reads 2^dim in every cell. Along an axis with a
    closed side (closed[a, side]) the weight a particle gives the ghost cell beyond it goes to its
    mirror, the cell next to the side (the particle's reflection), so cells along walls read the
    same as inside."""
    nx, ny, nz = density.shape
    density[...] = 0.0
    inv_h = 1.0 / h
    for p in range(x.shape[0]):
        X = (x[p, 0] - origin[0]) * inv_h - 0.5
        Y = (x[p, 1] - origin[1]) * inv_h - 0.5
        i0 = int(math.floor(X))
        j0 = int(math.floor(Y))
        fx = X - i0
        fy = Y - j0
        k0 = 0
        fz = 0.0
        if dim == 3:
            Z = (x[p, 2] - origin[2]) * inv_h - 0.5
            k0 = int(math.floor(Z))
            fz = Z - k0
        for dk in range(2 if dim == 3 else 1):
            k = 0
            wz = 1.0
            if dim == 3:
                k = _fold(k0 + dk, nz, closed[2, 0], closed[2, 1], per[2])
                wz = fz if dk else 1.0 - fz
            if k < 0:
                continue
            for dj in range(2):
                j = _fold(j0 + dj, ny, closed[1, 0], closed[1, 1], per[1])
                if j < 0:
                    continue
                wy = (fy if dj else 1.0 - fy) * wz
                for di in range(2):
                    i = _fold(i0 + di, nx, closed[0, 0], closed[0, 1], per[0])
                    if i < 0:
                        continue
                    density[i, j, k] += (fx if di else 1.0 - fx) * wy


@njit(cache=True)
def _inner_cell(liquid, cell_solid, frac, closed, i, j, k, dim, periodic):
    """Whether a liquid cell lies inside the liquid: each face neighbour is a liquid cell across
    a fully open face (no cut solid) or a closed domain side (where `particle_density` mirrors
    the particles). There the tent-weighted density reads the rest density exactly on the
    lattice, so a lower reading means particles are missing."""
    nx, ny, nz = liquid.shape
    for a in range(dim):
        n = nx if a == 0 else (ny if a == 1 else nz)
        fa = frac[a]
        c0 = i if a == 0 else (j if a == 1 else k)
        for sd in range(2):
            c = c0 + 2 * sd - 1
            if c < 0 or c >= n:
                if periodic[a]:
                    c %= n
                elif closed[a, sd]:
                    continue
                else:
                    return False
            if fa[i + (a == 0) * sd, j + (a == 1) * sd, k + (a == 2) * sd] < 1.0:
                return False
            ii = c if a == 0 else i
            jj = c if a == 1 else j
            kk = c if a == 2 else k
            if cell_solid[ii, jj, kk] or not liquid[ii, jj, kk]:
                return False
    return True


@njit(cache=True)
def density_excess(density, liquid, cell_solid, frac, closed, periodic, dim, rest, strength, rhs):
    """rhs = strength (density / rest - 1), the relative volume each liquid cell should give
    back (negative: take in): in every liquid cell holding more than `rest`, and in the inner
    cells (`_inner_cell`) also where it holds less (a cell at the free surface or next to a solid
    reads less than it holds, so it never draws particles in). 0 elsewhere. Returns the largest
    |rhs| / strength."""
    nx, ny, nz = density.shape
    worst = 0.0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                rhs[i, j, k] = 0.0
                if not liquid[i, j, k]:
                    continue
                e = density[i, j, k] / rest - 1.0
                if e < 0.0 and not _inner_cell(liquid, cell_solid, frac, closed, i, j, k, dim,
                                               periodic):
                    continue
                rhs[i, j, k] = strength * e
                worst = max(worst, abs(e))
    return worst


@njit(cache=True)
def count_particles(x, origin, h, dim, count, sub):
    """Particles per cell (the cell holding each) into count, and in sub the bit mask of the
    cell's 2^dim sub-cells (h/2 boxes) that hold one."""
    nx, ny, nz = count.shape
    count[...] = 0
    sub[...] = 0
    inv_h = 1.0 / h
    for p in range(x.shape[0]):
        X = (x[p, 0] - origin[0]) * inv_h
        Y = (x[p, 1] - origin[1]) * inv_h
        Z = (x[p, 2] - origin[2]) * inv_h if dim == 3 else 0.5
        i = min(max(int(math.floor(X)), 0), nx - 1)
        j = min(max(int(math.floor(Y)), 0), ny - 1)
        k = min(max(int(math.floor(Z)), 0), nz - 1)
        count[i, j, k] += 1
        bx = 1 if X - i >= 0.5 else 0
        by = 1 if Y - j >= 0.5 else 0
        bz = 1 if (dim == 3 and Z - k >= 0.5) else 0
        sub[i, j, k] |= 1 << (bx + 2 * by + 4 * bz)


@njit(cache=True)
def _enclosed(count, cell_solid, i, j, k, dim, least, periodic):
    """Whether every face neighbour of cell (i, j, k) holds at least `least` particles or is a
    solid or a closed domain side (the cell lies inside the liquid, not at its surface)."""
    nx, ny, nz = count.shape
    for a in range(dim):
        n = nx if a == 0 else (ny if a == 1 else nz)
        for sd in range(2):
            ii, jj, kk = i, j, k
            c = (i if a == 0 else (j if a == 1 else k)) + 2 * sd - 1
            if c < 0 or c >= n:
                if not periodic[a]:
                    continue   # a closed side (`reseed_plan` skips the cells on open sides)
                c %= n
            if a == 0:
                ii = c
            elif a == 1:
                jj = c
            else:
                kk = c
            if cell_solid[ii, jj, kk]:
                continue
            if count[ii, jj, kk] < least:
                return False
    return True


@njit(cache=True)
def reseed_plan(count, sub, density, cell_solid, dim, per_cell, periodic, open_cells, add):
    """Particles to add per cell: a hole inside the liquid, an empty cell reading less than half
    the rest density (tent weights, `particle_density`) whose neighbours all read at least 3/4 of
    it (or are solids or closed sides), gets a particle at the centre of each of its h/2
    sub-cells. Cells on open sides (open_cells) are left alone. Returns (particles to add, particles to remove: those beyond OVERFULL per_cell in a
    cell)."""
    nx, ny, nz = count.shape
    n_add = 0
    n_remove = 0
    limit = OVERFULL * per_cell
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                add[i, j, k] = 0
                c = count[i, j, k]
                if c > limit:
                    n_remove += c - limit
                    continue
                if c > 0 or density[i, j, k] >= 0.5 * per_cell or cell_solid[i, j, k] \
                        or open_cells[i, j, k]:
                    continue
                if not _enclosed(density, cell_solid, i, j, k, dim, 0.75 * per_cell, periodic):
                    continue
                m = 0
                for b in range(1 << dim):
                    if not (sub[i, j, k] >> b) & 1 and c + m < per_cell:
                        m += 1
                add[i, j, k] = m
                n_add += m
    return n_add, n_remove


@njit(cache=True)
def seed_positions(add, sub, origin, h, dim, out):
    """The new particles' positions (cells in order, empty sub-cells in bit order, each at its
    sub-cell's centre: the h/2 lattice of `add_block`) into out (rows from 0; z = 0 in 2-D)."""
    nx, ny, nz = add.shape
    n = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                m = add[i, j, k]
                if m == 0:
                    continue
                for b in range(1 << dim):
                    if m == 0:
                        break
                    if (sub[i, j, k] >> b) & 1:
                        continue
                    out[n, 0] = origin[0] + (i + 0.25 + 0.5 * (b & 1)) * h
                    out[n, 1] = origin[1] + (j + 0.25 + 0.5 * ((b >> 1) & 1)) * h
                    out[n, 2] = origin[2] + (k + 0.25 + 0.5 * ((b >> 2) & 1)) * h if dim == 3 else 0.0
                    n += 1
                    m -= 1
    return n


@njit(cache=True)
def mark_overfull(x, origin, h, dim, limit, seen, keep):
    """keep[p] = False for the particles of a cell beyond the first `limit` of it (in index order);
    seen: (cells) int scratch. Returns the number kept."""
    nx, ny, nz = seen.shape
    seen[...] = 0
    inv_h = 1.0 / h
    kept = 0
    for p in range(x.shape[0]):
        i = min(max(int(math.floor((x[p, 0] - origin[0]) * inv_h)), 0), nx - 1)
        j = min(max(int(math.floor((x[p, 1] - origin[1]) * inv_h)), 0), ny - 1)
        k = 0
        if dim == 3:
            k = min(max(int(math.floor((x[p, 2] - origin[2]) * inv_h)), 0), nz - 1)
        seen[i, j, k] += 1
        keep[p] = seen[i, j, k] <= limit
        if keep[p]:
            kept += 1
    return kept


# ----------------------------------------------------------------------------- open sides
@njit(cache=True)
def inflow_row(axis, side, dist, origin, h, n, dim, cell_solid, out):
    """One row of particles parallel to a domain side (axis, side 0 low / 1 high) at distance
    `dist` inside it, on the h/2 lattice of `add_block` along the side (2 per cell per axis),
    leaving out points in cells whose centre lies in a solid. Writes the rows from 0 of out
    (when given enough rows) and returns the count."""
    t1 = 1 if axis == 0 else 0
    t2 = 2 if axis != 2 else 1
    n1 = 2 * n[t1]
    n2 = 2 * n[t2] if dim == 3 else 1
    plane = origin[axis] + (dist if side == 0 else n[axis] * h - dist)
    ca = min(max(int(math.floor((plane - origin[axis]) / h)), 0), n[axis] - 1)
    m = 0
    for a1 in range(n1):
        for a2 in range(n2):
            c1 = a1 // 2
            c2 = a2 // 2 if dim == 3 else 0
            ii = ca if axis == 0 else c1
            jj = ca if axis == 1 else (c1 if t1 == 1 else c2)
            kk = ca if axis == 2 else (c2 if dim == 3 else 0)
            if cell_solid[ii, jj, kk]:
                continue
            if m < out.shape[0]:
                out[m, axis] = plane
                out[m, t1] = origin[t1] + (a1 + 0.5) * 0.5 * h
                if dim == 3:
                    out[m, t2] = origin[t2] + (a2 + 0.5) * 0.5 * h
                else:
                    out[m, 2] = 0.0
            m += 1
    return m


@njit(cache=True)
def mark_outside(x, lo, hi, keep):
    """keep[p] = whether particle p lies inside [lo, hi] on every axis; returns the number kept."""
    kept = 0
    for p in range(x.shape[0]):
        inside = True
        for c in range(3):
            if x[p, c] < lo[c] or x[p, c] > hi[c]:
                inside = False
        keep[p] = inside
        if inside:
            kept += 1
    return kept


# ----------------------------------------------------------------------------- the liquid
class LiquidFluid:
    """A particle liquid (PIC/FLIP/APIC) on a MAC grid in a box with walls, inflow and outflow
    sides (see the module docstring).

    World protocol: ``advance_before_rigid = True`` (the world advances it before its rigid stage,
    so the liquid's impulses reach the bodies' velocities before their positions are integrated).

    Parameters
    ----------
    shape : (nx, ny) or (nx, ny, nz) cells, each >= 4.
    cell_size : h, m (> 0).
    origin : lower corner of the box, m (default zeros).
    gravity : m/s^2 (default (0, -9.81) in 2-D, (0, 0, -9.81) in 3-D).
    method : "apic" (default), "flip" or "pic".
    flip_ratio : FLIP share of the PIC/FLIP blend in [0, 1] (default 0.95; "flip" only).
    density : rho, kg/m^3 (default 1000): pressure = rho phi / dt.
    tolerance : relative residual of the pressure solve (default 1e-8).
    max_iterations : of the pressure solve (default 2000).
    pressure_solver : "mgpcg" (multigrid-preconditioned CG, default) or "jacobi" (Jacobi-PCG),
        see `liquid_pressure`.
    parallel : parallel pressure kernels on large levels (None: when the grid has at least
        `kernels.PARALLEL_CELLS` cells; False: serial, faster on a loaded machine).
    cfl : CFL number for ``advance`` (default 1, at most 5).
    max_dt : largest substep, s (default 1/60).
    extrapolation_layers : velocity extrapolation depth into the air, cells (default 4).
    obstacles : colliders of `inertia.colliders` with this dim (static or with a `Motion`):
        cut-cell solids whose velocity enters the boundary condition; particles are pushed out.
    depth : thickness of a 2-D liquid in z, m (default 1): the pressure force on a rigid body is
        the force per unit length times `depth` (3-D: ignored).
    viscosity : kinematic viscosity nu, m^2/s, >= 0 (default 0: inviscid). Implicit (backward
        Euler, `viscosity.py`) after the pressure solve, traction-free at the free surface.
    walls : "slip" (default) or "no-slip" for every side, or a dict side ("x-", ..., "z+") ->
        "slip" / "no-slip" (only matters with viscosity > 0).
    obstacle_slip : False (default: no-slip), True, or one bool per obstacle; rigid shape rows
        take `bind_rigid(rigid, slip=)` (default no-slip). Only matters with viscosity > 0.
    volume_correction : beta in [0, 1], the share of each cell's density deviation given back
        per step by the volume stage (default 1; 0.5-1 keeps a collapsing column within 2 % of
        its density; 0 turns it off).
    reseed : fill holes inside the liquid and trim over-full cells (default False).
    boundaries : dict side ("x-", ..., "z+") -> `Wall` (may move along itself), `Inflow`
        (velocity into the domain; the side emits particles), `Outflow` (open, p = 0; particles
        leaving are removed), `Periodic` (both sides of an axis; an even cell count along it; not
        with viscosity) or their names ("slip", "no-slip", "outflow", "periodic"), as
        `GridFluid`'s `boundaries` (`boundaries.parse_boundaries`); sides not named follow
        ``walls``.
    """

    advance_before_rigid = True

    def __init__(self, shape, cell_size, *, origin=None, gravity=None, method="apic",
                 flip_ratio=0.95, density=1000.0, tolerance=1e-8, max_iterations=2000, cfl=1.0,
                 max_dt=1 / 60, extrapolation_layers=4, obstacles=(), depth=1.0,
                 pressure_solver="mgpcg", parallel=None, viscosity=0.0, walls="slip",
                 obstacle_slip=False, volume_correction=1.0, reseed=False, boundaries=None):
        try:
            shp = tuple(int(s) for s in shape)
        except TypeError:
            raise ValueError(f"shape must be 2 or 3 cell counts; got {shape!r}") from None
        if len(shp) not in (2, 3) or min(shp) < 4 or any(s != t for s, t in zip(shp, shape)):
            raise ValueError(f"shape must be 2 or 3 integer cell counts >= 4; got {shape!r}")
        self.dim = dim = len(shp)
        self.shape = shp
        self.cell_size = h = positive_scalar(cell_size, "cell_size")
        self.origin = np.zeros(3)
        if origin is not None:
            self.origin[:dim] = as_vector(origin, "origin", dim)
        self.gravity = np.zeros(3)
        if gravity is None:
            self.gravity[dim - 1] = -9.81
        else:
            self.gravity[:dim] = as_vector(gravity, "gravity", dim)
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}; got {method!r}")
        self.method = method
        fr = float(flip_ratio)
        if not 0.0 <= fr <= 1.0:
            raise ValueError(f"flip_ratio must be in [0, 1]; got {flip_ratio!r}")
        self.flip_ratio = fr
        self.density = positive_scalar(density, "density")
        self.tolerance = positive_scalar(tolerance, "tolerance")
        self.max_iterations = int(max_iterations)
        self.cfl = positive_scalar(cfl, "cfl")
        if self.cfl > 5:
            raise ValueError(f"cfl must be in (0, 5]; got {cfl!r}")
        self.max_dt = positive_scalar(max_dt, "max_dt")
        self.extrapolation_layers = int(extrapolation_layers)
        if self.extrapolation_layers < 1:
            raise ValueError(f"extrapolation_layers must be >= 1; got {extrapolation_layers!r}")
        self.n = np.array(shp + (1,) * (3 - dim), dtype=np.int64)
        nx, ny, nz = (int(s) for s in self.n)
        fs = [(nx + 1, ny, nz), (nx, ny + 1, nz), (nx, ny, nz + 1)]
        # grid arrays: face velocities (p2g, forces, project, extrapolate), m/s
        self.vel = tuple(np.zeros(s) for s in fs)
        # FLIP: velocity after p2g, then (project) the change made by the grid step
        self.vel_old = tuple(np.zeros(s) for s in fs)
        self._wsum = tuple(np.zeros(s) for s in fs)
        self._valid = tuple(np.zeros(s, dtype=np.bool_) for s in fs)
        self._valid2 = tuple(np.zeros(s, dtype=np.bool_) for s in fs)
        self._valid_b = tuple(np.zeros(s, dtype=np.bool_) for s in fs)
        cs = (nx, ny, nz)
        self.liquid = np.zeros(cs, dtype=np.bool_)        # surface stage
        self.phi = np.zeros(cs)                           # level set, m (surface stage)
        self.pressure_phi = np.zeros(cs)                  # p dt / rho, m^2/s (project)
        self.pressure = np.zeros(cs)                      # Pa (project)
        self._rhs = np.zeros(cs)                          # -div u* (project)
        # solids (obstacles stage): open fraction and solid velocity per face, pressure weights
        # (project), cells whose centre lies inside a solid
        self._frac = tuple(np.ones(s) for s in fs)
        self._solid = tuple(np.zeros(s) for s in fs)
        self._weights = tuple(np.zeros(s) for s in fs)
        self._cell_solid = np.zeros(cs, dtype=np.bool_)
        self._liquid_scratch = np.zeros(cs, dtype=np.bool_)
        self.depth = positive_scalar(depth, "depth")
        # implicit viscosity (viscosity stage): node kinds per component, the obstacles' signed
        # distance, surface velocity and index at the face nodes (obstacles stage), CG scratch
        self.viscosity = positive_scalar(viscosity, "viscosity", allow_zero=True)
        self._wall_no_slip = parse_walls(walls, dim)
        # domain sides (`boundaries`): closed (wall, inflow) or open (outflow), the velocity each
        # closed side imposes (rows 2 axis + side), the cells along an inflow side
        self.sides = self._parse_sides(boundaries)
        if self.viscosity > 0.0 and np.any(self._periodic):
            raise ValueError("viscosity > 0 with periodic boundaries is not supported by "
                             "LiquidFluid; use walls or outflow sides")
        ghost_value = np.zeros((3, 3, 2))
        ghost_kind = np.zeros((3, 3, 2), dtype=np.int64)
        for c in range(3):
            for ax in range(3):
                for sd in range(2):
                    if ax == c:
                        continue
                    b = self.sides[2 * ax + sd]
                    if isinstance(b, Outflow):
                        ghost_kind[c, ax, sd] = K.NEUMANN
                    elif isinstance(b, Inflow) or self._wall_no_slip[ax, sd]:
                        ghost_kind[c, ax, sd] = K.DIRICHLET
                        ghost_value[c, ax, sd] = self._side_vel[2 * ax + sd, c]
        frame = self.origin.copy()
        if dim == 2:
            frame[2] = -0.5 * h   # faces at z = 0 (the torque arms of the viscous impulses)
        self._ctx = K.GridContext(self.n.copy(), h, frame, dim, np.zeros(3, dtype=np.bool_),
                                  ghost_kind, ghost_value)
        par = (int(np.prod(self.n)) >= K.PARALLEL_CELLS) if parallel is None else bool(parallel)
        self._kv = K.KernelSet(V, par)
        self._kk = K.KernelSet(K, par)
        self._vkind = tuple(np.zeros(s, dtype=np.int8) for s in fs)
        self._vsdf = [np.zeros((1, 1, 1)) for _ in fs]
        self._vwall = [np.zeros((1, 1, 1)) for _ in fs]
        self._vowner = [np.full((1, 1, 1), -1, np.int64) for _ in fs]
        self._vrigid = [(np.zeros(0, np.int64), np.zeros(0, np.int64)) for _ in fs]
        self._vedge = []
        for a in range(3):
            e = np.zeros(fs[a], dtype=np.bool_)
            idx = [slice(None)] * 3
            for end in (0, -1):
                idx[a] = end
                e[tuple(idx)] = True
            self._vedge.append(e.reshape(-1))
        self._cg = [[np.zeros(s) for _ in range(4)] for s in fs]
        self._vpartial = np.zeros(int(max(self.n)) + 2)
        self.last_viscous_iterations = 0
        # pressure operator and solver (project)
        self.pressure_solver = pressure_solver
        if parallel not in (None, True, False):
            raise ValueError(f"parallel must be None (auto), True or False; got {parallel!r}")
        self._pressure = LiquidPressure(cs, method=pressure_solver, tolerance=self.tolerance,
                                        max_iterations=self.max_iterations, parallel=parallel,
                                        periodic=self._periodic.copy())
        # particles: x (N, 3) m, v (N, 3) m/s, c (N, 3, 3) 1/s (APIC); z = 0 in 2-D
        self.x = np.zeros((0, 3))
        self.v = np.zeros((0, 3))
        self.c = np.zeros((0, 3, 3))
        self.particles_per_cell = 4 if dim == 2 else 8
        # volume (volume stage): the share of a cell's excess particle density given back per
        # step, reseeding of holes and over-full cells
        vc = volume_correction
        if isinstance(vc, (bool, np.bool_)) or not isinstance(vc, (int, float, np.integer, np.floating)) \
                or not 0.0 <= float(vc) <= 1.0:
            raise ValueError(f"volume_correction must be a number in [0, 1] (0: off); got {vc!r}")
        self.volume_correction = float(vc)
        if not isinstance(reseed, (bool, np.bool_)):
            raise ValueError(f"reseed must be True or False; got {reseed!r}")
        self.reseed = bool(reseed)
        self.particle_density = np.zeros(cs)   # particles per cell, tent weights (volume stage)
        self._volume_rhs = np.zeros(cs)        # relative volume excess per cell (volume stage)
        self._volume_phi = np.zeros(cs)        # its potential, m^2 (volume stage)
        self._disp = tuple(np.zeros(s) for s in fs)            # displacement -grad q, m
        self._disp_valid = tuple(np.zeros(s, dtype=np.bool_) for s in fs)
        self._zero_faces = tuple(np.zeros(s) for s in fs)
        self._open_cells = np.zeros(cs, dtype=np.bool_)        # cells along an open or inflow side
        self._inflow_side = np.full(cs, -1, dtype=np.int64)    # 2 axis + side of an inflow layer
        for a in range(dim):
            for sd in range(2):
                idx = [slice(None)] * 3
                idx[a] = slice(0, 1) if sd == 0 else slice(-1, None)
                if isinstance(self.sides[2 * a + sd], (Outflow, Inflow)):
                    self._open_cells[tuple(idx)] = True
                if isinstance(self.sides[2 * a + sd], Inflow):
                    self._inflow_side[tuple(idx)] = 2 * a + sd
        self._any_inflow = bool(np.any(self._inflow_side >= 0))
        self._any_open = any(isinstance(b, Outflow) for b in self.sides[:2 * dim])
        # per side: how deep the liquid has entered since the last row (the first row lies
        # h/4 inside the side, as add_block's first particles)
        self._inflow_travel = np.full(6, 0.75 * h)
        self.particles_emitted = 0        # particles the inflow sides added, in total
        self.particles_drained = 0        # particles that left through open sides, in total
        self._keep = np.empty(0, dtype=np.bool_)
        self._count = np.zeros(cs, dtype=np.int64)
        self._sub = np.zeros(cs, dtype=np.int64)
        self._add = np.zeros(cs, dtype=np.int64)
        self.last_volume_excess = 0.0     # largest relative density excess of the last step
        self.particles_seeded = 0         # particles added by reseeding, in total
        self.particles_removed = 0        # particles removed from over-full cells, in total
        # level-set radius: puts phi = 0 halfway between the top liquid cell centre and the
        # first air cell centre for a lattice of spacing h/2 (2 per cell per axis): their
        # nearest particles lie sqrt(dim) h / 4 and sqrt(dim + 8) h / 4 away
        self.surface_radius = 0.5 * (math.sqrt(dim) + math.sqrt(dim + 8)) / 4 * h
        lo = self.origin[:3].copy()
        hi = lo + self.n * h
        margin = 1e-3 * h
        self._lo = lo + margin
        self._hi = hi - margin
        # the domain: particles beyond an open side are drained; advection clamps only at closed
        # sides (an open side lets them two cells past it)
        self._box_lo = lo.copy()
        self._box_hi = hi.copy()
        self._box_lo[dim:] = -np.inf
        self._box_hi[dim:] = np.inf
        self._adv_lo = self._lo.copy()
        self._adv_hi = self._hi.copy()
        self._length = self.n * h                  # (periodic axes wrap positions into it)
        for a in range(dim):
            if self._periodic[a]:
                self._adv_lo[a] = self._box_lo[a] = -np.inf
                self._adv_hi[a] = self._box_hi[a] = np.inf
                continue
            if not self._closed[a, 0]:
                self._adv_lo[a] = lo[a] - 2 * h
            if not self._closed[a, 1]:
                self._adv_hi[a] = hi[a] + 2 * h
        self.time = 0.0
        self.step_index = 0
        self.last_pressure_iterations = 0
        self.last_residual = 0.0
        self._dt_prev = 0.0     # the last step's dt (project: warm start of the pressure solve)
        # obstacles and rigid bodies (bind_rigid)
        from .obstacles import PlaneSlice
        self.obstacles = list(obstacles)
        for i, o in enumerate(self.obstacles):
            if getattr(o, "dim", None) != dim or not hasattr(o, "query"):
                raise ValueError(f"obstacles[{i}] must be a collider of inertia.colliders with "
                                 f"dim {dim}; got {o!r}")
        self._obstacle_views = [PlaneSlice(o, dim) for o in self.obstacles]
        self._slip = V.slip_flags(obstacle_slip, len(self.obstacles), "obstacle_slip")
        self._rigid_slip = False
        # viscous force on each obstacle (colliders, then shape rows), last substep
        self.obstacle_viscous_force = np.zeros((len(self.obstacles), 3))    # N
        self.obstacle_viscous_torque = np.zeros((len(self.obstacles), 3))   # N m about its reference
        self._visc_impulse = (np.zeros((len(self.obstacles), 3)), np.zeros((len(self.obstacles), 3)))
        self._rigid = None
        self._dynamic = np.zeros(0, dtype=np.bool_)
        self._any_dynamic = False
        self._rigid_obstacles = []
        self._owners = np.full(len(self.obstacles), -1, np.int64)
        self._moving = any(getattr(o, "motion", None) is not None for o in self.obstacles)
        self._cut = [(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64))] * 3
        # per-step work arrays: the obstacles stage's (`CutCells`, on first need), the dynamic-body
        # nodes of the viscosity (`_viscous_nodes`), particle queries (`_push_particles_out`)
        self._cells = None
        self._vrigid_buf = [(np.zeros(int(np.prod(s)), np.int64), np.zeros(int(np.prod(s)), np.int64))
                            for s in fs]
        self._pscratch = None
        self._coupling = None   # the pressure solve's body term (`_body_coupling`)
        self._obstacles_changed()
        self.body_force = np.zeros((0, 3))   # N, last substep's pressure force per body
        self.body_torque = np.zeros((0, 3))  # N m, about each body's centre of mass
        self._update_solids(0.0, check_domain=True)

    # ------------------------------------------------------------------------ particles
    @property
    def particle_count(self):
        return self.x.shape[0]

    def positions(self):
        """(N, dim) particle positions, m (a view)."""
        return self.x[:, :self.dim]

    def velocities(self):
        """(N, dim) particle velocities, m/s (a view)."""
        return self.v[:, :self.dim]

    def add_block(self, lower, upper, velocity=None, jitter=0.0, seed=0):
        """Fill the box [lower, upper] (m) with particles, 2 per cell per axis on the lattice
        of spacing h/2 (cells whose centre lies in the box), optionally jittered by
        `jitter` x h/4 (seeded); particles inside an obstacle are left out. Returns the number
        of particles added."""
        d = self.dim
        lo = as_vector(lower, "lower", d)
        hi = as_vector(upper, "upper", d)
        if np.any(hi <= lo):
            raise ValueError(f"upper must exceed lower on every axis; got {lower!r}, {upper!r}")
        h = self.cell_size
        s = h / 2
        axes = [np.arange(self.origin[a] + s / 2, self.origin[a] + self.n[a] * h, s) for a in range(d)]
        axes = [ax[(ax > lo[a]) & (ax < hi[a])] for a, ax in enumerate(axes)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
        if pts.shape[0] == 0:
            raise ValueError("the block holds no particle (smaller than the particle spacing h/2)")
        if jitter:
            rng = np.random.default_rng(seed)
            pts = pts + rng.uniform(-0.25 * jitter * h, 0.25 * jitter * h, pts.shape)
        x = np.zeros((pts.shape[0], 3))
        x[:, :d] = pts
        v = np.zeros_like(x)
        if velocity is not None:
            v[:, :d] = as_vector(velocity, "velocity", d)
        self._append_particles(x, v, np.zeros((x.shape[0], 3, 3)))
        np.clip(self.x, self._lo, self._hi, out=self.x)
        n0 = self.x.shape[0]
        self._drop_particles_in_solids(self.x.shape[0] - pts.shape[0])
        return pts.shape[0] - (n0 - self.x.shape[0])

    def _drop_particles_in_solids(self, first=0):
        """Remove particles (from index `first` on) whose position lies inside a solid: a block
        poured over an obstacle, or liquid where a body is placed (`bind_rigid`)."""
        obst = self._all_obstacles()
        if not obst or self.x.shape[0] <= first:
            return
        pts = self.x[first:, :self.dim]
        inside = np.zeros(pts.shape[0], dtype=np.bool_)
        for o in obst:
            inside |= np.asarray(o.signed_distance(pts, self.time)) < 0
        if inside.any():
            self._keep_particles(np.concatenate([np.ones(first, dtype=np.bool_), ~inside]))

    # ------------------------------------------------------------------------ solids
    def _all_obstacles(self):
        return self._obstacle_views + self._rigid_obstacles

    def _obstacles_changed(self):
        """After the obstacle list changed (constructor, `bind_rigid`): slip flags as one bool
        array, the viscous-torque reference points and force arrays, the obstacles stage's work
        arrays (`obstacles.CutCells`, made once per grid)."""
        nall = len(self.obstacles) + len(self._rigid_obstacles)
        self._slip_all = np.array(self._slip + [self._rigid_slip] * len(self._rigid_obstacles),
                                  dtype=np.bool_)
        self._refs = np.zeros((nall, 3))
        if nall and self._cells is None:
            from .obstacles import CutCells
            from .solver import MACGrid
            dim = self.dim
            g = MACGrid(self.shape, self.cell_size, self.origin[:dim])
            vshape = tuple(g.n + 1) if dim == 3 else (int(g.n[0]) + 1, int(g.n[1]) + 1, 1)
            self._cells = CutCells(g.vertex_positions(), vshape,
                                   [g.face_positions(a) for a in range(dim)], g.cell_positions(),
                                   dim, self._kk.parallel)
            self._pts = (self._cells.vertex_pts, self._cells.face_pts, self._cells.cell_pts, vshape)

    def _update_solids(self, t, check_domain=False):
        """Obstacles stage: open fractions, solid velocities and closed (body) faces from the
        obstacles at time t (`obstacles.CutCells`, the cut cells GridFluid uses; nothing
        allocated); walls and inflows close their domain side; cells whose centre lies inside a
        solid."""
        dim = self.dim
        obst = self._all_obstacles()
        if obst:
            cc = self._cells
            visc = self.viscosity > 0.0
            cc.update(obst, self._owners, t, self._frac, self._solid, self._cell_solid, nodes=visc)
            self._cut = cc.cut
            if visc:
                self._viscous_nodes(obst, None, t)
            if check_domain:
                if np.all(self._cell_solid):
                    raise ValueError("obstacles cover the whole domain")
                for i, o in enumerate(self.obstacles):
                    if not np.any(np.asarray(o.signed_distance(cc.cell_pts, t)) < self.cell_size):
                        raise ValueError(f"obstacles[{i}] lies outside the domain "
                                         f"{self.origin[:dim].tolist()} + "
                                         f"{(self.n[:dim] * self.cell_size).tolist()}")
        else:
            for a in range(3):
                self._frac[a][...] = 1.0
                self._solid[a][...] = 0.0
            self._cell_solid[...] = False
        if dim == 2:
            self._frac[2][...] = 0.0
        for a in range(dim):   # walls and inflows close their side (at the inflow's velocity)
            for sd in range(2):
                if not self._closed[a, sd]:
                    continue
                idx = [slice(None)] * 3
                idx[a] = 0 if sd == 0 else -1
                self._frac[a][tuple(idx)] = 0.0
                self._solid[a][tuple(idx)] = self._side_normal[a, sd]

    def _viscous_nodes(self, obst, faces, t):
        """Every face node's nearest obstacle (computed by the obstacles stage, ``nodes=True``):
        signed distance, velocity component, index (the no-slip boundary of the viscous solve),
        and the nodes near a dynamic body's shape, whose wall velocity `_diffuse` renews after
        the pressure solve changed the body's velocity."""
        h = self.cell_size
        cc = self._cells
        for a in range(self.dim):
            shape = self.vel[a].shape
            if self._vsdf[a].shape != shape:
                self._vsdf[a] = np.zeros(shape)
                self._vwall[a] = np.zeros(shape)
                self._vowner[a] = np.full(shape, -1, np.int64)
            best, own = cc.best[a], cc.near[a]
            self._vsdf[a].reshape(-1)[...] = best
            self._vwall[a].reshape(-1)[...] = cc.near_vel[a]
            self._vowner[a].reshape(-1)[...] = own
            if self._any_dynamic:
                nodes, body = self._vrigid_buf[a]
                n = _near_dynamic_nodes(best, own, self._owners, self._dynamic, 2.0 * h, nodes, body)
                self._vrigid[a] = (nodes[:n], body[:n])

    @property
    def face_fractions(self):
        """Open fraction of the u, v[, w] faces (views; 2-D: (nx+1, ny), (nx, ny+1))."""
        return tuple(f[:, :, 0] if self.dim == 2 else f for f in self._frac[:self.dim])

    def _push_particles_out(self, t):
        """Particles closer than 0.1 h to a solid (or inside it) move out along its normal and
        lose their velocity into it (relative to the solid's surface velocity)."""
        obst = self._all_obstacles()
        if not obst or self.x.shape[0] == 0:
            return
        d = self.dim
        n = self.x.shape[0]
        if self._pscratch is None or self._pscratch[0].shape[0] != n:   # particles added or dropped
            self._pscratch = (np.empty((n, d)), np.empty(n), np.empty((n, d)), np.empty((n, d)),
                              np.empty(n, np.int64), np.empty((n, d)))
        pts, dist, nrm, vs, idx, near = self._pscratch
        clearance = 0.1 * self.cell_size
        for o in obst:
            np.copyto(pts, self.x[:, :d])   # (each obstacle sees the pushes of those before it)
            o.query_into(pts, t, dist, nrm, vs)
            m = _close_rows(dist, clearance, pts, idx, near)
            if m == 0:
                continue
            o.query_into(near[:m], t, dist[:m], nrm[:m], vs[:m])
            push_out_of_solids(self.x, self.v, dist[:m], nrm[:m], vs[:m], idx[:m], d, clearance)
        _clamp_rows(self.x, self._adv_lo, self._adv_hi)

    # ------------------------------------------------------------------------ stepping
    def step(self, dt):
        """Advance by dt seconds (one step)."""
        dt = positive_scalar(dt, "dt")
        h = self.cell_size
        coupled = self._any_dynamic
        if coupled:
            self._predict_gravity(dt, 1.0)
        if self._moving:
            self._update_solids(self.time + dt)
        m = {"apic": 0, "flip": 1, "pic": 2}[self.method]
        particles_to_grid(self.x, self.v, self.c, m == 0, self.origin, h, self.dim, self.vel,
                          self._wsum, self._periodic)
        build_surface(self.x, self.origin, h, self.surface_radius, self.dim, self.liquid, self.phi,
                      self._periodic)
        if self._all_obstacles():
            wet_solid_cells(self.liquid, self.phi, self._cell_solid, self._frac, self.dim, h,
                            self._liquid_scratch)
        if m == 1:
            for a in range(self.dim):
                np.copyto(self.vel_old[a], self.vel[a])
        add_gravity_and_walls(self.vel, self.liquid, self.gravity, dt, self.dim, self._closed,
                              self._side_normal, self._periodic)
        surface = build_face_weights(self.liquid, self.phi, self._frac, self._cell_solid,
                                     self.dim, self._weights, self._periodic)
        self._pressure.set_operator(self.liquid, self._cell_solid, self._weights, h, self.dim,
                                    surface)
        liquid_divergence(self.vel, self._frac, self._solid, self.liquid, h, self.dim, self._rhs)
        # warm start from the last step's pressure (phi = p dt / rho, rescaled to this dt): the
        # solve then only works on what changed, so its residual error is not made anew (and
        # accumulated by the particles) every step; a liquid at rest stays at rest
        warm = self._dt_prev > 0.0
        if warm:
            np.multiply(self.pressure_phi, dt / self._dt_prev, out=self.pressure_phi)
        it, res = self._pressure.solve(self._rhs, self.pressure_phi, self._body_coupling(), warm)
        self._dt_prev = dt
        self.last_pressure_iterations, self.last_residual = it, res
        correct = self.volume_correction > 0.0 and self._volume_displacement()
        np.multiply(self.pressure_phi, self.density / dt, out=self.pressure)
        subtract_pressure_gradient(self.vel, self.pressure_phi, self.liquid, self.phi,
                                   self._weights, self._frac, self._solid, h, self.dim,
                                   self._valid, self._periodic)
        if self._rigid is not None:
            self._push_bodies(dt)
            if self._any_dynamic:
                # the bodies' new velocity on their faces (the solve made it divergence-free)
                origin, _ = self._impulse_frame()
                st = self._rigid.state
                for a in range(self.dim):
                    faces, frac, owner = self._cut[a]
                    if faces.size:
                        set_body_face_velocities(self.vel[a], self._solid[a], faces, frac, owner,
                                                 self._dynamic, a, h, origin, st.body_q, st.body_qd)
        if self.viscosity > 0.0:
            self._diffuse(dt)
        if coupled:
            self._predict_gravity(dt, -1.0)
        if m == 1:
            # FLIP: the grid's velocity change, extrapolated like the velocity
            for a in range(self.dim):
                np.subtract(self.vel[a], self.vel_old[a], out=self.vel_old[a])
                np.copyto(self._valid_b[a], self._valid[a])
            extrapolate(self.vel_old, self._valid_b, self._valid2, self.dim,
                        self.extrapolation_layers)
        extrapolate(self.vel, self._valid, self._valid2, self.dim, self.extrapolation_layers)
        grid_to_particles(self.x, self.v, self.c, self.vel, self.vel_old, self.origin, h,
                          self.dim, m, self.flip_ratio, self._periodic)
        advect_particles(self.x, self.vel, self.origin, h, self.dim, dt, self._adv_lo,
                         self._adv_hi, self._periodic, self._length)
        if correct:
            advect_particles(self.x, self._disp, self.origin, h, self.dim, 1.0, self._adv_lo,
                             self._adv_hi, self._periodic, self._length)
        if self._any_open:
            self._drain()
        if self._any_inflow:
            self._emit(dt)
        self._push_particles_out(self.time + dt)
        if self.reseed:
            self._reseed()
        if not _all_finite(self.v):
            bad = np.flatnonzero(~np.all(np.isfinite(self.v), axis=1))[:10]
            raise SimulationDiverged(
                f"liquid step {self.step_index} (t = {self.time:.6g} s): non-finite velocity of "
                f"particles {bad.tolist()}; likely cause: dt far above the CFL limit or a pressure "
                f"solve that did not converge (residual {res:.2e})",
                step=self.step_index, time=self.time, indices=bad)
        self.time += dt
        self.step_index += 1

    def _parse_sides(self, boundaries):
        """The six domain sides from ``boundaries`` (`boundaries.parse_boundaries`, GridFluid's
        description; sides not named are the ``walls`` setting): sets the closed flags, the
        closed sides' velocities and returns the side objects."""
        dim = self.dim
        names = SIDES[:2 * dim]
        if boundaries is None:
            boundaries = {}
        if isinstance(boundaries, dict):
            merged = {sd: Wall(slip=not self._wall_no_slip[i // 2, i % 2])
                      for i, sd in enumerate(names)}
            merged.update(boundaries)
            boundaries = merged
        sides = parse_boundaries(boundaries, dim)
        self._closed = np.ones((3, 2), dtype=np.bool_)
        self._periodic = np.zeros(3, dtype=np.bool_)
        self._side_vel = np.zeros((6, 3))
        self._side_normal = np.zeros((3, 2))
        for i, b in enumerate(sides[:2 * dim]):
            a, sd = i // 2, i % 2
            if isinstance(b, Periodic):   # (parse_boundaries checks both sides of the axis)
                if self.n[a] % 2:
                    raise ValueError(f"shape[{a}] must be even on a periodic axis (red-black "
                                     f"smoothing); got {self.n[a]}")
                self._closed[a, sd] = False
                self._periodic[a] = True
                continue
            if isinstance(b, Outflow):
                self._closed[a, sd] = False
                continue
            v = side_velocity(b, dim)
            if isinstance(b, Wall):
                if v[a] != 0.0:
                    raise ValueError(f"boundaries[{names[i]!r}]: a liquid's wall moves only along "
                                     f"itself; got velocity {b.velocity!r}")
                self._wall_no_slip[a, sd] = not b.slip
            else:
                inward = v[a] if sd == 0 else -v[a]
                if inward <= 0.0:
                    raise ValueError(f"boundaries[{names[i]!r}]: an Inflow's velocity must point "
                                     f"into the domain; got {b.velocity!r}")
            self._side_vel[i] = v
            self._side_normal[a, sd] = v[a]
        return sides

    def _append_particles(self, xn, vn, cn):
        """Append particles (positions, velocities, APIC affine matrices) after the last one."""
        self.x = np.ascontiguousarray(np.concatenate([self.x, xn]))
        self.v = np.ascontiguousarray(np.concatenate([self.v, vn]))
        self.c = np.ascontiguousarray(np.concatenate([self.c, cn]))

    def _keep_particles(self, keep):
        """Keep the particles where ``keep`` (N,) is True, in order."""
        self.x = np.ascontiguousarray(self.x[keep])
        self.v = np.ascontiguousarray(self.v[keep])
        self.c = np.ascontiguousarray(self.c[keep])

    def _emit(self, dt):
        """Inflow stage (after advection): each inflow side emits rows of particles on the h/2
        lattice of `add_block`, a row each time the liquid has entered h/2 deep (the side's
        inward speed x dt summed in `_inflow_travel`), placed as far in as the row has moved
        since, at the side's velocity: the particles enter at the lattice's density and the face
        velocity's rate."""
        h = self.cell_size
        rows = []
        for i in range(2 * self.dim):
            a, sd = i // 2, i % 2
            if not isinstance(self.sides[i], Inflow):
                continue
            speed = abs(self._side_normal[a, sd])
            self._inflow_travel[i] += speed * dt
            while self._inflow_travel[i] >= 0.5 * h:
                self._inflow_travel[i] -= 0.5 * h
                d = self._inflow_travel[i]
                n = inflow_row(a, sd, d, self.origin, h, self.n, self.dim, self._cell_solid,
                               np.zeros((0, 3)))
                xn = np.zeros((n, 3))
                inflow_row(a, sd, d, self.origin, h, self.n, self.dim, self._cell_solid, xn)
                vn = np.zeros((n, 3))
                vn[:] = self._side_vel[i]
                rows.append((xn, vn))
        if not rows:
            return
        xn = np.concatenate([r[0] for r in rows])
        vn = np.concatenate([r[1] for r in rows])
        n = xn.shape[0]
        self._append_particles(xn, vn, np.zeros((n, 3, 3)))
        self.particles_emitted += int(n)

    def _drain(self):
        """Outflow stage: particles that left the domain through an open side are removed."""
        keep = self._keep
        if keep.shape[0] != self.x.shape[0]:
            keep = self._keep = np.empty(self.x.shape[0], dtype=np.bool_)
        kept = mark_outside(self.x, self._box_lo, self._box_hi, keep)
        if kept == self.x.shape[0]:
            return
        self.particles_drained += self.x.shape[0] - kept
        self._keep_particles(keep)

    def _volume_displacement(self):
        """Volume stage (Kugelstadt, Longva, Thuerey and Bender 2019, the position-based density
        projection on the grid): the particle density per cell rho (tent weights, mirrored at
        walls) against the lattice's rest value rho_0 = particles_per_cell. With s = beta
        max(rho / rho_0 - 1, 0) the relative volume each over-full cell gives back (beta =
        ``volume_correction``), solve -Lap q = s with the step's pressure operator (p = 0 at the
        free surface, closed walls and solids) to VOLUME_TOLERANCE and move the particles by d =
        -grad q, so div d = s: the particles spread without any change of their velocity.
        Returns whether d != 0."""
        h = self.cell_size
        particle_density(self.x, self.origin, h, self.dim, self._closed, self._periodic,
                         self.particle_density)
        worst = density_excess(self.particle_density, self.liquid, self._cell_solid, self._frac,
                               self._closed, self._periodic, self.dim, float(self.particles_per_cell),
                               self.volume_correction, self._volume_rhs)
        self.last_volume_excess = worst
        if worst <= 0.0:
            return False
        self._pressure.solve(self._volume_rhs, self._volume_phi, None, False, VOLUME_TOLERANCE)
        for a in range(self.dim):
            self._disp[a][...] = 0.0
        subtract_pressure_gradient(self._disp, self._volume_phi, self.liquid, self.phi,
                                   self._weights, self._frac, self._zero_faces, h, self.dim,
                                   self._disp_valid, self._periodic)
        extrapolate(self._disp, self._disp_valid, self._valid2, self.dim,
                    self.extrapolation_layers)
        return True

    def _reseed(self):
        """Reseeding (`reseed_plan`): a hole inside the liquid (an empty cell reading under half
        the rest density, its neighbours 3/4 of it or more) gets one particle at the centre of
        each h/2 sub-cell, with the grid's velocity (APIC: and its gradient); a cell holding more
        than OVERFULL x particles_per_cell loses its particles beyond that (the last in index
        order). Serial kernels: deterministic. Allocates only when it adds or removes."""
        h = self.cell_size
        count_particles(self.x, self.origin, h, self.dim, self._count, self._sub)
        particle_density(self.x, self.origin, h, self.dim, self._closed, self._periodic,
                         self.particle_density)
        ppc = self.particles_per_cell
        n_add, n_remove = reseed_plan(self._count, self._sub, self.particle_density,
                                      self._cell_solid, self.dim, ppc, self._periodic,
                                      self._open_cells, self._add)
        if n_add == 0 and n_remove == 0:
            return
        if n_remove:
            keep = np.empty(self.x.shape[0], dtype=np.bool_)
            mark_overfull(self.x, self.origin, h, self.dim, OVERFULL * ppc, self._count, keep)
            self._keep_particles(keep)
            self.particles_removed += int(n_remove)
        if n_add:
            xn = np.zeros((n_add, 3))
            seed_positions(self._add, self._sub, self.origin, h, self.dim, xn)
            vn = np.zeros((n_add, 3))
            cn = np.zeros((n_add, 3, 3))
            m = 0 if self.method == "apic" else 2    # (FLIP: new particles take the grid's velocity)
            grid_to_particles(xn, vn, cn, self.vel, self.vel_old, self.origin, h, self.dim, m,
                              self.flip_ratio, self._periodic)
            self._append_particles(xn, vn, cn)
            self.particles_seeded += int(n_add)

    def _diffuse(self, dt):
        """Viscosity stage: backward Euler (I - nu dt Lap) u = u per component on the faces next to
        liquid (`viscosity.solve_component`, CG), after the pressure solve; zero stress across the
        free surface (AIR nodes), slip or no-slip domain walls (ghost rules of ``_ctx``), no-slip
        obstacles as Dirichlet data at their cut point (their surface velocity v + w x r, renewed
        for dynamic bodies after the pressure impulse), slip obstacles only their normal velocity.
        The momentum the no-slip links take from the liquid is the viscous force on each obstacle
        (`obstacle_viscous_force`), applied to rigid bodies as an impulse (explicit: after the
        implicit pressure coupling)."""
        h = self.cell_size
        coef = self.viscosity * dt / (h * h)
        obst = self._all_obstacles()
        for a in range(self.dim):
            V.liquid_node_kinds(self.liquid, self._frac[a], a, self._vkind[a])
        no_slip = False
        if obst:
            slip = self._slip_all
            for a in range(self.dim):
                if self._vsdf[a].shape != self.vel[a].shape:   # viscosity set after construction
                    self._update_solids(self.time + dt)
                no_slip |= V.obstacle_node_kinds(self._vkind[a].reshape(-1), self._vsdf[a].reshape(-1),
                                                 self._vowner[a].reshape(-1), slip, self._vedge[a])
            if self._any_dynamic:
                st = self._rigid.state
                faces = self._pts[1]
                for a in range(self.dim):
                    nodes, body = self._vrigid[a]
                    if nodes.size:
                        V.rigid_wall_velocity(self._vwall[a], faces[a], nodes, body, st.body_q,
                                              st.body_qd, a, self.dim)
        if no_slip:
            lin, ang = self._visc_impulse
            if lin.shape[0] != len(obst):
                lin, ang = self._visc_impulse = (np.zeros((len(obst), 3)), np.zeros((len(obst), 3)))
            if self.obstacle_viscous_force.shape[0] != len(obst):
                self.obstacle_viscous_force = np.zeros((len(obst), 3))
                self.obstacle_viscous_torque = np.zeros((len(obst), 3))
            lin[...] = 0.0
            ang[...] = 0.0
            ref = self._obstacle_refs()
            _, rho = self._impulse_frame()
            scale = rho * h ** 3 * coef     # rho h^d coef (2-D: per depth)
        its = 0
        for a in range(self.dim):
            kind = self._vkind[a]
            its = max(its, V.solve_component(self._kv, self._kk, self.vel[a], kind, self._vsdf[a],
                                             self._vwall[a], a, coef, self._ctx, self._cg[a],
                                             self._vpartial))
            if no_slip:
                V.wall_shear_impulses(self.vel[a], kind, self._vsdf[a], self._vwall[a],
                                      self._vowner[a], a, scale, self._ctx, ref, lin, ang)
                V.mark_no_slip_valid(kind, self._valid[a])
        self.last_viscous_iterations = its
        if no_slip:   # (arrays written in place: hold a .copy() across steps)
            np.divide(lin, dt, out=self.obstacle_viscous_force)
            np.divide(ang, dt, out=self.obstacle_viscous_torque)
            if self._rigid is not None:
                self._push_bodies_viscous(lin, ang, dt)
        elif self.obstacle_viscous_force.shape[0]:
            self.obstacle_viscous_force[...] = 0.0
            self.obstacle_viscous_torque[...] = 0.0

    def _obstacle_refs(self):
        """(n_obstacles, 3) reference points of the viscous torques: a collider's position at the
        current time (origin if it has no pose), a shape row's body centre of mass (written into
        the array `_obstacles_changed` made)."""
        n0 = len(self.obstacles)
        refs = self._refs
        for i, o in enumerate(self.obstacles):
            if hasattr(o, "pose"):
                p = np.asarray(o.pose(self.time)[0], dtype=np.float64).reshape(-1)
                refs[i, :p.size] = p[:3]
        if self._rigid is not None:
            body_q = self._rigid.state.body_q
            for i in range(len(self._rigid_obstacles)):
                b = self._owners[n0 + i]
                if b >= 0:
                    refs[n0 + i] = body_q[b, :3]
        return refs

    def _push_bodies_viscous(self, lin, ang, dt):
        """The viscous impulses of the shape rows (obstacles n_colliders..) summed per body and
        applied through `apply_body_impulses`; added to `body_force` / `body_torque`."""
        from ...dynamics.particle_coupling import apply_body_impulses
        n0 = len(self.obstacles)
        own = self._owners[n0:]
        blin, bang = self._impulse
        blin[...] = 0.0
        bang[...] = 0.0
        _sum_rows_per_body(own, lin[n0:], ang[n0:], blin, bang)
        _add_divided(blin, dt, self.body_force)
        _add_divided(bang, dt, self.body_torque)
        apply_body_impulses(self._rigid.model.bodies(), self._rigid.state, blin, bang)

    def stable_dt(self):
        vmax = float(np.max(np.abs(self.v))) if self.x.shape[0] else 0.0
        g = float(np.linalg.norm(self.gravity))
        # include the speed gravity adds over the step (v + g dt) <= cfl h / dt
        h = self.cell_size
        if vmax == 0.0 and g == 0.0:
            return self.max_dt
        dt = self.max_dt
        for _ in range(3):
            dt = min(self.max_dt, self.cfl * h / max(vmax + g * dt, 1e-12))
        return dt

    def advance(self, frame_dt, rigid=None):
        """Advance by frame_dt seconds in CFL substeps; returns the substep count. `rigid` (World
        protocol: the world's RigidWorld) couples the liquid to its bodies (`bind_rigid`) when it
        has shape rows. The world advances a liquid before its rigid stage
        (``advance_before_rigid``): the bodies are at their start-of-step poses, the liquid's
        impulses change their velocities, and the rigid stage then adds gravity and contacts and
        moves them (symplectic Euler)."""
        frame_dt = positive_scalar(frame_dt, "frame_dt")
        if rigid is not None and rigid is not self._rigid and int(rigid.model.shape_count):
            self.bind_rigid(rigid)
        done = 0.0
        n = 0
        while done < frame_dt * (1 - 1e-12):
            dt = min(self.stable_dt(), frame_dt - done)
            check_substep_runaway("liquid", n, done, frame_dt, self.cfl * self.cell_size / dt,
                                  step=self.step_index, time=self.time, dt=dt)
            self.step(dt)
            done += dt
            n += 1
        return n

    def _predict_gravity(self, dt, sign):
        """Add (sign +1) or remove (-1) g dt on the velocities of the awake dynamic bodies: the
        pressure solve sees each body with the velocity gravity gives it over the step (as the
        liquid's own faces get g dt), so a body lighter than the liquid floats stably; the rigid
        stage, which runs after the liquid, adds the same g dt itself."""
        st = self._rigid.state
        g = np.asarray(self._rigid.model.gravity, dtype=np.float64).reshape(3)
        _add_velocity(st.body_qd, self._dynamic, st.body_awake, (sign * dt) * g)

    # ------------------------------------------------------------------------ rigid coupling
    def bind_rigid(self, rigid, slip=False):
        """Couple to a rigid world (anything with ``.model`` and ``.state``; `advance` calls this).

        Every shape row of ``rigid.model`` becomes a cut-cell solid (`obstacles.rigid_obstacles`:
        a `BodyShape` at its body's live pose, v + w x r on covered faces; in 2-D its z = 0
        cross-section, bodies moving in the x-y plane), rebuilt every step while a kinematic or
        dynamic body exists. Dynamic bodies' velocities are unknowns of the pressure solve
        (`liquid_pressure.BodyCoupling`); the pressure on the closed faces of each body becomes an
        impulse dt F (and dt tau about its centre of mass), applied through
        `inertia.dynamics.particle_coupling.apply_body_impulses` (2-D: per unit length times
        `depth`). Particles inside a body are dropped. Heightfield and SDF rows are skipped.
        With viscosity > 0 and ``slip=False`` (default) the shapes are no-slip walls of the
        implicit viscosity and the viscous stress on them is added to the bodies' impulses;
        ``slip=True`` leaves only the pressure."""
        if not isinstance(slip, (bool, np.bool_)):
            raise ValueError(f"slip must be True or False; got {slip!r}")
        self._rigid_slip = bool(slip)
        from .obstacles import rigid_obstacles
        obst, owner = rigid_obstacles(rigid, self.dim)
        self._rigid = rigid
        self._rigid_obstacles = obst
        self._owners = np.concatenate([np.full(len(self.obstacles), -1, np.int64), owner])
        self._obstacles_changed()
        nb = int(rigid.model.body_count)
        self.body_force = np.zeros((nb, 3))
        self.body_torque = np.zeros((nb, 3))
        self._impulse = (np.zeros((nb, 3)), np.zeros((nb, 3)))
        self._moving = self._moving or bool(np.any(owner >= 0))
        from ...geometry import shapes as S
        bodies = rigid.model.bodies()
        self._dynamic = (np.asarray(bodies.body_type) == S.DYNAMIC) & (bodies.body_inv_mass > 0)
        self._any_dynamic = bool(np.any(self._dynamic))   # (a rigid world is bound and has one)
        self._coupling = None
        self._update_solids(self.time)
        self._drop_particles_in_solids()

    def _impulse_frame(self):
        """(origin with 2-D faces at z = 0, rho (face area) / h^2) for the body impulses."""
        h = self.cell_size
        origin = self.origin.copy()
        rho = self.density
        if self.dim == 2:
            origin[2] = -0.5 * h
            rho = self.density * self.depth / h
        return origin, rho

    def _body_coupling(self):
        """The implicit body term of the pressure solve (`liquid_pressure.BodyCoupling`), or None
        without dynamic bodies."""
        if not self._any_dynamic:
            return None
        c = self._coupling
        if c is None:   # made once per binding; the cut faces and poses are renewed every step
            bodies = self._rigid.model.bodies()
            origin, rho = self._impulse_frame()
            h = self.cell_size
            c = self._coupling = BodyCoupling(self._cut, self._dynamic, bodies.body_inv_mass,
                                              bodies.body_inv_inertia, self._rigid.state.body_q,
                                              origin, h, rho * h ** 3, self.dim)
        c.cut = self._cut
        c.body_q = self._rigid.state.body_q
        return c

    def _push_bodies(self, dt):
        """Pressure impulse on each body from its closed faces (GridFluid's `_pressure_impulses`:
        -rho (1 - A_f) (phi_R - phi_L) per unit face area, summed; in 2-D the face area is h x
        depth). Cells without liquid hold phi = 0 (air: the free-surface pressure)."""
        from ...dynamics.particle_coupling import apply_body_impulses
        from .solver import _pressure_impulses
        lin, ang = self._impulse
        lin[...] = 0.0
        ang[...] = 0.0
        h = self.cell_size
        origin, rho = self._impulse_frame()
        body_q = self._rigid.state.body_q
        for a in range(self.dim):
            faces, open_frac, body = self._cut[a]
            if faces.size:
                _pressure_impulses(self.pressure_phi, faces, open_frac, body, a, h, origin, rho,
                                   body_q, lin, ang)
        np.multiply(lin, 1.0 / dt, out=self.body_force)
        np.multiply(ang, 1.0 / dt, out=self.body_torque)
        apply_body_impulses(self._rigid.model.bodies(), self._rigid.state, lin, ang)

    # ------------------------------------------------------------------------ outputs
    def angular_momentum(self, center=None):
        """Total angular momentum about `center` (default the particles' centroid) per unit
        particle mass: z-component in 2-D, (3,) in 3-D."""
        x = self.x[:, :3]
        cen = np.mean(x, axis=0) if center is None else np.resize(np.asarray(center, float), 3)
        r = x - cen
        L = np.cross(r, self.v).sum(axis=0)
        return float(L[2]) if self.dim == 2 else L

    def kinetic_energy(self):
        """(1/2) sum |v_p|^2 per unit particle mass."""
        return 0.5 * float(np.sum(self.v * self.v))

    def level_set(self):
        """(nx, ny[, nz]) particle level set at cell centres, m (negative inside the liquid)."""
        build_surface(self.x, self.origin, self.cell_size, self.surface_radius, self.dim,
                      self.liquid, self.phi, self._periodic)
        return self.phi[:, :, 0].copy() if self.dim == 2 else self.phi.copy()

    def surface_mesh(self):
        """The liquid surface for rendering: the phi = 0 contour of the level set by
        scikit-image (marching squares in 2-D: list of (K, 2) polylines; marching cubes in
        3-D: (vertices (V, 3) m, triangles (T, 3) int)). Needs the ``surface`` extra
        (scikit-image)."""
        try:
            from skimage import measure
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("surface_mesh needs scikit-image: pip install 'inertia[surface]'") from e
        phi = self.level_set()
        h = self.cell_size
        # pad with air so surfaces touching the walls close
        big = 3.0 * h
        padded = np.pad(phi, 1, constant_values=big)
        off = self.origin[:self.dim] + 0.5 * h - h
        if self.dim == 2:
            lines = measure.find_contours(padded, 0.0)
            return [off + ln * h for ln in lines]
        verts, faces, _, _ = measure.marching_cubes(padded, 0.0, spacing=(h, h, h))
        return verts + off, faces.astype(np.int64)

    def frame_arrays(self):
        """Per-frame arrays (fixed shapes while no particle is added): positions ``x`` and
        velocities ``v`` (N, dim) float32, level set ``phi`` (nx, ny[, nz]) float32."""
        return {"x": self.x[:, :self.dim].astype(np.float32),
                "v": self.v[:, :self.dim].astype(np.float32),
                "phi": self.level_set().astype(np.float32)}

    def static_arrays(self):
        return {"origin": self.origin[:self.dim].copy(), "cell_size": np.array(self.cell_size),
                "shape": np.array(self.shape, dtype=np.int64)}

    def save_state(self):
        st = {"x": self.x.copy(), "v": self.v.copy(), "c": self.c.copy(),
              "time": np.array(self.time), "step_index": np.array(self.step_index),
              "pressure_phi": self.pressure_phi.copy(), "dt_prev": np.array(self._dt_prev),
              "inflow_travel": self._inflow_travel.copy(),
              "particle_counters": np.array([self.particles_emitted, self.particles_drained,
                                             self.particles_seeded, self.particles_removed])}
        return st

    #: state arrays whose row count (particles) may differ from a fresh fluid's (checkpoint checks)
    state_variable_rows = ("x", "v", "c")

    def check_state(self, state):
        """Raise ValueError naming the entry if ``state`` (from a checkpoint) does not fit this liquid:
        ``x``, ``v`` and ``c`` with one row per particle each and this liquid's trailing shapes, finite
        positions, a finite time and step index >= 0. Called first by ``restore_state``."""
        mine = self.save_state()
        rows = None
        for key in ("x", "v", "c"):
            if key not in state:
                raise ValueError(f"state is missing {key!r}")
            got = np.asarray(state[key])
            if got.ndim != mine[key].ndim or got.shape[1:] != mine[key].shape[1:] or got.dtype.kind != "f":
                raise ValueError(f"state[{key!r}] has shape {got.shape} and dtype {got.dtype}; this liquid needs "
                                 f"(particles,) + {mine[key].shape[1:]} floats")
            if rows is not None and got.shape[0] != rows:
                raise ValueError(f"state[{key!r}] has {got.shape[0]} rows but state['x'] has {rows}")
            rows = got.shape[0]
            if not np.all(np.isfinite(got)):
                raise ValueError(f"state[{key!r}] holds values that are not finite")
        for key in ("time", "step_index"):
            value = np.asarray(state.get(key, np.nan), dtype=float)
            if value.shape != () or not (np.isfinite(value) and value >= 0):
                raise ValueError(f"state[{key!r}] must be a finite number >= 0")

    def restore_state(self, state):
        self.check_state(state)
        self.x = np.ascontiguousarray(state["x"], dtype=np.float64).copy()
        self.v = np.ascontiguousarray(state["v"], dtype=np.float64).copy()
        self.c = np.ascontiguousarray(state["c"], dtype=np.float64).copy()
        self.time = float(state["time"])
        self.step_index = int(state["step_index"])
        # the pressure the next solve starts from (states saved without it: a cold start)
        self.pressure_phi[...] = state.get("pressure_phi", 0.0)
        self._dt_prev = float(state.get("dt_prev", 0.0))
        if "inflow_travel" in state:
            self._inflow_travel[...] = state["inflow_travel"]
        if "particle_counters" in state:
            (self.particles_emitted, self.particles_drained, self.particles_seeded,
             self.particles_removed) = (int(n) for n in state["particle_counters"])
        if self._moving:
            self._update_solids(self.time)


@njit(cache=True)
def _near_dynamic_nodes(best, near, owners, dynamic, dist, nodes, body):
    """Face nodes within `dist` of a shape of a dynamic body (best < dist, owners[near] >= 0 and
    dynamic): their flat index and body into nodes, body, in order; returns the count."""
    n = 0
    for m in range(best.shape[0]):
        b = owners[near[m]]
        if best[m] < dist and b >= 0 and dynamic[b]:
            nodes[n] = m
            body[n] = b
            n += 1
    return n


@njit(cache=True)
def _close_rows(dist, clearance, pts, idx, out):
    """Rows with dist < clearance: their index into idx and their point into out; returns the count."""
    n = 0
    for m in range(dist.shape[0]):
        if dist[m] < clearance:
            idx[n] = m
            for c in range(pts.shape[1]):
                out[n, c] = pts[m, c]
            n += 1
    return n


@njit(cache=True)
def _clamp_rows(x, lo, hi):
    """x[:, c] = clip(x[:, c], lo[c], hi[c]) in place (np.clip's values; NaN stays NaN)."""
    for p in range(x.shape[0]):
        for c in range(x.shape[1]):
            v = x[p, c]
            if v != v:
                continue
            if v < lo[c]:
                v = lo[c]
            if v > hi[c]:
                v = hi[c]
            x[p, c] = v


@njit(cache=True)
def _all_finite(a):
    """Whether every element of the 2-D array a is finite."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if not np.isfinite(a[i, j]):
                return False
    return True


@njit(cache=True)
def _add_velocity(body_qd, dynamic, awake, dv):
    """body_qd[b, 3:6] += dv for the awake dynamic bodies."""
    for b in range(body_qd.shape[0]):
        if dynamic[b] and awake[b]:
            for c in range(3):
                body_qd[b, 3 + c] += dv[c]


@njit(cache=True)
def _sum_rows_per_body(own, lin, ang, blin, bang):
    """blin[own[i]] += lin[i], bang[own[i]] += ang[i] for the rows with own[i] >= 0, in row order
    (np.add.at's sums)."""
    for i in range(own.shape[0]):
        b = own[i]
        if b >= 0:
            for c in range(3):
                blin[b, c] += lin[i, c]
                bang[b, c] += ang[i, c]


@njit(cache=True)
def _add_divided(a, dt, out):
    """out += a / dt."""
    for i in range(a.shape[0]):
        for c in range(a.shape[1]):
            out[i, c] += a[i, c] / dt
