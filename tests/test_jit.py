"""The shared size dispatch (src/inertia/_jit.py): serial twins give the parallel builds' bits,
the dispatch follows SERIAL_BELOW, and each build compiles only when it first runs."""

import numba
import numpy as np
from numba import njit, prange

from inertia import _jit
from inertia.ode import kernels as ode_kernels
from inertia.particles import kernels as particle_kernels


def test_serial_twin_and_parallel_build_give_identical_bits():
    # Above the threshold, on every thread: the fused semi-implicit step, an RK stage and the
    # chunked finite check must not depend on which build or how many threads ran them.
    rng = np.random.default_rng(0)
    n = 50_000
    x, v = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    inv_mass = rng.uniform(0.5, 2.0, n)
    inv_mass[::7] = 0.0
    g, force = np.array([0.0, 0.0, -9.81]), np.array([0.1, 0.0, 0.0])
    results = []
    for build in ("parallel", "serial"):
        kick = getattr(particle_kernels.affine_kick_drift, build)
        xs, vs = x.copy(), v.copy()
        for _ in range(3):
            kick(xs, vs, inv_mass, g, force, 0.3, 1e-3)
        y = np.concatenate([xs.ravel(), vs.ravel()])
        stages = rng.normal(size=(4, y.size)) if not results else results[0][2]
        out = np.empty_like(y)
        getattr(ode_kernels.rk_stage, build)(y, stages, np.array([0.5, 0.25, 0.0, 0.0]), 2, 1e-3, out)
        results.append((xs, vs, stages, out))
    for a, b in zip(results[0], results[1]):
        np.testing.assert_array_equal(a, b)


def test_dispatch_by_element_count():
    kernel = particle_kernels.affine_kick_drift
    assert kernel.serial_below == _jit.SERIAL_BELOW
    assert kernel.pick(_jit.SERIAL_BELOW - 1) is kernel.serial
    assert kernel.pick(_jit.SERIAL_BELOW) is kernel.parallel
    # The fountain (2,600 particles, (N, 3) arrays) and every bundled example run serially.
    assert 2600 * 3 < _jit.SERIAL_BELOW
    # A per-kernel threshold can only be lower than the global one (INERTIA_SERIAL_BELOW=0
    # forces every kernel parallel, for tests of the parallel builds).
    assert _jit.SizeDispatched(kernel.parallel, serial_below=10**12).serial_below == _jit.SERIAL_BELOW


def _double_into(x, out):
    for i in prange(x.shape[0]):
        out[i] = 2.0 * x[i]


def test_builds_compile_on_first_use_only():
    # A fresh kernel (not cached: defined with cache=False) compiles its serial twin for a small
    # call and its parallel build only when a big one comes.
    dispatched = _jit.SizeDispatched(njit(parallel=True)(_double_into), serial_below=100)
    x = np.arange(10.0)
    out = np.empty_like(x)
    dispatched(x, out)
    np.testing.assert_array_equal(out, 2.0 * x)
    assert dispatched._serial is not None and len(dispatched.serial.signatures) == 1
    assert len(dispatched.parallel.signatures) == 0
    big = np.arange(1000.0)
    out_big = np.empty_like(big)
    dispatched(big, out_big)
    assert len(dispatched.parallel.signatures) == 1
    np.testing.assert_array_equal(out_big, 2.0 * big)
    assert numba.get_num_threads() >= 1
