"""Sampled grids (src/inertia/fields/grid.py): multilinear interpolation."""

import numpy as np
import pytest

from inertia.fields import CurlNoise, Grid, Vortex


def _linear_values(shape, origin, spacing, A, b):
    """Node values of the linear field v(x) = A x + b, which multilinear interpolation
    reproduces exactly."""
    dim = len(shape)
    axes = [origin[k] + spacing[k] * np.arange(shape[k]) for k in range(dim)]
    x = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return x @ A.T + b


@pytest.mark.parametrize("dim", [2, 3])
def test_linear_fields_are_reproduced_exactly(dim):
    rng = np.random.default_rng(0)
    A, b = rng.normal(size=(dim, dim)), rng.normal(size=dim)
    shape, origin, spacing = (5, 7, 6)[:dim], np.array([-1.0, 0.5, 0.2][:dim]), np.array([0.3, 0.2, 0.25][:dim])
    grid = Grid(_linear_values(shape, origin, spacing, A, b), origin=origin, spacing=spacing)
    pts = origin + rng.uniform(0, 1, (2000, dim)) * (np.array(shape) - 1) * spacing
    np.testing.assert_allclose(grid(pts), pts @ A.T + b, atol=1e-12)
    # Jacobian of a linear field is A everywhere inside.
    np.testing.assert_allclose(grid.jacobian(pts), np.broadcast_to(A, (2000, dim, dim)), atol=1e-11)
    np.testing.assert_allclose(grid.upper, origin + (np.array(shape) - 1) * spacing)


def test_nodes_exact_outside_clamped_or_zero():
    values = np.random.default_rng(1).normal(size=(4, 5, 3, 3))
    grid = Grid(values, origin=(0.0, 0.0, 0.0), spacing=0.5)
    i, j, k = np.meshgrid(range(4), range(5), range(3), indexing="ij")
    nodes = np.stack([i, j, k], -1).reshape(-1, 3) * 0.5
    np.testing.assert_allclose(grid(nodes), values.reshape(-1, 3), atol=1e-14)
    # Outside: clamped to the nearest boundary node (here the corner), or zero.
    far = np.array([[-3.0, -3.0, -3.0], [10.0, 10.0, 10.0]])
    np.testing.assert_allclose(grid(far), [values[0, 0, 0], values[-1, -1, -1]])
    np.testing.assert_array_equal(grid.jacobian(far), 0.0)
    zero = Grid(values, spacing=0.5, outside="zero")
    np.testing.assert_array_equal(zero(far), 0.0)


def test_from_field_converges_quadratically():
    # Bilinear interpolation error is O(h^2): doubling the resolution divides it by ~4.
    vortex = Vortex((0.05, -0.1), 1.0, core_radius=0.3)
    pts = np.random.default_rng(2).uniform(-1, 1, (5000, 2))
    errors = []
    for n in (21, 41, 81):
        grid = Grid.from_field(vortex, (-1.0, -1.0), (1.0, 1.0), (n, n))
        errors.append(np.abs(grid(pts) - vortex(pts)).max())
    assert errors[1] < errors[0] / 3.2 and errors[2] < errors[1] / 3.2
    # Baking curl-noise works for 3-D fields too.
    noise = CurlNoise(dim=3, seed=1)
    baked = Grid.from_field(noise, (0, 0, 0), (1, 1, 1), (33, 33, 33), t=0.0)
    q = np.random.default_rng(3).uniform(0, 1, (1000, 3))
    assert np.abs(baked(q) - noise(q)).max() < 0.05 * np.abs(noise(q)).max()


def test_jacobian_matches_finite_differences_inside_cells():
    values = np.random.default_rng(4).normal(size=(6, 6, 2))
    grid = Grid(values, origin=(0.0, 0.0), spacing=0.2)
    pts = np.random.default_rng(5).uniform(0.01, 0.99, (3000, 2))
    eye = np.eye(2)
    fd = np.stack([(grid(pts + 1e-7 * eye[k]) - grid(pts - 1e-7 * eye[k])) / 2e-7 for k in range(2)], axis=2)
    # Away from cell faces (where the piecewise-linear derivative jumps) they agree.
    frac = (pts / 0.2) % 1.0
    inside = np.all((frac > 1e-5) & (frac < 1 - 1e-5), axis=1)
    np.testing.assert_allclose(grid.jacobian(pts)[inside], fd[inside], atol=1e-6)


@pytest.mark.parametrize("kwargs,name", [
    (dict(values=np.zeros((4, 4, 3))), "values"),
    (dict(values=np.zeros((1, 4, 2))), "values"),
    (dict(values=np.full((3, 3, 2), np.nan)), "values"),
    (dict(values=np.zeros((3, 3, 2)), spacing=0.0), "spacing"),
    (dict(values=np.zeros((3, 3, 2)), spacing=(1.0, 2.0, 3.0)), "spacing"),
    (dict(values=np.zeros((3, 3, 2)), origin=(0.0, 0.0, 0.0)), "origin"),
    (dict(values=np.zeros((3, 3, 2)), outside="wrap"), "outside"),
])
def test_validation(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Grid(**kwargs)
