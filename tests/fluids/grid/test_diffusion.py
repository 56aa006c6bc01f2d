"""Scalar diffusion and heat conduction of GridFluid (solver.py, the diffuse stage) against the
heat equation's closed forms.

A Gaussian blob s(r, 0) = exp(-r^2 / (2 s0^2)) in d dimensions diffuses as the heat kernel
(e.g. H. S. Carslaw and J. C. Jaeger, "Conduction of Heat in Solids", 2nd ed., 1959, ch. 10):

    s(r, t) = (s0^2 / st^2)^(d/2) exp(-r^2 / (2 st^2)),   st^2 = s0^2 + 2 kappa t,

and a semi-infinite body at T0 whose face is held at Tw from t = 0 (Carslaw and Jaeger, ch. 2.4):

    T(x, t) = T0 + (Tw - T0) erfc(x / (2 sqrt(kappa t))).

Backward Euler with the 2d + 1 point Laplacian: each Fourier mode k decays by 1 / (1 + kappa
|k_h|^2 dt) per step, |k_h|^2 = sum 4 sin^2(k_i h / 2) / h^2 = |k|^2 - sum k_i^4 h^2 / 12 + ...;
both the time and the space error slow the decay, so the blob's peak comes out high by (leading
order, averaging the mode errors over the Gaussian spectrum of variance 1 / st^2 per axis)

    kappa t / st^4 ((d^2 + 2 d) kappa dt / 2 + 3 d h^2 / 12).

The discrete second moment grows exactly as in the continuum (sum x^2 Lap s = 2 sum s for the
discrete Laplacian too), and insulating walls conserve the total.
"""

from math import erfc

import numpy as np
import pytest

from inertia.colliders import Box, Sphere
from inertia.fluids.grid import GridFluid, Inflow, Outflow, Wall


BALL = Sphere(center=(0.5, 0.5), radius=0.2)


def diffuse_blob(dim, n, dt, steps, kappa=0.01, s0=0.04):
    """A Gaussian blob centred on a cell of the unit box (insulating walls 5 st away)."""
    h = 1.0 / n
    f = GridFluid((n,) * dim, h, scalars=("density",), diffusivity={"density": kappa})
    r2 = np.sum((f.grid.cell_positions() - (0.5 + 0.5 * h)) ** 2, axis=1)
    c = f.scalar("density")
    c[...] = np.exp(-r2 / (2 * s0 ** 2)).reshape(c.shape)
    mass0 = c.sum()
    var0 = (c.reshape(-1) * r2).sum() / mass0 / dim
    for _ in range(steps):
        f.step(dt)
    t = dt * steps
    st2 = s0 ** 2 + 2 * kappa * t
    peak_error = c.reshape(-1)[np.argmin(r2)] / (s0 ** 2 / st2) ** (dim / 2) - 1.0
    predicted = kappa * t / st2 ** 2 * ((dim * dim + 2 * dim) * kappa * dt / 2 + 3 * dim * h * h / 12)
    variance_growth = ((c.reshape(-1) * r2).sum() / c.sum() / dim - var0) / (2 * kappa * t)
    return f, c.sum() / mass0, variance_growth, peak_error, predicted


def test_gaussian_blob_follows_the_heat_kernel_in_2d_at_second_order():
    # t = 0.4 s, st = 0.098 m: 10.5 cells at n = 64
    f64, mass, growth, err64, pred64 = diffuse_blob(2, 64, 0.04, 10)
    assert mass == pytest.approx(1.0, abs=1e-12)          # insulating walls
    assert growth == pytest.approx(1.0, abs=1e-4)         # width: st^2 - s0^2 = 2 kappa t
    assert 0.85 * pred64 <= err64 <= 1.25 * pred64        # peak: measured 7.9 %, predicted 7.5 %
    assert np.all(f64.u == 0.0) and np.all(f64.v == 0.0)  # diffusion leaves the fluid at rest
    _, _, growth, err128, pred128 = diffuse_blob(2, 128, 0.01, 40)   # h / 2, dt / 4
    assert growth == pytest.approx(1.0, abs=1e-4)
    assert 0.85 * pred128 <= err128 <= 1.25 * pred128     # 1.9 % (predicted 1.9 %)
    assert 3.5 < err64 / err128 < 4.5                      # O(h^2 + dt) with dt ~ h^2


