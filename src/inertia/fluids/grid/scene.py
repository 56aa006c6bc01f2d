"""The ``[fluids.NAME]`` scene table for grid fluids: a strict pydantic model and a builder.

    [fluids.plume]
    kind = "smoke"                       # or "liquid"
    shape = [128, 128]
    cell_size = 0.0078125
    advection = "maccormack"
    buoyancy = [0.1, 1.0]
    vorticity_confinement = 2.0
    obstacles = ["ball"]                 # names of the scene's colliders
    diffusivity = { temperature = 1e-4 }  # m^2/s per scalar (implicit diffusion)
    [fluids.plume.boundaries]
    "y+" = { type = "outflow" }
    "y-" = { type = "wall", temperature = 2.0 }   # a hot floor (conducts with the diffusivity)
    [[fluids.plume.sources]]
    lower = [0.45, 0.02]
    upper = [0.55, 0.08]
    density_rate = 5.0
    temperature_rate = 5.0

    [fluids.tank]
    kind = "liquid"
    shape = [64, 32]
    cell_size = 0.015625
    viscosity = 0.01                     # m^2/s (honey-like); 0: inviscid
    obstacles = ["rock", "post"]
    obstacle_slip = [false, true]        # or one bool for all (default false: no-slip)
    [fluids.tank.boundaries]
    "y-" = { type = "no-slip" }          # a liquid's sides are walls: "slip" (default) or "no-slip"
    [[fluids.tank.blocks]]
    lower = [0.0, 0.0]
    upper = [0.25, 0.5]

``build(table, world=None, colliders=None)`` returns a `GridFluid` or `LiquidFluid`. Every
error is a ``ValueError`` whose message starts with the key path (``fluids.plume.shape``) and
names the allowed values. ``inertia.scene`` uses the model for ``[fluids.NAME]`` and adds each
built fluid to the world (``world.add_fluid(name, fluid)``, `inertia.scene.fluids`).

Limitations: a liquid's domain is closed (its sides are slip or no-slip walls; no inflow,
outflow or periodic sides); rigid bodies of the world are coupled by the world step itself
(``World.add_fluid``), not here (``world`` is accepted for the protocol and unused); their
slip flag is the liquid's ``bind_rigid`` default (no-slip).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .boundaries import Inflow, Outflow, Periodic, Pressure, Wall
from .liquid import LiquidFluid
from .solver import GridFluid


#: smallest grid cell a scene may ask for, and most cells along one axis (the memory estimate
#: refuses what does not fit long before this)
MIN_CELL_SIZE = 1e-6
MAX_CELLS_PER_AXIS = 1_000_000


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


class BoundaryTable(_Strict):
    """One side of the domain."""
    type: Literal["wall", "slip", "no-slip", "inflow", "outflow", "pressure", "periodic"] = Field(
        description="wall = no-slip wall (velocity optional: a moving lid), slip, inflow, outflow, "
                    "pressure (an open side held at `pressure`), periodic")
    velocity: list[float] | None = Field(None, description="wall or inflow velocity, m/s (an inflow's mean "
                                                           "normal speed with profile = \"parabolic\")")
    density: float = Field(0.0, description="inflow density")
    temperature: float | None = Field(None, description="inflow temperature (default ambient); on a wall "
                                                        "the wall's fixed temperature (default: insulating)")
    profile: Literal["uniform", "parabolic"] = Field("uniform", description="inflow velocity profile")
    pressure: float | None = Field(None, description="pressure side: its pressure, Pa (relative)")


class SourceTable(_Strict):
    """A box that adds density/temperature per second and an acceleration, every step."""
    lower: list[float]
    upper: list[float]
    density_rate: float = 0.0
    temperature_rate: float = 0.0
    acceleration: list[float] | None = None


class BlockTable(_Strict):
    """A box of liquid particles (2 per cell per axis)."""
    lower: list[float]
    upper: list[float]
    velocity: list[float] | None = None


class GridFluidTable(_Strict):
    """``[fluids.NAME]``: a MAC-grid smoke/viscous fluid or a particle liquid."""
    kind: Literal["smoke", "liquid"] = "smoke"
    shape: list[int] = Field(description="cells per axis, 2 or 3 entries, each >= 4")
    cell_size: float = Field(gt=0, description="cell size h, m")
    origin: list[float] | None = None
    # smoke / viscous flow
    boundaries: dict[Literal["x-", "x+", "y-", "y+", "z-", "z+"], BoundaryTable] = Field(default_factory=dict)
    viscosity: float = Field(0.0, ge=0)
    advection: Literal["maccormack", "semi-lagrangian"] = "maccormack"
    pressure_solver: Literal["mgpcg", "cg", "jacobi"] = "mgpcg"
    tolerance: float = Field(1e-6, gt=0, lt=1)
    scalars: list[str] = Field(default_factory=lambda: ["density", "temperature"])
    buoyancy: list[float] = Field(default_factory=lambda: [0.0, 0.0], min_length=2, max_length=2)
    ambient_temperature: float = 0.0
    vorticity_confinement: float = Field(0.0, ge=0)
    dissipation: dict[str, float] = Field(default_factory=dict)
    diffusivity: dict[str, float] = Field(default_factory=dict, description="scalar name -> diffusivity, m^2/s")
    fluid_density: float = Field(1.2, gt=0, description="smoke: rho, kg/m^3 (pressure sides and body forces)")
    obstacle_temperature: float | list[float | None] | None = Field(
        None, description="smoke: obstacles held at a temperature (one for all, or one per obstacle, null = "
                          "insulating); needs diffusivity.temperature")
    body_acceleration: list[float] | None = None
    cfl: float = Field(1.0, gt=0, le=5)
    sources: list[SourceTable] = Field(default_factory=list)
    obstacles: list[str] = Field(default_factory=list, description="names of scene colliders")
    obstacle_slip: bool | list[bool] = Field(
        False, description="false (no-slip, default), true (slip), or one bool per obstacle; "
                           "matters with viscosity > 0")
    # liquid
    method: Literal["apic", "flip", "pic"] = "apic"
    flip_ratio: float = Field(0.95, ge=0, le=1)
    gravity: list[float] | None = None
    density: float = Field(1000.0, gt=0)
    blocks: list[BlockTable] = Field(default_factory=list)


    @model_validator(mode="after")
    def _relations(self):
        dim = len(self.shape)
        if dim not in (2, 3):
            raise ValueError(f"shape: needs 2 or 3 entries (cells per axis); got {len(self.shape)}")
        for a, n in enumerate(self.shape):
            if not 4 <= n <= MAX_CELLS_PER_AXIS:
                raise ValueError(f"shape[{a}]: cells per axis must be in 4..{MAX_CELLS_PER_AXIS} (got {n})")
        if self.cell_size < MIN_CELL_SIZE:
            raise ValueError(f"cell_size: must be >= {MIN_CELL_SIZE:g} m (got {self.cell_size!r})")
        origin = self.origin or [0.0] * dim
        if len(origin) != dim:
            raise ValueError(f"origin: needs {dim} components like shape (got {len(origin)})")
        upper = [o + n * self.cell_size for o, n in zip(origin, self.shape)]
        for key, items in (("sources", self.sources), ("blocks", self.blocks)):
            for i, box in enumerate(items):
                lo, hi = box.lower, box.upper
                if len(lo) != dim or len(hi) != dim:
                    raise ValueError(f"{key}[{i}]: lower and upper need {dim} components like shape")
                if any(not a < b for a, b in zip(lo, hi)):
                    raise ValueError(f"{key}[{i}]: every component of lower must be below upper (got {lo} and {hi})")
                if any(a < o - 1e-9 for a, o in zip(lo, origin)) or any(b > u + 1e-9 for b, u in zip(hi, upper)):
                    raise ValueError(f"{key}[{i}]: the box {lo}..{hi} must lie inside the grid {origin}..{upper}")
        sides = [s for s in ("x-", "x+", "y-", "y+", "z-", "z+")[:2 * dim]]
        extra = [s for s in self.boundaries if s not in sides]
        if extra:
            raise ValueError(f"boundaries.{extra[0]}: a {dim}-D grid has sides {sides}")
        inflows = [s for s, b in self.boundaries.items() if b.type == "inflow"]
        outlets = [s for s, b in self.boundaries.items() if b.type == "outflow"]
        if self.kind == "smoke" and inflows and not outlets:
            raise ValueError(f"boundaries.{inflows[0]}: an inflow needs an outflow side to leave by (the other "
                             "sides are closed: the incompressible flow cannot take in fluid); make one side "
                             "type = \"outflow\"")
        return self

    @field_validator("obstacle_slip", mode="before")
    @classmethod
    def _slip_values(cls, v):
        if isinstance(v, bool) or (isinstance(v, list) and all(isinstance(x, bool) for x in v)):
            return v
        raise ValueError(f"must be true, false or a list of one bool per obstacle; got {v!r}")


LIQUID_WALLS = {"slip": "slip", "no-slip": "no-slip", "wall": "no-slip"}


def _liquid_walls(boundaries):
    """A liquid's side -> "slip" / "no-slip" from its boundaries table (closed walls only)."""
    walls = {}
    for side, b in boundaries.items():
        if b.type not in LIQUID_WALLS:
            raise ValueError(f"boundaries.{side}: a liquid's sides are closed walls, one of "
                             f"{sorted(LIQUID_WALLS)}; got {b.type!r}")
        if b.velocity is not None:
            raise ValueError(f"boundaries.{side}.velocity: a liquid's walls do not move "
                             f"(leave velocity out)")
        walls[side] = LIQUID_WALLS[b.type]
    return walls


