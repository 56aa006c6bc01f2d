"""From collider objects to the renderer's primitive table.

Colliders (``inertia.colliders``) expose ``dim``, ``signed_distance(points, t)`` and
``normal(points, t)`` and carry their parameters as attributes. The renderer draws the shapes
it recognises exactly, by ray casting analytic primitives (`kernels.PRIM_*`):

==========  ==========================================================================
plane       a half-space: ``normal_vector``/``normal`` and a point on it (``point``/``origin``) or
            ``offset`` (n . x = offset); drawn as a grid plane (3-D) or a filled half-plane (2-D)
sphere      ``center`` and ``radius`` (a circle in 2-D)
box         ``center`` and ``half_extents`` (or ``half_size``, ``size``/``extents`` = full),
            optional ``rotation`` ((D, D) matrix, a quaternion (w, x, y, z), or an angle in 2-D)
capsule     two end points (``a``/``b``, ``p0``/``p1``, ``start``/``end``, or ``points``) and ``radius``
cylinder    ``center``, ``axis``, ``radius``, ``half_height`` (capped; 3-D)
container   a box particles live inside (``center``, ``half_extents``, walls ``plane_normals``):
            3-D draws its far walls only (a cut-away room); 2-D a wall band around it
==========  ==========================================================================

A collider may instead describe itself: ``render_primitive(t) -> (kind, params)`` with
kind in {"plane", "sphere", "box", "capsule"} and params a dict of the names above. Kinematic
colliders (``motion`` not None) are described at time ``t`` through that hook, or through
``pose(t) -> (p, R)`` of `inertia.colliders`: the rest shape's reference point ``rest_point``
moves to ``p`` and the shape rotates by ``R`` about it (world = R (x - rest_point) + p).

Anything else is drawn from its signed distance: sampled on the pixel grid in 2-D, sphere
traced in 3-D (slower: a few hundred ms per 720p frame for a NumPy SDF; cached while static).

Limitations: meshes are drawn only through their signed distance (sphere tracing), which is
slow for big meshes; ``Container.from_planes`` too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .kernels import PRIM_BOX, PRIM_CAPSULE, PRIM_CONTAINER, PRIM_CYLINDER, PRIM_PLANE, PRIM_SPHERE

__all__ = ["Primitives", "collider_primitives", "trace_signed_distance", "collider_bounds"]

_KINDS = {"plane": PRIM_PLANE, "halfspace": PRIM_PLANE, "halfplane": PRIM_PLANE, "sphere": PRIM_SPHERE,
          "circle": PRIM_SPHERE, "ball": PRIM_SPHERE, "disk": PRIM_SPHERE, "box": PRIM_BOX, "rect": PRIM_BOX,
          "rectangle": PRIM_BOX, "cuboid": PRIM_BOX, "aabb": PRIM_BOX, "obb": PRIM_BOX, "capsule": PRIM_CAPSULE,
          "stadium": PRIM_CAPSULE, "container": PRIM_CONTAINER, "cylinder": PRIM_CYLINDER}


@dataclass
class Primitives:
    """The analytic primitive table plus the colliders only drawable from their SDF."""

    params: np.ndarray = field(default_factory=lambda: np.zeros((0, 16)))     # (P, 16) float64
    kinds: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # (P,) int64
    generic: list = field(default_factory=list)                               # colliders
    indices: list = field(default_factory=list)                               # collider index per row

    def key(self) -> bytes:
        return self.params.tobytes() + self.kinds.tobytes() + bytes(len(self.generic))


def _get(obj, *names):
    for name in names:
        value = getattr(obj, name, None)
        if value is not None and not callable(value):
            return value
    return None


def _vec3(value) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    return np.append(v, 0.0) if v.size == 2 else v[:3]


def _rotation_matrix(rotation, dim: int) -> np.ndarray:
    """A (3, 3) world-from-local rotation from a matrix, a quaternion (w, x, y, z) or a 2-D angle."""
    if rotation is None:
        return np.eye(3)
    r = np.asarray(rotation, dtype=np.float64)
    if r.shape == ():  # a 2-D angle in radians
        c, s = np.cos(float(r)), np.sin(float(r))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    if r.shape == (2, 2):
        m = np.eye(3)
        m[:2, :2] = r
        return m
    if r.shape == (3, 3):
        return r
    if r.shape == (4,):
        w, x, y, z = r / np.linalg.norm(r)
        return np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ])
    raise ValueError(f"collider rotation: expected an angle, a (D, D) matrix or a quaternion, got shape {r.shape}")


def _kind_of(collider) -> int | None:
    name = type(collider).__name__.lower()
    for key in sorted(_KINDS, key=len, reverse=True):
        if key in name:
            return _KINDS[key]
    return None


def _describe(collider, t: float):
    """(kind, attribute source, pose) for a collider, or None when it has no analytic form."""
    hook = getattr(collider, "render_primitive", None)
    if callable(hook):
        kind, params = hook(t)
        return _KINDS[str(kind).lower()], params, None
    kind = _kind_of(collider)
    if kind is None:
        return None
    pose = None
    for name in ("pose", "transform"):
        fn = getattr(collider, name, None)
        if callable(fn) and getattr(collider, "motion", None) is not None:
            p, rotation = fn(t)
            rotation = _rotation_matrix(rotation, 3)
            ref = getattr(collider, "rest_point", None)
            ref = np.zeros(3) if ref is None or callable(ref) else _vec3(ref)
            pose = (_vec3(p) - rotation @ ref, rotation)
            break
    if getattr(collider, "motion", None) is not None and pose is None:
        return None  # moving, and no way to know where: fall back to the SDF
    return kind, collider, pose


def _row(kind: int, src, dim: int) -> np.ndarray | None:
    def get(*names):
        if isinstance(src, dict):
            for n in names:
                if src.get(n) is not None:
                    return src[n]
            return None
        return _get(src, *names)

    row = np.zeros(16)
    if kind == PRIM_PLANE:
        normal = get("normal_vector", "normal")
        if normal is None:
            return None
        n = _vec3(normal)
        n = n / np.linalg.norm(n)
        point = get("point", "origin", "position")
        if point is None:
            offset = get("offset", "distance", "d", "height")
            point = n * float(offset or 0.0)
        row[0:3], row[3:6] = _vec3(point), n
        return row
    if kind == PRIM_SPHERE:
        center, radius = get("center", "centre", "position"), get("radius")
        if center is None or radius is None:
            return None
        row[0:3], row[3] = _vec3(center), float(radius)
        return row
    if kind == PRIM_CONTAINER:
        center, half = get("center", "centre"), get("half_extents")
        if center is None or half is None:
            return None
        h = np.asarray(half, dtype=np.float64).reshape(-1)
        normals = get("plane_normals")
        rot = np.eye(3)
        if normals is not None and len(normals) == 2 * dim:
            # Wall 2k faces inward along +axis k: the box's k-th axis.
            for k in range(dim):
                rot[:dim, k] = np.asarray(normals[2 * k], dtype=np.float64)[:dim]
            if dim == 3 and np.linalg.det(rot) < 0:
                rot[:, 2] *= -1.0
        row[0:3] = _vec3(center)
        row[3:6] = _vec3(h) if dim == 3 else np.array([h[0], h[1], 1e9])
        row[6:15] = rot.T.reshape(-1)
        return row
    if kind == PRIM_CYLINDER:
        center, axis = get("center", "centre"), get("axis")
        radius, half_height = get("radius"), get("half_height", "half_length")
        if center is None or radius is None or half_height is None:
            return None
        u = _vec3(axis if axis is not None else (0.0, 0.0, 1.0))
        u = u / np.linalg.norm(u)
        c = _vec3(center)
        row[0:3], row[3:6], row[6] = c - float(half_height) * u, c + float(half_height) * u, float(radius)
        return row
    if kind == PRIM_BOX:
        center = get("center", "centre", "position")
        half = get("half_extents", "half_size", "halfsize", "half_extent")
        if half is None:
            full = get("size", "extents", "extent")
            half = None if full is None else 0.5 * np.asarray(full, dtype=np.float64)
        if half is None:
            lo, hi = get("lower", "min_corner", "lo"), get("upper", "max_corner", "hi")
            if lo is not None and hi is not None:
                center = 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))
                half = 0.5 * (np.asarray(hi, float) - np.asarray(lo, float))
        if center is None or half is None:
            return None
        h = np.broadcast_to(np.asarray(half, dtype=np.float64).reshape(-1), (dim,))
        rot = _rotation_matrix(get("rotation", "orientation", "angle"), dim)
        row[0:3] = _vec3(center)
        row[3:6] = _vec3(h) if dim == 3 else np.array([h[0], h[1], 1e9])
        row[6:15] = rot.T.reshape(-1)  # rows of R^T: local = R^T (p - c)
        return row
    if kind == PRIM_CAPSULE:
        a, b = get("a", "p0", "start", "point_a"), get("b", "p1", "end", "point_b")
        if a is None or b is None:
            pts = get("points", "endpoints", "segment")
            if pts is None:
                center, half_length = get("center", "centre"), get("half_length", "half_height")
                if center is None or half_length is None:
                    return None
                axis = _rotation_matrix(get("rotation", "orientation", "angle"), dim)[:, 0]
                a = _vec3(center) - float(half_length) * axis
                b = _vec3(center) + float(half_length) * axis
            else:
                a, b = np.asarray(pts, dtype=np.float64)[:2]
        radius = get("radius")
        if radius is None:
            return None
        row[0:3], row[3:6], row[6] = _vec3(a), _vec3(b), float(radius)
        return row
    return None


def _apply_pose(kind: int, row: np.ndarray, pose) -> np.ndarray:
    translation, rotation = pose
    trans = _vec3(translation)
    rot = _rotation_matrix(rotation, 3)
    row = row.copy()
    if kind == PRIM_PLANE:
        row[0:3] = rot @ row[0:3] + trans
        row[3:6] = rot @ row[3:6]
    elif kind == PRIM_SPHERE:
        row[0:3] = rot @ row[0:3] + trans
    elif kind in (PRIM_BOX, PRIM_CONTAINER):
        row[0:3] = rot @ row[0:3] + trans
        world_from_local = rot @ row[6:15].reshape(3, 3).T
        row[6:15] = world_from_local.T.reshape(-1)
    else:
        row[0:3] = rot @ row[0:3] + trans
        row[3:6] = rot @ row[3:6] + trans
    return row


def collider_primitives(colliders, t: float, dim: int) -> Primitives:
    """Describe ``colliders`` at time ``t`` as analytic primitives (and the rest as generic)."""
    rows, kinds, generic, indices = [], [], [], []
    for index, collider in enumerate(colliders or ()):
        described = _describe(collider, t)
        row = None
        if described is not None:
            kind, src, pose = described
            row = _row(kind, src, dim)
            if row is not None and pose is not None:
                row = _apply_pose(kind, row, pose)
        if row is None:
            if not callable(getattr(collider, "signed_distance", None)):
                raise TypeError(f"cannot draw collider {collider!r}: it has no signed_distance(points, t)")
            generic.append(collider)
            continue
        rows.append(row)
        kinds.append(kind)
        indices.append(index)
    params = np.array(rows, dtype=np.float64).reshape(-1, 16)
    return Primitives(params, np.array(kinds, dtype=np.int64), generic, indices)


def collider_bounds(prims: Primitives) -> tuple[np.ndarray, np.ndarray] | None:
    """World bounding box (lower, upper) of the finite analytic primitives, or None."""
    lows, highs = [], []
    for row, kind in zip(prims.params, prims.kinds, strict=True):
        if kind == PRIM_SPHERE:
            lows.append(row[0:3] - row[3])
            highs.append(row[0:3] + row[3])
        elif kind in (PRIM_BOX, PRIM_CONTAINER):
            half = np.where(row[3:6] > 1e8, 0.0, row[3:6])
            world_from_local = row[6:15].reshape(3, 3).T
            reach = np.abs(world_from_local) @ half
            lows.append(row[0:3] - reach)
            highs.append(row[0:3] + reach)
        elif kind in (PRIM_CAPSULE, PRIM_CYLINDER):
            lows.append(np.minimum(row[0:3], row[3:6]) - row[6])
            highs.append(np.maximum(row[0:3], row[3:6]) + row[6])
    if not lows:
        return None
    return np.min(lows, axis=0), np.max(highs, axis=0)


def trace_signed_distance(collider, t: float, origins: np.ndarray, directions: np.ndarray, *,
                          max_distance: float, tolerance: float, max_steps: int = 96):
    """Sphere-trace rays against ``collider.signed_distance`` (Hart 1996, "Sphere tracing").

    origins/directions (M, 3). Returns (distance along the ray (M,), NaN for a miss; world
    normals (M, 3)). Only the rays still marching are evaluated each step.
    """
    dim = int(getattr(collider, "dim", 3))
    count = origins.shape[0]
    travelled = np.zeros(count)
    alive = np.arange(count)
    hit = np.zeros(count, dtype=bool)
    for _ in range(max_steps):
        if alive.size == 0:
            break
        points = origins[alive] + travelled[alive, None] * directions[alive]
        d = np.asarray(collider.signed_distance(np.ascontiguousarray(points[:, :dim]), t), dtype=np.float64)
        done = d < tolerance
        hit[alive[done]] = True
        travelled[alive] += np.where(done, 0.0, np.maximum(d, tolerance * 0.5))
        alive = alive[~done & (travelled[alive] < max_distance)]
    distance = np.where(hit, travelled, np.nan)
    normals = np.zeros((count, 3))
    if hit.any():
        points = origins[hit] + travelled[hit, None] * directions[hit]
        n = np.asarray(collider.normal(np.ascontiguousarray(points[:, :dim]), t), dtype=np.float64)
        normals[hit, :dim] = n
    return distance, normals
