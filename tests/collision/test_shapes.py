"""Shapes: signed distances against closed forms, normals, surface velocities, bad input."""

import numpy as np
import pytest

import inertia as ia

C = ia.colliders
rng = np.random.default_rng(7)


def _pts(n=200, dim=3, scale=2.0):
    return rng.uniform(-scale, scale, size=(n, dim))


def _fd_gradient(collider, p, h=1e-6):
    g = np.zeros_like(p)
    for c in range(p.shape[1]):
        e = np.zeros(p.shape[1])
        e[c] = h
        g[:, c] = (collider.signed_distance(p + e) - collider.signed_distance(p - e)) / (2 * h)
    return g


def test_plane_distance_is_n_dot_x_minus_c():
    # phi(x) = n.(x - p) with n normalised
    col = C.Plane(point=(0, 0, 1), normal=(0, 3, 4))
    p = _pts()
    n = np.array([0, 0.6, 0.8])
    np.testing.assert_allclose(col.signed_distance(p), (p - [0, 0, 1]) @ n, atol=1e-14)
    np.testing.assert_allclose(col.normal(p), np.broadcast_to(n, p.shape), atol=1e-14)


def test_sphere_and_circle_distance():
    # phi(x) = |x - c| - R, in 3-D and 2-D (a circle)
    for dim in (2, 3):
        c = np.arange(dim) * 0.1
        col = C.Sphere(center=c, radius=0.7)
        p = _pts(dim=dim)
        np.testing.assert_allclose(col.signed_distance(p), np.linalg.norm(p - c, axis=1) - 0.7, atol=1e-14)


@pytest.mark.parametrize("dim", [2, 3])
def test_box_distance_matches_closed_form(dim):
    # phi = |max(q, 0)| + min(max_i q_i, 0), q = |R^T (x - c)| - h  (exact box distance)
    h = np.array([0.3, 0.5, 0.7])[:dim]
    c = np.array([0.1, -0.2, 0.3])[:dim]
    rot = 0.4 if dim == 2 else np.array([0.2, -0.5, 0.3])
    col = C.Box(center=c, half_extents=h, rotation=rot)
    r = ia.colliders.as_rotation(rot, dim)[:dim, :dim]
    p = _pts(dim=dim)
    q = np.abs((p - c) @ r) - h
    expected = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
    np.testing.assert_allclose(col.signed_distance(p), expected, atol=1e-13)
    # the normal is the gradient of the distance (away from edges and the medial axis)
    d = col.signed_distance(p)
    smooth = np.abs(d) > 0.05
    np.testing.assert_allclose(col.normal(p)[smooth], _fd_gradient(col, p[smooth]), atol=1e-5)


