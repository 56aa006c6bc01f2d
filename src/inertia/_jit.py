"""Numba helpers shared by every layer: serial twins of parallel kernels, size dispatch.

Launching a parallel region costs microseconds on an idle machine and up to a millisecond on a
loaded one; below a few thousand items the serial version of the same kernel is faster.
``serial_twin(kernel)`` compiles the kernel's Python source again without ``parallel`` (``prange``
then runs as ``range``), cached under its own name. Both versions compute identical bits: the
kernels write each output element from one iteration, and reductions use fixed chunks.
"""

from __future__ import annotations

import types

from numba import njit

SERIAL_BELOW = 2048


def serial_twin(kernel):
    """The same kernel compiled without ``parallel=True``."""
    py = kernel.py_func
    clone = types.FunctionType(py.__code__, py.__globals__, py.__name__ + "_serial", py.__defaults__,
                               py.__closure__)
    clone.__qualname__ = py.__qualname__ + "_serial"
    clone.__module__ = py.__module__
    clone.__doc__ = f"Serial twin of `{py.__name__}` (same code; prange runs as range)."
    return njit(cache=True)(clone)


def pick(kernel, twin, n: int):
    """The kernel to run for n items: the serial twin below ``SERIAL_BELOW``."""
    return twin if n < SERIAL_BELOW else kernel


class SizeDispatched:
    """Calls the parallel kernel, or its serial twin when the first argument has fewer than
    ``SERIAL_BELOW`` rows. Use from Python only; inside other kernels call ``.parallel``."""

    def __init__(self, kernel):
        self.parallel = kernel
        self._serial = None
        self.__doc__ = kernel.py_func.__doc__
        self.__name__ = kernel.py_func.__name__

    @property
    def serial(self):
        if self._serial is None:
            self._serial = serial_twin(self.parallel)
        return self._serial

    def __call__(self, *args):
        if args[0].shape[0] < SERIAL_BELOW:
            return self.serial(*args)
        return self.parallel(*args)


def parallel_kernel(fn):
    """Decorator: ``@njit(cache=True, parallel=True)`` plus a serial twin for small inputs."""
    return SizeDispatched(njit(cache=True, parallel=True)(fn))
