"""The scene file format: pydantic models of every section (``format_version = 1``).

A scene file (TOML, or JSON with the same structure) is validated by these models once, at
load time; `inertia.scene.build` then turns the validated models into arrays, force objects,
colliders and systems. Nothing of pydantic runs inside a time step.

Layout of a scene (see ``inertia/scene/schema.json`` for every key, type and default)::

    format_version = 1
    name = "fountain"
    [simulation]   dt, substeps, duration, fps, integrator, integrator_options, seed, dim
    [[particles]]  one system per group: a layout (positions | lattice | random | chain | cloth)
                   and/or emitters, mass, radius, pinned, forces, integrator, collision settings
    [[tracers]]    massless points advected by a named field (first-order integrators)
    [[forces]]     forces applied to every particle group (or to the groups named in `groups`)
    [[colliders]]  static or kinematic (`motion`) shapes shared by the particle groups
    [fields.NAME]  named vector fields used by tracers, wind and field forces
    [output]       which files a run writes
    [render]       image size, camera and colouring of videos and PNG frames

Conventions: lengths in metres, times in seconds, angles in degrees only where a key says so
(`*_degrees`), otherwise radians. 3-D scenes are z-up (gravity defaults to (0, 0, -9.81));
2-D scenes are y-up (gravity (0, -9.81)).

Limitations: vectors are checked for their length against ``simulation.dim`` in the build
step, not here (the error still names the key path).
"""

from __future__ import annotations

from pathlib import PurePosixPath, PureWindowsPath
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..ode.integrators import available as _available_integrators
from .fluids import GridFluidTable, SPHTable
from .rigid_models import Body, Material, Rigid, Vehicle

__all__ = [
    "FORMAT_VERSION", "INTEGRATORS", "FIRST_ORDER_INTEGRATORS", "SceneModel", "Simulation",
    "ParticleGroup", "TracerGroup", "Output", "Render",
]

#: The scene format version these models read.
FORMAT_VERSION = 1

INTEGRATORS = tuple(_available_integrators())
FIRST_ORDER_INTEGRATORS = ("euler", "midpoint", "rk4", "rk45")

IntegratorName = Literal[INTEGRATORS]  # type: ignore[valid-type]

Vec = Annotated[list[float], Field(min_length=2, max_length=3, description="a 2-D or 3-D vector")]
Points = Annotated[list[Vec], Field(description="a list of 2-D or 3-D points")]
PositiveFloat = Annotated[float, Field(gt=0)]
NonNegativeFloat = Annotated[float, Field(ge=0)]
Fraction = Annotated[float, Field(ge=0, le=1)]
Seed = Annotated[int, Field(ge=0, description="random seed; default: derived from simulation.seed")]


def _is_plain_name(text: str) -> bool:
    """A name usable as one path component: no separators, drive, parent reference or controls."""
    return (bool(text.strip()) and text not in (".", "..") and not any(c in text for c in "/\\:")
            and all(ord(c) >= 32 for c in text) and not text.startswith("~"))


def _is_inside_path(text: str) -> bool:
    """A relative path that stays below the directory it is joined to (POSIX and Windows forms)."""
    if not text.strip() or any(ord(c) < 32 for c in text) or text.startswith("~"):
        return False
    posix, windows = PurePosixPath(text), PureWindowsPath(text)
    if posix.is_absolute() or windows.anchor or windows.drive:
        return False
    return ".." not in posix.parts and ".." not in windows.parts


