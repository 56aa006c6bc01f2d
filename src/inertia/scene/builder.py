"""From a validated scene to a `World`: layouts to arrays, specs to force objects and colliders.

Runs once, at load time. Every problem found here (a vector of the wrong length, an index out
of range, a missing file, a name that names nothing) raises `SceneError` with the key path of
the entry being built; errors raised by the library's constructors are re-raised the same way.

Seeds: an entry with its own ``seed`` uses it as is; one without derives its seed from
``simulation.seed`` and its key path, so ``--seed`` changes every random choice of a scene
and the same seed always gives the same run.
"""

from __future__ import annotations

import contextlib
import inspect
import json
import math
import zlib
from pathlib import Path

import numpy as np

from .. import forces as F
from ..particles.emitters import BoxSource, Cone, DiskSource, Emitter, PointSource, SphereSource
from ..particles.system import ParticleSystem
from ..particles.tracers import Tracers
from ..world import World, fingerprint
from . import models as M
from .errors import Issue, SceneError, check_mesh_suffix, did_you_mean, read_mesh_file, read_npy_file
from .fluids import add_grid_fluids, add_sph_fluids

__all__ = ["build_world", "derive_seed", "scene_fingerprint", "build_colliders"]

_INTEGRATOR_OPTIONS = {"rk45": ("rtol", "atol", "max_substeps"),
                       "implicit_euler": ("cg_tolerance", "cg_max_iterations")}


def derive_seed(seed: int, path: str) -> int:
    """A 32-bit seed from the scene seed and a key path (stable across runs and machines)."""
    return int(np.random.SeedSequence([int(seed), zlib.crc32(path.encode())]).generate_state(1)[0])


def scene_fingerprint(model: M.SceneModel) -> str:
    """Hash of everything that determines the trajectory (not duration, outputs or rendering)."""
    data = model.model_dump(mode="json", exclude={"output", "render", "name", "description"})
    data["simulation"].pop("duration", None)
    return fingerprint(json.dumps(data, sort_keys=True))


def cloth_triangles(nu: int, nv: int) -> np.ndarray:
    """(2 (nu-1)(nv-1), 3) int64: two counter-clockwise triangles per quad of an nu x nv cloth grid
    (particle ``j nu + i`` at column i, row j), the surface the renderer shades."""
    idx = np.arange(nu * nv).reshape(nv, nu)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)


