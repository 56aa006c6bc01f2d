"""Analytic flow primitives: uniform flow, vortices, sources and sinks.

The superposition of such primitives is the classic procedural wind of Sims (1990) and
Wejchert & Haumann (1991); combine them with ``+`` and scalar ``*`` (see ``base.py``).
All have analytic Jacobians.

    Uniform:  v = U
    Rotation: v = omega x (x - c)    (rigid rotation; 2-D: omega (-(y - cy), x - cx))
    Vortex:   v = Gamma / (2 pi) (a x r) / (|r|^2 + rc^2)      r: offset from the axis
    Source:   v = Q / (4 pi) r / (|r|^2 + rc^2)^(3/2)     (3-D)
              v = Q / (2 pi) r / (|r|^2 + rc^2)           (2-D)

References
----------
- Sims, K. (1990), "Particle animation and rendering using data parallel computation",
  SIGGRAPH '90: vortices and other flow primitives for particle systems.
- Wejchert, J. & Haumann, D. (1991), "Animation aerodynamics", SIGGRAPH '91: uniform flow,
  sources, sinks and vortices superposed as potential flows.
- Witkin & Baraff (2001), "Differential Equation Basics": the rigid rotation field, whose exact
  paths are circles (explicit Euler spirals outward, RK4 stays on the circle to O(h^4)).
- Kaufmann, W. (1962) / Scully, M. P. (1975): the regularised vortex core |r|^2 + rc^2 used here
  (the velocity peaks at |r| = rc instead of diverging on the axis).

Limitations
-----------
- Rotation has no core: its speed grows with the distance from the centre.
- Vortex lines are straight and infinite; sources are points. The regularised source is not
  divergence-free inside its core (its volume flux is spread over the core, as intended).
- These primitives do not know about colliders: they flow through solids (use ``CurlNoise``
  with boundaries for flow that goes around obstacles).
"""

from __future__ import annotations

import numpy as np

from .._validate import as_vector, positive_scalar
from . import kernels as K
from .base import Field

__all__ = ["Sink", "Source", "Uniform", "Vortex"]


def _finite(value, name):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number; got {value!r}") from None
    if not np.isfinite(x):
        raise ValueError(f"{name} must be finite; got {value!r}")
    return x


class Uniform(Field):
    """Uniform flow ``v = velocity`` (m/s) everywhere; the dimension is the vector's length."""

    def __init__(self, velocity):
        self.velocity = as_vector(velocity, "velocity")
        self.dim = self.velocity.shape[0]

    def sample(self, points, t, out):
        self._check_out(points, out)
        out[:] = self.velocity

    def sample_jacobian(self, points, t, out):
        out[:] = 0.0

    def __repr__(self):
        return f"Uniform({self.velocity.tolist()})"


class Rotation(Field):
    """Rigid rotation ``v = omega x (x - center)``.

    `angular_velocity` is a number in rad/s for 2-D (counter-clockwise) or an (axis * rad/s)
    3-vector for 3-D; the dimension follows `center`.
    """

    def __init__(self, center, angular_velocity):
        self.center = as_vector(center, "center")
        self.dim = self.center.shape[0]
        if self.dim == 2:
            self.omega = _finite(angular_velocity, "angular_velocity")
        else:
            self.omega = as_vector(angular_velocity, "angular_velocity")
            if self.omega.shape[0] != 3:
                raise ValueError(f"angular_velocity must be a 3-vector for a 3-D center; got {self.omega.tolist()}")
        self._offset = np.empty((0, self.dim))

    def sample(self, points, t, out):
        self._check_out(points, out)
        c, w = self.center, self.omega
        if self.dim == 2:
            # out = w (-(y - cy), x - cx), column by column without temporaries
            np.subtract(points[:, 1], c[1], out=out[:, 0])
            out[:, 0] *= -w
            np.subtract(points[:, 0], c[0], out=out[:, 1])
            out[:, 1] *= w
            return
        if self._offset.shape != points.shape:
            self._offset = np.empty_like(points)
        r = self._offset
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


class Vortex(Field):
    """A straight regularised vortex line (a point vortex in 2-D).

    Parameters
    ----------
    center : (D,) a point on the vortex axis, m.
    circulation : Gamma in m^2/s; positive turns counter-clockwise about ``axis``. 1.0 default.
    axis : (3,) direction of the axis (3-D only; normalised); (0, 0, 1) default.
    core_radius : rc in m, where the swirl speed peaks (Gamma / (4 pi rc)); 0.1 default, > 0.
    """

    def __init__(self, center, circulation: float = 1.0, *, axis=(0.0, 0.0, 1.0),
                 core_radius: float = 0.1):
        self.center = as_vector(center, "center")
        self.dim = self.center.shape[0]
        self.circulation = _finite(circulation, "circulation")
        a = as_vector(axis, "axis", 3)
        norm = np.linalg.norm(a)
        if norm == 0:
            raise ValueError("axis must be a nonzero vector; got (0, 0, 0)")
        self.axis = a / norm
        if self.dim == 2 and not np.allclose(self.axis, (0.0, 0.0, 1.0)):
            raise ValueError("axis must be (0, 0, 1) for a 2-D vortex (it turns in the plane); "
                             f"got {tuple(axis)}")
        self.core_radius = positive_scalar(core_radius, "core_radius")
        self._jac = np.empty((0, self.dim, self.dim))

    def sample(self, points, t, out):
        self._check_out(points, out)
        K.vortex_field(points, self.center, self.axis, out, self._jac, self.circulation,
                       self.core_radius ** 2, 0)

    def sample_jacobian(self, points, t, out):
        v = np.empty(points.shape)
        K.vortex_field(points, self.center, self.axis, v, out, self.circulation,
                       self.core_radius ** 2, 1)

    def __repr__(self):
        return (f"Vortex(center={self.center.tolist()}, circulation={self.circulation}, "
                f"core_radius={self.core_radius})")


class Source(Field):
    """A regularised point source (a sink when ``strength`` < 0).

    Parameters
    ----------
    center : (D,) position, m.
    strength : Q, the volume flux out of the source in m^3/s (m^2/s in 2-D); 1.0 default.
    core_radius : rc in m, smoothing the singularity; 0.1 default, > 0.
    """

    def __init__(self, center, strength: float = 1.0, *, core_radius: float = 0.1):
        self.center = as_vector(center, "center")
        self.dim = self.center.shape[0]
        self.strength = _finite(strength, "strength")
        self.core_radius = positive_scalar(core_radius, "core_radius")
        self._jac = np.empty((0, self.dim, self.dim))

    def sample(self, points, t, out):
        self._check_out(points, out)
        K.source_field(points, self.center, out, self._jac, self.strength, self.core_radius ** 2, 0)

    def sample_jacobian(self, points, t, out):
        v = np.empty(points.shape)
        K.source_field(points, self.center, v, out, self.strength, self.core_radius ** 2, 1)

    def __repr__(self):
        return f"{type(self).__name__}(center={self.center.tolist()}, strength={self.strength})"


class Sink(Source):
    """A point sink: ``Sink(c, Q)`` is ``Source(c, -Q)``; Q > 0 is the volume flux drawn in."""

    def __init__(self, center, strength: float = 1.0, *, core_radius: float = 0.1):
        super().__init__(center, -_finite(strength, "strength"), core_radius=core_radius)

    def __repr__(self):
        return f"Sink(center={self.center.tolist()}, strength={-self.strength})"
