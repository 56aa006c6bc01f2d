"""Boundary conditions on the six (four in 2-D) sides of a MAC grid.

Each side ("x-", "x+", "y-", "y+", "z-", "z+") gets one of:

- ``Wall(slip=False, velocity=None)``: a solid wall. The normal velocity is the wall's normal
  velocity (usually 0); no-slip walls also impose their tangential velocity (a moving lid:
  ``Wall(velocity=(1, 0))`` on "y+"), slip walls leave it free (zero shear).
- ``Inflow(velocity, density=0.0, temperature=None)``: fluid enters with this velocity (all
  components imposed on the side) carrying these scalar values (``None`` = the ambient
  temperature). Scalars not named take 0.
- ``Outflow()``: open side, pressure 0 outside, zero normal gradient of velocity and scalars.
- ``Periodic()``: wraps around; must be on both sides of an axis.

Strings are accepted: "wall" / "no-slip", "slip", "outflow", "periodic".
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SIDES = ("x-", "x+", "y-", "y+", "z-", "z+")


@dataclass(frozen=True)
class Wall:
    slip: bool = False
    velocity: tuple | None = None


@dataclass(frozen=True)
class Inflow:
    velocity: tuple = (0.0, 0.0, 0.0)
    density: float = 0.0
    temperature: float | None = None
    scalars: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Outflow:
    pass


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
        if not isinstance(b, (Wall, Inflow, Outflow, Periodic)):
            raise ValueError(f"boundaries[{side!r}] must be a Wall, Inflow, Outflow or Periodic; "
                             f"got {type(b).__name__}")
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


def side_velocity(b, dim):
    """(3,) velocity imposed by a wall or inflow (zeros otherwise)."""
    v = np.zeros(3)
    vel = getattr(b, "velocity", None)
    if vel is not None:
        v[:dim] = np.asarray(vel, dtype=np.float64).reshape(-1)
    return v
