"""Incompressible Navier-Stokes on a staggered MAC grid, 2-D and 3-D: smoke and viscous flow.

One step (``GridFluid.step(dt)``) runs these stages; each reads the arrays named and writes
the ones after the arrow:

1. ``obstacles``  moving obstacles' signed distance and velocity -> face fractions, solid face
   velocities, pressure coefficients (skipped when every obstacle is static).
2. ``advect``     u, v, w and every scalar along the velocity of the step start: semi-Lagrangian
   with an RK2 back-trace (Stam 1999) or MacCormack with clamping (Selle et al. 2008).
3. ``forces``     body acceleration, buoyancy from density and temperature, vorticity
   confinement, sources -> u, v, w, scalars.
4. ``diffuse``    implicit (backward Euler) viscosity: (I - nu dt Lap) u = u* per component,
   conjugate gradients; unconditionally stable. No-slip obstacles are Dirichlet data at the
   surface's cut position between nodes (ghost fluid, Gibou et al. 2002); the momentum each wall
   link takes from the fluid is the viscous force on its obstacle / body. Viscous flow uses an
   incremental pressure correction: the last pressure gradient is subtracted before this solve.
   Then every scalar with a diffusivity: (I - kappa dt Lap) s = s*, the same solver with the
   scalar's ghost rules (walls insulate unless they hold a value; inflows hold theirs); obstacles
   held at a temperature are Dirichlet data at their cut position (ghost fluid), others insulate.
5. ``project``    weighted divergence -> pressure Poisson solve (MGPCG) -> u -= grad(p dt / rho)
   (viscous flow: the increment of phi). `Pressure` sides are Dirichlet data on their faces.
6. ``dissipate``  scalar decay s *= exp(-rate dt).

``advance(frame_dt)`` takes substeps of dt = cfl h / max|u| (capped by ``max_dt``) until the
frame is done.

References
----------
- J. Stam, "Stable fluids", SIGGRAPH 1999 (semi-Lagrangian advection, projection).
- A. Selle, R. Fedkiw, B. Kim, Y. Liu and J. Rossignac, "An unconditionally stable MacCormack
  method", J. Sci. Comput. 35, 2008 (MacCormack with limiter).
- R. Fedkiw, J. Stam and H. W. Jensen, "Visual simulation of smoke", SIGGRAPH 2001 (buoyancy,
  vorticity confinement).
- C. Batty, F. Bertails and R. Bridson, "A fast variational framework for accurate solid-fluid
  coupling", SIGGRAPH 2007 (face-fraction weights).
- A. McAdams, E. Sifakis and J. Teran, "A parallel multigrid Poisson solver for fluids
  simulation on large grids", SCA 2010 (MGPCG).
- F. Gibou, R. Fedkiw, L.-T. Cheng and M. Kang, "A second-order-accurate symmetric
  discretization of the Poisson equation on irregular domains", J. Comput. Phys. 176, 2002
  (the no-slip obstacle boundary of the viscosity solve).
- J. van Kan, "A second-order accurate pressure-correction scheme for viscous incompressible
  flow", SIAM J. Sci. Stat. Comput. 7, 1986; D. L. Brown, R. Cortez and M. L. Minion, "Accurate
  projection methods for the incompressible Navier-Stokes equations", J. Comput. Phys. 168,
  2001 (incremental pressure correction).
- H. S. Carslaw and J. C. Jaeger, "Conduction of Heat in Solids", 2nd ed., Oxford 1959 (the
  heat kernel and the erfc solution the scalar diffusion is tested against).
- F. H. Harlow and J. E. Welch, "Numerical calculation of time-dependent viscous
  incompressible flow of fluid with free surface", Phys. Fluids 8, 1965 (the MAC grid).

Limitations
-----------
- Constant density (Boussinesq smoke); no free surface (liquids are `LiquidFluid`, `fluids/grid/liquid.py`).
- First-order splitting in time; semi-Lagrangian advection adds numerical viscosity
  (measured in tests/fluids/grid/test_solver.py), MacCormack much less.
- No-slip obstacles (``obstacle_slip=False``, the default; `bind_rigid(slip=False)`): the
  viscous solve imposes the solid's velocity at the surface point between a fluid node and a
  node inside the solid along each axis (distance fraction theta from the node signed distances,
  clamped at ``kernels.THETA_MIN`` = 0.02); exact for linear profiles (plane Couette), first order
  on curved walls. The projection after it may change the tangential velocity next to the wall
  by the pressure increment's gradient (zero at a steady state). The viscous force uses the
  Laplacian form mu Lap u (equal to the stress divergence for a divergence-free field; the total
  force on a rigidly moving surface is the same). Slip obstacles impose only the normal velocity.
- Obstacles see the field at the step start: a moving obstacle's fractions are rebuilt once
  per step from its signed distance at the step's end time.
- Rigid bodies (``advance(dt, rigid)`` / `bind_rigid`, 3-D only): shape rows are obstacles at the
  bodies' current poses (the rigid stage has already moved them; the pose is held over the
  fluid's substeps, the velocity is updated by each substep's impulse). Pressure and, for
  viscous fluids, the viscous stress on no-slip shapes push bodies; the coupling is explicit (weak): a body much lighter than the fluid
  it displaces (added mass) can oscillate or blow up. The force is the pressure on the cut-cell
  faces, exactly rho g V_grid in a fluid at rest, V_grid the cut-cell volume (O(h^2) below V for
  convex bodies). Heightfield and SDF rows are skipped.
- The velocity field handed out (``velocity_field()``) is the current grid state; its ``t``
  argument is ignored.
- Scalar diffusion: insulating obstacles are staircases (zero flux across the faces of the cells
  whose centre is inside); only the temperature can be held on obstacles, and the held value is
  one constant per obstacle; diffusion and advection are split (first order in time).
- `Outflow` puts p = 0 at the ghost cell centre half a cell outside its side; `Pressure` puts its
  value on the side's faces (second order). Inflow profiles are fixed when the fluid is built
  (not time-dependent); a "parabolic" inflow in a 3-D duct is the product of two parabolas, not
  the exact duct profile (a series).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ..._validate import as_vector, positive_scalar
from ...errors import SimulationDiverged, check_substep_runaway
from . import kernels as K
from . import viscosity as V
from .boundaries import Inflow, Outflow, Periodic, Pressure, Wall, parse_boundaries, side_velocity
from .obstacles import CutCells, add_axis_impulse, face_cells, rigid_shape_obstacles
from .pressure import SOLVERS, PoissonSolver

ADVECTION = ("semi-lagrangian", "maccormack")
OPEN_SIDES = (Periodic, Outflow, Pressure)   # sides whose boundary faces are unknowns of the projection
MAX_CFL = 5.0


class MACGrid:
    """Geometry of a staggered (MAC) grid.

    Parameters
    ----------
    shape : (nx, ny) or (nx, ny, nz) cell counts, each >= 4 (the stencils and the multigrid
        need that many).
    cell_size : h, metres (> 0); cells are cubes.
    origin : position of the grid's lower corner, metres (default zeros).

    Node positions (metres): u[i, j, k] at origin + (i, j + 1/2, k + 1/2) h, v at
    (i + 1/2, j, k + 1/2) h, w at (i + 1/2, j + 1/2, k) h, scalars at (i + 1/2, j + 1/2, k + 1/2) h.
    """

    def __init__(self, shape, cell_size, origin=None):
        try:
            shp = tuple(int(s) for s in shape)
        except TypeError:
            raise ValueError(f"shape must be a tuple of 2 or 3 cell counts; got {shape!r}") from None
        if len(shp) not in (2, 3) or any(s != t for s, t in zip(shp, shape)):
            raise ValueError(f"shape must be 2 or 3 integer cell counts; got {shape!r}")
        if min(shp) < 4:
            raise ValueError(f"shape must have at least 4 cells per axis (the stencil and "
                             f"multigrid minimum); got {shp}")
        self.dim = len(shp)
        self.shape = shp
        self.cell_size = positive_scalar(cell_size, "cell_size")
        self.origin = (np.zeros(self.dim) if origin is None
                       else as_vector(origin, "origin", self.dim))
        self.n = np.array(shp + (1,) * (3 - self.dim), dtype=np.int64)
        self.origin3 = np.zeros(3)
        self.origin3[:self.dim] = self.origin
        if self.dim == 2:
            self.origin3[2] = -0.5 * self.cell_size  # cell centres at z = 0
        self.size = self.n * self.cell_size

    def face_positions(self, axis):
        """(M, dim) positions of the faces normal to `axis` (C order of the face array)."""
        nx, ny, nz = self.n
        shape = [nx, ny, nz]
        shape[axis] += 1
        idx = np.indices(shape, dtype=np.float64).reshape(3, -1).T
        off = np.full(3, 0.5)
        off[axis] = 0.0
        pts = self.origin3 + (idx + off) * self.cell_size
        return np.ascontiguousarray(pts[:, :self.dim])

    def cell_positions(self):
        """(M, dim) cell-centre positions (C order of a scalar array)."""
        idx = np.indices(tuple(self.n), dtype=np.float64).reshape(3, -1).T
        pts = self.origin3 + (idx + 0.5) * self.cell_size
        return np.ascontiguousarray(pts[:, :self.dim])

    def vertex_positions(self):
        """(M, dim) grid-vertex (cell-corner) positions, C order of an (nx+1, ny+1[, nz+1]) array."""
        shape = tuple(self.n + 1) if self.dim == 3 else (int(self.n[0]) + 1, int(self.n[1]) + 1, 1)
        idx = np.indices(shape, dtype=np.float64).reshape(3, -1).T
        pts = self.origin3 + idx * self.cell_size
        return np.ascontiguousarray(pts[:, :self.dim])


class GridFluid:
    """A MAC-grid fluid (see the module docstring for the stages and references).

    Parameters
    ----------
    shape, cell_size, origin : the grid (`MACGrid`).
    boundaries : dict side -> boundary (see `inertia.fluids.grid.boundaries`); default no-slip
        walls everywhere.
    viscosity : kinematic viscosity nu, m^2/s, >= 0 (default 0: inviscid smoke).
    advection : "maccormack" (default) or "semi-lagrangian".
    pressure_solver : "mgpcg" (default), "cg" or "jacobi".
    tolerance : relative residual of the pressure solve, default 1e-6 (1e-4 for visuals).
    max_iterations : pressure-solver iteration cap (default 200 for the CG methods).
    scalars : names of the advected cell scalars; default ("density", "temperature").
    ambient_temperature : T_amb for buoyancy and the default inflow temperature (default 0).
    buoyancy : (alpha, beta), f = (-alpha density + beta (T - T_amb)) up, m/s^2 per unit; default (0, 0).
    up : the buoyancy direction (default +y in 2-D, +z in 3-D).
    body_acceleration : uniform acceleration on the fluid (gravity or a pressure gradient
        driving a channel), m/s^2; default zeros.
    dissipation : dict scalar name -> decay rate (1/s, >= 0).
    vorticity_confinement : epsilon >= 0 (default 0; 1-5 for visible swirls at 64-256 cells).
    cfl : CFL number for ``advance`` (default 1; at most 5).
    max_dt : largest substep in ``advance``, s (default inf).
    obstacles : list of colliders (``inertia.colliders``) of the grid's dimension.
    obstacle_slip : False (default: no-slip), True, or one bool per obstacle. A no-slip obstacle's
        surface velocity (v + w x r) is the Dirichlet value of the implicit viscosity at its cut
        position between grid nodes; a slip obstacle imposes only its normal velocity (zero shear).
        Only matters when viscosity > 0 (the projection imposes the normal velocity either way).
    parallel : None (default: parallel kernels from 65536 cells up), True or False.
    fluid_density : rho, kg/m^3 (default 1.2, air): converts the projection's phi = p dt / rho into
        the pressure that pushes rigid bodies (``advance(dt, rigid)``, see `bind_rigid`) and the
        pressure of `Pressure` sides (Pa) into phi.
    diffusivity : dict scalar name -> diffusivity kappa, m^2/s, >= 0 (default none: scalars are
        only advected). Backward Euler (I - kappa dt Lap) s = s* after the sources, the implicit
        viscosity's solver (unconditionally stable); walls and obstacles insulate (zero flux)
        unless a `Wall` holds the scalar's value (``Wall(temperature=...)``: a hot or cold wall),
        inflow sides hold their inflow values, outflow and pressure sides have zero gradient.
        Guidance: heat in air 2e-5, in water 1.4e-7, dye in water 1e-9 m^2/s; visual diffusion of
        smoke 1e-4..1e-2 at grid scales of 1/64..1/256 m (the numerical diffusion of the
        advection, about 0.01..0.04 h |u| for semi-Lagrangian, adds to it).
    obstacle_temperature : None (default: obstacles insulate), one temperature for every obstacle,
        or one entry per obstacle (a number or None). A held obstacle conducts heat into the
        fluid: its surface is a Dirichlet boundary of the temperature's diffusion at the cut
        position between a fluid cell centre and a solid one (ghost fluid, as the no-slip
        viscosity), and its cells keep the value (advection reads it there). Needs
        ``diffusivity["temperature"] > 0``.
    """

    def __init__(self, shape, cell_size, *, origin=None, boundaries=None, viscosity=0.0,
                 advection="maccormack", pressure_solver="mgpcg", tolerance=1e-6,
                 max_iterations=None, scalars=("density", "temperature"), ambient_temperature=0.0,
                 buoyancy=(0.0, 0.0), up=None, body_acceleration=None, dissipation=None,
                 vorticity_confinement=0.0, cfl=1.0, max_dt=np.inf, obstacles=(), obstacle_slip=False,
                 parallel=None, fluid_density=1.2, diffusivity=None, obstacle_temperature=None):
        self.grid = g = MACGrid(shape, cell_size, origin)
        if parallel not in (None, True, False):
            raise ValueError(f"parallel must be None (auto), True or False; got {parallel!r}")
        if parallel is None:
            parallel = int(np.prod(g.n)) >= K.PARALLEL_CELLS
        self.parallel = bool(parallel)
        self._k = K.KernelSet(K, self.parallel)
        self._kv = K.KernelSet(V, self.parallel)   # implicit viscosity (viscosity.py)
        dim = self.dim = g.dim
        self.viscosity = positive_scalar(viscosity, "viscosity", allow_zero=True)
        self.fluid_density = positive_scalar(fluid_density, "fluid_density")
        if advection not in ADVECTION:
            raise ValueError(f"advection must be one of {ADVECTION}; got {advection!r}")
        self.advection = advection
        if pressure_solver not in SOLVERS:
            raise ValueError(f"pressure_solver must be one of {SOLVERS}; got {pressure_solver!r}")
        tol = positive_scalar(tolerance, "tolerance")
        if tol >= 1:
            raise ValueError(f"tolerance must be in (0, 1); got {tolerance!r}")
        self.cfl = positive_scalar(cfl, "cfl")
        if self.cfl > MAX_CFL:
            raise ValueError(f"cfl must be in (0, {MAX_CFL}] (the back-trace uses one ghost layer "
                             f"and MacCormack's limiter needs the trace inside its stencil); got {cfl!r}")
        self.max_dt = positive_scalar(max_dt, "max_dt") if np.isfinite(max_dt) else np.inf
        self.vorticity_confinement = positive_scalar(vorticity_confinement, "vorticity_confinement",
                                                     allow_zero=True)
        self.ambient_temperature = float(ambient_temperature)
        b = np.asarray(buoyancy, dtype=np.float64).reshape(-1)
        if b.shape != (2,) or not np.all(np.isfinite(b)):
            raise ValueError(f"buoyancy must be (alpha, beta), two finite numbers; got {buoyancy!r}")
        self.buoyancy = (float(b[0]), float(b[1]))
        self.up = np.zeros(3)
        if up is None:
            self.up[dim - 1] = 1.0
        else:
            uv = as_vector(up, "up", dim)
            if np.linalg.norm(uv) == 0:
                raise ValueError("up must be a nonzero vector")
            self.up[:dim] = uv / np.linalg.norm(uv)
        self.body_acceleration = np.zeros(3)
        if body_acceleration is not None:
            self.body_acceleration[:dim] = as_vector(body_acceleration, "body_acceleration", dim)
        names = tuple(scalars)
        if len(set(names)) != len(names) or not all(isinstance(s, str) for s in names):
            raise ValueError(f"scalars must be distinct names; got {scalars!r}")
        reserved = sorted(set(names) & {"speed", "u", "v", "solid"})
        if reserved:  # the keys frame_arrays records beside the scalars
            raise ValueError(f"scalars must not be named {reserved}: 'speed', 'u', 'v' and 'solid' are recorded "
                             f"velocity keys; got {scalars!r}")
        self.scalar_names = names
        self.dissipation = {}
        for key, rate in (dissipation or {}).items():
            if key not in names:
                raise ValueError(f"dissipation has an unknown scalar {key!r}; scalars are {names}")
            self.dissipation[key] = positive_scalar(rate, f"dissipation[{key!r}]", allow_zero=True)
        self.diffusivity = {}
        if diffusivity is not None and not isinstance(diffusivity, dict):
            raise ValueError(f"diffusivity must be a dict scalar name -> kappa (m^2/s, >= 0); "
                             f"got {diffusivity!r}")
        for key, kappa in (diffusivity or {}).items():
            if key not in names:
                raise ValueError(f"diffusivity has an unknown scalar {key!r}; scalars are {names}")
            if isinstance(kappa, (bool, np.bool_)):
                raise ValueError(f"diffusivity[{key!r}] must be a number >= 0 (m^2/s); got {kappa!r}")
            kappa = positive_scalar(kappa, f"diffusivity[{key!r}]", allow_zero=True)
            if kappa > 0.0:
                self.diffusivity[key] = kappa
        self.sides = parse_boundaries(boundaries, dim)
        for key, b in enumerate(self.sides[:2 * dim]):
            held = dict(getattr(b, "scalars", {}) or {})
            for name in held:
                if name not in names:
                    raise ValueError(f"boundaries[{('x-', 'x+', 'y-', 'y+', 'z-', 'z+')[key]!r}].scalars has "
                                     f"an unknown scalar {name!r}; scalars are {names}")
        periodic = np.array([isinstance(self.sides[2 * a], Periodic) for a in range(3)])
        for a in range(dim):
            if periodic[a] and g.n[a] % 2:
                raise ValueError(f"shape[{a}] must be even on a periodic axis (red-black "
                                 f"smoothing); got {g.n[a]}")
        self.periodic = periodic
        self.ctx = K.GridContext(g.n, g.cell_size, g.origin3, dim, periodic,
                                 *self._ghost_rules())

        # -- state arrays (written by the stages named) -----------------------------------
        nx, ny, nz = (int(x) for x in g.n)
        fs = [(nx + 1, ny, nz), (nx, ny + 1, nz), (nx, ny, nz + 1)]
        self._face_shapes = fs
        # face velocities, m/s: advect, forces, diffuse, project
        self._vel = [np.zeros(s) for s in fs]
        self._vel_tmp = [np.zeros(s) for s in fs]   # advect output
        self._vel_fwd = [np.zeros(s) for s in fs]   # MacCormack scratch
        self._vel_bwd = [np.zeros(s) for s in fs]
        # MacCormack limiter bounds per node (u, v, w faces, cells): advect
        self._range_lo = [np.zeros(s) for s in fs] + [np.zeros((nx, ny, nz))]
        self._range_hi = [np.zeros(s) for s in fs] + [np.zeros((nx, ny, nz))]
        # padded copies (one ghost layer along the grid's axes) read by the advection
        padz = 2 if dim == 3 else 0
        pshape = [(a + 2, b + 2, c + padz) for a, b, c in fs + [(nx, ny, nz)]]
        self._vel_pad = [np.zeros(s) for s in pshape[:3]]
        self._cell_pad = np.zeros(pshape[3])
        self._fwd_pad = [np.zeros(s) for s in pshape]
        self._offsets = [np.array([0.0 if a == c else 0.5 for c in range(3)]) for a in range(3)]
        self._offsets.append(np.full(3, 0.5))
        # cell scalars: advect, forces (sources), dissipate
        self._scal = [np.zeros((nx, ny, nz)) for _ in names]
        self._scal_tmp = [np.zeros((nx, ny, nz)) for _ in names]
        self._cell_fwd = np.zeros((nx, ny, nz))
        self._cell_bwd = np.zeros((nx, ny, nz))
        # the second scalar of a pair advected along one back-trace (`_advect_pair`)
        if len(names) >= 2:
            self._cell_pad2 = np.zeros(pshape[3])
            self._fwd_pad2 = np.zeros(pshape[3])
            self._cell_fwd2 = np.zeros((nx, ny, nz))
            self._cell_bwd2 = np.zeros((nx, ny, nz))
            self._range_lo2 = np.zeros((nx, ny, nz))
            self._range_hi2 = np.zeros((nx, ny, nz))
        # open fractions and solid velocities of faces: obstacles stage
        self._frac = [np.ones(s) for s in fs]
        self._solid = [np.zeros(s) for s in fs]
        # projection: weighted divergence (1/s), phi = p dt / rho (m^2/s)
        self.divergence = np.zeros((nx, ny, nz))
        self.phi = np.zeros((nx, ny, nz))
        # viscous flow (incremental pressure correction): the last step's pressure increment (the
        # next increment's initial guess) and the dt phi was computed with (0: no pressure yet)
        self._phi_inc = np.zeros((nx, ny, nz))
        self._phi_dt = 0.0
        self._rhs = np.zeros((nx, ny, nz))
        self._force = np.zeros((nx, ny, nz, 3))
        self._vort = np.zeros((nx, ny, nz, 3))
        self._partial = np.zeros(max(nx, ny, nz) + 2)
        self.pressure = PoissonSolver((nx, ny, nz), periodic, method=pressure_solver,
                                      tolerance=tol, max_iterations=max_iterations,
                                      parallel=self.parallel)
        # implicit viscosity: node kinds (V.FREE, FIXED, NO_SLIP, SLIP) per component (obstacles
        # stage); node signed distance, solid velocity and owning obstacle where no-slip obstacles
        # exist (allocated on first need)
        self._vkind = [np.zeros(s, dtype=np.int8) for s in fs]
        self._vsdf = [np.zeros((1, 1, 1)) for _ in fs]
        self._vwall = [np.zeros((1, 1, 1)) for _ in fs]
        self._vowner = [np.full((1, 1, 1), -1, np.int64) for _ in fs]
        self._no_slip_nodes = False
        self.obstacle_viscous_force = np.zeros((0, 3))    # N, last step, per obstacle (_diffuse)
        self.obstacle_viscous_torque = np.zeros((0, 3))   # N m about each obstacle's reference
        self._visc_impulse = (np.zeros((0, 3)), np.zeros((0, 3)))
        self._cg = [[np.zeros(s) for _ in range(4)] for s in fs]
        # scalar diffusion (diffuse stage): (scalar index, kappa) of each diffusing scalar, the
        # node kinds of the cells (V.FREE; V.AIR, a zero-flux neighbour, in solid cells: written
        # by the obstacles stage) and four CG vectors; allocated only when a scalar diffuses
        self._diffusing = [(names.index(n), kappa) for n, kappa in self.diffusivity.items()]
        self._skind = np.zeros((nx, ny, nz) if self._diffusing else (1, 1, 1), dtype=np.int8)
        self._scg = [np.zeros((nx, ny, nz) if self._diffusing else (1, 1, 1)) for _ in range(4)]
        self._no_node_data = np.zeros((1, 1, 1))   # sdf / wall arrays of a solve without NO_SLIP nodes
        self.sources = []
        self.time = 0.0
        self.step_index = 0
        self.profile = {}

        # -- obstacles ---------------------------------------------------------------------
        self.obstacles = list(obstacles)
        for o in self.obstacles:
            if getattr(o, "dim", None) != dim or not hasattr(o, "signed_distance"):
                raise ValueError(f"obstacles must be colliders with dim {dim} "
                                 f"(signed_distance, velocity); got {o!r}")
        self._moving = any(getattr(o, "motion", None) is not None for o in self.obstacles)
        self._slip = V.slip_flags(obstacle_slip, len(self.obstacles), "obstacle_slip")
        self._held = self._held_temperatures(obstacle_temperature)   # (n_obstacles,) or None
        self._rigid_slip = False
        self._cells = None            # the obstacles stage's work arrays (`CutCells`, on first need)
        self._cell_solid = np.zeros((nx, ny, nz), dtype=np.bool_)
        # rigid bodies (bind_rigid): one BodyShape obstacle per supported shape row
        self._rigid = None
        self._rigid_obstacles = []
        self._owner_body = np.zeros(0, np.int64)      # body of each shape-row obstacle
        self._obstacles_changed()
        # per-step work arrays of the obstacles and diffuse stages: closed faces of each axis
        # (the first `_closed` of them), domain-side face nodes the viscosity leaves alone
        self._closed_buf = [np.zeros(int(np.prod(s)), np.int64) for s in fs]
        self._side_values = [(axis, sd, self._side_normal_velocity(axis, sd))
                             for axis in range(dim) for sd in range(2)
                             if not isinstance(self.sides[2 * axis + sd], OPEN_SIDES)]
        self._check_outlet()
        # pressure sides (`Pressure`): (axis, side, pressure in Pa) of the projection's Dirichlet data
        self._pressure_sides = [(axis, sd, float(self.sides[2 * axis + sd].pressure))
                                for axis in range(dim) for sd in range(2)
                                if isinstance(self.sides[2 * axis + sd], Pressure)]
        self._vedge = []
        for a in range(3):
            edge = np.zeros(fs[a], dtype=np.bool_)
            idx = [slice(None)] * 3
            for end in (0, -1):
                idx[a] = end
                if not isinstance(self.sides[2 * a + (0 if end == 0 else 1)], OPEN_SIDES):
                    edge[tuple(idx)] = True
            self._vedge.append(edge.reshape(-1))
        # closed obstacle faces (obstacles stage): flat face index, open fraction, owner body
        self._cut = [(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)) for _ in range(3)]
        self.body_force = np.zeros((0, 3))            # N, last substep's pressure force (project)
        self.body_torque = np.zeros((0, 3))           # N m, about each body's centre of mass
        self._update_solids(0.0, check_domain=True)

    # ------------------------------------------------------------------------ boundary data
    def _ghost_rules(self):
        nsl = 3 + len(self.scalar_names)
        kind = np.zeros((nsl, 3, 2), dtype=np.int64)
        value = np.zeros((nsl, 3, 2))
        for axis in range(3):
            for sd in range(2):
                b = self.sides[2 * axis + sd]
                if isinstance(b, Periodic):
                    kind[:, axis, sd] = K.PERIODIC
                    continue
                v = side_velocity(b, self.dim)
                for c in range(3):
                    if c == axis:
                        kind[c, axis, sd] = K.NEUMANN  # clamp along the face's own axis
                    elif isinstance(b, Inflow) or (isinstance(b, Wall) and not b.slip):
                        kind[c, axis, sd] = K.DIRICHLET
                        value[c, axis, sd] = v[c]
                    else:
                        kind[c, axis, sd] = K.NEUMANN
                for s, name in enumerate(self.scalar_names):
                    if isinstance(b, Inflow):
                        kind[3 + s, axis, sd] = K.DIRICHLET
                        value[3 + s, axis, sd] = self._inflow_scalar(b, name)
                    elif isinstance(b, Wall) and self._wall_scalar(b, name) is not None:
                        kind[3 + s, axis, sd] = K.DIRICHLET   # a wall holding the scalar (hot wall)
                        value[3 + s, axis, sd] = self._wall_scalar(b, name)
                    else:
                        kind[3 + s, axis, sd] = K.NEUMANN
        return kind, value

    @staticmethod
    def _wall_scalar(b, name):
        """The value a wall holds scalar `name` at, or None (insulating)."""
        if name in b.scalars:
            return float(b.scalars[name])
        if name == "temperature" and b.temperature is not None:
            return float(b.temperature)
        return None

    def _side_normal_velocity(self, axis, sd):
        """Normal velocity of a closed side's boundary faces: a number (walls, uniform inflow) or
        the (n1, n2) face layer of an inflow profile (`Inflow.profile`)."""
        b = self.sides[2 * axis + sd]
        un = float(side_velocity(b, self.dim)[axis])
        if not isinstance(b, Inflow) or (isinstance(b.profile, str) and b.profile == "uniform"):
            return un
        g = self.grid
        layer = [slice(None)] * 3
        layer[axis] = 0 if sd == 0 else -1
        shape = self._face_shapes[axis]
        pts = g.face_positions(axis).reshape(shape + (self.dim,))[tuple(layer)]
        lshape = pts.shape[:-1]
        pts = np.ascontiguousarray(pts.reshape(-1, self.dim))
        key = f"boundaries[{('x-', 'x+', 'y-', 'y+', 'z-', 'z+')[2 * axis + sd]!r}].profile"
        if callable(b.profile):
            speed = np.asarray(b.profile(pts.copy()), dtype=np.float64)
            if speed.shape != (pts.shape[0],) or not np.all(np.isfinite(speed)):
                raise ValueError(f"{key} must return {pts.shape[0]} finite speeds (one per face of the "
                                 f"side, shape ({pts.shape[0]},)); got shape {speed.shape}")
        else:   # parabolic: mean un, zero on the edges of each non-periodic tangential axis
            speed = np.full(pts.shape[0], un)
            for t in range(self.dim):
                if t != axis and not self.periodic[t]:
                    x = (pts[:, t] - g.origin[t]) / g.size[t]
                    speed *= 6.0 * x * (1.0 - x)
        return speed.reshape(lshape)

    def _check_outlet(self):
        """A net inflow needs a side where the fluid can leave (an outflow or pressure side)."""
        if any(isinstance(b, (Outflow, Pressure)) for b in self.sides[:2 * self.dim]):
            return
        h = self.grid.cell_size
        net = 0.0
        for axis, sd, value in self._side_values:
            if isinstance(self.sides[2 * axis + sd], Inflow):
                layer = np.broadcast_to(value, tuple(np.delete(self.grid.n, axis)))
                net += (1.0 if sd == 0 else -1.0) * float(np.sum(layer)) * h ** (self.dim - 1)
        if abs(net) > 0.0:
            raise ValueError(f"boundaries: the inflow sides bring a net {net:.6g} m^{self.dim}/s into a closed "
                             f"domain; add an Outflow() or Pressure() side where the fluid can leave")

    def _inflow_scalar(self, b, name):
        if name in b.scalars:
            return float(b.scalars[name])
        if name == "density":
            return float(b.density)
        if name == "temperature":
            return self.ambient_temperature if b.temperature is None else float(b.temperature)
        return 0.0

    def _held_temperatures(self, obstacle_temperature):
        """Per-obstacle temperature (NaN: insulating) from `obstacle_temperature`, or None when
        no obstacle holds one; allocates the temperature's own node kinds, distances and values."""
        if obstacle_temperature is None:
            return None
        n = len(self.obstacles)
        key = "obstacle_temperature"
        items = [obstacle_temperature] * n if not isinstance(obstacle_temperature, (list, tuple)) \
            else list(obstacle_temperature)
        if len(items) != n:
            raise ValueError(f"{key} must be None, one number, or {n} entries (one per obstacle, a number or "
                             f"None); got {obstacle_temperature!r}")
        held = np.full(n, np.nan)
        for i, x in enumerate(items):
            if x is None:
                continue
            if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)) \
                    or not np.isfinite(x):
                raise ValueError(f"{key}[{i}] must be a finite number or None; got {x!r}")
            held[i] = float(x)
        if not np.any(np.isfinite(held)):
            return None
        if "temperature" not in self.diffusivity:
            raise ValueError(f"{key} needs the temperature to diffuse: give diffusivity={{'temperature': "
                             f"kappa}} (m^2/s, > 0) and a 'temperature' scalar")
        shape = tuple(int(x) for x in self.grid.n)
        self._tkind = np.zeros(shape, dtype=np.int8)
        self._tsdf = np.zeros(shape)
        self._twall = np.zeros(shape)
        return held

    def _obstacles_changed(self):
        """After the obstacle list changed (constructor, `bind_rigid`): the body of every obstacle
        (-1: a collider), the slip flags, the viscous-torque reference points, the work arrays."""
        n0 = len(self.obstacles)
        nall = n0 + len(self._rigid_obstacles)
        self._obstacle_body = np.concatenate([np.full(n0, -1, np.int64), self._owner_body])
        self._slip_all = np.array(self._slip + [self._rigid_slip] * len(self._rigid_obstacles),
                                  dtype=np.bool_)
        self._refs = np.zeros((nall, 3))
        if nall and self._cells is None:
            g = self.grid
            vshape = tuple(g.n + 1) if self.dim == 3 else (int(g.n[0]) + 1, int(g.n[1]) + 1, 1)
            self._cells = CutCells(g.vertex_positions(), vshape,
                                   [g.face_positions(a) for a in range(self.dim)], g.cell_positions(),
                                   self.dim, self.parallel)

    def _update_solids(self, t, check_domain=False):
        """Face fractions and solid velocities from the domain sides and the obstacles
        (`obstacles.CutCells`: nothing allocated)."""
        g = self.grid
        dim = self.dim
        obstacles = self.obstacles + self._rigid_obstacles
        if obstacles:
            visc = self.viscosity > 0.0
            cc = self._cells
            cc.update(obstacles, self._obstacle_body, t, self._frac, self._solid, self._cell_solid,
                      nodes=visc, cells=self._held is not None)
            if check_domain and np.all(cc.vertex_sdf < 0):
                raise ValueError("obstacles cover the whole domain")
            if check_domain:
                for i, o in enumerate(self.obstacles):
                    d = o.signed_distance(cc.vertex_pts, t)
                    if np.all(d > 0) and not self._inside_domain(o, t):
                        raise ValueError(f"obstacles[{i}] lies outside the domain "
                                         f"{g.origin3[:dim].tolist()} + {g.size[:dim].tolist()}")
            for a in range(dim):
                if visc:
                    self._viscous_nodes(a, cc.best[a], cc.near_vel[a], cc.near[a])
                self._cut[a] = cc.cut[a]
        else:
            for a in range(3):
                self._frac[a][...] = 1.0
                self._solid[a][...] = 0.0
        if dim == 2:
            self._frac[2][...] = 0.0
        # domain sides: walls and inflows close their boundary faces and impose the velocity
        for axis, sd, value in self._side_values:
            idx = [slice(None)] * 3
            idx[axis] = 0 if sd == 0 else -1
            self._frac[axis][tuple(idx)] = 0.0
            self._solid[axis][tuple(idx)] = value
        if self._diffusing:   # cells inside obstacles insulate (zero flux)
            K.cell_node_kinds(self._cell_solid, V.AIR, V.FREE, self._skind)
        if self._held is not None:   # the temperature: held obstacles are Dirichlet (ghost fluid)
            if obstacles:
                held = self._held_all()
                K.held_cell_kinds(self._cell_solid.reshape(-1), self._cells.cell_best, self._cells.cell_near, held,
                                  V.FREE, V.AIR, V.NO_SLIP, self._tkind.reshape(-1), self._tsdf.reshape(-1),
                                  self._twall.reshape(-1))
            else:
                self._tkind[...] = V.FREE
        self.pressure.set_coefficients(*self._frac, g.cell_size, dim,
                                       [(axis, sd) for axis, sd, _ in self._pressure_sides])
        self._closed = [self._closed_buf[a][:_closed_faces(self._frac[a].reshape(-1), self._closed_buf[a])]
                        for a in range(3)]
        # node kinds of the implicit viscosity
        self._no_slip_nodes = False
        for a in range(3):
            kind = self._vkind[a]
            V.fixed_where_closed(self._frac[a].reshape(-1), kind.reshape(-1))
            if self.viscosity > 0.0 and obstacles and a < dim:
                self._viscous_kinds(a)
            if self.periodic[a]:
                idx = [slice(None)] * 3
                idx[a] = -1
                kind[tuple(idx)] = V.FIXED  # the duplicate of face 0
        self._enforce()

    def _viscous_nodes(self, a, best, vel, owner):
        """Store the component-a face nodes' signed distance, solid velocity and nearest obstacle,
        and which of them lie inside a no-slip obstacle (for `_viscous_kinds`)."""
        shape = self._face_shapes[a]
        if self._vsdf[a].shape != shape:
            self._vsdf[a] = np.zeros(shape)
            self._vwall[a] = np.zeros(shape)
            self._vowner[a] = np.full(shape, -1, np.int64)
        self._vsdf[a].reshape(-1)[...] = best
        self._vwall[a].reshape(-1)[...] = vel
        self._vowner[a].reshape(-1)[...] = owner

    def _viscous_kinds(self, a):
        """NO_SLIP / SLIP kinds of the component-a face nodes inside obstacles."""
        best = self._vsdf[a].reshape(-1)
        owner = self._vowner[a].reshape(-1)
        # domain-side faces stay FIXED (their value is the wall's or the inflow's): `_vedge`
        any_no_slip = V.obstacle_node_kinds(self._vkind[a].reshape(-1), best, owner, self._slip_all,
                                            self._vedge[a])
        self._no_slip_nodes = self._no_slip_nodes or any_no_slip

    def _inside_domain(self, o, t):
        pts = self.grid.cell_positions()
        return bool(np.any(np.asarray(o.signed_distance(pts, t)) < self.grid.cell_size))

    # ------------------------------------------------------------------------ public arrays
    def _view(self, a):
        return a[:, :, 0] if self.dim == 2 else a

    @property
    def u(self):
        """x-velocity on x-faces, m/s: (nx+1, ny) in 2-D, (nx+1, ny, nz) in 3-D (a view)."""
        return self._view(self._vel[0])

    @property
    def v(self):
        """y-velocity on y-faces, m/s: (nx, ny+1) / (nx, ny+1, nz) (a view)."""
        return self._view(self._vel[1])

    @property
    def w(self):
        """z-velocity on z-faces, m/s: (nx, ny, nz+1), 3-D only (a view)."""
        if self.dim == 2:
            raise AttributeError("w exists only on 3-D grids")
        return self._vel[2]

    def scalar(self, name):
        """Cell-centred scalar `name`: (nx, ny) / (nx, ny, nz) view."""
        if name not in self.scalar_names:
            raise ValueError(f"name must be one of the scalars {self.scalar_names}; got {name!r}")
        return self._view(self._scal[self.scalar_names.index(name)])

    @property
    def face_fractions(self):
        """Open fractions (u faces, v faces[, w faces]) in [0, 1] (views; written by the
        obstacles stage)."""
        return tuple(self._view(f) for f in self._frac[:self.dim])

    def set_velocity(self, function):
        """Set every face velocity from ``function(points (M, dim)) -> (M, dim)`` sampled at
        the face centres, then re-impose the boundary values."""
        for a in range(self.dim):
            pts = self.grid.face_positions(a)
            val = np.asarray(function(pts), dtype=np.float64)
            if val.shape != pts.shape:
                raise ValueError(f"function must return an array of shape {pts.shape}; got {val.shape}")
            self._vel[a][...] = val[:, a].reshape(self._face_shapes[a])
        self._enforce()

    def add_source(self, lower, upper, *, density_rate=0.0, temperature_rate=0.0,
                   acceleration=None, scalar_rates=None):
        """A box [lower, upper] (metres) that adds scalar per second (density_rate,
        temperature_rate, or scalar_rates {name: rate}) to its cells and `acceleration`
        (m/s^2) to the velocity on its faces, every step."""
        lo = as_vector(lower, "lower", self.dim)
        hi = as_vector(upper, "upper", self.dim)
        if np.any(hi <= lo):
            raise ValueError(f"upper must exceed lower on every axis; got {lower!r}, {upper!r}")
        rates = dict(scalar_rates or {})
        if density_rate:
            rates["density"] = density_rate
        if temperature_rate:
            rates["temperature"] = temperature_rate
        for k in rates:
            if k not in self.scalar_names:
                raise ValueError(f"scalar_rates has an unknown scalar {k!r}; scalars are {self.scalar_names}")
        cells = self.grid.cell_positions()
        inside = np.all((cells >= lo) & (cells <= hi), axis=1)
        cell_idx = np.flatnonzero(inside)
        faces = []
        if acceleration is not None:
            acc = as_vector(acceleration, "acceleration", self.dim)
            for a in range(self.dim):
                pts = self.grid.face_positions(a)
                idx = np.flatnonzero(np.all((pts >= lo) & (pts <= hi), axis=1))
                faces.append((a, idx, float(acc[a])))
        if cell_idx.size == 0:
            raise ValueError(f"the source box {lo.tolist()}..{hi.tolist()} contains no cell centre")
        self.sources.append((cell_idx, [(self.scalar_names.index(k), float(r)) for k, r in rates.items()],
                             faces))

    # ------------------------------------------------------------------------ stages
    def _enforce(self):
        """Closed faces take the solid's (wall's, inflow's) velocity; a periodic axis copies face 0
        to face n (`K.enforce_faces`, over the closed-face lists of the obstacles stage)."""
        for a in range(3):
            vel = self._vel[a]
            K.enforce_closed(vel.reshape(-1), self._closed[a], self._solid[a].reshape(-1))
            if self.periodic[a]:
                _wrap_periodic(vel, a)

    def _advect(self, dt):
        g = self.ctx
        k = self._k
        for a in range(3):
            if a < self.dim:
                k.pad(self._vel[a], a, g, self._vel_pad[a])
        up, vp, wp = self._vel_pad
        for a in range(self.dim):
            self._advect_one(self._vel[a], self._vel_pad[a], a, up, vp, wp, dt, self._vel_tmp[a],
                             self._vel_fwd[a], self._vel_bwd[a])
        ns = len(self._scal)
        for s in range(0, ns - 1, 2):
            self._advect_pair(s, up, vp, wp, dt)
        if ns % 2:
            s = ns - 1
            k.pad(self._scal[s], 3 + s, g, self._cell_pad)
            self._advect_one(self._scal[s], self._cell_pad, 3 + s, up, vp, wp, dt, self._scal_tmp[s],
                             self._cell_fwd, self._cell_bwd)
        for a in range(self.dim):
            self._vel[a], self._vel_tmp[a] = self._vel_tmp[a], self._vel[a]
        for s in range(len(self._scal)):
            self._scal[s], self._scal_tmp[s] = self._scal_tmp[s], self._scal[s]
        self._enforce()

    def _advect_one(self, src, src_pad, slot, up, vp, wp, dt, dst, fwd, bwd):
        """Advect the padded field `src_pad` of `slot` into dst (fwd, bwd: MacCormack scratch)."""
        g = self.ctx
        k = self._k
        h = self.grid.cell_size
        off = self._offsets[min(slot, 3)]
        if self.advection == "semi-lagrangian":
            k.advect_padded(src_pad, up, vp, wp, dt / h, off, g.n, g.periodic, self.dim, dst,
                            dst, dst, False)
            return
        i = min(slot, 3)
        lo, hi, fwd_pad = self._range_lo[i], self._range_hi[i], self._fwd_pad[i]
        k.advect_padded(src_pad, up, vp, wp, dt / h, off, g.n, g.periodic, self.dim, fwd,
                        lo, hi, True)
        k.pad(fwd, slot, g, fwd_pad)
        k.advect_padded(fwd_pad, up, vp, wp, -dt / h, off, g.n, g.periodic, self.dim, bwd,
                        bwd, bwd, False)
        k.maccormack_combine(src, fwd, bwd, lo, hi, dst)

    def _advect_pair(self, s, up, vp, wp, dt):
        """Scalars s and s + 1 along one back-trace (`K.advect_padded_pair`; the same result as
        two `_advect_one` calls)."""
        g = self.ctx
        k = self._k
        h = self.grid.cell_size
        off = self._offsets[3]
        a, b = self._scal[s], self._scal[s + 1]
        da, db = self._scal_tmp[s], self._scal_tmp[s + 1]
        pa, pb = self._cell_pad, self._cell_pad2
        k.pad(a, 3 + s, g, pa)
        k.pad(b, 4 + s, g, pb)
        if self.advection == "semi-lagrangian":
            k.advect_padded_pair(pa, pb, up, vp, wp, dt / h, off, g.n, g.periodic, self.dim, da, db,
                                 da, da, db, db, False)
            return
        fa, fb, ba, bb = self._cell_fwd, self._cell_fwd2, self._cell_bwd, self._cell_bwd2
        loa, hia, lob, hib = self._range_lo[3], self._range_hi[3], self._range_lo2, self._range_hi2
        k.advect_padded_pair(pa, pb, up, vp, wp, dt / h, off, g.n, g.periodic, self.dim, fa, fb,
                             loa, hia, lob, hib, True)
        k.pad(fa, 3 + s, g, self._fwd_pad[3])
        k.pad(fb, 4 + s, g, self._fwd_pad2)
        k.advect_padded_pair(self._fwd_pad[3], self._fwd_pad2, up, vp, wp, -dt / h, off, g.n,
                             g.periodic, self.dim, ba, bb, ba, ba, bb, bb, False)
        k.maccormack_combine(a, fa, ba, loa, hia, da)
        k.maccormack_combine(b, fb, bb, lob, hib, db)

    def _forces(self, dt):
        f = self._force
        need = False
        f[...] = 0.0
        if np.any(self.body_acceleration):
            f[...] += self.body_acceleration
            need = True
        alpha, beta = self.buoyancy
        if (alpha or beta) and "density" in self.scalar_names and "temperature" in self.scalar_names:
            self._k.buoyancy_force(self._scal[self.scalar_names.index("density")],
                             self._scal[self.scalar_names.index("temperature")], alpha, beta,
                             self.ambient_temperature, self.up, f)
            need = True
        if self.vorticity_confinement > 0:
            u, v, w = self._vel
            self._k.cell_velocity_and_vorticity(u, v, w, self.ctx, self._vort)
            vf = self._vort  # reuse: confinement writes into a separate buffer below
            conf = self._conf if hasattr(self, "_conf") else None
            if conf is None:
                conf = self._conf = np.zeros_like(f)
            self._k.confinement_force(vf, self.vorticity_confinement, self.ctx, conf)
            f += conf
            need = True
        if need:
            for a in range(self.dim):
                self._k.add_cell_force(f, dt, a, self._frac[a], self.ctx, self._vel[a])
        for cell_idx, rates, faces in self.sources:
            for s, r in rates:
                _add_at(self._scal[s].reshape(-1), cell_idx, r * dt)
            for a, idx, acc in faces:
                _add_at(self._vel[a].reshape(-1), idx, acc * dt)
        self._enforce()

    def _held_all(self):
        """Held temperatures of all obstacles, shape rows of a rigid world insulating."""
        extra = len(self._rigid_obstacles)
        if extra == 0:
            return self._held
        if getattr(self, "_held_cache", None) is None or self._held_cache.shape[0] != self._held.shape[0] + extra:
            self._held_cache = np.concatenate([self._held, np.full(extra, np.nan)])
        return self._held_cache

    def _diffuse(self, dt):
        """Implicit viscosity of the velocity (viscosity > 0), then implicit diffusion of every
        scalar with a diffusivity: (I - kappa dt Lap) s = s* (`viscosity.solve_component`, the
        same CG and operator with the scalar's slot: its ghost rules are the sides' boundary
        conditions; solid cells are zero-flux neighbours)."""
        if self.viscosity > 0.0:
            self._diffuse_velocity(dt)
        h2 = self.grid.cell_size ** 2
        for s, kappa in self._diffusing:
            if self._held is not None and self.scalar_names[s] == "temperature":
                kind, sdf, wall = self._tkind, self._tsdf, self._twall
            else:
                kind, sdf, wall = self._skind, self._no_node_data, self._no_node_data
            V.solve_component(self._kv, self._k, self._scal[s], kind, sdf, wall, 3 + s, kappa * dt / h2,
                              self.ctx, self._scg, self._partial)

    def _diffuse_velocity(self, dt):
        g = self.ctx
        coef = self.viscosity * dt / (self.grid.cell_size ** 2)
        nobst = len(self.obstacles) + len(self._rigid_obstacles)
        if self._no_slip_nodes:
            lin, ang = self._visc_impulse
            if lin.shape[0] != nobst:
                lin, ang = self._visc_impulse = (np.zeros((nobst, 3)), np.zeros((nobst, 3)))
                self.obstacle_viscous_force = np.zeros((nobst, 3))
                self.obstacle_viscous_torque = np.zeros((nobst, 3))
            lin[...] = 0.0
            ang[...] = 0.0
            ref = self._obstacle_refs()
        for a in range(self.dim):
            x = self._vel[a]
            kind, sdf, wall = self._vkind[a], self._vsdf[a], self._vwall[a]
            V.solve_component(self._kv, self._k, x, kind, sdf, wall, a, coef, g, self._cg[a],
                              self._partial_for(x))
            if self._no_slip_nodes:
                scale = self.fluid_density * self.grid.cell_size ** self.dim * coef
                V.wall_shear_impulses(x, kind, sdf, wall, self._vowner[a], a, scale, g, ref,
                                      lin, ang)
        if self._no_slip_nodes:   # (arrays written in place: hold a .copy() across steps)
            np.divide(lin, dt, out=self.obstacle_viscous_force)
            np.divide(ang, dt, out=self.obstacle_viscous_torque)
        self._enforce()

    def _obstacle_refs(self):
        """(n_obstacles, 3) reference points of the viscous torques: a collider's reference point
        (its pose at the current time), a shape row's body centre of mass (written into the
        array `_obstacles_changed` made)."""
        refs = self._refs
        for i, o in enumerate(self.obstacles):
            if hasattr(o, "pose"):
                refs[i, :] = np.asarray(o.pose(self.time)[0], dtype=np.float64).reshape(-1)[:3]
        if self._rigid is not None:
            body_q = self._rigid.state.body_q
            for i, b in enumerate(self._owner_body):
                if b >= 0:
                    refs[len(self.obstacles) + i] = body_q[b, :3]
        return refs

    def _partial_for(self, a):
        return self._partial

    def project(self, dt=None):
        """Make the velocity divergence-free (weighted by the face fractions); returns the
        pressure-solver iteration count. dt scales the stored pressure (phi = p dt / rho) and is
        required when a side has a prescribed pressure (`Pressure`)."""
        u, v, w = self._vel
        fu, fv, fw = self._frac
        su, sv, sw = self._solid
        self._k.weighted_divergence(u, v, w, fu, fv, fw, su, sv, sw, self.ctx, self.divergence)
        np.negative(self.divergence, out=self._rhs)
        if self._pressure_sides:
            if dt is None:
                raise ValueError("dt is required by project() when a side has a prescribed pressure")
            self._pressure_side_data(dt, rhs=True)
        it = self.pressure.solve(self._rhs, self.phi)
        self._k.subtract_gradient(self.phi, fu, fv, fw, self.ctx, u, v, w)
        if self._pressure_sides:
            self._pressure_side_data(dt, phi=self.phi)
        self._enforce()
        return it

    def _pressure_side_data(self, dt, rhs=False, phi=None):
        """Prescribed-pressure sides (phi_b = p dt / rho on the side's faces, 0 for an increment:
        dt = 0): their share of the Poisson right-hand side (rhs=True), or the rest of the face
        gradient of `phi` after `subtract_gradient` (`K.pressure_side_rhs`, `pressure_side_gradient`)."""
        h = self.grid.cell_size
        for axis, sd, p in self._pressure_sides:
            value = p * dt / self.fluid_density
            if rhs:
                K.pressure_side_rhs(self._frac[axis], axis, sd, value, 1.0 / (h * h), self._rhs)
            else:
                K.pressure_side_gradient(phi, self._frac[axis], axis, sd, value, 1.0 / h, self._vel[axis])

    def _pressure_predictor(self, dt):
        """Incremental pressure correction (Van Kan 1986; Brown, Cortez and Minion 2001): the
        viscous solve sees the last step's pressure gradient (phi rescaled to this dt), so at a
        steady state the projection after it has nothing left to change and the no-slip values
        the viscous solve imposed on obstacle surfaces stay (a plain viscosity-then-projection
        splitting leaves a tangential wall velocity of dt times the pressure gradient)."""
        if dt != self._phi_dt:
            self.phi *= dt / self._phi_dt
        u, v, w = self._vel
        self._k.subtract_gradient(self.phi, *self._frac, self.ctx, u, v, w)
        if self._pressure_sides:
            self._pressure_side_data(dt, phi=self.phi)
        self._enforce()

    def _project_increment(self):
        """Projection of the predicted velocity: solve for the pressure increment (initial guess:
        the last increment), subtract its gradient, add it to phi."""
        u, v, w = self._vel
        fu, fv, fw = self._frac
        su, sv, sw = self._solid
        self._k.weighted_divergence(u, v, w, fu, fv, fw, su, sv, sw, self.ctx, self.divergence)
        np.negative(self.divergence, out=self._rhs)
        it = self.pressure.solve(self._rhs, self._phi_inc)
        self._k.subtract_gradient(self._phi_inc, fu, fv, fw, self.ctx, u, v, w)
        if self._pressure_sides:   # the increment is 0 on the sides (phi_b follows dt)
            self._pressure_side_data(0.0, phi=self._phi_inc)
        self.phi += self._phi_inc
        self._enforce()
        return it

    def measure_divergence(self):
        """Weighted divergence of the current face velocities, (nx, ny[, nz]) 1/s (a new array;
        zero up to the pressure tolerance right after a step)."""
        out = np.zeros(tuple(self.grid.n))
        u, v, w = self._vel
        self._k.weighted_divergence(u, v, w, *self._frac, *self._solid, self.ctx, out)
        return self._view(out).copy()

    def _dissipate(self, dt):
        for name, rate in self.dissipation.items():
            if rate > 0:
                a = self._scal[self.scalar_names.index(name)]
                self._k.scale_decay(a.reshape(-1), math.exp(-rate * dt))
        if self.obstacles:
            for a in self._scal:
                np.copyto(a, 0.0, where=self._cell_solid)
            if self._held is not None:   # held obstacles keep their temperature in their cells
                K.copy_where_kind(self._tkind.reshape(-1), V.NO_SLIP, self._twall.reshape(-1),
                                  self._scal[self.scalar_names.index("temperature")].reshape(-1))

    # ------------------------------------------------------------------------ stepping
    def step(self, dt):
        """Advance by dt seconds (one step, no CFL check)."""
        dt = positive_scalar(dt, "dt")
        if self._moving:
            self._update_solids(self.time + dt)
        self._advect(dt)
        self._forces(dt)
        incremental = self.viscosity > 0.0 and self._phi_dt > 0.0
        if incremental:
            self._pressure_predictor(dt)
        self._diffuse(dt)
        if incremental:
            self.last_pressure_iterations = self._project_increment()
        else:
            self.last_pressure_iterations = self.project(dt)
        self._phi_dt = dt
        if self._rigid is not None:
            self._push_bodies(dt)
        self._dissipate(dt)
        self._check_finite()
        self.time += dt
        self.step_index += 1

    def max_speed(self):
        return max(self._k.max_abs(self._vel[a], self._partial) for a in range(self.dim))

    def stable_dt(self):
        """dt = cfl h / max|u| (max_dt when the fluid is at rest)."""
        vmax = self.max_speed()
        if vmax == 0.0:
            return self.max_dt if np.isfinite(self.max_dt) else self.grid.cell_size
        return min(self.cfl * self.grid.cell_size / vmax, self.max_dt)

    def advance(self, frame_dt, rigid=None):
        """Advance by frame_dt seconds in CFL-limited substeps; returns the substep count.

        `rigid` is the World protocol's RigidWorld argument (docs/contracts.md): when given (and
        it has shape rows) its shapes are obstacles of a 3-D grid at the bodies' current poses and
        velocities, and the fluid's pressure pushes its dynamic bodies (`bind_rigid`)."""
        frame_dt = positive_scalar(frame_dt, "frame_dt")
        if rigid is not None and rigid is not self._rigid and self.dim == 3:
            self.bind_rigid(rigid)   # (2-D grids ignore the 3-D rigid world)
        done = 0.0
        n = 0
        while done < frame_dt * (1 - 1e-12):
            dt = min(self.stable_dt(), frame_dt - done)
            remaining = frame_dt - done - dt
            if 0 < remaining < 0.1 * dt:  # avoid a sliver of a last substep
                dt = 0.5 * (frame_dt - done)
            check_substep_runaway("grid fluid", n, done, frame_dt, self.max_speed(), step=self.step_index,
                                  time=self.time, dt=dt)
            self.step(dt)
            done += dt
            n += 1
        return n

    # ------------------------------------------------------------------------ rigid coupling
    def bind_rigid(self, rigid, slip=False):
        """Couple to a rigid world (anything with ``.model`` and ``.state``; `advance` calls this).

        Every shape row of ``rigid.model`` becomes an obstacle (a `BodyShape`: world pose
        ``body_q[shape_body] o shape_local_pose``, static rows baked in) whose surface moves with its
        body (v + w x r in the boundary condition); face fractions are rebuilt every step while a
        kinematic or dynamic body exists. After each projection the pressure on the cut faces of
        each body becomes an impulse dt F (and dt tau about its centre of mass), applied with
        `inertia.dynamics.particle_coupling.apply_body_impulses`. Rows the signed distance does not
        cover (SDF) are skipped. 3-D grids only.

        With ``slip=False`` (default) and viscosity > 0 the shapes are no-slip walls of the implicit
        viscosity and the viscous stress on them (`viscosity.wall_shear_impulses`) is added to each
        body's impulse; ``slip=True`` leaves only the pressure."""
        if self.dim != 3:
            raise ValueError(f"rigid bodies couple to 3-D grids only; this grid has dim {self.dim}")
        obst, owner = rigid_shape_obstacles(rigid)
        if not isinstance(slip, (bool, np.bool_)):
            raise ValueError(f"slip must be True or False; got {slip!r}")
        self._rigid = rigid
        self._rigid_slip = bool(slip)
        self._rigid_obstacles = obst
        self._owner_body = np.asarray(owner, np.int64)
        self._obstacles_changed()
        nb = int(rigid.model.body_count)
        self.body_force = np.zeros((nb, 3))
        self.body_torque = np.zeros((nb, 3))
        self._impulse = (np.zeros((nb, 3)), np.zeros((nb, 3)))
        self._moving = self._moving or bool(np.any(self._owner_body >= 0))
        self._update_solids(self.time)

    def _push_bodies(self, dt):
        """Pressure impulse on each body from the cut faces (obstacles stage's ``_cut``) plus the
        viscous impulse of the step's diffusion on its no-slip shapes."""
        lin, ang = self._impulse
        lin[...] = 0.0
        ang[...] = 0.0
        body_q = self._rigid.state.body_q
        for a in range(3):
            faces, open_frac, body = self._cut[a]
            if faces.size:
                _pressure_impulses(self.phi, faces, open_frac, body, a, self.ctx.h, self.grid.origin3,
                                   self.fluid_density, body_q, lin, ang)
        if self._no_slip_nodes and self.viscosity > 0.0:
            vlin, vang = self._visc_impulse
            n0 = len(self.obstacles)
            for i, b in enumerate(self._owner_body):
                if b >= 0 and n0 + i < vlin.shape[0]:
                    lin[b] += vlin[n0 + i]
                    ang[b] += vang[n0 + i]
        np.multiply(lin, 1.0 / dt, out=self.body_force)
        np.multiply(ang, 1.0 / dt, out=self.body_torque)
        from ...dynamics.particle_coupling import apply_body_impulses
        apply_body_impulses(self._rigid.model.bodies(), self._rigid.state, lin, ang)

    def _check_finite(self):
        for a in range(self.dim):
            if not np.isfinite(self._k.max_abs(self._vel[a], self._partial)):
                bad = np.argwhere(~np.isfinite(self._vel[a]))[:10]
                raise SimulationDiverged(
                    f"grid fluid step {self.step_index} (t = {self.time:.6g} s): non-finite "
                    f"{'uvw'[a]} velocity on faces {bad.tolist()}; likely cause: a source or body "
                    f"force too strong for dt, or a pressure solve that did not converge",
                    step=self.step_index, time=self.time, indices=bad)

    # ------------------------------------------------------------------------ outputs
    def velocity_field(self):
        """The current velocity as an ``inertia.fields`` field (see `FluidVelocityField`)."""
        from .field import FluidVelocityField
        return FluidVelocityField(self)

    def sample_velocity(self, points):
        """Velocity at (M, dim) points, (M, dim) m/s (linear interpolation with boundary ghosts)."""
        return self.velocity_field()(points)

    def sample_scalar(self, name, points):
        if name not in self.scalar_names:
            raise ValueError(f"name must be one of the scalars {self.scalar_names}; got {name!r}")
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        out = np.empty(pts.shape[0])
        self._k.sample_scalar_points(self._scal[self.scalar_names.index(name)],
                               3 + self.scalar_names.index(name), pts, self.ctx, out)
        return out

    def vorticity(self):
        """Cell-centred vorticity: (nx, ny) z-component in 2-D, (nx, ny, nz, 3) in 3-D, 1/s."""
        u, v, w = self._vel
        self._k.cell_velocity_and_vorticity(u, v, w, self.ctx, self._vort)
        return self._vort[:, :, 0, 2].copy() if self.dim == 2 else self._vort.copy()

    def kinetic_energy(self):
        """(1/2) sum of u^2 over faces times cell volume (per unit density), J/(kg/m^3)."""
        h = self.grid.cell_size
        vol = h ** self.dim
        e = 0.0
        for a in range(self.dim):
            x = self._vel[a]
            if self.periodic[a]:
                idx = [slice(None)] * 3
                idx[a] = slice(0, -1)
                x = x[tuple(idx)]
            e += float(np.sum(x * x))
        return 0.5 * e * vol

    # ------------------------------------------------------------------------ World protocol
    def save_state(self):
        """The state a bit-for-bit resume needs: face velocities, scalars, the last pressure
        (the next solve's initial guess; viscous flow: the predictor's pressure, its dt and the
        last increment), time and step index (copies)."""
        st = {f"vel{a}": self._vel[a].copy() for a in range(self.dim)}
        for name, a in zip(self.scalar_names, self._scal):
            st[f"scalar/{name}"] = a.copy()
        st["phi"] = self.phi.copy()
        st["phi_increment"] = self._phi_inc.copy()
        st["phi_dt"] = np.array(self._phi_dt)
        st["time"] = np.array(self.time)
        st["step_index"] = np.array(self.step_index)
        return st

    def check_state(self, state):
        """Raise ValueError naming the entry if ``state`` (from a checkpoint) does not fit this grid:
        a missing array, a shape other than this grid's, a time, step index or pressure dt that is
        not finite and >= 0. Called first by ``restore_state``."""
        mine = self.save_state()
        for key, value in mine.items():
            if key not in state:
                if key in ("phi_increment", "phi_dt"):
                    continue
                raise ValueError(f"state is missing {key!r}")
            got = np.asarray(state[key])
            if got.shape != value.shape:
                raise ValueError(f"state[{key!r}] has shape {got.shape}; this grid needs {value.shape}")
            if got.dtype.kind not in "fiu":
                raise ValueError(f"state[{key!r}] has dtype {got.dtype}; this grid needs numbers")
        for key in ("time", "step_index", "phi_dt"):
            if key in state:
                value = float(np.asarray(state[key]))
                if not (math.isfinite(value) and value >= 0):
                    raise ValueError(f"state[{key!r}] is {value!r}; it must be a finite number >= 0")

    def restore_state(self, state):
        """Restore a `save_state` dict (same grid and scalars); `check_state` first."""
        self.check_state(state)
        for a in range(self.dim):
            self._vel[a][...] = state[f"vel{a}"]
        for name, a in zip(self.scalar_names, self._scal):
            a[...] = state[f"scalar/{name}"]
        self.phi[...] = state["phi"]
        if "phi_increment" in state:
            self._phi_inc[...] = state["phi_increment"]
            self._phi_dt = float(state["phi_dt"])
        self.time = float(state["time"])
        self.step_index = int(state["step_index"])
        if self._moving or self._rigid is not None:
            self._update_solids(self.time)

    def frame_arrays(self):
        """Per-frame arrays for a recorded run (fixed shapes): every scalar and ``speed`` (|u|
        at cell centres, m/s) as float32 (nx, ny[, nz]). 2-D grids also record the cell-centre
        velocity components ``u``, ``v`` (float32, m/s, the average of the two faces) and
        ``solid`` (uint8, 1 where the cell centre is inside an obstacle): the renderer's tracer
        streaks (`inertia.render.fluid_grid.GridStreaks`) advect through them; 9 bytes a cell."""
        u, v, w = self._vel
        uc, vc = 0.5 * (u[1:] + u[:-1]), 0.5 * (v[:, 1:] + v[:, :-1])
        s2 = uc ** 2 + vc ** 2
        if self.dim == 3:
            s2 += (0.5 * (w[:, :, 1:] + w[:, :, :-1])) ** 2
        out = {name: self._view(a).astype(np.float32) for name, a in zip(self.scalar_names, self._scal)}
        out["speed"] = self._view(np.sqrt(s2)).astype(np.float32)
        if self.dim == 2:
            out["u"] = self._view(uc).astype(np.float32)
            out["v"] = self._view(vc).astype(np.float32)
            out["solid"] = self._view(self._cell_solid).astype(np.uint8)
        return out

    def static_arrays(self):
        """Grid description for a recorded run: origin (dim,), cell_size (), shape (dim,)."""
        return {"origin": self.grid.origin.copy(), "cell_size": np.array(self.grid.cell_size),
                "shape": np.array(self.grid.shape, dtype=np.int64)}

    def write_vti(self, path):
        """Export the current frame as VTK image data (see `inertia.fluids.grid.vtk`)."""
        from .vtk import write_vti
        return write_vti(path, self)

    def state_hash(self):
        """SHA-256 of the velocity and scalar arrays (determinism checks)."""
        hsh = hashlib.sha256()
        for a in self._vel[:self.dim] + self._scal:
            hsh.update(np.ascontiguousarray(a).tobytes())
        return hsh.hexdigest()


