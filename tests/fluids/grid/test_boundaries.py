"""Boundary conditions of GridFluid (boundaries.py): prescribed-pressure sides and inflow profiles,
against plane Poiseuille flow.

Plane Poiseuille flow (e.g. F. M. White, "Viscous Fluid Flow", 3rd ed., 2006, sec. 3-3.3): a
pressure drop dp over a length L between no-slip plates a distance H apart drives, at steady
state,

    u(y) = (dp / L) y (H - y) / (2 mu),   mu = rho nu,

the same profile as a body force g = dp / (rho L). On the MAC grid the steady discrete profile is
exact in the interior (the three-point second difference of a quadratic is exact) and the
no-slip ghost u_-1 = -u_0 shifts it by the constant (dp / L) h^2 / (8 mu) = (h / H)^2 u_max: the
bound of the tests below, second order in h.
"""

import numpy as np
import pytest

from inertia.fluids.grid import GridFluid, Inflow, Outflow, Pressure, Wall


def pressure_channel(shape, dp, nu, rho, steps, dt, periodic_z=True):
    h = 1.0 / shape[1]
    sides = {"x-": Pressure(dp), "x+": Pressure(0.0)}
    if len(shape) == 3 and periodic_z:
        sides.update({"z-": "periodic", "z+": "periodic"})
    f = GridFluid(shape, h, scalars=(), viscosity=nu, fluid_density=rho, boundaries=sides)
    for _ in range(steps):
        f.step(dt)
    return f


@pytest.mark.parametrize("shape", [(32, 16), (16, 16, 4)])
def test_pressure_drop_drives_poiseuille_flow(shape):
    # no body force: the flow comes from the two prescribed pressures alone; t = 2 s is 20
    # viscous times H^2 / (nu pi^2) (the start-up transient below 1e-8)
    dp, nu, rho, dt = 1.0, 1.0, 1000.0, 0.02
    f = pressure_channel(shape, dp, nu, rho, 100, dt)
    ny = shape[1]
    h, H, L = 1.0 / ny, 1.0, shape[0] / ny
    y = (np.arange(ny) + 0.5) * h
    exact = dp / L * y * (H - y) / (2 * rho * nu)
    umax = dp / L * H ** 2 / (8 * rho * nu)
    u = f.u if len(shape) == 2 else f.u[:, :, 1]
    # within the wall ghost's offset (h / H)^2 u_max: 0.39 % at 16 cells
    np.testing.assert_allclose(u, np.broadcast_to(exact, u.shape), atol=(h / H) ** 2 * umax * 1.001)
    assert np.abs(u - exact).max() > 0.99 * (h / H) ** 2 * umax     # the bound is the actual offset
    assert np.abs(f.v).max() < 1e-9 * umax
    # the pressure (phi = p dt / rho) falls linearly from dp on x- to 0 on x+, as the side values say
    x = (np.arange(shape[0]) + 0.5) * h
    p = (f.phi[:, :, 0] if len(shape) == 2 else f.phi[:, :, 1]) * rho / dt
    np.testing.assert_allclose(p, np.broadcast_to((dp * (1 - x / L))[:, None], p.shape), atol=1e-6 * dp)
    # what enters leaves
    assert u[-1].sum() == pytest.approx(u[0].sum(), rel=1e-9)


def test_pressure_side_lets_an_inflow_leave():
    f = GridFluid((24, 8), 1 / 8, scalars=(), boundaries={"x-": Inflow(velocity=(1.0, 0.0)), "x+": Pressure(0.0),
                                                         "y-": "slip", "y+": "slip"})
    for _ in range(5):
        f.step(0.05)
    np.testing.assert_allclose(f.u, 1.0, atol=1e-9)    # uniform plug flow through slip walls
    assert np.abs(f.measure_divergence()).max() < 1e-8


