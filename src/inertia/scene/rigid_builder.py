"""Build the rigid bodies of a scene (``[materials]``, ``[bodies]``, ``[rigid]``) into a `Model`.

`build_rigid(scene_model, source=, base_dir=)` returns a `RigidScene` (the finalized Model, the
RigidWorld options, per-body colours, the vehicles). `inertia.scene.builder.build_world` passes the
Model to ``World(model=, rigid_options=)``; `rigid_world(scene)` builds a bare `RigidWorld` of the bodies
only, and `step_scene` runs the ``[vehicles]`` scripts before each of its steps (in the coupled World,
`builder._drive_vehicles` wraps its ``step``).

Copies of one ``[bodies.NAME]`` table are named ``NAME[k]`` (k in creation order: x fastest, then y,
then z / layer). Static bodies become shapes of the world (body -1) at their world pose.
"""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import numpy as np

from ..geometry import shapes as S
from ..math import rotate_vectors
from . import rigid_models as R
from .errors import Issue, SceneError, did_you_mean, read_mesh_file, read_npy_file

__all__ = ["RigidScene", "VehicleController", "build_rigid", "rigid_world", "step_scene", "body_copies"]


@dataclasses.dataclass
class RigidScene:
    model: object                  # inertia.model.Model
    options: dict                  # RigidWorld keyword arguments
    body_colors: np.ndarray        # (B, 3) float32 in 0..1 (NaN where the scene gives none)
    shape_colors: np.ndarray       # (S, 3) float32 in 0..1 (NaN where none)
    vehicles: dict = dataclasses.field(default_factory=dict)   # name -> (chassis body index, R.Vehicle)
    controllers: list = dataclasses.field(default_factory=list)  # VehicleController, made by attach()

    def attach(self, world) -> "RigidScene":
        """Make the vehicles' controllers for a RigidWorld stepping this model (call once)."""
        self.controllers = [VehicleController(world, chassis, spec) for chassis, spec in self.vehicles.values()]
        return self

    def before_step(self, time: float) -> None:
        """Apply every vehicle's script at ``time`` (s) and compute its wheel forces for the next step."""
        for c in self.controllers:
            c(time)


class VehicleController:
    """A `RaycastVehicle` driven by its scene script (piecewise constant rows)."""

    def __init__(self, world, chassis: int, spec: R.Vehicle):
        from ..rigid.vehicle import RaycastVehicle, Wheel

        wheels = [Wheel(tuple(w.hardpoint), rest_length=w.rest_length, radius=w.radius, stiffness=w.stiffness,
                        damping=w.damping, friction=w.friction, inertia=w.inertia, steered=w.steered,
                        driven=w.driven) for w in spec.wheels]
        self.vehicle = RaycastVehicle(world, chassis, wheels)
        self.script = spec.script
        self._next = 0

    def __call__(self, time: float) -> None:
        while self._next < len(self.script) and self.script[self._next].time <= time + 1e-12:
            row = self.script[self._next]
            for key in ("engine_torque", "steering", "brake_torque"):
                if getattr(row, key) is not None:
                    setattr(self.vehicle, key, float(getattr(row, key)))
            self._next += 1
        self.vehicle.update()


def _hex(color):
    if color is None:
        return (np.nan, np.nan, np.nan)
    return tuple(int(color[i:i + 2], 16) / 255.0 for i in (1, 3, 5))


def body_copies(body: R.Body, seed: int = 0) -> list[np.ndarray]:
    """World positions of the copies of one body table (one entry when it has no array/pyramid)."""
    p0 = np.asarray(body.position, dtype=np.float64)
    if body.array is not None:
        a = body.array
        nx, ny, nz = a.count
        sx, sy, sz = a.spacing
        rng = np.random.default_rng(a.seed if a.seed is not None else seed)
        out = []
        for k in range(nz):
            for j in range(ny):
                for i in range(nx):
                    off = np.array([(i - 0.5 * (nx - 1)) * sx, (j - 0.5 * (ny - 1)) * sy, k * sz])
                    if a.jitter > 0:
                        off = off + rng.uniform(-a.jitter, a.jitter, 3)
                    out.append(p0 + off)
        return out
    if body.pyramid is not None:
        pyr = body.pyramid
        h, v = pyr.spacing
        out = []
        for k in range(pyr.base):
            n = pyr.base - k
            for j in range(n if pyr.square else 1):
                for i in range(n):
                    y = (j - 0.5 * (n - 1)) * h if pyr.square else 0.0
                    out.append(p0 + np.array([(i - 0.5 * (n - 1)) * h, y, k * v]))
        return out
    return [p0]


