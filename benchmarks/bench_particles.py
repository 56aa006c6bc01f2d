"""Benchmark of the foundation: 1M particles under gravity and drag; a 100k implicit spring network.

Run:  python benchmarks/bench_particles.py [--particles 1000000] [--cloth 316]

Reports, measured in the same run:
- ms per step of `semi_implicit_euler` and `rk4`, bare (the integrator's step) and through
  `Simulation.step` (stages and the NaN/inf check, folded into the fused kernels' pass), with
  the ratio between them (target <= 1.10x) and the ratio the check cost when it re-read the state;
- effective bandwidth: the bytes a step must move at least (read x, v, 1/m; write x, v = 104 bytes
  per 3-D particle) per second, as a fraction of the machine's copy bandwidth;
- speed-up over a plain vectorised NumPy implementation of the same step;
- ms per step of `implicit_euler` on a ~100k-particle cloth-like spring grid, with CG iterations.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import best_time, copy_bandwidth  # noqa: E402

import inertia as ia  # noqa: E402
from inertia.ode.kernels import all_finite  # noqa: E402

G = np.array([0.0, 0.0, -9.81])
K_DRAG = 0.1


def make_system(n):
    rng = np.random.default_rng(0)
    ps = ia.ParticleSystem(rng.random((n, 3)), rng.normal(size=(n, 3)), masses=rng.uniform(0.5, 2.0, n))
    ps.add_force(ia.forces.Gravity(G))
    ps.add_force(ia.forces.Drag(K_DRAG))
    return ps


def numpy_semi_implicit_euler(x, v, m, dt):
    # what a careful NumPy user writes: f = m g - k v; a = f / m; v += a dt; x += v dt
    f = m[:, None] * G - K_DRAG * v
    a = f / m[:, None]
    v += a * dt
    x += v * dt


def numpy_rk4(x, v, m, dt):
    def accel(vv):
        return G - K_DRAG * vv / m[:, None]

    k1x, k1v = v, accel(v)
    k2x, k2v = v + 0.5 * dt * k1v, accel(v + 0.5 * dt * k1v)
    k3x, k3v = v + 0.5 * dt * k2v, accel(v + 0.5 * dt * k2v)
    k4x, k4v = v + dt * k3v, accel(v + dt * k3v)
    x += dt / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
    v += dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)


def interleaved_times(*fns, repeat=15, warmup=3):
    """Median wall time of each fn(), the functions called in turn so all see the same machine load."""
    import time
    for _ in range(warmup):
        for fn in fns:
            fn()
    samples = [[] for _ in fns]
    for _ in range(repeat):
        for fn, times in zip(fns, samples):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
    return tuple(float(np.median(times)) for times in samples)


def cloth(side):
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    x = np.stack([i.ravel() * 0.01, np.zeros(side * side), -j.ravel() * 0.01], axis=1)
    idx = i * side + j
    pairs = np.concatenate([
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1),
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()], 1),
        np.stack([idx[1:, :-1].ravel(), idx[:-1, 1:].ravel()], 1)])
    ps = ia.ParticleSystem(x, masses=1e-4, pinned=idx[:, 0])
    ps.add_force(ia.forces.Gravity())
    ps.add_force(ia.forces.Springs(pairs, stiffness=1000.0, damping=0.01))
    return ps, len(pairs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=1_000_000)
    parser.add_argument("--cloth", type=int, default=316, help="cloth side (316^2 ~ 100k particles)")
    args = parser.parse_args()
    n, dt = args.particles, 1e-3
    from numba import get_num_threads
    print(f"inertia {ia.__version__}, numba threads: {get_num_threads()}, particles: {n:,}")

    # copy bandwidth at the size of the state itself (48 MB for 1M particles), so both sides see the same caches
    bandwidth = copy_bandwidth(nbytes=2 * n * 3 * 8)
    print(f"copy bandwidth (same run): {bandwidth / 1e9:.2f} GB/s")
    minimal_bytes = n * (3 * 8 * 4 + 8)   # read x, v, 1/m; write x, v

    rows = []
    for name, numpy_step in (("semi_implicit_euler", numpy_semi_implicit_euler), ("rk4", numpy_rk4)):
        ps = make_system(n)
        sim = ia.Simulation(ps, integrator=name, dt=dt)
        t_ours, t_sim, t_reread = interleaved_times(lambda: sim.integrator.step(0.0, dt), sim.step,
                                                    lambda: (sim.step(), all_finite(ps.state)))
        x, v, m = ps.x.copy(), ps.v.copy(), ps.mass.copy()
        t_numpy = best_time(lambda: numpy_step(x, v, m, dt), repeat=5)
        fraction = minimal_bytes / t_ours / bandwidth
        rows.append((name, t_ours * 1e3, t_sim * 1e3, t_reread * 1e3, fraction, t_numpy / t_ours))
    print(f"\n{'integrator':22s} {'ms/step':>9s} {'ms/step(sim)':>13s} {'sim/step':>9s} {'re-read/step':>13s} "
          f"{'of copy bw':>11s} {'vs NumPy':>9s}")
    for name, ms, ms_sim, ms_reread, frac, speedup in rows:
        print(f"{name:22s} {ms:9.2f} {ms_sim:13.2f} {ms_sim / ms:8.2f}x {ms_reread / ms:12.2f}x "
              f"{frac:10.2f}x {speedup:8.1f}x")
    print("(ms/step(sim) is Simulation.step: stages and the NaN/inf check, which the fused kernels fold\n"
          " into their own pass; sim/step is its ratio to the bare integrator step, target <= 1.10x;\n"
          " re-read/step: Simulation.step plus a separate pass over the state, the check as it was before)")

    ps, springs = cloth(args.cloth)
    sim = ia.Simulation(ps, integrator="implicit_euler", dt=1.0 / 60, cg_tolerance=1e-4,
                        cg_max_iterations=200)
    sim.step()
    t_implicit = best_time(sim.step, repeat=5, warmup=1)
    print(f"\nimplicit_euler cloth: {ps.particle_count:,} particles, {springs:,} springs, dt = 1/60 s: "
          f"{t_implicit * 1e3:.1f} ms/step, CG iterations {sim.integrator.last_cg_iterations} "
          f"(tolerance 1e-4)")


if __name__ == "__main__":
    main()
