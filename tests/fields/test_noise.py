"""Gradient noise (src/inertia/fields/noise.py): statistics, range, seeds, analytic derivatives."""

import numpy as np
import pytest

import inertia as ia
from inertia.fields import Noise

KINDS = ["simplex", "perlin"]
# (spatial dim, time_frequency): lattices of 2, 3 and 4 axes, with and without time.
SHAPES = [(2, 0.0), (2, 0.7), (3, 0.0), (3, 0.7), (4, 0.0)]


def _points(dim, count, scale=8.0, seed=0):
    return np.random.default_rng(seed).uniform(-scale, scale, (count, dim))


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dim,tf", SHAPES)
def test_statistics_and_documented_range(kind, dim, tf):
    # Over many lattice cells the mean is ~0 (every gradient has its opposite in the table) and
    # every value lies in the documented range [-amplitude, amplitude] (a proven bound).
    amplitude = 2.5
    noise = Noise(dim, seed=11, kind=kind, frequency=1.3, octaves=2, amplitude=amplitude,
                  time_frequency=tf)
    values = noise(_points(dim, 200_000, scale=40.0), t=3.0)
    std = values.std()
    assert noise.range == (-amplitude, amplitude)
    assert np.all(np.abs(values) <= amplitude)
    assert abs(values.mean()) < 0.02 * amplitude
    # Documented standard deviations: 0.12-0.54 of the bound depending on kind, axes, octaves.
    assert 0.08 * amplitude < std < 0.6 * amplitude
    # The range is used, not just bounded: the extremes reach a good fraction of it.
    assert np.abs(values).max() > 0.4 * amplitude


@pytest.mark.parametrize("kind", KINDS)
def test_single_octave_bound_is_tight_but_never_exceeded(kind):
    # One octave, 1e6 points in a small region (many samples per cell): |n| <= 1.
    for dim in (2, 3):
        noise = Noise(dim, seed=5, kind=kind)
        values = noise(_points(dim, 1_000_000, scale=6.0, seed=2))
        assert np.abs(values).max() <= 1.0
        assert np.abs(values).max() > 0.6


@pytest.mark.parametrize("kind", KINDS)
def test_same_seed_same_field_different_seed_differs(kind):
    pts = _points(3, 5000)
    a = Noise(3, seed=7, kind=kind, octaves=3, time_frequency=0.5)(pts, 1.25)
    b = Noise(3, seed=7, kind=kind, octaves=3, time_frequency=0.5)(pts, 1.25)
    c = Noise(3, seed=8, kind=kind, octaves=3, time_frequency=0.5)(pts, 1.25)
    np.testing.assert_array_equal(a, b)
    # Different seeds: essentially uncorrelated fields.
    assert abs(np.corrcoef(a, c)[0, 1]) < 0.1
    assert np.abs(a - c).max() > 0.1


