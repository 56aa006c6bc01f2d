"""A grid fluid's velocity as an ``inertia.fields`` vector field, so tracers, particle drag and
curl-noise sums use it (protocol in docs/contracts.md).

Limitations: the field reads the fluid's *current* arrays (it is a live view, not a snapshot);
its ``t`` argument is ignored. Linear interpolation; outside the grid the position is clamped
to the domain (or wrapped on periodic axes). No analytic Jacobian.
"""

from __future__ import annotations

import numpy as np

from ...fields.base import Field
from . import kernels as K


class FluidVelocityField(Field):
    """``field(points, t)`` -> (M, dim) velocity of a `GridFluid` at (M, dim) points, m/s."""

    def __init__(self, fluid):
        self.fluid = fluid
        self.dim = fluid.dim

    def sample(self, points, t, out):
        self._check_out(points, out)
        u, v, w = self.fluid._vel
        self.fluid._k.sample_points(u, v, w, points, self.fluid.ctx, out)

    def __repr__(self):
        return f"FluidVelocityField({self.fluid.grid.shape})"
