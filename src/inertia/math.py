"""Small rigid-body algebra for Numba kernels: quaternions, rigid transforms, 3x3 and spatial (6D) helpers.

Conventions (fixed: every layer relies on them)
- Quaternion ``q = (w, x, y, z)``, float64 array of 4, unit length for rotations. ``quat_rotate(q, v)`` is
  ``q v q*``: it maps body-frame vectors to the world frame.
- Rigid transform (pose) ``(px, py, pz, qw, qx, qy, qz)``, float64 array of 7: ``x_world = p + R(q) x_local``.
- Spatial vectors are 6D ``(angular, linear)`` in Featherstone's order (motion: ``(omega, v)``; force:
  ``(torque, force)``).
- 3x3 matrices are float64 ``(3, 3)`` C-ordered arrays.

Every function returns a new small array; ``*_into`` variants write into ``out`` for kernels that must not
allocate.  All functions are ``@njit(cache=True)``; they are plain Python-callable too (handy in tests).
``rotate_vectors`` and ``compose_poses`` are their NumPy counterparts for many rows at once (build-time,
export and rendering code: they broadcast over leading axes).

References
- Shoemake, K. (1985). Animating rotation with quaternion curves. SIGGRAPH '85 (quaternion algebra).
- Shepperd, S. W. (1978). Quaternion from rotation matrix. J. Guidance and Control 1(3) (``mat3_to_quat``).
- Featherstone, R. (2008). Rigid Body Dynamics Algorithms. Springer, ch. 2 (spatial cross products).

Limitations
- No input validation (these are kernel building blocks); callers validate at build time.
- ``quat_integrate`` is exact only for an angular velocity constant over the step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = [
    "quat_mul", "quat_conj", "quat_normalize", "quat_rotate", "quat_rotate_inv", "quat_rotate_into",
    "quat_rotate_inv_into", "quat_to_mat3", "quat_to_mat3_entries", "quat_to_mat3_into", "mat3_to_quat", "quat_from_axis_angle",
    "quat_from_axis_angle_into", "quat_integrate",
    "quat_integrate_into", "transform_point", "transform_point_inv", "transform_mul", "transform_inv",
    "cross", "dot", "skew", "mat3_mul", "mat3_vec", "mat3_transpose", "mat3_inv_sym", "world_inertia_inv",
    "world_inertia_inv_into",
    "spatial_cross_motion", "spatial_cross_force", "rotate_vectors", "compose_poses",
]

_jit = njit(cache=True)


# ---------------------------------------------------------------------------------------------- vectors
@_jit
def cross(a, b):
    """a x b for 3-vectors."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@_jit
def dot(a, b):
    """a . b for 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def skew(v):
    """The cross-product matrix [v]x, so that skew(v) @ w == cross(v, w)."""
    m = np.zeros((3, 3))
    m[0, 1] = -v[2]
    m[0, 2] = v[1]
    m[1, 0] = v[2]
    m[1, 2] = -v[0]
    m[2, 0] = -v[1]
    m[2, 1] = v[0]
    return m


# ------------------------------------------------------------------------------------------ 3x3 matrices
@_jit
def mat3_mul(a, b):
    """a @ b for 3x3 matrices."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]
    return out


@_jit
def mat3_vec(m, v):
    """m @ v for a 3x3 matrix and a 3-vector."""
    out = np.empty(3)
    for i in range(3):
        out[i] = m[i, 0] * v[0] + m[i, 1] * v[1] + m[i, 2] * v[2]
    return out


@_jit
def mat3_transpose(m):
    """m^T for a 3x3 matrix."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = m[j, i]
    return out


@_jit
def mat3_inv_sym(m):
    """Inverse of a symmetric 3x3 matrix by its adjugate (cofactors / determinant).

    Only the upper triangle is read.  A singular matrix gives non-finite entries (the caller checks)."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e = m[1, 1], m[1, 2]
    f = m[2, 2]
    # cofactors of the symmetric matrix [[a b c] [b d e] [c e f]]
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    c11 = a * f - c * c
    c12 = b * c - a * e
    c22 = a * d - b * b
    inv_det = 1.0 / (a * c00 + b * c01 + c * c02)
    out = np.empty((3, 3))
    out[0, 0] = c00 * inv_det
    out[0, 1] = c01 * inv_det
    out[0, 2] = c02 * inv_det
    out[1, 0] = c01 * inv_det
    out[1, 1] = c11 * inv_det
    out[1, 2] = c12 * inv_det
    out[2, 0] = c02 * inv_det
    out[2, 1] = c12 * inv_det
    out[2, 2] = c22 * inv_det
    return out


