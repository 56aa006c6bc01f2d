"""Analytic flow primitives (src/inertia/fields/analytic.py) against their closed forms."""

import numpy as np
import pytest

import inertia as ia
from inertia.fields import Sink, Source, Uniform, Vortex


def _circle(center, radius, count, axis=None):
    """Points on a circle and the unit tangents (counter-clockwise about axis / z)."""
    s = 2 * np.pi * (np.arange(count) + 0.5) / count
    if axis is None:
        pts = np.asarray(center) + radius * np.stack([np.cos(s), np.sin(s)], 1)
        tangents = np.stack([-np.sin(s), np.cos(s)], 1)
        return pts, tangents
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    u = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    pts = np.asarray(center) + radius * (np.cos(s)[:, None] * u + np.sin(s)[:, None] * w)
    tangents = -np.sin(s)[:, None] * u + np.cos(s)[:, None] * w
    return pts, tangents


@pytest.mark.parametrize("dim", [2, 3])
def test_vortex_circulation_closed_form(dim):
    # Circulation around a circle of radius R about the axis:
    #   oint v . dl = Gamma R^2 / (R^2 + rc^2)   (-> Gamma for R >> rc)
    gamma, rc, R = 2.5, 0.2, 0.7
    if dim == 2:
        vortex = Vortex((0.3, -0.1), gamma, core_radius=rc)
        pts, tangents = _circle((0.3, -0.1), R, 2000)
    else:
        axis = (1.0, 2.0, 2.0)
        vortex = Vortex((0.3, -0.1, 0.2), gamma, axis=axis, core_radius=rc)
        pts, tangents = _circle((0.3, -0.1, 0.2), R, 2000, axis=axis)
        pts = pts + 5.0 * np.asarray(axis) / 3.0  # anywhere along the (infinite) line
    v = vortex(pts)
    circulation = np.sum(np.sum(v * tangents, axis=1)) * (2 * np.pi * R / len(pts))
    assert circulation == pytest.approx(gamma * R**2 / (R**2 + rc**2), rel=1e-12)
    # Purely swirling: no radial component.
    radial = np.cross(tangents, np.asarray(axis) / 3.0) if dim == 3 else np.stack([tangents[:, 1], -tangents[:, 0]], 1)
    assert np.abs(np.sum(v * radial, axis=1)).max() < 1e-12


