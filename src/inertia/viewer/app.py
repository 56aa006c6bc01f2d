"""The interactive web viewer (viser): play, pause, step, scrub time, orbit the camera.

    from inertia.viewer import view
    view(states, colliders=world.colliders)             # a recorded run; blocks until Ctrl-C
    viewer = view(states, port=0, block=False)          # returns at once; viewer.url, viewer.close()
    view(lambda: (sim.step(), ps.x)[1], dim=3)          # live: called once per played frame

It serves a page (viser's bundled client, no internet needed) at ``http://HOST:PORT``, which
works over SSH port forwarding and in notebooks. The page shows the particles (shaded spheres
for up to ``sphere_limit`` particles, round points beyond), the colliders, a ground grid, and
a panel with Play / Pause, Step, a frame slider (scrubbing), the playback rate and a loop
switch. Orbit, pan and zoom with the mouse (viser's camera controls).

Colours follow the renderer (`inertia.render.colormaps.particle_colors`): speed on one scale for
the whole run, or group colours (``metadata["group_colors"]`` honoured).

A recorded run shows every system the video shows: particle groups; SPH and grid-liquid particles
(``fluid/<name>/x``, coloured by speed, `inertia.render.fluid_particles.with_fluid_particles`, so a
2-D fluid is seen in its own plane); grid fluids as colour maps on one scale for the run (a 2-D grid
as an image in its plane, coloured by density or speed; a 3-D grid as a cloud of its cells whose
density is above 5 % of the run's largest, coloured by density on the bright half of the inferno
map: the smoke's volume); rigid bodies
(meshes moved by ``body_q``); the colliders.

Requires viser (``pip install inertia[viewer]``).

Limitations: colliders known only by their signed distance (``SDF``, ``Mesh``,
``Container.from_planes``) are not drawn; one viewer thread per server; live mode keeps no
history (the slider shows the frame count only).
"""

from __future__ import annotations

import math
import os
import threading
import time
from typing import Sequence

import numpy as np

from ..math import mat3_to_quat

__all__ = ["Viewer", "view"]


def _import_viser():
    try:
        import viser
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError("the viewer needs viser: pip install inertia[viewer]  (or: pip install viser)") from error
    return viser


def _rgb8(colors: np.ndarray) -> np.ndarray:
    return np.clip(np.round(np.asarray(colors, dtype=np.float32) * 255.0), 0, 255).astype(np.uint8)