class _Model(BaseModel):
    """Base of every section: unknown keys are errors, models are immutable after loading.

    Types are strict: a number is a number (``mass = "0.01"`` and ``mass = true`` are errors; an
    integer is accepted where a float is expected), an integer is an integer (``substeps = 2.5``
    is an error), a boolean is ``true`` or ``false``; ``inf`` and ``nan`` are refused everywhere.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, strict=True,
                              allow_inf_nan=False)


# ----------------------------------------------------------------------------------------------
# simulation settings
# ----------------------------------------------------------------------------------------------
class IntegratorOptions(_Model):
    """Options of the integrators that take any (each applies to the integrators named)."""

    rtol: PositiveFloat | None = Field(None, description="rk45 relative tolerance (1e-6 default; 1e-3..1e-10)")
    atol: NonNegativeFloat | None = Field(None, description="rk45 absolute tolerance (1e-9 default)")
    max_substeps: Annotated[int, Field(ge=1)] | None = Field(None, description="rk45 internal steps per step")
    cg_tolerance: PositiveFloat | None = Field(
        None, description="implicit_euler CG relative residual (1e-8 default; 1e-4 is plenty for visuals)")
    cg_max_iterations: Annotated[int, Field(ge=1)] | None = Field(None, description="implicit_euler CG iterations (1000)")


class Simulation(_Model):
    """Time stepping and run settings."""

    dt: PositiveFloat = Field(1.0 / 600.0, description="simulation step in seconds (each split into `substeps`)")
    substeps: Annotated[int, Field(ge=1, le=1000)] = Field(
        1, description="integrator steps per simulation step (integrator dt = dt / substeps); 1 default, 2-8 for stiff scenes")
    duration: PositiveFloat = Field(5.0, description="simulated seconds of a run")
    fps: PositiveFloat = Field(30.0, description="output frame rate: frames recorded per simulated second (24-60)")
    integrator: IntegratorName = Field("rk4", description="default integrator of every group")
    integrator_options: IntegratorOptions = Field(default_factory=IntegratorOptions)
    seed: Annotated[int, Field(ge=0)] = Field(0, description="seed of every random choice not given its own seed")
    dim: Literal[2, 3] = Field(3, description="2 (x-y plane, y up) or 3 (z up)")

    @model_validator(mode="after")
    def _frames_after_steps(self):
        if 1.0 / self.fps < self.dt * (1.0 - 1e-9):
            raise ValueError(f"fps = {self.fps:g} asks for frames every {1.0 / self.fps:.4g} s, more often than "
                             f"the step dt = {self.dt:g} s: lower fps to at most {1.0 / self.dt:.4g} or make dt smaller")
        return self


# ----------------------------------------------------------------------------------------------
# forces
# ----------------------------------------------------------------------------------------------
class _Force(_Model):
    groups: list[str] | None = Field(
        None, description="top-level forces only: names of the particle groups it acts on (default: all)")


class GravityForce(_Force):
    type: Literal["gravity"]
    acceleration: Vec | None = Field(None, description="m/s^2; default (0, 0, -9.81) in 3-D, (0, -9.81) in 2-D")


class DragForce(_Force):
    type: Literal["drag"]
    coefficient: NonNegativeFloat = Field(0.1, description="linear drag k in kg/s (f = -k v); 0.01..1")


class QuadraticDragForce(_Force):
    type: Literal["quadratic_drag"]
    coefficient: NonNegativeFloat = Field(0.01, description="c in kg/m (f = -c |v| v)")


class SpringsForce(_Force):
    type: Literal["springs"]
    pairs: list[Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=2, max_length=2)]] = Field(
        description="particle index pairs [[i, j], ...]")
    stiffness: NonNegativeFloat | list[NonNegativeFloat] = Field(100.0, description="N/m, one or per spring")
    damping: NonNegativeFloat | list[NonNegativeFloat] = Field(0.0, description="kg/s, one or per spring")
    rest_lengths: NonNegativeFloat | list[NonNegativeFloat] | None = Field(
        None, description="m; default: the initial distances")


class AnchorSpringsForce(_Force):
    type: Literal["anchor_springs"]
    indices: list[Annotated[int, Field(ge=0)]] = Field(description="particles tied to anchors")
    anchors: Vec | Points = Field(description="one anchor point for all, or one per index")
    stiffness: NonNegativeFloat | list[NonNegativeFloat] = 100.0
    damping: NonNegativeFloat | list[NonNegativeFloat] = 0.0
    rest_length: NonNegativeFloat | list[NonNegativeFloat] = 0.0


class WindForce(_Force):
    type: Literal["wind"]
    velocity: Vec | None = Field(None, description="uniform air velocity in m/s (or give `field`)")
    field: str | None = Field(None, description="name of a field in [fields] giving the air velocity")
    coefficient: NonNegativeFloat = Field(0.1, description="k in kg/s: f = k (w - v)")
    gust_amplitude: NonNegativeFloat = Field(0.0, description="m/s; 0 = steady")
    gust_frequency: PositiveFloat = Field(0.5, description="Hz; 0.1..2 looks natural")
    seed: Seed | None = None

    @model_validator(mode="after")
    def _one_source(self):
        if (self.velocity is None) == (self.field is None):
            raise ValueError("give exactly one of `velocity` (a vector) or `field` (a field name)")
        return self


class AttractorForce(_Force):
    type: Literal["attractor"]
    center: Vec
    strength: float = Field(1.0, description="m^3/s^2 (like G M); negative repels")
    softening: PositiveFloat = Field(0.1, description="m; keeps the force finite at the centre")


class FieldForce(_Force):
    type: Literal["field_force"]
    field: str = Field(description="name of a field in [fields]")
    per_mass: bool = Field(True, description="the field gives accelerations (true) or forces (false)")
    scale: float = Field(1.0, description="factor applied to the field")


class GridForce(_Force):
    type: Literal["grid_force"]
    file: str = Field(description=".npy file (relative to the scene) of shape (n0, n1, 2) or (n0, n1, n2, 3)")
    origin: Vec
    spacing: PositiveFloat | Vec
    per_mass: bool = False


ForceSpec = Annotated[
    Union[GravityForce, DragForce, QuadraticDragForce, SpringsForce, AnchorSpringsForce, WindForce,
          AttractorForce, FieldForce, GridForce],
    Field(discriminator="type"),
]


# ----------------------------------------------------------------------------------------------
# emitters
# ----------------------------------------------------------------------------------------------
class PointSourceSpec(_Model):
    type: Literal["point"]
    point: Vec


class BoxSourceSpec(_Model):
    type: Literal["box"]
    center: Vec
    half_extents: Vec


class SphereSourceSpec(_Model):
    type: Literal["sphere"]
    center: Vec
    radius: NonNegativeFloat


class DiskSourceSpec(_Model):
    type: Literal["disk"]
    center: Vec
    radius: NonNegativeFloat
    normal: Vec = [0.0, 0.0, 1.0]


SourceSpec = Annotated[Union[PointSourceSpec, BoxSourceSpec, SphereSourceSpec, DiskSourceSpec],
                       Field(discriminator="type")]


class ConeSpec(_Model):
    direction: Vec
    speed: NonNegativeFloat
    spread: NonNegativeFloat = Field(0.0, description="half-angle in radians, 0..pi")
    speed_jitter: Fraction = Field(0.0, description="relative speed variation, 0..1")


class EmitterSpec(_Model):
    rate: PositiveFloat = Field(description="particles per second")
    position: Vec | None = Field(None, description="emit from a point (or give `source`)")
    source: SourceSpec | None = Field(None, description="emit from a region: point, box, sphere or disk")
    velocity: Vec | None = Field(None, description="initial velocity (or give `cone`)")
    cone: ConeSpec | None = Field(None, description="random directions within a cone")
    lifetime: PositiveFloat | Annotated[list[PositiveFloat], Field(min_length=2, max_length=2)] = Field(
        1e30, description="seconds, or [min, max]; default: forever")
    start: NonNegativeFloat = 0.0
    stop: PositiveFloat = Field(1e30, description="seconds; default: forever")
    seed: Seed | None = None

    @model_validator(mode="after")
    def _choices(self):
        if (self.position is None) == (self.source is None):
            raise ValueError("give exactly one of `position` (a point) or `source` (a region table)")
        if (self.velocity is None) == (self.cone is None):
            raise ValueError("give exactly one of `velocity` (a vector) or `cone` (a table)")
        if not isinstance(self.lifetime, float) and self.lifetime[1] < self.lifetime[0]:
            raise ValueError(f"lifetime [min, max] needs min <= max; got {self.lifetime}")
        if self.stop <= self.start:
            raise ValueError(f"stop ({self.stop}) must be after start ({self.start})")
        return self


# ----------------------------------------------------------------------------------------------
# particle layouts
# ----------------------------------------------------------------------------------------------
class Lattice(_Model):
    """A regular grid of points: origin + spacing * (i, j[, k]) for counts (nx, ny[, nz])."""

    origin: Vec
    counts: Annotated[list[Annotated[int, Field(ge=1)]], Field(min_length=2, max_length=3)]
    spacing: PositiveFloat | Vec = Field(description="distance between neighbours (one or per axis)")
    jitter: Fraction = Field(0.0, description="random offset as a fraction of the spacing")
    seed: Seed | None = None


class RandomLayout(_Model):
    """`count` points uniform in a box (center, half_extents) or a ball (center, radius)."""

    count: Annotated[int, Field(ge=1)]
    shape: Literal["box", "ball"] = "box"
    center: Vec
    half_extents: Vec | None = Field(None, description="box only")
    radius: PositiveFloat | None = Field(None, description="ball only")
    seed: Seed | None = None

    @model_validator(mode="after")
    def _extent(self):
        if self.shape == "box" and self.half_extents is None:
            raise ValueError("shape 'box' needs `half_extents`")
        if self.shape == "ball" and self.radius is None:
            raise ValueError("shape 'ball' needs `radius`")
        return self


class Chain(_Model):
    """`count` particles evenly from `start` to `end`, joined by springs in order."""

    start: Vec
    end: Vec
    count: Annotated[int, Field(ge=2)]
    stiffness: NonNegativeFloat = Field(100.0, description="N/m of each link")
    damping: NonNegativeFloat = Field(0.0, description="kg/s of each link")
    pin: Literal["none", "start", "end", "both"] = Field("start", description="which ends are fixed")


class Cloth(_Model):
    """A (nu x nv) spring grid spanning corner + s * edge_u + t * edge_v (cloth-like sheet).

    Index of node (i, j) is j * nu + i (i along edge_u, j along edge_v). Structural springs join
    grid neighbours; shear springs the diagonals; bend springs every second node.
    """

    corner: Vec = Field(description="position of node (0, 0): e.g. the top-left corner")
    edge_u: Vec = Field(description="vector from node (0, 0) to node (nu - 1, 0)")
    edge_v: Vec = Field(description="vector from node (0, 0) to node (0, nv - 1)")
    counts: Annotated[list[Annotated[int, Field(ge=2)]], Field(min_length=2, max_length=2)] = Field(
        description="[nu, nv] nodes along edge_u and edge_v")
    stiffness: NonNegativeFloat = Field(1000.0, description="N/m of structural springs")
    shear_stiffness: NonNegativeFloat | None = Field(None, description="N/m; default stiffness / 2; 0 = none")
    bend_stiffness: NonNegativeFloat | None = Field(None, description="N/m; default stiffness / 10; 0 = none")
    damping: NonNegativeFloat = Field(0.0, description="kg/s of every spring")
    pin: Literal["none", "corners", "edge"] = Field(
        "corners", description="fix the two ends of the first row (corners), the whole first row (edge), or none")


# ----------------------------------------------------------------------------------------------
# colliders
# ----------------------------------------------------------------------------------------------
class Motion(_Model):
    """Kinematic motion of a collider about its reference point (centre; a plane's point).

    Either keyframes (`times` with `positions` and/or `rotations`), or an analytic motion:
    p(t) = rest + velocity t + amplitude sin(2 pi frequency t + phase), R(t) = exp(t angular_velocity).
    """

    velocity: Vec | None = Field(None, description="m/s, constant translation")
    amplitude: Vec | None = Field(None, description="m, sinusoidal offset")
    frequency: NonNegativeFloat = Field(1.0, description="Hz of the sinusoidal offset")
    phase: float = Field(0.0, description="radians")
    angular_velocity: float | Vec | None = Field(
        None, description="rad/s: a number in 2-D; a rotation-vector rate (axis * rad/s) in 3-D")
    times: list[float] | None = Field(None, description="keyframe times (s), increasing")
    positions: Points | None = Field(None, description="keyframe positions of the reference point")
    rotations: list[float] | list[Vec] | None = Field(
        None, description="keyframe rotations: angles (2-D) or rotation vectors / quaternions (3-D)")

    @model_validator(mode="after")
    def _kind(self):
        analytic = (self.velocity, self.amplitude, self.angular_velocity)
        keyed = (self.positions, self.rotations)
        if self.times is not None:
            if any(a is not None for a in analytic):
                raise ValueError("give keyframes (`times` with `positions`/`rotations`) or an analytic motion "
                                 "(`velocity`, `amplitude`, `angular_velocity`), not both")
            if all(k is None for k in keyed):
                raise ValueError("keyframes need `positions` and/or `rotations` beside `times`")
        elif any(k is not None for k in keyed):
            raise ValueError("`positions`/`rotations` keyframes need `times`")
        elif all(a is None for a in analytic):
            raise ValueError("a motion needs `velocity`, `amplitude`, `angular_velocity` or keyframes")
        return self


class _Collider(_Model):
    name: str | None = Field(None, description="name used in messages and output")
    restitution: Fraction = Field(0.5, description="bounciness in [0, 1]")
    friction: NonNegativeFloat = Field(0.0, description="Coulomb coefficient (0 = frictionless)")
    groups: list[str] | None = Field(None, description="names of the particle groups it collides with (default: all)")
    motion: Motion | None = Field(None, description="kinematic motion; static when absent")


class PlaneCollider(_Collider):
    type: Literal["plane"]
    point: Vec = Field(description="a point on the plane")
    normal: Vec = Field(description="outward normal (the free side)")


class SphereCollider(_Collider):
    type: Literal["sphere"]
    center: Vec
    radius: PositiveFloat


class BoxCollider(_Collider):
    type: Literal["box"]
    center: Vec
    half_extents: Vec
    rotation: float | Vec | Annotated[list[float], Field(min_length=4, max_length=4)] | None = Field(
        None, description="2-D: angle (rad); 3-D: rotation vector (axis * rad) or quaternion [w, x, y, z]")


class CapsuleCollider(_Collider):
    type: Literal["capsule"]
    a: Vec = Field(description="one end of the axis segment")
    b: Vec = Field(description="the other end")
    radius: PositiveFloat


class CylinderCollider(_Collider):
    """3-D only: a capped cylinder around `axis` through `center`."""

    type: Literal["cylinder"]
    center: Vec
    radius: PositiveFloat
    half_height: PositiveFloat
    axis: Vec = [0.0, 0.0, 1.0]


class ContainerCollider(_Collider):
    type: Literal["container"]
    center: Vec
    half_extents: Vec = Field(description="inner half size; particles are kept inside")
    rotation: float | Vec | Annotated[list[float], Field(min_length=4, max_length=4)] | None = None


class MeshCollider(_Collider):
    """3-D only: a triangle mesh (OBJ/STL/PLY/... through trimesh), queried through a baked distance grid."""

    type: Literal["mesh"]
    file: str = Field(description="mesh file, relative to the scene file")
    scale: PositiveFloat = Field(1.0, description="uniform scale applied to the vertices")
    translation: Vec | None = Field(None, description="added to the vertices after scaling")
    resolution: Annotated[int, Field(ge=4, le=512)] = Field(
        64, description="distance-grid cells along the longest side (32-256)")
    signed: bool | None = Field(None, description="default: signed when the mesh is watertight")
    thickness: NonNegativeFloat = Field(0.0, description="half-thickness of an unsigned sheet (m)")


class SdfCollider(_Collider):
    type: Literal["sdf"]
    file: str = Field(description=".npy signed-distance grid (n0, n1[, n2]), relative to the scene file")
    origin: Vec = Field(description="world position of grid node (0, 0[, 0])")
    spacing: PositiveFloat = Field(description="cell size (m)")


ColliderSpec = Annotated[
    Union[PlaneCollider, SphereCollider, BoxCollider, CapsuleCollider, CylinderCollider,
          ContainerCollider, MeshCollider, SdfCollider],
    Field(discriminator="type"),
]


# ----------------------------------------------------------------------------------------------
# vector fields
# ----------------------------------------------------------------------------------------------
class UniformField(_Model):
    type: Literal["uniform"]
    velocity: Vec


class RotationField(_Model):
    """Rigid rotation v = omega x (x - center) (2-D: omega (-(y - cy), x - cx)): circles around center."""

    type: Literal["rotation"]
    center: Vec
    angular_velocity: float | Vec = Field(1.0, description="rad/s (2-D); a vector along the axis (3-D)")


class VortexField(_Model):
    """A (Lamb-Oseen-like) vortex with a smooth core: swirl around `center` (and `axis` in 3-D)."""

    type: Literal["vortex"]
    center: Vec
    axis: Vec | None = Field(None, description="3-D only; default z")
    circulation: float = Field(1.0, description="m^2/s")
    core_radius: PositiveFloat = Field(0.1, description="m")


class SourceField(_Model):
    type: Literal["source"]
    center: Vec
    strength: float = Field(1.0, description="volume flux, m^3/s (3-D) or m^2/s (2-D); negative for a sink")
    core_radius: PositiveFloat = 0.1


class CurlNoiseField(_Model):
    """Divergence-free procedural flow (Bridson et al. 2007), optionally bent along colliders."""

    type: Literal["curl_noise"]
    kind: Literal["simplex", "perlin"] = "simplex"
    frequency: PositiveFloat = Field(1.0, description="lattice cells per metre; eddies are about 0.5 / frequency across")
    octaves: Annotated[int, Field(ge=1, le=8)] = 1
    lacunarity: PositiveFloat = 2.0
    gain: PositiveFloat = 0.5
    speed: NonNegativeFloat = Field(1.0, description="typical flow speed (m/s)")
    time_frequency: NonNegativeFloat = Field(0.0, description="how fast the eddies evolve (cells per second)")
    boundaries: list[str] = Field(default_factory=list, description="names of colliders the flow runs along")
    boundary_width: PositiveFloat | None = Field(None, description="m; default 0.5 / frequency")
    seed: Seed | None = None


class GridField(_Model):
    """Velocities sampled on a regular grid, interpolated (bi/tri)linearly."""

    type: Literal["grid"]
    file: str = Field(description=".npy file (relative to the scene) of shape (n0, n1, 2) or (n0, n1, n2, 3), m/s")
    origin: Vec | None = Field(None, description="position of node (0, 0[, 0]); default the origin")
    spacing: PositiveFloat | Vec = Field(1.0, description="node spacing (m), one or per axis")
    outside: Literal["clamp", "zero"] = Field("clamp", description="value outside the grid")


class SumField(_Model):
    type: Literal["sum"]
    fields: list[str] = Field(description="names of the fields to add", min_length=1)
    weights: list[float] | None = Field(None, description="one factor per field (default 1)")


FieldSpec = Annotated[
    Union[UniformField, RotationField, VortexField, SourceField, CurlNoiseField, GridField, SumField],
    Field(discriminator="type"),
]


# ----------------------------------------------------------------------------------------------
# groups
# ----------------------------------------------------------------------------------------------
class Contacts(_Model):
    """Contact options of a group (``inertia.colliders.configure_contacts``)."""

    self_restitution: Fraction | None = Field(None, description="particle-particle bounciness (0.5 default)")
    self_friction: NonNegativeFloat | None = Field(None, description="particle-particle friction (0 default)")
    iterations: Annotated[int, Field(ge=1, le=1000)] | None = Field(None, description="pair solver passes (4; 8-16 for piles)")
    distance_tolerance: PositiveFloat | None = Field(None, description="contact distance tolerance in m (1e-6)")
    rest_speed: PositiveFloat | None = Field(None, description="speeds below this are at rest, m/s (1e-6)")
    max_substeps: Annotated[int, Field(ge=1, le=1000)] | None = Field(None, description="impacts per particle per step (4)")


class ParticleGroup(_Model):
    """One particle system. Give a layout (or none) and/or emitters (which need `capacity` slots)."""

    name: str | None = Field(None, description="default particles<i>")
    integrator: IntegratorName | None = Field(None, description="default simulation.integrator")
    integrator_options: IntegratorOptions | None = None
    mass: PositiveFloat | list[PositiveFloat] = Field(1.0, description="kg, one or per particle")
    radius: NonNegativeFloat | list[NonNegativeFloat] = Field(0.0, description="m (collision and drawing size)")
    velocity: Vec | None = Field(None, description="initial velocity of every particle of the layout")
    positions: Points | None = Field(None, description="explicit positions")
    velocities: Points | None = Field(None, description="explicit initial velocities (with `positions`)")
    lattice: Lattice | None = None
    random: RandomLayout | None = None
    chain: Chain | None = None
    cloth: Cloth | None = None
    pinned: list[Annotated[int, Field(ge=0)]] = Field(default_factory=list, description="indices of fixed particles")
    emitters: list[EmitterSpec] = Field(default_factory=list)
    capacity: Annotated[int, Field(ge=1)] | None = Field(
        None, description="pool slots for emitters (default: enough for rate x lifetime)")
    forces: list[ForceSpec] = Field(default_factory=list)
    collide: bool = Field(True, description="collide with the scene's colliders")
    restitution: Fraction | None = Field(None, description="overrides every collider's restitution for this group")
    friction: NonNegativeFloat | None = Field(None, description="overrides every collider's friction for this group")
    self_collisions: bool = Field(False, description="particles collide with each other as spheres of `radius`")
    collision_mode: Literal["a_priori", "a_posteriori"] = "a_priori"
    contacts: Contacts | None = Field(None, description="contact tolerances and particle-particle options")
    color: str | None = Field(None, description="drawing colour: a name or '#rrggbb'")

    @model_validator(mode="after")
    def _layout(self):
        given = [k for k in ("positions", "lattice", "random", "chain", "cloth") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give at most one layout of positions, lattice, random, chain, cloth; got {', '.join(given)}")
        if not given and not self.emitters:
            raise ValueError("a particle group needs a layout (positions, lattice, random, chain or cloth) or emitters")
        if self.velocities is not None and self.positions is None:
            raise ValueError("`velocities` goes with explicit `positions`")
        if self.velocities is not None and self.velocity is not None:
            raise ValueError("give `velocity` (one for all) or `velocities` (one per particle), not both")
        if self.capacity is not None and not self.emitters:
            raise ValueError("`capacity` is the emitters' pool size; this group has no emitters")
        return self


class TracerGroup(_Model):
    """Massless points carried by a field: dx/dt = field(x, t)."""

    name: str | None = Field(None, description="default tracers<i>")
    field: str = Field(description="name of a field in [fields]")
    integrator: Literal[FIRST_ORDER_INTEGRATORS] | None = Field(  # type: ignore[valid-type]
        None, description="euler, midpoint, rk4 or rk45; default simulation.integrator")
    integrator_options: IntegratorOptions | None = None
    positions: Points | None = None
    lattice: Lattice | None = None
    random: RandomLayout | None = None
    radius: NonNegativeFloat = Field(0.0, description="drawing size (m)")
    color: str | None = None

    @model_validator(mode="after")
    def _layout(self):
        given = [k for k in ("positions", "lattice", "random") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one layout of positions, lattice, random; got {', '.join(given) or 'none'}")
        return self


# ----------------------------------------------------------------------------------------------
# outputs and rendering
# ----------------------------------------------------------------------------------------------
class Output(_Model):
    """Which files `inertia run` writes (the state file, checkpoint and manifest always)."""

    directory: str | None = Field(None, description="default output directory, relative to the working directory "
                                                    "and inside it (no absolute path, '~' or '..'); --out wins")
    video: list[Literal["mp4", "gif"]] = Field(default_factory=lambda: ["mp4"], description="video formats")
    frames: bool = Field(False, description="PNG image of every frame")
    plot: bool = Field(True, description="energy and momentum over time (PNG)")
    ply: bool = Field(False, description="PLY point file of every frame")
    usd: bool = Field(False, description="animated USD points (.usdc); rigid bodies as animated transforms (bodies.usdc)")
    obj: bool = Field(False, description="OBJ mesh of the rigid bodies per frame (obj/frame_NNNNN.obj)")
    checkpoint_interval: PositiveFloat = Field(10.0, description="wall-clock seconds between checkpoints")

    @field_validator("directory")
    @classmethod
    def _inside(cls, value):
        if value is not None and not _is_inside_path(value):
            raise ValueError("must be a relative path inside the working directory (no absolute path, drive, '~' "
                             f"or '..'); a scene file cannot choose where files go: pass --out for that (got {value!r})")
        return value


class Camera(_Model):
    position: Vec | None = Field(None, description="eye point (default: framed automatically)")
    target: Vec | None = None
    azimuth: float | None = Field(None, description="degrees around the up axis")
    elevation: float | None = Field(None, description="degrees above the horizon")
    distance: PositiveFloat | None = None
    fov: Annotated[float, Field(ge=1, le=170)] | None = Field(None, description="vertical field of view (degrees)")
    height: PositiveFloat | None = Field(None, description="2-D: world units visible vertically")
    orbit: Annotated[float, Field(ge=-360, le=360)] | None = Field(
        None, description="3-D: degrees the framed camera turns about the up axis over the run (0: still)")
    follow: bool | None = Field(None, description="3-D: the framing follows the particles and moving bodies over "
                                "the run (unset: only when they travel far from where they start)")


class Render(_Model):
    width: Annotated[int, Field(ge=16, le=7680)] = 960
    height: Annotated[int, Field(ge=16, le=4320)] = 540
    color_by: Literal["auto", "speed", "group", "uniform"] = "auto"
    theme: Literal["dark", "light"] = "dark"
    camera: Camera = Field(default_factory=Camera)
    draw_colliders: bool = True
    trails: Annotated[int, Field(ge=0, le=100)] = Field(
        0, description="3-D: draw each particle's path over this many previous frames (shows the flow)")
    streaks: Annotated[int, Field(ge=0, le=100000)] = Field(
        400, description="2-D grid fluids: tracer streaks drawn over the colour map (0: none)")
    streak_length: Annotated[int, Field(ge=1, le=200)] = Field(
        8, description="2-D grid fluids: frames of history each tracer streak spans")
    fluid_surface: bool | None = Field(
        None, description="SPH fluids: draw the smoothed-particle liquid surface (a shaded mesh in 3-D, a filled "
                          "region in 2-D) instead of the particles; default: the surface when the 'surface' extra "
                          "(scikit-image) is installed, else the particles")


# ----------------------------------------------------------------------------------------------
# the scene
# ----------------------------------------------------------------------------------------------
class SceneModel(_Model):
    """A whole scene file."""

    model_config = ConfigDict(extra="forbid", frozen=True, title="Inertia scene", strict=True, allow_inf_nan=False,
                              json_schema_extra={"$id": "https://inertia.dev/schema/scene-1.json"})

    format_version: Literal[1] = Field(description="scene format version (1)")
    name: str | None = Field(None, description="default: the file name; a plain name (the default output "
                                               "directory is out/NAME), never a path")
    description: str = ""
    simulation: Simulation = Field(default_factory=Simulation)
    particles: list[ParticleGroup] = Field(default_factory=list)
    tracers: list[TracerGroup] = Field(default_factory=list)
    forces: list[ForceSpec] = Field(default_factory=list, description="forces on every particle group")
    colliders: list[ColliderSpec] = Field(default_factory=list)
    fields: dict[str, FieldSpec] = Field(default_factory=dict, description="named vector fields")
    output: Output = Field(default_factory=Output)
    render: Render = Field(default_factory=Render)
    materials: dict[str, Material] = Field(default_factory=dict, description="named rigid-body materials")
    bodies: dict[str, Body] = Field(default_factory=dict, description="rigid bodies (inertia.scene.rigid_models)")
    rigid: Rigid = Field(default_factory=Rigid, description="rigid-body solver options")
    vehicles: dict[str, Vehicle] = Field(default_factory=dict, description="ray-cast vehicles on bodies")
    sph: dict[str, SPHTable] = Field(default_factory=dict, description="SPH fluids (inertia.fluids.sph.scene)")
    fluids: dict[str, GridFluidTable] = Field(default_factory=dict, description="grid fluids (inertia.fluids.grid.scene)")

    @model_validator(mode="before")
    @classmethod
    def _version_first(cls, data: Any):
        # A newer format deserves one clear message rather than a cascade of unknown keys.
        if isinstance(data, dict):
            v = data.get("format_version")
            if isinstance(v, int) and not isinstance(v, bool) and v > FORMAT_VERSION:
                raise ValueError(f"format_version {v} is newer than this inertia reads ({FORMAT_VERSION}); "
                                 "upgrade inertia")
        return data

    @field_validator("name")
    @classmethod
    def _plain_name(cls, value):
        if value is not None and not _is_plain_name(value):
            raise ValueError(f"must be a plain name (no '/', '\\', ':', '..' or control characters), not a path: "
                             f"runs go to out/NAME unless --out says otherwise (got {value!r})")
        return value

    @model_validator(mode="after")
    def _names(self):
        if not self.particles and not self.tracers and not self.bodies and not self.sph and not self.fluids:
            raise ValueError("a scene needs at least one [[particles]] or [[tracers]] group, [bodies.NAME] table "
                             "or fluid ([sph.NAME], [fluids.NAME])")
        return self