@pytest.mark.parametrize("dim", [2, 3])
def test_source_flux_closed_form(dim):
    # Flux through a sphere (circle) of radius R around the source:
    #   3-D: Q R^3 / (R^2 + rc^2)^(3/2),  2-D: Q R^2 / (R^2 + rc^2)
    Q, rc, R = 1.7, 0.1, 0.5
    center = np.array([0.2, -0.3, 0.1][:dim])
    source = Source(center, Q, core_radius=rc)
    if dim == 2:
        pts, tangents = _circle(center, R, 4000)
        normals = np.stack([tangents[:, 1], -tangents[:, 0]], 1)
        flux = np.sum(np.sum(source(pts) * normals, axis=1)) * 2 * np.pi * R / len(pts)
        assert flux == pytest.approx(Q * R**2 / (R**2 + rc**2), rel=1e-12)
    else:
        normals = np.random.default_rng(0).normal(size=(200_000, 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        vn = np.sum(source(center + R * normals) * normals, axis=1)
        # Uniform radial field: every sample is the same, so the Monte Carlo flux is exact.
        assert np.ptp(vn) < 1e-12
        assert vn.mean() * 4 * np.pi * R**2 == pytest.approx(Q * R**3 / (R**2 + rc**2) ** 1.5, rel=1e-12)
    # A sink is a source of opposite sign.
    sink = Sink(center, Q, core_radius=rc)
    probe = center + 0.3
    np.testing.assert_allclose(sink(probe[None]), -source(probe[None]))


@pytest.mark.parametrize("dim", [2, 3])
def test_jacobians_match_finite_differences_and_vortex_is_divergence_free(dim):
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, (3000, dim))
    fields = [Uniform(np.arange(1.0, dim + 1.0)),
              Vortex(np.zeros(dim) + 0.1, 2.0, core_radius=0.2,
                     **({} if dim == 2 else {"axis": (1.0, -2.0, 0.5)})),
              Source(np.zeros(dim), 3.0, core_radius=0.2), Sink(np.zeros(dim) + 0.2, 1.0)]
    eye = np.eye(dim)
    for f in fields:
        jac = f.jacobian(pts)
        fd = np.stack([(f(pts + 1e-6 * eye[k]) - f(pts - 1e-6 * eye[k])) / 2e-6 for k in range(dim)], axis=2)
        assert np.abs(jac - fd).max() <= 1e-7 * max(np.abs(jac).max(), 1.0)
    # div v = 0 for the vortex (exactly, to rounding).
    assert np.abs(fields[1].divergence(pts)).max() < 1e-12


def test_uniform_and_validation():
    u = Uniform((1.0, 2.0, 3.0))
    np.testing.assert_array_equal(u(np.zeros((4, 3))), np.tile([1.0, 2.0, 3.0], (4, 1)))
    with pytest.raises(ValueError, match="velocity"):
        Uniform((1.0, np.nan))
    with pytest.raises(ValueError, match="core_radius"):
        Vortex((0.0, 0.0), 1.0, core_radius=0.0)
    with pytest.raises(ValueError, match="axis"):
        Vortex((0.0, 0.0), 1.0, axis=(1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="axis"):
        Vortex((0.0, 0.0, 0.0), 1.0, axis=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="strength"):
        Source((0.0, 0.0), "lots")
    with pytest.raises(ValueError, match="center"):
        Source((0.0, 0.0, 0.0, 0.0))


def test_primitives_drive_tracers():
    # A tracer in a point vortex circles at constant radius: |x - c| is conserved, and RK4 keeps
    # it to O(dt^4) (here ~1e-10 over one revolution).
    gamma, rc, R = 1.0, 0.05, 0.5
    vortex = ia.fields.Vortex((0.0, 0.0), gamma, core_radius=rc)
    tracers = ia.Tracers([[R, 0.0]], vortex)
    speed = gamma / (2 * np.pi) * R / (R**2 + rc**2)
    period = 2 * np.pi * R / speed
    sim = ia.Simulation(tracers, integrator="rk4", dt=period / 400)
    sim.run(period)
    assert np.linalg.norm(tracers.x[0]) == pytest.approx(R, abs=1e-9)
    np.testing.assert_allclose(tracers.x[0], [R, 0.0], atol=1e-6)


def test_rotation_paths_are_circles_and_divergence_free():
    """v = omega x (x - c): |v| = |omega| r, v . (x - c) = 0, div v = trace(J) = 0 exactly."""
    import inertia as ia
    rng = np.random.default_rng(2)
    p2 = rng.uniform(-2, 2, (50, 2))
    rot2 = ia.fields.Rotation((0.5, -0.5), 2.0)
    v2 = rot2(p2, 0.0)
    r2 = p2 - [0.5, -0.5]
    np.testing.assert_allclose(np.linalg.norm(v2, axis=1), 2.0 * np.linalg.norm(r2, axis=1), rtol=1e-14)
    np.testing.assert_allclose(np.einsum("ij,ij->i", v2, r2), 0.0, atol=1e-12)
    p3 = rng.uniform(-2, 2, (50, 3))
    rot3 = ia.fields.Rotation((0, 0, 0), (0.0, 0.0, 1.5))
    np.testing.assert_allclose(rot3(p3, 0.0)[:, :2], 1.5 * np.stack([-p3[:, 1], p3[:, 0]], 1), rtol=1e-14)
    np.testing.assert_allclose(rot3.divergence(p3, 0.0), 0.0, atol=1e-15)
    with pytest.raises(ValueError, match="angular_velocity"):
        ia.fields.Rotation((0, 0, 0), 1.0)
