"""Grid fluids: incompressible Navier-Stokes on a staggered MAC grid in 2-D and 3-D.

    from inertia.fluids.grid import GridFluid, Wall, Inflow, Outflow
    fluid = GridFluid((128, 128), 1 / 128, boundaries={"y+": Wall(velocity=(1, 0))}, viscosity=0.01)
    for frame in range(100):
        fluid.advance(1 / 30)
    u, v = fluid.u, fluid.v            # face velocities (views)
    tracers_field = fluid.velocity_field()

    from inertia.fluids.grid import LiquidFluid
    liquid = LiquidFluid((80, 48), 0.0125, method="apic")    # FLIP/PIC/APIC particles
    liquid.add_block((0, 0), (0.2, 0.4))
    liquid.advance(1 / 60)

Modules: ``solver`` (the step, smoke, references and limitations), ``liquid`` (free-surface
liquids), ``pressure`` (MGPCG, CG, Jacobi), ``kernels`` (Numba), ``boundaries``, ``obstacles``
(face fractions), ``field``, ``vtk`` (.vti export).
"""

from .boundaries import Inflow, Outflow, Periodic, Pressure, Wall
from .field import FluidVelocityField
from .liquid import LiquidFluid
from .pressure import PoissonSolver
from .solver import ADVECTION, GridFluid, MACGrid

__all__ = ["GridFluid", "LiquidFluid", "MACGrid", "Wall", "Inflow", "Outflow", "Pressure", "Periodic", "FluidVelocityField",
           "PoissonSolver", "ADVECTION"]
