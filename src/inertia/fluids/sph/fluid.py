"""Smoothed particle hydrodynamics: one fluid on struct-of-arrays particles, 2D or 3D.

    import inertia.fluids.sph as sph
    x = sph.sample_block((0, 0), (1, 2), spacing=0.02)
    fluid = sph.SPHFluid(x, spacing=0.02, domain=((0, 0), (4, 3)), method="dfsph")
    fluid.add_boundary(ia.colliders.Container(center=(2, 1.5), half_extents=(2, 1.5)))
    for _ in range(1000):
        fluid.step()                      # adaptive dt (CFL, viscosity); returns the dt taken
    fluid.x, fluid.v                      # (n, D) views of the live particles (cell order!)

The step (``SPHFluid.step``), each stage timed in ``fluid.profile``:

1. ``sort``: bin the fluid particles into the domain grid, counting sort, reorder every
   per-particle array into cell order (outflow: particles outside the domain or inside an
   outflow box are dropped here). Moving bodies: move and re-sort their boundary particles.
2. ``neighbours``: CSR lists fluid-fluid and fluid-boundary with W and grad W per pair.
3. ``density``: rho by summation (fluid + boundary), the DFSPH factor.
4. ``dt``: adaptive time step (CFL with gravity, explicit viscosity, WCSPH acoustic limit).
5. ``divergence`` (DFSPH): make d rho/dt vanish (Bender & Koschier 2017, algorithm 2),
   optionally warm-started (``warm_start_divergence``).
6. ``forces``: gravity, viscosity, surface tension; v += dt a; implicit viscosity solve; XSPH.
7. ``pressure``: DFSPH constant-density solve to ``density_tolerance`` (mean, algorithm 3) and
   ``local_density_tolerance`` (largest compression), or the WCSPH Tait pressure force
   (Becker & Teschner 2007). An unconverged DFSPH solve halves the next adaptive steps; in
   steps shorter than the CFL step at the flow's speed scale the compression present at the
   start is removed at a proportionally lower rate (see ``_solve``).
8. ``bodies``: force and torque of the fluid on every body (``body_force``, ``body_torque``).
9. ``advect``: x += dt v (symplectic Euler), periodic wrap; emitters spawn; finite check.

Runaway detection (before the step): a particle faster than ``runaway_speed`` (10x the flow's
speed scale) or an adaptive step below 1e-3 of the CFL step at that scale raises
``SimulationDiverged`` naming the step, the fastest particles and the likely cause: a blow-up
whose values stay finite (the dam break at 200 rows collapsed to 1e-6 s steps without a NaN).

References
----------
- Becker, M. & Teschner, M. (2007), "Weakly compressible SPH for free surface flows", SCA:
  Tait equation of state with gamma = 7, sound speed from the tolerated density variation
  (|drho|/rho0 ~ v^2 / c^2).
- Bender, J. & Koschier, D. (2015), "Divergence-free smoothed particle hydrodynamics", SCA;
  (2017), "Divergence-free SPH for incompressible and viscous fluids", IEEE TVCG 23(3):
  the DFSPH factor, the divergence and constant-density solvers, warm starting.
- Akinci, N., Ihmsen, M., Akinci, G., Solenthaler, B. & Teschner, M. (2012), "Versatile rigid-
  fluid coupling for incompressible SPH", ACM TOG 31(4): boundary particles contributing
  psi_b W to the density, pressure mirrored onto them, reaction forces and torques on bodies.
- Adami, S., Hu, X. Y. & Adams, N. A. (2012), "A generalized wall boundary condition for
  smoothed particle hydrodynamics", J. Comput. Phys. 231: the wall pressure extrapolated from
  the fluid (Shepard average plus the body force): the wall's hydrostatic share of the default
  "mirror" boundary pressure (pairwise), and the "extrapolated" mode.
- Akinci, N., Akinci, G. & Teschner, M. (2013), "Versatile surface tension and adhesion for SPH
  fluids", ACM TOG 32(6): cohesion kernel and curvature (normal difference) force.
- Monaghan, J. J. (2005), "Smoothed particle hydrodynamics", Rep. Prog. Phys. 68, and Morris,
  J. P., Fox, P. J. & Zhu, Y. (1997), "Modeling low Reynolds number incompressible flows using
  SPH", J. Comput. Phys. 136: the laminar viscosity term and its step limit 0.125 h^2 / nu.
- Monaghan, J. J. (1989), "On the problem of penetration in particle methods", J. Comput.
  Phys. 82: XSPH.
- Weiler, M., Koschier, D., Brand, M. & Bender, J. (2018), "A physically consistent implicit
  viscosity solver for SPH fluids", Computer Graphics Forum 37(2): implicit viscosity by CG.
- Ihmsen, M., Cornelis, J., Solenthaler, B., Horvath, C. & Teschner, M. (2014), "Implicit
  incompressible SPH", IEEE TVCG 20(3): relaxed Jacobi (omega = 0.5) for the pressure system.
- Polyak, B. T. (1964), "Some methods of speeding up the convergence of iteration methods", USSR
  Comput. Math. Math. Phys. 4(5) (heavy-ball momentum), and O'Donoghue, B. & Candes, E. (2015),
  "Adaptive restart for accelerated gradient schemes", Found. Comput. Math. 15: the momentum
  schedule k / (k + 3) and its restart in the constant-density solve (``SPHFluid._solve``).

Limitations
-----------
- One fluid phase with one particle mass; no multiphase, no adaptive particle sizes.
- Boundaries are bands of particles on the fluid's lattice, one kernel support thick, with the
  lattice volume (not Akinci's single-layer volume estimate, which over-weights the inner layer
  of a thick band): thin shapes (thinner than the band) are sampled fully, shapes thinner than
  one spacing vanish. Surfaces are staircased at the spacing; ``slip`` boundaries drop only the
  viscous term (the pressure term still acts along the lattice normal).
- Viscosity: explicit (step limit 0.125 h^2/nu) or implicit (``implicit_viscosity``; Weiler et
  al. 2018's matrix-free CG, here with the laminar operator and a scalar Jacobi preconditioner,
  not their strain-rate formulation with block preconditioning). Adhesion (Akinci 2013, eq. 7)
  is not implemented. Surface tension has no time-step limit of its own.
- The constant-density solve's momentum is a rescue for long, creeping solves (``_solve``): with
  the defaults the 20-row hydrostatic column's longest solve took 99 of the 100 iterations
  (measured); a taller column at rest may need a larger ``max_iterations``. A preconditioned
  Krylov solve of the pressure system (with the p >= 0 projection) is not implemented.
- The DFSPH error is the mean over all particles (as in the paper): below the surface layers
  the compression is ~1.7x the tolerance (measured, hydrostatic column); the largest one is
  bounded separately (``local_density_tolerance``, default 10x).
- Boundary pressure: DFSPH's default "mirror" (k_b = k_i plus the wall's hydrostatic share, pairwise,
  without the wall's acceleration) holds the floor row at rho0 g (H - y); Akinci's single term
  leaves it at ~1.7x; "extrapolated" (Adami et al. 2012's wall pressure, wall-normal body force
  only) compresses the start of a tall column more (see ``boundary_pressure``). Band et al. 2018's
  linear MLS fit was tried and ran away (with the cubic spline at h = dx a wall particle sees one
  row of fluid: the fit is degenerate or amplifies the noise of the iteration). The rows within
  one support of a free surface alternate by a few % (time average).
- DFSPH: a block given without velocities starts with its hydrostatic pressure
  (``hydrostatic_pressure``, the warm start of the first constant-density solve; the solve removes
  what a block not at rest, e.g. in free fall, does not need); with velocities, from zero. Only
  the body force across the periodic axes enters it (along a periodic axis the fluid accelerates
  freely; a flow driven only along one starts from zero).
- Body coupling is explicit (the body integrates the force of the step it was posed for).
- Bodies are sampled as bands one support thick: fluid that gets deeper into a moving body's
  sphere, box, capsule, cylinder or convex hull is pushed out through the nearest face after the
  advection (``kernels.push_out_of_cores``, the shapes' signed distances); meshes are not
  covered. The adaptive step does not see the bodies' speeds (a fast body may cross a band in one
  step).
- Particles are reordered every step: ``x``, ``v`` rows move; ``particle_id`` follows them.
- The domain grid is dense: its cell count is capped at ``MAX_CELLS``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ... import _validate
from ...collision import broadphase as _bp
from ...collision import distance as _dist
from ...dynamics.particle_coupling import apply_body_impulses
from ...errors import SimulationDiverged
from . import kernels as _k
from . import neighbours as _nb
from .smoothing import SMOOTHING_RANGE, kernel_id, kernel_norm, kernel_value
from .smoothing import kernel_gradient as _kernel_gradient

__all__ = ["SPHFluid", "sample_block", "METHODS"]

METHODS = ("dfsph", "wcsph")
MAX_CELLS = 1 << 26
TAIT_EXPONENT = 7.0
RELAXATION = 0.5  # relaxed Jacobi for the DFSPH solves (see kernels.pressure_increment)
# momentum of the constant-density solve (see SPHFluid._solve): engaged after RESCUE_SHARE of
# max_iterations once the plain relaxed Jacobi creeps (CREEP_ITERATIONS iterations in a row each
# removing less than 1 - CREEP of the mean error); iteration k after that carries
# min(MOMENTUM_MAX, k / (k + 3)) of the previous increment
MOMENTUM_MAX = 0.5
RESCUE_SHARE = 0.5
CREEP = 0.97
CREEP_ITERATIONS = 3
UNCONVERGED_SHRINK = 0.5
# a step after which more than this share of the fluid (and at least ESCAPE_MIN particles) lies
# beyond the domain bounds raised SimulationDiverged (see SPHFluid._check_escaped)
ESCAPE_SHARE = 0.25
ESCAPE_MIN = 8
# weight of k_i in the boundary term (see SPHFluid)
BOUNDARY_PRESSURE = {"extrapolated": 1.0, "akinci": 1.0, "mirror": 2.0}  # weight of k_i in the boundary term (see SPHFluid)
# the default boundary pressure of each method (``SPHFluid(boundary_pressure=None)``): WCSPH's Tait pressure
# is the state equation of a density that already counts the wall's particles, and mirrored (2 k_i) its
# noise throws spray up the walls (see the SPHFluid docstring)
DEFAULT_BOUNDARY_PRESSURE = {"dfsph": "mirror", "wcsph": "akinci"}


def _lattice(lo, hi, spacing, origin=None):
    """Points origin + (i + 1/2) spacing (per axis) inside [lo, hi)."""
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    origin = lo if origin is None else np.asarray(origin, float)
    axes = []
    for d in range(lo.shape[0]):
        i0 = math.ceil((lo[d] - origin[d]) / spacing - 0.5 - 1e-9)
        i1 = math.floor((hi[d] - origin[d]) / spacing - 0.5 - 1e-9)
        axes.append(origin[d] + (np.arange(i0, i1 + 1) + 0.5) * spacing)
    grids = np.meshgrid(*axes, indexing="ij")
    return np.ascontiguousarray(np.stack([g.ravel() for g in grids], axis=1))


def _unit_rows(v):
    v = np.asarray(v, float)
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)


def sample_block(lo, hi, spacing: float) -> np.ndarray:
    """Fluid particles on the square/cubic lattice lo + (i + 1/2) spacing inside the box [lo, hi)
    (M, D) [m]; the lattice the solver's boundary sampling uses too."""
    lo = _validate.as_vector(lo, "lo")
    hi = _validate.as_vector(hi, "hi", lo.shape[0])
    spacing = _validate.positive_scalar(spacing, "spacing")
    if np.any(hi <= lo):
        raise ValueError(f"hi must be > lo on every axis; got lo={lo.tolist()}, hi={hi.tolist()}")
    return _lattice(lo, hi, spacing)


