"""The fluid's velocity as an inertia.fields field: tracers follow it."""

import numpy as np

import inertia as ia
from inertia.fields import Field
from inertia.fluids.grid import GridFluid, Outflow


def test_tracers_follow_the_fluid_velocity_field():
    # rigid rotation u = omega (-(y - 1/2), x - 1/2): linear, so the MAC grid's linear
    # interpolation reproduces it exactly, and a tracer at radius r turns by omega t
    omega = 2.0
    f = GridFluid((16, 16), 1.0 / 16, scalars=(), boundaries={s: Outflow() for s in ("x-", "x+", "y-", "y+")})
    f.set_velocity(lambda p: omega * np.stack([-(p[:, 1] - 0.5), p[:, 0] - 0.5], axis=1))
    field = f.velocity_field()
    assert isinstance(field, Field) and field.dim == 2
    pts = np.array([[0.6, 0.5], [0.3, 0.45], [0.52, 0.71]])
    np.testing.assert_allclose(field(pts), omega * np.stack([-(pts[:, 1] - 0.5), pts[:, 0] - 0.5], 1),
                               atol=1e-13)
    out = np.empty_like(pts)
    field.sample(pts, 0.0, out)
    np.testing.assert_array_equal(out, field(pts, 3.0))
    tracers = ia.Tracers([[0.7, 0.5]], field)
    sim = ia.Simulation(tracers, "rk4", dt=0.01)
    sim.run(1.0)
    angle = omega * 1.0
    expect = 0.5 + 0.2 * np.array([np.cos(angle), np.sin(angle)])
    np.testing.assert_allclose(tracers.x[0], expect, atol=1e-8)
