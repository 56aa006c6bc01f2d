"""The ``[sph.NAME]`` scene table: a strict pydantic model and ``build(table, ...) -> SPHFluid``.

    [sph.water]
    spacing = 0.02
    domain = [[0, 0, 0], [1.0, 0.5, 0.8]]
    method = "dfsph"                      # or "wcsph"
    viscosity = 1e-3
    fluid = [{ box = [[0, 0, 0], [0.3, 0.5, 0.6]] }]
    boundaries = ["tank"]                 # names of the scene's colliders (static)
    emitters = [{ center = [0.5, 0.25, 0.7], velocity = [0, 0, -1], width = 0.1 }]
    outflows = [{ lo = [0.9, 0, 0], hi = [1.0, 0.5, 0.8] }]

Rigid bodies need no key: a world with a rigid model couples them on the first
``fluid.advance(dt, rigid)`` (every shape row is sampled, ``inertia.fluids.sph.coupling``); a 2-D
fluid in a world with rigid bodies is refused when the world adds it (``SPHFluid.check_rigid``).
Bad input raises ``ValueError`` naming the key as ``sph.NAME.key`` with the allowed values.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .fluid import METHODS, SPHFluid, sample_block
from .smoothing import KERNELS

__all__ = ["SPHTable", "FluidBlock", "EmitterTable", "OutflowTable", "build", "parse"]


class _Strict(BaseModel):
    """Strict types (no bool or string where a number goes; an integer is a number), finite values."""
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Corners = Annotated[list[Annotated[list[float], Field(min_length=2, max_length=3)]], Field(min_length=2, max_length=2)]
#: smallest particle spacing and time step a scene may ask for (far below any practical fluid)
MIN_SPACING = 1e-6
MIN_DT = 1e-7


def _check_corners(lo, hi, what: str):
    if len(lo) != len(hi):
        raise ValueError(f"{what}: lo and hi must have the same number of components (got {len(lo)} and {len(hi)})")
    if any(not a < b for a, b in zip(lo, hi)):
        raise ValueError(f"{what}: every component of lo must be below hi (got {lo} and {hi})")


class FluidBlock(_Strict):
    """A block of fluid particles on the lattice: ``box = [[lo], [hi]]`` [m], initial ``velocity`` [m/s]."""
    box: Corners
    velocity: list[float] | None = None


class EmitterTable(_Strict):
    """Inflow: a line (2D) / square (3D) of side ``width`` [m] at ``center`` emitting along ``velocity``."""
    center: list[float]
    velocity: list[float]
    width: Positive


class OutflowTable(_Strict):
    """Particles entering the box [lo, hi) are removed."""
    lo: list[float]
    hi: list[float]


class SPHTable(_Strict):
    """One ``[sph.NAME]`` table (see ``SPHFluid`` for every parameter's meaning and units)."""
    spacing: Annotated[float, Field(ge=MIN_SPACING)]
    domain: Corners
    fluid: list[FluidBlock]
    method: Literal[METHODS] = "dfsph"  # type: ignore[valid-type]
    kernel: Literal[tuple(KERNELS)] = "cubic_spline"  # type: ignore[valid-type]
    smoothing_length: Positive | None = None
    rest_density: Positive = 1000.0
    gravity: list[float] | None = None
    viscosity: NonNegative = 0.0
    implicit_viscosity: bool = False
    xsph: Annotated[float, Field(ge=0, le=1)] = 0.0
    surface_tension: NonNegative = 0.0
    density_tolerance: Annotated[float, Field(gt=0, lt=1)] = 1e-3
    max_iterations: Annotated[int, Field(ge=1, le=100_000)] = 100
    periodic: list[bool] | None = None
    cfl: Annotated[float, Field(gt=0, le=1)] = 0.4
    dt: Annotated[float, Field(ge=MIN_DT)] | None = None
    dt_max: Annotated[float, Field(ge=MIN_DT)] = 0.005
    max_speed: Positive | None = None
    capacity: Annotated[int, Field(ge=1)] | None = None
    boundaries: list[str] = []
    slip: bool = False
    boundary_viscosity: NonNegative | None = None
    emitters: list[EmitterTable] = []
    outflows: list[OutflowTable] = []

    @model_validator(mode="after")
    def _relations(self):
        lo, hi = self.domain
        _check_corners(lo, hi, "domain")
        for i, block in enumerate(self.fluid):
            blo, bhi = block.box
            _check_corners(blo, bhi, f"fluid[{i}].box")
            if len(blo) != len(lo):
                raise ValueError(f"domain: it has {len(lo)} components but fluid[{i}].box has {len(blo)}; "
                                 "give both in the scene's dimension")
            if any(a < c for a, c in zip(blo, lo)) or any(b > d for b, d in zip(bhi, hi)):
                raise ValueError(f"fluid[{i}].box: the block {blo}..{bhi} must lie inside the domain {lo}..{hi}")
        for key in ("gravity", "periodic"):
            value = getattr(self, key)
            if value is not None and len(value) != len(lo):
                raise ValueError(f"{key}: needs {len(lo)} components like domain (got {len(value)})")
        for i, o in enumerate(self.outflows):
            _check_corners(o.lo, o.hi, f"outflows[{i}]")
        return self


_KEYS_OF_ARGUMENTS = ("smoothing_length", "rest_density", "spacing", "domain", "method", "kernel", "gravity",
                      "viscosity", "xsph", "surface_tension", "density_tolerance", "max_iterations", "periodic",
                      "cfl", "dt_max", "dt", "max_speed", "capacity", "positions", "velocities")


def _named(name, exc):
    return ValueError(f"sph.{name}: {exc}")


def parse(table: dict, name: str = "fluid") -> SPHTable:
    """Validate a raw ``[sph.NAME]`` table; a ValueError names the offending key."""
    try:
        return SPHTable.model_validate(table)
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(p) for p in err["loc"])
        allowed = f" (allowed keys: {sorted(SPHTable.model_fields)})" if err["type"] == "extra_forbidden" else ""
        msg = str(err["msg"]).removeprefix("Value error, ")
        raise ValueError((f"sph.{name}.{key}: {msg}" if key else f"sph.{name}.{msg}") + allowed) from None


