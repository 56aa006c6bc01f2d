"""The vector-field protocol, and sums and scalings of fields.

Every vector field is a callable ``field(points, t=0.0) -> (M, D)`` over (M, D) float64 points
(D = ``field.dim``, 2 or 3) at time ``t`` (seconds), and fills a preallocated array with
``field.sample(points, t, out)``; ``inertia.Tracers`` and ``inertia.forces.Wind`` use ``sample``
so that a time step allocates nothing. Fields with analytic derivatives also give
``field.jacobian(points, t)`` -> (M, D, D) with ``J[i, a, b] = d v_a / d x_b`` at point i, and
``field.divergence(points, t)`` -> (M,), its trace.

Fields combine with ``+``, ``-`` and scalar ``*`` / ``/``: ``2.0 * a + b`` is a field whose
value is 2 a(x, t) + b(x, t); the sum of divergence-free fields is divergence-free.

Limitations
-----------
- Arithmetic is between fields of the same dimension, and with real scalars only (no
  spatially varying weights).
- ``sample`` checks only shapes; it trusts ``points`` to be finite, C-contiguous float64
  (``__call__`` converts and checks everything).
"""

from __future__ import annotations

import numbers

import numpy as np

from .._validate import as_points

__all__ = ["Field", "Scaled", "Sum"]


class Field:
    """Base class of vector fields (see the module docstring for the protocol).

    Subclasses set ``dim`` and implement ``sample(points, t, out)``; those with analytic
    derivatives implement ``sample_jacobian(points, t, out)``.
    """

    dim: int = 3
    # NumPy arrays do not broadcast over fields: `array * field` raises TypeError.
    __array_ufunc__ = None

    # -- evaluation -------------------------------------------------------------------------
    def __call__(self, points, t: float = 0.0) -> np.ndarray:
        """Velocity at each point: (M, D) float64, a new array."""
        pts = self._points(points)
        out = np.empty_like(pts)
        self.sample(pts, float(t), out)
        return out

    def sample(self, points: np.ndarray, t: float, out: np.ndarray) -> None:
        """Fill `out` (M, D) with the field at `points` (M, D) and time `t`."""
        raise NotImplementedError  # pragma: no cover

    def jacobian(self, points, t: float = 0.0) -> np.ndarray:
        """Analytic Jacobian, (M, D, D) with ``J[i, a, b] = d v_a / d x_b``."""
        pts = self._points(points)
        out = np.empty((pts.shape[0], self.dim, self.dim))
        self.sample_jacobian(pts, float(t), out)
        return out

    def sample_jacobian(self, points: np.ndarray, t: float, out: np.ndarray) -> None:
        raise NotImplementedError(
            f"{type(self).__name__} has no analytic Jacobian; differentiate its samples numerically")

    def divergence(self, points, t: float = 0.0) -> np.ndarray:
        """Divergence (trace of the analytic Jacobian) at each point, (M,)."""
        return np.trace(self.jacobian(points, t), axis1=1, axis2=2)

    # -- helpers ----------------------------------------------------------------------------
    def _points(self, points) -> np.ndarray:
        return as_points(points, "points", dim=self.dim)

    def _check_out(self, points: np.ndarray, out: np.ndarray) -> None:
        if points.ndim != 2 or points.shape[1] != self.dim:
            raise ValueError(f"points must have shape (M, {self.dim}); got {points.shape}")
        if out.shape != points.shape:
            raise ValueError(f"out must have the shape of points {points.shape}; got {out.shape}")

    # -- arithmetic -------------------------------------------------------------------------
    def __add__(self, other):
        if isinstance(other, Field):
            return Sum([self, other])
        if isinstance(other, numbers.Number) and other == 0:
            return self  # so that sum([a, b]) works
        return NotImplemented

    def __radd__(self, other):
        if isinstance(other, numbers.Number) and other == 0:
            return self
        if isinstance(other, Field):
            return Sum([other, self])
        return NotImplemented

    def __neg__(self):
        return Scaled(self, -1.0)

    def __sub__(self, other):
        if isinstance(other, Field):
            return Sum([self, Scaled(other, -1.0)])
        return NotImplemented

    def __mul__(self, factor):
        if isinstance(factor, numbers.Real):
            return Scaled(self, float(factor))
        return NotImplemented

    __rmul__ = __mul__

    def __truediv__(self, divisor):
        if isinstance(divisor, numbers.Real):
            if divisor == 0:
                raise ValueError("divisor must be nonzero; got 0")
            return Scaled(self, 1.0 / float(divisor))
        return NotImplemented


class Sum(Field):
    """Pointwise sum of fields of one dimension: ``Sum([a, b, c])(x, t) = a + b + c``.

    Built by ``a + b``; nested sums are flattened. Keeps one scratch array of the last point
    count it saw, so repeated sampling allocates nothing.
    """

    def __init__(self, fields):
        flat = []
        for f in fields:
            if not isinstance(f, Field):
                raise ValueError(f"fields must be inertia.fields.Field instances; got {type(f).__name__}")
            flat.extend(f.fields if isinstance(f, Sum) else [f])
        if not flat:
            raise ValueError("fields must hold at least one field; got an empty list")
        dims = {f.dim for f in flat}
        if len(dims) != 1:
            raise ValueError(f"fields must all have the same dim; got dims {[f.dim for f in flat]}")
        self.fields = tuple(flat)
        self.dim = flat[0].dim
        self._scratch = np.empty((0, self.dim))
        self._scratch_jac = np.empty((0, self.dim, self.dim))

    def sample(self, points, t, out):
        self.fields[0].sample(points, t, out)
        if len(self.fields) > 1:
            if self._scratch.shape != out.shape:
                self._scratch = np.empty_like(out)
            for f in self.fields[1:]:
                f.sample(points, t, self._scratch)
                out += self._scratch

    def sample_jacobian(self, points, t, out):
        self.fields[0].sample_jacobian(points, t, out)
        if len(self.fields) > 1:
            if self._scratch_jac.shape != out.shape:
                self._scratch_jac = np.empty_like(out)
            for f in self.fields[1:]:
                f.sample_jacobian(points, t, self._scratch_jac)
                out += self._scratch_jac

    def __repr__(self):
        return " + ".join(repr(f) for f in self.fields)


class Scaled(Field):
    """A field times a real constant: ``Scaled(a, 2.0)(x, t) = 2 a(x, t)``; built by ``2.0 * a``."""

    def __init__(self, field, factor: float):
        if not isinstance(field, Field):
            raise ValueError(f"field must be an inertia.fields.Field; got {type(field).__name__}")
        factor = float(factor)
        if not np.isfinite(factor):
            raise ValueError(f"factor must be a finite number; got {factor!r}")
        # Fold nested scalings.
        if isinstance(field, Scaled):
            factor *= field.factor
            field = field.field
        self.field = field
        self.factor = factor
        self.dim = field.dim

    def sample(self, points, t, out):
        self.field.sample(points, t, out)
        out *= self.factor

    def sample_jacobian(self, points, t, out):
        self.field.sample_jacobian(points, t, out)
        out *= self.factor

    def __repr__(self):
        return f"{self.factor!r} * {self.field!r}"