def _quat_from_matrix(r: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix (`inertia.math.mat3_to_quat`)."""
    return mat3_to_quat(np.ascontiguousarray(r, dtype=np.float64))


def _tube_mesh(a, b, radius, *, caps: str, segments: int = 24, rings: int = 8):
    """Triangle mesh of a capsule (caps="round") or capped cylinder (caps="flat") from a to b."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    axis = b - a
    length = float(np.linalg.norm(axis))
    u = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    angles = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    circle = np.cos(angles)[:, None] * e1 + np.sin(angles)[:, None] * e2
    # Profile: (offset along the axis from its end, radius) rings, bottom to top.
    if caps == "round":
        phis = np.linspace(-np.pi / 2, 0.0, rings + 1)
        bottom = [(radius * math.sin(p), radius * math.cos(p)) for p in phis]  # (axial offset, ring radius)
        profile = [(0, z, r) for z, r in bottom] + [(1, -z, r) for z, r in reversed(bottom)]
    else:
        profile = [(0, 0.0, 0.0), (0, 0.0, radius), (1, 0.0, radius), (1, 0.0, 0.0)]
    vertices, faces = [], []
    for end, z, r in profile:
        base = a if end == 0 else b
        vertices.append(base + z * u + r * circle)
    vertices = np.concatenate(vertices)
    n_rings = len(profile)
    for i in range(n_rings - 1):
        for j in range(segments):
            k0, k1 = i * segments + j, i * segments + (j + 1) % segments
            k2, k3 = k0 + segments, k1 + segments
            faces += [(k0, k1, k3), (k0, k3, k2)]
    return vertices.astype(np.float32), np.array(faces, dtype=np.int32)


def _icosphere(subdivisions: int = 1):
    """Unit icosphere (vertices, faces) for instanced particle spheres."""
    t = (1.0 + 5 ** 0.5) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    faces = list(f)
    def middle(i, j, cache):
        key = (min(i, j), max(i, j))
        if key not in cache:
            m = verts[i] + verts[j]
            verts.append(m / np.linalg.norm(m))
            cache[key] = len(verts) - 1
        return cache[key]

    for _ in range(subdivisions):
        cache, new_faces = {}, []
        for a, b, c in faces:
            ab, bc, ca = middle(a, b, cache), middle(b, c, cache), middle(c, a, cache)
            new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new_faces
    return np.array(verts, np.float32), np.array(faces, np.int32)


class _Source:
    """Frames from a `States` (random access) or from a live callback (forward only)."""

    def __init__(self, source, dim):
        from ..io.states import States, load_states

        if isinstance(source, (str, os.PathLike)):
            source = load_states(source)
        if isinstance(source, States):
            from ..render.fluid_particles import with_fluid_particles

            source = with_fluid_particles(source)  # SPH and liquid particles after the groups'
        self.states = source if isinstance(source, States) else None
        self.callback = None if self.states is not None else source
        if self.states is None and not callable(source):
            raise TypeError("view: expected a States, a state-file path, or a callable returning positions")
        self.live_frames: dict = {}
        if self.states is not None:
            self.dim = self.states.dim
        else:
            first = self._call()
            self.dim = first[0].shape[1] if dim is None else dim
            self.live_frames[0] = first

    def _call(self):
        value = self.callback()
        if isinstance(value, tuple):
            positions = np.asarray(value[0], dtype=np.float64)
            velocities = None if len(value) < 2 or value[1] is None else np.asarray(value[1], dtype=np.float64)
        else:
            positions, velocities = np.asarray(value, dtype=np.float64), None
        if positions.ndim != 2 or positions.shape[1] not in (2, 3):
            raise ValueError(f"view: the callback must return positions (N, 2) or (N, 3), got shape {positions.shape}")
        return positions.copy(), None if velocities is None else velocities.copy()

    @property
    def frame_count(self) -> int:
        return self.states.frame_count if self.states is not None else max(self.live_frames) + 1

    def get(self, frame: int):
        """(positions, velocities, time, active) of ``frame``."""
        if self.states is not None:
            s = self.states
            return (s.positions[frame], None if s.velocities is None else s.velocities[frame],
                    float(s.times[frame]), s.active(frame))
        newest = max(self.live_frames)
        while newest < frame:
            newest += 1
            self.live_frames[newest] = self._call()
            # Keep memory bounded in live mode: only the newest few frames.
            self.live_frames.pop(newest - 4, None)
        positions, velocities = self.live_frames.get(frame, self.live_frames[newest])
        return positions, velocities, float(frame), None


class Viewer:
    """A running viewer server (see `view`). ``url`` to open; `close` to stop it."""

    def __init__(
        self,
        source,
        *,
        colliders: Sequence = (),
        host: str = "127.0.0.1",
        port: int = 8080,
        fps: float | None = None,
        dim: int | None = None,
        color_by: str = "auto",
        colormap: str = "speed",  # colormaps.DEFAULT_SPEED_MAP, as the video
        color=(0.35, 0.62, 0.95),
        radius: float | None = None,
        sphere_limit: int = 4000,
        up: str = "z",
        loop: bool = True,
        autoplay: bool = False,
        verbose: bool = False,
    ):
        viser = _import_viser()
        from ..render.camera import Camera
        from ..render.colormaps import particle_colors, robust_speed_max, run_speed_max
        from ..render.renderer import scene_bounds

        self._particle_colors = particle_colors
        self.source = _Source(source, dim)
        self.dim = self.source.dim
        self.colliders = list(colliders or ())
        states = self.source.states
        self.fps = float(fps or (states.fps if states is not None else None) or 30.0)
        self.color_by, self.colormap, self.color = color_by, colormap, color
        self.loop = bool(loop)
        self.frame = 0
        self.playing = bool(autoplay)
        self._lock = threading.RLock()
        self._stop = threading.Event()

        # Scene scale, radii, colour scale, camera, from the whole run (or the first frame).
        positions0, velocities0, t0, active0 = self.source.get(0)
        self._grids = _GridLayers(states) if states is not None else None
        if states is not None:
            lo, hi = scene_bounds(states.positions, active=states.fields.get("active"))
            if self._grids is not None and self._grids.layers:
                glo, ghi = self._grids.bounds(self.dim)
                lo, hi = (glo, ghi) if states.particle_count == 0 else (np.minimum(lo, glo), np.maximum(hi, ghi))
            # The video's speed scale (`inertia run` colours by the same run-wide value).
            self.speed_max = run_speed_max(states.velocities) if states.velocities is not None else None
            self.groups = states.groups()
            self.group_colors = states.metadata.get("group_colors")
            radii = states.radius()
        else:
            lo, hi = scene_bounds(positions0)
            self.speed_max = robust_speed_max(velocities0) if velocities0 is not None else None
            self.groups, self.group_colors, radii = None, None, None
        size = float(np.linalg.norm(hi - lo)) or 1.0
        if radius is not None:
            radii = np.full(positions0.shape[0], float(radius))
        elif radii is None or not np.any(np.asarray(radii) > 0):
            radii = np.full(positions0.shape[0], 0.004 * size)
        radii = np.where(np.asarray(radii) > 0, radii, 0.004 * size).astype(np.float64)
        self.radii = radii
        self.size = size
        n = positions0.shape[0]
        self.use_spheres = n <= sphere_limit

        # The server and the static scene.
        self.server = viser.ViserServer(host=host, port=port, verbose=verbose)
        self.host, self.port = host, self.server.get_port()
        scene = self.server.scene
        if self.dim == 3:
            scene.set_up_direction("+z" if up == "z" else "+y")
        else:
            scene.set_up_direction("+y")
        lo3, hi3 = np.zeros(3), np.zeros(3)
        lo3[: self.dim], hi3[: self.dim] = lo, hi
        # The initial view frames the whole run (as the offline renderer's camera does).
        fov = 50.0
        if self.dim == 3:
            camera = Camera.fit(lo3, hi3, aspect=16 / 9, up=up, fov_y=fov)
            position, target, cam_up = camera.position, camera.target, camera.up
        else:
            center = 0.5 * (lo3 + hi3)
            height = max(hi3[1] - lo3[1], (hi3[0] - lo3[0]) * 9 / 16) * 1.15
            distance = height / (2 * math.tan(math.radians(fov / 2)))
            position, target, cam_up = np.array([center[0], center[1], distance]), center, np.array([0.0, 1.0, 0.0])
        self.camera_pose = (tuple(map(float, position)), tuple(map(float, target)), tuple(map(float, cam_up)))
        self.server.initial_camera.fov = math.radians(fov)
        self.server.initial_camera.position = self.camera_pose[0]
        self.server.initial_camera.look_at = self.camera_pose[1]
        self.server.initial_camera.up = self.camera_pose[2]

        @self.server.on_client_connect
        def _(client) -> None:
            client.camera.fov = math.radians(fov)
            client.camera.position = self.camera_pose[0]
            client.camera.look_at = self.camera_pose[1]
            client.camera.up_direction = self.camera_pose[2]
        self._add_ground(lo3, hi3, up)
        self._rest_pose: dict = {}
        self._collider_handles = self._add_colliders(t0)
        self._body_handles = self._add_bodies(states)

        # Particles.
        self._particles = None
        self._particle_count = -1
        self._sphere_mesh = _icosphere(2)
        self._show(0)

        # The panel.
        gui = self.server.gui
        gui.add_markdown("**Inertia viewer**")
        self._time_text = gui.add_markdown(self._time_label(0, t0))
        self._play = gui.add_button("Pause" if self.playing else "Play", icon=None)
        self._step = gui.add_button("Step")
        self._slider = gui.add_slider("Frame", min=0, max=max(self.source.frame_count - 1, 1), step=1, initial_value=0,
                                      disabled=self.source.frame_count <= 1 and states is not None)
        self._rate = gui.add_slider("Frames/s", min=1, max=120, step=1, initial_value=int(round(self.fps)))
        self._loop = gui.add_checkbox("Loop", initial_value=self.loop)

        @self._play.on_click
        def _(_event) -> None:
            self.playing = not self.playing
            self._play.label = "Pause" if self.playing else "Play"

        @self._step.on_click
        def _(_event) -> None:
            self.playing = False
            self._play.label = "Play"
            self.step()

        @self._slider.on_update
        def _(_event) -> None:
            value = int(self._slider.value)
            if value != self.frame:
                self.set_frame(value)

        @self._rate.on_update
        def _(_event) -> None:
            self.fps = float(self._rate.value)

        @self._loop.on_update
        def _(_event) -> None:
            self.loop = bool(self._loop.value)

        self._thread = threading.Thread(target=self._run, name="inertia-viewer", daemon=True)
        self._thread.start()

    # -- the scene ----------------------------------------------------------------------------
    def _add_ground(self, lo3, hi3, up) -> None:
        from ..render.renderer import nice_step

        spacing = nice_step(self.size / 12.0)
        extent = 4.0 * self.size
        if self.dim == 2:
            self.server.scene.add_grid("/ground", width=extent, height=extent, plane="xy", cell_size=spacing,
                                       section_size=5 * spacing, position=(0.5 * (lo3[0] + hi3[0]), 0.5 * (lo3[1] + hi3[1]), -0.01 * self.size))
            return
        has_plane = any(type(c).__name__ == "Plane" for c in self.colliders)
        if not has_plane:
            level = lo3[2] if up == "z" else lo3[1]
            center = 0.5 * (lo3 + hi3)
            position = (center[0], center[1], level) if up == "z" else (center[0], level, center[2])
            self.server.scene.add_grid("/ground", width=extent, height=extent, plane="xy" if up == "z" else "xz",
                                       cell_size=spacing, section_size=5 * spacing, position=position)

    def _add_colliders(self, t: float) -> list:
        """Static meshes for the analytic colliders; returns [(handle, collider, rest transform)]."""
        from ..render.colliders import collider_primitives
        from ..render import kernels as K

        handles = []
        color = (160, 165, 175)
        for index, collider in enumerate(self.colliders):
            prims = collider_primitives([collider], 0.0, self.dim)
            if len(prims.kinds) == 0:
                continue  # drawn by its signed distance only: not shown here
            kind, row = int(prims.kinds[0]), prims.params[0]
            name = f"/colliders/{index}"
            scene = self.server.scene
            if kind == K.PRIM_PLANE:
                n = row[3:6]
                # A grid in the plane: rotate +z onto the normal.
                z = np.array([0.0, 0.0, 1.0])
                axis = np.cross(z, n)
                if np.linalg.norm(axis) < 1e-9:
                    wxyz = (1.0, 0.0, 0.0, 0.0) if n[2] > 0 else (0.0, 1.0, 0.0, 0.0)
                else:
                    angle = math.acos(np.clip(n @ z, -1, 1))
                    axis = axis / np.linalg.norm(axis)
                    wxyz = (math.cos(angle / 2), *(math.sin(angle / 2) * axis))
                spacing = self.size / 12.0
                from ..render.renderer import nice_step

                handle = scene.add_grid(name, width=4 * self.size, height=4 * self.size, plane="xy", wxyz=wxyz,
                                        position=tuple(row[0:3]), cell_size=nice_step(spacing), section_size=5 * nice_step(spacing),
                                        plane_color=(120, 125, 135), plane_opacity=0.35)
            elif kind == K.PRIM_SPHERE:
                handle = scene.add_icosphere(name, radius=float(row[3]), color=color, subdivisions=3, position=tuple(row[0:3]))
            elif kind in (K.PRIM_BOX, K.PRIM_CONTAINER):
                world_from_local = row[6:15].reshape(3, 3).T
                half = np.where(row[3:6] > 1e8, 0.01 * self.size, row[3:6])
                handle = scene.add_box(name, color=color, dimensions=tuple(2 * half), wxyz=tuple(_quat_from_matrix(world_from_local)),
                                       position=tuple(row[0:3]), wireframe=kind == K.PRIM_CONTAINER)
            else:
                vertices, faces = _tube_mesh(row[0:3], row[3:6], float(row[6]), caps="round" if kind == K.PRIM_CAPSULE else "flat")
                handle = scene.add_mesh_simple(name, vertices, faces, color=color)
            handles.append((handle, collider))
        return handles

    def _add_bodies(self, states) -> list:
        """Meshes of the rigid shapes of a state file's model (the video's tessellation and
        colours, `inertia.render.drawables`); returns [(handle, shape row)] of the moving ones."""
        if states is None or self.dim != 3:
            return []
        from ..render.drawables import ModelDrawables

        drawables = ModelDrawables.from_states(states)
        if drawables is None or not drawables.shape_meshes:
            return []
        self._drawables = drawables
        body_q = states.fields.get("body_q")
        poses = drawables.shape_poses(None if body_q is None else body_q[0])
        handles = []
        for s, (vertices, faces, color) in drawables.shape_meshes.items():
            handle = self.server.scene.add_mesh_simple(
                f"/bodies/{s}", vertices.astype(np.float32), faces.astype(np.uint32), color=tuple(int(c) for c in _rgb8(color)),
                position=tuple(map(float, poses[s, :3])), wxyz=tuple(map(float, poses[s, 3:])), flat_shading=False)
            if drawables.shape_body[s] >= 0:
                handles.append((handle, s))
        return handles

    def _move_bodies(self, frame: int) -> None:
        states = self.source.states
        if not self._body_handles or states is None or "body_q" not in states.fields:
            return
        poses = self._drawables.shape_poses(states.fields["body_q"][frame])
        for handle, s in self._body_handles:
            handle.position = tuple(map(float, poses[s, :3]))
            handle.wxyz = tuple(map(float, poses[s, 3:]))

    def _move_colliders(self, t: float) -> None:
        for handle, collider in self._collider_handles:
            if getattr(collider, "motion", None) is None or not callable(getattr(collider, "pose", None)):
                continue
            # pose(t) = (p, R): world = R (x - rest_point) + p; the handle holds x at rest.
            p, rotation = collider.pose(t)
            rotation = np.asarray(rotation, dtype=np.float64)
            ref = np.zeros(3)
            ref[: self.dim] = np.asarray(collider.rest_point, dtype=np.float64)[: self.dim]
            key = id(handle)
            if key not in self._rest_pose:
                self._rest_pose[key] = (np.asarray(handle.position, dtype=np.float64), np.asarray(handle.wxyz, dtype=np.float64))
            rest_position, rest_wxyz = self._rest_pose[key]
            world_rest = _matrix_from_quat(rest_wxyz)
            handle.wxyz = tuple(_quat_from_matrix(rotation @ world_rest))
            handle.position = tuple(rotation @ (rest_position - ref) + np.asarray(p, dtype=np.float64)[:3])

    def _colors(self, positions, velocities) -> np.ndarray:
        return self._particle_colors(
            positions.shape[0], velocities=velocities, groups=self.groups, color_by=self.color_by,
            cmap=self.colormap, speed_max=self.speed_max, group_colors=self.group_colors, color=self.color,
        )

    def _show(self, frame: int) -> None:
        positions, velocities, t, active = self.source.get(frame)
        if getattr(self, "_body_handles", None):
            self._move_bodies(frame)
        if self._grids is not None and self._grids.layers:
            self._grids.show(self.server.scene, frame, self.size)
        if positions.shape[0] == 0:
            self._move_colliders(t)
            return
        points = np.zeros((positions.shape[0], 3), np.float32)
        points[:, : self.dim] = positions
        colors = _rgb8(self._colors(positions, velocities))
        radii = self.radii
        if active is not None:
            keep = np.asarray(active, dtype=bool)
            points, colors, radii = points[keep], colors[keep], radii[keep]
        finite = np.all(np.isfinite(points), axis=1)
        points, colors, radii = points[finite], colors[finite], radii[finite]
        scene = self.server.scene
        if self.use_spheres:
            vertices, faces = self._sphere_mesh
            count = points.shape[0]
            # Instanced spheres: one mesh, per-instance position, scale and colour, updated in
            # place while the count stays the same.
            if self._particles is not None and self._particle_count == count:
                self._particles.batched_positions = points
                self._particles.batched_scales = radii.astype(np.float32)
                self._particles.batched_colors = colors
                self._move_colliders(t)
                return
            if self._particles is not None:
                self._particles.remove()
            self._particle_count = count
            self._particles = scene.add_batched_meshes_simple(
                "/particles", vertices, faces,
                batched_wxyzs=np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (count, 1)),
                batched_positions=points, batched_scales=radii.astype(np.float32), batched_colors=colors,
                lod="off", cast_shadow=False, receive_shadow=False,
            )
        else:
            size = float(2.0 * np.median(radii)) if radii.size else 0.01 * self.size
            if self._particles is None:
                self._particles = scene.add_point_cloud("/particles", points=points, colors=colors, point_size=size,
                                                        point_shape="circle", precision="float32")
            else:
                self._particles.points = points
                self._particles.colors = colors
        self._move_colliders(t)

    def _time_label(self, frame: int, t: float) -> str:
        total = self.source.frame_count
        return f"frame {frame} / {max(total - 1, 0)}  ·  t = {t:.3f} s"

    # -- control ------------------------------------------------------------------------------
    def set_frame(self, frame: int) -> None:
        """Show ``frame`` (clamped to the recorded range; live sources advance to it)."""
        with self._lock:
            if self.source.states is not None:
                frame = int(np.clip(frame, 0, self.source.frame_count - 1))
            else:
                frame = max(int(frame), 0)
            self.frame = frame
            self._show(frame)
            _, _, t, _ = self.source.get(frame)
            self._time_text.content = self._time_label(frame, t)
            if self.source.states is None and frame >= int(self._slider.max):
                self._slider.max = frame + 1
            if int(self._slider.value) != frame:
                self._slider.value = frame

    def step(self) -> None:
        """Advance one frame (wrapping around at the end when looping)."""
        with self._lock:
            last = self.source.frame_count - 1
            if self.source.states is not None and self.frame >= last:
                if self.loop:
                    self.set_frame(0)
                else:
                    self.playing = False
                    self._play.label = "Play"
                return
            self.set_frame(self.frame + 1)

    def play(self) -> None:
        self.playing = True
        self._play.label = "Pause"

    def pause(self) -> None:
        self.playing = False
        self._play.label = "Play"

    def _run(self) -> None:
        next_time = time.perf_counter()
        while not self._stop.is_set():
            if self.playing:
                self.step()
                next_time += 1.0 / max(self.fps, 1e-3)
                delay = next_time - time.perf_counter()
                if delay < -0.5:
                    next_time = time.perf_counter()
                self._stop.wait(max(delay, 0.0))
            else:
                next_time = time.perf_counter()
                self._stop.wait(0.05)

    @property
    def url(self) -> str:
        host = "localhost" if self.host in ("0.0.0.0", "::") else self.host
        return f"http://{host}:{self.port}"

    def wait(self) -> None:
        """Block until Ctrl-C (or `close` from another thread)."""
        try:
            while not self._stop.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        """Stop playback and the server."""
        if not self._stop.is_set():
            self._stop.set()
            try:
                self.server.stop()
            except Exception:  # noqa: BLE001 - already stopped
                pass


