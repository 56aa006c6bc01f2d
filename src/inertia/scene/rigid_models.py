"""Scene-file models of rigid bodies: ``[materials.NAME]``, ``[bodies.NAME]`` and ``[rigid]``.

Syntax (3-D scenes only; z up; lengths in metres, angles in degrees where a key says so)::

    [rigid]                       # solver options of inertia.rigid.world.RigidWorld
    substeps = 8
    contact_hertz = 60.0
    sleep = true
    gravity = [0, 0, -9.81]

    [materials.wood]              # friction, restitution, rolling friction (m lever arm), density
    friction = 0.5
    restitution = 0.1

    [bodies.ground]
    motion = "static"
    shape = { type = "plane" }

    [bodies.crate]
    shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }
    material = "wood"              # default: the built-in "default" material
    density = 500                  # or mass = 4.0 (kg); default: the material's density
    position = [0, 0, 1]
    rotation = { axis = [0, 0, 1], degrees = 30 }   # or { quaternion = [w, x, y, z] } or { euler_degrees = [rx, ry, rz] }
    velocity = [1, 0, 0]
    angular_velocity = [0, 0, 0]
    array = { count = [10, 10, 10], spacing = [0.21, 0.21, 0.21] }   # a grid of copies
    # pyramid = { base = 20, spacing = [0.21, 0.2], depth = 1 }      # a wall (depth 1) or square pyramid (depth = base)

A body is one ``shape`` or a compound ``shapes = [...]`` (each with its own ``position``/``rotation``
in the body frame). ``mix = [shape, shape, ...]`` with an ``array`` makes copy k use shape k mod len.
Shapes: sphere (radius), box (half_extents), capsule / cylinder (radius, half_length along local z),
hull (points), hull parts (``parts`` = lists of points, a convex decomposition for dynamic bodies), mesh
(file or vertices + triangles; static or kinematic bodies only), plane (normal, offset), heightfield
(heights rows or a .npy file, spacing).

Limitations: a kinematic body moves with its constant velocity (no scripted paths yet); ``mesh``
files are read with trimesh; heightfield and mesh shapes cannot belong to dynamic bodies.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

#: Fastest initial body speed a scene may give (m/s): the RigidWorld's ``max_speed`` default, above
#: which a step reports the body as diverged (so `inertia validate` says it before any run)
MAX_BODY_SPEED = 1e4

#: Most bodies one [bodies.NAME] table may make (the solver is far from real time beyond ~10^4).
MAX_COPIES = 100_000

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3, description="a 3-D vector")]
Point3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, strict=True,
                              allow_inf_nan=False)


# ---------------------------------------------------------------------------------------- poses
class Rotation(_Model):
    """Exactly one of: a unit quaternion (w, x, y, z); an axis and an angle in degrees; Euler angles in
    degrees (extrinsic x, then y, then z)."""

    quaternion: Annotated[list[float], Field(min_length=4, max_length=4)] | None = None
    axis: Vec3 | None = None
    degrees: float | None = Field(None, description="angle about `axis` (degrees)")
    euler_degrees: Vec3 | None = Field(None, description="rotations about x, then y, then z (fixed axes)")

    @model_validator(mode="after")
    def _one(self):
        given = [k for k in ("quaternion", "axis", "euler_degrees") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of quaternion = [w, x, y, z], axis = [x, y, z] with degrees, or "
                             f"euler_degrees = [rx, ry, rz] (got {given or 'none'})")
        if self.quaternion is not None:
            n = math.sqrt(sum(c * c for c in self.quaternion))
            if abs(n - 1.0) > 1e-6:
                raise ValueError(f"quaternion must be a unit quaternion [w, x, y, z] (|q| = 1 within 1e-6); "
                                 f"got |q| = {n:.9g}")
        if self.axis is not None:
            if self.degrees is None:
                raise ValueError("axis needs `degrees` (the angle about it)")
            if math.sqrt(sum(c * c for c in self.axis)) < 1e-12:
                raise ValueError("axis must be a non-zero vector")
        elif self.degrees is not None:
            raise ValueError("degrees needs `axis`")
        return self

    def as_quaternion(self) -> tuple[float, float, float, float]:
        if self.quaternion is not None:
            w, x, y, z = self.quaternion
            n = math.sqrt(w * w + x * x + y * y + z * z)
            return (w / n, x / n, y / n, z / n)
        if self.axis is not None:
            return _axis_angle(self.axis, math.radians(self.degrees))
        q = (1.0, 0.0, 0.0, 0.0)
        for axis, deg in zip(((1, 0, 0), (0, 1, 0), (0, 0, 1)), self.euler_degrees):
            q = quat_mul(_axis_angle(axis, math.radians(deg)), q)
        return q


def _axis_angle(axis, angle):
    n = math.sqrt(sum(c * c for c in axis))
    s = math.sin(0.5 * angle) / n
    return (math.cos(0.5 * angle), axis[0] * s, axis[1] * s, axis[2] * s)


def quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


# ---------------------------------------------------------------------------------------- shapes
class _Shape(_Model):
    position: Vec3 | None = Field(None, description="pose in the body frame (compound bodies)")
    rotation: Rotation | None = None
    material: str | None = Field(None, description="overrides the body's material for this shape")


class SphereShape(_Shape):
    type: Literal["sphere"]
    radius: Positive


class BoxShape(_Shape):
    type: Literal["box"]
    half_extents: Annotated[list[Positive], Field(min_length=3, max_length=3)]


class CapsuleShape(_Shape):
    type: Literal["capsule"]
    radius: Positive
    half_length: Positive = Field(description="half length of the core segment along local z (m)")


class CylinderShape(_Shape):
    type: Literal["cylinder"]
    radius: Positive
    half_length: Positive = Field(description="half height along local z (m)")


class HullShape(_Shape):
    """A convex hull of ``points`` (>= 4, not coplanar), or several hulls (``parts``: a convex
    decomposition, the way a dynamic body takes a concave mesh)."""

    type: Literal["hull"]
    points: list[Point3] | None = None
    parts: list[list[Point3]] | None = None

    @model_validator(mode="after")
    def _one(self):
        if (self.points is None) == (self.parts is None):
            raise ValueError("give exactly one of points = [[x, y, z], ...] or parts = [[[x, y, z], ...], ...]")
        return self


class MeshShape(_Shape):
    """A triangle mesh for static or kinematic bodies: ``file`` (OBJ/STL/PLY via trimesh) or inline
    ``vertices`` and ``triangles`` (counter-clockwise seen from outside)."""

    type: Literal["mesh"]
    file: str | None = None
    scale: Positive = 1.0
    vertices: list[Point3] | None = None
    triangles: list[Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=3, max_length=3)]] | None = None

    @model_validator(mode="after")
    def _one(self):
        if (self.file is None) == (self.vertices is None) or (self.vertices is None) != (self.triangles is None):
            raise ValueError("give exactly one of file = 'mesh.obj' or vertices = [...] with triangles = [...]")
        return self


class PlaneShape(_Shape):
    type: Literal["plane"]
    normal: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 1.0])
    offset: float = Field(0.0, description="the surface is normal . x = offset; solid below")


class HeightfieldShape(_Shape):
    type: Literal["heightfield"]
    heights: list[list[float]] | None = Field(None, description="rows heights[i][j] at x_i, y_j (m)")
    file: str | None = Field(None, description=".npy (nx, ny) array of heights instead of `heights`")
    spacing: Annotated[list[Positive], Field(min_length=2, max_length=2)] = Field(description="dx, dy (m)")

    @model_validator(mode="after")
    def _one(self):
        if (self.heights is None) == (self.file is None):
            raise ValueError("give exactly one of heights = [[...], ...] or file = 'heights.npy'")
        return self


ShapeSpec = Annotated[Union[SphereShape, BoxShape, CapsuleShape, CylinderShape, HullShape, MeshShape,
                            PlaneShape, HeightfieldShape], Field(discriminator="type")]


# ---------------------------------------------------------------------------------------- layouts
class ArrayLayout(_Model):
    """A grid of copies: copy (i, j, k) sits at position + (i sx, j sy, k sz)."""

    count: Annotated[list[Annotated[int, Field(ge=1)]], Field(min_length=3, max_length=3)]
    spacing: Vec3
    jitter: NonNegative = Field(0.0, description="uniform random offset per copy in [-jitter, jitter] (m)")
    seed: Annotated[int, Field(ge=0)] | None = None


class PyramidLayout(_Model):
    """Layers of copies: layer k has (base - k) copies along x (and along y when depth = base, a square
    pyramid); rows sit `spacing[1]` apart in z, each layer shifted half a step."""

    base: Annotated[int, Field(ge=1, le=200)]
    spacing: Annotated[list[Positive], Field(min_length=2, max_length=2)] = Field(
        description="horizontal step, vertical step (m)")
    square: bool = Field(False, description="a square pyramid (layer k: (base-k)^2 copies) instead of a wall")


class Material(_Model):
    friction: NonNegative = 0.6
    restitution: Annotated[float, Field(ge=0, le=1)] = 0.0
    rolling_friction: NonNegative = Field(0.0, description="lever arm (m): |rolling impulse| <= value * normal impulse")
    density: Positive = Field(1000.0, description="default density (kg/m^3) of shapes made of it")


class Body(_Model):
    """One body, or a grid / pyramid of copies of it."""

    shape: ShapeSpec | None = None
    shapes: list[ShapeSpec] | None = Field(None, description="a compound body")
    mix: list[ShapeSpec] | None = Field(None, description="with array/pyramid: copy k uses mix[k % len]")
    motion: Literal["dynamic", "kinematic", "static"] = "dynamic"
    density: Positive | None = Field(None, description="kg/m^3 (default: the material's)")
    mass: Positive | None = Field(None, description="kg; overrides the density")
    material: str = "default"
    position: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rotation: Rotation | None = None
    velocity: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    angular_velocity: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="rad/s, world frame")
    linear_damping: NonNegative = 0.0
    angular_damping: NonNegative = 0.0
    bullet: bool = Field(False, description="sweep this body for its time of impact every step (fast projectiles)")
    array: ArrayLayout | None = None
    pyramid: PyramidLayout | None = None
    color: str | None = Field(None, description="#rrggbb")

    @model_validator(mode="after")
    def _one(self):
        given = [k for k in ("shape", "shapes", "mix") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of shape, shapes (compound) or mix (with array/pyramid); got {given or 'none'}")
        if self.mix is not None and self.array is None and self.pyramid is None:
            raise ValueError("mix needs array or pyramid (it picks a shape per copy)")
        if self.array is not None and self.pyramid is not None:
            raise ValueError("give array or pyramid, not both")
        if self.copies > MAX_COPIES:
            raise ValueError(f"array/pyramid makes {self.copies:,} bodies; at most {MAX_COPIES:,} per table")
        speed = math.sqrt(sum(c * c for c in self.velocity))
        if speed > MAX_BODY_SPEED:
            raise ValueError(f"velocity: |v| = {speed:.3g} m/s is above the rigid solver's limit of {MAX_BODY_SPEED:g} "
                             "m/s (RigidWorld max_speed): the first step would stop the run as diverged")
        if self.color is not None and (len(self.color) != 7 or self.color[0] != "#"
                                       or any(c not in "0123456789abcdefABCDEF" for c in self.color[1:])):
            raise ValueError(f"color must be '#rrggbb'; got {self.color!r}")
        return self


    @property
    def copies(self) -> int:
        """How many bodies this table makes."""
        if self.array is not None:
            return math.prod(self.array.count)
        if self.pyramid is not None:
            n = self.pyramid.base
            return n * (n + 1) * (2 * n + 1) // 6 if self.pyramid.square else n * (n + 1) // 2
        return 1


class Rigid(_Model):
    """Solver options (inertia.rigid.world.RigidWorld)."""

    substeps: Annotated[int, Field(ge=1, le=256)] = 8
    contact_hertz: Positive = 60.0
    contact_damping_ratio: NonNegative = 10.0
    restitution_threshold: NonNegative = Field(1.0, description="m/s: slower approaches do not bounce")
    sleep: bool = True
    gravity: Vec3 = Field(default_factory=lambda: [0.0, 0.0, -9.81])
    margin: NonNegative = Field(0.02, description="speculative contact margin (m)")


class WheelSpec(_Model):
    """One ray-cast wheel (inertia.rigid.vehicle.Wheel): ``hardpoint`` in the chassis frame (m)."""

    hardpoint: Vec3
    rest_length: Positive = 0.3
    radius: Positive = 0.35
    stiffness: Positive = Field(30000.0, description="N/m")
    damping: NonNegative = Field(3000.0, description="N s/m")
    friction: NonNegative = 1.0
    inertia: Positive = Field(1.2, description="spin inertia (kg m^2)")
    steered: bool = False
    driven: bool = False


class ControlRow(_Model):
    """From ``time`` on (s), the keys given hold until a later row changes them."""

    time: NonNegative
    engine_torque: float | None = Field(None, description="N m on each driven wheel")
    steering: float | None = Field(None, description="rad, + = left")
    brake_torque: NonNegative | None = Field(None, description="N m on every wheel")


class Vehicle(_Model):
    """A ray-cast vehicle (inertia.rigid.vehicle.RaycastVehicle) on a dynamic body, driven by a script."""

    chassis: str = Field(description="name of a [bodies.NAME] table making one dynamic body")
    wheels: Annotated[list[WheelSpec], Field(min_length=1)]
    script: list[ControlRow] = Field(default_factory=list, description="rows in increasing time")

    @model_validator(mode="after")
    def _sorted(self):
        times = [r.time for r in self.script]
        if times != sorted(times):
            raise ValueError(f"script rows must be in increasing time; got times {times}")
        return self