def hydrostatic_pressure(x, gravity, spacing, rest_density):
    """p_i = rho0 |g| (s_i - z_i) [Pa]: the hydrostatic pressure of particles x (N, D) at rest, z the
    height against gravity and s the free surface above the particle, half a spacing over the
    highest particle of its lateral column (columns one spacing wide across gravity)."""
    x = np.asarray(x, float)
    gmag = float(np.linalg.norm(gravity))
    up = -np.asarray(gravity, float) / gmag
    z = x @ up
    lateral = x - z[:, None] * up
    keys = np.round(lateral / spacing).astype(np.int64)
    _, column = np.unique(keys, axis=0, return_inverse=True)
    column = column.reshape(-1)
    top = np.full(int(column.max()) + 1, -np.inf)
    np.maximum.at(top, column, z)
    return rest_density * gmag * (top[column] + 0.5 * spacing - z)


def lattice_volume(kernel: str, dim: int, spacing: float, h: float) -> float:
    """1 / sum_j W(x_j) over the infinite lattice of the spacing (including the centre): the
    volume per particle that makes the summed density exactly rho0 inside a lattice block."""
    reach = int(math.ceil(2 * h / spacing)) + 1
    axis = np.arange(-reach, reach + 1) * spacing
    pts = np.stack([g.ravel() for g in np.meshgrid(*([axis] * dim), indexing="ij")], axis=1)
    return 1.0 / float(kernel_value(kernel, pts, h).sum())


def lattice_shear_response(kernel: str, dim: int, spacing: float, h: float, shifts: int = 64) -> float:
    """The viscosity term's response to the shear flow u_x = y^2 / 2 (for which nu lap u = nu),
    per unit nu, at a particle of the lattice (lattice volume) whose other rows (y != 0) are
    shifted along x by s, averaged over s in [0, dx): rows slide past each other in a shear flow.
    The continuous operator gives 1; the cubic spline with h = dx gives 0.75 in 2D (0.66 for the
    aligned lattice). ``SPHFluid`` divides the viscosity by it (a calibration of the discrete
    operator at the particle spacing, like the lattice volume of the mass)."""
    volume = lattice_volume(kernel, dim, spacing, h)
    reach = int(math.ceil(2 * h / spacing)) + 1
    axis = np.arange(-reach, reach + 1) * spacing
    base = np.stack([g.ravel() for g in np.meshgrid(*([axis] * dim), indexing="ij")], axis=1)
    total = 0.0
    for s in (np.arange(shifts) + 0.5) / shifts * spacing:
        pts = base.copy()
        pts[pts[:, 1] != 0.0, 0] += s
        pts = pts[np.any(pts != 0.0, axis=1)]
        rel = -pts                                   # x_i - x_j with x_i at the origin
        grad = _kernel_gradient(kernel, rel, h)
        v_rel = -0.5 * pts[:, 1] ** 2                # (v_i - v_j)_x for u_x = y^2 / 2
        r2 = (rel ** 2).sum(axis=1)
        total += 2 * (dim + 2) * volume * (v_rel * rel[:, 0] / (r2 + 0.01 * h * h) * grad[:, 0]).sum()
    return float(total / shifts)


