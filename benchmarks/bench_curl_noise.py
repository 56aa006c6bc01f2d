"""Benchmark: 3-D curl-noise sampling and tracer advection at 10^6 points.

    python benchmarks/bench_curl_noise.py [--points 1000000] [--repeat 5]
    python benchmarks/bench_curl_noise.py --leak [--leak-dt 0.005]   # issue 8's container check

Reports, for 3-D curl-noise with 3 octaves (3 potentials x 3 octaves = 9 noise evaluations
with gradient per point):

- sampling: ms per call and points per second, steady (3-D lattice) and time-varying (4-D
  lattice), simplex and Perlin, without and with a sphere boundary;
- baselines measured in the same run:
    * the machine's copy bandwidth (``_common.copy_bandwidth``) and the time to copy the
      (M, 3) float64 points into the output (48 bytes per point read + written): the
      memory-bound floor of any field evaluation;
    * a plain NumPy implementation of one octave of 3-D improved Perlin noise with its
      gradient (vectorised over the points, checked against the kernel's values), times 9:
      what the same work costs in NumPy;
- tracer advection of the same points with RK4 (``ia.Tracers`` + ``ia.Simulation``): ms per
  step (4 field evaluations per step).

``--compare-with SRC`` measures the sampling table only (1 thread and CPU time by default;
``--threads 2`` for the wall clock on two threads),
alternating, round by round, between this source tree and another one (for instance
``/work/main/src``, before the batched lattice walk) in subprocesses, and prints each
configuration's median over rounds (of each round's best time) on both and their ratio,
and the ratio of the best times: both trees see the same machine load.

    python benchmarks/bench_curl_noise.py --compare-with /work/main/src --rounds 3

``--leak`` instead runs issue 8's containment check: 3000 tracers spread uniformly inside
``Container(half_extents=(1, 1, 1))`` in ``CurlNoise(dim=3, seed=7)``, RK4 at ``--leak-dt`` for
10 s, and prints how many left and the least signed distance seen (before the continuous wall
blend, 53 of 3000 left). Takes minutes; the test suite runs 400 tracers near the edges.

``--threshold`` times the serial and the parallel build of the 3-D curl-noise kernel from 512 to
65,536 points (run it with ``NUMBA_NUM_THREADS=2``): where the parallel build pays sets
``fields.kernels.SERIAL_BELOW``.

``--profile`` splits a 3-D Perlin sample (10^6 points, 3 octaves, one thread, CPU time) into
its stages: the potential (``kernels.potential3_block`` over every block) and, within it, the
corner passes (``kernels._perlin_pass`` on one fixed block, as many times) and by difference
the lattice walk and fades; the curl assembly and output writes (the sample minus the
potential); with a sphere, the wall lists (``_Boundaries.prepare``: the collider's query,
``wall_counts`` / ``wall_rows``, normals and Hessians) and the bounded kernel's extra work.
Stage drivers are compiled on their own, so the parts add up only roughly (a few per cent).

``--cold-compile [SRC ...]`` measures the CPU seconds a 3-D curl-noise scene (3 octaves,
time-varying, a sphere boundary, 200 points) takes to build and sample once from an empty
Numba cache, in a fresh process per source tree (this one and each SRC):

    python benchmarks/bench_curl_noise.py --cold-compile /tmp/before/src

Timings are the best of ``--repeat`` runs after one warm-up call (Numba compilation excluded).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numba
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import copy_bandwidth  # noqa: E402

import inertia as ia  # noqa: E402
from inertia.fields.noise import _GRADIENTS, lattice_tables  # noqa: E402


def best_of(fn, repeat, clock=time.perf_counter):
    fn()  # warm-up (compilation, caches)
    times = []
    for _ in range(repeat):
        t0 = clock()
        fn()
        times.append(clock() - t0)
    return min(times)


def numpy_perlin3(p, perm, grads):
    """One octave of improved Perlin noise (Perlin 2002) and its gradient, in plain NumPy.

    Same lattice, hash and gradient table as the kernel's ``kind="perlin"``:
    n = sum_corners prod_k w_k (g . d), w_k = s(f_k) or 1 - s(f_k), s = 6f^5 - 15f^4 + 10f^3.
    """
    fl = np.floor(p)
    cell = fl.astype(np.int64) & 255
    f = p - fl
    s = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    ds = 30.0 * f * f * (f - 1.0) ** 2
    value = np.zeros(len(p))
    grad = np.zeros_like(p)
    for bits in range(8):
        o = np.array([bits & 1, (bits >> 1) & 1, (bits >> 2) & 1])
        h = perm[cell[:, 0] + o[0] + perm[cell[:, 1] + o[1] + perm[cell[:, 2] + o[2]]]] & 15
        g = grads[h]
        d = f - o
        gd = np.sum(g * d, axis=1)
        w = np.where(o == 1, s, 1.0 - s)
        dw = np.where(o == 1, ds, -ds)
        W = w[:, 0] * w[:, 1] * w[:, 2]
        value += W * gd
        grad[:, 0] += dw[:, 0] * w[:, 1] * w[:, 2] * gd + W * g[:, 0]
        grad[:, 1] += w[:, 0] * dw[:, 1] * w[:, 2] * gd + W * g[:, 1]
        grad[:, 2] += w[:, 0] * w[:, 1] * dw[:, 2] * gd + W * g[:, 2]
    return value, grad


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--steps", type=int, default=5, help="RK4 steps timed for advection")
    parser.add_argument("--leak", action="store_true", help="run the 3000-tracer container check only")
    parser.add_argument("--leak-dt", type=float, default=0.005)
    parser.add_argument("--compare-with", metavar="SRC", help="another source tree to compare with")
    parser.add_argument("--rounds", type=int, default=3, help="alternations for --compare-with")
    parser.add_argument("--threads", type=int, default=1, help="Numba threads for --compare-with")
    parser.add_argument("--threshold", action="store_true", help="serial vs parallel build by size")
    parser.add_argument("--cold-compile", nargs="*", metavar="SRC", help="cold-compile CPU seconds")
    parser.add_argument("--profile", action="store_true", help="Perlin sample split into stages")
    parser.add_argument("--cold-child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--sampling-json", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.leak:
        return leak_check(args.leak_dt)
    if args.threshold:
        return threshold()
    if args.cold_child:
        return cold_child()
    if args.profile:
        return profile(args.points, args.repeat)
    if args.cold_compile is not None:
        return cold_compile(args.cold_compile)
    if args.sampling_json:
        print(json.dumps(sampling_table(args.points, args.repeat)))
        return None
    if args.compare_with:
        return compare(args)
    M = args.points
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1.0, 1.0, (M, 3))
    out = np.empty_like(pts)
    print(f"inertia curl-noise benchmark: {M:,} points, numba threads {numba.get_num_threads()}, "
          f"cpus {os.cpu_count()}, load average {os.getloadavg()[0]:.1f}")

    # -- baselines ------------------------------------------------------------------------
    bandwidth = copy_bandwidth()
    copy_s = 2 * pts.nbytes / bandwidth
    print(f"baseline copy bandwidth {bandwidth / 1e9:.1f} GB/s: moving points in and velocities "
          f"out takes {copy_s * 1e3:.2f} ms")
    perm, offsets = lattice_tables(0, 1, 1)
    grads = _GRADIENTS[3]
    lattice = pts * 2.0 + offsets[0, 0, :3]
    numpy_s = best_of(lambda: numpy_perlin3(lattice, perm, grads), max(1, args.repeat // 2))
    # Cross-check: the NumPy octave is the kernel's Perlin noise (up to its range scale).
    noise = ia.fields.Noise(3, seed=0, kind="perlin", frequency=2.0)
    check = slice(0, 10_000)
    ref = numpy_perlin3(lattice[check], perm, grads)[0] * noise._scale
    assert np.allclose(ref, noise(pts[check]), atol=1e-12), "NumPy reference disagrees with the kernel"
    print(f"baseline NumPy, 1 octave Perlin + gradient:  {numpy_s * 1e3:9.2f} ms "
          f"(x 9 = {9 * numpy_s * 1e3:.0f} ms for 3 potentials x 3 octaves)")

    # -- sampling ---------------------------------------------------------------------------
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3)
    rows = []
    for kind in ("simplex", "perlin"):
        for time_frequency in (0.0, 0.5):
            for boundaries in ([], [sphere]):
                field = ia.fields.CurlNoise(dim=3, seed=1, kind=kind, frequency=2.0, octaves=3,
                                            time_frequency=time_frequency, boundaries=boundaries)
                s = best_of(lambda f=field: f.sample(pts, 0.25, out), args.repeat)
                label = (f"{kind:7s} {'4-D (t)' if time_frequency else '3-D    '} "
                         f"{'sphere' if boundaries else 'free  '}")
                rows.append((label, s))
                print(f"curl-noise {label}: {s * 1e3:9.2f} ms/call {M / s / 1e6:7.2f} Mpoints/s  "
                      f"x{s / copy_s:7.0f} copy  NumPy-Perlin/this {9 * numpy_s / s:6.1f}x")

    # One thread, CPU time: a figure that other processes on a shared machine disturb less.
    field = ia.fields.CurlNoise(dim=3, seed=1, frequency=2.0, octaves=3)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        part = pts[: max(1, M // 5)]
        part_out = np.empty_like(part)
        field.sample(part, 0.25, part_out)
        cpu = []
        for _ in range(args.repeat):
            t0 = time.process_time()
            field.sample(part, 0.25, part_out)
            cpu.append(time.process_time() - t0)
    finally:
        numba.set_num_threads(threads)
    per_point = min(cpu) / len(part)
    print(f"curl-noise simplex 3-D free, 1 thread: {per_point * 1e9:.0f} ns CPU per point "
          f"({per_point / 9 * 1e9:.0f} ns per octave of noise with gradient)")

    # -- advection --------------------------------------------------------------------------
    for boundaries in ([], [sphere]):
        field = ia.fields.CurlNoise(dim=3, seed=1, frequency=2.0, octaves=3, time_frequency=0.5,
                                   boundaries=boundaries)
        start = pts if not boundaries else np.where(
            (sphere.signed_distance(pts) > 0)[:, None], pts, pts + 1.0)
        tracers = ia.Tracers(start, field)
        sim = ia.Simulation(tracers, integrator="rk4", dt=1e-2)
        sim.step()  # warm-up
        t0 = time.perf_counter()
        for _ in range(args.steps):
            sim.step()
        step_s = (time.perf_counter() - t0) / args.steps
        print(f"RK4 advection, simplex 4-D (t) {'sphere' if boundaries else 'free  '}: "
              f"{step_s * 1e3:9.2f} ms/step ({M * 4 / step_s / 1e6:.2f} Mpoint-evaluations/s)")


def sampling_table(M, repeat):
    """Best seconds per `sample` call of 3-D curl-noise (3 octaves) at M points, per
    configuration: kind x steady / time-varying x no boundary / sphere / container.
    Process CPU time when Numba runs one thread (less disturbed by other processes on a
    shared machine than the wall clock), wall-clock time otherwise."""
    clock = time.process_time if numba.get_num_threads() == 1 else time.perf_counter
    pts = np.random.default_rng(0).uniform(-1.0, 1.0, (M, 3)) * 0.999
    out = np.empty_like(pts)
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3)
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    table = {}
    for kind in ("simplex", "perlin"):
        for time_frequency in (0.0, 0.5):
            for name, boundaries in (("free", []), ("sphere", [sphere]), ("container", [room])):
                field = ia.fields.CurlNoise(dim=3, seed=1, kind=kind, frequency=2.0, octaves=3,
                                            time_frequency=time_frequency, boundaries=boundaries)
                label = f"{kind} {'4-D (t)' if time_frequency else '3-D'} {name}"
                table[label] = best_of(lambda f=field: f.sample(pts, 0.25, out), repeat, clock)
    return table


def compare(args):
    """The sampling table on this tree and on args.compare_with, alternating round by round."""
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")
    trees = {"this": os.path.abspath(here), "other": os.path.abspath(args.compare_with)}
    runs = {"this": {}, "other": {}}  # label -> each round's best of --repeat
    for r in range(args.rounds):
        for name, src in trees.items():
            env = dict(os.environ, PYTHONPATH=src, NUMBA_NUM_THREADS=str(args.threads))
            if name == "other":  # compile the other tree's kernels into a cache of our own
                env["NUMBA_CACHE_DIR"] = os.path.join(os.path.expanduser("~"), ".cache",
                                                      "inertia-bench-compare")
            run = subprocess.run([sys.executable, os.path.abspath(__file__), "--sampling-json",
                                  "--points", str(args.points), "--repeat", str(args.repeat)],
                                 env=env, capture_output=True, text=True, check=True)
            for label, s in json.loads(run.stdout.strip().splitlines()[-1]).items():
                runs[name].setdefault(label, []).append(s)
        print(f"round {r + 1} of {args.rounds} done, load average {os.getloadavg()[0]:.1f}", flush=True)
    M = args.points
    clock = "CPU time" if args.threads == 1 else "wall clock"
    print(f"3-D curl-noise, 3 octaves, {M:,} points, {args.threads} thread(s), {clock}, "
          f"{args.rounds} rounds x best of {args.repeat}: this tree {trees['this']}, other "
          f"{trees['other']}; speed-up of the medians over rounds (and of the bests)")
    print(f"{'configuration':30s} {'other Mpts/s':>12s} {'this Mpts/s':>12s} {'speed-up':>9s} {'(best)':>8s}")
    for label in runs["this"]:
        a = np.median(runs["other"].get(label, [np.nan]))
        b = np.median(runs["this"][label])
        best = min(runs["other"].get(label, [np.nan])) / min(runs["this"][label])
        print(f"{label:30s} {M / a / 1e6:12.2f} {M / b / 1e6:12.2f} {a / b:8.2f}x {best:7.2f}x")


def threshold():
    """Median and best wall-clock time of the serial and parallel 3-D curl-noise builds."""
    from inertia.fields import kernels as K
    from inertia.fields.curl import _no_boundaries
    field = ia.fields.CurlNoise(dim=3, seed=1, frequency=2.0, octaves=3)
    p = field.params
    empty = _no_boundaries(3)

    def call(kernel, pts, out):
        kernel(pts, field._offsets, field._perm, field._grads[0], field._table, *field._codes, *empty,
               field.mean_velocity, out, 0.25, p.kind_code, p.frequency, p.lacunarity, p.gain,
               p.octaves, p.time_frequency, field._scale, field.boundary_width)

    rng = np.random.default_rng(0)
    print(f"numba threads {numba.get_num_threads()}, load average {os.getloadavg()[0]:.1f}")
    for M in (512, 1024, 2048, 4096, 8192, 16384, 65536):
        pts = rng.uniform(-1, 1, (M, 3))
        out = np.empty_like(pts)
        row = {}
        for name, kernel in (("serial", K.curl_noise3.serial), ("parallel", K.curl_noise3.parallel)):
            call(kernel, pts, out)
            times = []
            for _ in range(max(5, 200_000 // M)):
                t0 = time.perf_counter()
                call(kernel, pts, out)
                times.append(time.perf_counter() - t0)
            row[name] = (np.median(times), min(times))
        print(f"{M:6d} points: serial median {row['serial'][0] * 1e3:8.3f} ms (best "
              f"{row['serial'][1] * 1e3:.3f}), parallel median {row['parallel'][0] * 1e3:8.3f} ms "
              f"(best {row['parallel'][1] * 1e3:.3f}), load average {os.getloadavg()[0]:.1f}")


def profile(M, repeat):
    """Where a 3-D Perlin curl-noise sample spends its time (see the module docstring)."""
    from numba import njit
    from inertia.fields import kernels as K
    B = K._BLOCK

    @njit
    def potential_only(points, t, offsets, perm, table, simplex_codes, perlin_codes, frequency,
                       lacunarity, gain, octaves, time_frequency, scale, work, ints):
        for s0 in range(0, points.shape[0], B):
            K.potential3_block(points, s0, min(B, points.shape[0] - s0), t, offsets, perm, table,
                               simplex_codes, perlin_codes, frequency, lacunarity, gain, octaves,
                               time_frequency, scale, work, ints)

    @njit
    def passes_only(M, octaves, timed, work, hashes):
        for s0 in range(0, M, B):
            for _ in range(octaves):
                if timed:
                    K._perlin_pass(work, hashes, 0, min(B, M - s0), 0.3, 0.2, 0.4, True)
                    K._perlin_pass(work, hashes, 8, min(B, M - s0), 0.3, 0.2, -0.6, True)
                else:
                    K._perlin_pass(work, hashes, 0, min(B, M - s0), 0.3, 0.2, 0.0, False)

    numba.set_num_threads(1)
    clock = time.process_time
    pts = np.random.default_rng(0).uniform(-1.0, 1.0, (M, 3)) * 0.999
    out = np.empty_like(pts)
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3)
    rng = np.random.default_rng(1)
    print(f"3-D Perlin curl-noise, {M:,} points, 3 octaves, 1 thread, CPU ms (best of {repeat}), "
          f"load average {os.getloadavg()[0]:.1f}")
    for tf in (0.0, 0.5):
        free = ia.fields.CurlNoise(dim=3, seed=1, kind="perlin", frequency=2.0, octaves=3,
                                   time_frequency=tf)
        ball = ia.fields.CurlNoise(dim=3, seed=1, kind="perlin", frequency=2.0, octaves=3,
                                   time_frequency=tf, boundaries=[sphere])
        p = free.params
        work = rng.uniform(0.0, 1.0, 25 * B)
        ints = np.zeros(16 * B, np.int64)
        hashes = free._codes[1][rng.integers(0, 512, 16 * B)].copy()
        t_free = best_of(lambda f=free: f.sample(pts, 0.25, out), repeat, clock)
        t_ball = best_of(lambda f=ball: f.sample(pts, 0.25, out), repeat, clock)
        t_prep = best_of(lambda f=ball: f.boundaries.prepare(pts, 0.25), repeat, clock)
        t_pot = best_of(lambda: potential_only(
            pts, 0.25, free._offsets[0], free._perm, free._table, *free._codes, p.frequency,
            p.lacunarity, p.gain, p.octaves, p.time_frequency, free._scale, work, ints),
            repeat, clock)
        t_pass = best_of(lambda: passes_only(M, p.octaves, tf != 0.0, work, hashes), repeat, clock)
        label = "4-D (t)" if tf else "3-D"
        ms = 1e3
        print(f"perlin {label} free   {t_free * ms:7.1f}: potential {t_pot * ms:6.1f} (corner passes "
              f"{t_pass * ms:6.1f}, lattice walk + fades {(t_pot - t_pass) * ms:6.1f}), curl + "
              f"writes {(t_free - t_pot) * ms:6.1f}")
        print(f"perlin {label} sphere {t_ball * ms:7.1f}: wall lists (prepare) {t_prep * ms:6.1f}, "
              f"bounded kernel beyond the free one {(t_ball - t_free - t_prep) * ms:6.1f}")


def cold_child():
    """Build and sample a 3-D curl-noise scene once; print the CPU seconds it took."""
    t0 = time.process_time()
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3)
    field = ia.fields.CurlNoise(dim=3, seed=1, octaves=3, time_frequency=0.5, boundaries=[sphere])
    pts = np.random.default_rng(0).uniform(-1.0, 1.0, (200, 3))
    field.sample(pts, 0.1, np.empty_like(pts))
    print(time.process_time() - t0)


def cold_compile(others):
    """CPU seconds of `cold_child` from an empty Numba cache, for this tree and each other."""
    import tempfile
    here = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src"))
    for src in [here, *[os.path.abspath(o) for o in others]]:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, PYTHONPATH=src, NUMBA_CACHE_DIR=cache)
            run = subprocess.run([sys.executable, os.path.abspath(__file__), "--cold-child"],
                                 env=env, capture_output=True, text=True, check=True)
        seconds = float(run.stdout.strip().splitlines()[-1])
        print(f"cold compile, 3-D curl-noise scene with a sphere: {seconds:5.1f} s CPU  ({src}; "
              f"load average {os.getloadavg()[0]:.1f})", flush=True)


def leak_check(dt: float, count: int = 3000, duration: float = 10.0) -> None:
    """Issue 8: tracers must never leave a 3-D container."""
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    field = ia.fields.CurlNoise(dim=3, seed=7, boundaries=[room])
    x0 = np.random.default_rng(1).uniform(-0.999, 0.999, (count, 3))
    tracers = ia.Tracers(x0, field)
    sim = ia.Simulation(tracers, integrator="rk4", dt=dt)
    left = np.zeros(count, dtype=bool)
    least = np.inf
    t0 = time.perf_counter()
    for _ in range(int(round(duration / dt))):
        sim.step()
        d = room.signed_distance(tracers.x)
        left |= d < 0.0
        least = min(least, float(d.min()))
    print(f"container leak check: {int(left.sum())} of {count} tracers left over {duration:g} s "
          f"(RK4, dt = {dt:g}); least signed distance {least:.3g}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
