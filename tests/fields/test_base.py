"""Field arithmetic (src/inertia/fields/base.py): sums and scalings."""

import numpy as np
import pytest

from inertia.fields import CurlNoise, Field, Scaled, Source, Sum, Uniform, Vortex


def test_sums_and_scalings():
    pts = np.random.default_rng(0).uniform(-1, 1, (500, 3))
    a = CurlNoise(dim=3, seed=1)
    b = Uniform((1.0, 0.0, -2.0))
    c = Vortex((0.0, 0.0, 0.0), 1.5)
    combo = 2.0 * a + b - c / 4.0
    np.testing.assert_allclose(combo(pts, 0.5), 2.0 * a(pts, 0.5) + b(pts) - c(pts) / 4.0, atol=1e-14)
    assert isinstance(combo, Sum) and len(combo.fields) == 3  # flattened
    np.testing.assert_allclose((-a)(pts), -a(pts))
    np.testing.assert_allclose(sum([a, b, c])(pts), a(pts) + b(pts) + c(pts), atol=1e-14)
    # Nested scalings fold into one.
    s = 3.0 * (2.0 * b)
    assert isinstance(s, Scaled) and s.factor == 6.0 and s.field is b
    # Jacobians add and scale too.
    np.testing.assert_allclose(combo.jacobian(pts, 0.5),
                               2.0 * a.jacobian(pts, 0.5) - c.jacobian(pts) / 4.0, atol=1e-12)


def test_sum_of_divergence_free_fields_is_divergence_free():
    pts = np.random.default_rng(1).uniform(-1, 1, (1000, 3))
    flow = CurlNoise(dim=3, seed=2, octaves=2) + 0.5 * Vortex((0.0, 0.2, 0.0), 1.0, axis=(0, 1, 0))
    assert np.abs(flow.divergence(pts)).max() < 1e-12


def test_sample_reuses_buffers():
    pts = np.random.default_rng(2).uniform(-1, 1, (100, 2))
    flow = Uniform((1.0, 0.0)) + Source((0.0, 0.0), 1.0)
    out = np.empty_like(pts)
    flow.sample(pts, 0.0, out)
    scratch = flow._scratch
    flow.sample(pts, 0.1, out)
    assert flow._scratch is scratch
    np.testing.assert_allclose(out, flow(pts))


def test_errors():
    with pytest.raises(ValueError, match="dim"):
        Uniform((1.0, 0.0)) + Uniform((1.0, 0.0, 0.0))
    with pytest.raises(TypeError):
        Uniform((1.0, 0.0)) + "wind"
    with pytest.raises(TypeError):
        Uniform((1.0, 0.0)) * np.ones(2)
    with pytest.raises(ValueError, match="divisor"):
        Uniform((1.0, 0.0)) / 0
    with pytest.raises(ValueError, match="factor"):
        Scaled(Uniform((1.0, 0.0)), np.inf)
    with pytest.raises(ValueError, match="fields"):
        Sum([])
    with pytest.raises(NotImplementedError):
        Field().sample_jacobian(np.zeros((1, 3)), 0.0, np.zeros((1, 3, 3)))
