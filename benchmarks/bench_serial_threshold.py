"""Benchmark: where a parallel kernel starts to beat its serial twin (``inertia._jit.SERIAL_BELOW``).

    python benchmarks/bench_serial_threshold.py [--repeat 200]

For particle counts N from 500 to 10^6, times three kernels in their parallel build and their
serial twin (same code, ``prange`` run as ``range``): the fused semi-implicit Euler step
``affine_kick_drift`` (N, 3), the RK stage ``rk_stage`` over the flat state (6 N values, 4
stages) and the gravity + drag accumulation ``gravity_force`` (N, 3). Prints the median time
per call and the ratio serial / parallel (> 1: parallel pays), and the smallest N from which
parallel stays ahead. Run it on the machine you ship for, idle and with a second busy process
(``python -c "while 1: pass" &``): on 2 shared cores the crossover moves up by orders of
magnitude, since waking a busy core's thread costs up to a millisecond.
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np

from inertia.ode import kernels as ode_kernels
from inertia.particles import kernels as particle_kernels


def median_time(fn, repeat):
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=200)
    parser.add_argument("--sizes", type=str, default="500,2000,8000,32000,128000,512000,1000000")
    args = parser.parse_args(argv)
    print(f"serial-twin threshold: numba threads {numba.get_num_threads()}, cpus {os.cpu_count()}, "
          f"load average {os.getloadavg()[0]:.1f}")
    kick = particle_kernels.affine_kick_drift
    stage = ode_kernels.rk_stage
    crossover = {}
    for n in [int(s) for s in args.sizes.split(",")]:
        rng = np.random.default_rng(0)
        x, v = rng.random((n, 3)), rng.random((n, 3))
        inv_mass = np.ones(n)
        g, F = np.array([0.0, 0.0, -9.81]), np.zeros(3)
        y = rng.random(6 * n)
        stages = rng.random((4, 6 * n))
        coef = np.array([0.5, 0.0, 0.0, 0.0])
        out = np.empty_like(y)
        repeat = max(5, min(args.repeat, int(2e7 / n)))
        cases = {
            "affine_kick_drift (N,3)": (lambda k: k(x, v, inv_mass, g, F, 0.1, 1e-3), kick),
            "rk_stage (6N,)": (lambda k: k(y, stages, coef, 1, 1e-3, out), stage),
        }
        for name, (call, dispatched) in cases.items():
            tp = median_time(lambda: call(dispatched.parallel), repeat)
            ts = median_time(lambda: call(dispatched.serial), repeat)
            ratio = ts / tp
            print(f"N {n:>8,}  {name:24s} serial {ts * 1e6:9.1f} us  parallel {tp * 1e6:9.1f} us  "
                  f"serial/parallel {ratio:5.2f}")
            if ratio > 1.0:
                crossover.setdefault(name, n)
            else:
                crossover.pop(name, None)
    for name in cases:
        print(f"{name}: parallel ahead from N = {crossover.get(name, 'never (in range)')}")


if __name__ == "__main__":
    main()