class _RigidBuilder:
    def __init__(self, scene, source, base_dir: Path):
        self.m = scene
        self.source = source
        self.base = Path(base_dir) if base_dir is not None else Path(".")

    def fail(self, path, message):
        raise SceneError(self.source, [Issue(path, message)])

    @contextlib.contextmanager
    def at(self, path):
        try:
            yield
        except SceneError:
            raise
        except (ValueError, TypeError) as exc:
            self.fail(path, str(exc))

    def file(self, name, path) -> Path:
        p = Path(name).expanduser()
        if not p.is_absolute():
            p = self.base / p
        if not p.is_file():
            self.fail(path, f"file not found: {p}")
        return p

    def material(self, name, path):
        known = ["default", *self.m.materials]
        if name not in known:
            self.fail(path, f"unknown material {name!r}{did_you_mean(name, known, show_allowed=False)}; "
                            f"known materials: {', '.join(known)}")
        return name

    # ------------------------------------------------------------------ build
    def build(self) -> RigidScene:
        from ..model import ModelBuilder

        rig = self.m.rigid
        if self.m.bodies and self.m.simulation.dim != 3:
            self.fail("bodies", "rigid bodies need a 3-D scene (simulation.dim = 3)")
        b = ModelBuilder(gravity=rig.gravity, default_margin=rig.margin)
        for name, mat in self.m.materials.items():
            with self.at(f"materials.{name}"):
                b.add_material(name, friction=mat.friction, restitution=mat.restitution,
                               rolling_friction=mat.rolling_friction, density=mat.density)
        body_colors, shape_colors = [], []
        for name, body in self.m.bodies.items():
            path = f"bodies.{name}"
            self.material(body.material, f"{path}.material")
            q_body = body.rotation.as_quaternion() if body.rotation is not None else (1.0, 0.0, 0.0, 0.0)
            positions = body_copies(body, seed=self.m.simulation.seed)
            color = _hex(body.color)
            for k, pos in enumerate(positions):
                label = name if len(positions) == 1 and body.array is None and body.pyramid is None else f"{name}[{k}]"
                if body.shapes is not None:
                    specs = [(s, f"{path}.shapes[{i}]") for i, s in enumerate(body.shapes)]
                elif body.mix is not None:
                    i = k % len(body.mix)
                    specs = [(body.mix[i], f"{path}.mix[{i}]")]
                else:
                    specs = [(body.shape, f"{path}.shape")]
                static = body.motion == "static"
                if static:
                    bi = -1
                else:
                    kinds = {s.type for s, _ in specs}
                    if body.motion == "dynamic" and kinds & {"plane", "mesh", "heightfield"}:
                        bad = next(p for s, p in specs if s.type in ("plane", "mesh", "heightfield"))
                        self.fail(f"{bad}.type", "plane, mesh and heightfield shapes belong to static or kinematic "
                                                 "bodies (motion = 'static' | 'kinematic'); a dynamic body takes "
                                                 "a hull or hull parts")
                    with self.at(path):
                        bi = b.add_body(position=pos, orientation=q_body, linear_velocity=body.velocity,
                                        angular_velocity=body.angular_velocity, body_type=body.motion,
                                        mass=body.mass, linear_damping=body.linear_damping,
                                        angular_damping=body.angular_damping, name=label,
                                        bullet=bool(getattr(body, "bullet", False)))
                    body_colors.append(color)
                for spec, spath in specs:
                    n_before = len(b._shapes)
                    self.add_shape(b, bi, spec, spath, body, pos if static else None, q_body if static else None)
                    shape_colors.extend([color] * (len(b._shapes) - n_before))
        with self.at("bodies"):
            model = b.finalize()
        vehicles = {}
        for vname, spec in self.m.vehicles.items():
            path = f"vehicles.{vname}.chassis"
            body = self.m.bodies.get(spec.chassis)
            if body is None:
                self.fail(path, f"no body named {spec.chassis!r}{did_you_mean(spec.chassis, list(self.m.bodies), show_allowed=False)}; "
                                f"bodies: {', '.join(self.m.bodies) or 'none'}")
            if body.copies != 1 or body.motion != "dynamic":
                self.fail(path, f"the chassis must be one dynamic body (bodies.{spec.chassis} makes {body.copies} "
                                f"{body.motion} bodies)")
            vehicles[vname] = (model.body_name.index(spec.chassis), spec)
        options = dict(substeps=rig.substeps, contact_hertz=rig.contact_hertz,
                       contact_damping_ratio=rig.contact_damping_ratio,
                       restitution_threshold=rig.restitution_threshold, enable_sleep=rig.sleep,
                       dt=self.m.simulation.dt)
        return RigidScene(model, options, np.asarray(body_colors, np.float32).reshape(-1, 3),
                          np.asarray(shape_colors, np.float32).reshape(-1, 3), vehicles)

    def add_shape(self, b, bi, spec, path, body, world_pos, world_q):
        """Add one shape spec; ``world_pos``/``world_q`` given for static bodies (shapes on body -1)."""
        local_p = np.asarray(spec.position if spec.position is not None else (0.0, 0.0, 0.0), dtype=np.float64)
        local_q = spec.rotation.as_quaternion() if spec.rotation is not None else (1.0, 0.0, 0.0, 0.0)
        if world_pos is not None:
            qb = np.asarray(world_q, dtype=np.float64)
            pos = np.asarray(world_pos) + rotate_vectors(qb, local_p)
            q = R.quat_mul(tuple(qb), local_q)
        else:
            pos, q = local_p, local_q
        material = self.material(spec.material, f"{path}.material") if spec.material is not None else body.material
        kw = dict(position=pos, orientation=q, material=material)
        if body.density is not None:
            kw["density"] = body.density
        t = spec.type
        with self.at(path):
            if t == "sphere":
                b.add_sphere(bi, spec.radius, **kw)
            elif t == "box":
                b.add_box(bi, spec.half_extents, **kw)
            elif t == "capsule":
                b.add_capsule(bi, spec.radius, spec.half_length, **kw)
            elif t == "cylinder":
                b.add_cylinder(bi, spec.radius, spec.half_length, **kw)
            elif t == "hull":
                for part in (spec.parts if spec.parts is not None else [spec.points]):
                    b.add_convex_hull(bi, np.asarray(part, dtype=np.float64), **kw)
            elif t == "plane":
                n = np.asarray(spec.normal, dtype=np.float64)
                if np.linalg.norm(n) < 1e-12:
                    self.fail(f"{path}.normal", "must be a non-zero vector")
                n = rotate_vectors(np.asarray(q), n / np.linalg.norm(n))
                kw.pop("density", None)
                b.add_plane(n, spec.offset + float(np.dot(n, pos)), body=bi, material=material)
            elif t == "mesh":
                vertices, triangles = self.mesh(spec, path)
                kw.pop("density", None)
                b.add_triangle_mesh(vertices, triangles, body=bi, **kw)
            elif t == "heightfield":
                if spec.heights is not None:
                    rows = {len(r) for r in spec.heights}
                    if len(rows) != 1:
                        self.fail(f"{path}.heights", f"all rows need the same length (got lengths {sorted(rows)})")
                    heights = np.asarray(spec.heights, dtype=np.float64)
                else:
                    heights = read_npy_file(self.file(spec.file, f"{path}.file"), f"{path}.file", self.fail, ndim=2)
                kw.pop("density", None)
                b.add_heightfield(heights, spec.spacing, body=bi, **kw)

    def mesh(self, spec, path):
        if spec.vertices is not None:
            v = np.asarray(spec.vertices, dtype=np.float64) * spec.scale
            return v, np.asarray(spec.triangles, dtype=np.int64)
        file = self.file(spec.file, f"{path}.file")
        return read_mesh_file(file, path, self.fail, spec.scale)


