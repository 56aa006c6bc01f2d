"""SPH smoothing kernels: cubic spline and Wendland C2, normalised in 2D and 3D.

Both kernels have compact support ``H = 2 h`` (``h`` the smoothing length) and are written in
terms of the distance ``r``; each returns ``W(r)`` and ``dW/dr``, from which the gradient is
``grad W(x_ij) = dW/dr * x_ij / r`` (antisymmetric in i, j by construction).

- Cubic spline (Monaghan, J. J. (1992), "Smoothed particle hydrodynamics", Annu. Rev. Astron.
  Astrophys. 30): with ``q = r / h``, ``W = sigma_D [1 - 1.5 q^2 + 0.75 q^3]`` for ``q < 1``,
  ``sigma_D 0.25 (2 - q)^3`` for ``1 <= q < 2``, 0 beyond; ``sigma_2 = 10 / (7 pi h^2)``,
  ``sigma_3 = 1 / (pi h^3)``.
- Wendland C2 (Wendland, H. (1995), "Piecewise polynomial, positive definite and compactly
  supported radial functions of minimal degree", Adv. Comput. Math. 4; normalisation as in
  Dehnen, W. & Aly, H. (2012), "Improving convergence in smoothed particle hydrodynamics
  simulations without pairing instability", MNRAS 425): with ``s = r / H``,
  ``W = sigma_D (1 - s)^4 (1 + 4 s)``, ``sigma_2 = 7 / (pi H^2)``, ``sigma_3 = 21 / (2 pi H^3)``.

Limitations
-----------
- Radial kernels only (no anisotropic kernels, no kernel gradient correction).
- The support radius is ``2 h`` for both kernels; the valid smoothing length is checked by the
  solver against the particle spacing (see ``SMOOTHING_RANGE``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["KERNELS", "CUBIC_SPLINE", "WENDLAND_C2", "kernel_id", "kernel_value", "kernel_gradient"]

CUBIC_SPLINE = 0
WENDLAND_C2 = 1
KERNELS = {"cubic_spline": CUBIC_SPLINE, "wendland_c2": WENDLAND_C2}

# smoothing length / particle spacing accepted by the solver (per kernel): below the lower bound
# a particle has too few neighbours for a consistent density, above the upper one the cost grows
# as (h/dx)^D without a gain in accuracy for these kernels.
SMOOTHING_RANGE = {"cubic_spline": (0.9, 2.0), "wendland_c2": (1.0, 2.5)}


def kernel_id(name: str) -> int:
    """The integer code of a kernel name (``"cubic_spline"`` or ``"wendland_c2"``)."""
    if name not in KERNELS:
        raise ValueError(f"kernel must be one of {sorted(KERNELS)}; got {name!r}")
    return KERNELS[name]


@njit(cache=True, inline="always")
def kernel_norm(kernel, dim, h):
    """sigma_D of the kernel (see module docstring) for smoothing length h."""
    if kernel == CUBIC_SPLINE:
        if dim == 2:
            return 10.0 / (7.0 * math.pi * h * h)
        return 1.0 / (math.pi * h * h * h)
    support = 2.0 * h
    if dim == 2:
        return 7.0 / (math.pi * support * support)
    return 21.0 / (2.0 * math.pi * support * support * support)


@njit(cache=True, inline="always")
def w_and_dwdr(kernel, r, h, sigma):
    """(W(r), dW/dr) for distance r >= 0, smoothing length h and norm sigma = kernel_norm(...)."""
    if kernel == CUBIC_SPLINE:
        q = r / h
        if q < 1.0:
            return sigma * (1.0 - 1.5 * q * q + 0.75 * q * q * q), sigma / h * (-3.0 * q + 2.25 * q * q)
        if q < 2.0:
            t = 2.0 - q
            return sigma * 0.25 * t * t * t, -sigma / h * 0.75 * t * t
        return 0.0, 0.0
    support = 2.0 * h
    s = r / support
    if s < 1.0:
        t = 1.0 - s
        t3 = t * t * t
        return sigma * t3 * t * (1.0 + 4.0 * s), -sigma / support * 20.0 * s * t3
    return 0.0, 0.0


@njit(cache=True)
def _evaluate(kernel, rel, h, w_out, grad_out):
    n, dim = rel.shape
    sigma = kernel_norm(kernel, dim, h)
    for i in range(n):
        r2 = 0.0
        for d in range(dim):
            r2 += rel[i, d] * rel[i, d]
        r = math.sqrt(r2)
        w, dw = w_and_dwdr(kernel, r, h, sigma)
        w_out[i] = w
        for d in range(dim):
            grad_out[i, d] = dw * rel[i, d] / r if r > 0.0 else 0.0


def kernel_value(name: str, rel, h: float) -> np.ndarray:
    """W(x) (M,) for displacement vectors rel (M, D) [m] and smoothing length h [m] (1/m^D)."""
    rel = np.ascontiguousarray(rel, dtype=np.float64)
    w = np.empty(rel.shape[0])
    g = np.empty_like(rel)
    _evaluate(kernel_id(name), rel, float(h), w, g)
    return w


def kernel_gradient(name: str, rel, h: float) -> np.ndarray:
    """grad W(x) (M, D) for displacement vectors rel (M, D) [m] (1/m^(D+1))."""
    rel = np.ascontiguousarray(rel, dtype=np.float64)
    w = np.empty(rel.shape[0])
    g = np.empty_like(rel)
    _evaluate(kernel_id(name), rel, float(h), w, g)
    return g
