"""Vector and scalar fields: procedural noise, curl-noise, analytic flows and sampled grids.

Every vector field is called as ``field(points, t)`` with (M, D) points and returns (M, D)
velocities; ``field.sample(points, t, out)`` fills a preallocated array (what
``inertia.Tracers`` and ``inertia.forces.Wind`` call each step). Fields add and scale:
``ia.fields.CurlNoise(dim=3) + 0.5 * ia.fields.Uniform((1, 0, 0))``.

- ``Noise``: seeded simplex / Perlin gradient noise in 2-D, 3-D and 4-D (time as an axis),
  fractal octaves, analytic gradient and Hessian (``noise.py``).
- ``CurlNoise``: divergence-free flow after Bridson et al. (2007), going around colliders
  (``curl.py``).
- ``Uniform``, ``Rotation``, ``Vortex``, ``Source``, ``Sink`` (``analytic.py``) and ``Grid`` (``grid.py``).
- ``Field``, ``Sum``, ``Scaled``: the protocol and its arithmetic (``base.py``).

References and limitations are listed in each module.
"""

from .analytic import Rotation, Sink, Source, Uniform, Vortex
from .base import Field, Scaled, Sum
from .curl import CurlNoise
from .grid import Grid
from .noise import Noise

__all__ = ["CurlNoise", "Field", "Grid", "Noise", "Rotation", "Scaled", "Sink", "Source", "Sum",
           "Uniform", "Vortex"]
