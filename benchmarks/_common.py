"""Shared helpers for the benchmarks: timing and the machine's copy bandwidth, measured in-run."""

from __future__ import annotations

import time

import numpy as np
from numba import njit, prange


def best_time(fn, repeat=7, warmup=2):
    """Median wall time of `fn()` in seconds over `repeat` runs after `warmup` runs."""
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return float(np.median(samples))


@njit(cache=True, parallel=True)
def _parallel_copy(src, dst):
    for i in prange(src.shape[0]):
        dst[i] = src[i]


def copy_bandwidth(nbytes=256 * 2**20):
    """Bytes per second of the best of NumPy's copy and a parallel Numba copy (read + write counted)."""
    src = np.random.default_rng(0).random(nbytes // 8)
    dst = np.empty_like(src)
    t_numpy = best_time(lambda: np.copyto(dst, src), repeat=5)
    t_numba = best_time(lambda: _parallel_copy(src, dst), repeat=5)
    return 2 * src.nbytes / min(t_numpy, t_numba)


def rain_particles(n, seed=0):
    """The collision benchmarks' scene: n point particles (radius 0) in a 4 x 4 x 2 m box above the
    ground, unit-normal random velocities, gravity."""
    import inertia as ia
    rng = np.random.default_rng(seed)
    x = rng.uniform([-2.0, -2.0, 0.0], [2.0, 2.0, 2.0], size=(n, 3))
    v = rng.normal(0.0, 1.0, size=(n, 3))
    ps = ia.ParticleSystem(x, v, radius=0.0)
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    return ps
