"""How much memory and time a scene needs, estimated from the validated model before building.

A scene file can ask for more than a machine has: ``count = 1_000_000_000`` would allocate
about two terabytes, ``duration = 1e12`` would run for millennia. `estimate_resources` counts
what the builder would make (particles per group, springs of chains and cloth, emitter pools,
distance grids of mesh colliders) and the steps of a run, without allocating any of it, so
that `inertia.scene.build` can refuse a scene that does not fit (naming the key, the estimate
and the machine's available memory) and `inertia run` can refuse a run that would not finish.

Every part is counted: particle groups, emitter pools, springs, mesh-collider distance grids,
rigid bodies (with their hull points and inline mesh triangles), SPH particles (from the spacing
and the fluid boxes, with their neighbour lists and search grid) and grid-fluid cells. Parts too
large for their method (a hull of more than `MAX_HULL_POINTS` points, a mesh of more than
`MAX_MESH_TRIANGLES` triangles) are listed in ``limits`` and refused like a scene that does not fit.

Model of the cost (measured on the bundled integrators with tracemalloc, 1e5 particles, 3-D):
a particle costs 600-1900 bytes through building and stepping (state, integrator stages,
forces, collision scratch, the recorder's frame copies); ``BYTES_PER_PARTICLE = 2000`` covers
the heaviest (implicit Euler). A spring costs ``BYTES_PER_SPRING = 200`` (pairs, stiffness,
damping, rest length, colour batches). A mesh collider bakes a distance grid of
``resolution^3`` cells, about 32 bytes each while baking. Run time is bounded *below* by
``SECONDS_PER_PARTICLE_STEP = 2e-9`` per particle and integrator step (the fastest fused
kernel at 1M particles) plus ``SECONDS_PER_GROUP_STEP = 2e-6`` of per-step overhead, so a run
refused as too long is too long on any machine this library runs on.

Limitations: the estimate ignores memory shared with the Python process itself (about 200 MB
with Numba loaded) and the peak of the video writer; run time is a lower bound, not a forecast.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import models as M

__all__ = ["ResourceEstimate", "estimate_resources", "available_memory", "BYTES_PER_PARTICLE",
           "BYTES_PER_SPRING", "MAX_RUN_SECONDS", "BYTES_PER_BODY", "SECONDS_PER_BODY_SUBSTEP"]

BYTES_PER_PARTICLE = 2000
BYTES_PER_SPRING = 200
BYTES_PER_GRID_CELL = 32
SECONDS_PER_PARTICLE_STEP = 2e-9
SECONDS_PER_GROUP_STEP = 2e-6
#: A run whose lower-bound time exceeds this needs ``--force`` (one day).
MAX_RUN_SECONDS = 86400.0
#: a rigid body's arrays, its shapes' rows, contact manifolds, broad-phase pairs, solver scratch and the
#: recorder: peak resident memory of a 0.1 s run of 16,000 resting boxes minus that of 1,000 boxes,
#: over the 15,000 extra bodies, measured 930 - 246 MB -> 45.6 kB a body (was 4 kB, 8-10x low)
BYTES_PER_BODY = 46_000
#: a convex hull's point (body-local copy, support scans, hull faces for drawing) and a mesh triangle
#: (vertices, BVH node share, drawing copy)
BYTES_PER_HULL_POINT = 100
BYTES_PER_TRIANGLE = 300
#: largest hull and mesh a body may carry without --force (contact queries scan hull points)
MAX_HULL_POINTS = 10_000
MAX_MESH_TRIANGLES = 2_000_000
#: lower bounds on the work of a fluid: an SPH particle per fluid substep (neighbour search,
#: density, pressure solve: tens of neighbours, several passes; a 2-D DFSPH dam break of 800-3200
#: particles measures 1.5-1.8e-6 s of CPU per particle-step) and a grid cell per step
#: (advection, pressure iterations)
SECONDS_PER_SPH_PARTICLE_STEP = 2e-7
SECONDS_PER_GRID_CELL_STEP = 1e-8
#: rigid solve per body and substep, a lower bound: the 204-box pyramid (examples/box_pyramid.toml) runs
#: 240 steps x 8 substeps in ~15 s on a shared 2-core machine, 3.8e-5 s per body-substep, most bodies asleep
SECONDS_PER_BODY_SUBSTEP = 5e-6


def available_memory() -> int | None:
    """Bytes of memory this process can still use: the smallest of the system's available memory
    (``MemAvailable`` of /proc/meminfo, else sysconf), the address-space limit (``RLIMIT_AS``, less
    what the process maps already) and a cgroup v2 limit; None if unknown."""
    candidates = []
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    candidates.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            pass
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm", encoding="ascii") as handle:
                used = int(handle.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            candidates.append(max(0, soft - used))
    except (ImportError, OSError, ValueError, IndexError, AttributeError):
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
            candidates.append(max(0, int(limit) - used))
    except (OSError, ValueError):
        pass
    return min(candidates) if candidates else None


def _human_bytes(n: float) -> str:
    for unit in ("B", "KB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} PB"  # pragma: no cover


def _human_seconds(s: float) -> str:
    for unit, size in (("years", 3.156e7), ("days", 86400.0), ("hours", 3600.0), ("minutes", 60.0)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.3g} s"


@dataclass
class ResourceEstimate:
    """What a scene would allocate and how many steps a run takes.

    ``memory`` in bytes; ``largest_key``: the scene key whose entry costs the most (the one to
    lower); ``items``: {key: (bytes, description)}; ``steps``: integrator steps of a whole run
    (duration / dt x substeps); ``seconds``: a lower bound on the run's wall-clock time.
    """

    particles: int = 0
    springs: int = 0
    memory: float = 0.0
    items: dict = field(default_factory=dict)
    steps: float = 0.0
    seconds: float = 0.0
    groups: int = 0
    duration: float = 0.0
    substeps: int = 1
    bodies: int = 0
    cells: int = 0
    #: (key, message): parts larger than their method handles in reasonable time (refused without --force)
    limits: list = field(default_factory=list)

    @property
    def largest_key(self) -> str | None:
        return max(self.items, key=lambda k: self.items[k][0]) if self.items else None

    def memory_problem(self, available: int | None = None) -> tuple[str, str] | None:
        """(key, message) if the scene needs more memory than is available, else None."""
        available = available_memory() if available is None else available
        if available is None or self.memory <= available:
            return None
        key = self.largest_key
        _, what = self.items[key]
        return key, (f"{what} need about {_human_bytes(self.memory)} of memory in all, but this machine has "
                     f"{_human_bytes(available)} available; lower it")

    def size_problem(self) -> tuple[str, str] | None:
        """(key, message) of the first part too large for its method (hull points, mesh triangles)."""
        return self.limits[0] if self.limits else None

    def run_time_problem(self, limit: float = MAX_RUN_SECONDS) -> str | None:
        """A message naming simulation.duration (and dt, substeps) if the run would take longer
        than `limit` seconds even at the fastest speed this library reaches, else None."""
        if self.seconds <= limit:
            return None
        parts = [f"{self.particles:,} particles"] + ([f"{self.bodies:,} bodies"] if self.bodies else []) + (
            [f"{self.cells:,} grid cells"] if self.cells else [])
        return (f"simulation.duration: a run of {self.duration:g} s is {self.steps:.3g} integrator steps "
                f"(duration / dt x substeps = {self.substeps}) of {', '.join(parts)}: at least "
                f"{_human_seconds(self.seconds)} of computing even at the fastest speed inertia reaches. "
                "Lower duration or substeps (or raise dt), or pass --force to run it anyway")


def _cloth_springs(nu: int, nv: int, spec: M.Cloth) -> int:
    structural = (nu - 1) * nv + nu * (nv - 1)
    shear = 2 * (nu - 1) * (nv - 1)
    bend = max(nu - 2, 0) * nv + nu * max(nv - 2, 0)
    k_shear = spec.stiffness / 2.0 if spec.shear_stiffness is None else spec.shear_stiffness
    k_bend = spec.stiffness / 10.0 if spec.bend_stiffness is None else spec.bend_stiffness
    return structural + (shear if k_shear > 0 else 0) + (bend if k_bend > 0 else 0)


def _emitter_pool(model: M.SceneModel, group: M.ParticleGroup) -> list[tuple[str, float]]:
    """Pool slots each emitter adds (the builder's default capacity rule), per key."""
    sim = model.simulation
    out = []
    for k, e in enumerate(group.emitters):
        life = e.lifetime if isinstance(e.lifetime, float) else e.lifetime[1]
        window = min(e.stop, sim.duration) - e.start
        out.append((f"emitters[{k}].rate", 1.1 * (e.rate * max(0.0, min(life, window)) + e.rate * sim.dt + 1)))
    return out


def estimate_resources(model: M.SceneModel) -> ResourceEstimate:
    """Count what building `model` would allocate and what running it costs (nothing allocated)."""
    est = ResourceEstimate()
    sim = model.simulation

    def add(key: str, particles: float, springs: float, what: str):
        cost = particles * BYTES_PER_PARTICLE + springs * BYTES_PER_SPRING
        est.memory += cost
        est.particles += int(particles)
        est.springs += int(springs)
        previous = est.items.get(key, (0.0, what))[0]
        est.items[key] = (previous + cost, what)

    for i, g in enumerate(model.particles):
        path = f"particles[{i}]"
        if g.positions is not None:
            add(f"{path}.positions", len(g.positions), 0, f"{len(g.positions):,} particles")
        elif g.lattice is not None:
            n = math.prod(g.lattice.counts)
            add(f"{path}.lattice.counts", n, 0, f"{n:,} particles")
        elif g.random is not None:
            add(f"{path}.random.count", g.random.count, 0, f"{g.random.count:,} particles")
        elif g.chain is not None:
            n = g.chain.count
            add(f"{path}.chain.count", n, n - 1, f"{n:,} particles and {n - 1:,} springs")
        elif g.cloth is not None:
            nu, nv = g.cloth.counts
            springs = _cloth_springs(nu, nv, g.cloth)
            add(f"{path}.cloth.counts", nu * nv, springs, f"{nu * nv:,} particles and {springs:,} springs")
        if g.emitters and g.capacity is not None:
            add(f"{path}.capacity", g.capacity, 0, f"an emitter pool of {g.capacity:,} particles")
        elif g.emitters:
            for key, slots in _emitter_pool(model, g):
                add(f"{path}.{key}", slots, 0, f"an emitter pool of {int(slots):,} particles (rate x lifetime)")
        for k, f in enumerate([*model.forces, *g.forces]):
            if getattr(f, "type", None) == "springs":
                est.springs += len(f.pairs)
                est.memory += len(f.pairs) * BYTES_PER_SPRING
    for i, g in enumerate(model.tracers):
        path = f"tracers[{i}]"
        if g.positions is not None:
            add(f"{path}.positions", len(g.positions), 0, f"{len(g.positions):,} tracers")
        elif g.lattice is not None:
            n = math.prod(g.lattice.counts)
            add(f"{path}.lattice.counts", n, 0, f"{n:,} tracers")
        elif g.random is not None:
            add(f"{path}.random.count", g.random.count, 0, f"{g.random.count:,} tracers")
    for i, c in enumerate(model.colliders):
        if getattr(c, "type", None) == "mesh":
            cells = float(c.resolution + 1) ** 3
            key = f"colliders[{i}].resolution"
            est.memory += cells * BYTES_PER_GRID_CELL
            est.items[key] = (cells * BYTES_PER_GRID_CELL, f"a distance grid of {int(cells):,} cells")
    bodies = 0
    for name, body in model.bodies.items():
        n = body.copies
        bodies += n
        key = f"bodies.{name}" + (".array.count" if body.array is not None else ".pyramid.base" if body.pyramid is not None else "")
        cost = n * BYTES_PER_BODY
        for k, shape in _body_shapes(body):
            points, triangles = _shape_size(shape)
            cost += n * (points * BYTES_PER_HULL_POINT + triangles * BYTES_PER_TRIANGLE)
            if points > MAX_HULL_POINTS:
                est.limits.append((f"bodies.{name}.{k}.points", (
                    f"a convex hull of {points:,} points: every contact query scans them all; at most "
                    f"{MAX_HULL_POINTS:,} (simplify the hull, or pass --force)")))
            if triangles > MAX_MESH_TRIANGLES:
                est.limits.append((f"bodies.{name}.{k}.triangles", (
                    f"a mesh of {triangles:,} triangles; at most {MAX_MESH_TRIANGLES:,} (decimate it, or pass --force)")))
        est.memory += cost
        est.items[key] = (cost, f"{n:,} rigid bodies")
    est.bodies = bodies
    world_steps = _whole_steps(sim.duration, sim.dt)
    for name, table in model.sph.items():
        from .fluids import sph_memory

        n, cost = sph_memory(table)
        est.memory += cost
        est.particles += n
        est.items[f"sph.{name}.spacing"] = (cost, f"an SPH fluid of {n:,} particles")
        fluid_dt = table.dt if table.dt is not None else sph_step_bound(table)
        est.seconds += world_steps * max(1.0, sim.dt / fluid_dt) * n * SECONDS_PER_SPH_PARTICLE_STEP
    for name, table in model.fluids.items():
        from .fluids import grid_memory

        cells, cost = grid_memory(table)
        est.memory += cost
        est.cells += cells
        est.items[f"fluids.{name}.shape"] = (cost, f"a fluid grid of {cells:,} cells")
        est.seconds += world_steps * cells * SECONDS_PER_GRID_CELL_STEP
    est.groups = len(model.particles) + len(model.tracers)
    est.duration, est.substeps = sim.duration, sim.substeps
    est.steps = world_steps * float(sim.substeps)
    particle_steps = est.particles - sum(sph_particles(t) for t in model.sph.values())
    est.seconds += est.steps * (particle_steps * SECONDS_PER_PARTICLE_STEP + est.groups * SECONDS_PER_GROUP_STEP)
    est.seconds += world_steps * model.rigid.substeps * bodies * SECONDS_PER_BODY_SUBSTEP
    return est


def sph_step_bound(table) -> float:
    """The longest adaptive step an SPH fluid can take once it flows (s): at most ``dt_max``, and at most
    ``cfl`` spacings per step at the speed its tallest block reaches falling its own height,
    sqrt(2 |g| H) (or ``max_speed`` when larger), as `inertia.fluids.sph.SPHFluid` chooses it. A finer
    spacing means more particles *and* more steps."""
    dim = len(table.domain[0])
    g = np.zeros(dim)
    g[dim - 1] = -9.81
    if table.gravity is not None:
        g = np.asarray(table.gravity, float)
    gmag = float(np.linalg.norm(g))
    height = 0.0
    if gmag > 0.0:
        for block in table.fluid:
            lo, hi = block.box
            height = max(height, abs(float((np.asarray(hi, float) - np.asarray(lo, float)) @ g)) / gmag)
    speed = max(table.max_speed or 0.0, math.sqrt(2.0 * gmag * height))
    return table.dt_max if speed <= 0.0 else min(table.dt_max, table.cfl * table.spacing / speed)


def sph_particles(table) -> int:
    from .fluids import sph_particle_count
    return sph_particle_count(table)


def _whole_steps(duration: float, dt: float) -> float:
    """Steps of a run, ceil(duration / dt), as a float (no overflow for absurd ratios)."""
    ratio = duration / dt
    return float(math.ceil(ratio - 1e-9)) if ratio < 1e15 else ratio


def _body_shapes(body):
    """(key, shape spec) of each shape of a body table (shape, shapes[i], mix[i])."""
    if body.shape is not None:
        return [("shape", body.shape)]
    key = "shapes" if body.shapes is not None else "mix"
    return [(f"{key}[{i}]", s) for i, s in enumerate(body.shapes if body.shapes is not None else body.mix)]


def _shape_size(shape) -> tuple[int, int]:
    """(hull points, mesh or heightfield triangles) a shape spec holds inline."""
    t = getattr(shape, "type", None)
    if t == "hull":
        if shape.points is not None:
            return len(shape.points), 0
        return sum(len(p) for p in shape.parts), 0
    if t == "mesh" and getattr(shape, "triangles", None) is not None:
        return len(shape.vertices), len(shape.triangles)
    if t == "heightfield" and getattr(shape, "heights", None) is not None:
        rows = len(shape.heights)
        cols = max((len(r) for r in shape.heights), default=0)
        return rows * cols, 2 * max(rows - 1, 0) * max(cols - 1, 0)
    return 0, 0