def _boundary(b: BoundaryTable):
    if b.pressure is not None and b.type != "pressure":
        raise ValueError(f".pressure: only a side of type \"pressure\" takes a pressure (this side is {b.type!r})")
    if b.profile != "uniform" and b.type != "inflow":
        raise ValueError(f".profile: only an inflow side takes a profile (this side is {b.type!r})")
    if b.type == "slip":
        return Wall(slip=True, temperature=b.temperature)
    if b.type in ("wall", "no-slip"):
        return Wall(slip=False, velocity=b.velocity, temperature=b.temperature)
    if b.type == "inflow":
        if b.velocity is None:
            raise ValueError("velocity is required for an inflow boundary")
        return Inflow(velocity=b.velocity, density=b.density, temperature=b.temperature, profile=b.profile)
    if b.type == "outflow":
        return Outflow()
    if b.type == "pressure":
        if b.pressure is None:
            raise ValueError(".pressure: required for a pressure side (Pa)")
        return Pressure(b.pressure)
    return Periodic()


def build(table, world=None, colliders=None, name="fluid"):
    """A GridFluid or LiquidFluid from a ``[fluids.NAME]`` table (dict or GridFluidTable).
    `colliders`: dict name -> collider for ``obstacles``. Errors name the key path."""
    prefix = f"fluids.{name}"
    if not isinstance(table, GridFluidTable):
        try:
            table = GridFluidTable.model_validate(dict(table))
        except ValidationError as e:
            err = e.errors()[0]
            key = ".".join(str(p) for p in err["loc"])
            msg = str(err["msg"]).removeprefix("Value error, ")
            raise ValueError(f"{prefix}.{key}: {msg}" if key else f"{prefix}.{msg}") from None
    t = table
    try:
        obstacles = []
        for i, o in enumerate(t.obstacles):
            if colliders is None or o not in colliders:
                known = sorted(colliders) if colliders else []
                raise ValueError(f"obstacles[{i}]: unknown collider {o!r}; the scene's colliders are {known}")
            obstacles.append(colliders[o])
        if isinstance(t.obstacle_slip, list) and len(t.obstacle_slip) != len(obstacles):
            raise ValueError(f"obstacle_slip: must be true, false or {len(obstacles)} bools (one per "
                             f"obstacle); got {len(t.obstacle_slip)}")
        slip = t.obstacle_slip if isinstance(t.obstacle_slip, bool) else list(t.obstacle_slip)
        if t.kind == "liquid":
            fluid = LiquidFluid(t.shape, t.cell_size, origin=t.origin, gravity=t.gravity,
                                method=t.method, flip_ratio=t.flip_ratio, density=t.density,
                                cfl=t.cfl, viscosity=t.viscosity, obstacles=obstacles,
                                obstacle_slip=slip, walls=_liquid_walls(t.boundaries))
            for i, b in enumerate(t.blocks):
                try:
                    fluid.add_block(b.lower, b.upper, velocity=b.velocity)
                except ValueError as e:
                    raise ValueError(f"blocks[{i}]: {e}") from None
            return fluid
        sides = {}
        for side, b in t.boundaries.items():
            try:
                sides[side] = _boundary(b)
            except ValueError as e:
                msg = str(e)
                raise ValueError(f"boundaries.{side}{msg}" if msg.startswith(".") else
                                 f"boundaries.{side}: {msg}") from None
        fluid = GridFluid(t.shape, t.cell_size, origin=t.origin, boundaries=sides or None,
                          viscosity=t.viscosity, advection=t.advection,
                          pressure_solver=t.pressure_solver, tolerance=t.tolerance,
                          scalars=tuple(t.scalars), ambient_temperature=t.ambient_temperature,
                          buoyancy=tuple(t.buoyancy), body_acceleration=t.body_acceleration,
                          dissipation=t.dissipation, vorticity_confinement=t.vorticity_confinement,
                          cfl=t.cfl, obstacles=obstacles, obstacle_slip=slip,
                          diffusivity=t.diffusivity, fluid_density=t.fluid_density,
                          obstacle_temperature=t.obstacle_temperature)
        for i, s in enumerate(t.sources):
            try:
                fluid.add_source(s.lower, s.upper, density_rate=s.density_rate,
                                 temperature_rate=s.temperature_rate, acceleration=s.acceleration)
            except ValueError as e:
                raise ValueError(f"sources[{i}]: {e}") from None
        return fluid
    except ValueError as e:
        raise ValueError(f"{prefix}.{e}") from None