def build_rigid(scene_model, *, source=None, base_dir=None) -> RigidScene | None:
    """The rigid part of a validated scene, or None when it has no bodies."""
    if not scene_model.bodies:
        return None
    return _RigidBuilder(scene_model, source, base_dir).build()


def rigid_world(scene, **overrides):
    """Adapter: a `RigidWorld` stepping the bodies of a loaded `Scene` (``inertia.scene.read_scene``).

    Returns (world, RigidScene). To be replaced by ``World(model=..., rigid_options=...)`` in the coupled world.
    Scenes with ``[vehicles]`` need ``rs.before_step(world.state.time)`` before each ``world.step()``
    (`step_scene` does both)."""
    from ..rigid.world import RigidWorld

    rs = build_rigid(scene.model, source=scene.path, base_dir=scene.base_dir)
    if rs is None:
        raise SceneError(scene.path, [Issue("bodies", "the scene has no [bodies.NAME] tables")])
    world = RigidWorld(rs.model, **{**rs.options, **overrides})
    with _RigidBuilder(scene.model, scene.path, scene.base_dir).at("vehicles"):
        rs.attach(world)
    return world, rs


def step_scene(world, rs: RigidScene, steps: int = 1) -> None:
    """Step a scene's RigidWorld ``steps`` times, running its vehicle scripts before each step."""
    for _ in range(int(steps)):
        rs.before_step(world.state.time)
        world.step()