def test_time_axis():
    pts = _points(3, 2000)
    steady = Noise(3, seed=1)
    np.testing.assert_array_equal(steady(pts, 0.0), steady(pts, 5.0))
    moving = Noise(3, seed=1, time_frequency=0.5)
    assert np.abs(moving(pts, 0.0) - moving(pts, 2.0)).max() > 0.1
    # Continuous in time: a small step in t changes the field a little.
    assert np.abs(moving(pts, 1.0) - moving(pts, 1.0 + 1e-6)).max() < 1e-5


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dim,tf", SHAPES)
def test_gradient_and_hessian_match_finite_differences(kind, dim, tf):
    # Central differences: f'(x) = (f(x+h) - f(x-h)) / 2h + O(h^2 f'''); with h = 1e-5 and
    # lattice frequency ~2 the truncation is ~1e-9 relative, rounding ~1e-11 / h = 1e-6 absolute
    # on values of order 1, so 1e-6 relative to the largest derivative is the expected level.
    noise = Noise(dim, seed=3, kind=kind, frequency=1.7, octaves=3, time_frequency=tf)
    pts = _points(dim, 3000, scale=3.0)
    t = 0.3
    h = 1e-5
    grad = noise.gradient(pts, t)
    hess = noise.hessian(pts, t)
    eye = np.eye(dim)
    grad_fd = np.stack([(noise(pts + h * eye[k], t) - noise(pts - h * eye[k], t)) / (2 * h)
                        for k in range(dim)], axis=1)
    hess_fd = np.stack([(noise.gradient(pts + h * eye[k], t) - noise.gradient(pts - h * eye[k], t)) / (2 * h)
                        for k in range(dim)], axis=2)
    assert np.abs(grad - grad_fd).max() <= 1e-6 * np.abs(grad).max()
    # Perlin's Hessian is only continuous across cell faces (the fade's third derivative
    # jumps by 60 f^3 per unit f), so differences that straddle a face are first order: error
    # ~ h * jump ~ 1e-4 relative at the top octave (f ~ 7); a wrong formula gives O(1).
    hess_tol = 1e-6 if kind == "simplex" else 5e-4
    assert np.abs(hess - hess_fd).max() <= hess_tol * np.abs(hess).max()
    # The Hessian is symmetric (exactly, up to rounding).
    assert np.abs(hess - hess.transpose(0, 2, 1)).max() <= 1e-12 * np.abs(hess).max()


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dim,tf", SHAPES)
def test_unrolled_and_general_kernels_agree(kind, dim, tf):
    # Values and gradients come from the unrolled kernels (order 1) and, when a Hessian is
    # asked for, from the general D-dimensional kernels; both evaluate the same noise.
    noise = Noise(dim, seed=9, kind=kind, frequency=2.1, octaves=2, time_frequency=tf)
    pts = _points(dim, 4000)
    from inertia.fields import kernels as K
    p = noise.params
    value2 = np.empty(len(pts))
    grad2 = np.empty_like(pts)
    hess2 = np.empty((len(pts), dim, dim))
    K.fractal_noise(pts, noise._offsets, noise._perm, noise._grads, value2, grad2, hess2, 0.4,
                    p.kind_code, 2, p.frequency, p.lacunarity, p.gain, p.octaves,
                    p.time_frequency, noise._scale)
    np.testing.assert_allclose(noise(pts, 0.4), value2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(noise.gradient(pts, 0.4), grad2, rtol=0, atol=1e-10)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("lattice_dim", [2, 3, 4])
def test_noise_is_continuous_across_cells(kind, lattice_dim):
    # A kernel that reached past its simplex (Gustavson's r^2 = 0.6 in 3-D/4-D) or a wrong
    # corner would make jumps; a continuous C^1 noise changes by at most |grad| * step.
    noise = Noise(lattice_dim, seed=4, kind=kind, frequency=1.0)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-20, 20, (200_000, lattice_dim))
    step = 1e-9 * rng.normal(size=pts.shape)
    jump = np.abs(noise(pts + step) - noise(pts))
    slope = np.abs(noise.gradient(pts)).sum(axis=1) * np.abs(step).max(axis=1)
    assert np.all(jump <= slope + 1e-13)
    gjump = np.abs(noise.gradient(pts + step) - noise.gradient(pts)).max()
    assert gjump < 1e-6


def test_fractal_octaves_and_frequency():
    pts = _points(2, 20000, scale=5.0)
    one = Noise(2, seed=2, frequency=1.0)
    # frequency scales space: N_f(x) = N_1(f x) for a single octave (same offsets).
    twice = Noise(2, seed=2, frequency=2.0)
    np.testing.assert_allclose(twice(pts / 2.0), one(pts), atol=1e-12)
    # More octaves add finer detail. With gain 1/2 and lacunarity 2 the octaves' gradients are
    # equal while their values halve, so rms|grad N| / rms N grows ~ sqrt(4) / sqrt(1 + 1/4 +
    # 1/16 + 1/64) = 1.74 times from one octave to four.
    rough = Noise(2, seed=2, frequency=1.0, octaves=4, gain=0.5, lacunarity=2.0)

    def roughness(n):
        return np.sqrt(np.mean(np.sum(n.gradient(pts) ** 2, axis=1)) / np.mean(n(pts) ** 2))

    assert 1.4 < roughness(rough) / roughness(one) < 2.1


def test_sample_fills_preallocated_arrays():
    noise = Noise(3, seed=1)
    pts = _points(3, 100)
    out = np.empty(100)
    noise.sample(pts, 0.0, out)
    np.testing.assert_array_equal(out, noise(pts))
    value, grad = np.empty(100), np.empty((100, 3))
    noise.sample_with_gradient(pts, 0.0, value, grad)
    np.testing.assert_array_equal(grad, noise.gradient(pts))
    with pytest.raises(ValueError, match="out"):
        noise.sample(pts, 0.0, np.empty(99))


