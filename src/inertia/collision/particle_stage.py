"""The particle collision stage: colliders, resting contact and particle-particle contact.

``system.add_collider(collider, restitution=0.5, friction=0.0)`` attaches a collider;
``system.collision_mode = "a_priori" | "a_posteriori"`` picks continuous or discrete detection;
``system.self_collisions = True`` makes particles with a radius collide with each other. The
system delegates to ``attach_collider``, ``set_collision_mode`` and ``set_self_collisions``
here; the per-system data lives on ``system._collision`` (a ``ParticleCollisionData``).

Shape-table rows
----------------
In a ``World`` with a Model, the table's body and world rows are packed into the same kernel
arrays after the system's own colliders (``ParticleCollisionData.add_body_shapes``: each row a
``collision.shapes.BodyShape``, its geometry in its body's frame). Rows of dynamic and kinematic
bodies are moving colliders whose ``pose0``/``pose1`` the world writes from the bodies' poses
before and after the rigid stage (``update_poses`` leaves them alone), with the body's velocity
``body_qd`` after the rigid step in columns 12:18 (flag ``particle_kernels.BODY_VELOCITY``): a
particle touching such a row takes the body's material velocity v + w x (x - c) where it ends
the substep (not the pose difference, which is a chord: low by (w h)^2 / 24 in speed), and a
particle resting on it in a fused step is carried by the chord of the material point under it
(rotation keeps its distance to the axis); rows on body -1 and on static bodies are static
colliders in world coordinates, and a world whose rows are all static keeps the fused
integrator path (``can_fuse``). With dynamic bodies the world sets
``data.coupling`` (``inertia.dynamics.particle_coupling.ParticleBodyCoupling``): the force filter
and ``end_step`` then hand it the forces the filter cancelled and the state before and after the
collision pass, from which it gathers the impulses that go back into the bodies. A lone system's
colliders stay packed from the collider objects themselves (2-D colliders, unbaked SDFs and the
bit-exact packing of existing scenes have no 3-D table row to come from).

One step (``Simulation.step``), with what each part reads and writes
-------------------------------------------------------------------
begin_step (before the integrator)
    save      state -> ``state0`` (x0, v0: the step's start, for continuous detection); skipped
              when the previous end_step already wrote it and nobody changed the state since
              (``state_revision``); ``active`` -> ``active0``
    pose      motions -> ``pose0`` (t), ``pose1`` (t + dt) of the moving colliders
    start     (first step after a collider is added) particles inside a collider are pushed out,
              with a warning saying how many
    classify  x, v -> ``rest_k``, ``rest_n``, ``rest_u``: particles resting on a surface (within
              ``distance_tolerance`` of it, relative normal speed <= ``rest_speed``); reused from the
              previous end_step when nothing else changed the state and no collider moves
    fuse      when the integrator announces its fused method (``integrator_fused_step``: rk4's
              ``fused_rk4``, semi-implicit Euler's ``kick_drift``), all forces are affine and the
              colliders are static and compiled (no moving collider, no unbaked SDF, no
              self-collisions), nothing is saved: the integrator's kernel runs the collision pass
              per particle with the step's start in registers (``particle_kernels.step_and_collide``,
              the same bits as the separate pass below, one pass over memory instead of three);
              in a World that wants Contacts rows (``coupling`` set) the kernel's near loop also
              credits each particle's change over the pass to its contact slot of a table row
              (``pass_record``), as ``coupling.after_collisions`` does after the separate pass
              and the coupling lists the kernel's near particles that took a slot or rest on a
              table row (``ParticleBodyCoupling.note_near``): the rows the world fills
integrator
    non-fused steps: the force filter ``RestingContactFilter`` runs in every force evaluation:
    for resting particles it cancels the applied force into the surface and applies Coulomb
    friction (static / kinetic); writes ``load``, ``static_ok``. Fused steps (``fused_rk4``,
    ``kick_drift``, all forces affine) skip it (``fusable = True``) and end_step applies the
    same physics to the step's motion (``particle_kernels._resting_motion``).
end_step (after the integrator)
    fused     the kernel's counts; the state is known finite when its pass found no NaN/inf
              (``system.finite_revision``: ``Simulation.step`` then skips its own check)
    collide   x0, v0, x, v -> x, v (``particle_kernels.collide_particles``): a cheap distance
              bound skips particles whose path cannot reach any collider, and particles resting
              on a static plane take an inline path; the others get resting clean-up, a-priori
              time of impact and response (or a-posteriori projection and response), the
              end-of-step projection, and the next classification
    callables unbaked ``SDF`` colliders, in NumPy
    pairs     (self_collisions) broad phase (``broadphase``), shock-propagated Gauss-Seidel pair
              impulses and overlap projection by colour batches, then classification
    the system's ``state_modified()`` is called when anything changed.

Parameters (``configure_contacts``)
-----------------------------------
distance_tolerance : 1e-6 m default (1e-7..1e-4): contact distance tolerance; scale with the scene.
rest_speed : 1e-6 m/s default: relative speeds below this are "at rest" (plus twice what the
    step's forces add, for impacts: slower impacts are inelastic so bouncing ends).
self_restitution, self_friction : 0.5, 0.0 default: particle-particle restitution and friction.
iterations : 4 default (8-16 for loose piles of thousands): relaxation passes of the pair solver.
max_substeps : 4 default: a-priori impacts resolved per particle per step (corners need 2-3).

References
----------
- Witkin, A. & Baraff, D. (2001), *Physically Based Modeling*, SIGGRAPH course notes,
  "Particle System Dynamics": detection ``(X - P).N < eps`` and ``N.V < 0``, response
  ``v' = v_T - e v_N``, resting contact by cancelling the normal force.
- Bridson, R., Fedkiw, R. & Anderson, J. (2002), "Robust treatment of collisions, contact and
  friction for cloth animation", SIGGRAPH: friction bounded by the normal impulse.
- Guendelman, E., Bridson, R. & Fedkiw, R. (2003), "Nonconvex rigid bodies with stacking",
  SIGGRAPH: separate velocity and position passes, restitution off for resting contacts,
  shock propagation (supported bodies act as infinitely heavy for those resting on them).
- Mirtich, B. (1996), PhD thesis (conservative advancement); Redon et al. (2002) (continuous
  collision detection on the interpolated straight path).

Impacts on the step's path (issue 8)
------------------------------------
The path of a step is the parabola with the step's average acceleration through the
integrator's start and end points (exact for constant forces with every integrator; see
``toi.path_fraction``). The impact time is a fraction of the time step on that path (not of
the chord); a real bounce leaves under the applied acceleration, and only an impact slower than
the resting speed (inelastic) holds the particle and cancels the acceleration into the surface
for the rest of the step. The velocity the integrator stores can lag the path's slope (by
-a h / 2 for symplectic Euler, + a h / 2 for explicit Euler, 0 for the second-order methods
and rk4): responses act on the path's velocity and the lag is handed on, so the apex heights of
a bouncing ball are e^(2n) h0 with every integrator. A posteriori, the impact time on the path
comes from the signed distances at the step's start and end, and the normal velocity gained
after it (inside the collider) is removed before the response.

Limitations
-----------
- The continuous (a-priori) search follows the straight chord of each step to find contacts
  (the parabolic path lies within |a| dt^2 / 8 of it); impact times are exact for planes and
  container walls, second order in that deviation for curved surfaces.
- A posteriori, the time a particle spent inside a collider is lost (it restarts from the
  surface with the response velocity): up to one step per impact.
- Self-collisions are discrete (end-of-step overlap): particles moving more than about their
  radius per step can pass through each other.
- A particle rests on one collider at a time (the force filter uses that normal); in corners
  the other walls act through the end-of-step projection.
- Unbaked ``SDF`` colliders are handled in NumPy after the compiled pass with the kernels'
  parabolic path and response (``_collide_callables``), but one impact per collider per step,
  no resting-contact filter (a resting particle is projected back each step) and temporary
  arrays each step; bake them for full treatment.
- The pair solver is iterative: piles of thousands settle over a few tenths of a second and
  keep compacting slowly (particles creeping into gaps at cm/s); supported contacts do not
  conserve momentum (the ground takes it), free pairs do.
- With the fused integrator path the resting contact uses the step's average acceleration
  (exact for constant forces; first order for forces that vary within the step).
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from . import broadphase as bp
from . import distance as _d
from . import particle_kernels as pk
from .shapes import BodyShape, Collider

__all__ = ["attach_collider", "set_collision_mode", "set_self_collisions", "configure_contacts",
           "ParticleCollisionData", "ParticleCollisionStage", "RestingContactFilter", "COLLISION_MODES"]

COLLISION_MODES = ("a_priori", "a_posteriori")
# The kernels come from ``particle_kernels.kernels_for`` (compiled for the collider kinds in use;
# serial twin or parallel build by ``inertia._jit``'s size dispatch; the pair solver's colour
# batches by the number of pairs).


def _user_stacklevel() -> int:
    """stacklevel that points a warning at the first caller outside the inertia package."""
    import os
    import sys
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


class ParticleCollisionData:
    """Collision data of one particle system (``system._collision``).

    Model (changes only when colliders are added): ``colliders``, packed ``cint``, ``cmat``,
    ``cf``, ``ci``, ``ref`` (see ``particle_kernels``). Options: ``mode``, ``self_collisions``,
    ``distance_tolerance``, ``rest_speed``, ``self_restitution``, ``self_friction``,
    ``iterations``, ``max_substeps``.

    Step state (preallocated; N particles, D dims):
    state0 (2 N D,)      copy of the state at the start of the step (begin_step); x0, v0 views
    pose0, pose1 (K, 18) collider poses [p, R] at t and t + dt (begin_step); body rows also
                         carry their body's velocity [w, v] in columns 12:18 (written by the world)
    rest_k (N,) int64, rest_n (N, 3), rest_u (N, 3)   resting contacts (classify / end_step)
    load (N,), static_ok (N,) bool                    written by the force filter
    dv_step (N, 3)       velocity change of the step before responses (self-collisions)
    profile              cumulative seconds per part: save, classify, collide, callables,
                         broad_phase, pair_solve, coupling (gathering impulses for bodies); ``steps``
    """

    def __init__(self):
        self.colliders: list[Collider] = []
        self.restitution: list[float] = []
        self.friction: list[float] = []
        self.mode = "a_priori"
        self.self_collisions = False
        self.distance_tolerance = 1e-6
        self.rest_speed = 1e-6
        self.self_restitution = 0.5
        self.self_friction = 0.0
        self.iterations = 4
        self.max_substeps = 4
        self.max_iterations = 32
        self.check_start = False
        self.profile = dict.fromkeys(("save", "classify", "collide", "callables", "broad_phase",
                                      "pair_solve", "coupling"), 0.0)
        self.profile["steps"] = 0
        self.pair_count = 0
        self.color_count = 0
        self.resting_count = 0
        self._shape = None
        self._valid_revision = None
        self._saved_revision = None
        self._restored = False
        self._pending_contacts = None
        self.filter_ran = False
        # the fused step (``step_and_collide``): the integrator's fused method that will run the
        # collision pass inside its own kernel this step ("kick_drift", "rk4" or None; set by
        # begin_step), and that kernel's (changed, resting, finite) for end_step
        self.fused_step = None
        self.fused_armed = False  # between that begin_step and the integrator's kernel
        self.fused_result = None
        # two-way coupling with bodies (``inertia.dynamics.particle_coupling.ParticleBodyCoupling``,
        # set by the world): particle momentum changes go back into the bodies
        self.coupling = None
        self._no_record = None  # the fused step's placeholder ``PassRecord`` (nothing recorded)
        self._pack()

    # --- model -------------------------------------------------------------------------------
    def add(self, collider, restitution, friction):
        self.colliders.append(collider)
        self.restitution.append(restitution)
        self.friction.append(friction)
        self.check_start = True
        self._valid_revision = None
        self._pack()

    def _pack(self):
        k = len(self.colliders)
        kernel = [c for c in self.colliders]
        self.cint = np.zeros((max(k, 1), 4), np.int64)
        self.cint[:, 0] = _d.CALLABLE  # the placeholder row (no colliders) is skipped by kernels
        self.cmat = np.zeros((max(k, 1), 2))
        self.ref = np.zeros((max(k, 1), 3))
        self.pose0 = np.zeros((max(k, 1), pk.POSE_COLUMNS))
        self.pose0[:, 3::4] = 1.0  # identity rotations
        self.pose1 = self.pose0.copy()
        cfs, cis, off, ioff = [], [], 0, 0
        for i, c in enumerate(kernel):
            flags = pk.MOVING if c.moving else 0
            if c.moving and getattr(c, "from_body", False):
                flags |= pk.BODY_VELOCITY  # the world writes the body's velocity into pose1[i, 12:18]
            self.cint[i] = (c.kind, flags, off, ioff)
            self.cmat[i] = (self.restitution[i], self.friction[i])
            self.ref[i] = c._ref
            self.pose0[i, :3] = c._ref
            self.pose1[i, :3] = c._ref
            cfs.append(c._cf)
            cis.append(c._ci)
            off += c._cf.size
            ioff += c._ci.size
        self.cnear = np.zeros((max(k, 1), 5))
        self.cnear[:, 0] = pk.NEAR_NEVER
        for i, c in enumerate(kernel):
            self.cnear[i] = _near_bound(c, self.cint[i, 2])
        self.cf = np.concatenate(cfs) if cfs else np.zeros(1)
        self.ci = np.concatenate(cis) if cis else np.zeros(1, np.int64)
        # the rows of the fused step's cheap far test (planes and container walls, bounding balls)
        self.far_planes, self.far_balls = pk.far_slots(self.cnear, self.cf)
        self.callables = [(i, c) for i, c in enumerate(self.colliders) if c.kind == _d.CALLABLE]
        if getattr(self, "coupling", None) is not None:     # rows added later: re-map them to bodies
            self.coupling.entry_body = self.entry_bodies(self._model)
            self.coupling.entry_shape = self.entry_shapes()
        self.any_moving = any(c.moving for c in self.colliders)
        self.any_kernel = any(c.kind != _d.CALLABLE for c in self.colliders)
        # the kernels compiled for these collider kinds: looked up once per change of the table,
        # not per call (the lookup reads every row's kind)
        self.kernels = pk.kernels_for(self.cint)

    def can_fuse(self) -> bool:
        """True when the collision pass can run inside the integrator's fused kernel: only
        static compiled colliders (no moving ones, no unbaked SDFs) and no self-collisions.

        In a World whose bodies do not move (static bodies and body -1 rows only: every row is a
        static collider) the coupling has no body to push, so the fused path stays on; its near
        loop writes the coupling's contact slots itself (``pass_record``), so the world's
        Contacts buffer gets the same rows as after the separate pass (impacts and resting
        contacts, with the impulses). Rows of dynamic or kinematic bodies are moving colliders
        (``any_moving``), which always take the separate pass."""
        return self.any_kernel and not self.any_moving and not self.callables and not self.self_collisions

    def run_fused(self, system, affine, rk4, dt):
        """The integrator's fused step with the collision pass (``particle_kernels.step_and_collide``)."""
        g, force, damping = affine
        self.fused_armed = False
        tic = time.perf_counter()
        rec, record = self.pass_record()
        self.fused_result = self.kernels.step_and_collide(
            system.x, system.v, system.radius, system.inv_mass, system.active, g, force, damping, rk4,
            self.cint, self.cnear, self.cmat, self.cf, self.ci, self.far_planes, self.far_balls, self.pose1,
            self.ref, self.rest_k,
            self.rest_n, self.rest_u, self.load, self.static_ok, self.near_list, self.chunk_counts, rec, record,
            dt, self.distance_tolerance,
            self.rest_speed, self.mode == "a_priori", self.max_substeps, self.max_iterations)
        if record and self.coupling is not None:  # the particles that may have rows: the near ones only
            self.coupling.note_near(self.near_list, pk.STEP_CHUNK, self.rest_k)
        self.profile["collide"] += time.perf_counter() - tic

    def pass_record(self):
        """(``particle_kernels.PassRecord``, record) for the fused step: the coupling's contact slots
        when a World wants this group's Contacts rows (``coupling`` set: decided when the group is
        attached), else a placeholder and False (the pure particle path records nothing)."""
        c = self.coupling
        if c is None:
            if self._no_record is None:
                self._no_record = pk.no_record(self.cint.shape[0])
            return self._no_record, False
        return pk.PassRecord(c.slot_entry, c.slot_impulse, c.entry_body, c.entry_shape,
                             max(c.tol, self.distance_tolerance)), True

    def update_poses(self, t, dt):
        """pose0 / pose1 of the moving colliders at t and t + dt (rows of body shapes are written by
        the world from the bodies' poses, see ``set_body_poses``)."""
        if not self.any_moving:
            return
        for i, c in enumerate(self.colliders):
            if c.moving and not getattr(c, "from_body", False):
                self.pose0[i, :12] = c._packed_pose(t)
                self.pose1[i, :12] = c._packed_pose(t + dt)

    # --- shape-table rows on bodies ----------------------------------------------------------
    def add_body_shapes(self, model, shapes, state=None, cache=None):
        """Append rows ``shapes`` of ``model``'s shape table as colliders (``BodyShape``), with the
        rows' restitution and friction. Returns their entry indices (rows of cint, pose0, pose1).
        ``cache``: a dict shared by the groups of one world (a hull or mesh row is baked once)."""
        first = len(self.colliders)
        self._model = model
        body_q = None if state is None else state.body_q
        cache = {} if cache is None else cache
        for s in shapes:
            b = int(model.shape_body[s])
            if int(s) not in cache:
                cache[int(s)] = BodyShape(model, int(s), None if (body_q is None or b < 0) else body_q[b])
            shape = cache[int(s)]
            if getattr(shape, "unsupported", False):
                continue
            self.colliders.append(shape)
            self.restitution.append(float(min(max(model.shape_restitution[s], 0.0), 1.0)))
            self.friction.append(float(model.shape_friction[s]))
        self.check_start = True
        self._valid_revision = None
        self._pack()
        return np.arange(first, len(self.colliders))

    def shape_table(self):
        """The system's own colliders as a shape table (`inertia.model.with_colliders`, 3-D colliders;
        None in 2-D): what a lone system collides with, in the World's row format."""
        from ..model import with_colliders
        own = [c for c in self.colliders if not getattr(c, "from_body", False) and c.dim == 3]
        return with_colliders(None, own) if own else None

    def entry_bodies(self, model) -> np.ndarray:
        """(K,) int64: the dynamic body each packed collider row belongs to, -1 for the others."""
        out = np.full(self.cint.shape[0], -1, np.int64)
        for i, c in enumerate(self.colliders):
            if getattr(c, "from_body", False) and c.body >= 0 and int(model.body_type[c.body]) == 0:
                out[i] = c.body
        return out

    def entry_shapes(self) -> np.ndarray:
        """(K,) int64: the shape-table row of each packed collider row, -1 for the system's own colliders."""
        out = np.full(self.cint.shape[0], -1, np.int64)
        for i, c in enumerate(self.colliders):
            if getattr(c, "from_body", False):
                out[i] = c.shape
        return out

    # --- buffers -----------------------------------------------------------------------------
    def ensure_buffers(self, system):
        n, dim = system.x.shape
        shape = (n, dim, self.self_collisions)
        if self._shape == shape:
            return
        if self._shape is None or self._shape[:2] != (n, dim):
            self.state0 = np.empty_like(system.state)
            self.x0 = self.state0[:n * dim].reshape(n, dim)
            self.v0 = self.state0[n * dim:].reshape(n, dim)
            self.rest_k = np.full(n, -1, np.int32)
            self.active0 = np.zeros(n, bool)
            self.rest_n = np.zeros((n, 3))
            self.rest_u = np.zeros((n, 3))
            self.load = np.zeros(n)
            self.static_ok = np.zeros(n, bool)
            self.near_list = np.empty(n, np.int64)  # scratch of the fused step (step_and_collide)
            self.chunk_counts = np.zeros(((n + pk.STEP_CHUNK - 1) // pk.STEP_CHUNK, 3), np.int64)  # its counts
            self._valid_revision = None
        if self.self_collisions:
            self.table_size = bp.table_size_for(n)
            self.dense_capacity = max(bp.DENSE_CELLS_PER_PARTICLE * n, 4096)
            self.dv_step = np.zeros((n, 3))
            self.cell_key = np.empty(n, np.int64)
            self.bucket = np.empty(n, np.int64)
            self.bucket_start = np.empty(max(self.table_size, self.dense_capacity) + 1, np.int64)
            self.order = np.empty(n, np.int64)
            self.pair_counts = np.empty(n, np.int64)
            self.pair_start = np.empty(n + 1, np.int64)
            self.box_partial = np.empty((bp.BOX_CHUNKS, 6))
            self.box_lo, self.box_hi = np.zeros(3), np.zeros(3)
            self.grid_dims = np.ones(3, np.int64)
            self._alloc_pairs(max(64, 8 * n))
            self.used_colors = np.zeros(n, np.uint64)
            self.color_start = np.zeros(bp.MAX_COLORS + 1, np.int64)
            self.color_cursor = np.zeros(bp.MAX_COLORS, np.int64)
            self.in_pair = np.zeros(n, np.int8)
            self.support = np.zeros(n, bool)
            # sorted-space copies (see broadphase)
            dim = system.x.shape[1]
            self.xs, self.vs, self.dvs = np.empty((n, dim)), np.empty((n, dim)), np.empty((n, 3))
            self.rs, self.ims = np.empty(n), np.empty(n)
            self.ks, self.sups = np.empty(n, np.int64), np.zeros(n, bool)
        else:
            self.dv_step = np.zeros((1, 3))
        self._shape = shape
        self.apply_pending_contacts()

    def apply_pending_contacts(self):
        """Install resting contacts restored by ``set_state`` (once the buffers exist)."""
        if self._pending_contacts is None:
            return
        k, nrm, u, support = self._pending_contacts
        if k.shape == self.rest_k.shape:
            self.rest_k[:], self.rest_n[:], self.rest_u[:] = k, nrm, u
            if support is not None and self.self_collisions:
                self.support[:] = support
            self._restored = True
        self._pending_contacts = None

    def _alloc_pairs(self, capacity):
        self.pair_i = np.empty(capacity, np.int64)
        self.pair_j = np.empty(capacity, np.int64)
        self.pair_color = np.empty(capacity, np.int64)
        self.color_order = np.empty(capacity, np.int64)


def _near_bound(c, offset):
    """Row of ``cnear`` for collider c (see ``particle_kernels``): a cheap lower bound of its
    distance, exact for planes and containers, a bounding sphere for the bounded shapes."""
    dim = c.dim
    if c.moving:
        return (pk.NEAR_ALWAYS, 0, 0, 0, 0)
    f = c._cf
    if c.kind == _d.PLANE:
        return (pk.NEAR_PLANE, f[0], f[1], f[2], f[3])
    if c.kind == _d.CONTAINER:
        return (pk.NEAR_PLANES, offset, c._ci[0], 0, 0)
    if c.kind == _d.SPHERE:
        return (pk.NEAR_BALL, f[0], f[1], f[2], f[3])
    if c.kind == _d.BOX:
        return (pk.NEAR_BALL, f[0], f[1], f[2], float(np.linalg.norm(f[12:12 + dim])))
    if c.kind == _d.CAPSULE:
        a, b = f[0:3], f[3:6]
        return (pk.NEAR_BALL, *(0.5 * (a + b)), 0.5 * float(np.linalg.norm(b - a)) + f[6])
    if c.kind == _d.CYLINDER:
        return (pk.NEAR_BALL, f[0], f[1], f[2], float(np.hypot(f[6], f[7])))
    if c.kind == _d.GRID:
        lo, hi = f[_d.G_BMIN:_d.G_BMIN + 3], f[_d.G_BMAX:_d.G_BMAX + 3]
        centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        return (pk.NEAR_BALL, *centre, float(np.linalg.norm(half[:dim])) + f[_d.G_THICK])
    return (pk.NEAR_NEVER, 0, 0, 0, 0)


class RestingContactFilter:
    """Force filter for resting contact (see ``particle_kernels.resting_filter``).

    ``active`` is False while no particle rests on a collider (the filter is then a no-op).
    ``fusable`` is True: when a fused integrator step skips force filters, the collision stage
    applies the same resting-contact physics to the step's motion afterwards (see
    ``particle_kernels._resting_motion``), so the fused paths may stay on.
    """

    fusable = True

    def __init__(self, system, data: ParticleCollisionData):
        self.system, self.data = system, data

    @property
    def active(self) -> bool:
        return self.data.resting_count > 0

    def apply(self, x, v, t, f):
        d = self.data
        d.filter_ran = True
        if d.resting_count == 0 or d._shape is None:
            return
        if d.coupling is not None:
            d.coupling.before_filter(f)
        d.kernels.resting_filter(v, f, self.system.inv_mass, d.rest_k, d.rest_n, d.rest_u, d.cmat, d.rest_speed, d.load,
               d.static_ok)
        if d.coupling is not None:
            d.coupling.after_filter(x, f, d)


class ParticleCollisionStage:
    """Step stage that detects and responds to collisions (see the module docstring)."""

    name = "collisions"
    stage_order = 50

    def __init__(self, data: ParticleCollisionData):
        self.data = data

    # --- step --------------------------------------------------------------------------------
    def begin_step(self, system, t, dt):
        d = self.data
        if not d.colliders and not d.self_collisions:
            return
        d.ensure_buffers(system)
        d.filter_ran = False
        d.fused_result = None
        tic = time.perf_counter()
        # the collision pass runs inside the integrator's fused kernel when it can: then the
        # kernel keeps the step's start in registers and nothing is saved here
        fused = getattr(system, "integrator_fused_step", None)
        if fused is not None and d.can_fuse() and system._affine_terms() is not None:
            d.fused_step = fused
            d.fused_armed = True
            d._saved_revision = None
        else:
            d.fused_step = None
            d.fused_armed = False
            # the step's start: already written by the previous end_step unless someone changed it
            if d._saved_revision != system.state_revision:
                d.kernels.copy_into(system.state, d.state0)
            np.copyto(d.active0, system.active)
        d.update_poses(t, dt)
        toc = time.perf_counter()
        d.profile["save"] += toc - tic
        if d.check_start and d.colliders:
            self._push_out_start(system)
        # resting contacts at the start of the step (reuse end_step's when still valid)
        if d.any_kernel and (d.any_moving or (d._valid_revision != system.state_revision and not d._restored)):
            d.resting_count = d.kernels.classify_contacts(
                system.x, system.v, system.radius, system.inv_mass, system.active, d.cint, d.cf, d.ci,
                d.pose0, d.pose0, d.pose1, d.ref, d.rest_k, d.rest_n, d.rest_u, dt,
                d.distance_tolerance, d.rest_speed)
        d._restored = False
        d.profile["classify"] += time.perf_counter() - toc

    def end_step(self, system, t, dt):
        d = self.data
        if not d.colliders and not d.self_collisions:
            return
        if d.fused_step is not None:
            self._end_fused_step(system)
            return
        x, v = system.x, system.v
        changed = 0
        finite = True
        tic = time.perf_counter()
        coupling = d.coupling
        if coupling is not None:
            coupling.before_collisions(system)
        # x0, v0 can be refreshed by the kernel itself when nothing runs after it
        save_next = not d.self_collisions and not d.callables
        if d.any_kernel or d.self_collisions:
            classify = not d.self_collisions
            changed, resting, finite = d.kernels.collide_particles(
                x, v, d.x0, d.v0, system.radius, system.inv_mass, system.active, d.active0, d.cint,
                d.cnear, d.cmat, d.cf, d.ci, d.pose0, d.pose1, d.ref, d.rest_k, d.rest_n, d.rest_u, d.load,
                d.static_ok, d.dv_step, dt, d.distance_tolerance, d.rest_speed, d.mode == "a_priori",
                d.max_substeps, d.max_iterations, classify, d.self_collisions,
                None if d.filter_ran else True, save_next)
            if classify:
                d.resting_count = resting
        else:
            save_next = False
        toc = time.perf_counter()
        d.profile["collide"] += toc - tic
        if d.callables:
            changed += _collide_callables(d, system, t, dt)
            d.profile["callables"] += time.perf_counter() - toc
        if d.self_collisions:
            changed += self._self_collide(system, dt)
            finite = False  # not tracked by the pair solver: the simulation checks the state
        if coupling is not None:
            toc = time.perf_counter()
            coupling.after_collisions(system, d, dt)
            d.profile["coupling"] += time.perf_counter() - toc
        if changed:
            # the compiled pass reports whether what it wrote is finite (callables: not tracked)
            system.state_modified(finite=finite and not d.callables)
        d._valid_revision = system.state_revision
        d._saved_revision = system.state_revision if save_next else None
        d.profile["steps"] += 1

    def _end_fused_step(self, system):
        # the integrator's kernel ran the collision pass (``run_fused``)
        d = self.data
        if d.fused_result is None:
            raise RuntimeError(f"internal error: the integrator did not take its fused step "
                               f"{d.fused_step!r} announced to the collision stage")
        changed, resting, finite = d.fused_result
        d.fused_result = None
        d.resting_count = resting
        if changed:
            system.state_modified()
        # the kernel checked every value of the state it read and wrote
        system.finite_revision = system.state_revision if finite else None
        d._valid_revision = system.state_revision
        d._saved_revision = None
        d.profile["steps"] += 1

    # --- parts -------------------------------------------------------------------------------
    def _push_out_start(self, system):
        d = self.data
        d.check_start = False
        if not system.active.any():  # nothing to push out (e.g. an emitter's empty pool): no kernel
            return
        inside = np.zeros(d.cint.shape[0], np.int64)
        moved = d.kernels.push_out(system.x, system.v, system.radius, system.inv_mass, system.active, d.cint, d.cf, d.ci,
                       d.pose0, d.ref, d.distance_tolerance, inside)
        if moved:
            names = ", ".join(f"{type(c).__name__} #{i}: {int(inside[i])}"
                              for i, c in enumerate(d.colliders) if inside[i])
            warnings.warn(f"{moved} particles start inside colliders ({names}); they were pushed out "
                          "onto the surface on the first step", stacklevel=_user_stacklevel())
            d.state0[:] = system.state
            system.state_modified()
            d._valid_revision = None

    def _self_collide(self, system, dt):
        d = self.data
        x, v, radius = system.x, system.v, system.radius
        tic = time.perf_counter()
        rmax = float(radius.max()) if radius.size else 0.0
        if rmax <= 0.0:
            d.pair_count = 0
            self._classify_end(system, dt)
            return 0
        cell = 2.0 * rmax + d.distance_tolerance
        inv_cell = 1.0 / cell
        margin = d.distance_tolerance
        n = x.shape[0]
        # a dense grid over the particles' box when it is small enough, else a spatial hash
        dense = bp.grid_layout(x, cell, d.box_partial, d.box_lo, d.box_hi, d.grid_dims, d.dense_capacity)
        mask = d.table_size - 1
        nbuckets = int(np.prod(d.grid_dims)) if dense else d.table_size
        d.grid_mode = "dense" if dense else "hash"
        grid = (inv_cell, d.box_lo, d.grid_dims, dense, mask)
        kernels = d.kernels
        kernels.bin_particles(x, radius, system.active, *grid, d.cell_key, d.bucket)
        ns = int(bp.counting_sort(d.bucket, nbuckets, d.bucket_start, d.order))
        # sorted space: the particles in cell order (see broadphase)
        gather, scatter = kernels.gather.pick(x.size), kernels.scatter.pick(x.size)
        order = d.order
        xs, rs, ks = d.xs[:ns], d.rs[:ns], d.ks[:ns]
        gather(order, ns, x, xs)
        gather(order, ns, radius, rs)
        if not dense:
            gather(order, ns, d.cell_key, ks)
        kernels.count_pairs.pick(x.size)(
            xs, rs, ks, *grid, d.bucket_start, ns, margin, d.pair_counts)
        total = int(bp.exclusive_scan(d.pair_counts, ns, d.pair_start))
        if total > d.pair_i.shape[0]:
            d._alloc_pairs(int(total * 1.5) + 64)
        kernels.fill_pairs.pick(x.size)(
            xs, rs, ks, *grid, d.bucket_start, ns, margin, d.pair_start, d.pair_i, d.pair_j)
        ncolors = int(bp.color_pairs(d.pair_i, d.pair_j, total, d.used_colors, d.pair_color,
                                     d.color_start, d.color_order, d.color_cursor))
        toc = time.perf_counter()
        d.profile["broad_phase"] += toc - tic
        d.pair_count, d.color_count = total, ncolors
        if total:
            vs, dvs, ims, sups, inp = d.vs[:ns], d.dvs[:ns], d.ims[:ns], d.sups[:ns], d.in_pair[:ns]
            gather(order, ns, v, vs)
            gather(order, ns, d.dv_step, dvs)
            gather(order, ns, system.inv_mass, ims)
            gather(order, ns, d.support, sups)
            inp[:] = 0
            # colour batches pay off when they are large; small pair sets run serially
            kernels.mark_pairs.pick(total)(d.pair_i, d.pair_j, d.color_start, d.color_order,
                                                         ncolors, inp)
            kernels.solve_pairs.pick(total)(
                xs, vs, ims, rs, dvs, d.pair_i, d.pair_j, d.color_start, d.color_order, ncolors, inp, sups,
                d.cint, d.cnear, d.cmat, d.cf, d.ci, d.pose0, d.pose1, d.ref, dt, d.self_restitution,
                d.self_friction, d.rest_speed, d.iterations)
            scatter(order, ns, xs, x)
            scatter(order, ns, vs, v)
            scatter(order, ns, sups, d.support)
        self._classify_end(system, dt)
        d.profile["pair_solve"] += time.perf_counter() - toc
        return total

    def _classify_end(self, system, dt):
        # resting contacts for the next step, after the pair solver moved the particles
        d = self.data
        if d.any_kernel:
            d.resting_count = d.kernels.classify_contacts(
                system.x, system.v, system.radius, system.inv_mass, system.active, d.cint, d.cf, d.ci, d.pose1,
                d.pose0, d.pose1, d.ref, d.rest_k, d.rest_n, d.rest_u, dt, d.distance_tolerance, d.rest_speed)

    # --- checkpoints -------------------------------------------------------------------------
    def get_state(self) -> dict:
        d = self.data
        state = {"check_start": d.check_start, "resting_count": d.resting_count}
        if d._shape is not None:
            state.update(rest_k=d.rest_k.copy(), rest_n=d.rest_n.copy(), rest_u=d.rest_u.copy())
            if d.self_collisions:
                state["support"] = d.support.copy()
        return state

    def set_state(self, state: dict) -> None:
        d = self.data
        d.check_start = bool(state["check_start"])
        d.resting_count = int(state["resting_count"])
        # the saved start-of-step copy belongs to another time: begin_step copies again
        d._saved_revision = None
        d._valid_revision = None
        if "rest_k" in state:
            d._pending_contacts = (state["rest_k"].copy(), state["rest_n"].copy(), state["rest_u"].copy(),
                                   state.get("support"))
            if d._shape is not None:
                d.apply_pending_contacts()


# --- NumPy path for unbaked SDF colliders ------------------------------------------------------
# The same response as the compiled kernels (``particle_kernels._full_path``), vectorised over the
# particles: the step's path is the parabola through the integrator's start and end points
# (p(t) = s + w t + a t^2 / 2, a = (v1 - v0) / h the step's average acceleration), the impact time
# is a fraction of the step on that path (``toi.path_fraction``), a real bounce leaves under
# gravity, a slow one is held (the acceleration into the surface and the integrator's lag along
# the normal are cancelled for the rest of the step), and the a-posteriori projection drops the
# velocity gained inside. Limitations: one impact per callable collider per step (the end
# projection catches the rest); the path starts from the step's start even when a compiled
# collider changed the particle earlier in the same step.
def _np_path_fraction(chord_in, accel_in, sigma):
    """Vectorised ``toi.path_fraction`` over (M,) arrays."""
    qa, qb, qc = accel_in, chord_in - accel_in, -chord_in * sigma
    straight = (chord_in >= 0.0) | (np.abs(qa) <= 1e-12 * np.abs(chord_in))
    disc = np.sqrt(np.maximum(qb * qb - 4.0 * qa * qc, 0.0))
    q = -0.5 * (qb + np.copysign(disc, qb))
    safe_qa = np.where(straight, 1.0, qa)
    r1 = q / safe_qa
    r2 = np.divide(qc, q, out=r1.copy(), where=q != 0.0)
    lo, hi = np.minimum(r1, r2), np.maximum(r1, r2)
    eps = 1e-12
    departing = (qc == 0.0) & (qb > 0.0)
    take_lo = (lo >= -eps) & (lo <= 1.0 + eps) & ~(departing & (lo <= eps))
    take_hi = (hi >= -eps) & (hi <= 1.0 + eps)
    tau = np.where(take_lo, np.clip(lo, 0.0, 1.0), np.where(take_hi, np.clip(hi, 0.0, 1.0), sigma))
    return np.where(straight, sigma, tau)


def _rowdot(a, b):
    return (a * b).sum(1)


def _collide_callables(d, system, t, dt):
    x, v = system.x, system.v
    dim = x.shape[1]
    idx = np.flatnonzero(system.active & (system.inv_mass > 0))
    if idx.size == 0:
        return 0
    changed = np.zeros(idx.size, bool)
    tol = d.distance_tolerance
    r = system.radius[idx]
    # the integrator's step: start (s, sv), end (e, ev), average acceleration, path slope, lag
    ex, ev = x[idx], v[idx]
    started = d.active0[idx][:, None]
    sx = np.where(started, d.x0[idx], ex)
    sv = np.where(started, d.v0[idx], ev)
    acc = (ev - sv) / dt
    lag = np.where(started, sv - ((ex - sx) / dt - 0.5 * acc * dt), 0.0)
    ws = sv - lag              # the path's velocity at the segment start
    pv = ev - lag              # ... and at the end
    s_start = np.zeros(idx.size)  # the segment start as a fraction of the step
    collider_poses = []
    for k, col in d.callables:
        p0, r0 = col.pose(t)
        p1, r1 = col.pose(t + dt)
        ref = col._ref[:dim]
        rot0, rot1 = r0[:dim, :dim], r1[:dim, :dim]

        def to_rest(points, p, rot, ref=ref):
            return ref + (points - p[:dim]) @ rot

        def to_world(points, p, rot, ref=ref):
            return p[:dim] + (points - ref) @ rot.T

        collider_poses.append((k, col, p0, rot0, p1, rot1, to_rest, to_world))
        if d.mode != "a_priori":
            continue
        e_k, mu = d.restitution[k], d.friction[k]
        # the chord of the rest of the step in the rest frame (start through the interpolated pose)
        a0, a1 = to_rest(sx, p0, rot0), to_rest(sx, p1, rot1)
        ls = a0 + s_start[:, None] * (a1 - a0)
        le = to_rest(ex, p1, rot1)
        f0 = col.evaluate_rest(ls)[0] - r
        f1 = col.evaluate_rest(le)[0] - r
        length = np.linalg.norm(le - ls, axis=1)
        cand = np.flatnonzero((np.abs(f0) + np.abs(f1) - length <= 2 * tol) & (f0 > tol) & (length > 0))
        if not cand.size:
            continue
        # conservative advancement along the chord (vectorised over the candidates)
        sigma = np.zeros(cand.size)
        f = f0[cand].copy()
        hit = np.zeros(cand.size, bool)
        live = np.ones(cand.size, bool)
        seg = le[cand] - ls[cand]
        for _ in range(d.max_iterations * 4):
            sigma[live] += 0.9 * f[live] / length[cand][live]
            live &= sigma <= 1.0
            if not live.any():
                break
            f[live] = col.evaluate_rest(ls[cand][live] + sigma[live, None] * seg[live])[0] - r[cand][live]
            hit |= live & (f <= tol)
            live &= ~hit
        hit |= live  # iteration cap: stop conservatively
        if not hit.any():
            continue
        rows = cand[hit]
        sig = np.minimum(sigma[hit], 1.0)
        lc = ls[rows] + sig[:, None] * seg[hit]
        fc, g = col.evaluate_rest(lc)
        # advancement stops up to tol before the surface: Newton steps along the chord to the
        # root where the chord crosses it (exact for a plane after one), kept inside [sigma, 1]
        crosses = f1[rows] < 0.0
        for _ in range(3):
            slope = _rowdot(g, seg[hit])
            step = crosses & (slope < 0.0)
            if not step.any():
                break
            sig = np.where(step, np.clip(sig - (fc - r[rows]) / np.where(step, slope, -1.0), sig, 1.0), sig)
            lc = ls[rows] + sig[:, None] * seg[hit]
            fc, g = col.evaluate_rest(lc)
        # chord fraction -> time fraction on the path (tangent plane at the hit)
        n0 = g @ rot0.T
        span = (1.0 - s_start[rows]) * dt
        chord_in = _rowdot(g, seg[hit])
        accel_in = 0.5 * _rowdot(n0, acc[rows]) * span * span
        tau = _np_path_fraction(chord_in, accel_in, sig)
        best = s_start[rows] + tau * (1.0 - s_start[rows])
        t_hit = ((best - s_start[rows]) * dt)[:, None]
        a_r = acc[rows]
        c = sx[rows] + ws[rows] * t_hit + 0.5 * a_r * t_hit * t_hit
        cv = ws[rows] + t_hit * a_r
        w0, w1 = to_world(lc, p0, rot0), to_world(lc, p1, rot1)
        u = (w1 - w0) / dt
        n1 = g @ rot1.T
        n = n0 + best[:, None] * (n1 - n0)
        n /= np.linalg.norm(n, axis=1)[:, None]
        an = _rowdot(a_r, n)
        threshold = (2.0 * np.maximum(0.0, -an) * dt + d.rest_speed)[:, None]
        held = (an < 0.0) & (-_rowdot(cv - u, n) <= threshold[:, 0])
        cv = _np_response(cv, u, n, e_k, mu, threshold)
        # a slow impact is held: no acceleration into the surface nor lag along the normal for
        # the rest of the step; a real bounce keeps both (it leaves under gravity)
        hm = held[:, None]
        a_r = np.where(hm, a_r - an[:, None] * n, a_r)
        lag_r = lag[rows]
        lag[rows] = np.where(hm, lag_r - _rowdot(lag_r, n)[:, None] * n, lag_r)
        rem = ((1.0 - best) * dt)[:, None]
        ex[rows] = c + rem * cv + 0.5 * rem * rem * a_r
        pv[rows] = cv + rem * a_r
        acc[rows] = a_r
        sx[rows], ws[rows], s_start[rows] = c, cv, best
        changed[rows] = True
    # end-of-step projection (the a-posteriori response; a safety net a priori)
    for k, col, p0, rot0, p1, rot1, to_rest, to_world in collider_poses:
        e_k, mu = d.restitution[k], d.friction[k]
        le = to_rest(ex, p1, rot1)
        dist, g = col.evaluate_rest(le)
        f = dist - r
        near = np.flatnonzero(f < tol)
        if not near.size:
            continue
        n = g[near] @ rot1.T
        u = (to_world(le[near], p1, rot1) - to_world(le[near], p0, rot0)) / dt
        heading_in = _rowdot(pv[near] - u, n) < 0.0
        keep = (f[near] < -tol) | heading_in
        rows, n, u, heading_in = near[keep], n[keep], u[keep], heading_in[keep]
        if not rows.size:
            continue
        fr = f[rows]
        ex[rows] -= np.minimum(fr, 0.0)[:, None] * n
        changed[rows] = True
        resp = heading_in
        if not resp.any():
            continue
        rows, n, u, fr = rows[resp], n[resp], u[resp], fr[resp]
        an = _rowdot(acc[rows], n)
        cv = pv[rows]
        span = (1.0 - s_start[rows]) * dt
        if d.mode != "a_priori":
            # detected after the fact: the velocity gained inside is not kept. The impact time
            # on the path from the signed distances at the segment's start and end
            gained = (an < 0.0) & (fr < 0.0) & (span > 0.0)
            if gained.any():
                fs = col.evaluate_rest(to_rest(sx[rows], p0, rot0))[0] - r[rows]
                inside = span.copy()  # started inside: the whole step
                out = gained & (fs > 0.0)
                if out.any():
                    fo, so, sp = fr[out], fs[out], span[out]
                    tau = _np_path_fraction(fo - so, 0.5 * an[out] * sp * sp, so / (so - fo))
                    inside[out] = (1.0 - tau) * sp
                cv = cv - np.where(gained, an * inside, 0.0)[:, None] * n
        threshold = (2.0 * np.maximum(0.0, -an) * dt + d.rest_speed)[:, None]
        held = (an < 0.0) & (-_rowdot(cv - u, n) <= threshold[:, 0])
        pv[rows] = _np_response(cv, u, n, e_k, mu, threshold)
        lag_r = lag[rows]
        lag[rows] = np.where(held[:, None], lag_r - _rowdot(lag_r, n)[:, None] * n, lag_r)
    # the velocity handed to the next step: the path's plus the integrator's lag
    rows = np.flatnonzero(changed)
    if rows.size:
        x[idx[rows]] = ex[rows]
        v[idx[rows]] = pv[rows] + lag[rows]
    return int(rows.size)


def _np_response(v, u, n, restitution, friction, rest_speed):
    # NumPy twin of response.surface_response for (M, D) arrays
    w = v - u
    wn = (w * n).sum(1)[:, None]
    going_in = wn[:, 0] < 0
    e = np.where(-wn > rest_speed, restitution, 0.0)
    tang = w - wn * n
    dvn = -(1 + e) * wn
    tl = np.linalg.norm(tang, axis=1)[:, None]
    # rows not heading in are returned unchanged; only the others need a finite scale
    limit = friction * np.maximum(dvn, 0.0)
    scale = np.zeros_like(tl)
    np.divide(limit, tl, out=scale, where=tl > limit)
    scale = np.where(tl > limit, 1.0 - scale, 0.0)
    out = u + scale * tang - e * wn * n
    return np.where(going_in[:, None], out, v)


# --- entry points called by ParticleSystem -----------------------------------------------------
def _data(system) -> ParticleCollisionData:
    data = getattr(system, "_collision", None)
    if data is None:
        data = ParticleCollisionData()
        system._collision = data
    if not any(isinstance(s, ParticleCollisionStage) and s.data is data for s in system.stages):
        stage = ParticleCollisionStage(data)
        if hasattr(system, "add_stage"):
            system.add_stage(stage)
        else:
            system.stages.append(stage)
    if not any(isinstance(f, RestingContactFilter) and f.data is data for f in system.force_filters):
        system.force_filters.append(RestingContactFilter(system, data))
    return data


def _unit_interval(value, name):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [0, 1]; got {value!r}") from None
    if not (0.0 <= x <= 1.0):
        raise ValueError(f"{name} must be in [0, 1] (0 = inelastic, 1 = elastic); got {value!r}")
    return x


def _nonnegative(value, name):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number >= 0; got {value!r}") from None
    if not (np.isfinite(x) and x >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0 (Coulomb coefficient); got {value!r}")
    return x


def attach_collider(system, collider, *, restitution=0.5, friction=0.0):
    """Attach `collider` to `system` with its restitution (in [0, 1]) and friction (>= 0).

    Returns the collider. Particles that start inside it are pushed out on the next step (with a
    warning that says how many).
    """
    if not isinstance(collider, Collider):
        raise ValueError(f"collider must be one of inertia.colliders (Plane, Sphere, Box, Capsule, "
                         f"Cylinder, Container, Mesh, SDF); got {type(collider).__name__}")
    if collider.dim != system.x.shape[1]:
        raise ValueError(f"collider is {collider.dim}-D but the particle system is {system.x.shape[1]}-D")
    restitution = _unit_interval(restitution, "restitution")
    friction = _nonnegative(friction, "friction")
    _data(system).add(collider, restitution, friction)
    return collider


def set_collision_mode(system, mode):
    """Select continuous ("a_priori", default) or discrete ("a_posteriori") collision detection."""
    if mode not in COLLISION_MODES:
        raise ValueError(f"collision_mode must be one of {COLLISION_MODES}; got {mode!r}")
    _data(system).mode = mode


def set_self_collisions(system, flag):
    """Switch particle-particle collisions on or off (particles need radius > 0)."""
    if not isinstance(flag, (bool, np.bool_)):
        raise ValueError(f"self_collisions must be True or False; got {flag!r}")
    data = _data(system)
    data.self_collisions = bool(flag)
    if flag and not np.any(np.asarray(system.radius) > 0):
        warnings.warn("self_collisions is on but every particle has radius 0, so none can touch; "
                      "give the particles a radius (ParticleSystem(..., radius=...))",
                      stacklevel=_user_stacklevel())


def configure_contacts(system, *, distance_tolerance=None, rest_speed=None, self_restitution=None,
                       self_friction=None, iterations=None, max_substeps=None):
    """Set contact options of `system` (defaults and ranges in the module docstring)."""
    data = _data(system)
    if distance_tolerance is not None:
        data.distance_tolerance = _positive(distance_tolerance, "distance_tolerance")
    if rest_speed is not None:
        data.rest_speed = _positive(rest_speed, "rest_speed")
    if self_restitution is not None:
        data.self_restitution = _unit_interval(self_restitution, "self_restitution")
    if self_friction is not None:
        data.self_friction = _nonnegative(self_friction, "self_friction")
    if iterations is not None:
        data.iterations = _count(iterations, "iterations")
    if max_substeps is not None:
        data.max_substeps = _count(max_substeps, "max_substeps")
    return data


def _positive(value, name):
    x = _nonnegative(value, name)
    if x == 0:
        raise ValueError(f"{name} must be > 0; got {value!r}")
    return x


def _count(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1; got {value!r}")
    return int(value)