@pytest.mark.parametrize("shape", [(48, 16), (24, 8, 4)])
def test_parabolic_inflow_keeps_its_profile_downstream(shape):
    # the fully developed inflow (mean U) is plane Poiseuille flow: it must stay so down the
    # channel (Re = U H / nu = 10), to the wall ghost's (h / H)^2 of u_max
    U, nu = 1.0, 0.1
    ny = shape[1]
    h = 1.0 / ny
    sides = {"x-": Inflow(velocity=(U,) + (0.0,) * (len(shape) - 1), profile="parabolic"), "x+": Outflow()}
    if len(shape) == 3:
        sides.update({"z-": "periodic", "z+": "periodic"})
    f = GridFluid(shape, h, scalars=(), viscosity=nu, boundaries=sides)
    y = (np.arange(ny) + 0.5) * h
    par = 6 * U * y * (1 - y)
    u = f.u if len(shape) == 2 else f.u[:, :, 1]
    np.testing.assert_array_equal(u[0], par)                # the inflow faces hold the parabola
    for _ in range(120):                                    # t = 6 s: two flow-throughs
        f.step(0.05)
    u = f.u if len(shape) == 2 else f.u[:, :, 1]
    # downstream: within 1 % (measured 0.32 % at 16 cells: (h / H)^2 = 0.39 %)
    for i in (shape[0] // 3, 2 * shape[0] // 3, shape[0]):
        assert np.abs(u[i] - par).max() < max(0.01, 1.05 * h * h) * par.max()
    # mass in = mass out (to the pressure tolerance); the inflow's flux is the parabola's at the
    # face centres: U H (1 + 1 / (2 ny^2)) per unit depth
    flux_in, flux_out = f.u[0].sum() * h ** (len(shape) - 1), f.u[-1].sum() * h ** (len(shape) - 1)
    assert flux_in == pytest.approx(U * (1 + 0.5 / ny ** 2) * (shape[2] * h if len(shape) == 3 else 1.0), rel=1e-12)
    assert flux_out == pytest.approx(flux_in, rel=1e-6)


def test_parabolic_inflow_in_a_duct_is_the_product_of_two_parabolas_with_mean_U():
    f = GridFluid((8, 12, 8), 1 / 8, scalars=(), boundaries={"x-": Inflow(velocity=(2.0, 0.0, 0.0), profile="parabolic"),
                                                            "x+": Outflow()})
    y = (np.arange(12) + 0.5) / 12
    z = (np.arange(8) + 0.5) / 8
    np.testing.assert_allclose(f.w.shape, (8, 12, 9))
    np.testing.assert_allclose(f.u[0], 2.0 * 36 * np.outer(y * (1 - y), z * (1 - z)), rtol=1e-14)
    # the midpoint sums of s (1 - s): 1/6 (1 + 1 / (2 n^2)) per axis
    assert f.u[0].mean() == pytest.approx(2.0 * (1 + 0.5 / 12 ** 2) * (1 + 0.5 / 8 ** 2), rel=1e-12)


def test_inflow_profile_from_a_user_function():
    def profile(points):            # (M, 2) face centres on the side -> (M,) normal speed
        return 0.5 + np.sin(np.pi * points[:, 1])
    f = GridFluid((16, 8), 1 / 8, scalars=(), boundaries={"x-": Inflow(velocity=(0.0, 0.0), profile=profile),
                                                         "x+": Outflow()})
    y = (np.arange(8) + 0.5) / 8
    np.testing.assert_allclose(f.u[0], 0.5 + np.sin(np.pi * y), rtol=1e-15)
    f.step(0.02)
    np.testing.assert_allclose(f.u[0], 0.5 + np.sin(np.pi * y), rtol=1e-15)   # held every step
    # a profile on a high side: + along the axis, so an inflow through x+ is negative
    g = GridFluid((16, 8), 1 / 8, scalars=(), boundaries={"x+": Inflow(velocity=(-1.0, 0.0), profile="parabolic"),
                                                         "x-": Outflow()})
    assert np.all(g.u[-1] < 0) and g.u[-1].mean() == pytest.approx(-(1 + 0.5 / 64), rel=1e-12)


def test_an_inflow_needs_a_side_to_leave_through():
    with pytest.raises(ValueError, match=r"net .* closed domain; add an Outflow\(\) or Pressure\(\)"):
        GridFluid((8, 8), 1 / 8, boundaries={"x-": Inflow(velocity=(1.0, 0.0))})
    with pytest.raises(ValueError, match="closed domain"):
        GridFluid((8, 8), 1 / 8, boundaries={"y-": Inflow(velocity=(0.0, 1.0), profile="parabolic")})
    # an inflow whose flux cancels (in at one side, out through an inflow of the same speed at the
    # other) is allowed, and so is a tangential inflow
    GridFluid((8, 8), 1 / 8, boundaries={"x-": Inflow(velocity=(1.0, 0.0)), "x+": Inflow(velocity=(1.0, 0.0))})
    GridFluid((8, 8), 1 / 8, boundaries={"x-": Inflow(velocity=(0.0, 0.5))})


@pytest.mark.parametrize("sides,word", [
    ({"x-": Pressure("high"), "x+": Outflow()}, r"boundaries\['x-'\].pressure must be a finite number"),
    ({"x-": Pressure(np.nan)}, r"boundaries\['x-'\].pressure"),
    ({"x-": Pressure(True)}, r"boundaries\['x-'\].pressure"),
    ({"x-": Inflow(velocity=(1.0, 0.0), profile="cosine"), "x+": Outflow()},
     r"boundaries\['x-'\].profile must be one of \('uniform', 'parabolic'\)"),
    ({"x-": Inflow(velocity=(1.0, 0.0), profile=lambda p: np.ones(3)), "x+": Outflow()},
     r"boundaries\['x-'\].profile must return 8 finite speeds"),
    ({"x-": Inflow(velocity=(1.0, 0.0), profile=lambda p: np.full(len(p), np.nan)), "x+": Outflow()},
     r"boundaries\['x-'\].profile must return 8 finite speeds"),
    ({"x-": Inflow(velocity=(1.0, 0.0), density="thick"), "x+": Outflow()}, r"boundaries\['x-'\].density"),
])
def test_bad_boundary_values_name_the_side_and_key(sides, word):
    with pytest.raises(ValueError, match=word):
        GridFluid((8, 8), 1 / 8, boundaries=sides)


def test_project_needs_dt_with_a_pressure_side():
    f = GridFluid((8, 8), 1 / 8, boundaries={"x-": Pressure(1.0), "x+": Outflow()})
    with pytest.raises(ValueError, match="dt is required"):
        f.project()
    f.project(0.01)
    assert f.u[0].mean() > 0.0     # the drop pushes fluid in through x-


def test_pressure_channel_resumes_bit_for_bit(resumed_twin):
    def make():
        return GridFluid((16, 8), 1 / 8, scalars=("density",), viscosity=0.05,
                         boundaries={"x-": Pressure(2.0), "x+": Pressure(0.5)}, diffusivity={"density": 1e-3})
    a, b = resumed_twin(make, lambda s: s.step(0.05), 3, 3)
    assert a.state_hash() == b.state_hash()


THREADS_SCRIPT = """
import numpy as np
from inertia.colliders import Sphere
from inertia.fluids.grid import GridFluid, Inflow, Outflow, Pressure, Wall
# parallel kernels forced on small grids: diffusion with a hot obstacle and a hot wall, pressure
# sides, a parabolic inflow
f = GridFluid((32, 16), 1 / 16, viscosity=0.01, parallel=True, buoyancy=(0.0, 1.0),
              diffusivity={"temperature": 1e-3, "density": 1e-3}, obstacles=[Sphere(center=(0.8, 0.5), radius=0.2)],
              obstacle_temperature=1.0, boundaries={"x-": Pressure(1.0), "x+": Pressure(0.0),
                                                    "y-": Wall(temperature=0.5)})
g = GridFluid((32, 16), 1 / 16, viscosity=0.01, parallel=True, scalars=("density",), diffusivity={"density": 1e-2},
              boundaries={"x-": Inflow(velocity=(1.0, 0.0), density=1.0, profile="parabolic"), "x+": Outflow()})
for _ in range(5):
    f.step(0.02)
    g.step(0.02)
print(f.state_hash(), g.state_hash())
"""


def test_same_hash_at_one_and_two_threads_with_diffusion_and_pressure_sides():
    import os
    import subprocess
    import sys
    out = []
    for threads in ("1", "2"):
        env = dict(os.environ, NUMBA_NUM_THREADS=threads)
        run = subprocess.run([sys.executable, "-c", THREADS_SCRIPT], env=env, check=True, capture_output=True,
                             text=True, timeout=900)
        out.append(run.stdout.strip().splitlines()[-1])
    assert out[0] == out[1]
