"""Benchmark of the coupled world step: particles raining on a stack of rigid boxes.

Run:  python benchmarks/bench_world.py [--particles 20000] [--steps 60]

Scene: N particles (r = 3 mm, 1 g) fall from 0.7-1.5 m onto a stack of three 0.2 m boxes on the
ground plane (dt = 1/120 s, rigid substeps 4, semi-implicit Euler for the particles); the particles
push the boxes back (two-way coupling).

Reports, measured in the same run:
- ms per world step and per stage (``world.profile``: kinematics, rigid, fluids, the particle group,
  coupling) and the particle collision stage's own parts (classify, collide);
- the baseline: the same particles on the same ground plane without bodies (fused particle kernels),
  and the ratio coupled / baseline: what seeing moving bodies costs the particle layer.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import inertia as ia
from inertia.model import ModelBuilder
from inertia.world import World


def make(n: int, bodies: bool) -> World:
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    b.add_plane()
    if bodies:
        for k in range(3):
            body = b.add_body(position=(0.0, 0.0, 0.1 + 0.2 * k))
            b.add_box(body, half_extents=(0.1, 0.1, 0.1), density=200.0)
    world = World(dt=1 / 120, model=b.finalize(), rigid_options={"substeps": 4})
    rng = np.random.default_rng(7)
    x = np.column_stack([rng.uniform(-0.15, 0.15, n), rng.uniform(-0.15, 0.15, n), rng.uniform(0.7, 1.5, n)])
    ps = ia.ParticleSystem(x, masses=0.001, radius=0.003)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
    world.add("rain", ps, integrator="semi_implicit_euler")
    return world


def measure(n: int, steps: int, bodies: bool):
    world = make(n, bodies)
    for _ in range(5):            # compile, then start from a running state
        world.step()
    data = world["rain"]._collision
    for k in world.profile:
        world.profile[k] = 0.0
    for k in data.profile:
        data.profile[k] = 0 if k == "steps" else 0.0
    t0 = time.perf_counter()
    for _ in range(steps):
        world.step()
    ms = (time.perf_counter() - t0) / steps * 1e3
    stages = {k: v / steps * 1e3 for k, v in world.profile.items() if v}
    parts = {k: v / steps * 1e3 for k, v in data.profile.items() if k in ("classify", "collide") and v}
    return ms, stages, parts


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=20000)
    ap.add_argument("--steps", type=int, default=60)
    args = ap.parse_args()
    base, base_stages, _ = measure(args.particles, args.steps, bodies=False)
    coupled, stages, parts = measure(args.particles, args.steps, bodies=True)
    fmt = ", ".join
    print(f"{args.particles} particles raining on 3 boxes, dt = 1/120 s, {args.steps} steps")
    print(f"  coupled world : {coupled:8.2f} ms/step  stages: {fmt(f'{k} {v:.2f}' for k, v in stages.items())}")
    print(f"                  particle collision parts: {fmt(f'{k} {v:.2f}' for k, v in parts.items())}")
    print(f"  baseline      : {base:8.2f} ms/step  (ground plane only, fused particle kernels)")
    print(f"  ratio coupled / baseline: {coupled / base:.2f}x")


if __name__ == "__main__":
    main()
