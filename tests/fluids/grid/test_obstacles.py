"""Face fractions (inertia.fluids.grid.obstacles) against exact areas, and the variational
weights (Batty, Bertails and Bridson 2007) making a curved wall smooth."""

import numpy as np
import pytest

from inertia.colliders import Sphere
from inertia.fluids.grid import GridFluid, Inflow, Outflow
from inertia.fluids.grid.obstacles import face_fractions, fractions_into, segment_fraction, square_fraction


def test_segment_fraction_is_exact_for_a_linear_distance():
    # phi = x - 0.3 on [0, 1]: the part with phi > 0 has length 0.7
    assert segment_fraction(-0.3, 0.7) == 0.7
    assert segment_fraction(0.7, -0.3) == 0.7
    assert segment_fraction(1.0, 2.0) == 1.0
    assert segment_fraction(-1.0, -2.0) == 0.0


def test_square_fraction_is_exact_for_a_plane():
    # phi = n . (x - x0) on the unit square, exact open area computed by fine sampling
    rng = np.random.default_rng(1)
    for _ in range(20):
        angle = rng.uniform(0, 2 * np.pi)
        nrm = np.array([np.cos(angle), np.sin(angle)])
        x0 = rng.uniform(0, 1, 2)
        phi = lambda x, y: nrm[0] * (x - x0[0]) + nrm[1] * (y - x0[1])  # noqa: E731
        got = square_fraction(phi(0, 0), phi(1, 0), phi(1, 1), phi(0, 1))
        g = (np.arange(800) + 0.5) / 800
        X, Y = np.meshgrid(g, g)
        exact = np.mean(phi(X, Y) > 0)
        assert abs(got - exact) < 3e-3



@pytest.mark.parametrize("dim", [2, 3])
def test_fraction_kernel_gives_the_bits_of_the_numpy_reference(dim):
    # the step's kernel (`fractions_into`, no allocation) against `face_fractions` (NumPy, whose
    # exactness the two tests above check): random vertex distances with exact zeros, sign ties,
    # tiny values and a NaN; every fraction bit for bit
    rng = np.random.default_rng(7)
    shp = (9, 8, 7) if dim == 3 else (9, 8, 1)
    for scale in (1e-3, 1.0):
        s = rng.normal(size=shp) * scale
        s[rng.random(shp) < 0.1] = 0.0
        s[0, 0, 0] = np.nan
        ref = face_fractions(np.concatenate([s, s], axis=2) if dim == 2 else s, dim)
        out = [np.full(r.shape, -1.0) for r in ref]
        fractions_into(s, dim, *out)
        for a in range(3):
            assert np.array_equal(out[a].view(np.int64), ref[a].view(np.int64)), a
        assert 0.0 < np.mean(ref[0]) < 1.0

def test_open_area_of_a_cylinder_converges_to_the_circle():
    # the blocked length of the y-faces on one grid line is the chord; summed over all faces the
    # blocked area (times h) approaches pi r^2 at second order -- a staircase only at first order
    r = 0.3
    errors = []
    for n in (16, 32, 64):
        f = GridFluid((n, n), 1.0 / n, scalars=(), obstacles=[Sphere(center=(0.503, 0.497), radius=r)])
        fu, fv = f.face_fractions
        blocked_u = np.sum(1.0 - fu[1:-1, :]) / n**2  # interior faces; approximates the area
        errors.append(abs(blocked_u - np.pi * r * r))
    assert errors[2] < errors[0] / 8
    assert errors[2] < 2e-3


# ----------------------------------------------------------------------------- no-slip obstacles
def _plate_couette(n, U=1.0, nu=1.0, H=0.83, steps=40, dt=0.05):
    """Plane Couette flow between the no-slip domain wall y = 0 (at rest) and the lower face
    y = H of a plate obstacle sliding at U along a periodic x axis; H is off the grid lines so the
    surface cuts the faces (theta != 1)."""
    from inertia.colliders import Box, Motion
    h = 1.0 / n
    top = H + 1.0
    plate = Box(center=(0.0, top), half_extents=(100.0, 1.0),
                motion=Motion(position=lambda t: (U * t, top)))
    ny = int(np.ceil(H / h)) + 2
    f = GridFluid((8, ny), h, boundaries={"x-": "periodic", "x+": "periodic"}, viscosity=nu,
                  obstacles=[plate], scalars=(), fluid_density=1.0)
    for _ in range(steps):   # t = 2: the start-up transient is below exp(-pi^2 nu t / H^2) ~ 1e-12
        f.step(dt)
    return f, (np.arange(ny) + 0.5) * h


