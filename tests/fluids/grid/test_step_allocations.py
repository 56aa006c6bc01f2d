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

import tracemalloc
from types import SimpleNamespace

import numpy as np

from inertia.colliders import Motion, Sphere
from inertia.fluids.grid import GridFluid, Outflow
from inertia.fluids.grid.liquid import LiquidFluid
from inertia.model import ModelBuilder

N = 128                      # cells per axis
CELL_BYTES = N * N           # the smallest grid-proportional array: one bool per cell


def _arrays_in(x):
    if isinstance(x, np.ndarray):
        return 1
    if isinstance(x, tuple):
        return sum(_arrays_in(y) for y in x)
    return 0


def _kernel_allocations(step, n):
    """{kernel name: NRT allocations made inside it} over n calls of step (see the module docstring)."""
    from numba import _dispatcher
    from numba.core.registry import CPUDispatcher
    from numba.core.runtime import _nrt_python, rtsys
    base = _dispatcher.Dispatcher.__call__
    inside = {}
    calls = [0]

    def counting_call(self, *args, **kwargs):
        wrapped = _arrays_in(args) + _arrays_in(tuple(kwargs.values()))
        a0 = rtsys.get_allocation_stats().alloc
        out = base(self, *args, **kwargs)
        extra = rtsys.get_allocation_stats().alloc - a0 - wrapped
        calls[0] += 1
        if extra:
            name = f"{self.py_func.__module__}.{self.py_func.__qualname__}"
            inside[name] = inside.get(name, 0) + extra
        return out

    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    CPUDispatcher.__call__ = counting_call
    try:
        for _ in range(n):
            step()
    finally:
        del CPUDispatcher.__call__
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert calls[0] > 50                     # the wrapper saw the kernels (the counter works)
    return inside


def _peak_bytes(step, n):
    """tracemalloc's peak above the start over n calls of step, bytes."""
    tracemalloc.start()
    try:
        c0 = tracemalloc.get_traced_memory()[0]
        for _ in range(n):
            step()
        return tracemalloc.get_traced_memory()[1] - c0
    finally:
        tracemalloc.stop()


def _moving_ball(x0, y0, r):
    return Sphere(center=(x0, y0), radius=r, motion=Motion(position=lambda t: (x0 + 0.3 * t, y0)))


def test_smoke_step_with_a_moving_obstacle_allocates_nothing():
    # viscous smoke (MacCormack, buoyancy, a source, MGPCG) around a moving no-slip ball: every step
    # rebuilds the cut cells, the viscous boundary data and the torque reference points
    f = GridFluid((N, N), 1 / N, obstacles=[_moving_ball(0.4, 0.5, 0.12)], viscosity=0.01,
                  buoyancy=(0.1, 1.0), boundaries={"y+": Outflow()})
    f.add_source((0.4, 0.05), (0.6, 0.2), density_rate=5.0, temperature_rate=5.0)
    step = lambda: f.step(0.01)    # noqa: E731
    step()
    assert _kernel_allocations(step, 1) == {}
    peak = _peak_bytes(step, 2)
    assert peak < CELL_BYTES, peak
    assert np.any(f.obstacle_viscous_force != 0.0) and f.face_fractions[0].min() == 0.0


def test_liquid_step_with_a_body_and_a_moving_obstacle_allocates_nothing():
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
    inside = _kernel_allocations(step, 1)
    # the fluid's kernels allocate nothing. Two kernels of other layers the step calls do, 3x3
    # matrices per call: `BodyShape.pose` (collision/shapes.py) returns math.quat_to_mat3(q), and
    # `apply_body_impulses` (dynamics/particle_coupling.py, `_apply`) calls math.world_inertia_inv
    # per body (the liquid's own body term uses a non-allocating twin, liquid_pressure.py)
    assert not [k for k in inside if k.startswith("inertia.fluids")], inside
    assert set(inside) <= {"inertia.math.quat_to_mat3", "inertia.dynamics.particle_coupling._apply"}, inside
    peak = _peak_bytes(step, 2)
    assert peak < CELL_BYTES, peak
    assert f.particle_count > CELL_BYTES           # so one (N,) bool array would exceed the bound too
    assert f.body_force[body, 1] > 0.0             # the liquid pushes the body up