def build(table, world=None, colliders=None, name: str = "fluid") -> SPHFluid:
    """An ``SPHFluid`` from a ``[sph.NAME]`` table (dict or ``SPHTable``). ``colliders``: name ->
    collider object for ``boundaries``; ``world``: when given, its gravity is the default gravity
    (``world.gravity`` or ``world.model.gravity``)."""
    t = table if isinstance(table, SPHTable) else parse(table, name)
    colliders = colliders or {}
    blocks, vels = [], []
    for i, block in enumerate(t.fluid):
        key = f"sph.{name}.fluid[{i}].box"
        lo, hi = (np.asarray(b, float) for b in block.box)
        dom_lo, dom_hi = (np.asarray(b, float) for b in t.domain)
        if lo.shape != dom_lo.shape or hi.shape != dom_lo.shape:
            raise ValueError(f"{key}: lo and hi must have {dom_lo.size} components like domain")
        if np.any(lo < dom_lo) or np.any(hi > dom_hi):
            raise ValueError(f"{key}: the block {lo.tolist()}..{hi.tolist()} must lie inside the domain "
                             f"{dom_lo.tolist()}..{dom_hi.tolist()}")
        try:
            x = sample_block(lo, hi, t.spacing)
        except ValueError as exc:
            raise ValueError(f"{key}: {exc}") from None
        if x.shape[0] == 0:
            raise ValueError(f"{key}: the block holds no particle at spacing {t.spacing} (make it at least one "
                             f"spacing thick on every axis)")
        blocks.append(x)
        vels.append(np.broadcast_to(np.asarray(block.velocity if block.velocity is not None else 0.0, float),
                                    x.shape))
    if not blocks:
        raise ValueError(f"sph.{name}.fluid: at least one block of fluid is needed")
    x = np.concatenate(blocks)
    v = np.concatenate(vels)
    gravity = t.gravity
    if gravity is None and world is not None:
        g = getattr(world, "gravity", None)
        if g is None and getattr(world, "model", None) is not None:
            g = getattr(world.model, "gravity", None)
        if g is not None:
            gravity = list(np.asarray(g, float)[: x.shape[1]])
    kwargs = dict(spacing=t.spacing, domain=t.domain, method=t.method, kernel=t.kernel,
                  smoothing_length=t.smoothing_length, velocities=v, rest_density=t.rest_density, gravity=gravity,
                  viscosity=t.viscosity, xsph=t.xsph, surface_tension=t.surface_tension, periodic=t.periodic,
                  density_tolerance=t.density_tolerance, max_iterations=t.max_iterations, max_speed=t.max_speed,
                  dt=t.dt, cfl=t.cfl, dt_max=t.dt_max, capacity=t.capacity, implicit_viscosity=t.implicit_viscosity)
    try:
        fluid = SPHFluid(x, **kwargs)
    except ValueError as exc:
        raise _named(name, exc) from None
    for i, cname in enumerate(t.boundaries):
        if cname not in colliders:
            raise ValueError(f"sph.{name}.boundaries[{i}]: unknown collider {cname!r}; known: {sorted(colliders)}")
        try:
            fluid.add_boundary(colliders[cname], slip=t.slip, boundary_viscosity=t.boundary_viscosity)
        except ValueError as exc:
            raise ValueError(f"sph.{name}.boundaries[{i}]: {exc}") from None
    for i, e in enumerate(t.emitters):
        try:
            fluid.add_emitter(e.center, e.velocity, e.width)
        except ValueError as exc:
            raise ValueError(f"sph.{name}.emitters[{i}]: {exc}") from None
    for i, o in enumerate(t.outflows):
        try:
            fluid.add_outflow(o.lo, o.hi)
        except ValueError as exc:
            raise ValueError(f"sph.{name}.outflows[{i}]: {exc}") from None
    return fluid
