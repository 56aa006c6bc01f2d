import os
import subprocess
import sys
import tracemalloc
from types import SimpleNamespace

from pathlib import Path

import numpy as np
import pytest

# Tests must not depend on a display.
os.environ.setdefault("MPLBACKEND", "Agg")

# The suite runs in one worker process per core (pytest-xdist, the README's test command), and each
# worker's parallel kernels start their own OpenMP threads: waiting threads sleep instead of spinning,
# so two workers on two cores do not take turns burning each other's time. Read when Numba first
# loads its OpenMP pool, which happens after this file.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


# ----------------------------------------------------------------------------- allocation counters
# "No allocation per step" (the project standard) is checked with two counters, shared by the
# allocation tests of each layer (tests/fluids/grid/test_step_allocations.py explains both).

def _arrays_in(x):
    if isinstance(x, np.ndarray):
        return 1
    if isinstance(x, tuple):
        return sum(_arrays_in(y) for y in x)
    return 0


def kernel_allocations(step, n):
    """{kernel name: NRT allocations made inside it} over n calls of step (explained in
    tests/fluids/grid/test_step_allocations.py)."""
    from numba import _dispatcher
    from numba.core.registry import CPUDispatcher
    from numba.core.runtime import _nrt_python, rtsys
    base = _dispatcher.Dispatcher.__call__
    inside = {}
    calls = [0]

    def counting_call(self, *args, **kwargs):
        wrapped = _arrays_in(args) + _arrays_in(tuple(kwargs.values()))
        a0 = rtsys.get_allocation_stats().alloc
        out = base(self, *args, **kwargs)
        extra = rtsys.get_allocation_stats().alloc - a0 - wrapped
        calls[0] += 1
        if extra:
            name = f"{self.py_func.__module__}.{self.py_func.__qualname__}"
            inside[name] = inside.get(name, 0) + extra
        return out

    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    CPUDispatcher.__call__ = counting_call
    try:
        for _ in range(n):
            step()
    finally:
        del CPUDispatcher.__call__
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert calls[0] > 50                     # the wrapper saw the kernels (the counter works)
    return inside


def peak_bytes(step, n, bound, windows=12):
    """tracemalloc's peak above the start over n calls of step, bytes: the first window of n calls
    whose peak is below ``bound``, else the least of ``windows`` windows. An allocation the step makes
    every time shows in every window, so the least window still holds it; a one-off (a lazily filled
    cache the first time a path runs) shows in one only. tracemalloc counts every thread's
    allocations: run such a test ``isolated`` (below), in a process with no other test's threads."""
    peaks = []
    for _ in range(windows):
        tracemalloc.start()
        try:
            c0 = tracemalloc.get_traced_memory()[0]
            for _ in range(n):
                step()
            peaks.append(tracemalloc.get_traced_memory()[1] - c0)
        finally:
            tracemalloc.stop()
        if peaks[-1] < bound:
            break
    return min(peaks)


@pytest.fixture
def alloc():
    """The allocation counters: ``alloc.kernel_allocations(step, n)``, ``alloc.peak_bytes(step, n, bound)``."""
    return SimpleNamespace(kernel_allocations=kernel_allocations, peak_bytes=peak_bytes)


# ----------------------------------------------------------------------------- isolated tests
# A test marked ``isolated`` runs in a fresh Python process of its own (pytest on its node id alone):
# for measurements that any other thread in the process would disturb. tracemalloc counts every
# thread's allocations, and a process that ran the dask cluster of tests/sweep keeps its event-loop
# thread, whose periodic callbacks allocate 50-300 KB during any window of a few steps (measured).
_ISOLATED = "INERTIA_TEST_ISOLATED"


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    if pyfuncitem.get_closest_marker("isolated") is None or os.environ.get(_ISOLATED):
        return None
    env = dict(os.environ, **{_ISOLATED: "1"})
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", pyfuncitem.nodeid]
    run = subprocess.run(cmd, cwd=pyfuncitem.config.rootpath, env=env, capture_output=True, text=True,
                         timeout=1200)
    if run.returncode != 0:
        pytest.fail(f"{pyfuncitem.nodeid} in its own process:\n{run.stdout[-6000:]}\n{run.stderr[-3000:]}",
                    pytrace=False)
    return True


# ----------------------------------------------------------------------------- thread counts
@pytest.fixture
def thread_counts():
    """``for threads in thread_counts():`` runs the loop body at 1 and at 2 Numba threads (as many as the
    machine gives), set with ``numba.set_num_threads``; the count is restored afterwards."""
    import numba
    before = numba.get_num_threads()

    def counts():
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            yield threads
        numba.set_num_threads(before)

    yield counts
    numba.set_num_threads(before)


# ----------------------------------------------------------------------------- resume twins
def _resumed_twin(make, step, before, after):
    """Checkpoint and resume, the way every saveable system is tested: ``a = make()`` steps ``before``
    times, saves its state, and steps ``after`` more; ``b = make()`` restores that state and steps the same
    ``after`` times. Returns (a, b), which must agree bit for bit (``step(system)`` takes one step)."""
    a = make()
    for _ in range(before):
        step(a)
    state = a.save_state()
    for _ in range(after):
        step(a)
    b = make()
    b.restore_state(state)
    for _ in range(after):
        step(b)
    return a, b


@pytest.fixture
def resumed_twin():
    """``a, b = resumed_twin(make, step, before, after)``: see `_resumed_twin`."""
    return _resumed_twin


# ----------------------------------------------------------------------------- the fast set
# ``pytest -m "not slow"`` leaves out the tests listed in tests/slow.txt (the ones that took more than a
# few seconds on the 2-core reference machine, measured; tests/slow_list.py regenerates the list) as well
# as those marked ``@pytest.mark.slow`` in their files.
_SLOW_TESTS = frozenset(line for line in Path(__file__).with_name("slow.txt").read_text().splitlines()
                        if line and not line.startswith("#"))


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.nodeid in _SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
