"""Ray casts against single shapes and shape casts (swept convex shapes) by conservative advancement.

A ray is ``origin + t direction`` for ``0 <= t <= max_t`` (``direction`` need not be unit length; ``t`` is in
units of it).  Every function returns ``(t, normal)``: the first entry into the solid and the unit outward
surface normal there, or ``(inf, 0)`` for a miss.  Rays that start inside a solid report no hit (as in
Box2D): a query "what does this ray enter" has no answer for the solid it starts in.  The triangle and the
triangle mesh are two-sided surfaces (the normal returned faces the ray).

Closed forms, all in the shape's local frame (world rays are moved in by the inverse pose):
- sphere: the smaller root of |o + t d|^2 = r^2;
- box: the slab test (Kay and Kajiya 1986): entry = latest entry over the three slabs;
- capsule: the side of the infinite cylinder of radius r about z, clipped to |z| <= h, and the two end
  spheres; cylinder: the side clipped to |z| <= h, and the two cap discs;
- convex hull: Cyrus-Beck clipping of the ray by the hull's face planes (Haines 1991);
- plane (solid z <= 0): t = -o_z / d_z; triangle: Moller and Trumbore (1997).
The shape cast moves shape A by ``translation`` and finds the first time of contact with B (within
``tolerance``) by conservative advancement (Mirtich 1996, thesis; Catto's time of impact): each GJK distance d
with normal n allows an advance of d / (translation . n) without touching; the loop is ``inertia.geometry.toi``'s
kernel (one home for shape casts and bullet times of impact).

References
- Kay, T. L. and Kajiya, J. T. (1986). Ray tracing complex scenes. SIGGRAPH '86 (slabs).
- Haines, E. (1991). Fast ray-convex polyhedron intersection. Graphics Gems II, 247-250.
- Moller, T. and Trumbore, B. (1997). Fast, minimum storage ray-triangle intersection. Journal of Graphics
  Tools 2(1), 21-28.
- Mirtich, B. (1996). Impulse-based dynamic simulation of rigid body systems. PhD thesis, UC Berkeley
  (conservative advancement).

Limitations
- Triangle meshes are cast brute force over their triangles (no BVH here; rigid-core's BVH accelerates them).
- Heightfields are not handled (rigid-core's shape table owns them).
- The shape cast is translational only (no rotation during the sweep); a swept shape already touching or
  overlapping B at the start reports t = 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inertia import math as _m
from inertia.geometry import toi as _toi
from inertia.geometry.convex import BOX, CAPSULE, CONVEX_HULL, CYLINDER, PLANE, SPHERE, TRIANGLE_MESH

__all__ = ["ray_sphere", "ray_box", "ray_capsule", "ray_cylinder", "ray_convex_hull", "ray_plane",
           "ray_triangle", "ray_cast", "shape_cast"]

_MISS = np.inf


@njit(cache=True)
def _miss():
    return _MISS, np.zeros(3)


@njit(cache=True)
def ray_sphere(origin, direction, radius):
    """Entry of the ray into the sphere of ``radius`` at the local origin."""
    a = _m.dot(direction, direction)
    b = _m.dot(origin, direction)
    c = _m.dot(origin, origin) - radius * radius
    if c <= 0.0 or a == 0.0:
        return _miss()  # starts inside (or no direction)
    disc = b * b - a * c
    if disc < 0.0 or b >= 0.0:
        return _miss()
    # t = (-b - sqrt(disc)) / a, written as c / (-b + sqrt(disc)) to avoid cancellation for far rays
    t = c / (-b + math.sqrt(disc))
    p = origin + t * direction
    return t, p / radius


@njit(cache=True)
def ray_box(origin, direction, half_extents):
    """Entry into the box [-h, h]^3 by the slab test."""
    t_enter = -np.inf
    t_exit = np.inf
    axis = -1
    sign = 0.0
    for k in range(3):
        if direction[k] == 0.0:
            if abs(origin[k]) > half_extents[k]:
                return _miss()
            continue
        inv = 1.0 / direction[k]
        t0 = (-half_extents[k] - origin[k]) * inv
        t1 = (half_extents[k] - origin[k]) * inv
        s = -1.0
        if t0 > t1:
            t0, t1 = t1, t0
            s = 1.0
        if t0 > t_enter:
            t_enter = t0
            axis = k
            sign = s
        t_exit = min(t_exit, t1)
    if axis < 0 or t_enter > t_exit or t_enter < 0.0:
        return _miss()
    n = np.zeros(3)
    n[axis] = sign
    return t_enter, n


@njit(cache=True)
def _side_of_z_cylinder(origin, direction, radius, half_height):
    """First t >= 0 at which the ray enters the infinite cylinder x^2 + y^2 = r^2 with |z| <= h there."""
    a = direction[0] ** 2 + direction[1] ** 2
    if a == 0.0:
        return _MISS
    b = origin[0] * direction[0] + origin[1] * direction[1]
    c = origin[0] ** 2 + origin[1] ** 2 - radius * radius
    disc = b * b - a * c
    if disc < 0.0 or c <= 0.0 or b >= 0.0:
        return _MISS  # misses, or starts inside the infinite cylinder, or moves away from the axis
    t = c / (-b + math.sqrt(disc))
    z = origin[2] + t * direction[2]
    if abs(z) > half_height:
        return _MISS
    return t


@njit(cache=True)
def ray_capsule(origin, direction, radius, half_length):
    """Entry into the capsule: points within ``radius`` of the segment z in [-half_length, half_length]."""
    # inside test: distance from the origin to the segment
    zc = min(max(origin[2], -half_length), half_length)
    if origin[0] ** 2 + origin[1] ** 2 + (origin[2] - zc) ** 2 <= radius * radius:
        return _miss()
    best = _side_of_z_cylinder(origin, direction, radius, half_length)
    n = np.zeros(3)
    if best < _MISS:
        p = origin + best * direction
        n[0] = p[0] / radius
        n[1] = p[1] / radius
    for cap in (-half_length, half_length):
        shifted = origin.copy()
        shifted[2] -= cap
        t, nc = ray_sphere(shifted, direction, radius)
        if t < best:
            best = t
            n = nc
    if best == _MISS:
        return _miss()
    return best, n


@njit(cache=True)
def ray_cylinder(origin, direction, radius, half_height):
    """Entry into the solid cylinder of ``radius`` about z with |z| <= half_height."""
    if abs(origin[2]) <= half_height and origin[0] ** 2 + origin[1] ** 2 <= radius * radius:
        return _miss()
    best = _side_of_z_cylinder(origin, direction, radius, half_height)
    n = np.zeros(3)
    if best < _MISS:
        p = origin + best * direction
        n[0] = p[0] / radius
        n[1] = p[1] / radius
    # cap discs: the plane z = +-h entered from outside, hit point within the radius
    if direction[2] != 0.0:
        cap = half_height if origin[2] > half_height else (-half_height if origin[2] < -half_height else 0.0)
        if cap != 0.0 and (cap - origin[2]) * direction[2] > 0.0:
            t = (cap - origin[2]) / direction[2]
            x = origin[0] + t * direction[0]
            y = origin[1] + t * direction[1]
            if x * x + y * y <= radius * radius and t < best:
                best = t
                n = np.zeros(3)
                n[2] = 1.0 if cap > 0.0 else -1.0
    if best == _MISS:
        return _miss()
    return best, n


@njit(cache=True)
def ray_convex_hull(origin, direction, face_planes, face_start, face_count):
    """Entry into a convex hull given by its outward face planes (n, d), n . x <= d inside (Cyrus-Beck)."""
    t_enter = -np.inf
    t_exit = np.inf
    entry_face = -1
    for f in range(face_start, face_start + face_count):
        n0, n1, n2, d = face_planes[f, 0], face_planes[f, 1], face_planes[f, 2], face_planes[f, 3]
        denom = n0 * direction[0] + n1 * direction[1] + n2 * direction[2]
        dist = d - (n0 * origin[0] + n1 * origin[1] + n2 * origin[2])  # > 0: origin inside this plane
        if denom == 0.0:
            if dist < 0.0:
                return _miss()
            continue
        t = dist / denom
        if denom < 0.0:
            if t > t_enter:
                t_enter = t
                entry_face = f
        else:
            t_exit = min(t_exit, t)
        if t_enter > t_exit:
            return _miss()
    if entry_face < 0 or t_enter < 0.0:
        return _miss()
    return t_enter, face_planes[entry_face, :3].copy()


@njit(cache=True)
def ray_plane(origin, direction):
    """Entry into the half space z <= 0 (the plane's local frame)."""
    if origin[2] <= 0.0 or direction[2] >= 0.0:
        return _miss()
    n = np.zeros(3)
    n[2] = 1.0
    return -origin[2] / direction[2], n


@njit(cache=True)
def ray_triangle(origin, direction, a, b, c):
    """Two-sided ray-triangle hit (Moller and Trumbore 1997); the normal faces the ray."""
    e1 = b - a
    e2 = c - a
    pvec = _m.cross(direction, e2)
    det = _m.dot(e1, pvec)
    scale = math.sqrt(_m.dot(e1, e1) * _m.dot(e2, e2) * _m.dot(direction, direction))
    if abs(det) <= 1e-14 * scale:
        return _miss()  # parallel to the triangle's plane
    inv = 1.0 / det
    tvec = origin - a
    u = _m.dot(tvec, pvec) * inv
    if u < 0.0 or u > 1.0:
        return _miss()
    qvec = _m.cross(tvec, e1)
    v = _m.dot(direction, qvec) * inv
    if v < 0.0 or u + v > 1.0:
        return _miss()
    t = _m.dot(e2, qvec) * inv
    if t < 0.0:
        return _miss()
    n = _m.cross(e1, e2)
    n /= math.sqrt(_m.dot(n, n))
    if _m.dot(n, direction) > 0.0:
        n = -n
    return t, n


@njit(cache=True)
def ray_cast(shape_type, params, pose, verts, vert_start, face_planes, face_start, face_count, triangles,
             tri_start, tri_count, origin, direction, max_t):
    """World-frame ray cast against one shape-table row; returns (t, world normal), t = inf for a miss or
    a hit beyond ``max_t``.  Hulls use ``face_planes[face_start:face_start + face_count]``; meshes use
    ``triangles[tri_start:tri_start + tri_count]`` (indices relative to ``vert_start``)."""
    o = _m.transform_point_inv(pose, origin)
    d = _m.quat_rotate_inv(pose[3:7], direction)
    if shape_type == SPHERE:
        t, n = ray_sphere(o, d, params[0])
    elif shape_type == BOX:
        t, n = ray_box(o, d, params[0:3])
    elif shape_type == CAPSULE:
        t, n = ray_capsule(o, d, params[0], params[1])
    elif shape_type == CYLINDER:
        t, n = ray_cylinder(o, d, params[0], params[1])
    elif shape_type == CONVEX_HULL:
        t, n = ray_convex_hull(o, d, face_planes, face_start, face_count)
    elif shape_type == PLANE:
        t, n = ray_plane(o, d)
    elif shape_type == TRIANGLE_MESH:
        t = _MISS
        n = np.zeros(3)
        for k in range(tri_start, tri_start + tri_count):
            tk, nk = ray_triangle(o, d, verts[vert_start + triangles[k, 0]], verts[vert_start + triangles[k, 1]],
                                  verts[vert_start + triangles[k, 2]])
            if tk < t:
                t = tk
                n = nk
    else:
        raise ValueError("ray_cast: shape_type must be SPHERE, BOX, CAPSULE, CYLINDER, CONVEX_HULL, PLANE or "
                         "TRIANGLE_MESH")
    if t > max_t:
        return _miss()
    return t, _m.quat_rotate(pose[3:7], n)


@njit(cache=True)
def shape_cast(type_a, params_a, pose_a, start_a, count_a, translation, type_b, params_b, pose_b, start_b,
               count_b, verts, tolerance, max_iterations):
    """Sweep convex shape A along ``translation`` (A's pose at time s in [0, 1] is pose_a moved by s
    translation) against convex shape B.  Returns (s, normal from A to B, witness point on B): the first
    time the distance falls to ``tolerance`` (m), or s = inf if they never come that close.  Starting closer
    than ``tolerance`` (or overlapping) gives s = 0.  If ``max_iterations`` (20-50 is ample for polytopes;
    grazing curved shapes need more) runs out, the last s reached is returned: the shapes do not touch
    before it, so it is a conservative time of impact."""
    # one home for sweeps: the time-of-impact kernel (conservative advancement on GJK) without rotation
    pose_a1 = pose_a.copy()
    pose_a1[0:3] = pose_a[0:3] + translation
    s, n, _, wb, hit = _toi.toi_kernel(type_a, params_a, start_a, count_a, pose_a, pose_a1, type_b, params_b,
                                       start_b, count_b, pose_b, pose_b, verts, 0.0, tolerance, max_iterations)
    if not hit:
        return _MISS, np.zeros(3), np.zeros(3)
    return s, n, wb