# ------------------------------------------------------------------------------------------- quaternions
@_jit
def quat_mul(a, b):
    """Hamilton product a b (apply b first, then a, when both are rotations)."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@_jit
def quat_conj(q):
    """Conjugate (w, -x, -y, -z): the inverse of a unit quaternion."""
    out = np.empty(4)
    out[0] = q[0]
    out[1] = -q[1]
    out[2] = -q[2]
    out[3] = -q[3]
    return out


@_jit
def quat_normalize(q):
    """q / |q|; the identity (1, 0, 0, 0) for a zero quaternion."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    out = np.empty(4)
    if n == 0.0:
        out[0] = 1.0
        out[1] = 0.0
        out[2] = 0.0
        out[3] = 0.0
        return out
    inv = 1.0 / n
    for i in range(4):
        out[i] = q[i] * inv
    return out


@_jit
def quat_rotate_into(q, v, out):
    """out = R(q) v (body to world), writing into ``out`` (3,); ``out`` may alias ``v``.

    Uses v' = v + 2 w (u x v) + 2 u x (u x v) with u = (x, y, z), valid for unit q."""
    w, ux, uy, uz = q[0], q[1], q[2], q[3]
    vx, vy, vz = v[0], v[1], v[2]
    # t = 2 (u x v)
    tx = 2.0 * (uy * vz - uz * vy)
    ty = 2.0 * (uz * vx - ux * vz)
    tz = 2.0 * (ux * vy - uy * vx)
    out[0] = vx + w * tx + (uy * tz - uz * ty)
    out[1] = vy + w * ty + (uz * tx - ux * tz)
    out[2] = vz + w * tz + (ux * ty - uy * tx)


@_jit
def quat_rotate_inv_into(q, v, out):
    """out = R(q)^T v (world to body), writing into ``out`` (3,); ``out`` may alias ``v``."""
    w, ux, uy, uz = q[0], -q[1], -q[2], -q[3]
    vx, vy, vz = v[0], v[1], v[2]
    tx = 2.0 * (uy * vz - uz * vy)
    ty = 2.0 * (uz * vx - ux * vz)
    tz = 2.0 * (ux * vy - uy * vx)
    out[0] = vx + w * tx + (uy * tz - uz * ty)
    out[1] = vy + w * ty + (uz * tx - ux * tz)
    out[2] = vz + w * tz + (ux * ty - uy * tx)


@_jit
def quat_rotate(q, v):
    """R(q) v: rotate a body-frame vector into the world frame (unit q)."""
    out = np.empty(3)
    quat_rotate_into(q, v, out)
    return out


@_jit
def quat_rotate_inv(q, v):
    """R(q)^T v: rotate a world-frame vector into the body frame (unit q)."""
    out = np.empty(3)
    quat_rotate_inv_into(q, v, out)
    return out


@_jit
def quat_to_mat3(q):
    """The rotation matrix R(q) of a unit quaternion."""
    return quat_to_mat3_into(q, np.empty((3, 3)))


@_jit
def quat_to_mat3_entries(w, x, y, z):
    """The nine entries of R(q) for a unit quaternion (w, x, y, z), row-major, as a tuple (no array)."""
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


@_jit
def quat_to_mat3_into(q, m):
    """R(q) of a unit quaternion written into m (3, 3) (no allocation); returns m."""
    r = quat_to_mat3_entries(q[0], q[1], q[2], q[3])
    m[0, 0], m[0, 1], m[0, 2] = r[0], r[1], r[2]
    m[1, 0], m[1, 1], m[1, 2] = r[3], r[4], r[5]
    m[2, 0], m[2, 1], m[2, 2] = r[6], r[7], r[8]
    return m