def test_couette_between_a_wall_and_a_sliding_obstacle_plate_is_linear():
    # Steady plane Couette flow u = U y / H (closed form). The plate's surface velocity enters the
    # implicit viscosity as a Dirichlet value at the cut position (ghost fluid, Gibou et al. 2002),
    # which is exact for a linear profile: reached 9e-10 of U on 16 cells (bound: 1 %).
    U, H = 1.0, 0.83
    f, y = _plate_couette(16, U=U, H=H)
    fluid = y < H
    assert fluid.sum() >= 13
    np.testing.assert_allclose(f.u[3, fluid], U * y[fluid] / H, rtol=0, atol=0.01 * U)
    assert np.max(np.abs(f.u[:, fluid] - f.u[3:4, fluid])) < 1e-9  # uniform in x (CG tolerance)
    # covered faces carry the plate's velocity
    np.testing.assert_allclose(f.u[:, ~fluid], U, rtol=1e-6)  # (Motion: finite-difference velocity)


def test_viscous_force_on_the_sliding_plate_is_mu_u_over_h():
    # Shear stress of plane Couette flow on the moving plate: tau = -mu U / H per unit area (it drags
    # the plate back), here times the plate length 8 h (2-D: per unit depth). Reached 1e-8 relative
    # (bound 2 %); no normal force.
    U, nu, H = 1.0, 1.0, 0.83
    f, _ = _plate_couette(16, U=U, nu=nu, H=H)
    length = 8 * f.grid.cell_size
    F = f.obstacle_viscous_force[0]
    assert F[0] == pytest.approx(-nu * 1.0 * U / H * length, rel=0.02)
    assert abs(F[1]) < 1e-9


def _cylinder_in_channel(n, slip):
    # Stokes-like flow (Re = U D / nu = 0.4) past a cylinder of radius 0.2 in a 2 x 1 channel
    f = GridFluid((2 * n, n), 1.0 / n, boundaries={"x-": Inflow(velocity=(1.0, 0.0)), "x+": Outflow(),
                                                   "y-": "slip", "y+": "slip"},
                  viscosity=1.0, obstacles=[Sphere(center=(0.8, 0.5), radius=0.2)],
                  obstacle_slip=slip, scalars=())
    for _ in range(30):   # t = 1.5, near steady (the wall value changes < 1 % over the last 0.5 s)
        f.step(0.05)
    ang = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    tangent = np.stack([-np.sin(ang), np.cos(ang)], axis=1)
    pts = np.array([0.8, 0.5]) + 0.2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    return np.max(np.abs(np.sum(f.sample_velocity(pts) * tangent, axis=1)))


def test_no_slip_cylinder_has_zero_tangential_velocity_on_its_wall():
    # On the wall of a no-slip cylinder the tangential velocity vanishes up to the interpolation
    # error of the linear sampler across the surface (nodes inside the solid hold the solid's
    # velocity; the error is ~ h/2 times the wall shear, first order), so it shrinks with h:
    # reached 0.38 (16 cells per unit; the wall shear is ~ 15 U / m here) and 0.17 (32) of the
    # inflow speed; a slip cylinder keeps 1.19 U there (same sampler).
    slip = _cylinder_in_channel(16, True)
    coarse = _cylinder_in_channel(16, False)
    fine = _cylinder_in_channel(32, False)
    assert slip > 1.0
    assert coarse < 0.45 and fine < 0.2
    assert fine < 0.55 * coarse   # at least first order in h (measured ratio 0.43)


def test_obstacle_slip_flags_are_checked():
    with pytest.raises(ValueError, match="obstacle_slip"):
        GridFluid((8, 8), 1 / 8, obstacles=[Sphere(center=(0.5, 0.5), radius=0.2)],
                  obstacle_slip=[True, False])
