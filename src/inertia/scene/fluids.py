"""Fluids in scene files: ``[sph.NAME]`` tables and ``[fluids.NAME]`` grid-fluid tables.

The table models and builders belong to the fluid packages (``inertia.fluids.sph.scene``: the
strict pydantic ``SPHTable`` and ``build(table, world, colliders)``; ``inertia.fluids.grid.scene``:
``GridFluidTable`` and its ``build``); this module only wires them
into a scene: the table type used by ``SceneModel.sph``, the builder step that adds each fluid to
the `World` (``world.add_fluid(name, fluid)``) with errors re-raised as `SceneError` at the key
path ``sph.NAME...``, and the memory estimate of `inertia.scene.resources`.

    [sph.water]
    spacing = 0.02
    domain = [[0, 0], [1.6, 1.0]]
    fluid = [{ box = [[0, 0], [0.4, 0.8]] }]
    boundaries = ["tank"]        # names of the scene's [[colliders]]

Limitations: the memory estimate counts fluid particles (blocks or ``capacity``) with their
neighbour lists at rest density; boundary particles (sampled on the colliders at build time) are
not counted. A fluid's dimension must equal ``simulation.dim``.
"""

from __future__ import annotations

import math

from ..fluids.grid.scene import GridFluidTable
from ..fluids.grid.scene import build as build_grid
from ..fluids.sph.scene import SPHTable
from ..fluids.sph.scene import build as build_sph

__all__ = ["SPHTable", "GridFluidTable", "add_sph_fluids", "add_grid_fluids", "grid_memory", "sph_particle_count", "sph_memory", "BYTES_PER_SPH_PARTICLE"]

#: per-particle state besides the neighbour list: positions, velocities, densities, pressures,
#: DFSPH factors, sort scratch, and a share of the boundary particles and the cell grid (tracemalloc
#: measured about 1 kB per fluid particle in all for a 40 x 40 2-D dam break; tests/scene/test_fluids.py)
BYTES_PER_SPH_PARTICLE = 1000


def sph_particle_count(table: SPHTable) -> int:
    """Fluid particles the table's blocks hold at its spacing (or ``capacity`` when larger)."""
    n = 0
    if not table.spacing > 0:
        return table.capacity or 0
    for block in table.fluid:
        lo, hi = block.box
        n += math.prod(max(0, math.floor((b - a) / table.spacing + 1e-9)) for a, b in zip(lo, hi))
    return max(n, table.capacity or 0)


def sph_memory(table: SPHTable) -> tuple[int, float]:
    """(particles, bytes): state arrays plus neighbour lists (every neighbour inside the kernel's
    support, 2 h, at rest spacing: index int32, weight and gradient float64, 25 % head-room) and the
    search's fixed-stride scratch rows (1.5x the neighbours + 8 per particle, `SPHFluid._stride`)."""
    dim = len(table.domain[0])
    n = sph_particle_count(table)
    h = table.smoothing_length or (1.0 if table.kernel == "cubic_spline" else 1.2) * table.spacing
    ratio = 2.0 * h / table.spacing
    neighbours = (math.pi * ratio ** 2) if dim == 2 else (4.0 / 3.0 * math.pi * ratio ** 3)
    per_pair = 4 + 8 + 8 * dim
    # the neighbour search's cell grid over the domain (cells of side 2 h: start and count, int64)
    lo, hi = table.domain
    cells = math.prod(max(1.0, (b - a) / (2.0 * h) + 1.0) for a, b in zip(lo, hi))
    return n, n * (BYTES_PER_SPH_PARTICLE + (1.25 * neighbours + 1.5 * neighbours + 8) * per_pair) + 16.0 * cells


def add_sph_fluids(builder, world) -> None:
    """Build each ``[sph.NAME]`` table of the builder's scene and add it to ``world``."""
    for name, table in builder.m.sph.items():
        path = f"sph.{name}"
        dim = len(table.domain[0])
        if not table.spacing > 0:  # checked here so the message names the key, not the first block
            builder.fail(f"{path}.spacing", f"must be > 0 (got {table.spacing!r})")
        if dim != builder.dim:
            builder.fail(f"{path}.domain", f"the fluid is {dim}-D but simulation.dim is {builder.dim}")
        try:
            fluid = build_sph(table, world, dict(builder.collider_names), name=name)
        except ValueError as exc:
            message = str(exc)
            key = path
            # The fluid package names the key as "sph.NAME.key: message": keep its path.
            if message.startswith(path):
                key, _, message = message.partition(": ")
            builder.fail(key, message)
        with builder.at(path):
            world.add_fluid(name, fluid)


def grid_memory(table: GridFluidTable) -> tuple[int, float]:
    """(cells, bytes) of a grid fluid: about 40 float64 values per cell (velocity faces, pressure,
    multigrid levels, scalars and their advection scratch); liquids add their particles (2 per cell
    per axis of each block: 4 per cell in 2-D, 8 in 3-D; 200 bytes each)."""
    cells = math.prod(table.shape)
    cost = cells * 40 * 8
    if table.kind == "liquid":
        per_cell = 2 ** len(table.shape)
        for b in table.blocks:
            cost += per_cell * math.prod(max(0.0, (hi - lo) / table.cell_size) for lo, hi in zip(b.lower, b.upper)) * 200
    return cells, cost


def add_grid_fluids(builder, world) -> None:
    """Build each ``[fluids.NAME]`` table of the builder's scene and add it to ``world``."""
    for name, table in builder.m.fluids.items():
        path = f"fluids.{name}"
        if len(table.shape) != builder.dim:
            builder.fail(f"{path}.shape", f"the grid is {len(table.shape)}-D but simulation.dim is {builder.dim}")
        if name in builder.m.sph:
            builder.fail(path, f"the name {name!r} is taken by [sph.{name}]; fluid names must be unique")
        try:
            fluid = build_grid(table, world, dict(builder.collider_names), name=name)
        except ValueError as exc:
            message, key = str(exc), path
            if message.startswith(path):
                key, _, message = message.partition(": ")
            builder.fail(key, message)
        with builder.at(path):
            world.add_fluid(name, fluid)
