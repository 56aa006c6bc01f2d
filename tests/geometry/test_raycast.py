"""Tests for inertia.geometry.raycast: rays against analytic hits and against brute-force marching of
closed-form inside tests (refined by bisection), and shape casts against closed-form times of impact."""

import numpy as np
import pytest

from inertia import math as im
from inertia.geometry import raycast as R
from inertia.geometry.convex import build_convex_hull

RNG = np.random.default_rng(77)
SPHERE, BOX, CAPSULE, CYLINDER, HULL, MESH, PLANE = 0, 1, 2, 3, 4, 5, 6
EMPTY_V = np.zeros((1, 3))
EMPTY_F = np.zeros((1, 4))
EMPTY_T = np.zeros((1, 3), dtype=np.int64)


def params(*values):
    out = np.zeros(4)
    out[:len(values)] = values
    return out


def cast(shape_type, par, pose, origin, direction, max_t=np.inf, verts=EMPTY_V, planes=EMPTY_F, nf=0,
         tris=EMPTY_T, nt=0):
    return R.ray_cast(shape_type, par, pose, verts, 0, planes, 0, nf, tris, 0, nt, np.asarray(origin, float),
                      np.asarray(direction, float), max_t)


# closed-form inside tests in the local frame
def inside(shape_type, par, p, planes=None):
    x, y, z = p
    if shape_type == SPHERE:
        return x * x + y * y + z * z <= par[0] ** 2
    if shape_type == BOX:
        return abs(x) <= par[0] and abs(y) <= par[1] and abs(z) <= par[2]
    if shape_type == CAPSULE:
        zc = min(max(z, -par[1]), par[1])
        return x * x + y * y + (z - zc) ** 2 <= par[0] ** 2
    if shape_type == CYLINDER:
        return x * x + y * y <= par[0] ** 2 and abs(z) <= par[1]
    if shape_type == HULL:
        return np.all(planes[:, :3] @ p <= planes[:, 3])
    if shape_type == PLANE:
        return z <= 0
    raise AssertionError


def march(shape_type, par, origin, direction, planes=None, t_max=20.0, steps=20000):
    """First entry by marching in steps of t_max/steps, then 60 bisections; inf if never inside."""
    ts = np.linspace(0.0, t_max, steps + 1)
    prev = 0.0
    for t in ts[1:]:
        if inside(shape_type, par, origin + t * direction, planes):
            lo, hi = prev, t
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if inside(shape_type, par, origin + mid * direction, planes):
                    hi = mid
                else:
                    lo = mid
            return hi
        prev = t
    return np.inf


def random_pose(rng):
    q = rng.normal(size=4)
    return np.concatenate([rng.normal(size=3), q / np.linalg.norm(q)])


def test_analytic_hits():
    # sphere: ray through the centre enters at |c - o| - r, normal -d
    t, n = cast(SPHERE, params(0.5), np.array([1.0, 2.0, 3.0, 1, 0, 0, 0]), [1.0, 2.0, -2.0], [0, 0, 1.0])
    assert t == pytest.approx(4.5, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, -1], atol=1e-15)
    # box face hit at x = -hx
    t, n = cast(BOX, params(0.5, 1.0, 2.0), np.array([0, 0, 0, 1.0, 0, 0, 0]), [-3.0, 0.3, 0.2], [2.0, 0, 0])
    assert t == pytest.approx(1.25, abs=1e-15)  # direction length 2: parameter is distance / 2
    np.testing.assert_array_equal(n, [-1, 0, 0])
    # plane z <= 0 from above at 45 degrees; from below (inside) no hit
    t, n = cast(PLANE, params(), np.array([0, 0, 0, 1.0, 0, 0, 0]), [0, 0, 2.0], [1.0, 0, -1.0])
    assert t == pytest.approx(2.0) and n[2] == 1.0
    assert cast(PLANE, params(), np.array([0, 0, 0, 1.0, 0, 0, 0]), [0, 0, -1.0], [0, 0, -1.0])[0] == np.inf
    # cylinder cap and capsule end cap along the axis
    t, n = cast(CYLINDER, params(1.0, 0.5), np.array([0, 0, 0, 1.0, 0, 0, 0]), [0.3, 0.2, 3.0], [0, 0, -1.0])
    assert t == pytest.approx(2.5) and n[2] == 1.0
    t, n = cast(CAPSULE, params(0.3, 1.0), np.array([0, 0, 0, 1.0, 0, 0, 0]), [0, 0, -5.0], [0, 0, 1.0])
    assert t == pytest.approx(5.0 - 1.3)
    np.testing.assert_allclose(n, [0, 0, -1], atol=1e-15)
    # max_t cuts the ray
    assert cast(SPHERE, params(0.5), np.array([0, 0, 0, 1.0, 0, 0, 0]), [0, 0, -2.0], [0, 0, 1.0], max_t=1.0)[0] \
        == np.inf


@pytest.mark.parametrize("shape_type,par", [(SPHERE, params(0.8)), (BOX, params(0.4, 0.9, 0.6)),
                                            (CAPSULE, params(0.4, 0.7)), (CYLINDER, params(0.7, 0.5)),
                                            (PLANE, params())])
def test_random_rays_against_marching(shape_type, par):
    rng = np.random.default_rng(shape_type)
    hits = 0
    for _ in range(25):
        pose = random_pose(rng)
        origin_local = rng.normal(size=3) * 2.5
        if inside(shape_type, par, origin_local):
            continue
        # aim near the shape so about half the rays hit
        target = rng.normal(size=3) * 0.6
        d_local = target - origin_local
        origin = im.transform_point(pose, origin_local)
        direction = im.quat_rotate(pose[3:], d_local)
        t, n = cast(shape_type, par, pose, origin, direction)
        ref = march(shape_type, par, origin_local, d_local, t_max=3.0, steps=3000)
        if ref == np.inf:
            assert t == np.inf
            continue
        hits += 1
        assert t == pytest.approx(ref, abs=1e-9)
        # the normal is unit, outward (against the ray) and, on flat faces, the face normal
        assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
        assert n @ direction < 0
    assert hits >= 5


