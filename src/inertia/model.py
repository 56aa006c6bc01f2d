"""Model / State / Control and the builder that makes them (DESIGN.md "Model, State, Control, Contacts").

What a scene *is* lives in a `Model` (flat arrays named ``<entity>_<quantity>``, built once by
`ModelBuilder.finalize()`, never written during a step). What *changes* lives in a `State`
(``model.state()``); what the user sets each step lives in a `Control` (``model.control()``).
The narrow phase writes `inertia.dynamics.contacts.Contacts`.

Conventions
- Body pose ``body_q (B, 7)`` = ``(px, py, pz, qw, qx, qy, qz)``: the position of the centre of mass
  and the orientation of the principal axes in the world (the *body frame*).
- Body velocity ``body_qd (B, 6)`` = ``(wx, wy, wz, vx, vy, vz)``: angular velocity (rad/s, world
  frame) first, then the linear velocity of the centre of mass (m/s, world frame) -- the spatial
  (angular, linear) order of ``inertia.math`` and of the articulated layer to come.
- Bodies are ``dynamic`` (moved by forces and contacts), ``kinematic`` (moved by their velocity only,
  infinite mass; they push dynamic bodies) or ``static`` (never move). World geometry can also be
  attached to body ``-1``.
- A body's user frame (the pose given to ``add_body``) may differ from its body frame when its shapes
  are off-centre; ``body_com_pose (B, 7)`` is the body frame in the user frame, and the shapes' local
  poses are stored in the body frame.

Mass properties of primitives are the closed forms (solid sphere 2/5 m r^2, box m (b^2 + c^2)/12,
capsule = cylinder + two hemispheres with the hemisphere centroid offset 3r/8, cylinder
m (3 r^2 + h^2)/12); several shapes combine by the parallel-axis theorem and are diagonalised to
principal axes. Convex hulls get theirs from the exact polyhedral integration of
``inertia.geometry.mass`` (Mirtich 1996), like the primitives, from their density. For a solid that is not a
shape (hemisphere, torus, tube, shell, cone, thin rod), take ``mass`` and ``inertia`` from that module's
routines and give them to ``add_body``, with the body's position at the solid's centre of mass:
``p = hemisphere_mass_properties(0.2, 1000.0)``, ``add_body(position=p.com, mass=p.mass, inertia=p.inertia)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ._validate import positive_scalar
from .geometry import shapes as S
from .geometry.mass import shape_mass_properties
from .math import mat3_mul, mat3_to_quat, mat3_transpose, mat3_vec, quat_to_mat3, transform_inv, transform_mul

__all__ = ["ModelBuilder", "Model", "State", "Control", "Material", "BodyArrays", "ShapeArrays"]


class Material(NamedTuple):
    """Surface and bulk material. friction: Coulomb coefficient (0.6 default; combined by geometric
    mean); restitution: 0..1 (0 default; combined by max); rolling_friction: lever arm in metres of the
    rolling-resistance torque ``mu_r N`` (0 default; combined by max); density kg/m^3 (1000)."""
    friction: float = 0.6
    restitution: float = 0.0
    rolling_friction: float = 0.0
    density: float = 1000.0


class BodyArrays(NamedTuple):
    """Kernel bundle of the Model's body columns (read-only in a step)."""
    body_type: np.ndarray
    body_inv_mass: np.ndarray
    body_inv_inertia: np.ndarray
    body_linear_damping: np.ndarray
    body_angular_damping: np.ndarray
    body_bound_radius: np.ndarray


class ShapeArrays(NamedTuple):
    """Kernel bundle of the shape table (read-only in a step)."""
    shape_type: np.ndarray
    shape_body: np.ndarray
    shape_local_pose: np.ndarray
    shape_params: np.ndarray
    shape_margin: np.ndarray
    shape_friction: np.ndarray
    shape_restitution: np.ndarray
    shape_rolling_friction: np.ndarray
    shape_group: np.ndarray
    shape_mask: np.ndarray
    shape_is_sensor: np.ndarray
    shape_vert_start: np.ndarray
    shape_vert_count: np.ndarray
    geom_vertices: np.ndarray
    geom_bvh_bounds: np.ndarray
    geom_bvh_nodes: np.ndarray
    shape_bvh_start: np.ndarray


def _unit_quat(value, name):
    q = np.asarray(value, dtype=np.float64).reshape(-1)
    if q.shape != (4,) or not np.all(np.isfinite(q)):
        raise ValueError(f"{name} must be a finite quaternion (w, x, y, z); got {value!r}")
    n = math.sqrt(float(np.sum(q * q)))   # not np.linalg.norm: its BLAS dot rounds by CPU kernel
    if abs(n - 1.0) > 1e-6:
        raise ValueError(f"{name} must be a unit quaternion (w, x, y, z) with |q| = 1 within 1e-6; "
                         f"got |q| = {n:.9g} for {q.tolist()}")
    return q / n


def _vec3(value, name):
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be 3 finite numbers; got {value!r}")
    return v


