"""Collider shapes: what a collider *is* (geometry, rest pose, prescribed motion).

Every collider answers, for many points at once, the signed distance (negative inside the
solid), the unit outward normal and the velocity of the collider's surface material:

    collider.signed_distance(points, t=0.0) -> (M,)
    collider.normal(points, t=0.0)          -> (M, D)
    collider.velocity(points, t=0.0)        -> (M, D)
    collider.query(points, t, distance_out, normal_out, velocity_out)   (preallocated outputs)

``points`` is an (M, D) float64 array, D = ``collider.dim``. Colliders are static unless built
with ``motion=`` (a ``Motion``, or a callable t -> position of the reference point); a moving
collider carries particles along and hits them with its surface velocity.

References
----------
- Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes,
  "Particle System Dynamics": point-plane collision.
- Osher, S. & Fedkiw, R. (2003), *Level Set Methods and Dynamic Implicit Surfaces*: implicit
  (signed distance) shapes.
- Quilez, I., "Distance functions": the analytic box, capsule and cylinder distances.

Limitations
-----------
- ``Cylinder`` and ``Mesh`` are 3-D only; the others exist in 2-D and 3-D.
- Shapes are rigid; motions are rigid (see ``inertia.collision.motion``).
- ``SDF`` trusts the user's function to be (close to) a true distance: 1-Lipschitz, negative
  inside. Unbaked it is evaluated in NumPy each step (slower, see ``SDF``).
"""

from __future__ import annotations

import numpy as np

from .. import _validate
from . import distance as _d
from ..geometry import shapes as _S
from ..math import mat3_to_quat
from .motion import Motion, as_rotation

__all__ = ["Collider", "Plane", "Sphere", "Box", "Capsule", "Cylinder", "Container", "SDF"]


def _vec3(value, name, dim=None):
    v = _validate.as_vector(value, name, dim)
    out = np.zeros(3)
    out[:v.shape[0]] = v
    return out, v.shape[0]


def _positive(value, name):
    return _validate.positive_scalar(value, name)


def _as_motion(motion):
    if motion is None or isinstance(motion, Motion):
        return motion
    if callable(motion):
        return Motion(position=motion)
    raise ValueError(f"motion must be None, an inertia.colliders.Motion or a callable t -> position; "
                     f"got {type(motion).__name__}")


def _quat_z_to(axis) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of the shortest rotation taking +z onto the unit vector `axis`."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    w = 1.0 + a[2]
    if w < 1e-12:                       # axis = -z: half turn about x
        return np.array([0.0, 1.0, 0.0, 0.0])
    q = np.array([w, -a[1], a[0], 0.0])  # (1 + z.a, z x a)
    return q / np.linalg.norm(q)


def _pose(position, q=(1.0, 0.0, 0.0, 0.0)) -> np.ndarray:
    return np.concatenate([np.asarray(position, dtype=np.float64).reshape(3), np.asarray(q, dtype=np.float64)])


def _row(kind, position, q=(1.0, 0.0, 0.0, 0.0), params=(), **extra) -> dict:
    p = np.zeros(4)
    p[:len(params)] = params
    return dict(type=kind, pose=_pose(position, q), params=p, **extra)


