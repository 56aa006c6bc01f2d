"""Allocation-free 3-vector and quaternion helpers on tuples, for the hot rigid kernels.

``inertia.math`` (arrays in, arrays out) is the public algebra; the contact kernels run these tuple
twins instead so the inner loops of the narrow phase and the solver keep everything in registers.
Conventions are the same: quaternions ``(w, x, y, z)``, ``qrot(q, v) = q v q*`` (body -> world).
They are ordinary ``@njit(cache=True)`` functions, compiled once per signature; LLVM inlines them into
their callers. (Numba's ``inline="always"`` would re-type each one at every call site: the solver and
narrow phase took about twice as long to compile that way.)
"""

from __future__ import annotations

import math

from numba import njit

_inl = njit(cache=True)


@_inl
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@_inl
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_inl
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@_inl
def madd(a, b, s):
    """a + s b"""
    return (a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s)


@_inl
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_inl
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_inl
def norm(a):
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@_inl
def normalize(a):
    n = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if n < 1e-300:
        return (0.0, 0.0, 1.0)
    inv = 1.0 / n
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@_inl
def qrot(q, v):
    """R(q) v: v + 2 w (u x v) + 2 u x (u x v) with q = (w, u)."""
    w, ux, uy, uz = q[0], q[1], q[2], q[3]
    tx = 2.0 * (uy * v[2] - uz * v[1])
    ty = 2.0 * (uz * v[0] - ux * v[2])
    tz = 2.0 * (ux * v[1] - uy * v[0])
    return (v[0] + w * tx + (uy * tz - uz * ty),
            v[1] + w * ty + (uz * tx - ux * tz),
            v[2] + w * tz + (ux * ty - uy * tx))


@_inl
def qrot_inv(q, v):
    """R(q)^T v."""
    return qrot((q[0], -q[1], -q[2], -q[3]), v)


@_inl
def qmul(a, b):
    return (a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0])


@_inl
def qconj(q):
    return (q[0], -q[1], -q[2], -q[3])


@_inl
def mat_vec(m, v):
    """m (9-tuple, row-major) times v."""
    return (m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
            m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
            m[6] * v[0] + m[7] * v[1] + m[8] * v[2])


@_inl
def orthonormal_basis(n):
    """Two unit tangents t1, t2 with (t1, t2, n) right-handed (Duff et al. 2017, branchless ONB)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t1 = (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    t2 = (b, sign + n[1] * n[1] * a, -n[1])
    return t1, t2
