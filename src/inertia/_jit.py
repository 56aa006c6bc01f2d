"""Numba helpers shared by every layer: serial twins of parallel kernels, size dispatch.

Starting a parallel region costs microseconds on an idle machine and up to tens of
milliseconds when the other core is busy (the region waits for a thread that the operating
system has not scheduled). ``serial_twin(kernel)`` compiles the kernel's Python source again
without ``parallel`` (``prange`` then runs as ``range``), cached under its own name. Both
versions compute identical bits: the kernels write each output element from one iteration,
and reductions use fixed chunks.

``parallel_kernel`` / ``SizeDispatched`` is the one size-dispatch mechanism: the serial twin
runs when the first argument holds fewer than ``SERIAL_BELOW`` elements (``args[0].size``, or
another count through ``.pick(n)``, e.g. the pair solver's number of pairs), the parallel
build from there on. ``SERIAL_BELOW`` is read at every call, so setting it (0: always
parallel) applies to every dispatched kernel, the particle collision kernels included. Each build is compiled on its first call only, so a small
scene never compiles the parallel build (which costs several times the serial build's
compile time) and a large one never compiles the serial twin.

How ``SERIAL_BELOW`` was chosen (``benchmarks/bench_serial_threshold.py``, 2-core machine):
with the other core idle, the memory-bound particle kernels run faster on two threads from
about 10^4 elements; with the other core busy, the parallel build's median call was 30-40 ms
at every size from 2,000 to 10^6 elements, against 8 us to 23 ms serially, so it paid only
for the largest flat updates. 2^17 elements (about 22,000 particles in 3-D for an (N, 3)
array, 11,000 for a flat [x, v] state) keeps every bundled example and the fountain serial
(the issue measured 2.2 s at one thread against 6.4 s at two under load) and leaves the 10^5
and 10^6 particle benchmarks parallel. Compute-bound kernels (noise, curl-noise, rendering)
do ~100 times more work per element and pass a lower ``serial_below``.
"""

from __future__ import annotations

import os
import types

from numba import njit

# Elements (args[0].size) below which a SizeDispatched kernel runs its serial twin. The
# environment variable INERTIA_SERIAL_BELOW overrides it at import (0: always parallel).
SERIAL_BELOW = int(os.environ.get("INERTIA_SERIAL_BELOW", 1 << 17))


def serial_twin(kernel):
    """The same kernel compiled without ``parallel=True``."""
    py = kernel.py_func
    clone = types.FunctionType(py.__code__, py.__globals__, py.__name__ + "_serial", py.__defaults__,
                               py.__closure__)
    clone.__qualname__ = py.__qualname__ + "_serial"
    clone.__module__ = py.__module__
    clone.__doc__ = f"Serial twin of `{py.__name__}` (same code; prange runs as range)."
    options = {k: v for k, v in kernel.targetoptions.items() if k not in ("parallel", "nopython")}
    # Cached on disk when the parallel build is (every library kernel).
    options["cache"] = type(getattr(kernel, "_cache", None)).__name__ != "NullCache"
    return njit(**options)(clone)


class SizeDispatched:
    """Calls the parallel kernel, or its serial twin when the first argument has fewer than
    ``serial_below`` elements (``SERIAL_BELOW`` default). Each is compiled on first use.
    Use from Python only; inside other kernels call ``.parallel`` or ``.serial``.

    The threshold is read at each call, so setting ``inertia._jit.SERIAL_BELOW`` (0: always
    parallel, as the thread-count tests do) applies to every dispatched kernel. ``serial`` may
    hand in an existing serial twin (kernels other code calls by their ``_serial`` name)."""

    def __init__(self, kernel, serial_below: int | None = None, serial=None):
        self.parallel = kernel
        self._own_below = None if serial_below is None else int(serial_below)
        self._serial = serial
        self.__doc__ = kernel.py_func.__doc__
        self.__name__ = kernel.py_func.__name__
        self.py_func = kernel.py_func

    @property
    def serial_below(self) -> int:
        """Elements below which the serial twin runs: the kernel's own threshold, never above
        the global ``SERIAL_BELOW``."""
        below = SERIAL_BELOW
        return below if self._own_below is None else min(self._own_below, below)

    @property
    def serial(self):
        if self._serial is None:
            self._serial = serial_twin(self.parallel)
        return self._serial

    def pick(self, n: int):
        """The build that runs for a first argument of n elements."""
        return self.serial if n < self.serial_below else self.parallel

    def __call__(self, *args):
        if args[0].size < self.serial_below:
            return self.serial(*args)
        return self.parallel(*args)


def parallel_kernel(fn=None, *, serial_below: int | None = None, **options):
    """Decorator: ``@njit(cache=True, parallel=True, **options)`` plus a serial twin for inputs
    below ``serial_below`` elements (``SERIAL_BELOW`` default). ``@parallel_kernel`` or
    ``@parallel_kernel(serial_below=4096, fastmath=...)``."""
    def wrap(f):
        return SizeDispatched(njit(cache=True, parallel=True, **options)(f), serial_below)
    return wrap if fn is None else wrap(fn)
