"""No allocation per step in the grid fluids (the project standard: "no allocation inside a step").

Two counters, each over a few steps after warm-up of a scene with a moving obstacle:

* Numba's NRT allocation counter (``rtsys.get_allocation_stats().alloc``). Calling a compiled
  kernel from Python wraps every array argument in an NRT meminfo, which the counter also counts
  (one per array; arrays inside tuples and named tuples such as ``GridContext`` each count). The
  dispatcher's ``__call__`` is wrapped for the measurement to count those arrays, so
  ``alloc - array arguments`` is exactly what the kernels themselves allocate (``np.empty`` and
  friends inside ``@njit`` code). It must be 0: the bound is exact, any kernel-side array adds 1.
* tracemalloc's peak above the start of the measured steps: every Python object and every NumPy
  data buffer (NumPy reports its buffers to tracemalloc). The bound is the size of the smallest
  array that grows with the grid, one byte per cell (a bool cell mask): 128 x 128 = 16384 bytes.
  Any array proportional to the grid (faces, cells, vertices) or to the particles alone exceeds
  it. What stays under it is Python's fixed overhead per step: the call frames and views of the
  stage methods, the few small arrays a collider builds to report its pose (``Motion.pose``,
  ``Collider._packed_pose``; collision/), the per-level lists of the multigrid V-cycle: 10.4,
  10.8, 11.1 KB for the smoke at 16^2, 32^2, 64^2 (it grows with the number of multigrid levels,
  not with the cells); 12 KB at 128^2.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from inertia.colliders import Motion, Sphere
from inertia.fluids.grid import GridFluid, Outflow, Pressure, Wall
from inertia.fluids.grid.liquid import LiquidFluid
from inertia.model import ModelBuilder

N = 128                      # cells per axis
CELL_BYTES = N * N           # the smallest grid-proportional array: one bool per cell


def _moving_ball(x0, y0, r):
    return Sphere(center=(x0, y0), radius=r, motion=Motion(position=lambda t: (x0 + 0.3 * t, y0)))


@pytest.mark.isolated
def test_smoke_step_with_a_moving_obstacle_allocates_nothing(alloc):
    # viscous smoke (MacCormack, buoyancy, a source, MGPCG) around a moving no-slip ball: every step
    # rebuilds the cut cells, the viscous boundary data and the torque reference points
    f = GridFluid((N, N), 1 / N, obstacles=[_moving_ball(0.4, 0.5, 0.12)], viscosity=0.01,
                  buoyancy=(0.1, 1.0), boundaries={"y+": Outflow()})
    f.add_source((0.4, 0.05), (0.6, 0.2), density_rate=5.0, temperature_rate=5.0)
    step = lambda: f.step(0.01)    # noqa: E731
    step()
    assert alloc.kernel_allocations(step, 1) == {}
    peak = alloc.peak_bytes(step, 2, CELL_BYTES)
    assert peak < CELL_BYTES, peak
    assert np.any(f.obstacle_viscous_force != 0.0) and f.face_fractions[0].min() == 0.0


@pytest.mark.isolated
def test_smoke_step_with_diffusion_pressure_sides_and_a_hot_moving_obstacle_allocates_nothing(alloc):
    # scalar diffusion (a hot wall, a moving obstacle held at a temperature: its cells' nearest
    # obstacle every step), pressure sides (Dirichlet data in the projection) and viscosity
    f = GridFluid((N, N), 1 / N, obstacles=[_moving_ball(0.4, 0.5, 0.12)], viscosity=0.01,
                  diffusivity={"temperature": 1e-3, "density": 1e-4}, obstacle_temperature=2.0,
                  buoyancy=(0.1, 1.0), boundaries={"x-": Pressure(1.0), "x+": Pressure(0.0),
                                                   "y-": Wall(temperature=1.0)})
    step = lambda: f.step(0.01)    # noqa: E731
    step()
    step()
    assert alloc.kernel_allocations(step, 1) == {}
    peak = alloc.peak_bytes(step, 2, CELL_BYTES)
    assert peak < CELL_BYTES, peak
    assert f.scalar("temperature").max() == 2.0 and f.u[0].mean() > 0.0


@pytest.mark.isolated
def test_liquid_step_with_a_body_and_a_moving_obstacle_allocates_nothing(alloc):
    # viscous APIC liquid with a dynamic box (body velocities in the pressure solve, viscous and
    # pressure impulses) and a moving collider: the cut cells, the body coupling, the particle
    # push-out all run every step
    b = ModelBuilder(gravity=(0, -9.81, 0))
    body = b.add_body(position=(0.5, 0.5, 0.0))        # half submerged
    b.add_box(body, half_extents=(0.1, 0.05, 0.05), density=500.0)
    model = b.finalize()
    rigid = SimpleNamespace(model=model, state=model.state())
    f = LiquidFluid((N, N), 1 / N, depth=0.1, viscosity=0.01, obstacles=[_moving_ball(0.2, 0.3, 0.08)])
    f.add_block((0, 0), (1.0, 0.5))
    f.bind_rigid(rigid)
    step = lambda: f.step(1 / 240)    # noqa: E731
    step()
    # no kernel the step calls allocates: the fluid's, the body poses (`BodyShape.pose`) and the
    # impulses onto the body (`apply_body_impulses`)
    assert alloc.kernel_allocations(step, 1) == {}
    peak = alloc.peak_bytes(step, 2, CELL_BYTES)
    assert peak < CELL_BYTES, peak
    assert f.particle_count > CELL_BYTES           # so one (N,) bool array would exceed the bound too
    assert f.body_force[body, 1] > 0.0             # the liquid pushes the body up