def test_gaussian_blob_follows_the_heat_kernel_in_3d():
    _, mass, growth, err, pred = diffuse_blob(3, 32, 0.04, 10)
    assert mass == pytest.approx(1.0, abs=1e-12)
    assert growth == pytest.approx(1.0, abs=1e-3)
    assert 0.85 * pred <= err <= 1.25 * pred               # 18.4 % (predicted 16.2 %) at 3.1 cells per st


def hot_wall(n, dt, steps, kappa=1e-3, t0=0.25, tw=1.25, dim=2):
    """Fluid at rest at t0 in [0, 1] x [0, 4 h] (x [0, 4 h]); the x- wall is held at tw, the rest
    insulate."""
    h = 1.0 / n
    sides = {"x-": Wall(temperature=tw), "y-": "slip", "y+": "slip"}
    if dim == 3:
        sides.update({"z-": "slip", "z+": "slip"})
    f = GridFluid((n,) + (4,) * (dim - 1), h, scalars=("temperature",), diffusivity={"temperature": kappa},
                  ambient_temperature=t0, boundaries=sides)
    f.scalar("temperature")[...] = t0
    for _ in range(steps):
        f.step(dt)
    t = dt * steps
    x = (np.arange(n) + 0.5) * h
    exact = t0 + (tw - t0) * np.array([erfc(xi / (2 * np.sqrt(kappa * t))) for xi in x])
    temp = f.scalar("temperature").reshape(n, -1)
    return f, np.abs(temp - exact[:, None]).max() / (tw - t0)


def test_hot_wall_conducts_heat_as_the_error_function():
    # t = 10 s: the heated layer 2 sqrt(kappa t) = 0.2 m (13 cells at n = 64), far from x+
    f, err64 = hot_wall(64, 0.2, 50)
    assert err64 < 5e-3                                    # measured 3.6e-3 of Tw - T0
    assert np.all(f.u == 0.0) and np.all(f.v == 0.0)       # no buoyancy: the fluid stays at rest
    _, err128 = hot_wall(128, 0.05, 200)
    assert err128 < 1.5e-3                                 # 8.9e-4
    assert err64 / err128 > 3.5                            # second order (dt ~ h^2)
    f3, err3 = hot_wall(64, 0.2, 50, dim=3)
    assert err3 == pytest.approx(err64, rel=1e-6)          # 3-D: the same 1-D problem
    assert np.all(f3.w == 0.0)


def hot_slab(n, dt, steps, offset, kappa=1e-3):
    """A slab obstacle held at 1 fills x < xs, its surface xs = 0.125 m + offset h between two cell
    centres; fluid at 0, at rest."""
    h = 1.0 / n
    xs = 0.125 + offset * h
    slab = Box(center=(xs - 0.5, 0.5), half_extents=(0.5, 1.0))
    f = GridFluid((n, 8), h, scalars=("temperature",), diffusivity={"temperature": kappa},
                  boundaries={"y-": "slip", "y+": "slip"}, obstacles=[slab], obstacle_temperature=1.0)
    for _ in range(steps):
        f.step(dt)
    t = dt * steps
    x = (np.arange(n) + 0.5) * h
    fluid = x > xs
    exact = np.array([erfc((xi - xs) / (2 * np.sqrt(kappa * t))) for xi in x[fluid]])
    temp = f.scalar("temperature")
    return f, np.abs(temp[fluid] - exact[:, None]).max(), temp[~fluid]


@pytest.mark.parametrize("offset", [0.1, 0.3, 0.8])
def test_hot_obstacle_conducts_from_its_own_surface(offset):
    # the erfc solution measured from the obstacle's surface, wherever it cuts the cell: the
    # ghost-fluid Dirichlet condition places it between the nodes (a staircase at the solid
    # cell centre would shift the profile by up to h / 2: about 0.04 at n = 64 from the surface
    # slope 1 / sqrt(pi kappa t) = 5.6 / m)
    f, err, solid = hot_slab(64, 0.2, 50, offset)
    assert err < 5e-3                                # measured 3.3e-3 .. 3.5e-3
    assert np.all(solid == 1.0)                      # the obstacle's cells keep its temperature
    assert np.all(f.u == 0.0)


def test_hot_obstacle_conduction_is_second_order():
    _, err64, _ = hot_slab(64, 0.2, 50, 0.3)
    _, err128, _ = hot_slab(128, 0.05, 200, 0.3)
    assert err64 / err128 > 3.5                      # 3.3e-3 -> 8.2e-4


