"""Sweep throughput: N short variants on the embedded dask LocalCluster against the same N run one after
another in this process (the baseline, measured in the same run).

Scene: one ball (radius 0.05 m) dropped from 1 m onto a plane, velocity Verlet, dt = 1 ms, 0.5 s simulated
(500 steps, 51 frames), restitution drawn from a Latin hypercube over [0.1, 0.9]; metrics time_to_rest,
max_penetration, final_energy. This is the "many tiny variants" case, where the per-variant overhead
(scene validation and build, the run loop's state file and checkpoint, task scheduling) matters most.

Prints, for N variants (200 default):
- serial (with the workers' Numba thread count per variant): seconds, variants per second, mean wall time of one variant, of which pure stepping
  (`World.step` in a loop without the run loop) -> the run-loop overhead per variant;
- cluster: start-up seconds (scheduler + workers + warm-up), sweep seconds on the warm cluster, the
  ratio serial / cluster (the speed-up), the overhead per variant (cluster seconds x workers / N minus
  the mean variant wall time: scheduling and transfer cost per variant and worker slot);
- memory: resident set size of each worker after the sweep, and of this process;
- equality: the cluster's table equals the serial one bit for bit (max difference, must be 0);
- the load average, since the machine may be shared.

    python benchmarks/bench_sweep.py [--variants 200] [--duration 0.5] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

BALL = """
format_version = 1
name = "sweep_ball"
[simulation]
dt = 0.001
duration = {duration}
fps = 100
integrator = "velocity_verlet"
[[forces]]
type = "gravity"
[[colliders]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[particles]]
positions = [[0.0, 0.0, 1.05]]
radius = 0.05
restitution = 0.5
"""

METRICS = ["time_to_rest", "max_penetration", "final_energy"]


def rss_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--variants", type=int, default=200)
    parser.add_argument("--duration", type=float, default=0.5)
    parser.add_argument("--workers", type=int, default=None, help="default: one per usable core")
    args = parser.parse_args()

    import logging

    from distributed import Client, LocalCluster

    from inertia.scene import build, read_scene
    from inertia.sweep import sweep

    n = args.variants
    folder = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    scene = folder / "ball.toml"
    scene.write_text(BALL.format(duration=args.duration))
    params = {"particles[0].restitution": "0.1:0.9"}
    cores = len(os.sched_getaffinity(0))
    workers = args.workers or cores
    print(f"bench_sweep: {n} variants of a {args.duration:g} s bouncing ball ({round(args.duration / 0.001)} steps), "
          f"{cores} cores, {workers} workers; load average before: {os.getloadavg()[0]:.2f}")

    # the baseline gets the workers' Numba threads per variant (1 on 2 cores with 2 workers), so the ratio
    # measures running variants side by side, not thread counts inside a variant
    import numba

    numba.set_num_threads(max(1, min(numba.config.NUMBA_NUM_THREADS, cores // workers)))
    # pure stepping of one variant (no run loop): the floor of a variant's cost
    world = build(read_scene(scene))
    steps = int(round(args.duration / world.dt))
    world.run(args.duration)          # compile / load the kernels
    world = build(read_scene(scene))
    t0 = time.perf_counter()
    for _ in range(steps):
        world.step()
    stepping = time.perf_counter() - t0

    # baseline: one after another in this process (warm: a first variant compiled everything)
    sweep(scene, params, METRICS, samples=2, seed=1, client="serial")
    t0 = time.perf_counter()
    serial = sweep(scene, params, METRICS, samples=n, seed=0, client="serial")
    t_serial = time.perf_counter() - t0
    mean_variant = float(serial["wall_time"].mean())

    # the cluster: start, warm up (each worker loads the cached kernels), then the timed sweep
    t0 = time.perf_counter()
    src = str(Path(__file__).resolve().parents[1] / "src")
    env = {"NUMBA_NUM_THREADS": str(max(1, cores // workers)),
           "PYTHONPATH": os.pathsep.join(filter(None, [src, os.environ.get("PYTHONPATH")]))}
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                           silence_logs=logging.ERROR, env=env)
    client = Client(cluster)
    sweep(scene, params, METRICS, samples=2 * workers, seed=1, client=client)
    t_start = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = sweep(scene, params, METRICS, samples=n, seed=0, client=client)
    t_cluster = time.perf_counter() - t0
    worker_rss = client.run(rss_mb)
    client.close()
    cluster.close()

    same = all(np.array_equal(table[m].to_numpy(), serial[m].to_numpy(), equal_nan=True) for m in METRICS)
    diff = max(float(np.nanmax(np.abs(table[m].to_numpy() - serial[m].to_numpy()), initial=0.0)) for m in METRICS)
    overhead = t_cluster * workers / n - float(table["wall_time"].mean())
    print(f"serial : {t_serial:7.2f} s  {n / t_serial:7.1f} variants/s  mean variant {mean_variant * 1e3:6.1f} ms "
          f"(pure stepping {stepping * 1e3:5.1f} ms -> run loop + build overhead {1e3 * (mean_variant - stepping):5.1f} ms)")
    print(f"cluster: {t_cluster:7.2f} s  {n / t_cluster:7.1f} variants/s  mean variant "
          f"{table['wall_time'].mean() * 1e3:6.1f} ms on a worker; start-up + warm-up {t_start:.1f} s")
    print(f"ratio serial/cluster = {t_serial / t_cluster:.2f}x with {workers} workers "
          f"(ideal {workers}x); scheduling overhead per variant {overhead * 1e3:.1f} ms per worker slot")
    print(f"ratio including start-up = {t_serial / (t_cluster + t_start):.2f}x")
    cpu_serial, cpu_worker = float(serial["cpu_time"].mean()), float(table["cpu_time"].mean())
    print(f"cpu    : {cpu_serial * 1e3:6.1f} ms per variant in this process, {cpu_worker * 1e3:6.1f} ms on a worker "
          f"-> on an idle machine the cluster would reach about {workers * cpu_serial / cpu_worker:.2f}x "
          f"(workers x serial cpu / worker cpu; a load-independent estimate)")
    print("memory : workers " + ", ".join(f"{v:.0f} MB" for v in worker_rss.values())
          + f"; this process {rss_mb():.0f} MB")
    print(f"results equal bit for bit: {same} (max difference {diff:g}); "
          f"completed {int((table['status'] == 'completed').sum())}/{n}; load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