class _GridLayers:
    """The grid fluids of a recorded run as viser layers (see the module docstring)."""

    #: 3-D: cells drawn where the density exceeds this share of the run's largest, at most this many.
    THRESHOLD, MAX_POINTS = 0.05, 60000

    def __init__(self, states):
        self.states = states
        self.layers = []  # (name, quantity, dim, origin (3,), cell size, vmax)
        self.handles: dict = {}
        for key, value in states.fields.items():
            parts = key.split("/")
            if len(parts) != 3 or parts[0] != "fluid" or parts[2] != "speed" or np.ndim(value) not in (3, 4):
                continue
            name = parts[1]
            if f"fluid/{name}/origin" not in states.model or f"fluid/{name}/cell_size" not in states.model:
                continue
            dim = np.ndim(value) - 1
            quantity = "density" if f"fluid/{name}/density" in states.fields else "speed"
            data = np.asarray(states.fields[f"fluid/{name}/{quantity}"])
            sample = data[:: max(1, data.shape[0] // 50)]
            finite = sample[np.isfinite(sample)]
            vmax = float(np.percentile(finite, 99.5)) if finite.size else 1.0
            origin = np.zeros(3)
            origin[:dim] = np.asarray(states.model[f"fluid/{name}/origin"], np.float64).ravel()[:dim]
            self.layers.append((name, quantity, dim, origin, float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0]),
                                vmax if vmax > 0 else 1.0))

    def bounds(self, dim: int) -> tuple[np.ndarray, np.ndarray]:
        lows, highs = [], []
        for name, quantity, gdim, origin, h, _ in self.layers:
            shape = np.asarray(self.states.fields[f"fluid/{name}/{quantity}"].shape[1:], np.float64)
            lows.append(origin[:dim])
            highs.append(origin[:dim] + np.pad(shape, (0, 3 - gdim))[:dim] * h)
        return np.min(lows, axis=0), np.max(highs, axis=0)

    def show(self, scene, frame: int, size: float) -> None:
        from ..render.colormaps import colormap

        for name, quantity, dim, origin, h, vmax in self.layers:
            data = np.asarray(self.states.fields[f"fluid/{name}/{quantity}"][frame], np.float64)
            cmap = "inferno" if quantity == "density" else "viridis"
            if dim == 2:
                # an image in the grid's plane: row 0 is the top (largest y)
                rgb = colormap(cmap, np.flipud(data.T).ravel(), vmin=0.0, vmax=vmax).reshape(data.shape[1], data.shape[0], 3)
                image = _rgb8(rgb)
                width, height = data.shape[0] * h, data.shape[1] * h
                centre = (origin[0] + 0.5 * width, origin[1] + 0.5 * height, -0.002 * size)
                handle = self.handles.get(name)
                if handle is None:
                    self.handles[name] = scene.add_image(f"/fluids/{name}", image, render_width=width,
                                                         render_height=height, position=centre)
                else:
                    handle.image = image
                continue
            # 3-D: the cells above the threshold as a point cloud (the volume), coloured by the quantity
            cells = np.argwhere(data > self.THRESHOLD * vmax)
            if cells.shape[0] > self.MAX_POINTS:
                cells = cells[:: -(-cells.shape[0] // self.MAX_POINTS)]
            points = (origin + (cells + 0.5) * h).astype(np.float32)
            values = data[tuple(cells.T)] if cells.size else np.zeros(0)
            # the map's bright half (red to yellow): thin smoke reads as smoke on the page's light background
            colors = _rgb8(colormap(cmap, values, vmin=-0.6 * vmax, vmax=vmax)) if cells.size else np.zeros((0, 3), np.uint8)
            handle = self.handles.get(name)
            if handle is not None:
                handle.remove()
            self.handles[name] = scene.add_point_cloud(f"/fluids/{name}", points=points.reshape(-1, 3), colors=colors,
                                                       point_size=float(h), point_shape="circle", precision="float32")


def _matrix_from_quat(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def view(
    source,
    *,
    colliders: Sequence = (),
    port: int = 8080,
    host: str = "127.0.0.1",
    fps: float | None = None,
    color_by: str = "auto",
    open_browser: bool = False,
    block: bool = True,
    autoplay: bool = True,
    **options,
) -> Viewer:
    """Serve the interactive viewer for a run and (by default) block until Ctrl-C.

    ``source``: a `States`, a state-file path, or a callable returning positions (N, D) or
    (positions, velocities) once per played frame (live simulation). ``port=0`` picks a free
    port. ``open_browser``: open the page in the default browser. ``block=False`` returns the
    running `Viewer` at once (its ``url``; call ``close()`` when done). Other options:
    ``dim``, ``colormap``, ``color`` (for ``color_by="uniform"``), ``radius``, ``sphere_limit``
    (4000: more particles are drawn as round points), ``up``, ``loop``, ``verbose``.
    """
    viewer = Viewer(source, colliders=colliders, host=host, port=port, fps=fps, color_by=color_by,
                    autoplay=autoplay, **options)
    print(f"Inertia viewer at {viewer.url}  (Ctrl-C to stop)", flush=True) if block else None
    if open_browser:
        import webbrowser

        webbrowser.open(viewer.url)
    if block:
        viewer.wait()
    return viewer