class Collider:
    """Base class of every collider (see the module docstring for the query interface).

    Attributes
    ----------
    dim : int
        2 or 3.
    motion : Motion or None
        Prescribed motion; None for a static collider.
    rest_point : (D,) float64
        Reference point (centre; a plane's ``point``) that ``motion`` positions and rotates about.
    """

    kind = -1

    def __init__(self, dim: int, rest_point: np.ndarray, cf, ci=None, motion=None):
        self.dim = int(dim)
        self._ref = np.asarray(rest_point, dtype=np.float64).reshape(3).copy()
        self._cf = np.ascontiguousarray(cf, dtype=np.float64)
        self._ci = np.ascontiguousarray(np.zeros(1, np.int64) if ci is None else ci, dtype=np.int64)
        self.motion = _as_motion(motion)

    # --- pose --------------------------------------------------------------------------------
    @property
    def rest_point(self) -> np.ndarray:
        return self._ref[:self.dim].copy()

    @property
    def moving(self) -> bool:
        return self.motion is not None

    def pose(self, t: float = 0.0):
        """(p (3,), R (3, 3)): where the reference point is and how the shape is rotated at t."""
        if self.motion is None:
            return self._ref.copy(), np.eye(3)
        return self.motion.pose(t, self.dim, self._ref)

    def _packed_pose(self, t):
        p, r = self.pose(t)
        return np.concatenate([p, r.reshape(-1)])

    def _rigid_velocity(self, t):
        """(v_ref (3,), omega (3,)) at t by central differences of the pose."""
        if self.motion is None:
            return np.zeros(3), np.zeros(3)
        h = 1e-6 * max(1.0, abs(t))
        p0, r0 = self.pose(t - h)
        p1, r1 = self.pose(t + h)
        v = (p1 - p0) / (2 * h)
        # R1 R0^T = exp([w] 2h)
        dr = r1 @ r0.T
        omega = np.array([dr[2, 1] - dr[1, 2], dr[0, 2] - dr[2, 0], dr[1, 0] - dr[0, 1]]) / (4 * h)
        return v, omega

    # --- queries -----------------------------------------------------------------------------
    def _points(self, points):
        return _validate.as_points(points, "points", dim=self.dim)

    def query(self, points, t, distance_out, normal_out, velocity_out) -> None:
        """Fill distance_out (M,), normal_out (M, D), velocity_out (M, D) at world points (M, D)."""
        points = self._points(points)
        pose = self._packed_pose(t)
        v, w = self._rigid_velocity(t)
        kinds = _d.kinds_token((self.kind,))   # compile this kind's distance only
        _d.query_points(points, kinds, self.kind, self._cf, self._ci, pose, self._ref, self.moving, v, w,
                        distance_out, normal_out, velocity_out)

    def _query_new(self, points, t):
        points = self._points(points)
        m = points.shape[0]
        d, n, v = np.empty(m), np.empty((m, self.dim)), np.empty((m, self.dim))
        self.query(points, t, d, n, v)
        return d, n, v

    def signed_distance(self, points, t: float = 0.0) -> np.ndarray:
        """(M,) signed distance of each point to the surface (negative inside the solid)."""
        return self._query_new(points, t)[0]

    def normal(self, points, t: float = 0.0) -> np.ndarray:
        """(M, D) unit outward normal (gradient of the signed distance)."""
        return self._query_new(points, t)[1]

    def velocity(self, points, t: float = 0.0) -> np.ndarray:
        """(M, D) velocity of the collider's surface material at the points."""
        return self._query_new(points, t)[2]

    def __repr__(self):
        return f"{type(self).__name__}(dim={self.dim}{', moving' if self.moving else ''})"

    # --- shape-table rows --------------------------------------------------------------------
    def shape_rows(self) -> list[dict]:
        """This collider as rows of the Model's shape table (3-D colliders only).

        Each row is a dict: ``type`` (an ``inertia.geometry.shapes`` code), ``pose`` (7,) (position,
        quaternion w, x, y, z) *relative to the collider's rest frame* (its reference point, rest
        orientation), ``params`` (4,), and for meshes ``vertices`` (V, 3) / ``triangles`` (T, 3) in
        that frame. A static collider's rows sit on body -1 at ``rest_point + pose``; a moving one's
        on a kinematic body whose pose is the collider's ``pose(t)`` (see ``inertia.model.with_colliders``).
        """
        if self.dim != 3:
            raise ValueError(f"{type(self).__name__} is {self.dim}-D; only 3-D colliders become shape-table rows")
        return [dict(type=_S.SDF, pose=_pose(np.zeros(3)), params=np.zeros(4))]