def _nonneg(value, name, upper=None):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number >= 0; got {value!r}") from None
    if not math.isfinite(x) or x < 0 or (upper is not None and x > upper):
        rng = f"in [0, {upper}]" if upper is not None else ">= 0"
        raise ValueError(f"{name} must be a finite number {rng}; got {value!r}")
    return x


class Model:
    """Constant description of a rigid scene (built by `ModelBuilder.finalize`; never written in a step).

    Bodies (B rows, insertion order)
    - ``body_type (B,) int32``: 0 dynamic, 1 kinematic, 2 static (``inertia.geometry.shapes``).
    - ``body_mass (B,)`` kg; ``body_inv_mass (B,)`` 1/kg (0 for kinematic and static bodies).
    - ``body_inertia (B, 3)`` kg m^2, principal moments about the centre of mass;
      ``body_inv_inertia (B, 3)`` their inverses (0 for non-dynamic bodies).
    - ``body_com_pose (B, 7)``: body frame (centre of mass, principal axes) in the user frame.
    - ``body_linear_damping``, ``body_angular_damping (B,)`` 1/s: dv/dt = -c v.
    - ``body_bound_radius (B,)`` m: radius about the centre of mass enclosing every finite shape
      (for velocity fattening of the broad-phase boxes).
    - ``body_name``: list of B names.
    - ``body_bullet (B,) bool``: swept for time of impact every step (``add_body(bullet=True)``).

    Shapes (S rows, insertion order) -- the contract's shape table:
    ``shape_type (S,) int32``, ``shape_body (S,) int32`` (-1 static world), ``shape_local_pose (S, 7)``
    (in the body frame), ``shape_params (S, 4)`` (see `inertia.geometry.shapes`), ``shape_margin (S,)`` m
    (speculative distance), ``shape_friction``, ``shape_restitution``, ``shape_rolling_friction`` (m),
    ``shape_density`` kg/m^3, ``shape_group``, ``shape_mask (S,) int32`` bitmasks (a pair collides when
    ``group_a & mask_b`` and ``group_b & mask_a`` are both non-zero), ``shape_is_sensor (S,) bool``
    (overlap events, no response), ``shape_vert_start``, ``shape_vert_count (S,) int32`` into
    ``geom_vertices (V, 3)`` m (hull vertices, mesh triangle lists, heightfield grid points; shape frame);
    ``geom_bvh_bounds (N, 6)``, ``geom_bvh_nodes (N, 3) int32`` mesh BVH nodes from
    ``shape_bvh_start (S,) int32`` (-1: no BVH; `inertia.geometry.bvh`). Baked ``SDF`` rows: their packed
    distance grids (``inertia.collision.distance`` GRID layout) in ``sdf_grid_f (F,)`` and
    ``sdf_grid_i (I,) int64`` from ``shape_sdf_start (S, 2) int64`` (float, integer offset; -1: no grid;
    `inertia.geometry.sdf_collide`).

    World: ``gravity (3,)`` m/s^2.
    """

    def __init__(self, **arrays):
        for k, v in arrays.items():
            setattr(self, k, v)
        self.body_count = len(self.body_type)
        self.shape_count = len(self.shape_type)

    def bodies(self) -> BodyArrays:
        return BodyArrays(*(getattr(self, f) for f in BodyArrays._fields))

    def shapes(self) -> ShapeArrays:
        return ShapeArrays(*(getattr(self, f) for f in ShapeArrays._fields))

    def state(self) -> "State":
        """A new State at the initial poses and velocities given to the builder."""
        return State(self._initial_q.copy(), self._initial_qd.copy())

    def control(self) -> "Control":
        return Control(np.zeros((self.body_count, 3)), np.zeros((self.body_count, 3)))

    def body_index(self, name: str) -> int:
        try:
            return self.body_name.index(name)
        except ValueError:
            raise ValueError(f"unknown body name {name!r}; known: {self.body_name[:20]}") from None


class State:
    """What changes in a step (written by the world step's integrate stages and finalize).

    - ``body_q (B, 7)``: centre-of-mass position (m) and principal-axes orientation (unit quaternion
      w, x, y, z), world frame; written by integrate_positions.
    - ``body_qd (B, 6)``: angular velocity (rad/s) then linear velocity (m/s), world frame; written by
      integrate_velocities and solve/relax/restitution. Kinematic bodies keep the velocity you set.
    - ``body_sleep_time (B,)`` s: how long the body has been below the sleep velocity thresholds;
      ``body_awake (B,) bool``; ``body_sleep_island (B,) int64`` (the island a sleeping body went to
      sleep with; woken together); written by finalize (sleep) and the islands stage (wake).
    - ``time``, ``step`` (floats/ints, 1-element arrays so a copy captures them).
    """

    def __init__(self, body_q, body_qd):
        self.body_q = np.ascontiguousarray(body_q, dtype=np.float64)
        self.body_qd = np.ascontiguousarray(body_qd, dtype=np.float64)
        n = len(self.body_q)
        self.body_sleep_time = np.zeros(n)
        self.body_awake = np.ones(n, dtype=np.bool_)
        self.body_sleep_island = np.full(n, -1, dtype=np.int64)
        self.clock = np.zeros(1)
        self.step_index = np.zeros(1, dtype=np.int64)

    _FIELDS = ("body_q", "body_qd", "body_sleep_time", "body_awake", "body_sleep_island", "clock",
               "step_index")

    @property
    def time(self) -> float:
        return float(self.clock[0])

    def copy(self) -> "State":
        out = State.__new__(State)
        for f in self._FIELDS:
            setattr(out, f, getattr(self, f).copy())
        return out

    def assign(self, other: "State") -> None:
        """Copy ``other``'s arrays into this state's arrays (views held elsewhere stay valid)."""
        for f in self._FIELDS:
            getattr(self, f)[...] = getattr(other, f)