@pytest.mark.parametrize("kwargs,name", [
    (dict(dim=5), "dim"),
    (dict(dim=3, kind="value"), "kind"),
    (dict(dim=3, seed=-1), "seed"),
    (dict(dim=3, seed=1.5), "seed"),
    (dict(dim=3, octaves=0), "octaves"),
    (dict(dim=3, frequency=0.0), "frequency"),
    (dict(dim=3, lacunarity=-2.0), "lacunarity"),
    (dict(dim=3, gain=0.0), "gain"),
    (dict(dim=3, amplitude=-1.0), "amplitude"),
    (dict(dim=3, time_frequency=-1.0), "time_frequency"),
    (dict(dim=4, time_frequency=1.0), "time_frequency"),
])
def test_validation_names_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Noise(**kwargs)


def test_points_are_validated():
    noise = Noise(3)
    with pytest.raises(ValueError, match="points"):
        noise(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        noise(np.full((2, 3), np.nan))


def test_public_names():
    assert ia.fields.Noise is Noise
    for name in ia.fields.__all__:
        assert hasattr(ia.fields, name)


@pytest.mark.parametrize("D", [3, 4])
def test_component_gradient_tables_are_balanced_and_uncorrelated(D):
    # 3-D curl-noise's three potentials share the lattice and differ only in these tables.
    # Independent noises need, over the 256 hashes: zero mean per table (E[n_c] = 0) and zero
    # covariance between tables (then E[n_a n_b] = sum_corners W^2 d^T E[g_a g_b^T] d = 0);
    # the construction makes both exact (rounding only), and every entry is a lattice
    # gradient of unit length (so the range bound of noise.py still holds).
    from inertia.fields.noise import _GRADIENTS, component_gradients
    T = component_gradients(7, 3, D)
    assert T.shape == (3, 256, D)
    np.testing.assert_array_equal(T[0], _GRADIENTS[D][np.arange(256) % len(_GRADIENTS[D])])
    np.testing.assert_allclose(np.linalg.norm(T, axis=2), 1.0, rtol=1e-15)
    assert np.abs(T.sum(axis=1)).max() < 1e-12
    for a, b in ((0, 1), (0, 2), (1, 2)):
        assert np.abs(T[a].T @ T[b]).max() < 1e-12
        assert np.mean(np.all(T[a] == T[b], axis=1)) < 0.2  # not the same table
    # Different seeds give different tables 1 and 2; the same seed the same.
    np.testing.assert_array_equal(component_gradients(7, 3, D), T)
    assert np.any(component_gradients(8, 3, D)[1] != T[1])


@pytest.mark.parametrize("D", [3, 4])
def test_gradient_codes_decode_to_the_tables(D):
    # 3-D curl-noise (simplex and Perlin) reads its gradients as 2-bit codes (kernels.*_block):
    # entry (c, k) of the corner reached through perm[x] is u * (((codes[x] >> (8 c + 2 k)) & 3) - 1),
    # u the tables' one nonzero magnitude (1/sqrt(D - 1)). Decoding every code must give back
    # table[perm[x]] exactly, and entries the table lacks (k = 3 in 3-D) must decode to 0.
    from inertia.fields.noise import component_gradients, gradient_codes, lattice_tables
    perm, _ = lattice_tables(5, 1, 1)
    table = np.ascontiguousarray(component_gradients(5, 3, D).transpose(1, 0, 2))  # (256, 3, D)
    codes = gradient_codes(table, perm)
    assert codes.shape == (512,) and codes.dtype == np.int64
    u = 1.0 / np.sqrt(D - 1.0)
    shifts = 8 * np.arange(3)[:, None] + 2 * np.arange(4)[None, :]
    decoded = u * (((codes[:, None, None] >> shifts) & 3) - 1)  # (512, 3, 4)
    np.testing.assert_array_equal(decoded[:, :, :D], table[perm])
    assert np.all(decoded[:, :, D:] == 0.0)
    with pytest.raises(ValueError, match="0 or \\+-u"):
        gradient_codes(table * np.linspace(1.0, 2.0, 256)[:, None, None], perm)
