"""Small analytic fields and adapters the scene format offers beside `inertia.fields`.

``Rotation``: rigid rotation about a centre, v = omega x (x - c) (2-D: omega (-(y - cy), x - cx)),
the flow field of Witkin & Baraff's "Differential Equation Basics": its exact paths are
circles, explicit Euler spirals outward, RK4 stays on the circle to O(h^4).
``uniform``: a constant velocity. ``field_force``: a force object from a field.

Limitations: Rotation has no core (speeds grow with the distance from the centre).
"""

from __future__ import annotations

import numpy as np

from ..fields import Field
from ..forces import ForceField

__all__ = ["Rotation", "Uniform", "uniform", "field_force"]


class Rotation(Field):
    """v = omega x (x - center); `omega` a number (2-D, rad/s) or a 3-vector (3-D, axis * rad/s)."""

    def __init__(self, center, angular_velocity):
        self.center = np.asarray(center, dtype=np.float64).copy()
        self.dim = int(self.center.shape[0])
        self.omega = (float(angular_velocity) if self.dim == 2
                      else np.asarray(angular_velocity, dtype=np.float64).reshape(3).copy())
        self._r = np.empty((0, self.dim))

    def sample(self, points, t, out):
        self._check_out(points, out)
        c, w = self.center, self.omega
        if self.dim == 2:
            # out = w (-(y - cy), x - cx), written column by column without temporaries
            np.subtract(points[:, 1], c[1], out=out[:, 0])
            out[:, 0] *= -w
            np.subtract(points[:, 0], c[0], out=out[:, 1])
            out[:, 1] *= w
            return
        if self._r.shape != points.shape:
            self._r = np.empty_like(points)
        r = self._r
        np.subtract(points, c, out=r)
        out[:, 0] = w[1] * r[:, 2] - w[2] * r[:, 1]
        out[:, 1] = w[2] * r[:, 0] - w[0] * r[:, 2]
        out[:, 2] = w[0] * r[:, 1] - w[1] * r[:, 0]

    def sample_jacobian(self, points, t, out):
        out[:] = 0.0
        if self.dim == 2:
            out[:, 0, 1], out[:, 1, 0] = -self.omega, self.omega
        else:
            w = self.omega
            out[:] = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])

    def __repr__(self):
        return f"Rotation(center={self.center.tolist()}, angular_velocity={np.asarray(self.omega).tolist()})"


class Uniform(Field):
    """A constant velocity everywhere."""

    def __init__(self, velocity):
        self.velocity = np.asarray(velocity, dtype=np.float64).copy()
        self.dim = int(self.velocity.shape[0])

    def sample(self, points, t, out):
        self._check_out(points, out)
        out[:] = self.velocity

    def sample_jacobian(self, points, t, out):
        out[:] = 0.0

    def __repr__(self):
        return f"Uniform({self.velocity.tolist()})"


def uniform(velocity):
    """`inertia.fields.Uniform` when the library has it, else the local one."""
    import inertia.fields as fields

    cls = getattr(fields, "Uniform", None)
    if cls is not None:
        try:
            return cls(velocity)
        except TypeError:
            pass
    return Uniform(velocity)


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
