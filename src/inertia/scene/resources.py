"""How much memory and time a scene needs, estimated from the validated model before building.

A scene file can ask for more than a machine has: ``count = 1_000_000_000`` would allocate
about two terabytes, ``duration = 1e12`` would run for millennia. `estimate_resources` counts
what the builder would make (particles per group, springs of chains and cloth, emitter pools,
distance grids of mesh colliders) and the steps of a run, without allocating any of it, so
that `inertia.scene.build` can refuse a scene that does not fit (naming the key, the estimate
and the machine's available memory) and `inertia run` can refuse a run that would not finish.

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
#: a rigid body's arrays, its shapes' rows, contact manifolds (about 3 per body in a pile) and scratch
BYTES_PER_BODY = 4000
#: rigid solve per body and substep, a lower bound: the 204-box pyramid (examples/box_pyramid.toml) runs
#: 240 steps x 8 substeps in ~15 s on a shared 2-core machine, 3.8e-5 s per body-substep, most bodies asleep
SECONDS_PER_BODY_SUBSTEP = 5e-6


def available_memory() -> int | None:
    """Bytes of memory this process can still use: the smaller of the system's available memory
    (``MemAvailable`` of /proc/meminfo, else sysconf) and a cgroup v2 limit; None if unknown."""
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

    def run_time_problem(self, limit: float = MAX_RUN_SECONDS) -> str | None:
        """A message naming simulation.duration (and dt, substeps) if the run would take longer
        than `limit` seconds even at the fastest speed this library reaches, else None."""
        if self.seconds <= limit:
            return None
        return (f"simulation.duration: a run of {self.duration:g} s is {self.steps:.3g} integrator steps "
                f"(duration / dt x substeps = {self.substeps}) of {self.particles:,} particles: at least "
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
        est.memory += n * BYTES_PER_BODY
        est.items[key] = (n * BYTES_PER_BODY, f"{n:,} rigid bodies")
    for name, table in model.sph.items():
        from .fluids import sph_memory

        n, cost = sph_memory(table)
        est.memory += cost
        est.particles += n
        est.items[f"sph.{name}.spacing"] = (cost, f"an SPH fluid of {n:,} particles")
    for name, table in model.fluids.items():
        from .fluids import grid_memory

        cells, cost = grid_memory(table)
        est.memory += cost
        est.items[f"fluids.{name}.shape"] = (cost, f"a fluid grid of {cells:,} cells")
    est.groups = len(model.particles) + len(model.tracers)
    est.duration, est.substeps = sim.duration, sim.substeps
    est.steps = math.ceil(sim.duration / sim.dt - 1e-9) * float(sim.substeps)
    est.seconds = est.steps * (est.particles * SECONDS_PER_PARTICLE_STEP + est.groups * SECONDS_PER_GROUP_STEP)
    est.seconds += math.ceil(sim.duration / sim.dt - 1e-9) * model.rigid.substeps * bodies * SECONDS_PER_BODY_SUBSTEP
    return est