class Plane(Collider):
    """Half-space below the plane through ``point`` with unit outward ``normal``.

    Parameters: ``point`` (D,), ``normal`` (D,) non-zero (normalised here); free space is on the
    side the normal points to. 2-D: a line. Reference point: ``point``.
    """

    kind = _d.PLANE

    def __init__(self, point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), *, motion=None):
        p, dim = _vec3(point, "point")
        n, ndim = _vec3(normal, "normal")
        if ndim != dim:
            raise ValueError(f"point and normal must have the same number of components; got {dim} and {ndim}")
        length = np.linalg.norm(n)
        if not length > 1e-12:
            raise ValueError(f"normal must be a non-zero vector; got {n[:dim].tolist()}")
        n = n / length
        self.point, self.normal_vector = p[:dim].copy(), n[:dim].copy()
        super().__init__(dim, p, [n[0], n[1], n[2], float(n @ p)], motion=motion)

    def shape_rows(self):
        Collider.shape_rows(self)
        return [_row(_S.PLANE, np.zeros(3), _quat_z_to(self.normal_vector))]


class Sphere(Collider):
    """Solid ball of ``radius`` > 0 around ``center`` (a disc in 2-D). Reference point: centre."""

    kind = _d.SPHERE

    def __init__(self, center=(0.0, 0.0, 0.0), radius=1.0, *, motion=None):
        c, dim = _vec3(center, "center")
        self.center, self.radius = c[:dim].copy(), _positive(radius, "radius")
        super().__init__(dim, c, [c[0], c[1], c[2], self.radius], motion=motion)

    def shape_rows(self):
        Collider.shape_rows(self)
        return [_row(_S.SPHERE, np.zeros(3), params=(self.radius,))]


def _center_extents_rotation(center, half_extents, rotation):
    """Validated (center as 3-vector, half_extents (D,) > 0, rotation (3, 3), dim) of a box-like shape."""
    c, dim = _vec3(center, "center")
    h = _validate.as_vector(half_extents, "half_extents", dim)
    if np.any(h <= 0):
        raise ValueError(f"half_extents must all be > 0; got {h.tolist()}")
    return c, h, as_rotation(rotation, dim, "rotation"), dim


class Box(Collider):
    """Solid oriented box: ``center`` (D,), ``half_extents`` (D,) > 0, ``rotation`` (see
    ``inertia.colliders.as_rotation``: 2-D angle, 3-D matrix / quaternion (w, x, y, z) /
    rotation vector). Reference point: centre."""

    kind = _d.BOX

    def __init__(self, center=(0.0, 0.0, 0.0), half_extents=(0.5, 0.5, 0.5), rotation=None, *,
                 motion=None):
        c, h, r, dim = _center_extents_rotation(center, half_extents, rotation)
        self.center, self.half_extents, self.rotation = c[:dim].copy(), h.copy(), r[:dim, :dim].copy()
        h3 = np.full(3, _d.BIG)
        h3[:dim] = h
        super().__init__(dim, c, np.concatenate([c, r.reshape(-1), h3]), motion=motion)

    def shape_rows(self):
        Collider.shape_rows(self)
        return [_row(_S.BOX, np.zeros(3), mat3_to_quat(np.ascontiguousarray(self.rotation)),
                     params=self.half_extents)]


class Capsule(Collider):
    """Solid capsule: all points within ``radius`` > 0 of the segment ``a``-``b`` (2-D: a
    stadium). Reference point: the segment's midpoint."""

    kind = _d.CAPSULE

    def __init__(self, a=(0.0, 0.0, -0.5), b=(0.0, 0.0, 0.5), radius=0.25, *, motion=None):
        pa, dim = _vec3(a, "a")
        pb, bdim = _vec3(b, "b")
        if bdim != dim:
            raise ValueError(f"a and b must have the same number of components; got {dim} and {bdim}")
        self.a, self.b, self.radius = pa[:dim].copy(), pb[:dim].copy(), _positive(radius, "radius")
        super().__init__(dim, 0.5 * (pa + pb), np.concatenate([pa, pb, [self.radius]]), motion=motion)

    def shape_rows(self):
        Collider.shape_rows(self)
        axis = self.b - self.a
        half = 0.5 * float(np.linalg.norm(axis))
        if half == 0.0:                  # a ball
            return [_row(_S.SPHERE, np.zeros(3), params=(self.radius,))]
        return [_row(_S.CAPSULE, np.zeros(3), _quat_z_to(axis), params=(self.radius, half))]