def test_insulating_walls_and_obstacles_conserve_the_scalar():
    f = GridFluid((24, 24), 1 / 24, scalars=("dye",), diffusivity={"dye": 0.05}, obstacles=[BALL])
    dye = f.scalar("dye")
    x = f.grid.cell_positions()
    dye[...] = np.where((x[:, 0] < 0.25) & (x[:, 1] < 0.25), 1.0, 0.0).reshape(dye.shape)
    total = dye.sum()
    for _ in range(20):
        f.step(0.05)
    assert dye.sum() == pytest.approx(total, rel=1e-9)
    # t = 1, sqrt(2 kappa t) = 0.32 m: spread past the source box (peak 1 -> 0.35), nothing
    # inside the insulating ball
    assert dye.max() < 0.4 and dye[12, 2] > 0.1 and dye[12, 12] == 0.0


@pytest.mark.parametrize("sides", [
    {"x-": Wall(slip=True, scalars={"density": 1.0})},                       # a wall holding 1
    {"x-": Inflow(velocity=(0.0, 0.0), density=1.0), "x+": Outflow()},       # an inflow at rest
])
def test_a_side_holding_a_value_fills_the_fluid_with_it(sides):
    # pure diffusion through a fluid at rest from a side held at 1 towards an insulating wall or
    # an outflow (zero gradient): the steady state is uniform 1 (the slowest mode,
    # exp(-kappa (pi / 2L)^2 t) = exp(-4.9), is below 1e-2 at t = 4; backward Euler's 1 / (1 +
    # kappa k^2 dt)^n is larger, so 40 steps of 0.1 leave 1.1e-2 of it)
    f = GridFluid((16, 4), 1 / 16, scalars=("density",), diffusivity={"density": 0.5},
                  boundaries={"y-": "slip", "y+": "slip", **sides})
    for _ in range(40):
        f.step(0.1)
    d = f.scalar("density")
    assert d.min() > 0.98 and d.max() < 1.0 + 1e-12
    assert np.all(np.diff(d[:, 0]) < 0)                    # decreasing away from the held side


def test_diffusion_off_costs_no_arrays_and_leaves_scalars_alone():
    f = GridFluid((16, 16), 1 / 16, scalars=("density",))
    assert f._skind.size == 1 and f._scg[0].size == 1
    d = f.scalar("density")
    d[5, 5] = 1.0
    f.step(0.1)
    assert d[5, 5] == 1.0 and d.sum() == 1.0


@pytest.mark.parametrize("kwargs,word", [
    ({"diffusivity": {"smoke": 1e-3}}, "diffusivity has an unknown scalar 'smoke'"),
    ({"diffusivity": {"density": -1e-3}}, r"diffusivity\['density'\]"),
    ({"diffusivity": {"density": True}}, r"diffusivity\['density'\]"),
    ({"diffusivity": {"density": np.nan}}, r"diffusivity\['density'\]"),
    ({"diffusivity": 1e-3}, "diffusivity must be a dict"),
    ({"boundaries": {"x-": Wall(temperature="hot")}}, r"boundaries\['x-'\].temperature"),
    ({"boundaries": {"x-": Wall(temperature=np.inf)}}, r"boundaries\['x-'\].temperature"),
    ({"boundaries": {"x-": Wall(scalars={"dye": 1.0})}}, r"boundaries\['x-'\].scalars has an unknown scalar 'dye'"),
    ({"obstacles": [BALL], "obstacle_temperature": 1.0}, r"obstacle_temperature needs the temperature to diffuse"),
    ({"obstacles": [BALL], "obstacle_temperature": [1.0, 2.0], "diffusivity": {"temperature": 1e-3}},
     r"obstacle_temperature must be None, one number, or 1 entries"),
    ({"obstacles": [BALL], "obstacle_temperature": [True], "diffusivity": {"temperature": 1e-3}},
     r"obstacle_temperature\[0\] must be a finite number or None"),
])
def test_bad_diffusion_input_names_the_argument(kwargs, word):
    with pytest.raises(ValueError, match=word):
        GridFluid((8, 8), 0.125, **kwargs)


def test_diffusing_fluid_resumes_bit_for_bit(resumed_twin):
    def make():
        f = GridFluid((16, 8), 1 / 8, boundaries={"x+": Outflow(), "x-": Wall(temperature=1.0)},
                      diffusivity={"temperature": 0.01, "density": 0.002}, buoyancy=(0.0, 1.0))
        f.add_source((0.5, 0.1), (0.9, 0.3), density_rate=1.0)
        return f
    a, b = resumed_twin(make, lambda s: s.step(0.05), 3, 3)
    assert a.state_hash() == b.state_hash()