class SPHFluid:
    """A single-phase SPH fluid (see the module docstring for the step and the references).

    Parameters
    ----------
    positions : (N, D) array [m]
        Initial particles, D = 2 or 3, on a lattice of ``spacing`` (``sample_block``).
    spacing : float [m]
        Particle spacing dx; the particle volume is the lattice volume (about dx^D).
    domain : (lo, hi) pair of D-vectors [m]
        The simulation box. Fluid particles more than one kernel support outside it
        (non-periodic axes) are removed.
    method : "dfsph" (default) or "wcsph".
    kernel : "cubic_spline" (default) or "wendland_c2".
    smoothing_length : float [m]
        h, support 2h; default 1.0 dx (cubic spline) / 1.2 dx (Wendland); allowed
        ``SMOOTHING_RANGE`` times dx.
    velocities : (N, D) array [m/s], default 0.
    rest_density : float [kg/m^3], default 1000.
    gravity : D-vector [m/s^2], default (0, -9.81) / (0, 0, -9.81). Any body force per unit mass.
    viscosity : float [m^2/s], kinematic, default 0 (explicit; step limit 0.125 h^2/nu).
    xsph : float, default 0 (XSPH epsilon; 0.01-0.1 smooths the velocity field).
    surface_tension : float, default 0: Akinci 2013 gamma (the cohesion force scales with
        gamma m^2 / H^(D+1)... so the useful range depends on the spacing; 2D, dx = 0.01 m:
        0.001-0.02 rounds a 0.2 m drop in 0.5 s, 0.5 bursts it; no time-step limit is derived).
    periodic : D bools, default all False.
    density_tolerance : float, default 1e-3 (0.1 %): DFSPH stops when the mean compression
        (rho* - rho0)+ / rho0 is below it; WCSPH sets its sound speed from it
        (c = max_speed / sqrt(tolerance)).
    divergence_tolerance : float, default 1e-3: DFSPH divergence solve, mean (drho/dt)+ dt / rho0.
    max_iterations : int, default 100 (per DFSPH solve; 2 minimum). A block at rest starts with
        its hydrostatic pressure (1-3 iterations per solve for the first steps of a 20-row column;
        from zero pressure up to ~140). The constant-density solve is a relaxed Jacobi with
        momentum (see ``_solve``): the 20-row hydrostatic column meets the default tolerance in
        every step over 10 s with 20.2 iterations per step on average, 99 at most (measured; the
        plain relaxed Jacobi crept towards it and missed it within 100 in ~1 % of the steps).
    max_speed : float [m/s], WCSPH only: the largest expected flow speed; default
        sqrt(2 |g| H) with H the fluid's initial extent along gravity.
    dt : float [s] or None: fixed step (checked against the CFL/viscosity/acoustic limits
        at max_speed), or None for adaptive steps.
    cfl : float, default 0.4 (fraction of dx a particle may travel per step).
    dt_max : float [s], default 0.005.
    capacity : int, default N (rows preallocated; emitters need more).
    divergence_solve : bool, default True (DFSPH: run the divergence-free solve).
    implicit_viscosity : bool, default False: solve the viscosity implicitly (Weiler et al.
        2018: (I - dt nu L) v = v*, conjugate gradients, relative residual 1e-6) so that its
        step limit 0.125 h^2 / nu no longer applies (honey, lava; nu >~ 0.01 m^2/s at dx ~ 1 cm).
    local_density_tolerance : float, default 10 x density_tolerance (1 %): DFSPH also iterates
        until no particle is compressed by more than this (the mean criterion alone lets the
        bottom rows of a tall column be compressed by several % while the mean is met). A solve
        that misses either tolerance within ``max_iterations`` halves the next adaptive steps
        (they grow back by 10 % per converged step).
    runaway_speed : float [m/s] or None: a particle faster than this raises
        ``SimulationDiverged`` (a blow-up caught while the values are still finite); default 10 x
        the flow's speed scale max(max_speed, sqrt(2 |g| domain height), initial speeds,
        spacing / dt_max). Also raised: an adaptive step below 1e-3 of ``cfl spacing /
        speed scale``.
    boundary_pressure : "mirror", "akinci" or "extrapolated"; default None: "mirror" for DFSPH,
        "akinci" for WCSPH. The pressure of the
        boundary particles b in the symmetric pressure term -sum_b psi_b (k_i + k_b) grad W_ib.
        WCSPH defaults to Akinci's single term: its Tait pressure is the state equation of a
        density that already counts the wall's particles, and the mirror (2 k_i) answers the
        noise of that stiff pressure twice; in the inviscid 2-D dam break (a = 0.2 m, dx = a / 20)
        it threw spray up the wall the column stood against and the residual height stood 0.1-1.2
        of 2a above Martin & Moyce's at T = 3.1-4.8 (runs at cfl 0.4, 0.2 and 0.1 alike), where
        Akinci's term stays within 0.05 (tested).
        "mirror": k_b = k_i (pressure mirroring) plus the wall's hydrostatic share once per step
        (``kernels.boundary_hydrostatic_kick``, Adami et al. 2012 pairwise; a particle without
        pressure takes only its wall-normal part); the DFSPH factor keeps Akinci's diagonal
        |a + b|^2 (see ``step``). Hydrostatic column over 1-10 s (defaults): every row below the
        surface layers within 5 % of rho0 g (H - y), floor load within 5 % of the weight (tested).
        "extrapolated": k_b = p_b / rho0^2 with p_b the Shepard average of the neighbouring fluid
        pressures plus the wall-normal body-force share rho (g . n_b)(n_b . (x_b - x_f)) (Adami,
        Hu & Adams 2012, normal part only), applied with the warm start of each DFSPH solve; the
        solver's increments mirrored (k_b = k_i), a fluid particle seeing at most the mirror's
        k_i + hydrostatic share; see ``kernels``. Hydrostatic column: floor row 1.04, rows
        0.97-1.05 (1-4 s); 20 000-particle dam break to T = 3 with the front within the coarse
        test's bounds with max_iterations=300 (measured). Not the default: a 200-row column
        from rest compressed by 12 % in its start transient (before the hydrostatic start).
        "akinci": k_b = 0, a_i = -k_i sum_b psi_b grad W_ib (Akinci et al. 2012, as
        SPlisHSPlasH's DFSPH): a wall carries its load with half the per-unit-pressure push, so
        the fluid row on a floor holds ~1.7x rho0 g (H - y).
    warm_start_divergence : bool, default False: start the divergence solve from the previous
        step's k (Bender & Koschier 2017; the density solve always is). At rest the two solves
        then share the hydrostatic load, but in the
        20 000-particle dam break it shot surface particles at the wall out at 100+ m/s at
        t = 0.33 s (measured; without it the run reaches T = 3), hence off by default.
    """

    def __init__(self, positions, *, spacing, domain, method="dfsph", kernel="cubic_spline",
                 smoothing_length=None, velocities=None, rest_density=1000.0, gravity=None,
                 viscosity=0.0, xsph=0.0, surface_tension=0.0, periodic=None, density_tolerance=1e-3,
                 divergence_tolerance=1e-3, max_iterations=100, max_speed=None, dt=None, cfl=0.4,
                 dt_max=0.005, capacity=None, divergence_solve=True, implicit_viscosity=False,
                 local_density_tolerance=None, runaway_speed=None, boundary_pressure=None,
                 warm_start_divergence=False):
        x0 = _validate.as_points(positions, "positions")
        n, dim = x0.shape
        self.dim = dim
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}; got {method!r}")
        self.method = method
        self.kernel_name = kernel
        self.kernel = kernel_id(kernel)
        self.spacing = _validate.positive_scalar(spacing, "spacing")
        lo_r, hi_r = SMOOTHING_RANGE[kernel]
        h = (1.0 if kernel == "cubic_spline" else 1.2) * self.spacing if smoothing_length is None else \
            _validate.positive_scalar(smoothing_length, "smoothing_length")
        if not lo_r * self.spacing - 1e-12 <= h <= hi_r * self.spacing + 1e-12:
            raise ValueError(f"smoothing_length must lie in [{lo_r}, {hi_r}] x spacing for the {kernel} "
                             f"kernel ([{lo_r * self.spacing:g}, {hi_r * self.spacing:g}] m); got {h:g} m")
        self.h = h
        self.support = 2.0 * h
        self.rest_density = _validate.positive_scalar(rest_density, "rest_density")
        try:
            lo, hi = domain
        except (TypeError, ValueError):
            raise ValueError("domain must be a pair (lo, hi) of D-vectors") from None
        lo = _validate.as_vector(lo, "domain lo", dim)
        hi = _validate.as_vector(hi, "domain hi", dim)
        if np.any(hi - lo < self.spacing):
            raise ValueError(f"domain must be at least one spacing ({self.spacing:g} m) wide on every axis; "
                             f"got lo={lo.tolist()}, hi={hi.tolist()}")
        self.domain_lo, self.domain_hi = lo, hi
        outside = np.any((x0 < lo) | (x0 >= hi), axis=1)
        if np.any(outside):
            raise ValueError(f"positions must lie inside the domain; rows {np.flatnonzero(outside)[:10].tolist()} "
                             f"are outside [{lo.tolist()}, {hi.tolist()})")
        periodic = np.zeros(dim, bool) if periodic is None else np.asarray(periodic, bool).reshape(-1)
        if periodic.shape != (dim,):
            raise ValueError(f"periodic must have {dim} booleans (one per axis); got {periodic.tolist()}")
        self.periodic = periodic
        g = np.zeros(dim)
        g[dim - 1] = -9.81
        self.gravity = g if gravity is None else _validate.as_vector(gravity, "gravity", dim)
        self.viscosity = _validate.positive_scalar(viscosity, "viscosity", allow_zero=True)
        self.xsph = _validate.positive_scalar(xsph, "xsph", allow_zero=True)
        if self.xsph > 0.5:
            raise ValueError(f"xsph must lie in [0, 0.5]; got {xsph}")
        self.surface_tension = _validate.positive_scalar(surface_tension, "surface_tension", allow_zero=True)
        self.density_tolerance = _validate.positive_scalar(density_tolerance, "density_tolerance")
        self.divergence_tolerance = _validate.positive_scalar(divergence_tolerance, "divergence_tolerance")
        if self.density_tolerance >= 0.1:
            raise ValueError(f"density_tolerance must be < 0.1 (10 %); got {density_tolerance}")
        if int(max_iterations) != max_iterations or max_iterations < 2:
            raise ValueError(f"max_iterations must be an integer >= 2; got {max_iterations!r}")
        self.max_iterations = int(max_iterations)
        self.cfl = _validate.positive_scalar(cfl, "cfl")
        if self.cfl > 1.0:
            raise ValueError(f"cfl must lie in (0, 1]; got {cfl}")
        self.dt_max = _validate.positive_scalar(dt_max, "dt_max")
        capacity = n if capacity is None else int(capacity)
        if capacity < n:
            raise ValueError(f"capacity must be >= the number of particles ({n}); got {capacity}")
        self.capacity = capacity

        # --- particle constants: lattice volume, mass
        self.volume = lattice_volume(kernel, dim, self.spacing, h)
        self.mass = self.rest_density * self.volume
        self._w0 = float(kernel_norm(self.kernel, dim, h))  # W(0) = sigma for both kernels
        self._visc_scale = 1.0 / lattice_shear_response(kernel, dim, self.spacing, h)
        self._factor_eps = 1e-9 * (self.mass * self._w0 / h) ** 2

        # --- WCSPH sound speed and fixed-step checks
        gmag = float(np.linalg.norm(self.gravity))
        if max_speed is None:
            extent = float(np.ptp(x0 @ (-self.gravity / gmag))) + self.spacing if gmag > 0 and n else self.spacing
            max_speed = math.sqrt(2.0 * max(gmag, 1e-12) * extent)
        self.max_speed = _validate.positive_scalar(max_speed, "max_speed")
        self.sound_speed = self.max_speed / math.sqrt(self.density_tolerance)
        self.tait_stiffness = self.rest_density * self.sound_speed ** 2 / TAIT_EXPONENT
        self.divergence_solve = bool(divergence_solve)
        self.implicit_viscosity = bool(implicit_viscosity)
        self.local_density_tolerance = 10.0 * self.density_tolerance if local_density_tolerance is None else \
            _validate.positive_scalar(local_density_tolerance, "local_density_tolerance")
        if self.local_density_tolerance < self.density_tolerance:
            raise ValueError(f"local_density_tolerance must be >= density_tolerance ({self.density_tolerance:g}); "
                             f"got {local_density_tolerance}")
        # speed scale of the flow: a particle at 10x it, or a step 1e-3 of the CFL step at it, is a blow-up
        height = float(np.abs((hi - lo) @ (self.gravity / gmag))) if gmag > 0 else 0.0
        v0 = 0.0 if velocities is None else float(np.sqrt((np.asarray(velocities, float) ** 2).sum(axis=1).max(
            initial=0.0)))
        self.speed_scale = max(self.max_speed, math.sqrt(2.0 * gmag * height), v0, self.spacing / self.dt_max)
        self.runaway_speed = 10.0 * self.speed_scale if runaway_speed is None else \
            _validate.positive_scalar(runaway_speed, "runaway_speed")
        self.min_dt = 1e-3 * self.cfl * self.spacing / self.speed_scale
        self._dt_ref = self.cfl * self.spacing / self.speed_scale
        if boundary_pressure is None:   # per method: see the docstring
            boundary_pressure = DEFAULT_BOUNDARY_PRESSURE[method]
        if boundary_pressure not in BOUNDARY_PRESSURE:
            raise ValueError(f"boundary_pressure must be one of {sorted(BOUNDARY_PRESSURE)}; got {boundary_pressure!r}")
        self.boundary_pressure = boundary_pressure
        self._mirror = BOUNDARY_PRESSURE[boundary_pressure]
        # "extrapolated": the warm-start totals push with k_i + the extrapolated k_b (bfac 1 plus
        # boundary_pressure_kick), the solver's increments with the mirror (bfac 2)
        self._bfac_iter = 2.0 if boundary_pressure == "extrapolated" else self._mirror
        self._g3 = np.zeros(3)
        self._g3[:dim] = self.gravity
        self._hydrostatic_wall = boundary_pressure == "mirror"   # Adami et al.'s wall share comes with the mirror
        self._extrapolated = boundary_pressure == "extrapolated"   # Adami et al. 2012's wall pressure
        self.warm_start_divergence = bool(warm_start_divergence)
        self._dt_scale = 1.0  # adaptive-step factor of the DFSPH convergence control (saved in the state)
        self.fixed_dt = None
        if dt is not None:
            dt = _validate.positive_scalar(dt, "dt")
            limit = self._dt_limit(self.max_speed)
            if dt > limit * (1 + 1e-12):
                raise ValueError(f"dt = {dt:g} s is above the stability limit {limit:g} s of this fluid "
                                 f"(CFL {self.cfl} at max_speed {self.max_speed:g} m/s"
                                 f"{', acoustic at c = %g m/s' % self.sound_speed if method == 'wcsph' else ''}"
                                 f"{', viscous 0.125 h^2/nu' if self.viscosity > 0 else ''}); lower dt or pass dt=None")
            self.fixed_dt = dt

        # --- grid over the domain
        cell = np.ones(3)
        dims = np.ones(3, np.int64)
        length = np.ones(3)
        lo3 = np.zeros(3)
        lo3[:dim] = lo
        length[:dim] = hi - lo
        for d in range(dim):
            # cells at least support / REACH wide (a block of 2 REACH + 1 cells holds the support)
            if periodic[d] and length[d] < 3 * self.support * (1 - 1e-9):
                raise ValueError(f"periodic axis {d} must be at least 3 kernel supports long "
                                 f"({3 * self.support:g} m); the domain is {length[d]:g} m")
            cells = max(1, int(math.floor(length[d] * _nb.REACH / self.support + 1e-9)))
            dims[d] = cells if periodic[d] else cells + 1
            cell[d] = length[d] / cells
        if int(np.prod(dims)) > MAX_CELLS:
            raise ValueError(f"domain holds {int(np.prod(dims))} grid cells of {self.support / _nb.REACH:g} m, "
                             f"more than {MAX_CELLS}; shrink the domain or increase spacing")
        self.grid = _nb.Grid(lo3, length, 1.0 / cell, dims, np.concatenate([periodic, np.zeros(3 - dim, bool)]))
        self._ncells = int(np.prod(dims))

        # --- state (sorted space; rows [0, n) live)
        cap = capacity
        self._n = n
        z = np.zeros
        self._F = _k.FluidArrays(z((cap, dim)), z((cap, dim)), z(cap), z(cap), z(cap), z(cap), z(cap), z(cap),
                                 z((cap, dim)), z((cap, dim)), z((cap, dim)))
        self._F.x[:n] = x0
        if velocities is not None:
            self._F.v[:n] = _validate.as_points(velocities, "velocities", dim=dim, count=n)
        elif method == "dfsph" and gmag > 0 and n:
            # a block at rest starts with its hydrostatic pressure as the warm start of the first
            # constant-density solve (from zero, the first solves of a 20-row column needed up to ~140
            # iterations, 1-3 with it; a 200-row column was compressed by 8-10 % in its first steps).
            # Only the body force across the periodic axes has a hydrostatic balance: along a periodic
            # axis the fluid accelerates freely (a pressure ramp along it jumps at the seam: in a
            # channel driven along its periodic axis that jump threw the fluid across the channel)
            g_static = np.where(self.periodic, 0.0, self.gravity)
            if np.any(g_static != 0.0):
                self._F.k_dens[:n] = hydrostatic_pressure(x0, g_static, self.spacing, self.rest_density) / \
                    self.rest_density ** 2
        self._id = np.full(cap, -1, np.int64)
        self._id[:n] = np.arange(n)
        self._next_id = n
        self._cell_of = np.empty(cap, np.int64)
        self._order = np.empty(cap, np.int64)
        self._cell_start = np.zeros(self._ncells + 2, np.int64)
        self._tmp2 = np.empty((cap, dim))
        self._tmp1 = np.empty(cap)
        self._tmpi = np.empty(cap, np.int64)
        self._count = np.empty(cap, np.int64)
        self._nf = self._alloc_neighbours(cap, 32 * cap if dim == 3 else 16 * cap)
        self._nbn = self._alloc_neighbours(cap, 4 * cap)
        # one-pass neighbour search rows: 1.5x the neighbours of a lattice particle + 8
        reach = 2.0 * h / self.spacing
        self._stride = int(1.5 * (math.pi * reach ** 2 if dim == 2 else 4.0 / 3.0 * math.pi * reach ** 3)) + 8
        self._strided = self._alloc_strided(self._stride)
        self._no_wg = (np.zeros(1), np.zeros((1, dim)))   # fill_strided's unwritten W / grad W placeholders
        self._partial = np.zeros((_k.REDUCE_CHUNKS, 2))
        if implicit_viscosity:
            self._cg = tuple(np.zeros((cap, dim)) for _ in range(5)) + (np.ones(cap),)
        self._red = np.zeros(2)
        self._outflow_lo = np.zeros((0, 3))
        self._outflow_hi = np.zeros((0, 3))
        self._emitters = []

        # --- boundaries (finalised on the first step)
        self._boundary_parts = []  # (x (M, D), body, noslip nu, local (M, D))
        self._bodies = []          # (initial centre (3,), initial rotation (3, 3)) per body
        self._B = None
        self._rigid_model = None
        self._pending_state = None
        self.body_force = np.zeros((0, 3))
        self.body_torque = np.zeros((0, 3))
        self._cores = []           # (body, distance kind, cf, ci) in the body frame (coupling.solid_cores)

        self.time = 0.0
        self.step_count = 0
        self.last_dt = 0.0
        self.profile = {}
        self.stats = {"density_iterations": 0, "density_error": 0.0, "divergence_iterations": 0,
                      "divergence_error": 0.0, "max_speed": 0.0, "neighbours_per_particle": 0.0}

    # ------------------------------------------------------------------ public views
    @property
    def particle_count(self) -> int:
        """Number of live fluid particles."""
        return self._n

    @property
    def x(self) -> np.ndarray:
        """(n, D) [m] positions of the live particles, a view in cell order (rows move each step:
        use ``particle_id``; ``.copy()`` to keep)."""
        return self._F.x[:self._n]

    @property
    def v(self) -> np.ndarray:
        """(n, D) [m/s] velocities, a view like ``x``."""
        return self._F.v[:self._n]

    @property
    def particle_id(self) -> np.ndarray:
        """(n,) int64: the creation index of each row (0..N-1 initial, then emitted ones)."""
        return self._id[:self._n]

    @property
    def density(self) -> np.ndarray:
        """(n,) [kg/m^3] summed density at the start of the last step (view)."""
        return self._F.rho[:self._n]

    @property
    def pressure(self) -> np.ndarray:
        """(n,) [Pa] pressure of the last step, p = k rho^2 (a new array): DFSPH the sum of the
        divergence and constant-density solves' k (both act on the velocity every step and
        share the hydrostatic load, Bender & Koschier 2017); WCSPH the Tait pressure."""
        n = self._n
        k = self._F.k_dens[:n] + self._F.k_div[:n] if self.method == "dfsph" else self._F.k_dens[:n]
        return k * self._F.rho[:n] ** 2

    @property
    def boundary_x(self) -> np.ndarray:
        """(Nb, D) [m] boundary particle positions (sorted order, view); empty before the first step."""
        return np.zeros((0, self.dim)) if self._B is None else self._B.x

    # ------------------------------------------------------------------ building
    def add_boundary(self, collider, *, slip=False, boundary_viscosity=None):
        """Sample a static collider's solid (signed distance < 0) with boundary particles: the
        fluid lattice's points within one kernel support of the surface, inside the domain
        grown by one support. ``slip``: no viscous coupling to the wall; otherwise no-slip with
        ``boundary_viscosity`` [m^2/s] (default: the fluid's viscosity, or 1e-3 * spacing * max
        speed when the fluid is inviscid). Returns the number of particles added."""
        grow = np.where(self.periodic, 0.0, self.support)  # a periodic axis holds each point once
        pts = self._band(collider, self.domain_lo - grow, self.domain_hi + grow, origin=self.domain_lo)
        self._add_part(pts, -1, self._noslip(slip, boundary_viscosity), np.zeros_like(pts),
                       _unit_rows(collider.normal(pts)) if pts.shape[0] else np.zeros_like(pts))
        return pts.shape[0]

    def add_body(self, collider, *, slip=False, boundary_viscosity=None) -> int:
        """Sample a Box or Sphere collider as a moving body's boundary (lattice in the body frame,
        centred on the collider's centre) and return the body index. Move it with
        ``set_body_state``; read the fluid's ``body_force`` / ``body_torque`` after each step."""
        from ...collision.shapes import Box, Sphere
        from .coupling import fitted_box_lattice
        if isinstance(collider, Box):
            half = np.asarray(collider.half_extents, float)
        elif isinstance(collider, Sphere):
            half = np.full(self.dim, float(collider.radius))
        else:
            raise ValueError(f"collider must be a Box or Sphere for a body; got {type(collider).__name__}")
        if collider.dim != self.dim:
            raise ValueError(f"collider must be {self.dim}-D like the fluid; got {collider.dim}-D")
        p, rot = collider.pose(0.0)
        rot = rot[:self.dim, :self.dim]
        if isinstance(collider, Box):  # faces half a cell outside the outer layer
            local = fitted_box_lattice(half, self.spacing)
        else:
            local = _lattice(-half, half, self.spacing, origin=np.zeros(self.dim) - 0.5 * self.spacing *
                             (np.round(2 * half / self.spacing) % 2))
        world = p[:self.dim] + local @ rot.T
        sd = collider.signed_distance(world)
        keep = (sd < 0) & (sd >= -self.support)
        body = len(self._bodies)
        rot3 = np.eye(3)
        rot3[:self.dim, :self.dim] = rot
        self._bodies.append((p.copy(), rot3))
        normal = _unit_rows(collider.normal(world[keep])) @ rot if keep.any() else np.zeros((0, self.dim))
        self._add_part(world[keep], body, self._noslip(slip, boundary_viscosity), local[keep], normal)
        # the core in the body frame (centre at the origin, the rotation is the body's), packed as
        # the collider itself packs its distance (a 2-D box has an infinite z extent)
        origin = np.zeros(self.dim)
        core = Box(center=origin, half_extents=half) if isinstance(collider, Box) else \
            Sphere(center=origin, radius=float(collider.radius))
        self._cores.append((body, int(core.kind), core._cf.copy(), np.zeros(1, np.int64)))
        count = len(self._bodies)
        self.body_force = np.zeros((count, 3))
        self.body_torque = np.zeros((count, 3))
        old = (self._body_x, self._body_rot, self._body_v, self._body_w) if body else None
        self._body_x = np.array([b[0] for b in self._bodies])
        self._body_rot = np.array([b[1] for b in self._bodies])
        self._body_v = np.zeros((count, 3))
        self._body_w = np.zeros((count, 3))
        if old is not None:  # keep the poses already set for the earlier bodies
            self._body_x[:body], self._body_rot[:body], self._body_v[:body], self._body_w[:body] = (
                o[:body] for o in old)
        self._B = None
        return body

    def add_rigid_model(self, model, body_q=None, *, slip=False, boundary_viscosity=None) -> int:
        """Sample every shape row of a rigid ``Model`` (``inertia.model``) with boundary particles
        (``coupling.sample_model``; Akinci et al. 2012): static geometry on the world lattice,
        shapes of dynamic/kinematic bodies in their body frame, posed at ``body_q`` (default the
        model's initial state). Fluid body k is rigid body k. Returns the number of particles.
        Called by ``advance`` on first use with the RigidWorld's model."""
        from . import coupling
        if self.dim != 3:
            raise ValueError("a rigid Model couples with a 3-D fluid only (make a 2-D scene a thin 3-D fluid, "
                             "periodic across its depth)")
        if self._bodies:
            raise ValueError("the fluid already has bodies; add_rigid_model must be the only source of bodies")
        if body_q is None:
            body_q = model.state().body_q
        grow = np.where(self.periodic, 0.0, self.support)
        parts = coupling.sample_model(model, body_q, self.spacing, self.support, _lattice,
                                      self.domain_lo - grow, self.domain_hi + grow, self.domain_lo)
        noslip = self._noslip(slip, boundary_viscosity)
        count = 0
        for world, body, local, normal in parts:
            self._add_part(np.ascontiguousarray(world), body, noslip, np.ascontiguousarray(local),
                           np.ascontiguousarray(normal))
            count += world.shape[0]
        nbody = int(model.body_count)
        self._cores = coupling.solid_cores(model)
        # a box spanning a periodic axis (the 2-D slabs) has no faces on it
        length = self.domain_hi - self.domain_lo
        rot0 = coupling.quat_to_matrices(body_q[:, 3:7]) if nbody else np.zeros((0, 3, 3))
        for body, kind, cf, _ in self._cores:
            if kind != _dist.BOX:
                continue
            axes = rot0[body] @ cf[3:12].reshape(3, 3)   # packed box: centre, R (columns = axes), half
            for d in np.flatnonzero(self.periodic):
                for e in range(3):
                    if abs(axes[d, e]) > 0.999 and 2 * cf[12 + e] >= length[d] - self.spacing:
                        cf[12 + e] = _dist.BIG
        rot = coupling.quat_to_matrices(body_q[:, 3:7]) if nbody else np.zeros((0, 3, 3))
        self._bodies = [(np.asarray(body_q[k, :3], float).copy(), rot[k]) for k in range(nbody)]
        self._body_x = np.array(body_q[:, :3], float).reshape(nbody, 3)
        self._body_rot = rot.reshape(nbody, 3, 3).copy()
        self._body_v = np.zeros((nbody, 3))
        self._body_w = np.zeros((nbody, 3))
        self.body_force = np.zeros((nbody, 3))
        self.body_torque = np.zeros((nbody, 3))
        self._rigid_model = model
        self._B = None
        return count

    def _pose_from_rigid(self, state):
        from . import coupling
        if not len(self._bodies):
            return
        self._body_x[:] = state.body_q[:, :3]
        self._body_rot[:] = coupling.quat_to_matrices(state.body_q[:, 3:7])
        self._body_w[:] = state.body_qd[:, 0:3]
        self._body_v[:] = state.body_qd[:, 3:6]
        self._bodies_moved = True

    def _extrapolate_bodies(self, dt):
        # move the bands with the bodies' velocities between the fluid sub-steps of one world step
        if not len(self._bodies):
            return
        from . import coupling
        self._body_x += dt * self._body_v
        w = self._body_w
        angle = np.linalg.norm(w, axis=1) * dt
        axis = w / np.maximum(np.linalg.norm(w, axis=1), 1e-300)[:, None]
        q = np.concatenate([np.cos(0.5 * angle)[:, None], axis * np.sin(0.5 * angle)[:, None]], axis=1)
        self._body_rot[:] = coupling.quat_to_matrices(q) @ self._body_rot
        self._bodies_moved = True

    def check_rigid(self, rigid) -> None:
        """The World protocol's construction-time check (``World.add_fluid``): raises ValueError
        when this fluid cannot couple with ``rigid`` (a RigidWorld with bodies): a 2-D fluid, since
        rigid bodies are 3-D (make a 2-D scene a thin 3-D fluid, periodic across its depth, or
        move 2-D boxes and spheres yourself with ``add_body`` / ``set_body_state`` outside a World)."""
        if rigid is not None and self.dim != 3:
            raise ValueError("a 2-D SPH fluid cannot join a World with rigid bodies (they are 3-D, and 2-D "
                             "bodies do not exist yet): make the fluid a thin 3-D slab, periodic across 6 "
                             "spacings, or use SPHFluid.add_body / set_body_state without a World")

    def advance(self, dt, rigid=None) -> int:
        """The World protocol: advance the fluid by ``dt`` [s] in fluid steps no longer than its
        own limit (adaptive or fixed dt), coupled with ``rigid`` (a RigidWorld or None): the bands
        follow ``rigid.state.body_q/body_qd`` and the fluid's impulse on every dynamic body over dt
        is written into ``body_qd`` (``dynamics.particle_coupling.apply_body_impulses``). Returns the number of
        fluid steps taken; ``body_force`` / ``body_torque`` then hold the mean force [N] and
        torque [N m] over dt."""
        from . import coupling
        dt = _validate.positive_scalar(dt, "dt")
        if rigid is not None:
            self.check_rigid(rigid)
            if self._rigid_model is None:
                self.add_rigid_model(rigid.model, rigid.state.body_q)
                if self._pending_state is not None:
                    pending, self._pending_state = self._pending_state, None
                    self.restore_state(pending)
            elif self._rigid_model is not rigid.model:
                raise ValueError("rigid must be the RigidWorld whose model this fluid sampled")
            self._pose_from_rigid(rigid.state)
        nbody = len(self._bodies)
        impulse = np.zeros((nbody, 3))
        angular = np.zeros((nbody, 3))
        left, steps = dt, 0
        while left > 1e-12 * dt:
            if steps:
                self._extrapolate_bodies(self.last_dt)
            taken = self.step(at_most=left)
            impulse += taken * self.body_force
            angular += taken * self.body_torque
            left -= taken
            steps += 1
        if nbody:
            self.body_force[:] = impulse / dt
            self.body_torque[:] = angular / dt
            if rigid is not None:
                apply_body_impulses(rigid.model, rigid.state, impulse, angular)
        return steps

    # ------------------------------------------------------------------ World protocol: state
    _SCALARS = ("time", "step_count", "last_dt", "_n", "_next_id")

    def save_state(self) -> dict:
        """Everything the next step reads, as arrays (copies): the fluid rows (all capacity rows,
        in their current cell order, with the warm-start pressures), particle ids, the boundary
        particles in their sorted order with the bodies' poses, emitter progress, clock and
        counters. ``restore_state`` of it continues bit for bit."""
        if self._B is None:
            self._finalize_boundary()
        out = {f"fluid_{k}": getattr(self._F, k).copy() for k in self._F._fields}
        out.update({f"boundary_{k}": getattr(self._B, k).copy() for k in self._B._fields})
        out["particle_id"] = self._id.copy()
        out["boundary_rest"] = self._b_rest.copy()
        out["boundary_local"] = self._b_local.copy()
        out["boundary_normal"] = self._b_normal.copy()
        out["boundary_normal_rest"] = self._b_nrest.copy()
        out["boundary_cell_start"] = self._b_start.copy()
        out["bodies_moved"] = np.array(self._bodies_moved)
        if len(self._bodies):
            for k in ("_body_x", "_body_rot", "_body_v", "_body_w"):
                out["body" + k[5:]] = getattr(self, k).copy()
            out["body_force"], out["body_torque"] = self.body_force.copy(), self.body_torque.copy()
        out["emitter_travel"] = np.array([e["travel"] for e in self._emitters], float)
        out["counters"] = np.array([self.time, self.step_count, self.last_dt, self._n, self._next_id,
                                    self.stats.get("removed", 0), self.stats.get("emitter_dropped", 0),
                                    self._dt_scale], float)
        return out

    def check_state(self, state: dict) -> None:
        """Raise ValueError naming the entry if ``state`` (from a checkpoint) holds a count or index
        outside the arrays it indexes: the live particle count against the capacity, the counters
        finite, the boundary cell starts inside the boundary rows, the boundary owners among the
        bodies. Called first by ``restore_state``: nothing of a bad state reaches a kernel."""
        cap = self._F.x.shape[0]
        c = np.asarray(state.get("counters", ()))
        if c.ndim != 1 or c.shape[0] < 5 or c.dtype.kind not in "fi":
            raise ValueError(f"state['counters'] has shape {c.shape} and dtype {c.dtype}; expected at least 5 numbers")
        if not np.all(np.isfinite(c)):
            raise ValueError(f"state['counters'] holds a value that is not finite: {c.tolist()}")
        if not (0 <= c[3] <= cap and c[3] == int(c[3])):
            raise ValueError(f"state['counters'][3] (live particles) is {c[3]:g}; this fluid's capacity is {cap}")
        if c[4] < c[3] or c[1] < 0 or c[0] < 0 or c[2] < 0:
            raise ValueError(f"state['counters'] (time, steps, last dt, live particles, next id) = {c[:5].tolist()} "
                             "are not a state this fluid can be in")
        nb = self._B.x.shape[0] if self._B is not None else None
        start = state.get("boundary_cell_start")
        if start is not None and nb is not None:
            start = np.asarray(start)
            # (cells + 2,): the cells' starts, then the total, then one spare slot
            if start.dtype.kind not in "iu" or (start.size and (start.min() < 0 or start.max() > nb
                                                                or np.any(np.diff(start[:-1]) < 0))):
                raise ValueError(f"state['boundary_cell_start'] must be non-decreasing integers in 0..{nb}")
        body = state.get("boundary_body")
        if body is not None:
            body = np.asarray(body)
            nbody = max(len(self._bodies), int(np.asarray(state.get("body_x", np.zeros((0, 3)))).shape[0]))
            if body.dtype.kind not in "iu" or (body.size and (body.min() < -1 or body.max() >= nbody)):
                raise ValueError(f"state['boundary_body'] must hold -1 or body indices 0..{nbody - 1}")
        ids = np.asarray(state.get("particle_id", ()))
        if ids.dtype.kind in "iu" and ids.shape == (cap,) and np.any(ids[:int(c[3])] < 0):
            raise ValueError(f"state['counters'][3] counts {int(c[3])} live particles but rows "
                             f"{int(np.flatnonzero(ids[:int(c[3])] < 0)[0])}.. hold none (particle_id -1)")

    def restore_state(self, state: dict) -> None:
        """Continue from ``save_state``'s arrays (same fluid set-up: capacity, boundaries, bodies,
        emitters); raises ValueError naming the first key that is missing or has the wrong shape,
        or a count or index outside its arrays (`check_state`).
        A fluid coupled to a RigidWorld samples its bodies on the first ``advance``: restoring
        before that keeps the state and applies it right after the sampling."""
        if "body_x" in state and not self._bodies:
            self._pending_state = state
            return
        if self._B is None:
            self._finalize_boundary()
        self.check_state(state)

        def put(key, dst):
            if key not in state:
                raise ValueError(f"state is missing {key!r} (not saved by this fluid's save_state)")
            src = np.asarray(state[key])
            if src.shape != dst.shape:
                raise ValueError(f"state[{key!r}] has shape {src.shape}; this fluid needs {dst.shape}")
            dst[...] = src

        for k in self._F._fields:
            put(f"fluid_{k}", getattr(self._F, k))
        for k in self._B._fields:
            put(f"boundary_{k}", getattr(self._B, k))
        put("particle_id", self._id)
        put("boundary_rest", self._b_rest)
        put("boundary_local", self._b_local)
        put("boundary_normal", self._b_normal)
        put("boundary_normal_rest", self._b_nrest)
        put("boundary_cell_start", self._b_start)
        self._bodies_moved = bool(np.asarray(state["bodies_moved"]))
        if len(self._bodies):
            for k in ("_body_x", "_body_rot", "_body_v", "_body_w"):
                put("body" + k[5:], getattr(self, k))
            put("body_force", self.body_force)
            put("body_torque", self.body_torque)
        travel = np.asarray(state["emitter_travel"], float)
        if travel.shape != (len(self._emitters),):
            raise ValueError(f"state['emitter_travel'] has {travel.shape} entries; this fluid has "
                             f"{len(self._emitters)} emitters")
        for e, t in zip(self._emitters, travel):
            e["travel"] = float(t)
        c = np.asarray(state["counters"], float)
        self.time, self.step_count, self.last_dt = float(c[0]), int(c[1]), float(c[2])
        self._n, self._next_id = int(c[3]), int(c[4])
        self._dt_scale = float(c[7]) if c.shape[0] > 7 else 1.0
        if c[5]:
            self.stats["removed"] = int(c[5])
        if self._emitters:
            self.stats["emitter_dropped"] = int(c[6])

    def frame_arrays(self) -> dict:
        """What a run records per frame, fixed shapes: ``x`` (capacity, D) float32 [m], ``v``
        (capacity, D) float32 [m/s], ``speed`` (capacity,) float32 [m/s], ``particle_id``
        (capacity,) int64 (-1 for dead rows), ``active`` (capacity,) bool. Rows are in the solver's
        cell order (use ``particle_id`` to follow a particle)."""
        n, cap = self._n, self.capacity
        active = np.zeros(cap, bool)
        active[:n] = True
        x = self._F.x.astype(np.float32)
        v = self._F.v.astype(np.float32)
        x[n:] = np.nan
        v[n:] = 0.0
        ids = self._id.copy()
        ids[n:] = -1
        return {"x": x, "v": v, "speed": np.linalg.norm(v, axis=1).astype(np.float32), "particle_id": ids,
                "active": active}

    def static_arrays(self) -> dict:
        """Constant per run: ``domain`` (2, D) [m], ``spacing`` (1,) [m], ``smoothing_length`` (1,) [m],
        ``rest_density`` (1,) [kg/m^3], ``boundary_x`` (Nb, D) float32 [m] of the static boundary
        particles (walls; moving bodies are drawn from their shapes)."""
        if self._B is None:
            self._finalize_boundary()
        static = self._B.body < 0
        return {"domain": np.stack([self.domain_lo, self.domain_hi]), "spacing": np.array([self.spacing]),
                "smoothing_length": np.array([self.h]), "rest_density": np.array([self.rest_density]),
                "boundary_x": self._B.x[static].astype(np.float32)}

    def set_body_state(self, body: int, position, rotation, velocity, angular_velocity):
        """Pose of a body for the next step: centre position (D,), rotation (D, D), velocity (D,)
        [m/s], angular velocity (3,) [rad/s] (2D: (0, 0, omega_z) or a scalar)."""
        if not 0 <= int(body) < len(self._bodies):
            raise ValueError(f"body must be a body index in [0, {len(self._bodies)}); got {body!r}")
        d = self.dim
        self._body_x[body, :d] = _validate.as_vector(position, "position", d)
        self._body_rot[body, :d, :d] = np.asarray(rotation, float).reshape(d, d)
        self._body_v[body, :d] = _validate.as_vector(velocity, "velocity", d)
        w = np.asarray(angular_velocity, float).reshape(-1)
        self._body_w[body] = (0.0, 0.0, float(w[-1])) if d == 2 else w
        self._bodies_moved = True

    def add_outflow(self, lo, hi):
        """Remove fluid particles that enter the box [lo, hi) (at the next step's sort)."""
        lo = _validate.as_vector(lo, "lo", self.dim)
        hi = _validate.as_vector(hi, "hi", self.dim)
        if np.any(hi <= lo):
            raise ValueError(f"hi must be > lo on every axis; got lo={lo.tolist()}, hi={hi.tolist()}")
        lo3, hi3 = np.full(3, -np.inf), np.full(3, np.inf)
        lo3[:self.dim], hi3[:self.dim] = lo, hi
        self._outflow_lo = np.vstack([self._outflow_lo, lo3])
        self._outflow_hi = np.vstack([self._outflow_hi, hi3])

    def add_emitter(self, center, velocity, width):
        """Inflow: a line (2D) or square (3D) of side ``width`` [m] centred at ``center``, normal to
        ``velocity`` [m/s], that releases one layer of lattice particles each time the previous
        layer has moved one spacing. Needs ``capacity`` room; particles beyond it are not emitted
        (``stats['emitter_dropped']`` counts them)."""
        c = _validate.as_vector(center, "center", self.dim)
        u = _validate.as_vector(velocity, "velocity", self.dim)
        width = _validate.positive_scalar(width, "width")
        speed = float(np.linalg.norm(u))
        if speed <= 0:
            raise ValueError("velocity must be non-zero for an emitter")
        if np.any(c < self.domain_lo) or np.any(c >= self.domain_hi):
            raise ValueError(f"center must lie inside the domain [{self.domain_lo.tolist()}, "
                             f"{self.domain_hi.tolist()}); got {c.tolist()}")
        nrm = u / speed
        # an orthonormal basis of the emitter plane
        helper = np.eye(self.dim)[int(np.argmin(np.abs(nrm)))]
        t1 = helper - nrm * (helper @ nrm)
        t1 /= np.linalg.norm(t1)
        count = max(1, int(round(width / self.spacing)))
        s = (np.arange(count) - 0.5 * (count - 1)) * self.spacing
        if self.dim == 2:
            layer = c + s[:, None] * t1
        else:
            t2 = np.cross(nrm, t1)
            a, b = np.meshgrid(s, s, indexing="ij")
            layer = c + a.reshape(-1, 1) * t1 + b.reshape(-1, 1) * t2
        self._emitters.append({"layer": np.ascontiguousarray(layer), "velocity": u, "direction": nrm,
                               "speed": speed, "travel": self.spacing})
        self.stats.setdefault("emitter_dropped", 0)

    # ------------------------------------------------------------------ internals: boundaries
    def _noslip(self, slip, boundary_viscosity):
        if slip:
            return 0.0
        if boundary_viscosity is not None:
            return _validate.positive_scalar(boundary_viscosity, "boundary_viscosity", allow_zero=True)
        return self.viscosity if self.viscosity > 0 else 1e-3 * self.spacing * self.max_speed

    def _band(self, collider, lo, hi, origin):
        if getattr(collider, "dim", None) != self.dim:
            raise ValueError(f"collider must be a {self.dim}-D collider like the fluid; got {collider!r}")
        pts = _lattice(lo, hi, self.spacing, origin=origin)
        sd = collider.signed_distance(pts)
        return np.ascontiguousarray(pts[(sd < 0) & (sd >= -self.support)])

    def _add_part(self, pts, body, noslip, local, normal):
        # normal: unit normal of the solid's surface (out of the solid), world frame for static
        # parts, body frame for moving ones (the wall-normal direction of the extrapolated pressure)
        self._boundary_parts.append((pts, body, noslip, local, normal))
        self._B = None

    def _finalize_boundary(self):
        d = self.dim
        parts = self._boundary_parts
        x = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, d))
        nbnd = x.shape[0]
        body = np.concatenate([np.full(p[0].shape[0], p[1], np.int64) for p in parts]) if parts else \
            np.zeros(0, np.int64)
        noslip = np.concatenate([np.full(p[0].shape[0], p[2]) for p in parts]) if parts else np.zeros(0)
        noslip *= self._visc_scale
        local = np.concatenate([p[3] for p in parts]) if parts else np.zeros((0, d))
        self._b_nrest = np.ascontiguousarray(np.concatenate([p[4] for p in parts])) if parts else np.zeros((0, d))
        self._b_normal = self._b_nrest.copy()   # world frame (bodies: rotated in _sort_boundary)
        psi = np.full(nbnd, self.rest_density * self.volume)
        self._B = _k.BoundaryArrays(np.ascontiguousarray(x), np.zeros((nbnd, d)), psi, body, noslip)
        self._b_rest = x.copy()
        self._b_local = np.ascontiguousarray(local)
        self._b_cell = np.empty(nbnd, np.int64)
        self._b_order = np.empty(nbnd, np.int64)
        self._b_start = np.zeros(self._ncells + 2, np.int64)
        self._b_tmp2 = np.empty((nbnd, d))
        self._b_tmp1 = np.empty(nbnd)
        self._b_tmpi = np.empty(nbnd, np.int64)
        self._k_floor = np.zeros(self.capacity)  # k_i of the hydrostatic wall kick (kernels)
        # extrapolated boundary pressure (kernels.boundary_extrapolated_pressure): boundary->fluid lists, k_b
        self._bt_start = np.zeros(nbnd + 1, np.int64)
        self._bt = self._alloc_transpose(max(16, 4 * nbnd))
        self._kb_dens = np.zeros(nbnd)   # k_b of the density solve's total (WCSPH: of the Tait pressure)
        self._kb_div = np.zeros(nbnd)    # k_b of the divergence solve's total
        self._k0_dens = np.zeros(self.capacity)   # k_dens / k_div at the start of this step's solves
        self._k0_div = np.zeros(self.capacity)
        self._bodies_moved = bool(self._bodies)
        c = self._cores   # packed once: kernels.push_out_of_cores's core arrays
        off = np.cumsum([0] + [e[2].shape[0] for e in c])
        ioff = np.cumsum([0] + [e[3].shape[0] for e in c])
        self._core_arrays = (_k.CORE_KINDS, np.array([e[0] for e in c], np.int64),
                             np.array([e[1] for e in c], np.int64), off[:-1].astype(np.int64),
                             ioff[:-1].astype(np.int64),
                             np.concatenate([e[2] for e in c] + [np.zeros(1)]).astype(float),
                             np.concatenate([e[3] for e in c] + [np.zeros(1, np.int64)]).astype(np.int64))
        self._sort_boundary()

    def _alloc_transpose(self, m):
        return np.zeros(m, np.int64), np.zeros(m)   # fluid index, W_bf

    def _boundary_lists(self):
        """Boundary->fluid neighbour lists of this step (for the extrapolated boundary pressure)."""
        nbnd = self._B.x.shape[0]
        pairs = int(self._nbn.start[self._n])
        if pairs > self._bt[0].shape[0]:
            self._bt = self._alloc_transpose(int(pairs * 1.25) + 16)
        _k.boundary_transpose(self._nbn, self._n, nbnd, self._bt_start, self._bt[0], self._bt[1])

    def _boundary_push(self, k_fluid, kb, dt):
        """Extrapolate the fluid's k (a solve's total) to the boundary particles (into kb) and push
        the fluid with their share of the pressure term (Adami et al. 2012)."""
        nbnd = self._B.x.shape[0]
        self._K.boundary_extrapolated_pressure(self._F, self._B, self.grid, nbnd, self._bt_start, self._bt[0],
                                               self._bt[1], self._b_normal, k_fluid, self.rest_density, self._g3, kb)
        self._K.boundary_pressure_kick(self._F, self._nbn, self._B, self.grid, self._n, dt, kb, k_fluid, self._g3,
                                       self._b_normal)

    def _sort_boundary(self):
        B = self._B
        self._K = _k.kernel_set(max(self._n, B.x.shape[0]))
        nbnd = B.x.shape[0]
        if self._bodies:
            self._K.move_boundary(self._b_local, B.body, self._b_rest, self._body_x, self._body_rot, self._body_v,
                             self._body_w, B.x, B.v)
            _k.rotate_boundary_normals(self._b_nrest, B.body, self._body_rot, self._b_normal)
        self._K.bin_cells(B.x, nbnd, self.grid, np.inf, self._outflow_lo[:0], self._outflow_hi[:0], self._b_cell)
        total = _bp.counting_sort(self._b_cell, self._ncells, self._b_start, self._b_order)
        assert total == nbnd
        o = self._b_order
        for arr, tmp in ((B.x, self._b_tmp2), (B.v, self._b_tmp2), (self._b_rest, self._b_tmp2),
                         (self._b_local, self._b_tmp2), (self._b_nrest, self._b_tmp2),
                         (self._b_normal, self._b_tmp2), (B.psi, self._b_tmp1), (B.noslip, self._b_tmp1),
                         (B.body, self._b_tmpi)):
            self._K.gather(o, nbnd, arr, tmp)
            arr[:] = tmp
        self._bodies_moved = False

    # ------------------------------------------------------------------ internals: fluid
    def _alloc_neighbours(self, cap, m):
        return _k.Neighbours(np.zeros(cap + 1, np.int64), np.zeros(m, np.int32), np.zeros(m),
                             np.zeros((m, self.dim)))

    def _sort_fluid(self):
        F = self._F
        cap = self.capacity
        self._K.bin_cells(F.x, self._n, self.grid, self.support, self._outflow_lo, self._outflow_hi, self._cell_of)
        n = _bp.counting_sort(self._cell_of, self._ncells, self._cell_start, self._order)
        if n < self._n:
            self._check_escaped()
        o = self._order
        for arr, tmp in ((F.x, self._tmp2), (F.v, self._tmp2), (F.k_dens, self._tmp1), (F.k_div, self._tmp1),
                         (self._id, self._tmpi)):
            self._K.gather(o, n, arr, tmp)
            arr[:n] = tmp[:n]
        if n < self._n:
            self.stats["removed"] = self.stats.get("removed", 0) + self._n - n
            F.k_dens[n:cap] = 0.0
            F.k_div[n:cap] = 0.0
        self._n = n

    def _neighbour_lists(self, xt, start_t, exclude_self, nl):
        F = self._F
        n = self._n
        K = self._K
        args = (F.x, n, xt, start_t, self.grid, self.kernel, self.h, exclude_self)
        stride = self._stride
        sj = self._strided
        K.fill_strided(F.x, n, xt, start_t, self.grid, self.h, exclude_self, stride, self._count, sj, *self._no_wg)
        total = _nb.exclusive_scan(self._count, n, nl.start)
        if total > nl.j.shape[0]:
            nl = self._alloc_neighbours(self.capacity, int(total * 1.25) + 16)
            _nb.exclusive_scan(self._count, n, nl.start)
        widest = int(self._count[:n].max()) if n else 0
        if widest <= stride:
            K.compact(F.x, n, xt, self.grid, self.kernel, self.h, stride, nl.start, sj, nl.j, nl.w, nl.g)
        else:  # a row overflowed its stride: the two-pass fill, and a wider stride from now on
            K.fill_neighbours(*args, nl.start, nl.j, nl.w, nl.g)
            self._stride = int(widest * 1.25) + 4
            self._strided = self._alloc_strided(self._stride)
        return nl, total

    def _alloc_strided(self, stride):
        cap = self.capacity
        return np.zeros(cap * stride, np.int32)

    def _dt_limit(self, vmax):
        # CFL with gravity: (vmax + |g| dt) dt <= cfl dx; explicit viscosity; WCSPH acoustic CFL
        g = float(np.linalg.norm(self.gravity))
        reach = self.cfl * self.spacing
        dt = 2.0 * reach / (vmax + math.sqrt(vmax * vmax + 4.0 * g * reach)) if (vmax > 0 or g > 0) else self.dt_max
        if self.viscosity > 0 and not self.implicit_viscosity:
            dt = min(dt, 0.125 * self.h * self.h / (self.viscosity * self._visc_scale))
        if self.method == "wcsph":
            dt = min(dt, self.cfl * self.h / (self.sound_speed + vmax))
        return dt

    def _reduce(self, values, n):
        self._K.chunk_sum_max(values, n, self._partial, self._red)
        return float(self._red[0]), float(self._red[1])

    def _solve(self, density_mode, dt, tolerance):
        """One DFSPH solve; returns (iterations, mean error, max error, converged). The density
        solve stops when the mean compression is below ``tolerance`` *and* the largest one below
        ``local_density_tolerance``; the divergence solve on the mean only (as the paper)."""
        F, nf, nb, B, n, m = self._F, self._nf, self._nbn, self._B, self._n, self.mass
        total = F.k_dens if density_mode else F.k_div
        kb = self._kb_dens if density_mode else self._kb_div
        if density_mode:
            # warm start with the previous step's pressure (Bender & Koschier 2017, sec. 4.3):
            # the constant-density solve balances the same forces (gravity) every step
            self._K.apply_pressure(F, nf, nb, B, n, m, dt, total, total, False, self._mirror)
            if self._extrapolated:
                self._boundary_push(total, kb, dt)
        else:
            # optional warm start of the divergence solve (Bender & Koschier 2017): at rest it
            # then carries part of the hydrostatic load (see warm_start_divergence)
            if self.warm_start_divergence:
                self._K.apply_pressure(F, nf, nb, B, n, m, dt, total, total, False, self._mirror)
                if self._extrapolated:
                    self._boundary_push(total, kb, dt)
            else:
                total[:n] = 0.0
                kb[:] = 0.0
        if self._extrapolated:   # the mirrored increments of this solve are total - k0 (body wrench)
            (self._k0_dens if density_mode else self._k0_div)[:n] = total[:n]
        scale = 1.0 / self.rest_density * (1.0 if density_mode else dt)
        local = self.local_density_tolerance if density_mode else math.inf
        # compression present at the start of a step shorter than the CFL step at the flow's
        # speed scale is removed at that step's pace (a share dt / dt_ref per step): removing it
        # all within dt needs a speed e dx / dt, which shortens the next CFL step, which raises
        # that speed again (the runaway of tall columns started from rest)
        beta = min(1.0, dt / self._dt_ref)
        err = big = 0.0
        it = 0
        converged = False
        # momentum (heavy ball, Polyak 1964) on the relaxed Jacobi of the constant-density solve:
        # kappa_k = omega factor e_k / dt^2 + mu_k kappa_(k-1). Jacobi alone removes the smooth
        # error of a deep column at a rate 1 - omega lambda_min per iteration (~0.3 % in the 20-row
        # column: its solve crept from 2e-3 to 1e-3 in ~120 iterations and missed the tolerance
        # within the default 100 in 33 of 2757 steps); with momentum that error decays at ~sqrt(mu)
        # per iteration. Momentum slows the error that Jacobi removes fast (local, after a splash:
        # every mode then decays at >= sqrt(mu)) and changed the flows: with mu up to 0.9 from the
        # first iteration the collapsing tall column kept 3.5-6 % compressions and a sinking dense
        # box ran away; engaged in every creeping solve (mu <= 0.5-0.6), the coarse dam break's
        # residual column stood 0.05-0.06 x 2a high at T = 4.8; as a rescue with mu <= 0.7 the tall
        # column still kept 3.4 % (all measured). So it is a rescue with mu <= 0.5:
        # engaged only in the second half of max_iterations (RESCUE_SHARE) and only once Jacobi creeps
        # (CREEP_ITERATIONS iterations in a row that each removed less than 3 % of the mean
        # error); the solves that plain Jacobi finishes within max_iterations / 2 are untouched.
        # From there mu grows as k / (k + 3) (Nesterov's schedule) up to MOMENTUM_MAX, and an
        # iteration that raised the mean error switches it off until Jacobi creeps again
        # (adaptive restart, O'Donoghue & Candes 2015; it acts one iteration late: the error of
        # iteration k is summed in the pass that makes kappa_k). The divergence solve stays plain.
        F.kappa[:n] = 0.0
        run, last, slow = -1, math.inf, 0
        while True:
            momentum = min(MOMENTUM_MAX, run / (run + 3.0)) if density_mode and run > 0 else 0.0
            self._K.pressure_increment(F, nf, nb, B, n, m, self.rest_density, dt, density_mode, RELAXATION, momentum,
                                       total, beta, self._partial, self._red)
            s, mx = float(self._red[0]), float(self._red[1])
            err, big = s / max(n, 1) * scale, mx * scale
            converged = err <= tolerance and big <= local
            if err > last:            # restart: plain Jacobi until it creeps again
                run, slow = -1, 0
            else:
                slow = slow + 1 if err > CREEP * last else 0
                if run >= 0 or (slow >= CREEP_ITERATIONS and it >= RESCUE_SHARE * self.max_iterations):
                    run += 1
            last = err
            if (converged and it >= 1) or it >= self.max_iterations:
                break
            self._K.apply_pressure(F, nf, nb, B, n, m, dt, F.kappa, total, True, self._bfac_iter)
            it += 1
        return it, err, big, converged

    def _solve_viscosity(self, dt, tolerance=1e-6, max_iterations=200):
        # (I - dt nu L) v = v* + wall terms, preconditioned CG from v* (kernels.viscosity_operator)
        F, K, n = self._F, self._K, self._n
        r, z, p, ap, wall, diag = self._cg
        nu = self.viscosity * self._visc_scale
        args = (F, self._nf, self._nbn, self._B, self.grid, n, self.mass, self.rest_density, self.h, nu, dt)
        K.viscosity_operator(*args, F.v, ap, diag, wall)
        np.subtract(wall[:n], ap[:n], out=r[:n])
        np.add(r[:n], F.v[:n], out=r[:n])                     # r = (v* + wall) - A v*
        np.divide(r[:n], diag[:n, None], out=z[:n])
        p[:n] = z[:n]
        bnorm = math.sqrt(K.dot_rows(F.v, F.v, n, self._partial)) + 1e-30
        rz = K.dot_rows(r, z, n, self._partial)
        it = 0
        while it < max_iterations and math.sqrt(K.dot_rows(r, r, n, self._partial)) > tolerance * bnorm:
            K.viscosity_operator(*args, p, ap, diag, wall)
            alpha = rz / K.dot_rows(p, ap, n, self._partial)
            K.cg_update(n, alpha, p, ap, F.v, r, diag, z)
            rz_new = K.dot_rows(r, z, n, self._partial)
            K.cg_direction(n, rz_new / rz, z, p)
            rz = rz_new
            it += 1
        return it

    def _tick(self, name, t0):
        t1 = time.perf_counter()
        self.profile[name] = self.profile.get(name, 0.0) + t1 - t0
        return t1

    # ------------------------------------------------------------------ the step
    def step(self, dt=None, *, at_most=None) -> float:
        """Advance by one step; returns the dt taken (``dt`` overrides the fixed/adaptive step
        for this call; ``at_most`` caps it, e.g. to end exactly at a frame time)."""
        if self._B is None:
            self._finalize_boundary()
        F, m = self._F, self.mass
        t0 = time.perf_counter()
        self._K = _k.kernel_set(self._n)
        # 1. sort
        self._sort_fluid()
        if self._bodies_moved:
            self._sort_boundary()
        n = self._n
        t0 = self._tick("sort", t0)
        # 2. neighbours
        self._nf, pairs = self._neighbour_lists(F.x, self._cell_start, True, self._nf)
        self._nbn, _ = self._neighbour_lists(self._B.x, self._b_start, False, self._nbn)
        nf, nb, B = self._nf, self._nbn, self._B
        self.stats["neighbours_per_particle"] = pairs / max(n, 1)
        if self._extrapolated:
            self._boundary_lists()
        t0 = self._tick("neighbours", t0)
        # 3. density
        # the factor's boundary weight: Akinci's (1) in every mode, also where the increments are
        # mirrored (2): |a + b|^2 + s >= s. The mirrored diagonal (a + 2b) . (a + b) + s is smaller
        # where b . (a + b) < 0 (a particle drawn off a wall), down to 0: the Jacobi steps there
        # rattled particles against the slip walls of the 200-row column (one-step compressions
        # of 6.8 % late in its collapse, 3.8 % with this one, both started from zero pressure),
        # and the sinking dense 2-D box diverged; extrapolated: rows near the surface alternated
        self._K.density_and_factor(F, nf, nb, B, n, m, self._w0, self._factor_eps, 1.0)
        t0 = self._tick("density", t0)
        # 4. dt
        self._K.speed_squared(F.v, n, self._tmp1)
        vmax = math.sqrt(self._reduce(self._tmp1, n)[1])
        if not math.isfinite(vmax):
            self._diverged(self.last_dt)
        if vmax > self.runaway_speed:
            self._runaway(f"a particle moves at {vmax:.3g} m/s, more than runaway_speed = {self.runaway_speed:.3g} "
                          f"m/s (10x the flow's speed scale {self.speed_scale:.3g} m/s)")
        limit = self._dt_limit(vmax)
        if dt is None:
            if self.fixed_dt is not None:
                dt = self.fixed_dt
            else:
                dt = min(self.dt_max, limit) * self._dt_scale
                if dt < self.min_dt:
                    self._runaway(f"the adaptive step fell to {dt:.3g} s, below 1e-3 of the CFL step at the flow's "
                                  f"speed scale ({self.min_dt:.3g} s)")
        else:
            dt = _validate.positive_scalar(dt, "dt")
        if at_most is not None:
            # split what is left evenly into steps no longer than dt (no sliver step at the end)
            dt = at_most / max(1, math.ceil(at_most / dt - 1e-9))
        self.stats["max_speed"] = vmax
        # 5. divergence solve
        if self.method == "dfsph" and self.divergence_solve and n:
            it, err, _, _ = self._solve(False, dt, self.divergence_tolerance)
            self.stats["divergence_iterations"], self.stats["divergence_error"] = it, err
        t0 = self._tick("divergence", t0)
        # 6. non-pressure forces
        if self.surface_tension > 0:
            self._K.surface_normals(F, nf, n, m, self.support)
        g3 = self._g3
        g3[:self.dim] = self.gravity   # in place: no allocation per step
        explicit_nu = 0.0 if self.implicit_viscosity else self.viscosity * self._visc_scale
        self._K.nonpressure_accel(F, nf, nb, B, self.grid, n, m, self.rest_density, self.h, explicit_nu,
                                  not self.implicit_viscosity, self.surface_tension, g3)
        self._K.kick(F, n, dt)
        if self._hydrostatic_wall:   # mirrored boundary pressure: the wall's hydrostatic share (Adami et al. 2012)
            self._K.boundary_hydrostatic_kick(F, nb, B, self.grid, n, dt, g3, self._b_normal, self._k_floor)
        if self.implicit_viscosity and n:
            self.stats["viscosity_iterations"] = self._solve_viscosity(dt)
        if self.xsph > 0:
            self._K.xsph(F, nf, n, m, self.xsph)
        t0 = self._tick("forces", t0)
        # 7. pressure
        if self.method == "dfsph":
            if n:
                it, err, big, converged = self._solve(True, dt, self.density_tolerance)
                self.stats["density_iterations"], self.stats["density_error"] = it, err
                self.stats["max_density_error"] = big
                # convergence control of the adaptive step: a solve that misses its tolerances
                # halves the next steps (the remaining compression would build up: the runaway
                # of a tall column at fine spacing); converged steps grow back by 10 %
                if not converged:
                    self.stats["unconverged_solves"] = self.stats.get("unconverged_solves", 0) + 1
                    self._dt_scale *= UNCONVERGED_SHRINK
                elif it <= self.max_iterations // 2:
                    self._dt_scale = min(1.0, self._dt_scale * 1.1)
        else:
            self._K.tait_pressure(F, n, self.rest_density, self.tait_stiffness, TAIT_EXPONENT)
            self._K.apply_pressure(F, nf, nb, B, n, m, dt, F.k_dens, F.k_dens, False, self._mirror)
            if self._extrapolated:
                self._boundary_push(F.k_dens, self._kb_dens, dt)
                self._k0_dens[:n] = F.k_dens[:n]   # no solver increments (body wrench)
            np.subtract(F.rho[:n], self.rest_density, out=self._tmp1[:n])
            np.maximum(self._tmp1[:n], 0.0, out=self._tmp1[:n])
            self.stats["density_error"] = self._reduce(self._tmp1, n)[0] / max(n, 1) / self.rest_density
        t0 = self._tick("pressure", t0)
        # 8. bodies
        if self._bodies:
            _k.body_wrench(F, nb, B, n, m, self.rest_density, self.h, self._body_x, self.body_force,
                           self.body_torque, self._mirror)
            if self._hydrostatic_wall:   # the wall's hydrostatic share (Adami et al. 2012), mirrored mode only
                _k.body_hydrostatic_wrench(F, nb, B, self.grid, n, m, self._body_x, g3, self._b_normal,
                                           self._k_floor, self.body_force, self.body_torque)
            if self._extrapolated:   # the boundary particles' extrapolated pressure (Adami et al. 2012)
                _k.body_boundary_pressure_wrench(F, nb, B, self.grid, n, m, self._body_x, self._kb_dens, self._kb_div,
                                                 self._k0_dens, self._k0_div, g3, self._b_normal, self.body_force,
                                                 self.body_torque)
        t0 = self._tick("bodies", t0)
        # 9. advect, emit, check
        self._K.advect(F, self.grid, n, dt)
        if self._cores:   # fluid that got through a thick body's band into its hollow core
            self.stats["pushed_out"] = self.stats.get("pushed_out", 0) + _k.push_out_of_cores(
                F, n, *self._core_arrays, self._body_x, self._body_rot, self._body_v, self._body_w,
                self.support, 0.5 * self.spacing)
        if self._emitters:
            self._emit(dt)
        self._K.speed_squared(F.v, self._n, self._tmp1)
        if not math.isfinite(self._reduce(self._tmp1, self._n)[1]):
            self._diverged(dt)
        self._tick("advect", t0)
        self.time += dt
        self.step_count += 1
        self.last_dt = dt
        return dt

    def _emit(self, dt):
        F = self._F
        for e in self._emitters:
            e["travel"] += e["speed"] * dt
            while e["travel"] >= self.spacing:
                e["travel"] -= self.spacing
                layer = e["layer"] + e["direction"] * e["travel"]
                k = layer.shape[0]
                room = min(k, self.capacity - self._n)
                if room < k:
                    self.stats["emitter_dropped"] += k - room
                a, b = self._n, self._n + room
                F.x[a:b] = layer[:room]
                F.v[a:b] = e["velocity"]
                F.k_dens[a:b] = 0.0
                F.k_div[a:b] = 0.0
                self._id[a:b] = np.arange(self._next_id, self._next_id + room)
                self._next_id += room
                self._n = b

    def _check_escaped(self):
        """Called by the sort when rows were dropped: more than ``ESCAPE_SHARE`` of the fluid (and
        at least ``ESCAPE_MIN`` particles) beyond the domain bounds after one step is a blow-up.
        With the CFL step (at most ``cfl`` <= 1 spacing per step) a flow leaving through an open
        side loses at most about one lattice layer per step; a fluid whose step is unstable shoots
        out all at once (and would otherwise end with no particles and no error)."""
        n_before = self._n
        escaped = _nb.count_escaped(self._cell_of, n_before)
        self.stats["escaped"] = self.stats.get("escaped", 0) + escaped
        if escaped < ESCAPE_MIN or escaped <= ESCAPE_SHARE * n_before:
            return
        rows = np.flatnonzero(self._cell_of[:n_before] == _nb.ESCAPED)   # the error path only
        ids = self._id[rows]
        step, dt = self.step_count - 1, self.last_dt
        raise SimulationDiverged(
            f"SPH step {step} (t = {self.time - dt:g} s, dt = {dt:g} s) blew up: {escaped} of {n_before} fluid "
            f"particles ({100.0 * escaped / n_before:.0f} %) left the domain by more than one kernel support "
            f"(not through an outflow region), particle ids {ids[:10].tolist()}{' ...' if escaped > 10 else ''}; "
            f"likely cause: {self._likely_cause()}", step=step, time=self.time - dt, indices=ids)

    def _likely_cause(self):
        if self.method == "wcsph":
            return ("stiffness/time step: the sound speed is too low for the flow (lower density_tolerance) or dt "
                    "too large")
        return ("time step / pressure-solve tolerance: the DFSPH solve leaves compression that builds up "
                f"({self.stats.get('unconverged_solves', 0)} unconverged solves so far; raise max_iterations, "
                "lower dt_max, cfl or local_density_tolerance)")

    def _runaway(self, what):
        n = self._n
        self._K.speed_squared(self._F.v, n, self._tmp1)
        worst = np.argsort(self._tmp1[:n])[::-1][:10]
        ids = self._id[:n][worst]
        where = ", ".join(f"{i} at {np.round(self._F.x[k], 4).tolist()} ({math.sqrt(self._tmp1[k]):.3g} m/s)"
                          for i, k in zip(ids[:3], worst[:3]))
        cause = self._likely_cause()
        raise SimulationDiverged(
            f"SPH step {self.step_count} (t = {self.time:g} s) ran away: {what}. Fastest particles (ids): {where}; "
            f"likely cause: {cause}", step=self.step_count, time=self.time, indices=ids)

    def _diverged(self, dt):
        v = self._F.v[:self._n]
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        ids = self._id[:self._n][bad]
        cause = ("the time step is too large for the sound speed (lower dt or cfl)" if self.method == "wcsph"
                 else "the time step or the pressure solve (raise max_iterations, lower cfl or dt_max)")
        raise SimulationDiverged(
            f"SPH step {self.step_count} (t = {self.time:g} s, dt = {dt:g} s) produced non-finite velocities "
            f"for {bad.size} particles (ids {ids[:10].tolist()}); likely cause: {cause}",
            step=self.step_count, time=self.time, indices=ids)
