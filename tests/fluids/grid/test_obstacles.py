"""Face fractions (inertia.fluids.grid.obstacles) against exact areas, and the variational
weights (Batty, Bertails and Bridson 2007) making a curved wall smooth."""

import numpy as np

from inertia.colliders import Sphere
from inertia.fluids.grid import GridFluid
from inertia.fluids.grid.obstacles import segment_fraction, square_fraction


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