def test_convex_hull_rays_against_marching():
    pts = RNG.normal(size=(20, 3))
    hull = build_convex_hull(pts)
    planes = hull.face_planes
    hits = 0
    for _ in range(30):
        pose = random_pose(RNG)
        origin_local = RNG.normal(size=3) * 3
        if inside(HULL, None, origin_local, planes):
            continue
        d_local = RNG.normal(size=3) * 0.5 - origin_local
        t, n = cast(HULL, params(), pose, im.transform_point(pose, origin_local), im.quat_rotate(pose[3:], d_local),
                    planes=planes, nf=planes.shape[0])
        ref = march(HULL, None, origin_local, d_local, planes, t_max=3.0, steps=3000)
        if ref == np.inf:
            assert t == np.inf
            continue
        hits += 1
        assert t == pytest.approx(ref, abs=1e-9)
        # the entry face's plane holds the hit point
        p = origin_local + t * d_local
        n_local = im.quat_rotate_inv(pose[3:], n)
        assert np.min(np.abs(planes[:, :3] @ p - planes[:, 3])) < 1e-9
        assert np.any(np.all(np.abs(planes[:, :3] - n_local) < 1e-12, axis=1))
    assert hits >= 5


def test_triangle_and_mesh():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    # from above and below: two-sided, normal facing the ray
    t, n = R.ray_triangle(np.array([0.2, 0.3, 2.0]), np.array([0, 0, -1.0]), a, b, c)
    assert t == pytest.approx(2.0) and n[2] == 1.0
    t, n = R.ray_triangle(np.array([0.2, 0.3, -1.0]), np.array([0, 0, 1.0]), a, b, c)
    assert t == pytest.approx(1.0) and n[2] == -1.0
    assert R.ray_triangle(np.array([0.8, 0.3, 2.0]), np.array([0, 0, -1.0]), a, b, c)[0] == np.inf
    assert R.ray_triangle(np.array([0.2, 0.3, 2.0]), np.array([1.0, 0, 0]), a, b, c)[0] == np.inf
    # a closed mesh (a box's triangles): the first hit equals the box's slab result
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * [0.4, 0.9, 0.6]
    hull = build_convex_hull(corners)
    tris = hull.triangles.astype(np.int64)
    for _ in range(20):
        pose = random_pose(RNG)
        origin = RNG.normal(size=3) * 3
        direction = RNG.normal(size=3) * 0.3 - origin
        tm, nm = cast(MESH, params(), pose, origin, direction, verts=hull.vertices, tris=tris, nt=tris.shape[0])
        tb, nb = cast(BOX, params(0.4, 0.9, 0.6), pose, origin, direction)
        if tb == np.inf:
            assert tm == np.inf or tm == pytest.approx(0.0)  # a ray starting inside hits the mesh from inside
            continue
        assert tm == pytest.approx(tb, abs=1e-12)
        np.testing.assert_allclose(nm, nb, atol=1e-12)


def test_shape_cast_closed_forms():
    verts = np.zeros((1, 3))
    # a sphere of radius 0.5 swept along +x by 10 towards a sphere of radius 1 at x = 6: contact at x = 4.5
    s, n, p = R.shape_cast(SPHERE, params(0.5), np.array([0, 0, 0, 1.0, 0, 0, 0]), 0, 0, np.array([10.0, 0, 0]),
                           SPHERE, params(1.0), np.array([6.0, 0, 0, 1, 0, 0, 0]), 0, 0, verts, 1e-9, 50)
    assert s * 10 == pytest.approx(4.5, abs=1e-8)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(p, [5.0, 0, 0], atol=1e-8)
    # a box swept diagonally onto a turned box: face contact after closing the known gap along x
    q = im.quat_from_axis_angle(np.array([1.0, 0, 0]), 0.7)
    s, n, p = R.shape_cast(BOX, params(0.5, 0.5, 0.5), np.array([0, 0, 0, 1.0, 0, 0, 0]), 0, 0,
                           np.array([4.0, 0.4, 0.0]), BOX, params(0.5, 0.3, 0.3),
                           np.array([3.0, 0.5, 0.0, *q]), 0, 0, verts, 1e-9, 100)
    # gap along x: 3.0 - 0.5 - 0.5 = 2.0 closed at 4.0 per unit s
    assert s == pytest.approx(0.5, abs=1e-8)
    # moving away: no hit
    s, _, _ = R.shape_cast(SPHERE, params(0.5), np.array([0, 0, 0, 1.0, 0, 0, 0]), 0, 0, np.array([-1.0, 0, 0]),
                           SPHERE, params(1.0), np.array([6.0, 0, 0, 1, 0, 0, 0]), 0, 0, verts, 1e-9, 50)
    assert s == np.inf
    # passing beside: the closest approach is 0.5 + 1 + 0.2 apart, never touching
    s, _, _ = R.shape_cast(SPHERE, params(0.5), np.array([0, 1.7, 0, 1.0, 0, 0, 0]), 0, 0, np.array([12.0, 0, 0]),
                           SPHERE, params(1.0), np.array([6.0, 0, 0, 1, 0, 0, 0]), 0, 0, verts, 1e-9, 100)
    assert s == np.inf
