"""Collision benchmarks; every figure is a ratio to a baseline measured in the same run.

    python benchmarks/bench_collisions.py            # full sizes (1e6 particles)
    python benchmarks/bench_collisions.py --quick    # 1e5 / 1e4 particles
    INERTIA_SERIAL_BELOW=1000000000 python benchmarks/bench_collisions.py --only colliders --cpu
                                                     # serial kernels, CPU time of the stepping thread

1. N particles falling on a ground plane and a sphere: ms per step with the colliders, as a
   ratio to the same step (same integrator, same forces) without colliders. Target <= 1.5x.
   Reported for the default integrator (rk4, fused path) and for semi-implicit Euler, in both
   collision modes, with the machine's copy bandwidth as a floor reference. With static
   colliders the collision pass runs inside the integrator's fused kernel ("fused" in the
   table; ``particle_kernels.step_and_collide``); "separate" forces the separate pass
   (integrator kernel, then ``collide_particles`` with a saved start-of-step copy) for comparison.
2. Self-colliding spheres stacked in a box (every particle in contact) at two sizes (10x
   apart): ms per step, the broad-phase share of the step, and the growth ratio (target <= 12x
   for 10x the particles).

Timings are medians over repeated steps after a warm-up (Numba compilation excluded); with and
without colliders are stepped in turn so that both see the same machine load. On a loaded machine
the wall-clock figures of parallel kernels mostly measure waiting for a core: ``--cpu`` times the
CPU time of the calling thread instead (``time.thread_time``), which is the work of the step when
the kernels run serially in that thread (``INERTIA_SERIAL_BELOW`` above the array sizes).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numba
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import copy_bandwidth, rain_particles  # noqa: E402

import inertia as ia  # noqa: E402

C = ia.colliders


#: The clock of the timings: wall time, or the calling thread's CPU time (``--cpu``)
_clock = time.perf_counter


def _median_step_ms(sim, steps):
    times = []
    for _ in range(steps):
        t0 = _clock()
        sim.step()
        times.append(_clock() - t0)
    return 1e3 * float(np.median(times))


def bench_colliders(n, integrator, steps, warmup):
    """Median ms per step without colliders and with them (both modes). The three simulations
    are stepped in turn, round after round, so that a change of machine load during the run
    affects the baseline and the collision steps alike."""
    sims = {"none": ia.Simulation(rain_particles(n), integrator=integrator, dt=1e-3)}
    for mode in ("a_priori", "a_posteriori", "a_priori separate"):
        ps = rain_particles(n)
        ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)), restitution=0.3, friction=0.3)
        ps.add_collider(C.Sphere(center=(0.5, 0.0, 0.5), radius=0.5), restitution=0.5, friction=0.1)
        ps.collision_mode = mode.split()[0]
        if mode.endswith("separate"):
            ps._collision.can_fuse = lambda: False
        sims[mode] = ia.Simulation(ps, integrator=integrator, dt=1e-3)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*start inside colliders")  # the sphere is in the rain
        for sim in sims.values():
            for _ in range(warmup):
                sim.step()
    times = {name: [] for name in sims}
    profiles = {name: dict(sim.system._collision.profile) for name, sim in sims.items() if name != "none"}
    for _ in range(steps):
        for name, sim in sims.items():
            t0 = _clock()
            sim.step()
            times[name].append(_clock() - t0)
    plain = 1e3 * float(np.median(times["none"]))
    rows = []
    for mode in ("a_priori", "a_posteriori", "a_priori separate"):
        data = sims[mode].system._collision
        prof = {k: 1e3 * (data.profile[k] - profiles[mode][k]) / steps for k in ("save", "classify", "collide")}
        label = mode if mode.endswith("separate") else f"{mode} {'fused' if data.fused_step else 'separate'}"
        rows.append((label, 1e3 * float(np.median(times[mode])), prof, data.resting_count))
    return plain, rows


def _box_pile(n, r):
    # spheres stacked in a cubic lattice (touching) on the floor of a container, under gravity:
    # every particle has its 4-6 neighbours in contact from the first step
    side = int(np.ceil((n / 10) ** 0.5))
    layers = int(np.ceil(n / side ** 2))
    g = (np.arange(side) - (side - 1) / 2) * 2 * r
    xs, ys, zs = np.meshgrid(g, g, r + np.arange(layers) * 2 * r, indexing="ij")
    x = np.column_stack([xs.ravel(), ys.ravel(), zs.ravel()])[:n]
    ps = ia.ParticleSystem(x, radius=r)
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    half = side * r + r
    height = 2 * layers * r
    ps.add_collider(C.Container(center=(0, 0, height), half_extents=(half, half, height)),
                    restitution=0.2, friction=0.4)
    ps.self_collisions = True
    C.configure_contacts(ps, self_restitution=0.2, self_friction=0.4)
    return ps


def bench_self(n, steps, warmup):
    ps = _box_pile(n, 0.02)
    sim = ia.Simulation(ps, integrator="semi_implicit_euler", dt=2e-3)
    for _ in range(warmup):
        sim.step()
    p0 = dict(ps._collision.profile)
    t0 = time.perf_counter()
    ms = _median_step_ms(sim, steps)
    total = time.perf_counter() - t0
    broad = ps._collision.profile["broad_phase"] - p0["broad_phase"]
    solve = ps._collision.profile["pair_solve"] - p0["pair_solve"]
    return ms, broad / total, solve / total, ps._collision.pair_count, ps._collision.color_count


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x smaller sizes")
    parser.add_argument("--only", choices=("colliders", "self"), help="run one of the two benchmarks")
    parser.add_argument("--cpu", action="store_true", help="time the calling thread's CPU time, not wall "
                        "time (set INERTIA_SERIAL_BELOW above the sizes so that the kernels run in it)")
    args = parser.parse_args(argv)
    global _clock
    _clock = time.thread_time if args.cpu else time.perf_counter
    big = 100_000 if args.quick else 1_000_000
    print(f"inertia collision benchmarks; numba threads = {numba.get_num_threads()}; "
          f"{'CPU time of the calling thread' if args.cpu else 'wall time'}")
    bandwidth = copy_bandwidth()
    # the separate pass keeps the start-of-step state: it writes x0, v0 (48 B) and reads x, v, x0
    # (72 B) per particle and step, at least 120 B of memory traffic on top of the step's 104 B
    # (read x, v, 1/m; write x, v); the fused pass adds only radius, rest_k and active (13 B)
    print(f"copy bandwidth {bandwidth / 1e9:.1f} GB/s: per step, {big:,} particles need "
          f"{104 * big / bandwidth * 1e3:.2f} ms without colliders (104 B each), "
          f"{117 * big / bandwidth * 1e3:.2f} ms fused (117 B: floor ratio 1.13x), "
          f"{224 * big / bandwidth * 1e3:.2f} ms as a separate pass (224 B: 2.15x)\n")

    print(f"1. {big:,} particles, ground plane + sphere (ratio to the same step without colliders)")
    for integrator in ("rk4", "semi_implicit_euler") if args.only != "self" else ():
        plain, rows = bench_colliders(big, integrator, steps=21, warmup=40)
        print(f"   {integrator:<20s} no colliders {plain:8.2f} ms/step")
        for mode, ms, prof, resting in rows:
            parts = ", ".join(f"{k} {v:.2f}" for k, v in prof.items())
            print(f"   {'':<20s} {mode:<19s} {ms:8.2f} ms/step  ratio {ms / plain:5.2f}x   "
                  f"({parts} ms; {resting:,} resting)")

    if args.only == "colliders":
        return
    small = big // 10
    print(f"\n2. self-colliding spheres in a box: {small:,} and {big:,}")
    results = {}
    for n in (small, big):
        ms, broad, solve, pairs, colours = bench_self(n, steps=5, warmup=5)
        results[n] = ms
        print(f"   {n:>9,d} spheres: {ms:9.2f} ms/step  broad phase {100 * broad:4.1f}%  pair solve "
              f"{100 * solve:4.1f}%  ({pairs:,} pairs, {colours} colours)")
    print(f"   growth for 10x the particles: {results[big] / results[small]:.2f}x (target <= 12x)")


if __name__ == "__main__":
    main()
