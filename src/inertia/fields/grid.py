"""A vector field sampled on a regular grid, interpolated bilinearly (2-D) or trilinearly (3-D).

Node (i, j[, k]) sits at ``origin + (i, j[, k]) * spacing``; between nodes the value is the
multilinear blend of the 2^D surrounding nodes. ``Grid.from_field`` bakes any field (e.g. a
``CurlNoise`` with boundaries) into a grid once, so later sampling costs a few lookups.

References
----------
- Bridson, R. (2015), *Fluid Simulation for Computer Graphics*, 2nd ed., ch. 5.2: bilinear /
  trilinear interpolation of grid quantities.

Limitations
-----------
- Node-centred and time-independent (one snapshot).
- Interpolation is C^0: the Jacobian jumps across cell faces, and a divergence-free field
  baked into a grid is divergence-free only to the grid's truncation error O(h^2).
- Outside the grid the value is clamped to the nearest boundary node (``outside="clamp"``)
  or zero (``outside="zero"``).
"""

from __future__ import annotations

import numpy as np

from .._validate import as_vector
from . import kernels as K
from .base import Field

__all__ = ["Grid"]

_OUTSIDE = ("clamp", "zero")


class Grid(Field):
    """Vector field from node values on a regular grid.

    Parameters
    ----------
    values : array (n0, n1, 2) or (n0, n1, n2, 3)
        Velocity at each node, m/s; at least 2 nodes along every axis.
    origin : (D,)
        Position of node (0, 0[, 0]), m; zeros default.
    spacing : float or (D,)
        Node spacing, m; 1.0 default; > 0.
    outside : {"clamp", "zero"}
        Value outside the grid: the nearest boundary value ("clamp", default) or zero.
    """

    def __init__(self, values, *, origin=None, spacing=1.0, outside: str = "clamp"):
        values = np.asarray(values, dtype=np.float64)
        if values.ndim not in (3, 4) or values.shape[-1] != values.ndim - 1:
            raise ValueError("values must have shape (n0, n1, 2) or (n0, n1, n2, 3); "
                             f"got {values.shape}")
        if min(values.shape[:-1]) < 2:
            raise ValueError(f"values must have at least 2 nodes along every axis; got {values.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError("values must be finite")
        self.dim = values.shape[-1]
        self.values = np.ascontiguousarray(values)
        self.origin = np.zeros(self.dim) if origin is None else as_vector(origin, "origin", self.dim)
        sp = np.asarray(spacing, dtype=np.float64)
        sp = np.full(self.dim, float(sp)) if sp.ndim == 0 else as_vector(sp, "spacing", self.dim)
        if np.any(sp <= 0) or not np.all(np.isfinite(sp)):
            raise ValueError(f"spacing must be > 0 and finite along every axis; got {sp.tolist()}")
        self.spacing = sp
        if outside not in _OUTSIDE:
            raise ValueError(f"outside must be one of {list(_OUTSIDE)}; got {outside!r}")
        self.outside = outside
        self._inv = 1.0 / sp
        # The kernel reads 4-D node arrays; a 2-D grid is one layer thick.
        self._nodes = self.values if self.dim == 3 else self.values[:, :, None, :]

    @classmethod
    def from_field(cls, field, lower, upper, shape, *, t: float = 0.0, outside: str = "clamp"):
        """Sample ``field`` at time ``t`` on the nodes of a grid spanning [lower, upper]."""
        dim = field.dim
        lo = as_vector(lower, "lower", dim)
        hi = as_vector(upper, "upper", dim)
        shape = tuple(int(n) for n in np.atleast_1d(shape))
        if len(shape) != dim or min(shape) < 2:
            raise ValueError(f"shape must hold {dim} node counts, each >= 2; got {shape}")
        if np.any(hi <= lo):
            raise ValueError(f"upper must exceed lower along every axis; got {lo.tolist()} and {hi.tolist()}")
        axes = [np.linspace(lo[k], hi[k], shape[k]) for k in range(dim)]
        mesh = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)
        values = field(mesh, t).reshape(*shape, dim)
        spacing = (hi - lo) / (np.array(shape) - 1)
        return cls(values, origin=lo, spacing=spacing, outside=outside)

    @property
    def upper(self) -> np.ndarray:
        """Position of the last node, m."""
        return self.origin + (np.array(self.values.shape[:-1]) - 1) * self.spacing

    def sample(self, points, t, out):
        self._check_out(points, out)
        K.grid_sample(points, self._nodes, self.origin, self._inv, out[:, :, None], 0,
                      self.outside == "zero")

    def sample_jacobian(self, points, t, out):
        K.grid_sample(points, self._nodes, self.origin, self._inv, out, 1, self.outside == "zero")

    def __repr__(self):
        return (f"Grid(shape={self.values.shape[:-1]}, origin={self.origin.tolist()}, "
                f"spacing={self.spacing.tolist()})")
