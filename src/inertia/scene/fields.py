"""Adapters the scene format needs beside `inertia.fields`.

``field_force``: a force object (or acceleration) equal to ``scale * field(x, t)``.
"""

from __future__ import annotations

import numpy as np

from ..forces import ForceField

__all__ = ["field_force"]


def field_force(field, scale: float = 1.0, per_mass: bool = True) -> ForceField:
    """A force (per_mass: an acceleration) equal to ``scale * field(x, t)``, sampled without allocating."""
    scratch = {"out": np.empty((0, field.dim))}

    def fn(x, v, t):
        out = scratch["out"]
        if out.shape != x.shape:
            out = scratch["out"] = np.empty_like(x)
        field.sample(np.ascontiguousarray(x), t, out)
        if scale != 1.0:
            out *= scale
        return out

    return ForceField(fn, per_mass=per_mass)
