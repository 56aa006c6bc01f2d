"""Boundary conditions on the six (four in 2-D) sides of a MAC grid.

Each side ("x-", "x+", "y-", "y+", "z-", "z+") gets one of:

- ``Wall(slip=False, velocity=None, temperature=None, scalars={})``: a solid wall. The normal
  velocity is the wall's normal velocity (usually 0); no-slip walls also impose their tangential
  velocity (a moving lid: ``Wall(velocity=(1, 0))`` on "y+"), slip walls leave it free (zero
  shear). Scalars see an insulating wall (zero flux) unless the wall holds a value:
  ``temperature`` (a hot or cold wall) or ``scalars={name: value}`` fix the scalar on the wall
  (Dirichlet), so the fluid's scalar diffusion conducts it in (`GridFluid(diffusivity=...)`).
- ``Inflow(velocity, density=0.0, temperature=None, scalars={}, profile="uniform")``: fluid
  enters with this velocity carrying these scalar values (``None`` = the ambient temperature;
  scalars not named take 0). ``profile``: "uniform" (every face of the side gets ``velocity``),
  "parabolic" (the normal speed is a parabola across each tangential axis that is not periodic,
  zero on the side's edges, whose mean is the normal component of ``velocity``: the fully
  developed laminar profile between plates; in a 3-D duct the product of two parabolas, not the
  exact duct series), or a function ``profile(points) -> speed`` taking the (M, dim) face-centre
  positions of the side (m) and returning the (M,) velocity component along the side's axis
  (m/s, + along the axis); the tangential components are always those of ``velocity``.
- ``Outflow()``: open side, pressure 0 outside (at the ghost cell centre half a cell beyond the
  side), zero normal gradient of velocity and scalars.
- ``Pressure(pressure=0.0)``: open side held at a pressure (Pa, relative; Dirichlet on the
  side's faces, second order), zero normal gradient of the velocity and the scalars. A pressure
  drop between two such sides drives the flow without a body force (fluid enters where the
  pressure is higher). The pressure is converted with ``GridFluid(fluid_density=...)``.
- ``Periodic()``: wraps around; must be on both sides of an axis.

A fluid with an inflow needs a side where it can leave (``Outflow`` or ``Pressure``): the
constructor refuses a net inflow into a closed domain. Strings are accepted: "wall" / "no-slip",
"slip", "outflow", "periodic".
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SIDES = ("x-", "x+", "y-", "y+", "z-", "z+")


PROFILES = ("uniform", "parabolic")


@dataclass(frozen=True)
class Wall:
    slip: bool = False
    velocity: tuple | None = None
    temperature: float | None = None   # fixed wall temperature (None: insulating, zero flux)
    scalars: dict = field(default_factory=dict)   # other scalars held on the wall


@dataclass(frozen=True)
class Inflow:
    velocity: tuple = (0.0, 0.0, 0.0)
    density: float = 0.0
    temperature: float | None = None
    scalars: dict = field(default_factory=dict)
    profile: object = "uniform"        # "uniform", "parabolic" or profile(points) -> (M,) speed


@dataclass(frozen=True)
class Outflow:
    pass


@dataclass(frozen=True)
class Pressure:
    pressure: float = 0.0              # Pa (relative), imposed on the side's faces


@dataclass(frozen=True)
class Periodic:
    pass


_NAMES = {"wall": Wall(), "no-slip": Wall(), "noslip": Wall(), "slip": Wall(slip=True),
          "outflow": Outflow(), "periodic": Periodic()}


def parse_boundaries(boundaries, dim: int):
    """Return a list of 6 boundary objects (z sides are Periodic in 2-D). Default: no-slip walls."""
    sides = SIDES[:2 * dim]
    if boundaries is None:
        boundaries = {}
    if not isinstance(boundaries, dict):
        raise ValueError(f"boundaries must be a dict from side {sides} to a boundary; "
                         f"got {type(boundaries).__name__}")
    for key in boundaries:
        if key not in sides:
            raise ValueError(f"boundaries has an unknown side {key!r}; allowed sides: {sides}")
    out = []
    for side in SIDES:
        if side not in sides:
            out.append(Periodic())
            continue
        b = boundaries.get(side, Wall())
        if isinstance(b, str):
            if b not in _NAMES:
                raise ValueError(f"boundaries[{side!r}] must be one of {tuple(_NAMES)} or a "
                                 f"Wall/Inflow/Outflow/Periodic object; got {b!r}")
            b = _NAMES[b]
        if not isinstance(b, (Wall, Inflow, Outflow, Pressure, Periodic)):
            raise ValueError(f"boundaries[{side!r}] must be a Wall, Inflow, Outflow, Pressure or "
                             f"Periodic; got {type(b).__name__}")
        _check_values(b, side)
        vel = b.velocity if isinstance(b, (Wall, Inflow)) else None
        if vel is not None:
            arr = np.asarray(vel, dtype=np.float64).reshape(-1)
            if arr.shape[0] != dim or not np.all(np.isfinite(arr)):
                raise ValueError(f"boundaries[{side!r}].velocity must be {dim} finite numbers; "
                                 f"got {vel!r}")
        out.append(b)
    for axis in range(dim):
        lo, hi = out[2 * axis], out[2 * axis + 1]
        if isinstance(lo, Periodic) != isinstance(hi, Periodic):
            raise ValueError(f"boundaries[{SIDES[2 * axis]!r}] and boundaries[{SIDES[2 * axis + 1]!r}]"
                             f" contradict: periodic must be on both sides of the {'xyz'[axis]} axis")
    return out


def _finite_number(x, key):
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)) \
            or not np.isfinite(x):
        raise ValueError(f"{key} must be a finite number; got {x!r}")


def _check_values(b, side):
    """Scalar values, profiles and pressures of one side: finite numbers, known profiles."""
    key = f"boundaries[{side!r}]"
    if isinstance(b, Pressure):
        _finite_number(b.pressure, f"{key}.pressure")
    if isinstance(b, (Wall, Inflow)):
        if b.temperature is not None:
            _finite_number(b.temperature, f"{key}.temperature")
        if not isinstance(b.scalars, dict):
            raise ValueError(f"{key}.scalars must be a dict scalar name -> value; got {b.scalars!r}")
        for name, value in b.scalars.items():
            _finite_number(value, f"{key}.scalars[{name!r}]")
    if isinstance(b, Inflow):
        _finite_number(b.density, f"{key}.density")
        if not callable(b.profile) and b.profile not in PROFILES:
            raise ValueError(f"{key}.profile must be one of {PROFILES} or a function "
                             f"profile(points) -> (M,) speed; got {b.profile!r}")


def side_velocity(b, dim):
    """(3,) velocity imposed by a wall or inflow (zeros otherwise)."""
    v = np.zeros(3)
    vel = getattr(b, "velocity", None)
    if vel is not None:
        v[:dim] = np.asarray(vel, dtype=np.float64).reshape(-1)
    return v