def test_capsule_and_cylinder_distances():
    a, b, r = np.array([0, 0, -0.5]), np.array([0.2, 0, 0.5]), 0.3
    cap = C.Capsule(a=a, b=b, radius=r)
    p = _pts()
    s = np.clip(((p - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
    closest = a + s[:, None] * (b - a)
    np.testing.assert_allclose(cap.signed_distance(p), np.linalg.norm(p - closest, axis=1) - r, atol=1e-13)

    cyl = C.Cylinder(center=(0, 0, 0), radius=0.5, half_height=0.4, axis=(0, 0, 2))
    rho = np.linalg.norm(p[:, :2], axis=1)
    dr, dh = rho - 0.5, np.abs(p[:, 2]) - 0.4
    expected = np.where((dr > 0) & (dh > 0), np.hypot(dr, dh), np.maximum(dr, dh))
    np.testing.assert_allclose(cyl.signed_distance(p), expected, atol=1e-13)
    smooth = np.abs(expected) > 0.05
    np.testing.assert_allclose(cyl.normal(p)[smooth], _fd_gradient(cyl, p[smooth]), atol=1e-5)


@pytest.mark.parametrize("dim", [2, 3])
def test_container_is_the_inside_of_a_box(dim):
    # free space inside: phi = min_i (distance to wall i) = -(box distance) for interior points
    h = np.array([1.0, 0.5, 0.8])[:dim]
    cont = C.Container(center=np.zeros(dim), half_extents=h)
    box = C.Box(center=np.zeros(dim), half_extents=h)
    p = rng.uniform(-1, 1, size=(300, dim)) * h
    np.testing.assert_allclose(cont.signed_distance(p), -box.signed_distance(p), atol=1e-14)
    assert np.all(cont.signed_distance(p * 1.5)[np.any(np.abs(p * 1.5) > h, axis=1)] < 0)


def test_moving_collider_pose_and_velocity():
    # x(t) = p(t) + R(t)(X - c): a sphere moving at (1, 2, 0) m/s and a box spinning at 3 rad/s about z
    sph = C.Sphere(center=(0, 0, 0), radius=0.5, motion=lambda t: (1.0 * t, 2.0 * t, 0.0))
    p = np.array([[2.0, 4.0, 0.0]])
    np.testing.assert_allclose(sph.signed_distance(p, t=2.0), [-0.5], atol=1e-12)
    np.testing.assert_allclose(sph.velocity(p, t=2.0), [[1.0, 2.0, 0.0]], atol=1e-6)
    box = C.Box(center=(0, 0, 0), half_extents=(1, 0.1, 0.1),
                motion=C.Motion(rotation=lambda t: (0.0, 0.0, 3.0 * t)))
    q = np.array([[0.0, 1.0, 0.0]])  # on the y axis: v = w x r = (-3, 0, 0)
    np.testing.assert_allclose(box.velocity(q, t=0.3), [[-3.0, 0.0, 0.0]], atol=1e-6)
    # after a quarter turn the long axis lies along y
    np.testing.assert_allclose(box.signed_distance(np.array([[0.0, 0.95, 0.0]]), t=np.pi / 6), [-0.05],
                               atol=1e-9)


def test_keyframes_interpolate_and_hold():
    m = C.Motion.keyframes([0.0, 1.0], positions=[[0, 0, 0], [0, 0, 2]], rotations=[[0, 0, 0], [0, 0, np.pi / 2]])
    p, r = m.pose(0.5, 3, np.zeros(3))
    np.testing.assert_allclose(p, [0, 0, 1])
    np.testing.assert_allclose(r, C.as_rotation((0, 0, np.pi / 4), 3), atol=1e-12)
    p, r = m.pose(5.0, 3, np.zeros(3))
    np.testing.assert_allclose(p, [0, 0, 2])


def _icosphere(subdivisions=3, radius=1.0):
    trimesh = pytest.importorskip("trimesh")
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def test_mesh_sdf_of_a_sphere():
    # a watertight icosphere: phi ~ |x| - R within the baked grid (3 cells of padding);
    # error: the faceting R (1 - cos(edge angle / 2)) ~ 0.005 plus interpolation O(h^2 / R)
    mesh = C.Mesh(_icosphere(3, 1.0), resolution=40)
    assert mesh.signed and mesh.watertight
    p = rng.uniform(-1.14, 1.14, size=(500, 3))
    err = mesh.signed_distance(p) - (np.linalg.norm(p, axis=1) - 1.0)
    assert np.max(np.abs(err)) < 0.01
    # outside the grid: an upper bound, exact along the axes
    far = np.array([[3.0, 0, 0], [0, -2.5, 0], [2.0, 2.0, 2.0]])
    d = mesh.signed_distance(far)
    np.testing.assert_allclose(d[:2], [2.0, 1.5], atol=0.01)
    assert np.sqrt(12) - 1 - 0.01 <= d[2] <= np.sqrt(12) - 1 + 0.2
    inside = np.linalg.norm(p, axis=1) < 0.9
    assert np.all(mesh.signed_distance(p[inside]) < 0)


def test_mesh_from_file_and_arrays(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1, 2, 3))
    for ext in ("obj", "stl", "ply"):
        path = tmp_path / f"box.{ext}"
        box.export(path)
        mesh = C.Mesh(path, resolution=24)
        np.testing.assert_allclose(mesh.signed_distance(np.array([[0, 0, 0.0], [0, 0, 2.0]])), [-0.5, 0.5],
                                   atol=1e-9)
    arrays = C.Mesh((box.vertices, box.faces), resolution=24)
    assert arrays.signed


def test_open_mesh_warns_and_is_unsigned():
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.warns(UserWarning, match="not watertight"):
        sheet = C.Mesh((v, f), resolution=16)
    assert not sheet.signed
    np.testing.assert_allclose(sheet.signed_distance(np.array([[0.2, 0.1, 0.3], [0.2, 0.1, -0.3]])), [0.3, 0.3],
                               atol=1e-12)
    with pytest.raises(ValueError, match="watertight"):
        C.Mesh((v, f), signed=True)
    C.Mesh((v, f), signed=False)  # explicit: no warning


def test_sdf_callable_and_baked():
    # a user sphere of radius 0.5: phi = |x| - 0.5, gradient by central differences
    def fn(p):
        return np.linalg.norm(p, axis=1) - 0.5

    p = rng.uniform(-1, 1, size=(100, 3))
    exact = np.linalg.norm(p, axis=1) - 0.5
    user = C.SDF(fn)
    np.testing.assert_allclose(user.signed_distance(p), exact, atol=1e-12)
    np.testing.assert_allclose(user.normal(p), p / np.linalg.norm(p, axis=1)[:, None], atol=1e-6)
    baked = C.SDF(fn, bake={"bounds": ((-1.2,) * 3, (1.2,) * 3), "resolution": 48})
    # trilinear interpolation of a sphere: error O(h^2 / R)
    assert np.max(np.abs(baked.signed_distance(p) - exact)) < 0.01


@pytest.mark.parametrize("build, match", [
    (lambda: C.Plane(normal=(0, 0, 0)), "normal must be a non-zero"),
    (lambda: C.Plane(normal=(0, np.nan, 1)), "normal must be finite"),
    (lambda: C.Sphere(radius=-1.0), "radius must be"),
    (lambda: C.Box(half_extents=(1, 0, 1)), "half_extents must all be > 0"),
    (lambda: C.Capsule(radius=0.0), "radius must be"),
    (lambda: C.Cylinder(axis=(0, 0, 0)), "axis must be a non-zero"),
    (lambda: C.Container(half_extents=(1, -1)), "half_extents"),
    (lambda: C.Box(rotation=np.ones((3, 3))), "rotation must be a proper rotation"),
    (lambda: C.SDF(3.0), "function must be a callable"),
    (lambda: C.Plane(motion=5), "motion must be"),
    (lambda: C.Motion.keyframes([0, 0], positions=[[0, 0, 0], [1, 1, 1]]), "strictly increasing"),
])
def test_bad_shapes_raise_value_error_naming_the_argument(build, match):
    with pytest.raises(ValueError, match=match):
        build()
