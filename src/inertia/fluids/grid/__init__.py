"""Grid fluids: incompressible Navier-Stokes on a staggered MAC grid in 2-D and 3-D.

    from inertia.fluids.grid import GridFluid, Wall, Inflow, Outflow
    fluid = GridFluid((128, 128), 1 / 128, boundaries={"y+": Wall(velocity=(1, 0))}, viscosity=0.01)
    for frame in range(100):
        fluid.advance(1 / 30)
    u, v = fluid.u, fluid.v            # face velocities (views)
    tracers_field = fluid.velocity_field()

Modules: ``solver`` (the step, smoke, references and limitations), ``pressure`` (MGPCG, CG,
Jacobi), ``kernels`` (Numba), ``boundaries``, ``obstacles`` (face fractions), ``field``.
"""

from .boundaries import Inflow, Outflow, Periodic, Wall
from .field import FluidVelocityField
from .pressure import PoissonSolver
from .solver import ADVECTION, GridFluid, MACGrid

__all__ = ["GridFluid", "MACGrid", "Wall", "Inflow", "Outflow", "Periodic", "FluidVelocityField",
           "PoissonSolver", "ADVECTION"]
