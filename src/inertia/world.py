"""The world: every system stepped together, and the run loop that records and checkpoints them.

A `World` holds one shape table (``world.model``, an `inertia.model.Model`): the rows of the model
given to it (bodies and their shapes, static world geometry) followed by the rows its 3-D
``colliders`` become (`inertia.model.with_colliders`: static colliders on body -1, a collider with a
``Motion`` on a kinematic body that follows the motion). With bodies, ``world.rigid`` is a
`inertia.rigid.RigidWorld` stepping that table (``rigid_options``: its keyword options, e.g.
``{"substeps": 4}``), so rigid bodies land on the scene's collider planes and meshes too. Particle
and tracer groups (each a `ParticleSystem` or `Tracers` with its own `Simulation` and integrator)
advance in lockstep at one fixed step ``dt``, each step split into ``substeps`` integrator steps of
``dt / substeps``; fluids (``add_fluid``) advance once per step.

One `World.step` runs these stages in order, each timed in ``world.profile`` (seconds, summed):

1. ``kinematics`` -- kinematic bodies of moving colliders are posed at t with the velocity that
                     takes them to their pose at t + dt; the bodies' start-of-step poses are kept;
2. ``rigid``      -- ``RigidWorld.step`` (its own stages broad phase, narrow phase, islands,
                     solve, finalize are also timed as ``rigid/<stage>``);
3. ``fluids``     -- ``fluid.advance(dt, world.rigid)`` per fluid, in insertion order (each also
                     timed as ``fluid/<name>``); fluids read the moved bodies and push them back.
                     A fluid with ``advance_before_rigid = True`` (the particle liquid, whose
                     pressure solve has the bodies' velocities as unknowns) advances instead
                     between stages 1 and 2, so its impulses reach the bodies' velocities before
                     the rigid stage integrates their positions (also timed under ``fluids``);
4. groups         -- per group (timed under its name), ``substeps`` calls of ``Simulation.step``
                     (begin -> integrate -> end -> check, see `inertia.simulation`). 3-D particle
                     groups collide with the shape table's body and world rows
                     (``collision.shapes.BodyShape``, packed into the particle stage's kernel
                     format); a body row's pose over each substep is interpolated between the
                     body's poses before and after the rigid stage. The momentum the particles
                     gain from body rows is gathered per body (`inertia.dynamics.particle_coupling`);
5. ``coupling``   -- those impulses are applied to the bodies (``apply_body_impulses``):
                     linear and angular momentum of particles plus bodies are conserved; then the
                     particle rows of the step are appended to the rigid world's ``Contacts``
                     buffer after its rigid rows (``_fill_particle_contacts``: per group in order,
                     count, grow, fill; `inertia.dynamics.contacts` documents a row).

Particle contacts (worlds with bodies): a 3-D particle group's coupling records, per particle and
step, the table rows (static rows too) that pushed it -- the collision pass's momentum change
attributed to the nearest row, the resting filter's load -- with the impulse each gave it (two slots
per particle: a third row met in one step adds to the second), plus the row it rests on at the end of
the step. Those become the particle rows; `World.contact_events` reports their begin / persist / end
keyed by (group, particle, shape). Sensor rows are not collided with; a particle overlapping one
(distance minus radius <= 0 at the end of the step) gets a sensor row.

Rows the particle colliders became are *not* added to the particle groups a second time: a
particle system sees a collider through ``system.add_collider`` (with its own restitution and
friction) exactly as before; the table's rows make them visible to the rigid bodies.

`Run` drives a world over a duration and records it:

1. ``setup``      -- a new state directory (frame 0 = the initial state), or, with ``resume``,
                     the checkpoint restored into the world and the state directory cut back
                     to the frames the checkpoint had seen;
2. ``advance``    -- step until the time of the next output frame (frames are sampled at
                     ``fps``, decoupled from ``dt``: frame k is recorded at the first step
                     boundary at or after k / fps);
3. ``record``     -- positions, velocities, the active mask and energies appended to the
                     `inertia.io.StateWriter`;
4. ``checkpoint`` -- every ``checkpoint_interval`` wall-clock seconds, at the end, on Ctrl-C
                     and on divergence (the last good state): the state writer is flushed, then
                     ``checkpoint.npz`` is written atomically. Resuming from it gives a
                     trajectory identical, bit for bit, to an uninterrupted run.

``checkpoint.npz`` holds numeric arrays (read with ``allow_pickle=False``) and one JSON tree;
nothing is pickled, and a file holding a pickled object is refused (`CheckpointError`). On
resume the run facts (fingerprint, fps, dt, substeps, particle count) are checked before any
array is read (a changed scene is named by the keys that differ from the scene recorded in the
state directory); every archive member's header is checked against its stored size before it is
read (a bad CRC or a truncated file is a `CheckpointError`); then `check_checkpoint` compares the
decoded state with what this world's ``save_state`` makes (every array's dtype and shape, numbers
finite and of their kind) and checks every count and index against the arrays it indexes (contact
rows and their bodies, shapes and particles; each fluid's ``check_state``: the SPH live count
against its capacity, grid shapes and clocks), the step count against the frame count and the
frame count against the frames in the state directory, before any of it reaches a kernel.

Ctrl-C (SIGINT) sets a flag checked after every step: the run stops at the current step,
writes what it has and returns ``status = "interrupted"``. The handler is installed before the
first write to ``out_dir`` and removed after the last (`Run.catching_sigint`; a caller such as
the CLI can hold it longer, until its own last write). A second Ctrl-C raises
``KeyboardInterrupt`` at once (files stay consistent: every write is atomic).

Arrays (N = total particles over the groups in order, D = dim): ``World.positions()`` and
``World.velocities()`` are (N, D) float64 copies gathered from the groups, ``World.active()``
(N,) bool; group ``g`` owns rows ``group.start : group.stop``.

``Run`` also writes ``model.npz`` (``States.model``, see `model_file_arrays`) and, per frame,
``body_q`` (B, 7) when the world has bodies, ``fluid/<name>/<key>`` for each fluid's
``frame_arrays()``, ``diag/<system>/<quantity>`` (`World.system_diagnostics`: the bodies' and each
fluid's energies and conservation errors, for the energy plot) and ``vehicle/<k>/wheel_pose``
(W, 7) for each ray-cast vehicle; checkpoints hold the rigid state and contact cache and each fluid's
``save_state()``.

Limitations: all groups share dim and dt; groups do not interact with each other (springs,
self-collisions and forces act within a group); the particle count is fixed for a run. The
coupling is explicit: bodies move first and feel the particles' impulses from the next step on;
particles see a moving body's surface velocity as its material velocity v + w x (x - c) from
``body_qd`` after the rigid step, where the particle ends the (sub)step. In a world whose bodies are
all static the particle groups keep the fused integrator path, whose step writes the same Contacts
rows as the separate pass (impacts and resting contacts, with their impulses).
Heightfield rows are seen by particles as the solid under the rigid side's triangles
(`inertia.collision.heightfield_distance`), a column ``max(1 m, grid extent)`` deep. Particle rows
are recorded only in worlds with bodies (a world of static colliders has no Contacts buffer), for the
table's rows (not for colliders attached with ``system.add_collider``), for 3-D particle groups (not
tracers); a particle row's impulse includes particle-particle impulses of particles touching the row
(the coupling's attribution). Rigid bodies collide only with baked ``SDF`` colliders (sampled surface
points, ``inertia.geometry.sdf_collide``), and a ``Container``'s walls are infinite planes for them.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import signal
import threading
import time as _time
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numba import njit

from .errors import SimulationDiverged
from .collision.particle_kernels import NEAR_ALWAYS as _NEAR_ALWAYS
from .collision.particle_kernels import NEAR_BALL as _NEAR_BALL
from .geometry import shapes as _S
from .math import quat_to_mat3_entries, rotate_vectors
from .simulation import Simulation, SimulationState

__all__ = ["World", "Group", "WorldState", "Run", "RunResult", "save_checkpoint", "load_checkpoint",
           "CHECKPOINT_NAME", "STATES_NAME", "frame_steps", "CheckpointError",
           "read_checkpoint_info", "check_checkpoint", "model_file_arrays", "STAGES"]

#: the world step's stages (``world.profile`` keys, besides one per group and ``fluid/<name>``)
STAGES = ("kinematics", "rigid", "fluids", "coupling")

CHECKPOINT_NAME = "checkpoint.npz"
STATES_NAME = "states"
CHECKPOINT_VERSION = 1


@dataclass
class Group:
    """One system of a world: its name, kind ("particles" or "tracers"), system and simulation.

    ``start``/``stop``: the rows of this group in the world's gathered (N, D) arrays.
    """

    name: str
    kind: str
    system: Any
    simulation: Simulation
    color: str | None = None
    start: int = 0
    stop: int = 0
    colliders: list = field(default_factory=list)
    # (T, 3) int64 group-local particle indices of a drawn surface (``World.add(triangles=)``)
    triangles: np.ndarray | None = None
    # the shape-table rows on moving bodies this group collides with: their rows in the group's
    # packed collider arrays, their bodies, and bounding radii about the centre of mass (-1: plane)
    body_entries: np.ndarray | None = None
    entry_body_all: np.ndarray | None = None
    entry_bound: np.ndarray | None = None
    # True when the group's particle rows go into the world's Contacts buffer (3-D particles in a
    # world with bodies)
    records_contacts: bool = False

    @property
    def integrator(self) -> str:
        return self.simulation.integrator_name

    @property
    def particle_count(self) -> int:
        return self.system.particle_count


@dataclass
class WorldState:
    """A checkpoint of a world: its step count, every group's `SimulationState`, the rigid state
    (``rigid``: a dict of arrays, see `World.save_state`; None without bodies) and each fluid's
    ``save_state()`` dict by name."""

    step_count: int
    groups: list[SimulationState]
    rigid: dict | None = None
    fluids: dict = field(default_factory=dict)


class World:
    """Groups of particles and tracers stepped in lockstep.

    Parameters
    ----------
    groups : list of `Group` (build them with `World.add_particles` / `World.add_tracers`, or
        load a scene file with `inertia.load_scene`).
    dt : the simulation step in seconds.
    substeps : integrator steps per simulation step (each of dt / substeps); 1 default.
    colliders : the collider objects of the scene (for drawing; attach them to systems yourself).
    """

    def __init__(self, *, dt: float, substeps: int = 1, colliders=(), model=None, rigid_options=None,
                 name: str = "world"):
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"dt must be a finite number > 0; got {dt!r}")
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1; got {substeps!r}")
        if rigid_options is not None and not isinstance(rigid_options, dict):
            raise ValueError(f"rigid_options must be a dict of RigidWorld options (e.g. {{'substeps': 4}}); "
                             f"got {type(rigid_options).__name__}")
        self.name = name
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.groups: list[Group] = []
        self.colliders = list(colliders)
        self.fluids: dict[str, Any] = {}
        self.step_count = 0
        self.t = 0.0
        self.profile: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._in_particle_stage = False
        self._setup_model(model, rigid_options)
        self.metadata: dict[str, Any] = {}
        # run settings of a loaded scene (None for a world built by hand)
        self.duration: float | None = None
        self.fps: float | None = None
        self.seed: int | None = None

    # ---- building ----------------------------------------------------------------------------
    def _setup_model(self, model, rigid_options) -> None:
        """One shape table: the model's rows plus the rows the 3-D colliders become (see
        `inertia.model.with_colliders`); a RigidWorld when the model has bodies."""
        from .model import Model, with_colliders
        if model is not None and not isinstance(model, Model):
            raise ValueError(f"model must be an inertia.model.Model (ModelBuilder(...).finalize()) or None; "
                             f"got {type(model).__name__}")
        self._user_bodies = 0 if model is None else model.body_count
        colliders3 = [c for c in self.colliders if getattr(c, "dim", 3) == 3]
        self.model = with_colliders(model, self.colliders) if (model is not None or colliders3) else None
        self.rigid = None
        self._body_shape_cache: dict = {}
        self._sensors = None
        self._no_slots = None
        self._rigid_options = dict(rigid_options or {})
        if self.model is not None and self._user_bodies > 0:
            from .rigid.world import RigidWorld
            options = dict(self._rigid_options)
            if "dt" in options:
                raise ValueError("rigid_options must not set 'dt': the rigid world steps the world's dt")
            self.rigid = RigidWorld(self.model, dt=self.dt, **options)
            nb = self.model.body_count
            self._q_start = np.zeros((nb, 7))
            self._impulse_linear = np.zeros((nb, 3))
            self._impulse_angular = np.zeros((nb, 3))
            self._impulse_scratch = np.empty((2, 3, 3))       # apply_body_impulses' work array
            # colliders with a Motion: kinematic bodies driven by the collider's pose(t)
            self._driven = [(int(b), self.colliders[int(src)]) for b, src in enumerate(self.model.body_source)
                            if src >= 0]
            self._kinematics(0.0)

    def add(self, name: str, system, *, integrator: str = "rk4", color: str | None = None,
            kind: str | None = None, triangles=None, **integrator_options) -> Group:
        """Add a system (ParticleSystem or Tracers) stepped by its own integrator; returns its group.

        ``triangles``: optional (T, 3) int, group-local particle indices of a surface drawn over the
        particles (cloth); recorded as ``surface_triangles`` in the state file's model.
        In a world with a shape table, a 3-D particle system collides with the table's body and world
        rows (the rows the particle colliders became are attached by ``system.add_collider`` as before).
        """
        if any(g.name == name for g in self.groups):
            raise ValueError(f"a group named {name!r} already exists; names must be unique")
        if self.groups and system.dim != self.dim:
            raise ValueError(f"group {name!r} is {system.dim}-D but the world is {self.dim}-D")
        if name in STAGES or name in self.fluids:
            raise ValueError(f"group name {name!r} is taken (stages {STAGES}, fluids {sorted(self.fluids)})")
        tri = None
        if triangles is not None:
            tri = np.asarray(triangles)
            if (tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer)
                    or (tri.size and (tri.min() < 0 or tri.max() >= system.particle_count))):
                raise ValueError(f"triangles must be a (T, 3) integer array of particle indices in "
                                 f"[0, {system.particle_count - 1}]; got shape {tri.shape}")
            tri = tri.astype(np.int64)
        sim = Simulation(system, integrator=integrator, dt=self.dt / self.substeps, **integrator_options)
        kind = kind or ("particles" if getattr(system, "second_order", False) else "tracers")
        start = self.particle_count
        group = Group(name, kind, system, sim, color, start, start + system.particle_count, triangles=tri)
        self.groups.append(group)
        self.profile[name] = 0.0
        self._attach_shape_table(group)
        return group

    def _attach_shape_table(self, group) -> None:
        """Give a 3-D particle group the shape table's rows that are not particle colliders nor sensors
        (the builder's world geometry and every body's shapes), couple it to the dynamic bodies, and
        (with bodies) record its contacts with those rows and its overlaps with sensor rows in the
        world's Contacts buffer."""
        system, model = group.system, self.model
        if model is None or system.dim != 3 or group.kind != "particles":
            return
        rows = np.flatnonzero((model.shape_source < 0) & ~model.shape_is_sensor)
        group.records_contacts = self.rigid is not None
        if rows.size == 0:
            return
        from .collision.particle_stage import _data
        from .dynamics.particle_coupling import ParticleBodyCoupling
        data = _data(system)
        state = self.rigid.state if self.rigid is not None else model.state()
        entries = data.add_body_shapes(model, rows, state, self._body_shape_cache)
        moving = np.array([i for i in entries if data.colliders[i].moving], np.int64)
        group.body_entries = moving
        group.entry_body_all = np.array([data.colliders[i].body for i in moving], np.int64)
        # bounding radius about the centre of mass of each moving row (-1: unbounded, a plane)
        group.entry_bound = np.array([-1.0 if model.shape_type[data.colliders[i].shape] == _S.PLANE
                                      else float(model.body_bound_radius[data.colliders[i].body])
                                      for i in moving], np.float64)
        if self.rigid is not None and entries.size:
            # with bodies the coupling also records every particle's contacts with table rows (static
            # ones too) for the Contacts buffer, so it is set even when no row is on a dynamic body
            entry_body = data.entry_bodies(model)
            data.coupling = ParticleBodyCoupling(system, entry_body, self.rigid.state.body_q,
                                                 self._impulse_linear, self._impulse_angular,
                                                 data.distance_tolerance, data.entry_shapes())

    def _sensor_rows(self):
        """The shape table's sensor rows packed for the particle kernels (`SensorRows`), built once."""
        if self._sensors is None:
            from .collision.shapes import BodyShape
            from .dynamics.particle_coupling import SensorRows
            m = self.model
            rows = [int(s) for s in np.flatnonzero(m.shape_is_sensor & (m.shape_source < 0))]
            shapes = [BodyShape(m, s, None if m.shape_body[s] < 0 else self.rigid.state.body_q[m.shape_body[s]])
                      for s in rows]
            shapes = [(s, c) for s, c in zip(rows, shapes) if not getattr(c, "unsupported", False)]
            q = len(shapes)
            cint = np.zeros((q, 4), np.int64)
            cfs, cis, off, ioff = [np.zeros(1)], [np.zeros(1, np.int64)], 1, 1
            for j, (s, c) in enumerate(shapes):
                ci = np.zeros(0, np.int64) if c._ci is None else np.asarray(c._ci, np.int64)
                cint[j] = (c.kind, 1 if c.moving else 0, off, ioff)
                cfs.append(np.asarray(c._cf, np.float64))
                cis.append(ci)
                off += cfs[-1].size
                ioff += ci.size
            self._sensors = SensorRows(cint, np.concatenate(cfs), np.concatenate(cis), np.zeros((q, 12)),
                                       np.zeros((q, 3)), np.array([s for s, _ in shapes], np.int64),
                                       np.array([int(m.shape_body[s]) for s, _ in shapes], np.int64))
        return self._sensors

    def shape_collider(self, shape: int):
        """Row ``shape`` of the shape table as a collider object that follows its body (a bound
        `inertia.collision.shapes.BodyShape`): use it where a collider is expected outside the
        particle stage, e.g. as a curl-noise boundary (``CurlNoise(boundaries=[...])``). During
        the particle stage its pose is interpolated over the step like the stage's own rows."""
        from .collision.shapes import BodyShape
        m = self.model
        if m is None or not isinstance(shape, (int, np.integer)) or not 0 <= shape < m.shape_count:
            count = 0 if m is None else m.shape_count
            raise ValueError(f"shape must be a row index of the world's shape table in [0, {count - 1}]; got {shape!r}")
        body = int(m.shape_body[shape])
        col = BodyShape(m, int(shape), None if (body < 0 or self.rigid is None) else self.rigid.state.body_q[body])
        if body >= 0 and self.rigid is not None:
            col.bind(lambda t, b=body: self._body_pose_at(b, t), lambda t, b=body: self.rigid.state.body_qd[b])
        return col

    def _body_pose_at(self, body: int, t: float) -> np.ndarray:
        q1 = self.rigid.state.body_q[body]
        if not self._in_particle_stage:
            return q1.copy()
        s = min(max((t - self.t) / self.dt, 0.0), 1.0)
        q0 = self._q_start[body]
        q = np.empty(7)
        q[:3] = (1.0 - s) * q0[:3] + s * q1[:3]
        r = (1.0 - s) * q0[3:] + s * np.copysign(1.0, float(q0[3:] @ q1[3:])) * q1[3:]
        q[3:] = r / np.linalg.norm(r)
        return q

    def add_fluid(self, name: str, fluid) -> Any:
        """Add a fluid (an object with ``advance(dt, rigid)``, ``save_state()``, ``restore_state(d)``,
        ``frame_arrays()``, ``static_arrays()``; see the contract in the module docstring). The fluids
        stage calls ``fluid.advance(dt, world.rigid)`` after the rigid stage, before the particle groups;
        a fluid whose ``advance_before_rigid`` is True is advanced before the rigid stage instead."""
        if not isinstance(name, str) or not name or "/" in name:
            raise ValueError(f"fluid name must be a non-empty string without '/'; got {name!r}")
        if name in self.fluids or any(g.name == name for g in self.groups) or name in STAGES:
            raise ValueError(f"a group, fluid or stage named {name!r} already exists; names must be unique")
        missing = [m for m in ("advance", "save_state", "restore_state", "frame_arrays", "static_arrays")
                   if not callable(getattr(fluid, m, None))]
        if missing:
            raise ValueError(f"fluid {name!r} lacks the methods {missing} (the fluid protocol: advance(dt, rigid), "
                             "save_state(), restore_state(dict), frame_arrays(), static_arrays())")
        check = getattr(fluid, "check_rigid", None)   # optional: a fluid that cannot couple with the bodies
        if self.rigid is not None and callable(check):
            check(self.rigid)
        self.fluids[name] = fluid
        self.profile[f"fluid/{name}"] = 0.0
        return fluid

    # ---- sizes and lookup --------------------------------------------------------------------
    @property
    def dim(self) -> int:
        return self.groups[0].system.dim if self.groups else 3

    @property
    def particle_count(self) -> int:
        return self.groups[-1].stop if self.groups else 0

    def group(self, name: str) -> Group:
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"no group named {name!r}; groups: {[g.name for g in self.groups]}")

    def __getitem__(self, name: str):
        """The system of group `name` (``world["chain"].x`` are its positions)."""
        return self.group(name).system

    def __iter__(self):
        return iter(self.groups)

    # ---- stepping ----------------------------------------------------------------------------
    def step(self) -> None:
        """Advance everything by dt: the stages of the module docstring, each timed in ``profile``."""
        clock = _time.perf_counter
        rigid = self.rigid
        t0 = clock()
        if rigid is not None:
            self._kinematics(self.t)
            self._q_start[:] = rigid.state.body_q
        t1 = clock()
        self.profile["kinematics"] += t1 - t0
        for name, fluid in self.fluids.items():   # fluids that push bodies before they move
            if getattr(fluid, "advance_before_rigid", False):
                tf = clock()
                fluid.advance(self.dt, rigid)
                self.profile[f"fluid/{name}"] += clock() - tf
        early = clock() - t1
        self.profile["fluids"] += early
        t1 += early
        if rigid is not None:
            before = dict(rigid.profile)
            rigid.step()
            if self._driven:
                self._kinematics_end(self.t + self.dt)
            for stage, seconds in rigid.profile.items():      # the rigid world's own stages
                key = f"rigid/{stage}"
                self.profile[key] = self.profile.get(key, 0.0) + seconds - before.get(stage, 0.0)
        t2 = clock()
        self.profile["rigid"] += t2 - t1
        for name, fluid in self.fluids.items():
            if getattr(fluid, "advance_before_rigid", False):
                continue
            tf = clock()
            fluid.advance(self.dt, rigid)
            self.profile[f"fluid/{name}"] += clock() - tf
        t3 = clock()
        self.profile["fluids"] += t3 - t2
        if rigid is not None:
            self._impulse_linear[:] = 0.0
            self._impulse_angular[:] = 0.0
            for g in self.groups:
                coupling = getattr(getattr(g.system, "_collision", None), "coupling", None)
                if coupling is not None:
                    coupling.clear_slots()
        self._in_particle_stage = True
        try:
            for g in self.groups:
                t0 = clock()
                sim = g.simulation
                entries = g.body_entries if rigid is not None else None
                for j in range(self.substeps):
                    if entries is not None and entries.size:
                        data = g.system._collision
                        _interpolated_poses(entries, g.entry_body_all, g.entry_bound, self._q_start,
                                            rigid.state.body_q, j / self.substeps, (j + 1) / self.substeps,
                                            data.pose0, data.pose1, data.cnear, rigid.state.body_qd)
                    sim.step()
                self.profile[g.name] += clock() - t0
        finally:
            self._in_particle_stage = False
        t4 = clock()
        if rigid is not None:
            from .dynamics.particle_coupling import apply_body_impulses
            apply_body_impulses(self.model, rigid.state, self._impulse_linear, self._impulse_angular,
                                scratch=self._impulse_scratch)
            self._fill_particle_contacts()
        self.profile["coupling"] += clock() - t4
        self.step_count += 1
        self.t = self.step_count * self.dt

    def _fill_particle_contacts(self) -> None:
        """Append the particle rows of this step to the rigid world's Contacts buffer, after the rigid
        rows, group by group (count, grow the buffer, fill: `particle_coupling.fill_particle_contacts`)."""
        from .dynamics.particle_coupling import (ContactSlots, PackedRows, SLOTS, fill_particle_contacts)
        c = self.rigid.contacts
        c.particle_start = c.count
        c.particle_count = 0
        sensors = None
        for gi, g in enumerate(self.groups):
            if not g.records_contacts:
                continue
            if sensors is None:
                sensors = self._sensor_rows()
                _sensor_poses(sensors.body, self.rigid.state.body_q, sensors.pose)
            system = g.system
            data = getattr(system, "_collision", None)
            coupling = None if data is None else data.coupling
            if coupling is not None:
                slots = ContactSlots(coupling.slot_entry, coupling.slot_impulse)
                rows = PackedRows(data.cint, data.cf, data.ci, data.pose1, data.ref, coupling.entry_body,
                                  coupling.entry_shape)
                rest_k = data.rest_k
                order = coupling.row_order(sensors.shape.size > 0)   # the particles that can have rows
            else:
                if sensors.shape.size == 0:
                    continue
                n = system.x.shape[0]
                if self._no_slots is None or self._no_slots[0].entry.shape[0] != n:   # built once
                    self._no_slots = (ContactSlots(np.full((n, SLOTS), -1, np.int64), np.zeros((n, SLOTS, 3))),
                                      np.full(n, -1, np.int32),
                                      PackedRows(np.zeros((1, 4), np.int64), np.zeros(1), np.zeros(1, np.int64),
                                                 np.zeros((1, 12)), np.zeros((1, 3)), np.full(1, -1, np.int64),
                                                 np.full(1, -1, np.int64)))
                slots, rest_k, rows = self._no_slots
                order = (rows.entry_shape, -1)                        # every particle (sensor rows)
            start = c.particle_start + c.particle_count
            args = (system.x, system.radius, system.active, rest_k, slots, rows, self.model.shape_body,
                    sensors, gi)
            n_rows = fill_particle_contacts(*args, c.particle_arrays(), start, False, *order)
            c.reserve(start + n_rows)
            fill_particle_contacts(*args, c.particle_arrays(), start, True, *order)
            c.particle_count += n_rows

    def contact_events(self, *, touch_slop: float = 0.0) -> dict:
        """Begin / persist / end events of the last step, for shape pairs and for particles.

        Shape pairs: the keys of `inertia.rigid.RigidWorld.contact_events` (``begin``, ``persist``,
        ``end`` as (K, 2) int32 shape-row pairs; ``begin_impulse``, ``persist_impulse`` N s).
        Particles (rows of the Contacts buffer's particle range; a particle row exists while the
        particle touches the shape, see `inertia.dynamics.contacts`): ``particle_begin``,
        ``particle_persist``, ``particle_end`` as (K, 3) int32 ``(group index, particle index, shape
        row)`` in buffer order, ``particle_begin_impulse`` and ``particle_persist_impulse`` (K,) the
        normal impulse (N s) the shape gave the particle over the step (0 for sensors). Sensor rows
        are included (a particle overlapping a sensor); ``touch_slop`` applies to shape pairs only.
        Empty arrays in a world without bodies."""
        empty3 = np.zeros((0, 3), np.int32)
        if self.rigid is None:
            e2 = np.zeros((0, 2), np.int32)
            return {"begin": e2, "persist": e2, "end": e2, "begin_impulse": np.zeros(0),
                    "persist_impulse": np.zeros(0), "particle_begin": empty3, "particle_persist": empty3,
                    "particle_end": empty3, "particle_begin_impulse": np.zeros(0),
                    "particle_persist_impulse": np.zeros(0)}
        out = self.rigid.contact_events(touch_slop=touch_slop)
        cur, prev = self.rigid.contacts, self.rigid._prev_contacts
        span = max([g.particle_count for g in self.groups] + [1])

        def keyed(c):
            rows = c.particle_rows()
            trip = np.empty((rows.size, 3), np.int32)
            trip[:, :2] = c.contact_particle[rows]
            trip[:, 2] = c.contact_shape[rows, 0]
            key = ((trip[:, 0].astype(np.int64) * span + trip[:, 1]) * self.model.shape_count + trip[:, 2])
            return rows, trip, key

        rows, trip, key = keyed(cur)
        prows, ptrip, pkey = keyed(prev)
        new = ~np.isin(key, pkey)
        gone = ~np.isin(pkey, key)
        imp = cur.contact_total_normal_impulse[rows, 0]
        out.update(particle_begin=trip[new], particle_persist=trip[~new], particle_end=ptrip[gone],
                   particle_begin_impulse=imp[new], particle_persist_impulse=imp[~new])
        return out

    def _kinematics(self, t: float) -> None:
        """Bodies of moving colliders: pose at t, velocity from the pose at t and t + dt."""
        from .collision.motion import rotation_log
        from .math import mat3_to_quat
        st = self.rigid.state
        for b, col in self._driven:
            p0, r0 = col.pose(t)
            p1, r1 = col.pose(t + self.dt)
            st.body_q[b, :3] = p0
            st.body_q[b, 3:] = mat3_to_quat(np.ascontiguousarray(r0))
            st.body_qd[b, :3] = rotation_log(r1 @ r0.T) / self.dt
            st.body_qd[b, 3:] = (p1 - p0) / self.dt

    def _kinematics_end(self, t: float) -> None:
        from .math import mat3_to_quat
        st = self.rigid.state
        for b, col in self._driven:
            p, r = col.pose(t)
            st.body_q[b, :3] = p
            st.body_q[b, 3:] = mat3_to_quat(np.ascontiguousarray(r))

    def run(self, duration: float | None = None, callback: Callable[["World"], None] | None = None) -> None:
        """Advance by `duration` seconds (rounded up to whole steps); default the scene's duration."""
        if duration is None:
            if self.duration is None:
                raise ValueError("run() needs a duration (this world has no scene duration)")
            duration = self.duration
        steps = int(math.ceil(float(duration) / self.dt - 1e-9))
        for _ in range(steps):
            self.step()
            if callback is not None:
                callback(self)

    # ---- gathered arrays ---------------------------------------------------------------------
    def positions(self, out: np.ndarray | None = None) -> np.ndarray:
        """(N, D) positions of every group, in group order (a copy, or written into `out`)."""
        out = np.empty((self.particle_count, self.dim)) if out is None else out
        for g in self.groups:
            out[g.start:g.stop] = g.system.x
        return out

    def velocities(self, out: np.ndarray | None = None) -> np.ndarray:
        """(N, D) velocities (for tracers: the field velocity at their positions)."""
        out = np.empty((self.particle_count, self.dim)) if out is None else out
        for g in self.groups:
            out[g.start:g.stop] = g.system.v
        return out

    def active(self, out: np.ndarray | None = None) -> np.ndarray:
        """(N,) bool: False for emitter pool slots not in use."""
        out = np.empty(self.particle_count, dtype=bool) if out is None else out
        for g in self.groups:
            out[g.start:g.stop] = g.system.active
        return out

    def energies(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per group: kinetic (G,), potential (G,) in J and momentum (G, D) in kg m/s (NaN for tracers)."""
        n = len(self.groups)
        kinetic, potential = np.full(n, np.nan), np.full(n, np.nan)
        momentum = np.full((n, self.dim), np.nan)
        for i, g in enumerate(self.groups):
            if g.kind == "particles":
                kinetic[i] = g.system.kinetic_energy()
                potential[i] = g.system.potential_energy()
                momentum[i] = g.system.momentum()
        return kinetic, potential, momentum

    def body_energies(self) -> tuple[float, float, np.ndarray]:
        """Of the dynamic rigid bodies: kinetic energy (J; translation 1/2 m |v|^2 plus rotation
        1/2 w_b . I w_b with w_b the angular velocity in the principal axes), potential energy in
        gravity (J; -m g . x) and linear momentum (3,) kg m/s; zeros without bodies."""
        if self.rigid is None:
            return 0.0, 0.0, np.zeros(3)
        m, st = self.model, self.rigid.state
        dynamic = np.asarray(m.body_inv_mass) > 0
        mass = np.asarray(m.body_mass)[dynamic]
        q, qd = st.body_q[dynamic], st.body_qd[dynamic]
        w, v = qd[:, :3], qd[:, 3:]
        # angular velocity in the body's principal axes: rotate by the conjugate quaternion
        w_body = rotate_vectors(q[:, 3:] * np.array([1.0, -1.0, -1.0, -1.0]), w)
        kinetic = 0.5 * float(np.sum(mass * np.einsum("ij,ij->i", v, v)))
        kinetic += 0.5 * float(np.sum(np.asarray(m.body_inertia)[dynamic] * w_body * w_body))
        gravity = np.asarray(m.gravity, dtype=np.float64).reshape(3)
        potential = -float(np.sum(mass * (q[:, :3] @ gravity)))
        return kinetic, potential, (mass[:, None] * v).sum(axis=0)

    def system_diagnostics(self) -> dict[str, float | np.ndarray]:
        """Per-frame diagnostics of the bodies and fluids (recorded by `Run` as ``diag/<system>/<quantity>``):

        - ``bodies``: ``kinetic_energy`` J (translation + rotation of the dynamic bodies,
          sum m |v|^2 / 2 + w_b . I w_b / 2 in the principal frame), ``potential_energy`` J
          (-sum m g . c, relative to the origin), ``momentum`` (3,) kg m/s;
        - an SPH fluid: ``kinetic_energy`` J, ``mass`` kg, ``density_error`` (mean relative
          compression of the last step) and ``divergence_error`` (1/s, DFSPH's divergence pass);
        - a grid smoke: ``kinetic_energy`` J (``fluid_density`` times the face velocities' energy),
          ``divergence`` 1/s (largest |div u| after the projection);
        - a grid liquid: ``kinetic_energy`` J (``density`` h^D / particles-per-cell per particle),
          ``volume`` m^3 (cells inside the particle level set).
        One call per recorded frame (it may allocate; never called inside a step)."""
        out: dict[str, float | np.ndarray] = {}
        m, rigid = self.model, self.rigid
        if rigid is not None and m is not None and np.any(m.body_type == 0):
            kinetic, potential, momentum = self.body_energies()
            out["bodies/kinetic_energy"] = kinetic
            out["bodies/potential_energy"] = potential
            out["bodies/momentum"] = momentum
        for name, fluid in self.fluids.items():
            key = f"{name}/"
            if hasattr(fluid, "rest_density") and hasattr(fluid, "stats"):      # SPH
                n, v = fluid.particle_count, fluid.v
                out[key + "kinetic_energy"] = float(0.5 * fluid.mass * np.sum(v * v))
                out[key + "mass"] = float(fluid.mass * n)
                out[key + "density_error"] = float(fluid.stats.get("density_error", np.nan))
                out[key + "divergence_error"] = float(fluid.stats.get("divergence_error", np.nan))
            elif hasattr(fluid, "fluid_density") and hasattr(fluid, "measure_divergence"):  # grid smoke
                out[key + "kinetic_energy"] = float(fluid.fluid_density * fluid.kinetic_energy())
                out[key + "divergence"] = float(np.max(np.abs(fluid.measure_divergence()), initial=0.0))
            elif hasattr(fluid, "particles_per_cell") and hasattr(fluid, "level_set"):  # grid liquid
                h = float(fluid.cell_size)
                out[key + "kinetic_energy"] = float(fluid.density * h ** fluid.dim / fluid.particles_per_cell
                                                    * fluid.kinetic_energy())
                out[key + "volume"] = float(np.count_nonzero(fluid.level_set() < 0.0) * h ** fluid.dim)
        return out

    def vehicles(self) -> list:
        """The scene's ray-cast vehicles (`inertia.rigid.vehicle.RaycastVehicle`), in scene order."""
        return [c.vehicle for c in getattr(getattr(self, "rigid_scene", None), "controllers", None) or []]

    def wheel_poses(self, vehicle) -> np.ndarray:
        """(W, 7) world pose of each wheel's centre (position + the chassis's quaternion): the hardpoint
        moved down the chassis's -z by the suspension's length, ``rest_length - compression``."""
        q = self.rigid.state.body_q[vehicle.chassis]
        local = np.array([np.asarray(wh.hardpoint, np.float64) - np.array([0.0, 0.0, wh.rest_length - c])
                          for wh, c in zip(vehicle.wheels, vehicle.wheel_compression)])
        out = np.empty((len(vehicle.wheels), 7))
        out[:, :3] = rotate_vectors(q[3:], local) + q[:3]
        out[:, 3:] = q[3:]
        return out

    @property
    def has_emitters(self) -> bool:
        return any(getattr(g.system, "emitters", None) for g in self.groups)

    # ---- checkpoints -------------------------------------------------------------------------
    def save_state(self) -> WorldState:
        """Everything that changes; `restore_state` continues bit for bit.

        ``rigid`` holds the rigid State's arrays (``body_q``, ``body_qd``, ``body_sleep_time``,
        ``body_awake``, ``body_sleep_island``, ``clock``, ``step_index``) and the warm-start contact
        cache (``contacts/<array>`` and ``contacts_count``, ``contacts_active_count``)."""
        rigid = None
        if self.rigid is not None:
            saved = self.rigid.save()
            rigid = {f: np.array(getattr(saved["state"], f)) for f in saved["state"]._FIELDS}
            contacts = saved["contacts"]
            from .dynamics.contacts import _SPEC
            for name in _SPEC:
                rigid[f"contacts/{name}"] = np.array(getattr(contacts, name))
            rigid["contacts_count"] = int(contacts.count)
            rigid["contacts_active_count"] = int(contacts.active_count)
            rigid["contacts_particle_count"] = int(contacts.particle_count)
        fluids = {name: dict(f.save_state()) for name, f in self.fluids.items()}
        return WorldState(self.step_count, [g.simulation.save_state() for g in self.groups], rigid, fluids)

    def restore_state(self, state: WorldState, *, check: bool = True) -> None:
        """Continue from `save_state`'s snapshot. ``check``: first compare it with what this world
        saves (`check_checkpoint`: every array's dtype and shape, every count and index against the
        arrays it indexes) and raise `CheckpointError` naming the entry; pass False only for a state
        already checked."""
        if check:
            check_checkpoint(self, state, None, "saved state")
        if len(state.groups) != len(self.groups):
            raise ValueError(f"the saved state has {len(state.groups)} groups; this world has {len(self.groups)}")
        if (state.rigid is None) != (self.rigid is None):
            raise ValueError("the saved state and this world differ in having rigid bodies")
        if sorted(state.fluids) != sorted(self.fluids):
            raise ValueError(f"the saved state has fluids {sorted(state.fluids)}; this world has {sorted(self.fluids)}")
        for g, s in zip(self.groups, state.groups):
            g.simulation.restore_state(s)
        if self.rigid is not None:
            from .dynamics.contacts import _SPEC, Contacts
            from .model import State
            r = state.rigid
            saved_state = State.__new__(State)
            for f in State._FIELDS:
                setattr(saved_state, f, np.asarray(r[f]))
            contacts = Contacts.__new__(Contacts)
            contacts.capacity = int(r["contacts/" + next(iter(_SPEC))].shape[0])
            contacts.count, contacts.active_count = int(r["contacts_count"]), int(r["contacts_active_count"])
            contacts.particle_start = contacts.count
            contacts.particle_count = int(r.get("contacts_particle_count", 0))
            for name in _SPEC:
                if f"contacts/{name}" in r:
                    setattr(contacts, name, np.asarray(r[f"contacts/{name}"]))
                else:         # a checkpoint from before the array existed
                    shape, dtype = _SPEC[name]
                    setattr(contacts, name, np.zeros((contacts.capacity,) + shape, dtype))
            self.rigid.restore({"state": saved_state, "contacts": contacts})
        for name, f in self.fluids.items():
            f.restore_state(state.fluids[name])
        self.step_count = int(state.step_count)
        self.t = self.step_count * self.dt

    def __repr__(self):
        groups = ", ".join(f"{g.name}: {g.particle_count} {g.kind} ({g.integrator})" for g in self.groups)
        return f"World({self.name!r}, dt={self.dt:g}, substeps={self.substeps}, t={self.t:g}, groups=[{groups}])"


@njit(cache=True)
def _sensor_poses(body, body_q, pose):
    """pose rows [p, R row-major] of the sensor rows on bodies (``body >= 0``) from the bodies' poses."""
    for k in range(body.shape[0]):
        b = body[k]
        if b < 0:
            continue
        for c in range(3):
            pose[k, c] = body_q[b, c]
        r = quat_to_mat3_entries(body_q[b, 3], body_q[b, 4], body_q[b, 5], body_q[b, 6])
        for i in range(9):
            pose[k, 3 + i] = r[i]


@njit(cache=True)
def _interpolated_poses(entries, entry_body, entry_bound, q_start, q_end, s0, s1, pose0, pose1, cnear, qd):
    """pose0/pose1 rows [p, R row-major] of the body-shape colliders `entries` at fractions s0, s1 of
    the step (positions linear, orientations normalised-linear between the step's two poses), and
    their ``cnear`` rows: a ball about the centre of mass swept over the substep (radius
    ``entry_bound`` + half the displacement) for bounded shapes, "always near" for planes (< 0).
    Columns 12:18 of both rows: the body's velocity ``qd`` (``body_qd`` after the rigid step, the
    velocity that moved it over the step), from which the particle stage takes the surface's
    material velocity (``particle_kernels._body_velocity``)."""
    for e in range(entries.shape[0]):
        k, b = entries[e], entry_body[e]
        for c in range(6):
            pose0[k, 12 + c] = qd[b, c]
            pose1[k, 12 + c] = qd[b, c]
        if entry_bound[e] >= 0.0:
            half = 0.0
            cnear[k, 0] = _NEAR_BALL
            for c in range(3):
                a = (1.0 - s0) * q_start[b, c] + s0 * q_end[b, c]
                z = (1.0 - s1) * q_start[b, c] + s1 * q_end[b, c]
                cnear[k, 1 + c] = 0.5 * (a + z)
                half += (z - a) * (z - a)
            cnear[k, 4] = entry_bound[e] + 0.5 * np.sqrt(half) + 1e-9
        else:
            cnear[k, 0] = _NEAR_ALWAYS
        for out, s in ((pose0, s0), (pose1, s1)):
            if s == 1.0:
                w, x, y, z = q_end[b, 3], q_end[b, 4], q_end[b, 5], q_end[b, 6]
            elif s == 0.0:
                w, x, y, z = q_start[b, 3], q_start[b, 4], q_start[b, 5], q_start[b, 6]
            else:
                w, x, y, z = _nlerp(q_start[b, 3:7], q_end[b, 3:7], s)
            for c in range(3):
                out[k, c] = (1.0 - s) * q_start[b, c] + s * q_end[b, c] if 0.0 < s < 1.0 else (
                    q_start[b, c] if s == 0.0 else q_end[b, c])
            r = quat_to_mat3_entries(w, x, y, z)
            for i in range(9):
                out[k, 3 + i] = r[i]


@njit(cache=True)
def _nlerp(qa, qb, s):
    """(1 - s) qa + s qb (qb's sign flipped onto qa's hemisphere), normalised: four scalars."""
    dot = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]
    sign = 1.0 if dot >= 0.0 else -1.0
    w = (1.0 - s) * qa[0] + s * sign * qb[0]
    x = (1.0 - s) * qa[1] + s * sign * qb[1]
    y = (1.0 - s) * qa[2] + s * sign * qb[2]
    z = (1.0 - s) * qa[3] + s * sign * qb[3]
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    return w / norm, x / norm, y / norm, z / norm


# ----------------------------------------------------------------------------------------------
# checkpoint files: a JSON tree with the arrays beside it in one .npz, written atomically.
# Nothing is pickled: a checkpoint is data only (arrays loaded with allow_pickle=False, JSON),
# so a checkpoint someone sends you cannot run code when it is resumed.
# ----------------------------------------------------------------------------------------------
class CheckpointError(ValueError):
    """A checkpoint file cannot be used: damaged, from another scene, or not data only."""


_TAGS = ("__array__", "__scalar__", "__tuple__", "__items__")
_MAX_DEPTH = 64          # nesting of a checkpoint's JSON tree (ours is < 10 deep)


def _encode(value, arrays: dict, where: str = "state"):
    def store(array) -> str:
        key = f"a{len(arrays)}"
        arrays[key] = array
        return key

    if value is None or isinstance(value, (bool, int, str, float)):
        return value
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            raise TypeError(f"checkpoint: {where} is an array of Python objects; checkpoints hold numeric "
                            "arrays and JSON only")
        return {"__array__": store(value)}
    if isinstance(value, np.generic):
        return {"__scalar__": store(np.asarray(value))}
    if isinstance(value, dict):
        if all(isinstance(k, str) and not k.startswith("__") for k in value):
            return {k: _encode(v, arrays, f"{where}.{k}") for k, v in value.items()}
        return {"__items__": [[_encode(k, arrays, f"{where} key"), _encode(v, arrays, f"{where}[{k!r}]")]
                              for k, v in value.items()]}
    if isinstance(value, list):
        return [_encode(v, arrays, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, tuple):
        return {"__tuple__": [_encode(v, arrays, f"{where}[{i}]") for i, v in enumerate(value)]}
    raise TypeError(f"checkpoint: {where} is a {type(value).__name__}; checkpoints hold arrays, numbers, "
                    "strings, lists and dicts only (a stage's get_state must return those)")


def _decode(value, arrays, path, depth: int = 0):
    if depth > _MAX_DEPTH:
        raise CheckpointError(f"{path}: the checkpoint's tree is nested deeper than {_MAX_DEPTH} levels; "
                              "it was not written by inertia")
    if isinstance(value, list):
        return [_decode(v, arrays, path, depth + 1) for v in value]
    if not isinstance(value, dict):
        return value

    def array(key):
        if not isinstance(key, str) or key not in arrays:
            raise CheckpointError(f"{path}: the checkpoint names an array {key!r} it does not hold; "
                                  "the file is damaged")
        return arrays[key]

    if "__pickle__" in value:
        raise CheckpointError(f"{path}: the checkpoint holds a pickled object, which is refused (loading it "
                              "could run code). Checkpoints written by this inertia hold arrays and JSON only; "
                              "run without --resume to start over.")
    tags = [k for k in value if isinstance(k, str) and k.startswith("__")]
    if tags and (len(value) != 1 or tags[0] not in _TAGS):
        raise CheckpointError(f"{path}: unknown entry {tags[0]!r} in the checkpoint; the file is damaged "
                              "or from a newer inertia")
    if "__array__" in value:
        return np.array(array(value["__array__"]))
    if "__scalar__" in value:
        return array(value["__scalar__"])[()]
    if "__tuple__" in value:
        return tuple(_decode(v, arrays, path, depth + 1) for v in value["__tuple__"])
    if "__items__" in value:
        return {_decode(k, arrays, path, depth + 1): _decode(v, arrays, path, depth + 1)
                for k, v in value["__items__"]}
    return {k: _decode(v, arrays, path, depth + 1) for k, v in value.items()}


def save_checkpoint(path, state: WorldState, info: dict) -> Path:
    """Write `state` and `info` (JSON-able run facts) to `path` atomically (an .npz file).

    Raises TypeError naming the entry if the state holds anything but arrays, numbers, strings,
    lists, tuples and dicts (nothing is ever pickled).
    """
    from .io import atomic_write

    arrays: dict[str, np.ndarray] = {}
    groups = [{"time": s.time, "step_count": s.step_count,
               "system": _encode(s.system, arrays, f"groups[{i}].system"),
               "integrator": _encode(s.integrator, arrays, f"groups[{i}].integrator"),
               "extra": _encode(s.extra, arrays, f"groups[{i}].extra")}
              for i, s in enumerate(state.groups)]
    tree = {"checkpoint_version": CHECKPOINT_VERSION, "info": info, "step_count": state.step_count,
            "groups": groups, "rigid": _encode(state.rigid, arrays, "rigid"),
            "fluids": _encode(state.fluids, arrays, "fluids")}
    arrays["tree"] = np.array(json.dumps(tree))
    with atomic_write(path, "wb") as handle:
        np.savez(handle, **arrays)
    return Path(path)


def _check_member_sizes(path, data) -> None:
    """Every array of an open checkpoint archive: its .npy header read alone and checked against the
    member's stored size (`inertia.io.states.npz_member_problem`), before anything is allocated."""
    from .io.states import npz_member_problem

    zip_file = getattr(data, "zip", None)
    problem = None if zip_file is None else npz_member_problem(zip_file)
    if problem is not None:
        raise CheckpointError(f"{path}: {problem}")


def _read_tree(path, data) -> dict:
    """The JSON tree of an open checkpoint, version-checked (nothing else is read)."""
    _check_member_sizes(path, data)
    if "tree" not in data.files:
        raise CheckpointError(f"{path}: not an inertia checkpoint (no tree inside)")
    try:
        raw = data["tree"]
    except _DAMAGED as exc:
        raise CheckpointError(f"{path}: the checkpoint is damaged: its tree cannot be read "
                              f"({type(exc).__name__}: {exc})") from None
    try:
        tree = json.loads(str(raw[()]))
    except (ValueError, RecursionError, IndexError) as exc:
        raise CheckpointError(f"{path}: the checkpoint's tree is not valid JSON ({type(exc).__name__})") from None
    if not isinstance(tree, dict) or not isinstance(tree.get("info"), dict) or not isinstance(tree.get("groups"), list):
        raise CheckpointError(f"{path}: not an inertia checkpoint (its tree lacks info or groups)")
    if tree.get("checkpoint_version") != CHECKPOINT_VERSION:
        raise CheckpointError(f"{path}: checkpoint version {tree.get('checkpoint_version')!r} is not "
                              f"{CHECKPOINT_VERSION}")
    return tree


#: what reading a damaged archive member raises (bad CRC, truncated stream, bad header)
_DAMAGED = (OSError, ValueError, zipfile.BadZipFile, EOFError, zlib.error, NotImplementedError, KeyError,
            OverflowError, MemoryError)


def _open_checkpoint(path):
    try:
        return np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise CheckpointError(f"{path}: checkpoint not found") from None
    except _DAMAGED as exc:
        raise CheckpointError(f"{path}: not a readable checkpoint ({exc})") from None


def read_checkpoint_info(path) -> dict:
    """The run facts of a checkpoint (fingerprint, fps, dt, duration, seed, ...), decoding nothing else."""
    with _open_checkpoint(path) as data:
        if not hasattr(data, "files"):
            raise CheckpointError(f"{path}: not an inertia checkpoint (a single array, not an archive)")
        return _read_tree(path, data)["info"]


def load_checkpoint(path, *, fingerprint: str | None = None) -> tuple[WorldState, dict]:
    """Read a checkpoint written by `save_checkpoint`: (state, info).

    ``fingerprint``: when given, the checkpoint must have been written by a scene with this
    fingerprint; it is checked before any array is read or any entry decoded. Raises
    `CheckpointError` (a ValueError naming the file) for a damaged or foreign checkpoint, and for
    one that holds a pickled object (refused: loading it could run code).
    """
    with _open_checkpoint(path) as data:
        if not hasattr(data, "files"):
            raise CheckpointError(f"{path}: not an inertia checkpoint (a single array, not an archive)")
        tree = _read_tree(path, data)
        info = tree["info"]
        if fingerprint is not None and info.get("fingerprint") != fingerprint:
            raise CheckpointError(f"{path}: the checkpoint was written by another scene (fingerprint "
                                  f"{info.get('fingerprint')!r}, this scene {fingerprint!r})")
        arrays = {}
        for key in data.files:
            if key == "tree":
                continue
            try:
                arrays[key] = data[key]
            except ValueError as exc:
                if "allow_pickle" in str(exc):    # an object array: numpy refuses it without pickle
                    raise CheckpointError(f"{path}: array {key!r} holds Python objects, which is refused "
                                          f"(loading it could run code): {exc}") from None
                raise CheckpointError(f"{path}: array {key!r} is damaged ({exc})") from None
            except _DAMAGED as exc:
                raise CheckpointError(f"{path}: array {key!r} is damaged ({type(exc).__name__}: {exc})") from None
    try:
        groups = [SimulationState(g["time"], g["step_count"], _decode(g["system"], arrays, path),
                                  _decode(g["integrator"], arrays, path), _decode(g["extra"], arrays, path))
                  for g in tree["groups"]]
        rigid = _decode(tree.get("rigid"), arrays, path)
        fluids = _decode(tree.get("fluids") or {}, arrays, path)
        return WorldState(tree["step_count"], groups, rigid, fluids), info
    except (KeyError, TypeError) as exc:
        raise CheckpointError(f"{path}: the checkpoint is damaged (missing or malformed entry {exc})") from None


# ----------------------------------------------------------------------------------------------
# checking a loaded checkpoint against the world it is restored into: every array's shape and
# dtype against what this scene's world saves, every count and index against the arrays it
# indexes, before any kernel runs (a checkpoint from anyone must never reach memory it does not own)
# ----------------------------------------------------------------------------------------------
def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    if isinstance(value, np.generic):
        return f"a {value.dtype} scalar"
    return f"a {type(value).__name__}"


def _compare_layout(template, loaded, where: str, problems: list, variable_rows=(), depth: int = 0) -> None:
    """Append to `problems` each place where `loaded` differs in layout from `template` (what this
    world's ``save_state`` makes): arrays by dtype and shape (rows free for the keys in
    `variable_rows`), numbers by kind and finiteness, dicts by key, lists by length."""
    if len(problems) >= 8 or depth > _MAX_DEPTH:
        return
    if isinstance(template, (np.ndarray, np.generic)):
        t = np.asarray(template)
        if not isinstance(loaded, (np.ndarray, np.generic)):
            problems.append(f"{where}: expected {_describe(t)}, the checkpoint holds {_describe(loaded)}")
            return
        got = np.asarray(loaded)
        if got.dtype != t.dtype:
            problems.append(f"{where}: dtype {got.dtype}, this scene makes {t.dtype}")
        elif where.rsplit(".", 1)[-1] in variable_rows and t.ndim >= 1:
            if got.ndim != t.ndim or got.shape[1:] != t.shape[1:]:
                problems.append(f"{where}: shape {got.shape}, this scene makes (rows,) + {t.shape[1:]}")
        elif got.shape != t.shape:
            problems.append(f"{where}: shape {got.shape}, this scene makes {t.shape}")
        return
    if isinstance(template, dict):
        if not isinstance(loaded, dict):
            problems.append(f"{where}: expected a table, the checkpoint holds {_describe(loaded)}")
            return
        for key, value in template.items():
            if key not in loaded:
                problems.append(f"{where}.{key}: missing from the checkpoint")
                continue
            _compare_layout(value, loaded[key], f"{where}.{key}", problems, variable_rows, depth + 1)
        return
    if isinstance(template, (list, tuple)):
        if not isinstance(loaded, (list, tuple)) or len(loaded) != len(template):
            n = len(loaded) if isinstance(loaded, (list, tuple)) else _describe(loaded)
            problems.append(f"{where}: {n} entries, this scene makes {len(template)}")
            return
        for i, (a, b) in enumerate(zip(template, loaded)):
            _compare_layout(a, b, f"{where}[{i}]", problems, variable_rows, depth + 1)
        return
    if isinstance(template, bool):
        if not isinstance(loaded, (bool, np.bool_)):
            problems.append(f"{where}: expected true or false, the checkpoint holds {loaded!r:.40}")
        return
    if isinstance(template, (int, float)):
        if isinstance(loaded, (bool, np.bool_)) or not isinstance(loaded, (int, float, np.integer, np.floating)):
            problems.append(f"{where}: expected a number, the checkpoint holds {_describe(loaded)}")
        elif isinstance(template, int) and not isinstance(loaded, (int, np.integer)):
            problems.append(f"{where}: expected an integer, the checkpoint holds {loaded!r:.40}")
        elif isinstance(loaded, (float, np.floating)) and not math.isfinite(loaded):
            problems.append(f"{where}: {loaded!r} is not a finite number")
        return
    if isinstance(template, str) and not isinstance(loaded, str):
        problems.append(f"{where}: expected a string, the checkpoint holds {_describe(loaded)}")


def _index_problem(where: str, values, lo: int, hi: int) -> str | None:
    """A message if an integer array holds a value outside [lo, hi) (indices into hi rows)."""
    values = np.asarray(values)
    if values.size == 0:
        return None
    bad = (values < lo) | (values >= hi)
    if bad.any():
        first = int(np.flatnonzero(bad.ravel())[0])
        return (f"{where}: holds {int(values.ravel()[first])} at entry {first}, outside {lo}..{hi - 1} "
                f"(the rows it indexes)")
    return None


def _count_problem(where: str, value, lo: int, hi: int) -> str | None:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return f"{where}: expected an integer count, the checkpoint holds {value!r:.40}"
    if not lo <= int(value) <= hi:
        return f"{where}: {int(value)} is outside {lo}..{hi} (the capacity of the arrays it counts)"
    return None


def _rigid_problems(world: "World", r: dict) -> list[str]:
    """Counts and indices of the rigid state and contact cache against their arrays."""
    from .dynamics.contacts import _SPEC
    m = world.model
    nb, ns = int(m.body_count), int(m.shape_count)
    rows = {r[f"contacts/{name}"].shape[0] for name in _SPEC if f"contacts/{name}" in r}
    if len(rows) != 1:
        return [f"rigid.contacts: its arrays have different row counts {sorted(rows)}"]
    cap = rows.pop()
    out = [_count_problem("rigid.contacts_count", r["contacts_count"], 0, cap)]
    if out[0] is not None:
        return out
    count = int(r["contacts_count"])
    out += [_count_problem("rigid.contacts_active_count", r["contacts_active_count"], 0, count),
            _count_problem("rigid.contacts_particle_count", r.get("contacts_particle_count", 0), 0, cap - count)]
    if any(out):
        return [p for p in out if p]
    used = count + int(r.get("contacts_particle_count", 0))
    active = int(r["contacts_active_count"])
    out += [_index_problem("rigid.contacts/active", r["contacts/active"][:active], 0, count),
            _index_problem("rigid.contacts/contact_body", r["contacts/contact_body"][:used], -1, nb),
            _index_problem("rigid.contacts/contact_shape", r["contacts/contact_shape"][:count], -1, ns),
            _index_problem("rigid.contacts/contact_point_count", r["contacts/contact_point_count"][:count], 0, 5),
            _index_problem("rigid.body_sleep_island", r["body_sleep_island"], -1, nb)]
    if "contacts/contact_particle" in r and used > count:
        particle = r["contacts/contact_particle"][count:used]
        out.append(_index_problem("rigid.contacts/contact_particle[group]", particle[:, 0], 0, max(len(world.groups), 1)))
        out.append(_index_problem("rigid.contacts/contact_particle[particle]", particle[:, 1], 0,
                                  max([g.particle_count for g in world.groups] + [1])))
    for key in ("clock", "step_index"):
        value = np.asarray(r[key])
        if not np.all(np.isfinite(value)) or np.any(value < 0):
            out.append(f"rigid.{key}: {value.tolist()} is not a finite value >= 0")
    return [p for p in out if p]


def check_checkpoint(world: "World", state: WorldState, info: dict | None, path, *,
                     frames_recorded: int | None = None) -> None:
    """Raise `CheckpointError` naming the array or fact if `state` (a loaded checkpoint) does not fit
    `world`: every array's dtype and shape against what this world's ``save_state`` makes, numbers
    finite and of the right kind, every count and index (contact rows, bodies, shapes, particles,
    fluid counters) inside the arrays it indexes, the step count against the frame count, and the
    frame count against the frames present in the state directory (``frames_recorded``; both
    frame checks need the run facts ``info``, None skips them).
    Nothing of `state` reaches a kernel before this passes."""
    template = world.save_state()
    problems: list[str] = []
    _compare_layout(template.step_count, state.step_count, "step_count", problems)
    if len(state.groups) != len(template.groups):
        problems.append(f"groups: {len(state.groups)} in the checkpoint, this scene has {len(template.groups)}")
    else:
        for i, (t, s) in enumerate(zip(template.groups, state.groups)):
            name = world.groups[i].name
            for part in ("system", "integrator", "extra"):
                _compare_layout(getattr(t, part), getattr(s, part), f"groups[{name}].{part}", problems)
            for part in ("time", "step_count"):
                _compare_layout(getattr(t, part), getattr(s, part), f"groups[{name}].{part}", problems)
    if (template.rigid is None) != (state.rigid is None):
        problems.append("rigid: the checkpoint " + ("has" if state.rigid is not None else "lacks")
                        + " rigid bodies, this scene " + ("has none" if template.rigid is None else "has them"))
    elif template.rigid is not None:
        from .dynamics.contacts import _SPEC
        rows = tuple(f"contacts/{name}" for name in _SPEC)
        _compare_layout(template.rigid, state.rigid, "rigid", problems, rows)
    if not isinstance(state.fluids, dict) or sorted(state.fluids) != sorted(template.fluids):
        got = sorted(state.fluids) if isinstance(state.fluids, dict) else _describe(state.fluids)
        problems.append(f"fluids: the checkpoint holds {got}, this scene has {sorted(template.fluids)}")
    else:
        for name, t in template.fluids.items():
            rows = tuple(getattr(world.fluids[name], "state_variable_rows", ()))
            _compare_layout(t, state.fluids[name], f"fluids.{name}", problems, rows)
    if not problems and template.rigid is not None:
        problems += _rigid_problems(world, state.rigid)
    if not problems:
        for name, fluid in world.fluids.items():
            check = getattr(fluid, "check_state", None)
            if check is not None:
                try:
                    check(state.fluids[name])
                except ValueError as exc:
                    problems.append(f"fluids.{name}: {exc}")
    if not problems and info is not None:
        frames = int(info["frame_count"])
        steps = int(state.step_count)
        fps, dt = float(info["fps"]), float(info["dt"])
        low = 0 if frames == 0 else frame_steps(frames - 1, fps, dt)
        if frames < 0 or not low <= steps <= frame_steps(frames, fps, dt):
            problems.append(f"frame_count: {frames} frames do not go with step_count {steps} (frame k is "
                            f"recorded at step ceil(k / (fps dt)))")
        elif frames_recorded is not None and frames > frames_recorded:
            problems.append(f"frame_count: the checkpoint counts {frames} frames but the state directory "
                            f"holds {frames_recorded}")
    if problems:
        more = "" if len(problems) < 8 else " (and maybe more)"
        advice = ". Run without --resume to start over." if info is not None else "."
        raise CheckpointError(f"{path}: the checkpoint does not fit this scene: " + "; ".join(problems) + more
                              + advice)


# ----------------------------------------------------------------------------------------------
# the run loop
# ----------------------------------------------------------------------------------------------
def frame_steps(frame: int, fps: float, dt: float) -> int:
    """Steps from t = 0 to output frame `frame`: the first step boundary at or after frame / fps."""
    return max(0, int(math.ceil(frame / (fps * dt) - 1e-6)))


@dataclass
class RunResult:
    """What a run did. ``status``: "completed", "interrupted" or "diverged"."""

    status: str
    frame_count: int
    step_count: int
    time: float
    states_path: Path
    checkpoint_path: Path | None
    timings: dict[str, float]
    error: BaseException | None = None
    first_frame_seconds: float | None = None


@dataclass
class Progress:
    """Handed to the progress callback: where the run is."""

    time: float
    duration: float
    frame: int
    frame_count: int
    step_count: int
    steps_per_second: float


class Run:
    """Run a world for `duration` seconds into `out_dir`, recording at `fps`.

    Parameters
    ----------
    world : the `World`.
    out_dir : directory that receives ``states/`` (the state directory) and ``checkpoint.npz``.
    duration, fps : simulated seconds and output frames per simulated second.
    resume : continue from ``out_dir/checkpoint.npz`` (its ``fingerprint`` must match).
    fingerprint : a string naming the physics of the scene; a checkpoint made from another
        scene is refused on resume.
    metadata : JSON-able header entries for the state file (scene text, seed, groups, ...).
    checkpoint_interval : wall-clock seconds between checkpoints (10 default).
    progress : callback ``progress(Progress)`` (after frames and at most every 0.2 s).
    stop_after_frames : stop as if interrupted once this many frames are recorded (testing).
    handle_sigint : catch Ctrl-C to stop cleanly (main thread only).
    """

    def __init__(self, world: World, out_dir, *, duration: float, fps: float, resume: bool = False,
                 fingerprint: str = "", metadata: dict | None = None, checkpoint_interval: float = 10.0,
                 progress: Callable[[Progress], None] | None = None, stop_after_frames: int | None = None,
                 handle_sigint: bool = True):
        if not (duration > 0 and math.isfinite(duration)):
            raise ValueError(f"duration must be a finite number > 0; got {duration!r}")
        if not (fps > 0 and math.isfinite(fps)):
            raise ValueError(f"fps must be a finite number > 0; got {fps!r}")
        self.world = world
        self.out_dir = Path(out_dir)
        self.duration, self.fps = float(duration), float(fps)
        self.resume = bool(resume)
        self.fingerprint = fingerprint
        self.metadata = dict(metadata or {})
        self.checkpoint_interval = float(checkpoint_interval)
        self.progress = progress
        self.stop_after_frames = stop_after_frames
        self.handle_sigint = handle_sigint
        self.states_path = self.out_dir / STATES_NAME
        self.checkpoint_path = self.out_dir / CHECKPOINT_NAME
        self._stop_requested = False
        self._sigint_depth = 0
        self.frame_count = int(math.floor(self.duration * self.fps + 1e-6)) + 1
        w = world
        self._x = np.empty((w.particle_count, w.dim))
        self._v = np.empty((w.particle_count, w.dim))
        self._active = np.empty(w.particle_count, dtype=bool)

    # ---- pieces ------------------------------------------------------------------------------
    def request_stop(self) -> None:
        """Ask the loop to stop after the current step (what Ctrl-C does)."""
        self._stop_requested = True

    def _info(self, frames: int) -> dict:
        w = self.world
        return {"fingerprint": self.fingerprint, "fps": self.fps, "dt": w.dt, "substeps": w.substeps,
                "frame_count": frames, "time": w.t, "particle_count": w.particle_count,
                "groups": [g.name for g in w.groups], "duration": self.duration, "seed": w.seed,
                "body_count": 0 if w.rigid is None else int(w.model.body_count), "fluids": sorted(w.fluids)}

    def _static(self) -> dict[str, np.ndarray]:
        w = self.world
        group = np.zeros(w.particle_count, dtype=np.int32)
        radius = np.zeros(w.particle_count)
        mass = np.zeros(w.particle_count)
        for i, g in enumerate(w.groups):
            group[g.start:g.stop] = i
            radius[g.start:g.stop] = g.system.radius
            mass[g.start:g.stop] = getattr(g.system, "mass", 0.0)
        return {"group": group, "radius": radius, "mass": mass}

    def _model_arrays(self) -> dict[str, np.ndarray]:
        """``States.model``: the shape table, spring_pairs, surface_triangles, fluids' static arrays."""
        return model_file_arrays(self.world)

    def _header(self) -> dict:
        w = self.world
        meta = {
            "groups": [g.name for g in w.groups],
            "group_kinds": [g.kind for g in w.groups],
            "group_colors": [g.color for g in w.groups],
            "integrators": [g.integrator for g in w.groups],
            "dt": w.dt, "substeps": w.substeps, "duration": self.duration,
            "body_names": [] if w.model is None else [str(n) for n in w.model.body_name],
            "fluids": list(w.fluids),
            # what kinetic_energy, potential_energy and momentum sum (NaN when none of these exists)
            "diagnostics_cover": ((["particles"] if any(g.kind == "particles" for g in w.groups) else [])
                                  + (["bodies"] if w.rigid is not None else [])),
        }
        meta.update(self.metadata)
        return meta

    def _record(self, writer) -> None:
        w = self.world
        w.positions(self._x)
        w.velocities(self._v)
        kinetic, potential, momentum = w.energies()
        particles = [i for i, g in enumerate(w.groups) if g.kind == "particles"]
        total_k = np.float64(np.sum(kinetic[particles])) if particles else np.float64(np.nan)
        total_p = np.float64(np.sum(potential[particles])) if particles else np.float64(np.nan)
        total_m = np.sum(momentum[particles], axis=0) if particles else np.full(w.dim, np.nan)
        if w.rigid is not None:
            # the bodies' share (3-D scenes only: bodies live in 3-D)
            bk, bp, bm = w.body_energies()
            total_k = np.float64(bk + (total_k if particles else 0.0))
            total_p = np.float64(bp + (total_p if particles else 0.0))
            total_m = (total_m if particles else 0.0) + bm[:w.dim]
        fields = {
            "kinetic_energy": total_k, "potential_energy": total_p, "momentum": total_m,
            "group_kinetic_energy": kinetic, "group_potential_energy": potential,
        }
        if w.has_emitters:
            fields["active"] = w.active(self._active)
        if w.rigid is not None:
            fields["body_q"] = w.rigid.state.body_q
        for key, value in w.system_diagnostics().items():
            fields[f"diag/{key}"] = np.asarray(value, np.float64)
        for k, vehicle in enumerate(w.vehicles()):
            fields[f"vehicle/{k}/wheel_pose"] = w.wheel_poses(vehicle)
        for name, fluid in w.fluids.items():
            for key, value in fluid.frame_arrays().items():
                fields[f"fluid/{name}/{key}"] = value
        writer.append(w.t, self._x, self._v, **fields)

    def _checkpoint(self, writer, frames: int) -> None:
        writer.flush()
        save_checkpoint(self.checkpoint_path, self.world.save_state(), self._info(frames))

    # ---- the loop ----------------------------------------------------------------------------
    def execute(self) -> RunResult:
        """Set up (fresh or resumed), step and record to the end, checkpoint; see the module doc.

        Ctrl-C is caught from before the first write to ``out_dir`` until after the last
        (`catching_sigint`), so an interrupt at any moment leaves a resumable run.
        """
        with self.catching_sigint():
            return self._execute()

    def _execute(self) -> RunResult:
        from .io import StateWriter

        w = self.world
        clock = _time.perf_counter
        started = clock()
        timings = {"simulate": 0.0, "record": 0.0, "checkpoint": 0.0}

        # setup: fresh, or from the checkpoint (its run facts and fingerprint checked before
        # anything else of it is decoded)
        if self.resume:
            self._check_compatible(read_checkpoint_info(self.checkpoint_path))
            state, info = load_checkpoint(self.checkpoint_path, fingerprint=self.fingerprint)
            from .io.states import recorded_frame_count
            check_checkpoint(w, state, info, self.checkpoint_path,
                             frames_recorded=recorded_frame_count(self.states_path))
            w.restore_state(state, check=False)
            frame = int(info["frame_count"])
            writer = StateWriter.reopen(self.states_path, frame_count=frame)
        else:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            writer = StateWriter(self.states_path, dim=w.dim, particle_count=w.particle_count, fps=self.fps,
                                 static=self._static(), metadata=self._header(), model=self._model_arrays(),
                                 overwrite=True)
            frame = 0
        status, error = "completed", None
        first_frame = None
        try:
            last_checkpoint = clock()
            last_report = 0.0
            report_steps, report_clock = w.step_count, clock()
            rate = 0.0
            while frame < self.frame_count and not self._stop_requested:
                # advance to the step of this frame
                target = frame_steps(frame, self.fps, w.dt)
                t0 = clock()
                while w.step_count < target and not self._stop_requested:
                    try:
                        w.step()
                    except SimulationDiverged as exc:
                        status, error = "diverged", exc
                        break
                    now = clock()
                    if self.progress is not None and now - last_report > 0.2:
                        rate = (w.step_count - report_steps) / max(now - report_clock, 1e-9)
                        last_report = now
                        self.progress(Progress(w.t, self.duration, frame, self.frame_count, w.step_count, rate))
                timings["simulate"] += clock() - t0
                if status == "diverged" or self._stop_requested:
                    break
                # record
                t0 = clock()
                self._record(writer)
                frame += 1
                timings["record"] += clock() - t0
                if first_frame is None and w.step_count > 0:
                    first_frame = clock() - started
                if self.stop_after_frames is not None and frame >= self.stop_after_frames and frame < self.frame_count:
                    self._stop_requested = True
                    break
                now = clock()
                if self.progress is not None:
                    rate = (w.step_count - report_steps) / max(now - report_clock, 1e-9)
                    self.progress(Progress(w.t, self.duration, frame, self.frame_count, w.step_count, rate))
                if now - last_checkpoint > self.checkpoint_interval:
                    t0 = clock()
                    self._checkpoint(writer, frame)
                    timings["checkpoint"] += clock() - t0
                    last_checkpoint = clock()
            if self._stop_requested and status == "completed" and frame < self.frame_count:
                status = "interrupted"
        finally:
            # what was simulated is kept: flush frames; checkpoint unless the state is broken
            t0 = clock()
            if status == "diverged":
                writer.flush()
            else:
                self._checkpoint(writer, frame)
            writer.close()
            timings["checkpoint"] += clock() - t0
        timings["total"] = clock() - started
        return RunResult(status, frame, w.step_count, w.t, self.states_path,
                         None if status == "diverged" else self.checkpoint_path, timings, error, first_frame)

    def _check_compatible(self, info: dict) -> None:
        w = self.world
        problems = []
        try:
            if info.get("fingerprint") != self.fingerprint:
                problems.append("the scene's physics changed since the checkpoint was written"
                                + self._scene_changes())
            if float(info["fps"]) != self.fps:
                problems.append(f"fps is {self.fps:g} but the checkpoint was recorded at {float(info['fps']):g}")
            if float(info["dt"]) != w.dt or int(info["substeps"]) != w.substeps:
                problems.append("dt or substeps changed")
            if int(info["particle_count"]) != w.particle_count:
                problems.append("the particle count changed")
            if int(info.get("body_count", 0)) != (0 if w.rigid is None else int(w.model.body_count)):
                problems.append("the body count changed")
            if list(info.get("fluids", [])) != sorted(w.fluids):
                problems.append("the fluids changed")
            int(info["frame_count"])
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{self.checkpoint_path}: the checkpoint's run facts are damaged ({exc!r})") from None
        if problems:
            raise CheckpointError(f"cannot resume from {self.checkpoint_path}: {'; '.join(problems)}. "
                                  "Run without --resume to start over.")

    def _scene_changes(self) -> str:
        """' (key: old -> new, ...)' between the scene text recorded with the run and this run's."""
        try:
            header = json.loads((self.states_path / "header.json").read_text(encoding="utf-8"))
            from .scene.errors import scene_changes
            changes = scene_changes(str(header["scene"]), str(header.get("scene_format", "toml")),
                                    str(self.metadata["scene"]), str(self.metadata.get("scene_format", "toml")))
        except Exception:  # noqa: BLE001 - no recorded scene: nothing more to say
            return ""
        return f" ({'; '.join(changes)})" if changes else ""

    @contextlib.contextmanager
    def catching_sigint(self):
        """Inside this block Ctrl-C (SIGINT) asks the run to stop at the next step boundary; a
        second Ctrl-C raises KeyboardInterrupt. Nested uses install nothing more; only the main
        thread can catch signals (elsewhere, and with ``handle_sigint=False``, this does nothing).
        """
        if (self._sigint_depth or not self.handle_sigint
                or threading.current_thread() is not threading.main_thread()):
            self._sigint_depth += 1
            try:
                yield self
            finally:
                self._sigint_depth -= 1
            return

        def handler(signum, frame):
            if self._stop_requested:
                raise KeyboardInterrupt
            self._stop_requested = True

        previous = signal.signal(signal.SIGINT, handler)
        self._sigint_depth += 1
        try:
            yield self
        finally:
            self._sigint_depth -= 1
            signal.signal(signal.SIGINT, previous)

    @property
    def stop_requested(self) -> bool:
        """True once Ctrl-C (or `request_stop`) asked the run to stop."""
        return self._stop_requested


def model_file_arrays(world: World) -> dict[str, np.ndarray]:
    """What `Run` writes to the state directory's ``model.npz`` (``States.model``).

    - the shape table (when the world has one): ``shape_type``, ``shape_body``, ``shape_source``
      (S,) int32, ``shape_local_pose (S, 7)``, ``shape_params (S, 4)``, ``shape_vert_start`` /
      ``shape_vert_count (S,) int32`` into ``geom_vertices (V, 3)``, ``shape_tri_start`` /
      ``shape_tri_count (S,) int32`` into ``geom_triangles (T, 3) int32`` (rows of geom_vertices:
      the outward hull of a convex hull, a mesh's triangles, a heightfield's grid cells), and
      ``body_type``, ``body_source (B,) int32``, ``body_com_pose (B, 7)``, and ``shape_color (S, 3)
      float32`` (sRGB in 0..1, NaN for the default colour) when the scene gives bodies a ``color``;
    - ``spring_pairs (P, 2) int64``: global particle indices of every Springs force's pairs;
    - ``surface_triangles (T, 3) int64``: global particle indices of the groups' ``triangles=``;
    - ``vehicle/<k>/wheel_radius (W,)`` m of each ray-cast vehicle's wheels (their per-frame
      ``vehicle/<k>/wheel_pose (W, 7)`` is recorded with the frames);
    - ``fluid/<name>/<key>``: each fluid's ``static_arrays()``.
    """
    from .geometry import shapes as S
    out: dict[str, np.ndarray] = {}
    m = world.model
    if m is not None:
        ns = m.shape_count
        out["shape_type"] = np.asarray(m.shape_type, np.int32)
        out["shape_body"] = np.asarray(m.shape_body, np.int32)
        out["shape_source"] = np.asarray(getattr(m, "shape_source", np.full(ns, -1)), np.int32)
        out["shape_local_pose"] = np.asarray(m.shape_local_pose, np.float64)
        out["shape_params"] = np.asarray(m.shape_params, np.float64)
        out["shape_vert_start"] = np.asarray(m.shape_vert_start, np.int32)
        out["shape_vert_count"] = np.asarray(m.shape_vert_count, np.int32)
        out["geom_vertices"] = np.asarray(m.geom_vertices, np.float64).reshape(-1, 3)
        out["body_type"] = np.asarray(m.body_type, np.int32)
        out["body_source"] = np.asarray(getattr(m, "body_source", np.full(m.body_count, -1)), np.int32)
        out["body_com_pose"] = np.asarray(m.body_com_pose, np.float64).reshape(-1, 7)
        tri_start, tri_count, tris = np.zeros(ns, np.int32), np.zeros(ns, np.int32), []
        total = 0
        for si in range(ns):
            t, v0, nv = int(m.shape_type[si]), int(m.shape_vert_start[si]), int(m.shape_vert_count[si])
            if t == S.CONVEX_HULL:
                from scipy.spatial import ConvexHull
                pts = m.geom_vertices[v0:v0 + nv]
                faces = ConvexHull(pts).simplices.astype(np.int64)
                a, b, c = pts[faces[:, 0]], pts[faces[:, 1]], pts[faces[:, 2]]
                flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - pts.mean(axis=0)) < 0
                faces[flip] = faces[flip][:, ::-1]
                local = faces
            elif t == S.TRIANGLE_MESH:
                local = np.arange(nv, dtype=np.int64).reshape(-1, 3)
            elif t == S.HEIGHTFIELD:
                nx, ny = int(m.shape_params[si, 0]), int(m.shape_params[si, 1])
                i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
                p00 = (i * ny + j).ravel()
                p10, p01, p11 = p00 + ny, p00 + 1, p00 + ny + 1
                local = np.concatenate([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)])
            else:
                continue
            tri_start[si], tri_count[si] = total, len(local)
            tris.append(local + v0)
            total += len(local)
        out["shape_tri_start"], out["shape_tri_count"] = tri_start, tri_count
        out["geom_triangles"] = (np.concatenate(tris) if tris else np.zeros((0, 3))).astype(np.int32)
        colors = getattr(getattr(world, "rigid_scene", None), "shape_colors", None)
        if colors is not None and np.isfinite(colors).any():
            # The scene's `color` of each body's shapes (rows the colliders appended: NaN = default).
            shape_color = np.full((ns, 3), np.nan, np.float32)
            shape_color[:min(ns, len(colors))] = np.asarray(colors, np.float32)[:ns]
            out["shape_color"] = shape_color
    pairs, surfaces = [], []
    for g in world.groups:
        for force in getattr(g.system, "forces", ()):
            p = getattr(force, "pairs", None)
            if type(force).__name__ == "Springs" and p is not None:
                pairs.append(np.asarray(p, np.int64) + g.start)
        if getattr(g, "triangles", None) is not None:
            surfaces.append(g.triangles + g.start)
    if pairs:
        out["spring_pairs"] = np.concatenate(pairs).reshape(-1, 2)
    for k, vehicle in enumerate(world.vehicles()):
        out[f"vehicle/{k}/wheel_radius"] = np.array([wh.radius for wh in vehicle.wheels], np.float64)
    if surfaces:
        out["surface_triangles"] = np.concatenate(surfaces).reshape(-1, 3)
    for name, fluid in world.fluids.items():
        for key, value in fluid.static_arrays().items():
            out[f"fluid/{name}/{key}"] = np.asarray(value)
    return out


def fingerprint(text: str) -> str:
    """A short hash of a canonical description of a scene's physics."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]