class Control:
    """Set by the user or a controller before each step (read by integrate_velocities).

    - ``body_force (B, 3)`` N at the centre of mass, world frame; ``body_torque (B, 3)`` N m, world.
    Both persist across steps until changed.
    """

    def __init__(self, body_force, body_torque):
        self.body_force = body_force
        self.body_torque = body_torque


class ModelBuilder:
    """Adds bodies and shapes, then `finalize()` validates once and returns a `Model`.

    >>> b = ModelBuilder()
    >>> b.add_plane()                                   # static ground z = 0
    >>> box = b.add_body(position=(0, 0, 1))
    >>> b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=1000)
    >>> model = b.finalize(); state = model.state()
    """

    def __init__(self, *, gravity=(0.0, 0.0, -9.81), default_margin: float = 0.02):
        self.gravity = _vec3(gravity, "gravity")
        self.default_margin = _nonneg(default_margin, "default_margin")
        self.materials: dict[str, Material] = {"default": Material()}
        self._bodies: list[dict] = []
        self._shapes: list[dict] = []

    # ------------------------------------------------------------------ materials
    def add_material(self, name: str, *, friction=0.6, restitution=0.0, rolling_friction=0.0,
                     density=1000.0) -> str:
        self.materials[str(name)] = Material(_nonneg(friction, "friction"),
                                             _nonneg(restitution, "restitution", 1.0),
                                             _nonneg(rolling_friction, "rolling_friction"),
                                             positive_scalar(density, "density"))
        return str(name)

    # ------------------------------------------------------------------ bodies
    def add_body(self, *, position=(0.0, 0.0, 0.0), orientation=(1.0, 0.0, 0.0, 0.0),
                 linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                 body_type: str = "dynamic", mass=None, inertia=None, linear_damping=0.0,
                 angular_damping=0.0, name: str | None = None, bullet: bool = False) -> int:
        """Add a body; returns its index. ``mass`` (kg) and ``inertia`` (3 principal moments or a 3x3
        tensor in the user frame, kg m^2) override the values computed from the shapes' densities.
        ``body_type``: "dynamic" (default), "kinematic" (moves with its velocity), "static".
        ``bullet``: sweep this body's motion for time of impact every step (fast projectiles; see
        ``inertia.rigid.world``)."""
        if not isinstance(bullet, (bool, np.bool_)):
            raise ValueError(f"bullet must be True or False; got {bullet!r}")
        if body_type not in S.BODY_TYPE_NAMES:
            raise ValueError(f"body_type must be one of {sorted(S.BODY_TYPE_NAMES)}; got {body_type!r}")
        if mass is not None:
            mass = positive_scalar(mass, "mass")
        if inertia is not None:
            inertia = np.asarray(inertia, dtype=np.float64)
            if inertia.shape == (3,):
                inertia = np.diag(inertia)
            if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)) or \
                    np.any(np.linalg.eigvalsh(0.5 * (inertia + inertia.T)) <= 0):
                raise ValueError("inertia must be 3 positive principal moments or a symmetric positive "
                                 f"definite 3x3 tensor (kg m^2); got {np.asarray(inertia).tolist()}")
        self._bodies.append(dict(
            position=_vec3(position, "position"), orientation=_unit_quat(orientation, "orientation"),
            linear_velocity=_vec3(linear_velocity, "linear_velocity"),
            angular_velocity=_vec3(angular_velocity, "angular_velocity"),
            type=S.BODY_TYPE_NAMES[body_type], mass=mass, inertia=inertia,
            linear_damping=_nonneg(linear_damping, "linear_damping"),
            angular_damping=_nonneg(angular_damping, "angular_damping"), bullet=bool(bullet),
            name=name if name is not None else f"body{len(self._bodies)}"))
        return len(self._bodies) - 1

    # ------------------------------------------------------------------ shapes
    def add_shape(self, body: int, shape_type: str, params=(0.0, 0.0, 0.0, 0.0), *,
                  position=(0.0, 0.0, 0.0), orientation=(1.0, 0.0, 0.0, 0.0), material=None,
                  density=None, friction=None, restitution=None, rolling_friction=None, margin=None,
                  group: int = 1, mask: int = -1, is_sensor: bool = False, vertices=None) -> int:
        """Add a shape to ``body`` (-1 = static world) at a pose in the body's user frame.

        Material values come from ``material`` (a name given to `add_material`; "default" if None),
        overridden by the keywords given."""
        if not isinstance(body, (int, np.integer)) or body < -1 or body >= len(self._bodies):
            raise ValueError(f"body must be -1 (static world) or a body index in [0, {len(self._bodies) - 1}]; "
                             f"got {body!r}")
        if shape_type not in S.SHAPE_NAMES:
            raise ValueError(f"shape_type must be one of {sorted(S.SHAPE_NAMES)}; got {shape_type!r}")
        code = S.SHAPE_NAMES[shape_type]
        if code in (S.TRIANGLE_MESH, S.HEIGHTFIELD) and vertices is None:
            raise ValueError(f"add {shape_type!r} shapes with add_triangle_mesh / add_heightfield")
        if code in (S.PLANE, S.TRIANGLE_MESH, S.HEIGHTFIELD) and body != -1 and self._bodies[body]["type"] == S.DYNAMIC:
            raise ValueError(f"a {shape_type} can only belong to body -1 or a static/kinematic body")
        if material is None:
            material = "default"
        if material not in self.materials:
            raise ValueError(f"unknown material key {material!r}; known materials: {sorted(self.materials)}")
        mat = self.materials[material]
        p = np.zeros(4)
        params = np.asarray(params, dtype=np.float64).reshape(-1)
        p[:len(params)] = params
        need = {S.SPHERE: 1, S.BOX: 3, S.CAPSULE: 2, S.CYLINDER: 2}.get(code, 0)
        names = {S.SPHERE: ("radius",), S.BOX: ("hx", "hy", "hz"), S.CAPSULE: ("radius", "half_length"),
                 S.CYLINDER: ("radius", "half_height")}.get(code, ())
        for i in range(need):
            positive_scalar(p[i], f"{shape_type} {names[i]}")
        verts = None
        if code == S.CONVEX_HULL:
            verts = np.asarray(vertices, dtype=np.float64)
            if verts.ndim != 2 or verts.shape[1] != 3 or len(verts) < 4 or not np.all(np.isfinite(verts)):
                raise ValueError("vertices must be a finite (N >= 4, 3) array of hull points")
            c = verts - verts.mean(axis=0)
            if np.linalg.matrix_rank(c, tol=1e-9 * max(1.0, np.abs(c).max())) < 3:
                raise ValueError("vertices of a convex hull must not be coplanar (degenerate hull)")
        self._shapes.append(dict(
            type=code, body=int(body), pose=np.concatenate([_vec3(position, "position"),
                                                            _unit_quat(orientation, "orientation")]),
            params=p, margin=self.default_margin if margin is None else _nonneg(margin, "margin"),
            density=mat.density if density is None else positive_scalar(density, "density"),
            friction=mat.friction if friction is None else _nonneg(friction, "friction"),
            restitution=mat.restitution if restitution is None else _nonneg(restitution, "restitution", 1.0),
            rolling_friction=(mat.rolling_friction if rolling_friction is None
                              else _nonneg(rolling_friction, "rolling_friction")),
            group=int(group), mask=int(mask), sensor=bool(is_sensor),
            verts=verts if verts is not None else (vertices if code in (S.TRIANGLE_MESH, S.HEIGHTFIELD) else None),
            bvh=None))
        return len(self._shapes) - 1

    def add_triangle_mesh(self, vertices, triangles, *, body: int = -1, **kw):
        """Static triangle mesh (``vertices (V, 3)`` m, ``triangles (T, 3)`` indices, counter-clockwise seen
        from the solid's outside) on body -1 or a static/kinematic body. Stored as a triangle list in BVH
        order (see `inertia.geometry.trimesh_collide`)."""
        from .geometry.trimesh_collide import mesh_soup
        soup, bvh = mesh_soup(vertices, triangles)
        si = self.add_shape(body, "triangle_mesh", (len(soup) // 3, 0.0, 0.0, 0.0), vertices=soup, **kw)
        self._shapes[si]["bvh"] = bvh
        return si

    def add_heightfield(self, heights, spacing, *, body: int = -1, **kw):
        """Static heightfield: ``heights (nx, ny)`` m on a grid of ``spacing (dx, dy)`` m, centred on the
        shape's local origin (x_i = (i - (nx - 1) / 2) dx), surface z = height, solid below."""
        from .geometry.trimesh_collide import heightfield_vertices
        verts, params = heightfield_vertices(heights, spacing)
        return self.add_shape(body, "heightfield", params, vertices=verts, **kw)

    def add_sphere(self, body, radius, **kw):
        return self.add_shape(body, "sphere", (positive_scalar(radius, "radius"),), **kw)

    def add_box(self, body, half_extents, **kw):
        h = _vec3(half_extents, "half_extents")
        return self.add_shape(body, "box", h, **kw)

    def add_capsule(self, body, radius, half_length, **kw):
        return self.add_shape(body, "capsule", (positive_scalar(radius, "radius"),
                                                positive_scalar(half_length, "half_length")), **kw)

    def add_cylinder(self, body, radius, half_height, **kw):
        return self.add_shape(body, "cylinder", (positive_scalar(radius, "radius"),
                                                 positive_scalar(half_height, "half_height")), **kw)

    def add_convex_hull(self, body, vertices, **kw):
        return self.add_shape(body, "convex_hull", vertices=vertices, **kw)

    def add_plane(self, normal=(0.0, 0.0, 1.0), offset: float = 0.0, *, body: int = -1, **kw):
        """Static half-space {x : n.x <= offset} (its surface n.x = offset)."""
        n = _vec3(normal, "normal")
        ln = float(np.linalg.norm(n))
        if ln < 1e-12:
            raise ValueError("normal must be non-zero")
        n = n / ln
        # rotation taking +z to n
        z = np.array([0.0, 0.0, 1.0])
        axis = np.cross(z, n)
        s, c = np.linalg.norm(axis), float(np.dot(z, n))
        if s < 1e-12:
            q = np.array([1.0, 0, 0, 0]) if c > 0 else np.array([0.0, 1.0, 0, 0])
        else:
            ang = math.atan2(s, c)
            q = np.concatenate([[math.cos(ang / 2)], axis / s * math.sin(ang / 2)])
        return self.add_shape(body, "plane", position=n * float(offset), orientation=q, **kw)

    # ------------------------------------------------------------------ finalize
    def finalize(self) -> Model:
        """Validate once and flatten to a `Model` (see its docstring for every array)."""
        nb, ns = len(self._bodies), len(self._shapes)
        body_shapes = [[] for _ in range(nb)]
        for si, sh in enumerate(self._shapes):
            if sh["body"] >= 0:
                body_shapes[sh["body"]].append(si)

        body_type = np.zeros(nb, np.int32)
        body_mass = np.zeros(nb)
        body_inertia = np.zeros((nb, 3))
        body_com_pose = np.zeros((nb, 7))
        q0 = np.zeros((nb, 7))
        qd0 = np.zeros((nb, 6))
        shape_pose = np.array([sh["pose"] for sh in self._shapes]).reshape(ns, 7)
        for bi, bd in enumerate(self._bodies):
            body_type[bi] = bd["type"]
            # -- mass properties in the user frame: sum of shapes (parallel axis), or the given values
            m_tot, com, itensor = 0.0, np.zeros(3), np.zeros((3, 3))
            parts = []
            for si in body_shapes[bi]:
                sh = self._shapes[si]
                if sh["sensor"] or sh["type"] in (S.PLANE, S.TRIANGLE_MESH, S.HEIGHTFIELD) or sh["density"] <= 0:
                    continue
                props = shape_mass_properties(sh["type"], sh["params"], sh["density"], vertices=sh["verts"])
                r = quat_to_mat3(np.ascontiguousarray(sh["pose"][3:], dtype=np.float64))
                parts.append((props.mass, sh["pose"][:3] + mat3_vec(r, props.com),
                              mat3_mul(mat3_mul(r, props.inertia), mat3_transpose(r))))
            for m, c, _ in parts:
                m_tot += m
                com += m * c
            if m_tot > 0:
                com /= m_tot
                for m, c, i_c in parts:
                    d = c - com
                    itensor += i_c + m * (float(np.sum(d * d)) * np.eye(3) - np.outer(d, d))
            if bd["mass"] is not None:
                if m_tot > 0:
                    itensor *= bd["mass"] / m_tot
                m_tot = bd["mass"]
            if bd["inertia"] is not None:
                itensor = bd["inertia"]
            if bd["type"] == S.DYNAMIC and (m_tot <= 0 or not np.any(itensor)):
                raise ValueError(f"dynamic body {bd['name']!r} has no mass: add a shape with density > 0 "
                                 "or give mass= and inertia=")
            # -- principal axes: eigenvectors as a right-handed rotation
            if np.any(itensor):
                evals, evecs = np.linalg.eigh(0.5 * (itensor + itensor.T))
                if np.allclose(itensor, np.diag(np.diag(itensor)), atol=1e-14 * np.abs(itensor).max()):
                    evals, evecs = np.diag(itensor).copy(), np.eye(3)
                if np.linalg.det(evecs) < 0:
                    evecs[:, 2] *= -1
                rq = mat3_to_quat(np.ascontiguousarray(evecs))
            else:
                evals, rq = np.zeros(3), np.array([1.0, 0, 0, 0])
            body_com_pose[bi] = np.concatenate([com, rq])
            body_mass[bi] = m_tot
            body_inertia[bi] = evals
            user = np.concatenate([bd["position"], bd["orientation"]])
            q0[bi] = transform_mul(user, body_com_pose[bi])
            qd0[bi, :3] = bd["angular_velocity"]
            # the velocity given is that of the user-frame origin; move it to the centre of mass
            r_com = q0[bi, :3] - bd["position"]
            qd0[bi, 3:] = bd["linear_velocity"] + np.cross(bd["angular_velocity"], r_com)
            inv_com = transform_inv(body_com_pose[bi])
            for si in body_shapes[bi]:
                shape_pose[si] = transform_mul(inv_com, np.ascontiguousarray(self._shapes[si]["pose"], dtype=np.float64))

        dyn = body_type == S.DYNAMIC
        inv_mass = np.where(dyn, 1.0 / np.where(body_mass > 0, body_mass, 1.0), 0.0)
        inv_inertia = np.where(dyn[:, None], 1.0 / np.where(body_inertia > 0, body_inertia, 1.0), 0.0)

        # -- CSR hull vertices
        vstart = np.zeros(ns, np.int32)
        vcount = np.zeros(ns, np.int32)
        verts = []
        for si, sh in enumerate(self._shapes):
            if sh["verts"] is not None:
                vstart[si] = sum(len(v) for v in verts)
                vcount[si] = len(sh["verts"])
                verts.append(sh["verts"])
        geom_vertices = np.concatenate(verts) if verts else np.zeros((0, 3))
        # -- CSR mesh BVH nodes
        bvh_start = np.full(ns, -1, np.int32)
        bvh_b, bvh_n = [np.zeros((0, 6))], [np.zeros((0, 3), np.int32)]
        for si, sh in enumerate(self._shapes):
            if sh.get("bvh") is not None:
                bvh_start[si] = sum(len(x) for x in bvh_n)
                bvh_b.append(sh["bvh"][0])
                bvh_n.append(sh["bvh"][1])

        shape_params = np.array([sh["params"] for sh in self._shapes]).reshape(ns, 4)
        shape_type = np.array([sh["type"] for sh in self._shapes], np.int32)
        shape_body = np.array([sh["body"] for sh in self._shapes], np.int32)
        # bounding radius of each body about its centre of mass (finite shapes only)
        bound = np.zeros(nb)
        for si in range(ns):
            bi = shape_body[si]
            if bi < 0 or shape_type[si] == S.PLANE:
                continue
            t, p = shape_type[si], shape_params[si]
            if t == S.SPHERE:
                ext = p[0]
            elif t == S.BOX:
                ext = float(np.linalg.norm(p[:3]))
            elif t in (S.CAPSULE, S.CYLINDER):
                ext = p[0] + p[1]
            else:
                v = geom_vertices[vstart[si]:vstart[si] + vcount[si]]
                ext = float(np.linalg.norm(v, axis=1).max())
            bound[bi] = max(bound[bi], float(np.linalg.norm(shape_pose[si, :3])) + ext)

        model = Model(
            body_type=body_type, body_mass=body_mass, body_inv_mass=inv_mass,
            body_inertia=body_inertia, body_inv_inertia=inv_inertia, body_com_pose=body_com_pose,
            body_linear_damping=np.array([b["linear_damping"] for b in self._bodies]).reshape(nb),
            body_angular_damping=np.array([b["angular_damping"] for b in self._bodies]).reshape(nb),
            body_bound_radius=bound, body_name=[b["name"] for b in self._bodies],
            body_bullet=np.array([b["bullet"] for b in self._bodies], bool).reshape(nb),
            shape_type=shape_type, shape_body=shape_body, shape_local_pose=shape_pose,
            shape_params=shape_params,
            shape_margin=np.array([sh["margin"] for sh in self._shapes]).reshape(ns),
            shape_friction=np.array([sh["friction"] for sh in self._shapes]).reshape(ns),
            shape_restitution=np.array([sh["restitution"] for sh in self._shapes]).reshape(ns),
            shape_rolling_friction=np.array([sh["rolling_friction"] for sh in self._shapes]).reshape(ns),
            shape_density=np.array([sh["density"] for sh in self._shapes]).reshape(ns),
            shape_group=np.array([sh["group"] for sh in self._shapes], np.int32).reshape(ns),
            shape_mask=np.array([sh["mask"] for sh in self._shapes], np.int32).reshape(ns),
            shape_is_sensor=np.array([sh["sensor"] for sh in self._shapes], np.bool_).reshape(ns),
            shape_vert_start=vstart, shape_vert_count=vcount, geom_vertices=geom_vertices,
            geom_bvh_bounds=np.concatenate(bvh_b), geom_bvh_nodes=np.concatenate(bvh_n), shape_bvh_start=bvh_start,
            sdf_grid_f=np.zeros(0), sdf_grid_i=np.zeros(0, np.int64),
            shape_sdf_start=np.full((ns, 2), -1, np.int64), gravity=self.gravity.copy())
        model._initial_q = q0
        model._initial_qd = qd0
        return model


def _sdf_row(collider, row):
    """An SDF row of ``collider``: (row, corner vertices, (cf, ci) grid) when the collider has a distance grid
    (a baked ``SDF``, a ``Mesh``), else (row, None, None) (unbaked: rigid bodies cannot see it). The row's
    params hold the rest-frame position of its frame (the collider's reference point, where the row sits);
    its vertices are the 8 corners of the field's bounding box in the row's frame (for the broad phase)."""
    from .collision import distance as _d
    if getattr(collider, "kind", None) != _d.GRID:
        return row, None, None
    cf = np.ascontiguousarray(collider._cf, dtype=np.float64)
    ci = np.ascontiguousarray(collider._ci, dtype=np.int64)
    ref = np.asarray(collider._ref, dtype=np.float64)
    pad = float(cf[_d.G_THICK])
    lo = cf[_d.G_BMIN:_d.G_BMIN + 3] - pad - ref
    hi = cf[_d.G_BMAX:_d.G_BMAX + 3] + pad - ref
    corners = np.array([[hi[0] if v & 1 else lo[0], hi[1] if v & 2 else lo[1], hi[2] if v & 4 else lo[2]]
                        for v in range(8)])
    params = np.zeros(4)
    params[:3] = ref
    return dict(row, params=params), corners, (cf, ci)


# ---------------------------------------------------------------------------------------------------
# one shape table: particle colliders as rows (static on body -1, moving ones on kinematic bodies)
# ---------------------------------------------------------------------------------------------------
def empty_model(gravity=(0.0, 0.0, -9.81)) -> Model:
    """A Model with no bodies and no shapes (the start of a table that colliders are appended to)."""
    return ModelBuilder(gravity=gravity).finalize()


def with_colliders(model: Model | None, colliders, *, margin: float = 0.02, friction: float = 0.6,
                   restitution: float = 0.0) -> Model:
    """A new Model: `model`'s bodies and shapes, then the shape rows of the 3-D `colliders`
    (``Collider.shape_rows``) appended.

    A static collider's rows sit on body -1 (world pose = its rest pose); a moving one (``motion``)
    gets a kinematic body named ``collider<i>`` whose pose is the collider's ``pose(t)`` (the world's
    kinematics stage writes ``body_q`` and ``body_qd`` from it each step). New columns:
    ``shape_source (S,) int32`` (the index in `colliders` a row came from, -1 for the builder's shapes)
    and ``body_source (B,) int32`` (same for bodies). Rows get ``margin``, ``friction`` and
    ``restitution`` (the rigid material; particles use the values given to ``add_collider``).
    Colliders of another dimension than 3 are skipped (the shape table is 3-D). An ``SDF`` row (an
    ``SDF`` collider, or a mesh whose triangles the rigid side cannot use) of a collider with a distance
    grid (baked ``SDF``, ``Mesh``) appends that grid to ``sdf_grid_f``/``sdf_grid_i``
    (``shape_sdf_start``) so rigid bodies collide with it (`inertia.geometry.sdf_collide`); an unbaked
    ``SDF`` row has none.
    """
    from .geometry.trimesh_collide import mesh_soup
    from .math import mat3_to_quat as _m2q

    base = empty_model() if model is None else model
    nb0, ns0 = base.body_count, base.shape_count
    bodies, shapes = [], []
    for ci, col in enumerate(colliders):
        if getattr(col, "dim", 3) != 3:
            continue
        rows = col.shape_rows()
        if col.moving:
            p, r = col.pose(0.0)
            bodies.append(dict(q=np.concatenate([p, _m2q(np.ascontiguousarray(r))]), source=ci,
                               name=f"collider{ci}", rows=rows))
            body = nb0 + len(bodies) - 1
        else:
            body = -1
        for row in rows:
            pose = np.array(row["pose"], dtype=np.float64)
            if body < 0:
                pose[:3] += col._ref
            verts, bvh, grid = None, None, None
            if row["type"] == S.TRIANGLE_MESH:
                try:
                    verts, bvh = mesh_soup(row["vertices"], row["triangles"])
                except ValueError:     # e.g. zero-area triangles: an SDF-type row on the mesh's distance grid
                    row = dict(row, type=S.SDF)
            if row["type"] == S.SDF:
                row, verts, grid = _sdf_row(col, row)
            shapes.append(dict(type=int(row["type"]), body=body, pose=pose, params=np.asarray(row["params"], float),
                               verts=verts, bvh=bvh, source=ci, grid=grid))
    nb, ns = nb0 + len(bodies), ns0 + len(shapes)

    def grow(name, extra, dtype=None):
        old = getattr(base, name)
        extra = np.asarray(extra, dtype=old.dtype if dtype is None else dtype).reshape((-1,) + old.shape[1:])
        return np.concatenate([old, extra])

    kb = len(bodies)
    arrays = {}
    arrays["body_type"] = grow("body_type", [S.KINEMATIC] * kb)
    for name in ("body_mass", "body_inv_mass", "body_linear_damping", "body_angular_damping"):
        arrays[name] = grow(name, np.zeros(kb))
    for name in ("body_inertia", "body_inv_inertia"):
        arrays[name] = grow(name, np.zeros((kb, 3)))
    arrays["body_com_pose"] = grow("body_com_pose", np.tile([0.0, 0, 0, 1, 0, 0, 0], (kb, 1)))
    arrays["body_name"] = list(base.body_name) + [b["name"] for b in bodies]
    if hasattr(base, "body_bullet"):
        arrays["body_bullet"] = grow("body_bullet", np.zeros(kb, bool))
    arrays["body_source"] = np.concatenate([getattr(base, "body_source", np.full(nb0, -1, np.int32)),
                                            np.array([b["source"] for b in bodies], np.int32)]).astype(np.int32)
    # shapes
    vstart, vcount, verts = [], [], []
    nverts = len(base.geom_vertices)
    bvh_start, bvh_b, bvh_n = [], [base.geom_bvh_bounds], [base.geom_bvh_nodes]
    nnodes = len(base.geom_bvh_nodes)
    for sh in shapes:
        if sh["verts"] is not None:
            vstart.append(nverts)
            vcount.append(len(sh["verts"]))
            verts.append(sh["verts"])
            nverts += len(sh["verts"])
        else:
            vstart.append(0)
            vcount.append(0)
        if sh["bvh"] is not None:
            bvh_start.append(nnodes)
            bvh_b.append(sh["bvh"][0])
            bvh_n.append(sh["bvh"][1])
            nnodes += len(sh["bvh"][1])
        else:
            bvh_start.append(-1)
    k = len(shapes)
    arrays["shape_type"] = grow("shape_type", [sh["type"] for sh in shapes])
    arrays["shape_body"] = grow("shape_body", [sh["body"] for sh in shapes])
    arrays["shape_local_pose"] = grow("shape_local_pose", [sh["pose"] for sh in shapes])
    arrays["shape_params"] = grow("shape_params", [sh["params"] for sh in shapes])
    arrays["shape_margin"] = grow("shape_margin", np.full(k, float(margin)))
    arrays["shape_friction"] = grow("shape_friction", np.full(k, float(friction)))
    arrays["shape_restitution"] = grow("shape_restitution", np.full(k, float(restitution)))
    arrays["shape_rolling_friction"] = grow("shape_rolling_friction", np.zeros(k))
    arrays["shape_density"] = grow("shape_density", np.zeros(k))
    arrays["shape_group"] = grow("shape_group", np.ones(k))
    arrays["shape_mask"] = grow("shape_mask", np.full(k, -1))
    arrays["shape_is_sensor"] = grow("shape_is_sensor", np.zeros(k, bool))
    arrays["shape_vert_start"] = grow("shape_vert_start", vstart)
    arrays["shape_vert_count"] = grow("shape_vert_count", vcount)
    arrays["geom_vertices"] = np.concatenate([base.geom_vertices] + verts) if verts else base.geom_vertices.copy()
    arrays["geom_bvh_bounds"] = np.concatenate(bvh_b)
    arrays["geom_bvh_nodes"] = np.concatenate(bvh_n)
    arrays["shape_bvh_start"] = grow("shape_bvh_start", bvh_start)
    # baked SDF rows: the colliders' packed grids appended (geometry/sdf_collide.py)
    grid_f = [getattr(base, "sdf_grid_f", np.zeros(0))]
    grid_i = [getattr(base, "sdf_grid_i", np.zeros(0, np.int64))]
    nf, ni = len(grid_f[0]), len(grid_i[0])
    sdf_start = np.full((k, 2), -1, np.int64)
    for j, sh in enumerate(shapes):
        if sh["grid"] is not None:
            sdf_start[j] = nf, ni
            grid_f.append(sh["grid"][0])
            grid_i.append(sh["grid"][1])
            nf += len(sh["grid"][0])
            ni += len(sh["grid"][1])
    arrays["sdf_grid_f"] = np.concatenate(grid_f).astype(np.float64)
    arrays["sdf_grid_i"] = np.concatenate(grid_i).astype(np.int64)
    arrays["shape_sdf_start"] = np.concatenate([getattr(base, "shape_sdf_start", np.full((ns0, 2), -1, np.int64)),
                                                sdf_start]).astype(np.int64)
    arrays["shape_source"] = np.concatenate([getattr(base, "shape_source", np.full(ns0, -1, np.int32)),
                                             np.array([sh["source"] for sh in shapes], np.int32)]).astype(np.int32)
    # bounding radius of the new kinematic bodies (finite shapes; planes are unbounded and skipped)
    bound = np.zeros(kb)
    for sh in shapes:
        if sh["body"] >= nb0 and sh["type"] != S.PLANE:
            p = sh["params"]
            ext = {S.SPHERE: p[0], S.BOX: float(np.linalg.norm(p[:3])), S.CAPSULE: p[0] + p[1],
                   S.CYLINDER: p[0] + p[1]}.get(sh["type"])
            if ext is None:
                ext = float(np.linalg.norm(sh["verts"], axis=1).max()) if sh["verts"] is not None else 0.0
            i = sh["body"] - nb0
            bound[i] = max(bound[i], float(np.linalg.norm(sh["pose"][:3])) + ext)
    arrays["body_bound_radius"] = np.concatenate([base.body_bound_radius, bound])
    arrays["gravity"] = base.gravity.copy()
    for name, value in vars(base).items():      # columns other helpers appended to the Model
        if name not in arrays and not name.startswith("_") and name not in ("body_count", "shape_count"):
            arrays[name] = value
    out = Model(**arrays)
    out._initial_q = np.concatenate([base._initial_q, np.array([b["q"] for b in bodies]).reshape(kb, 7)])
    out._initial_qd = np.concatenate([base._initial_qd, np.zeros((kb, 6))])
    assert out.body_count == nb and out.shape_count == ns
    return out