class _Builder:
    def __init__(self, model: M.SceneModel, source, base_dir: Path):
        self.m = model
        self.source = source
        self.base = base_dir
        self.dim = model.simulation.dim
        self.seed = model.simulation.seed
        self.fields: dict = {}
        self.colliders: list = []           # (spec, object, path)
        self.collider_names: dict = {}

    # ---- helpers -------------------------------------------------------------------------
    def fail(self, path: str, message: str):
        raise SceneError(self.source, [Issue(path, message)])

    @contextlib.contextmanager
    def at(self, path: str):
        """Re-raise a library ValueError from inside the block with the key path."""
        try:
            yield
        except SceneError:
            raise
        except (ValueError, TypeError) as exc:
            self.fail(path, str(exc))

    def vec(self, value, path: str, dim: int | None = None) -> np.ndarray:
        dim = self.dim if dim is None else dim
        arr = np.asarray(value, dtype=np.float64)
        if arr.shape != (dim,):
            self.fail(path, f"must have {dim} components in a {self.dim}-D scene (got {list(value)})")
        if not np.all(np.isfinite(arr)):
            self.fail(path, f"must be finite (got {list(value)})")
        return arr

    def points(self, value, path: str) -> np.ndarray:
        bad = next((i for i, p in enumerate(value) if len(p) != self.dim), None)
        if bad is not None:
            self.fail(f"{path}[{bad}]", f"must have {self.dim} components in a {self.dim}-D scene "
                                        f"(got {list(value[bad])})")
        arr = np.asarray(value, dtype=np.float64).reshape(-1, self.dim)
        if not np.all(np.isfinite(arr)):
            self.fail(path, "must be finite")
        return arr

    def require(self, module, name: str, path: str):
        cls = getattr(module, name, None)
        if cls is None:
            self.fail(path, f"this installation of inertia has no {module.__name__}.{name}")
        return cls

    def seed_for(self, explicit, path: str) -> int:
        return int(explicit) if explicit is not None else derive_seed(self.seed, path)

    def file(self, name: str, path: str) -> Path:
        p = Path(name).expanduser()
        if not p.is_absolute():
            p = self.base / p
        if not p.is_file():
            self.fail(path, f"file not found: {p}" + (" (it is a directory)" if p.is_dir() else ""))
        return p

    def npy(self, name: str, path: str, *, ndim: int | None = None) -> np.ndarray:
        """A .npy file's array, its header checked against the file and the memory (`read_npy_file`)."""
        return read_npy_file(self.file(name, path), path, self.fail, ndim=ndim)

    def per_item(self, value, count: int, path: str) -> np.ndarray:
        if isinstance(value, list):
            if len(value) != count:
                self.fail(path, f"needs one value per item: {count} (got {len(value)})")
            return np.asarray(value, dtype=np.float64)
        return np.full(count, float(value))

    # ---- layouts ---------------------------------------------------------------------------
    def lattice(self, spec: M.Lattice, path: str) -> np.ndarray:
        origin = self.vec(spec.origin, f"{path}.origin")
        if len(spec.counts) != self.dim:
            self.fail(f"{path}.counts", f"needs {self.dim} counts in a {self.dim}-D scene (got {spec.counts})")
        spacing = (np.full(self.dim, spec.spacing) if isinstance(spec.spacing, float)
                   else self.vec(spec.spacing, f"{path}.spacing"))
        if np.any(spacing <= 0):
            self.fail(f"{path}.spacing", "must be > 0")
        axes = [np.arange(n) * h for n, h in zip(spec.counts, spacing)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, self.dim) + origin
        if spec.jitter:
            rng = np.random.default_rng(self.seed_for(spec.seed, path))
            grid += (rng.random(grid.shape) - 0.5) * spec.jitter * spacing
        return grid

    def random(self, spec: M.RandomLayout, path: str) -> np.ndarray:
        center = self.vec(spec.center, f"{path}.center")
        rng = np.random.default_rng(self.seed_for(spec.seed, path))
        if spec.shape == "box":
            half = self.vec(spec.half_extents, f"{path}.half_extents")
            return center + (2.0 * rng.random((spec.count, self.dim)) - 1.0) * half
        direction = rng.standard_normal((spec.count, self.dim))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True) + 1e-300
        r = spec.radius * rng.random(spec.count) ** (1.0 / self.dim)
        return center + direction * r[:, None]

    def chain(self, spec: M.Chain, path: str):
        a, b = self.vec(spec.start, f"{path}.start"), self.vec(spec.end, f"{path}.end")
        if np.allclose(a, b):
            self.fail(f"{path}.end", "must differ from start")
        s = np.linspace(0.0, 1.0, spec.count)[:, None]
        x = a + s * (b - a)
        pairs = np.stack([np.arange(spec.count - 1), np.arange(1, spec.count)], axis=1)
        pinned = {"none": [], "start": [0], "end": [spec.count - 1], "both": [0, spec.count - 1]}[spec.pin]
        k = np.full(len(pairs), spec.stiffness)
        return x, pairs, k, np.full(len(pairs), spec.damping), pinned

    def cloth(self, spec: M.Cloth, path: str):
        corner = self.vec(spec.corner, f"{path}.corner")
        eu, ev = self.vec(spec.edge_u, f"{path}.edge_u"), self.vec(spec.edge_v, f"{path}.edge_v")
        nu, nv = spec.counts
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="xy")    # (nv, nu)
        x = corner + (i.reshape(-1, 1) / (nu - 1)) * eu + (j.reshape(-1, 1) / (nv - 1)) * ev
        idx = np.arange(nu * nv).reshape(nv, nu)                            # idx[j, i] = j nu + i

        def join(p, q):
            return np.stack([p.ravel(), q.ravel()], axis=1)

        structural = np.concatenate([join(idx[:, :-1], idx[:, 1:]), join(idx[:-1, :], idx[1:, :])])
        shear = np.concatenate([join(idx[:-1, :-1], idx[1:, 1:]), join(idx[:-1, 1:], idx[1:, :-1])])
        bend = np.concatenate([join(idx[:, :-2], idx[:, 2:]), join(idx[:-2, :], idx[2:, :])])
        ks = spec.stiffness
        kshear = ks / 2.0 if spec.shear_stiffness is None else spec.shear_stiffness
        kbend = ks / 10.0 if spec.bend_stiffness is None else spec.bend_stiffness
        parts = [(structural, ks)] + [(p, k) for p, k in ((shear, kshear), (bend, kbend)) if k > 0 and len(p)]
        pairs = np.concatenate([p for p, _ in parts]).astype(np.int64)
        k = np.concatenate([np.full(len(p), kk) for p, kk in parts])
        pinned = {"none": [], "corners": [0, nu - 1], "edge": list(range(nu))}[spec.pin]
        return x, pairs, k, np.full(len(pairs), spec.damping), pinned

    # ---- fields ----------------------------------------------------------------------------
    def field(self, name: str, path: str):
        if name in self.fields:
            if self.fields[name] is None:
                self.fail(path, f"field {name!r} refers to itself through a sum")
            return self.fields[name]
        if name not in self.m.fields:
            self.fail(path, f"no field named {name!r} in [fields]" + did_you_mean(name, list(self.m.fields)))
        self.fields[name] = None      # cycle guard
        spec = self.m.fields[name]
        fpath = f"fields.{name}"
        with self.at(fpath):
            obj = self._make_field(spec, fpath)
        self.fields[name] = obj
        return obj

    def _make_field(self, spec, path):
        import inertia.fields as fields

        dim = self.dim
        if spec.type == "uniform":
            return fields.Uniform(self.vec(spec.velocity, f"{path}.velocity"))
        if spec.type == "rotation":
            center = self.vec(spec.center, f"{path}.center")
            w = spec.angular_velocity
            if dim == 3:
                w = self.vec([0.0, 0.0, w] if isinstance(w, float) else w, f"{path}.angular_velocity", 3)
            elif not isinstance(w, float):
                self.fail(f"{path}.angular_velocity", "must be a number (rad/s) in a 2-D scene")
            return fields.Rotation(center, w)
        if spec.type == "vortex":
            cls = self.require(fields, "Vortex", path)
            kwargs = dict(center=self.vec(spec.center, f"{path}.center"), circulation=spec.circulation,
                          core_radius=spec.core_radius)
            if spec.axis is not None:
                kwargs["axis"] = self.vec(spec.axis, f"{path}.axis", 3)
            return cls(**kwargs)
        if spec.type == "source":
            cls = self.require(fields, "Source", path)
            return cls(center=self.vec(spec.center, f"{path}.center"), strength=spec.strength,
                       core_radius=spec.core_radius)
        if spec.type == "curl_noise":
            cls = self.require(fields, "CurlNoise", path)
            boundaries = [self.collider_by_name(n, f"{path}.boundaries[{i}]") for i, n in enumerate(spec.boundaries)]
            return cls(dim, seed=self.seed_for(spec.seed, path), kind=spec.kind, frequency=spec.frequency,
                       octaves=spec.octaves, lacunarity=spec.lacunarity, gain=spec.gain,
                       speed=spec.speed, time_frequency=spec.time_frequency,
                       boundaries=boundaries, boundary_width=spec.boundary_width)
        if spec.type == "grid":
            cls = self.require(fields, "Grid", path)
            values = self.npy(spec.file, f"{path}.file")
            kwargs = dict(spacing=spec.spacing if isinstance(spec.spacing, float) else self.vec(spec.spacing, f"{path}.spacing"),
                          outside=spec.outside)
            if spec.origin is not None:
                kwargs["origin"] = self.vec(spec.origin, f"{path}.origin")
            if values.ndim != dim + 1:
                self.fail(f"{path}.file", f"must hold a {dim}-D grid of {dim}-vectors (got shape {values.shape})")
            return cls(values, **kwargs)
        if spec.type == "sum":
            parts = [self.field(n, f"{path}.fields[{i}]") for i, n in enumerate(spec.fields)]
            weights = spec.weights or [1.0] * len(parts)
            if len(weights) != len(parts):
                self.fail(f"{path}.weights", f"needs one weight per field: {len(parts)} (got {len(weights)})")
            return sum((w * f if w != 1.0 else f) for w, f in zip(weights, parts))
        self.fail(path, f"field type {spec.type!r} is not supported")  # pragma: no cover

    # ---- forces ----------------------------------------------------------------------------
    def force(self, spec, path: str, count: int):
        t = spec.type
        if t == "gravity":
            g = (self.vec(spec.acceleration, f"{path}.acceleration") if spec.acceleration is not None
                 else np.array([0.0, -9.81] if self.dim == 2 else [0.0, 0.0, -9.81]))
            return F.Gravity(g)
        if t == "drag":
            return F.Drag(spec.coefficient)
        if t == "quadratic_drag":
            return F.QuadraticDrag(spec.coefficient)
        if t == "springs":
            pairs = np.asarray(spec.pairs, dtype=np.int64).reshape(-1, 2)
            bad = np.flatnonzero(pairs.max(axis=1, initial=0) >= count) if len(pairs) else []
            if len(bad):
                self.fail(f"{path}.pairs[{bad[0]}]", f"index out of range: the group has {count} particles "
                                                   f"(indices 0..{count - 1}); got {pairs[bad[0]].tolist()}")
            m = len(pairs)
            rest = None if spec.rest_lengths is None else self.per_item(spec.rest_lengths, m, f"{path}.rest_lengths")
            return F.Springs(pairs, stiffness=self.per_item(spec.stiffness, m, f"{path}.stiffness"),
                             damping=self.per_item(spec.damping, m, f"{path}.damping"), rest_lengths=rest)
        if t == "anchor_springs":
            idx = np.asarray(spec.indices, dtype=np.int64)
            if len(idx) and idx.max() >= count:
                i = int(np.argmax(idx >= count))
                self.fail(f"{path}.indices[{i}]", f"index out of range: the group has {count} particles (got {idx[i]})")
            anchors = spec.anchors
            if anchors and isinstance(anchors[0], float):
                anchors = np.tile(self.vec(anchors, f"{path}.anchors"), (len(idx), 1))
            else:
                anchors = self.points(anchors, f"{path}.anchors")
                if len(anchors) != len(idx):
                    self.fail(f"{path}.anchors", f"needs one anchor per index: {len(idx)} (got {len(anchors)})")
            m = len(idx)
            return F.AnchorSprings(idx, anchors, stiffness=self.per_item(spec.stiffness, m, f"{path}.stiffness"),
                                   damping=self.per_item(spec.damping, m, f"{path}.damping"),
                                   rest_length=self.per_item(spec.rest_length, m, f"{path}.rest_length"))
        if t == "wind":
            velocity = (self.field(spec.field, f"{path}.field") if spec.field is not None
                        else self.vec(spec.velocity, f"{path}.velocity"))
            return F.Wind(velocity, spec.coefficient, gust_amplitude=spec.gust_amplitude,
                          gust_frequency=spec.gust_frequency, seed=self.seed_for(spec.seed, path))
        if t == "attractor":
            return F.Attractor(self.vec(spec.center, f"{path}.center"), spec.strength, spec.softening)
        if t == "field_force":
            from .fields import field_force
            return field_force(self.field(spec.field, f"{path}.field"), spec.scale, spec.per_mass)
        if t == "grid_force":
            values = self.npy(spec.file, f"{path}.file")
            spacing = spec.spacing if isinstance(spec.spacing, float) else self.vec(spec.spacing, f"{path}.spacing")
            return F.GridForceField(values, self.vec(spec.origin, f"{path}.origin"), spacing, per_mass=spec.per_mass)
        self.fail(path, f"force type {t!r} is not supported")  # pragma: no cover

    # ---- colliders -------------------------------------------------------------------------
    def collider_by_name(self, name: str, path: str):
        if name not in self.collider_names:
            self.fail(path, f"no collider named {name!r}" + did_you_mean(name, list(self.collider_names)))
        return self.collider_names[name]

    def build_colliders(self) -> None:
        for i, spec in enumerate(self.m.colliders):
            path = f"colliders[{i}]"
            with self.at(path):
                obj = self._make_collider(spec, path)
            name = spec.name or f"{spec.type}{i}"
            if name in self.collider_names:
                self.fail(f"{path}.name", f"collider name {name!r} is used twice")
            obj.name = name
            self.collider_names[name] = obj
            self.colliders.append((spec, obj, path))

    def _motion(self, spec: M.Motion, path: str, rest):
        from ..collision.motion import Motion

        dim = self.dim
        if spec.times is not None:
            kwargs = {}
            if spec.positions is not None:
                if len(spec.positions) != len(spec.times):
                    self.fail(f"{path}.positions", f"needs one position per time: {len(spec.times)} (got {len(spec.positions)})")
                kwargs["positions"] = self.points(spec.positions, f"{path}.positions")
            if spec.rotations is not None:
                if len(spec.rotations) != len(spec.times):
                    self.fail(f"{path}.rotations", f"needs one rotation per time: {len(spec.times)} (got {len(spec.rotations)})")
                kwargs["rotations"] = np.asarray(spec.rotations, dtype=np.float64)
            with self.at(path):
                return Motion.keyframes(spec.times, **kwargs)
        rest = np.asarray(rest, dtype=np.float64)[:dim].copy()
        velocity = None if spec.velocity is None else self.vec(spec.velocity, f"{path}.velocity")
        amplitude = None if spec.amplitude is None else self.vec(spec.amplitude, f"{path}.amplitude")
        omega = spec.angular_velocity
        if omega is not None:
            if dim == 2 and not isinstance(omega, float):
                self.fail(f"{path}.angular_velocity", "must be a number (rad/s) in a 2-D scene")
            if dim == 3:
                omega = self.vec([0.0, 0.0, omega] if isinstance(omega, float) else omega, f"{path}.angular_velocity", 3)
        position = None
        if velocity is not None or amplitude is not None:
            w, phase = 2.0 * math.pi * spec.frequency, spec.phase

            def position(t, rest=rest, velocity=velocity, amplitude=amplitude, w=w, phase=phase):
                p = rest.copy()
                if velocity is not None:
                    p += velocity * t
                if amplitude is not None:
                    p += amplitude * math.sin(w * t + phase)
                return p
        rotation = None
        if omega is not None:
            def rotation(t, omega=omega):
                return omega * t      # 2-D: an angle; 3-D: a rotation vector
        return Motion(position=position, rotation=rotation)

    def _make_collider(self, spec, path):
        from ..collision import shapes as S

        dim = self.dim
        t = spec.type
        rest = None
        if t == "plane":
            args = dict(point=self.vec(spec.point, f"{path}.point"), normal=self.vec(spec.normal, f"{path}.normal"))
            rest, cls = args["point"], S.Plane
        elif t == "sphere":
            args = dict(center=self.vec(spec.center, f"{path}.center"), radius=spec.radius)
            rest, cls = args["center"], S.Sphere
        elif t in ("box", "container"):
            args = dict(center=self.vec(spec.center, f"{path}.center"),
                        half_extents=self.vec(spec.half_extents, f"{path}.half_extents"))
            if spec.rotation is not None:
                r = spec.rotation
                if dim == 2 and not isinstance(r, float):
                    self.fail(f"{path}.rotation", "must be an angle in radians in a 2-D scene")
                if dim == 3 and (isinstance(r, float) or len(r) not in (3, 4)):
                    self.fail(f"{path}.rotation", "must be a rotation vector [x, y, z] (axis * radians) "
                                                  "or a quaternion [w, x, y, z] in a 3-D scene")
                args["rotation"] = r
            rest, cls = args["center"], (S.Box if t == "box" else S.Container)
        elif t == "capsule":
            a, b = self.vec(spec.a, f"{path}.a"), self.vec(spec.b, f"{path}.b")
            args = dict(a=a, b=b, radius=spec.radius)
            rest, cls = 0.5 * (a + b), S.Capsule
        elif t == "cylinder":
            if dim != 3:
                self.fail(path, "cylinder colliders are 3-D only")
            args = dict(center=self.vec(spec.center, f"{path}.center"), radius=spec.radius,
                        half_height=spec.half_height, axis=self.vec(spec.axis, f"{path}.axis", 3))
            rest, cls = args["center"], S.Cylinder
        elif t == "mesh":
            if dim != 3:
                self.fail(path, "mesh colliders are 3-D only")
            return self._mesh(spec, path)
        elif t == "sdf":
            return self._sdf(spec, path)
        else:  # pragma: no cover
            self.fail(path, f"collider type {t!r} is not supported")
        if spec.motion is not None:
            args["motion"] = self._motion(spec.motion, f"{path}.motion", rest)
        return cls(**args)

    def _mesh(self, spec, path):
        from ..collision.mesh import Mesh

        file = self.file(spec.file, f"{path}.file")
        check_mesh_suffix(file, f"{path}.file", self.fail)
        source = str(file)
        if spec.scale != 1.0 or spec.translation is not None:
            vertices, faces = read_mesh_file(file, path, self.fail, spec.scale)
            if spec.translation is not None:
                vertices = vertices + self.vec(spec.translation, f"{path}.translation")
            source = (vertices, faces)
        kwargs = dict(resolution=spec.resolution, signed=spec.signed, thickness=spec.thickness)
        if spec.motion is not None:
            kwargs["motion"] = self._motion(spec.motion, f"{path}.motion", np.zeros(3))
        try:
            return Mesh(source, **kwargs)
        except ImportError as exc:
            self.fail(path, str(exc))
        except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a file it cannot read
            self.fail(f"{path}.file", f"cannot use {file} as a collider: {type(exc).__name__}: {exc}")

    def _sdf(self, spec, path):
        from scipy.interpolate import RegularGridInterpolator

        from ..collision.shapes import SDF

        values = self.npy(spec.file, f"{path}.file")
        if values.ndim != self.dim or min(values.shape) < 2:
            self.fail(f"{path}.file", f"must hold a {self.dim}-D grid of distances, each side >= 2 (got shape {values.shape})")
        origin = self.vec(spec.origin, f"{path}.origin")
        axes = [origin[a] + spec.spacing * np.arange(n) for a, n in enumerate(values.shape)]
        interpolate = RegularGridInterpolator(axes, np.asarray(values, dtype=np.float64),
                                              bounds_error=False, fill_value=None)
        hi = origin + spec.spacing * (np.array(values.shape) - 1)
        kwargs = dict(dim=self.dim, bake={"bounds": (origin, hi), "resolution": int(max(values.shape)) - 1},
                      rest_point=0.5 * (origin + hi), scale=spec.spacing)
        if spec.motion is not None:
            kwargs["motion"] = self._motion(spec.motion, f"{path}.motion", 0.5 * (origin + hi))
        return SDF(interpolate, **kwargs)

    # ---- groups ----------------------------------------------------------------------------
    def integrator(self, group, path: str):
        name = group.integrator or self.m.simulation.integrator
        options = {k: v for k, v in self.m.simulation.integrator_options.model_dump().items()
                   if v is not None and k in _INTEGRATOR_OPTIONS.get(name, ())}
        if group.integrator_options is not None:
            for k, v in group.integrator_options.model_dump().items():
                if v is None:
                    continue
                if k not in _INTEGRATOR_OPTIONS.get(name, ()):
                    takes = _INTEGRATOR_OPTIONS.get(name)
                    self.fail(f"{path}.integrator_options.{k}",
                              f"integrator {name!r} takes " + (f"only {', '.join(takes)}" if takes else "no options"))
                options[k] = v
        return name, options

    def check_group_names(self, names: list[str], path: str, known: list[str]) -> None:
        for i, n in enumerate(names):
            if n not in known:
                self.fail(f"{path}[{i}]", f"no particle group named {n!r}" + did_you_mean(n, known))

    def emitter_capacity(self, group) -> int:
        duration = self.m.simulation.duration
        total = 0.0
        for e in group.emitters:
            life = e.lifetime if isinstance(e.lifetime, float) else e.lifetime[1]
            window = min(e.stop, duration) - e.start
            total += e.rate * max(0.0, min(life, window)) + e.rate * self.m.simulation.dt + 1
        return int(math.ceil(1.1 * total)) + 8

    def emitter(self, spec: M.EmitterSpec, path: str) -> Emitter:
        if spec.source is None:
            source = PointSource(self.vec(spec.position, f"{path}.position"))
        else:
            s, sp = spec.source, f"{path}.source"
            with self.at(sp):
                if s.type == "point":
                    source = PointSource(self.vec(s.point, f"{sp}.point"))
                elif s.type == "box":
                    source = BoxSource(self.vec(s.center, f"{sp}.center"), self.vec(s.half_extents, f"{sp}.half_extents"))
                elif s.type == "sphere":
                    source = SphereSource(self.vec(s.center, f"{sp}.center"), s.radius)
                else:
                    if self.dim != 3:
                        self.fail(sp, "disk sources are 3-D only")
                    source = DiskSource(self.vec(s.center, f"{sp}.center"), s.radius, self.vec(s.normal, f"{sp}.normal"))
        if spec.cone is None:
            velocity = self.vec(spec.velocity, f"{path}.velocity")
        else:
            c = spec.cone
            with self.at(f"{path}.cone"):
                velocity = Cone(self.vec(c.direction, f"{path}.cone.direction"), c.speed, c.spread, c.speed_jitter)
        lifetime = spec.lifetime if isinstance(spec.lifetime, float) else tuple(spec.lifetime)
        lifetime = tuple(math.inf if v >= 1e30 else v for v in np.atleast_1d(lifetime))
        with self.at(path):
            return Emitter(spec.rate, source, velocity, lifetime if len(lifetime) == 2 else lifetime[0],
                           start=spec.start, stop=math.inf if spec.stop >= 1e30 else spec.stop,
                           seed=self.seed_for(spec.seed, path))

    def particle_group(self, world: World, index: int, group: M.ParticleGroup, names: list[str]):
        path = f"particles[{index}]"
        name = names[index]
        springs = None
        pinned = list(group.pinned)
        surface = None
        if group.positions is not None:
            x = self.points(group.positions, f"{path}.positions")
        elif group.lattice is not None:
            x = self.lattice(group.lattice, f"{path}.lattice")
        elif group.random is not None:
            x = self.random(group.random, f"{path}.random")
        elif group.chain is not None:
            x, pairs, k, c, pins = self.chain(group.chain, f"{path}.chain")
            springs, pinned = (pairs, k, c), pinned + pins
        elif group.cloth is not None:
            x, pairs, k, c, pins = self.cloth(group.cloth, f"{path}.cloth")
            springs, pinned = (pairs, k, c), pinned + pins
            surface = cloth_triangles(*group.cloth.counts)
        else:
            x = np.zeros((0, self.dim))
        n_layout = len(x)
        capacity = (group.capacity or self.emitter_capacity(group)) if group.emitters else 0
        n = n_layout + capacity
        # initial velocities
        v = np.zeros((n, self.dim))
        if group.velocities is not None:
            vel = self.points(group.velocities, f"{path}.velocities")
            if len(vel) != n_layout:
                self.fail(f"{path}.velocities", f"needs one velocity per position: {n_layout} (got {len(vel)})")
            v[:n_layout] = vel
        elif group.velocity is not None:
            v[:n_layout] = self.vec(group.velocity, f"{path}.velocity")
        # per-particle constants
        for key in ("mass", "radius"):
            value = getattr(group, key)
            if isinstance(value, list) and len(value) != n_layout:
                self.fail(f"{path}.{key}", f"needs one value per particle of the layout: {n_layout} (got {len(value)})"
                          + ("; emitted particles need a single value" if capacity else ""))
        mass = group.mass if not isinstance(group.mass, list) else np.concatenate([group.mass, np.ones(capacity)])
        radius = group.radius if not isinstance(group.radius, list) else np.concatenate([group.radius, np.zeros(capacity)])
        bad = [p for p in pinned if p >= n_layout]
        if bad:
            self.fail(f"{path}.pinned", f"index out of range: the layout has {n_layout} particles (got {bad[0]})")
        positions = np.concatenate([x, np.zeros((capacity, self.dim))]) if capacity else x
        with self.at(path):
            system = ParticleSystem(positions, v, mass, pinned=pinned or None, radius=radius)
            if capacity:
                system.active[n_layout:] = False
                system.refresh_masses()
        # forces: the scene's, then the group's own, then the layout's springs
        for k, spec in enumerate(self.m.forces):
            if spec.groups is None or name in spec.groups:
                fpath = f"forces[{k}]"
                with self.at(fpath):
                    system.add_force(self.force(spec, fpath, n))
        for k, spec in enumerate(group.forces):
            fpath = f"{path}.forces[{k}]"
            if spec.groups is not None:
                self.fail(f"{fpath}.groups", "only top-level [[forces]] take `groups`; this force already belongs to one group")
            with self.at(fpath):
                system.add_force(self.force(spec, fpath, n))
        if springs is not None:
            pairs, k, c = springs
            with self.at(path):
                system.add_force(F.Springs(pairs, stiffness=k, damping=c))
        for k, spec in enumerate(group.emitters):
            epath = f"{path}.emitters[{k}]"
            emitter = self.emitter(spec, epath)
            with self.at(epath):
                system.add_emitter(emitter)
        # colliders
        attached = []
        if group.collide:
            for spec, obj, cpath in self.colliders:
                if spec.groups is not None and name not in spec.groups:
                    continue
                restitution = spec.restitution if group.restitution is None else group.restitution
                friction = spec.friction if group.friction is None else group.friction
                with self.at(cpath):
                    system.add_collider(obj, restitution=restitution, friction=friction)
                attached.append(obj)
        if group.collision_mode != "a_priori":
            with self.at(f"{path}.collision_mode"):
                system.collision_mode = group.collision_mode
        if group.self_collisions:
            with self.at(f"{path}.self_collisions"):
                system.self_collisions = True
        if group.contacts is not None:
            from ..collision.particle_stage import configure_contacts

            options = {k: v for k, v in group.contacts.model_dump().items() if v is not None}
            if options:
                with self.at(f"{path}.contacts"):
                    configure_contacts(system, **options)
        integrator, options = self.integrator(group, path)
        with self.at(f"{path}.integrator"):
            g = world.add(name, system, integrator=integrator, color=group.color, kind="particles",
                          triangles=surface, **options)
        g.colliders = attached

    def tracer_group(self, world: World, index: int, group: M.TracerGroup, name: str):
        path = f"tracers[{index}]"
        if group.positions is not None:
            x = self.points(group.positions, f"{path}.positions")
        elif group.lattice is not None:
            x = self.lattice(group.lattice, f"{path}.lattice")
        else:
            x = self.random(group.random, f"{path}.random")
        field = self.field(group.field, f"{path}.field")
        if getattr(field, "dim", self.dim) != self.dim:
            self.fail(f"{path}.field", f"field {group.field!r} is {field.dim}-D; the scene is {self.dim}-D")
        with self.at(path):
            system = Tracers(x, field)
            system.radius[:] = group.radius
        integrator, options = self.integrator(group, path)
        with self.at(f"{path}.integrator"):
            world.add(name, system, integrator=integrator, color=group.color, kind="tracers", **options)

    # ---- everything ------------------------------------------------------------------------
    def world(self) -> World:
        m = self.m
        names = [g.name or f"particles{i}" for i, g in enumerate(m.particles)]
        names += [g.name or f"tracers{i}" for i, g in enumerate(m.tracers)]
        seen = set()
        for i, n in enumerate(names):
            if n in seen:
                where = f"particles[{i}].name" if i < len(m.particles) else f"tracers[{i - len(m.particles)}].name"
                self.fail(where, f"group name {n!r} is used twice; names must be unique")
            seen.add(n)
        particle_names = names[:len(m.particles)]
        for k, spec in enumerate(m.forces):
            if spec.groups is not None:
                self.check_group_names(spec.groups, f"forces[{k}].groups", particle_names)
        for k, spec in enumerate(m.colliders):
            if spec.groups is not None:
                self.check_group_names(spec.groups, f"colliders[{k}].groups", particle_names)
        self.build_colliders()
        from .rigid_builder import build_rigid

        rigid = build_rigid(m, source=self.source, base_dir=self.base)
        kwargs = {}
        if rigid is not None and "model" in inspect.signature(World).parameters:
            kwargs = dict(model=rigid.model, rigid_options={k: v for k, v in rigid.options.items() if k != "dt"})
        world = World(dt=m.simulation.dt, substeps=m.simulation.substeps,
                      colliders=[obj for _, obj, _ in self.colliders], name=m.name or "scene", **kwargs)
        world.rigid_scene = rigid          # the bodies (RigidScene): colours, vehicles
        if rigid is not None and rigid.vehicles and getattr(world, "rigid", None) is not None:
            _drive_vehicles(world, rigid)
        for i, group in enumerate(m.particles):
            self.particle_group(world, i, group, names)
        for i, group in enumerate(m.tracers):
            self.tracer_group(world, i, group, names[len(m.particles) + i])
        add_sph_fluids(self, world)
        add_grid_fluids(self, world)
        return world


def _drive_vehicles(world, rigid) -> None:
    """Run the scene's vehicle scripts before each world step (the World has no pre-step hook yet: this
    wraps the instance's ``step``). The script is re-applied from the clock, so a resumed run sets the same
    controls; the wheels' spin is not in the checkpoint (a resumed vehicle run is not bit for bit)."""
    rigid.attach(world.rigid)
    step = world.step

    def step_with_vehicles():
        rigid.before_step(world.rigid.state.time)
        step()

    world.step = step_with_vehicles


def build_world(model: M.SceneModel, *, source=None, base_dir=None) -> World:
    """Build the `World` a validated scene describes (raises `SceneError` with key paths)."""
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    return _Builder(model, source, base).world()


def build_colliders(model: M.SceneModel, *, source=None, base_dir=None) -> list:
    """Only the colliders of a scene (for drawing a recorded run)."""
    b = _Builder(model, source, Path(base_dir) if base_dir is not None else Path.cwd())
    b.build_colliders()
    return [obj for _, obj, _ in b.colliders]