@_jit
def mat3_to_quat(m):
    """Unit quaternion of a rotation matrix (Shepperd 1978: branch on the largest of w^2, x^2, y^2, z^2
    for accuracy); the sign is chosen so that w >= 0."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    q = np.empty(4)
    if tr >= m[0, 0] and tr >= m[1, 1] and tr >= m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + tr)  # s = 4 w
        q[0] = 0.25 * s
        q[1] = (m[2, 1] - m[1, 2]) / s
        q[2] = (m[0, 2] - m[2, 0]) / s
        q[3] = (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] >= m[1, 1] and m[0, 0] >= m[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0))  # s = 4 x
        q[0] = (m[2, 1] - m[1, 2]) / s
        q[1] = 0.25 * s
        q[2] = (m[0, 1] + m[1, 0]) / s
        q[3] = (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] >= m[2, 2]:
        s = 2.0 * math.sqrt(max(1.0 + m[1, 1] - m[0, 0] - m[2, 2], 0.0))  # s = 4 y
        q[0] = (m[0, 2] - m[2, 0]) / s
        q[1] = (m[0, 1] + m[1, 0]) / s
        q[2] = 0.25 * s
        q[3] = (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(max(1.0 + m[2, 2] - m[0, 0] - m[1, 1], 0.0))  # s = 4 z
        q[0] = (m[1, 0] - m[0, 1]) / s
        q[1] = (m[0, 2] + m[2, 0]) / s
        q[2] = (m[1, 2] + m[2, 1]) / s
        q[3] = 0.25 * s
    if q[0] < 0.0:
        for i in range(4):
            q[i] = -q[i]
    return quat_normalize(q)


@_jit
def quat_from_axis_angle(axis, angle):
    """Rotation by ``angle`` radians about ``axis`` (normalised here; a zero axis gives the identity)."""
    return quat_from_axis_angle_into(axis, angle, np.empty(4))


@_jit
def quat_from_axis_angle_into(axis, angle, q):
    """`quat_from_axis_angle` written into q (4,) (no allocation); returns q."""
    n = math.sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
    if n == 0.0:
        q[0] = 1.0
        q[1] = 0.0
        q[2] = 0.0
        q[3] = 0.0
        return q
    s = math.sin(0.5 * angle) / n
    q[0] = math.cos(0.5 * angle)
    q[1] = axis[0] * s
    q[2] = axis[1] * s
    q[3] = axis[2] * s
    return q


@_jit
def quat_integrate_into(q, omega_world, dt, out):
    """out = exp(omega dt / 2) q, renormalised; ``out`` may alias ``q``.

    dq/dt = 1/2 (0, omega) q for a world-frame angular velocity; for omega constant over the step the
    solution is the rotation by |omega| dt about omega/|omega| applied after q (the exponential map).
    Small angles use the Taylor series of sin(h)/|omega| to stay accurate as |omega| -> 0."""
    wx, wy, wz = omega_world[0], omega_world[1], omega_world[2]
    speed = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * speed * dt
    if half < 1e-4:
        # sin(h)/speed = dt/2 (1 - h^2/6 + h^4/120), error < 1e-22 relative for h < 1e-4
        h2 = half * half
        s = 0.5 * dt * (1.0 - h2 / 6.0 + h2 * h2 / 120.0)
        c = 1.0 - 0.5 * h2 + h2 * h2 / 24.0
    else:
        s = math.sin(half) / speed
        c = math.cos(half)
    dw, dx, dy, dz = c, wx * s, wy * s, wz * s
    qw, qx, qy, qz = q[0], q[1], q[2], q[3]
    rw = dw * qw - dx * qx - dy * qy - dz * qz
    rx = dw * qx + dx * qw + dy * qz - dz * qy
    ry = dw * qy - dx * qz + dy * qw + dz * qx
    rz = dw * qz + dx * qy - dy * qx + dz * qw
    inv = 1.0 / math.sqrt(rw * rw + rx * rx + ry * ry + rz * rz)
    out[0] = rw * inv
    out[1] = rx * inv
    out[2] = ry * inv
    out[3] = rz * inv


@_jit
def quat_integrate(q, omega_world, dt):
    """exp(omega dt / 2) q, renormalised (see ``quat_integrate_into``)."""
    out = np.empty(4)
    quat_integrate_into(q, omega_world, dt, out)
    return out


# ------------------------------------------------------------------------------------- rigid transforms
@_jit
def transform_point(pose, p):
    """pose applied to a point: position + R(q) p."""
    out = np.empty(3)
    quat_rotate_into(pose[3:7], p, out)
    out[0] += pose[0]
    out[1] += pose[1]
    out[2] += pose[2]
    return out


@_jit
def transform_point_inv(pose, p):
    """The inverse pose applied to a point: R(q)^T (p - position)."""
    d = np.empty(3)
    d[0] = p[0] - pose[0]
    d[1] = p[1] - pose[1]
    d[2] = p[2] - pose[2]
    quat_rotate_inv_into(pose[3:7], d, d)
    return d


@_jit
def transform_mul(a, b):
    """Composition a * b: apply b, then a (p = a.p + R_a b.p, q = a.q b.q)."""
    out = np.empty(7)
    quat_rotate_into(a[3:7], b[0:3], out[0:3])
    out[0] += a[0]
    out[1] += a[1]
    out[2] += a[2]
    q = quat_mul(a[3:7], b[3:7])
    for k in range(4):      # element by element: a slice assignment compiles Numba's broadcasting checks
        out[3 + k] = q[k]
    return out


@_jit
def transform_inv(a):
    """Inverse pose: q' = q*, p' = -R^T p."""
    out = np.empty(7)
    out[3] = a[3]
    out[4] = -a[4]
    out[5] = -a[5]
    out[6] = -a[6]
    quat_rotate_inv_into(a[3:7], a[0:3], out[0:3])
    out[0] = -out[0]
    out[1] = -out[1]
    out[2] = -out[2]
    return out


# --------------------------------------------------------------------------------------------- inertia
@_jit
def world_inertia_inv(q, inv_inertia_diag):
    """World-frame inverse inertia R diag(I^-1) R^T for a body whose frame is on its principal axes."""
    return world_inertia_inv_into(q, inv_inertia_diag, np.empty((3, 3)), np.empty((3, 3)))


@_jit
def world_inertia_inv_into(q, inv_inertia_diag, r, out):
    """`world_inertia_inv` into out (3, 3), with R(q) into r (3, 3) (no allocation); returns out."""
    quat_to_mat3_into(q, r)
    for i in range(3):
        for j in range(i, 3):
            s = (r[i, 0] * inv_inertia_diag[0] * r[j, 0] + r[i, 1] * inv_inertia_diag[1] * r[j, 1]
                 + r[i, 2] * inv_inertia_diag[2] * r[j, 2])
            out[i, j] = s
            out[j, i] = s
    return out


# ------------------------------------------------------------------------------------ spatial algebra
@_jit
def spatial_cross_motion(v, m):
    """Spatial motion cross product v x m (Featherstone 2008, eq. 2.31), v = (omega, vel), m = (w_m, v_m):
    (omega x w_m, omega x v_m + vel x w_m)."""
    out = np.empty(6)
    out[0:3] = cross(v[0:3], m[0:3])
    out[3:6] = cross(v[0:3], m[3:6]) + cross(v[3:6], m[0:3])
    return out


@_jit
def spatial_cross_force(v, f):
    """Spatial force cross product v x* f (Featherstone 2008, eq. 2.32), f = (torque n, force f_l):
    (omega x n + vel x f_l, omega x f_l)."""
    out = np.empty(6)
    out[0:3] = cross(v[0:3], f[0:3]) + cross(v[3:6], f[3:6])
    out[3:6] = cross(v[0:3], f[3:6])
    return out


# ------------------------------------------------------------------------------- NumPy, many rows at once
def rotate_vectors(q, v):
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)`` (w, x, y, z), broadcasting:
    ``v + 2 w (u x v) + u x (2 u x v)`` with ``u = (x, y, z)`` (NumPy; build-time and render code)."""
    q, v = np.asarray(q, np.float64), np.asarray(v, np.float64)
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def compose_poses(a, b):
    """Poses ``a * b`` (..., 7) (position + quaternion w, x, y, z), broadcasting: the world pose of a frame
    at ``b`` inside a frame at ``a``: ``p = R_a p_b + p_a``, ``q = q_a q_b`` (NumPy)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., :3] = rotate_vectors(a[..., 3:], b[..., :3]) + a[..., :3]
    aw, ax, ay, az = np.moveaxis(a[..., 3:], -1, 0)
    bw, bx, by, bz = np.moveaxis(b[..., 3:], -1, 0)
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 4] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 5] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 6] = aw * bz + ax * by - ay * bx + az * bw
    return out