@K.njit(cache=True)
def _pressure_impulses(phi, faces, open_frac, body, axis, h, origin, rho, body_q, lin, ang):
    """Pressure impulse on the bodies owning closed faces: J_axis = -rho h^2 (1 - A) (phi_R - phi_L)
    per face (phi = p dt / rho, so J = dt F), torque (x_face - c) x J about the body's centre c.
    Summed over the solid's faces this is -dt (integral of grad p over its volume) = -dt (surface
    integral of p n): runs of fully closed faces telescope to the pressures of the fluid cells at
    their ends, so solid cells' phi drops out. Faces on the domain sides are walls (skipped).
    Serial, in face order: deterministic."""
    nx, ny, nz = phi.shape
    for m in range(faces.shape[0]):
        b = body[m]
        if b < 0:
            continue
        i, j, k, il, jl, kl, interior = face_cells(faces[m], axis, nx, ny, nz)
        if not interior:
            continue
        J = -rho * h * h * (1.0 - open_frac[m]) * (phi[i, j, k] - phi[il, jl, kl])
        x = origin[0] + (i + (0.0 if axis == 0 else 0.5)) * h - body_q[b, 0]
        y = origin[1] + (j + (0.0 if axis == 1 else 0.5)) * h - body_q[b, 1]
        z = origin[2] + (k + (0.0 if axis == 2 else 0.5)) * h - body_q[b, 2]
        add_axis_impulse(lin, ang, b, axis, J, x, y, z)


@K.njit(cache=True)
def _closed_faces(frac, out):
    """Flat indices of the closed faces (frac == 0) into out, in C order; returns their count."""
    n = 0
    for f in range(frac.shape[0]):
        if frac[f] == 0.0:
            out[n] = f
            n += 1
    return n


@K.njit(cache=True)
def _wrap_periodic(vel, axis):
    """The last face layer along a periodic `axis` is a copy of the first (face n = face 0)."""
    nx, ny, nz = vel.shape
    if axis == 0:
        for j in range(ny):
            for k in range(nz):
                vel[nx - 1, j, k] = vel[0, j, k]
    elif axis == 1:
        for i in range(nx):
            for k in range(nz):
                vel[i, ny - 1, k] = vel[i, 0, k]
    else:
        for i in range(nx):
            for j in range(ny):
                vel[i, j, nz - 1] = vel[i, j, 0]


@K.njit(cache=True)
def _add_at(a, idx, value):
    """a[idx] += value (flat a; distinct indices)."""
    for m in range(idx.shape[0]):
        a[idx[m]] += value