class Cylinder(Collider):
    """Solid capped cylinder (3-D only): ``center``, ``radius`` > 0, ``half_height`` > 0 along the
    unit ``axis`` (default +z). Reference point: centre."""

    kind = _d.CYLINDER

    def __init__(self, center=(0.0, 0.0, 0.0), radius=0.5, half_height=0.5, *, axis=(0.0, 0.0, 1.0),
                 motion=None):
        c, _dim = _vec3(center, "center", 3)
        u = _validate.as_vector(axis, "axis", 3)
        length = np.linalg.norm(u)
        if not length > 1e-12:
            raise ValueError(f"axis must be a non-zero vector; got {u.tolist()}")
        u = u / length
        self.center, self.axis = c.copy(), u
        self.radius, self.half_height = _positive(radius, "radius"), _positive(half_height, "half_height")
        super().__init__(3, c, np.concatenate([c, u, [self.radius, self.half_height]]), motion=motion)

    def shape_rows(self):
        Collider.shape_rows(self)
        return [_row(_S.CYLINDER, np.zeros(3), _quat_z_to(self.axis), params=(self.radius, self.half_height))]


class Container(Collider):
    """A closed box that particles live *inside*: its walls are inward-facing planes.

    ``Container(center, half_extents, rotation=None)`` builds the 2*D walls of an oriented box;
    ``Container.from_planes(points, normals)`` any convex region (normals point inward, into the
    free space). The signed distance is positive inside (free space) and negative outside.
    Reference point: centre (the mean of the plane points for ``from_planes``).
    """

    kind = _d.CONTAINER

    def __init__(self, center=(0.0, 0.0, 0.0), half_extents=(0.5, 0.5, 0.5), rotation=None, *,
                 motion=None):
        c, h, r, dim = _center_extents_rotation(center, half_extents, rotation)
        self.center, self.half_extents = c[:dim].copy(), h.copy()
        normals, points = [], []
        for axis in range(dim):
            for sign in (-1.0, 1.0):
                out = sign * r[:, axis]            # outward axis of the box
                normals.append(-out)               # walls face inward
                points.append(c + h[axis] * out)
        self._init_planes(dim, c, np.array(points), np.array(normals), motion)

    @classmethod
    def from_planes(cls, points, normals, *, motion=None) -> "Container":
        """Convex container bounded by planes through ``points`` (P, D) with inward ``normals`` (P, D)."""
        pts = _validate.as_points(points, "points")
        nrm = _validate.as_points(normals, "normals", dim=pts.shape[1], count=pts.shape[0])
        lengths = np.linalg.norm(nrm, axis=1)
        if np.any(lengths <= 1e-12):
            raise ValueError(f"normals must be non-zero; rows {np.flatnonzero(lengths <= 1e-12).tolist()} are zero")
        dim = pts.shape[1]
        p3 = np.zeros((pts.shape[0], 3))
        n3 = np.zeros((pts.shape[0], 3))
        p3[:, :dim], n3[:, :dim] = pts, nrm / lengths[:, None]
        self = cls.__new__(cls)
        self.center, self.half_extents = pts.mean(axis=0), None
        self._init_planes(dim, p3.mean(axis=0), p3, n3, motion)
        return self

    def _init_planes(self, dim, ref, points, normals, motion):
        cf = np.concatenate([np.concatenate([n, [n @ p]]) for p, n in zip(points, normals, strict=True)])
        self.plane_points, self.plane_normals = points[:, :dim].copy(), normals[:, :dim].copy()
        Collider.__init__(self, dim, ref, cf, np.array([len(points)], np.int64), motion=motion)

    def shape_rows(self):
        """One PLANE row per wall (normal into the free space), so rigid bodies inside collide with
        the walls. A plane is unbounded: a body outside the container is pushed in (limitation)."""
        Collider.shape_rows(self)
        return [_row(_S.PLANE, p - self._ref, _quat_z_to(n))
                for p, n in zip(self.plane_points, self.plane_normals, strict=True)]


