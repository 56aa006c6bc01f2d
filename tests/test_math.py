"""Tests for inertia.math: quaternion algebra identities, round trips, the exponential map against
scipy.spatial.transform.Rotation, rigid transforms, 3x3 helpers and Featherstone's spatial cross products."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inertia import math as im

RNG = np.random.default_rng(20261123)


def random_unit_quats(n):
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def scipy_rot(q):
    """scipy stores quaternions scalar-last (x, y, z, w)."""
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


def test_cross_dot_skew_match_numpy():
    for _ in range(20):
        a, b = RNG.normal(size=3), RNG.normal(size=3)
        np.testing.assert_allclose(im.cross(a, b), np.cross(a, b), rtol=0, atol=1e-15)
        assert im.dot(a, b) == pytest.approx(np.dot(a, b), abs=1e-15)
        np.testing.assert_allclose(im.skew(a) @ b, np.cross(a, b), rtol=0, atol=1e-15)
        np.testing.assert_allclose(im.skew(a).T, -im.skew(a), rtol=0, atol=0)


def test_mat3_helpers_match_numpy():
    for _ in range(20):
        a, b, v = RNG.normal(size=(3, 3)), RNG.normal(size=(3, 3)), RNG.normal(size=3)
        np.testing.assert_allclose(im.mat3_mul(a, b), a @ b, rtol=0, atol=1e-14)
        np.testing.assert_allclose(im.mat3_vec(a, v), a @ v, rtol=0, atol=1e-14)
        np.testing.assert_array_equal(im.mat3_transpose(a), a.T)
        # a symmetric positive definite matrix (an inertia tensor), well conditioned
        s = a @ a.T + np.eye(3)
        np.testing.assert_allclose(im.mat3_inv_sym(s) @ s, np.eye(3), rtol=0, atol=1e-12)


def test_quaternion_product_is_rotation_composition():
    qa, qb = random_unit_quats(2)
    for _ in range(20):
        qa, qb = random_unit_quats(2)
        v = RNG.normal(size=3)
        # R(a b) v = R(a) R(b) v
        np.testing.assert_allclose(im.quat_rotate(im.quat_mul(qa, qb), v),
                                   im.quat_rotate(qa, im.quat_rotate(qb, v)), rtol=0, atol=1e-14)
        # associativity, q q* = identity
        qc = random_unit_quats(1)[0]
        np.testing.assert_allclose(im.quat_mul(im.quat_mul(qa, qb), qc), im.quat_mul(qa, im.quat_mul(qb, qc)),
                                   rtol=0, atol=1e-15)
        np.testing.assert_allclose(im.quat_mul(qa, im.quat_conj(qa)), [1, 0, 0, 0], rtol=0, atol=1e-15)


def test_rotation_matches_scipy_and_matrix():
    for q in random_unit_quats(30):
        v = RNG.normal(size=3)
        r = scipy_rot(q)
        np.testing.assert_allclose(im.quat_rotate(q, v), r.apply(v), rtol=0, atol=1e-14)
        np.testing.assert_allclose(im.quat_rotate_inv(q, v), r.inv().apply(v), rtol=0, atol=1e-14)
        np.testing.assert_allclose(im.quat_to_mat3(q), r.as_matrix(), rtol=0, atol=1e-15)
        np.testing.assert_allclose(im.quat_rotate(q, im.quat_rotate_inv(q, v)), v, rtol=0, atol=1e-14)


def test_matrix_quaternion_round_trip_all_branches():
    quats = list(random_unit_quats(40))
    # rotations by ~pi about each axis exercise the x, y, z branches of Shepperd's method
    for axis in np.eye(3):
        quats.append(im.quat_from_axis_angle(axis, np.pi - 1e-3))
        quats.append(im.quat_from_axis_angle(axis, np.pi))
    quats.append(np.array([1.0, 0, 0, 0]))
    for q in quats:
        q_back = im.mat3_to_quat(im.quat_to_mat3(q))
        assert q_back[0] >= 0.0
        assert abs(np.linalg.norm(q_back) - 1.0) < 1e-15
        # same rotation: q_back = +-q
        s = np.sign(np.dot(q_back, q)) or 1.0
        np.testing.assert_allclose(q_back, s * q, rtol=0, atol=1e-14)


def test_axis_angle_matches_scipy_rotvec():
    for _ in range(20):
        axis = RNG.normal(size=3)
        angle = RNG.uniform(-4, 4)
        q = im.quat_from_axis_angle(axis, angle)
        ref = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle)
        np.testing.assert_allclose(im.quat_to_mat3(q), ref.as_matrix(), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(im.quat_from_axis_angle(np.zeros(3), 1.0), [1, 0, 0, 0])
    np.testing.assert_array_equal(im.quat_normalize(np.zeros(4)), [1, 0, 0, 0])
    np.testing.assert_allclose(im.quat_normalize(np.array([2.0, 0, 0, 0])), [1, 0, 0, 0])


@pytest.mark.parametrize("speed", [0.0, 1e-9, 1e-3, 1.0, 50.0])
def test_exponential_map_matches_scipy(speed):
    # constant world angular velocity w: q(dt) = Rotation.from_rotvec(w dt) * q(0)  (world-frame rotation
    # applied after the current orientation), exactly, for any |w| dt
    for q in random_unit_quats(10):
        d = RNG.normal(size=3)
        omega = speed * d / np.linalg.norm(d)
        dt = 0.37
        got = im.quat_integrate(q, omega, dt)
        ref = Rotation.from_rotvec(omega * dt) * scipy_rot(q)
        np.testing.assert_allclose(im.quat_to_mat3(got), ref.as_matrix(), rtol=0, atol=2e-14)
        assert abs(np.linalg.norm(got) - 1.0) < 1e-15


def test_exponential_map_solves_the_quaternion_ode():
    # dq/dt = 1/2 (0, w) q: a central difference of quat_integrate matches the right-hand side
    q = random_unit_quats(1)[0]
    omega = np.array([0.3, -1.2, 2.0])
    h = 1e-5
    dq = (im.quat_integrate(q, omega, h) - im.quat_integrate(q, omega, -h)) / (2 * h)
    rhs = 0.5 * im.quat_mul(np.array([0.0, *omega]), q)
    np.testing.assert_allclose(dq, rhs, rtol=0, atol=1e-9)


def test_transforms_compose_and_invert():
    for _ in range(20):
        a = np.concatenate([RNG.normal(size=3), random_unit_quats(1)[0]])
        b = np.concatenate([RNG.normal(size=3), random_unit_quats(1)[0]])
        p = RNG.normal(size=3)
        ab = im.transform_mul(a, b)
        np.testing.assert_allclose(im.transform_point(ab, p), im.transform_point(a, im.transform_point(b, p)),
                                   rtol=0, atol=1e-13)
        np.testing.assert_allclose(im.transform_point_inv(a, im.transform_point(a, p)), p, rtol=0, atol=1e-13)
        ident = im.transform_mul(a, im.transform_inv(a))
        np.testing.assert_allclose(ident[:3], 0, atol=1e-14)
        np.testing.assert_allclose(abs(ident[3]), 1, atol=1e-15)
        np.testing.assert_allclose(im.transform_point(im.transform_inv(a), p), im.transform_point_inv(a, p),
                                   rtol=0, atol=1e-13)
        # against scipy: x = p + R v
        np.testing.assert_allclose(im.transform_point(a, p), a[:3] + scipy_rot(a[3:]).apply(p), rtol=0,
                                   atol=1e-13)


def test_world_inertia_inverse():
    for q in random_unit_quats(10):
        inertia = RNG.uniform(0.5, 3.0, size=3)
        r = scipy_rot(q).as_matrix()
        world = r @ np.diag(inertia) @ r.T
        np.testing.assert_allclose(im.world_inertia_inv(q, 1.0 / inertia), np.linalg.inv(world), rtol=0,
                                   atol=1e-13)
        np.testing.assert_allclose(im.mat3_inv_sym(world), np.linalg.inv(world), rtol=0, atol=1e-13)


def spatial_motion_matrix(v):
    """Featherstone (2008) eq. 2.31: v x = [[w x, 0], [v x, w x]]."""
    w, u = im.skew(v[:3]), im.skew(v[3:])
    return np.block([[w, np.zeros((3, 3))], [u, w]])


def test_spatial_cross_products():
    for _ in range(10):
        v, m, f = RNG.normal(size=6), RNG.normal(size=6), RNG.normal(size=6)
        np.testing.assert_allclose(im.spatial_cross_motion(v, m), spatial_motion_matrix(v) @ m, rtol=0,
                                   atol=1e-14)
        # v x* = -(v x)^T  (eq. 2.32)
        np.testing.assert_allclose(im.spatial_cross_force(v, f), -spatial_motion_matrix(v).T @ f, rtol=0,
                                   atol=1e-14)
        # the power pairing is invariant: (v x m) . f + m . (v x* f) = 0
        assert abs(im.spatial_cross_motion(v, m) @ f + m @ im.spatial_cross_force(v, f)) < 1e-13


def _matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_numpy_compose_poses_and_rotate_vectors_match_rotation_matrices():
    """The NumPy batch helpers against R(q) built from the quaternion (Shoemake 1985), one row and broadcast."""
    from inertia.math import compose_poses, rotate_vectors
    rng = np.random.default_rng(3)
    qa, qb = rng.normal(size=(5, 4)), rng.normal(size=(5, 4))
    qa /= np.linalg.norm(qa, axis=1, keepdims=True)
    qb /= np.linalg.norm(qb, axis=1, keepdims=True)
    a = np.concatenate([rng.normal(size=(5, 3)), qa], axis=1)
    b = np.concatenate([rng.normal(size=(5, 3)), qb], axis=1)
    out = compose_poses(a, b)
    for k in range(5):
        ra, rb = _matrix(a[k, 3:]), _matrix(b[k, 3:])
        assert np.allclose(out[k, :3], ra @ b[k, :3] + a[k, :3], atol=1e-14)
        assert np.allclose(_matrix(out[k, 3:]), ra @ rb, atol=1e-14)
        assert np.allclose(rotate_vectors(a[k, 3:], b[:, :3]), b[:, :3] @ ra.T, atol=1e-14)
    assert np.array_equal(compose_poses(a[0], b[0]), out[0])
