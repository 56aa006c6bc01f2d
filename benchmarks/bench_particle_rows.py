"""Cost of the particle Contacts rows on the fused path (issue 9), the scene of bench_collisions.py.

    python benchmarks/bench_particle_rows.py [N [STEPS]]     # default 1,000,000 particles, 21 steps

N particles raining on a ground plane and a sphere, three setups stepped in turn (same load):
``off`` a lone Simulation (no rows: the pure particle path); ``on`` the same with the fused step
writing contact slots (``ParticleCollisionData.pass_record``; the slots cleared each step as the
World does); ``world`` a World with the plane (body -1) and a static sphere body, whose groups
record rows (the fused step's slots plus the world's count and fill of the Contacts rows, timed
under its ``coupling`` stage). Median ms per step after 40 warm-up steps; the fused kernel's mean
time from the collision profile.
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import rain_particles  # noqa: E402  (the scene of bench_collisions.py)

import inertia as ia  # noqa: E402
from inertia.collision import particle_kernels as pk  # noqa: E402
from inertia.model import ModelBuilder  # noqa: E402
from inertia.world import World  # noqa: E402

C = ia.colliders
n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
steps = int(sys.argv[2]) if len(sys.argv) > 2 else 21



warnings.simplefilter("ignore")  # the sphere starts inside the rain: "start inside colliders"
for integrator in ("rk4", "semi_implicit_euler"):
    runs = {}
    for name in ("off", "on"):
        ps = rain_particles(n)
        ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)), restitution=0.3, friction=0.3)
        ps.add_collider(C.Sphere(center=(0.5, 0.0, 0.5), radius=0.5), restitution=0.5, friction=0.1)
        sim = ia.Simulation(ps, integrator=integrator, dt=1e-3)
        d = ps._collision
        if name == "on":
            k = d.cint.shape[0]
            rec = pk.PassRecord(np.full((n, 2), -1, np.int64), np.zeros((n, 2, 3)), np.full(k, -1, np.int64),
                                np.arange(k, dtype=np.int64), d.distance_tolerance)
            d.pass_record = lambda rec=rec: (rec, True)
            def step(sim=sim, rec=rec):
                rec.slot_entry.fill(-1); rec.slot_impulse.fill(0.0)
                sim.step()
        else:
            step = sim.step
        runs[name] = (step, d)
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    b.add_plane(restitution=0.3, friction=0.3)
    ball = b.add_body(body_type="static", position=(0.5, 0.0, 0.5))
    b.add_sphere(ball, 0.5, restitution=0.5, friction=0.1)
    world = World(dt=1e-3, model=b.finalize())
    ps = rain_particles(n)
    world.add("rain", ps, integrator=integrator)
    runs["world"] = (world.step, ps._collision)
    for step, d in runs.values():
        for _ in range(40):
            step()
    times = {k: [] for k in runs}
    kern0 = {k: d.profile["collide"] for k, (s, d) in runs.items()}
    coup0 = world.profile["coupling"]
    for _ in range(steps):
        for k, (step, d) in runs.items():
            t0 = time.perf_counter(); step(); times[k].append(time.perf_counter() - t0)
    print(f"{integrator}: fused={[d.fused_step for s, d in runs.values()]}, rows last world step "
          f"{world.rigid.contacts.particle_count}")
    for k, (s, d) in runs.items():
        kern = 1e3 * (d.profile["collide"] - kern0[k]) / steps
        extra = f", world fill rows {1e3 * (world.profile['coupling'] - coup0) / steps:.2f} ms" if k == "world" else ""
        print(f"   {k:6s} {1e3 * np.median(times[k]):8.2f} ms/step  (fused kernel {kern:.2f} ms mean{extra})")
