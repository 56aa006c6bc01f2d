"""Smoothed particle hydrodynamics (SPH) on struct-of-arrays particles, 2D and 3D.

    import inertia as ia
    from inertia.fluids import sph
    x = sph.sample_block((0.0, 0.0), (1.0, 2.0), spacing=0.02)
    fluid = sph.SPHFluid(x, spacing=0.02, domain=((0, 0), (4, 3)), method="dfsph")
    fluid.add_boundary(ia.colliders.Container(center=(2, 1.5), half_extents=(2, 1.5)))
    while fluid.time < 1.0:
        fluid.step()

Public names: ``SPHFluid`` (the solver: DFSPH or WCSPH, viscosity, XSPH, surface tension,
boundaries sampled on colliders, moving bodies with force/torque feedback, emitters, outflow,
periodic domains, adaptive dt), ``sample_block`` (lattice of fluid particles), the kernels
``kernel_value`` / ``kernel_gradient`` and ``KERNELS``. Algorithms and references: the module
docstrings of ``fluid``, ``kernels``, ``neighbours`` and ``smoothing``.
"""

from .fluid import METHODS, SPHFluid, sample_block
from .smoothing import KERNELS, kernel_gradient, kernel_value

__all__ = ["SPHFluid", "sample_block", "METHODS", "KERNELS", "kernel_value", "kernel_gradient"]