class SDF(Collider):
    """A user-defined implicit shape.

    Parameters
    ----------
    function : callable (M, D) -> (M,)
        Signed distance in the rest frame, vectorised with NumPy, negative inside the solid. It
        should be a true distance (or at least 1-Lipschitz) for the time-of-impact search.
    gradient : callable (M, D) -> (M, D), optional
        Its gradient; default: central differences with step ``1e-6 * scale``.
    dim : int
        2 or 3 (default 3).
    bake : dict, optional
        ``{"bounds": (lo, hi), "resolution": n}`` samples the function once on a grid with n
        cells along the longest side; the collider then runs inside the compiled kernels (fast)
        with the grid's limitations (see ``inertia.collision.distance``). Unbaked, the function is
        called from Python once or a few times per step on the candidate particles. Rigid bodies
        collide with the collider only when it is baked (its grid is their distance field,
        ``inertia.geometry.sdf_collide``).
    motion : Motion or callable, optional
    rest_point : (D,), optional
        Reference point for ``motion`` (default: the origin).
    """

    kind = _d.CALLABLE

    def __init__(self, function, *, gradient=None, dim=3, bake=None, motion=None, rest_point=None,
                 scale=1.0):
        if not callable(function):
            raise ValueError(f"function must be a callable (M, D) -> (M,); got {type(function).__name__}")
        if gradient is not None and not callable(gradient):
            raise ValueError(f"gradient must be a callable (M, D) -> (M, D); got {type(gradient).__name__}")
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3; got {dim!r}")
        self.function, self.gradient_function = function, gradient
        self.fd_step = 1e-6 * _positive(scale, "scale")
        ref = np.zeros(3)
        if rest_point is not None:
            ref, _dim = _vec3(rest_point, "rest_point", dim)
        Collider.__init__(self, dim, ref, np.zeros(1), motion=motion)
        self.baked = False
        if bake is not None:
            self._bake(bake)

    def _bake(self, bake):
        from .mesh import bake_callable
        if not isinstance(bake, dict) or "bounds" not in bake:
            raise ValueError("bake must be a dict with 'bounds': (lo, hi) and optionally 'resolution': n")
        lo = _validate.as_vector(bake["bounds"][0], "bake bounds lo", self.dim)
        hi = _validate.as_vector(bake["bounds"][1], "bake bounds hi", self.dim)
        if np.any(hi <= lo):
            raise ValueError(f"bake bounds must have hi > lo in every component; got lo={lo.tolist()}, hi={hi.tolist()}")
        resolution = int(bake.get("resolution", 64))
        if resolution < 2:
            raise ValueError(f"bake resolution must be >= 2; got {resolution}")
        self._cf, self._ci = bake_callable(self.evaluate_rest, lo, hi, resolution, self.dim)
        self.kind = _d.GRID
        self.baked = True

    def evaluate_rest(self, points):
        """(d (M,), unit gradient (M, D)) of the user's function at rest-frame points (M, D)."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        d = np.asarray(self.function(points), dtype=np.float64).reshape(-1)
        if d.shape[0] != points.shape[0]:
            raise ValueError(f"the SDF function must return one value per point ({points.shape[0]}); got {d.shape[0]}")
        if self.gradient_function is not None:
            g = np.asarray(self.gradient_function(points), dtype=np.float64).reshape(points.shape)
        else:
            g = np.empty_like(points)
            h = self.fd_step
            for c in range(points.shape[1]):
                p = points.copy()
                p[:, c] += h
                fp = np.asarray(self.function(p), dtype=np.float64).reshape(-1)
                p[:, c] -= 2 * h
                fm = np.asarray(self.function(p), dtype=np.float64).reshape(-1)
                g[:, c] = (fp - fm) / (2 * h)
        length = np.linalg.norm(g, axis=1)
        good = length > 0
        g[good] /= length[good, None]
        g[~good] = 0.0
        if g.shape[1] >= 1:
            g[~good, -1] = 1.0
        return d, g

    def query(self, points, t, distance_out, normal_out, velocity_out) -> None:
        if self.baked:
            return Collider.query(self, points, t, distance_out, normal_out, velocity_out)
        points = self._points(points)
        p, r = self.pose(t)
        dim = self.dim
        rest = self._ref[:dim] + (points - p[:dim]) @ r[:dim, :dim]  # R^T (x - p) row-wise
        d, g = self.evaluate_rest(rest)
        distance_out[:] = d
        normal_out[:] = g @ r[:dim, :dim].T
        v, w = self._rigid_velocity(t)
        rel = np.zeros((points.shape[0], 3))
        rel[:, :dim] = points - p[:dim]
        velocity_out[:] = (v + np.cross(w, rel))[:, :dim]


class BodyShape(Collider):
    """A row of the Model's shape table as particles see it (built by the particle stage from the row).

    The packed data (``_cf``, ``_ci``) is the row's geometry in its body's frame (reference point the
    body-frame origin, the centre of mass); the particle stage is handed the body's pose at the start
    and end of each step (``pose0``/``pose1`` rows written by the world from ``body_q``, and the body's
    velocity ``body_qd``), so the kernels treat it as a moving collider whose material moves with the
    body at v + w x (x - c) (``particle_kernels._body_velocity``). Rows on body -1 and on static
    bodies are packed once in world coordinates and are static colliders.

    Mapping: SPHERE, BOX, CAPSULE, CYLINDER, PLANE to the closed-form kinds; CONVEX_HULL (its outward
    triangulated hull) and TRIANGLE_MESH to a distance-grid ``Mesh`` (``inertia.collision.mesh``);
    HEIGHTFIELD to the ``Mesh`` of its triangles closed below (``collision.heightfield_distance``);
    SDF rows are not mapped: they always come from particle colliders, which particles see directly
    (``system.add_collider``), and rigid bodies collide with the baked ones (``geometry.sdf_collide``).
    """

    def __init__(self, model, shape: int, body_pose=None):
        from ..math import quat_to_mat3, transform_mul
        self.shape, self.body = int(shape), int(model.shape_body[shape])
        self.from_body = True
        t = int(model.shape_type[shape])
        local = np.ascontiguousarray(model.shape_local_pose[shape], dtype=np.float64)
        self._moves = self.body >= 0 and int(model.body_type[self.body]) != _S.STATIC
        if self.body >= 0 and not self._moves:        # a static body: bake its pose in
            q0 = model.state().body_q[self.body] if body_pose is None else body_pose
            local = transform_mul(np.ascontiguousarray(q0, dtype=np.float64), local)
        p, r = local[:3].copy(), quat_to_mat3(np.ascontiguousarray(local[3:]))
        par = model.shape_params[shape]
        ci = None
        if t == _S.SPHERE:
            self.kind, cf = _d.SPHERE, [p[0], p[1], p[2], par[0]]
        elif t == _S.BOX:
            self.kind, cf = _d.BOX, np.concatenate([p, r.reshape(-1), par[:3]])
        elif t == _S.CAPSULE:
            a, b = p - par[1] * r[:, 2], p + par[1] * r[:, 2]
            self.kind, cf = _d.CAPSULE, np.concatenate([a, b, [par[0]]])
        elif t == _S.CYLINDER:
            self.kind, cf = _d.CYLINDER, np.concatenate([p, r[:, 2], par[:2]])
        elif t == _S.PLANE:
            n = r[:, 2]
            self.kind, cf = _d.PLANE, [n[0], n[1], n[2], float(n @ p)]
        elif t in (_S.CONVEX_HULL, _S.TRIANGLE_MESH):
            from .mesh import Mesh, _watertight
            v0, nv = int(model.shape_vert_start[shape]), int(model.shape_vert_count[shape])
            verts = model.geom_vertices[v0:v0 + nv]
            if t == _S.CONVEX_HULL:
                verts, faces = hull_triangles(verts)
            else:
                verts, inverse = np.unique(verts, axis=0, return_inverse=True)
                faces = inverse.reshape(-1, 3).astype(np.int64)
            mesh = Mesh((p + verts @ r.T, faces), signed=_watertight(faces))
            self.kind, cf, ci = _d.GRID, mesh._cf, mesh._ci
        elif t == _S.HEIGHTFIELD:
            # the rigid side's triangles closed below into a solid (collision/heightfield_distance.py)
            from .heightfield_distance import heightfield_closed_mesh
            from .mesh import Mesh
            v0, nv = int(model.shape_vert_start[shape]), int(model.shape_vert_count[shape])
            verts, faces = heightfield_closed_mesh(model.geom_vertices[v0:v0 + nv], int(par[0]), int(par[1]))
            mesh = Mesh((p + verts @ r.T, faces), signed=True)
            self.kind, cf, ci = _d.GRID, mesh._cf, mesh._ci
        else:
            self.kind, cf = _d.CALLABLE, np.zeros(1)
            self.unsupported = True
        Collider.__init__(self, 3, np.zeros(3), cf, ci)

    @property
    def moving(self) -> bool:
        return self._moves

    def bind(self, body_pose, body_velocity) -> "BodyShape":
        """Follow a live body: ``body_pose(t) -> (7,)`` pose and ``body_velocity(t) -> (6,)`` (angular,
        linear) at time t (the world's `World.shape_collider` binds its rigid state). Then ``pose``,
        ``query``, ``signed_distance``, ``normal`` and ``velocity`` (surface velocity v + w x r) answer
        for the body where it is, so the shape serves as a boundary of curl-noise fields and the like."""
        self._live = (body_pose, body_velocity)
        return self

    def pose(self, t: float = 0.0):
        live = getattr(self, "_live", None)
        if live is None or not self._moves:
            return Collider.pose(self, t)
        from ..math import quat_to_mat3_into
        q = np.asarray(live[0](t), dtype=np.float64)
        # R written by the kernel into an array made here: the caller owns the returned pair
        return q[:3].copy(), quat_to_mat3_into(np.ascontiguousarray(q[3:]), np.empty((3, 3)))

    def _rigid_velocity(self, t):
        live = getattr(self, "_live", None)
        if live is None or not self._moves:
            return np.zeros(3), np.zeros(3)
        qd = np.asarray(live[1](t), dtype=np.float64)
        return qd[3:].copy(), qd[:3].copy()

    def shape_rows(self):
        raise ValueError("a BodyShape already is a shape-table row")

    def __repr__(self):
        return f"BodyShape(shape={self.shape}, body={self.body})"


def hull_triangles(points):
    """(vertices (V, 3), faces (F, 3) int64) of the convex hull of `points`, faces wound outward
    (counter-clockwise seen from outside). Qhull (scipy.spatial.ConvexHull) gives the facets."""
    from scipy.spatial import ConvexHull
    pts = np.asarray(points, dtype=np.float64)
    hull = ConvexHull(pts)
    used = np.unique(hull.simplices)
    remap = np.full(len(pts), -1, np.int64)
    remap[used] = np.arange(len(used))
    verts = pts[used]
    faces = remap[hull.simplices].astype(np.int64)
    centre = verts.mean(axis=0)
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - centre) < 0
    faces[flip] = faces[flip][:, ::-1]
    return verts, faces
