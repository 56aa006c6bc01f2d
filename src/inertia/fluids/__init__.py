"""Fluids: MAC-grid Navier-Stokes (`inertia.fluids.grid`: `GridFluid`, smoke and viscous flow) and
smoothed particle hydrodynamics (`inertia.fluids.sph`: `SPHFluid`, DFSPH and WCSPH). Each solver owns
its grids or particle arrays; solid shapes enter as boundary conditions (see docs/fluids-grid.md,
docs/fluids-sph.md and docs/architecture.md)."""

from . import grid, sph
from .grid import GridFluid
from .sph import SPHFluid

__all__ = ["grid", "sph", "GridFluid", "SPHFluid"]
