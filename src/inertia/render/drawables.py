"""What a state file's ``model`` adds to the particles of each frame: bodies, cloth, springs.

`ModelDrawables(model)` reads the contract's arrays once (``docs/contracts.md``,
``inertia.io.States.model``):

- the shape table (``shape_type``, ``shape_body``, ``shape_local_pose (S, 7)`` position +
  quaternion (w, x, y, z) in the body frame, ``shape_params``, ``geom_vertices``...,
  ``shape_color (S, 3)`` optional) -> every shape tessellated once in its own frame
  (`inertia.render.meshes.tessellate_shape`); a static plane facing up becomes the renderer's
  analytic ground, any other static plane a finite patch under the subject (`plane_colliders`);
  rows a scene collider added (``shape_source >= 0``: a container's walls, a kinematic paddle) are
  left to the colliders' own drawing (`inertia.render.colliders`: a container as a box cut away
  toward the camera), unless ``include_collider_rows=True``;
- ``surface_triangles (T, 3)`` global particle indices -> a cloth surface over the particle
  positions of each frame (smooth normals per frame); its particles are not also drawn as
  spheres (`hidden`);
- ``spring_pairs (P, 2)`` global particle indices -> lines (except springs between two particles of a
  surface, which the surface shows);
- ``vehicle/<k>/wheel_radius (W,)`` with the frames' ``vehicle/<k>/wheel_pose (F, W, 7)`` -> each
  ray-cast vehicle's wheels as dark cylinders (`wheels`).

`frame(positions, body_q)` returns the ``meshes=`` and ``lines=`` of `Renderer.frame` for one
frame: the shapes moved by ``body_q (B, 7)`` (the body frame's position and orientation;
world pose of a shape = body pose composed with its local pose).

Limitations: planes on moving bodies are not drawn; shape colours default to a palette by body
index (static shapes grey).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..math import compose_poses, rotate_vectors
from .colormaps import GROUP_PALETTE
from .meshes import LineSet, TriangleMesh, tessellate_shape

__all__ = ["ModelDrawables", "PlanePatch", "subject_bounds", "frame_options", "trail_lines"]

#: Colour of ray-cast vehicles' wheels (sRGB).
WHEEL_COLOR = (0.12, 0.12, 0.13)


def _wheel_mesh(radius: float, width: float, segments: int = 20):
    """A closed cylinder about the y axis (vertices (V, 3), normals (V, 3), triangles (T, 3)): flat
    shading, a ring of side quads and two caps."""
    a = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    c, s = np.cos(a), np.sin(a)
    half = 0.5 * width
    side_v = np.concatenate([np.stack([radius * c, np.full(segments, -half), radius * s], 1),
                             np.stack([radius * c, np.full(segments, half), radius * s], 1)])
    side_n = np.concatenate([np.stack([c, np.zeros(segments), s], 1)] * 2)
    i = np.arange(segments)
    j = (i + 1) % segments
    side_t = np.concatenate([np.stack([i, j, j + segments], 1), np.stack([i, j + segments, i + segments], 1)])
    verts, norms, tris = [side_v], [side_n], [side_t]
    base = 2 * segments
    for sign in (-1.0, 1.0):
        ring = np.stack([radius * c, np.full(segments, sign * half), radius * s], 1)
        verts.append(np.vstack([[0.0, sign * half, 0.0], ring]))
        norms.append(np.tile([0.0, sign, 0.0], (segments + 1, 1)))
        fan = np.stack([np.zeros(segments, int), i + 1, j + 1], 1)
        tris.append(base + (fan if sign > 0 else fan[:, [0, 2, 1]]))
        base += segments + 1
    tris = np.concatenate(tris).astype(np.int64)[:, [0, 2, 1]]  # wound counter-clockwise seen from outside
    return np.concatenate(verts), np.concatenate(norms), tris


#: Colours of cloth surfaces and spring lines when the model gives none (sRGB).
CLOTH_COLOR = (0.86, 0.42, 0.32)
SPRING_COLOR = (0.93, 0.86, 0.62)
STATIC_COLOR = (0.62, 0.64, 0.68)


@njit(cache=True)
def _pose_vertices(local_v, local_n, vertex_shape, shape_pose, out_v, out_n):
    """World vertices and normals: each vertex rotated and moved by its shape's world pose."""
    for i in range(local_v.shape[0]):
        s = vertex_shape[i]
        w, x, y, z = shape_pose[s, 3], shape_pose[s, 4], shape_pose[s, 5], shape_pose[s, 6]
        for which in range(2):
            src = local_v if which == 0 else local_n
            vx, vy, vz = src[i, 0], src[i, 1], src[i, 2]
            # v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
            tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
            rx = vx + w * tx + (y * tz - z * ty)
            ry = vy + w * ty + (z * tx - x * tz)
            rz = vz + w * tz + (x * ty - y * tx)
            if which == 0:
                out_v[i, 0] = rx + shape_pose[s, 0]
                out_v[i, 1] = ry + shape_pose[s, 1]
                out_v[i, 2] = rz + shape_pose[s, 2]
            else:
                out_n[i, 0], out_n[i, 1], out_n[i, 2] = rx, ry, rz


class ModelDrawables:
    """Meshes and lines of a model (see the module docstring); ``group_colors`` (N, 3) sRGB per
    particle, optional, colours cloth surfaces by their first vertex's group."""

    def __init__(self, model: dict, *, particle_colors=None, include_collider_rows: bool = False):
        model = dict(model or {})
        self.model = model
        from ..geometry import shapes as S

        # Shapes: one tessellation per row, concatenated with the row index per vertex.
        self.planes: list[tuple[np.ndarray, np.ndarray]] = []
        #: Shape row -> (local vertices (V, 3), triangles (T, 3), sRGB colour (3,)) of each drawn shape.
        self.shape_meshes: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        local_v, local_n, tris, tri_colors, vertex_shape, base = [], [], [], [], [], 0
        shape_type = np.asarray(model.get("shape_type", np.zeros(0)), np.int64)
        shape_body = np.asarray(model.get("shape_body", np.full(shape_type.shape, -1)), np.int64)
        pose = np.asarray(model.get("shape_local_pose", np.tile([0, 0, 0, 1.0, 0, 0, 0], (len(shape_type), 1))), np.float64)
        colors = model.get("shape_color")
        source = np.asarray(model.get("shape_source", np.full(shape_type.shape, -1)), np.int64)
        for s in range(len(shape_type)):
            if source[s] >= 0 and not include_collider_rows:
                continue  # a scene collider's row: drawn from the collider (walls cut away, motion)
            if shape_type[s] == S.PLANE:
                if shape_body[s] < 0:
                    normal = rotate_vectors(pose[s, 3:], np.array([0.0, 0.0, 1.0]))
                    self.planes.append((pose[s, :3].copy(), normal))
                continue
            mesh = tessellate_shape(model, s)
            if mesh is None:
                continue
            v, n, t = mesh
            if colors is not None and s < len(colors) and np.isfinite(colors[s]).all():
                color = np.asarray(colors[s], np.float32)
            elif shape_body[s] < 0:
                color = np.array(STATIC_COLOR, np.float32)
            else:
                color = np.asarray(GROUP_PALETTE[int(shape_body[s]) % len(GROUP_PALETTE)], np.float32)
            self.shape_meshes[s] = (v, t, color)
            local_v.append(v)
            local_n.append(n)
            tris.append(t + base)
            tri_colors.append(np.tile(color, (t.shape[0], 1)))
            vertex_shape.append(np.full(v.shape[0], s, np.int64))
            base += v.shape[0]
        self.shape_count = len(shape_type)
        self.shape_body = shape_body
        self.shape_local_pose = pose
        if local_v:
            self.local_vertices = np.ascontiguousarray(np.concatenate(local_v))
            self.local_normals = np.ascontiguousarray(np.concatenate(local_n))
            self.triangles = np.ascontiguousarray(np.concatenate(tris))
            self.triangle_colors = np.concatenate(tri_colors).astype(np.float32)
            self.vertex_shape = np.concatenate(vertex_shape)
        else:
            self.local_vertices = None
        self.surface_triangles = model.get("surface_triangles")
        if self.surface_triangles is not None:
            self.surface_triangles = np.ascontiguousarray(self.surface_triangles, dtype=np.int64).reshape(-1, 3)
        self.spring_pairs = model.get("spring_pairs")
        if self.spring_pairs is not None:
            self.spring_pairs = np.ascontiguousarray(self.spring_pairs, dtype=np.int64).reshape(-1, 2)
            if self.surface_triangles is not None and self.surface_triangles.size and self.spring_pairs.size:
                # springs inside a shaded surface (cloth) are the surface: draw only the others as lines
                covered = np.zeros(int(max(self.spring_pairs.max(), self.surface_triangles.max())) + 1, bool)
                covered[self.surface_triangles.reshape(-1)] = True
                keep = ~(covered[self.spring_pairs[:, 0]] & covered[self.spring_pairs[:, 1]])
                self.spring_pairs = np.ascontiguousarray(self.spring_pairs[keep])
        self.particle_colors = None if particle_colors is None else np.asarray(particle_colors, np.float32)
        #: Ray-cast vehicles: vehicle index -> wheel radii (W,) m (drawn at ``vehicle/<k>/wheel_pose``).
        self.wheel_radii = {int(key.split("/")[1]): np.asarray(value, np.float64).ravel()
                            for key, value in model.items() if key.startswith("vehicle/") and key.endswith("/wheel_radius")}

    @classmethod
    def from_states(cls, states, *, particle_colors=None, include_collider_rows: bool = False) -> "ModelDrawables | None":
        """Drawables of a `States` (its ``model`` dict), or None when it has nothing to draw."""
        model = getattr(states, "model", None)
        if not model or states.dim != 3:
            return None
        drawables = cls(model, particle_colors=particle_colors, include_collider_rows=include_collider_rows)
        return drawables if not drawables.empty else None

    @property
    def empty(self) -> bool:
        return (self.local_vertices is None and self.surface_triangles is None and self.spring_pairs is None
                and not self.planes and not self.wheel_radii)

    def wheels(self, fields: dict, f: int) -> list:
        """The vehicles' wheels at frame ``f`` as one dark `TriangleMesh` of cylinders (axle along the
        chassis's y, width 0.6 x radius), from the recorded ``vehicle/<k>/wheel_pose (F, W, 7)``."""
        verts, norms, tris, base = [], [], [], 0
        for k, radii in self.wheel_radii.items():
            poses = fields.get(f"vehicle/{k}/wheel_pose")
            if poses is None:
                continue
            for pose, r in zip(np.asarray(poses[f], np.float64), radii):
                v, n, t = _wheel_mesh(r, 0.6 * r)
                verts.append(rotate_vectors(pose[3:], v) + pose[:3])
                norms.append(rotate_vectors(pose[3:], n))
                tris.append(t + base)
                base += v.shape[0]
        if not verts:
            return []
        return [TriangleMesh(np.concatenate(verts), np.concatenate(norms), np.concatenate(tris), np.array(WHEEL_COLOR, np.float32))]

    def plane_colliders(self, bounds=None) -> list:
        """Static planes to draw: a plane facing up (+z) as `inertia.colliders.Plane` (the
        renderer's ground, under the subject); any other plane as a finite square patch
        (`PlanePatch`) around the projection of the subject's bounds ``(lower (3,), upper (3,))``
        onto it, 1.2 times the bounds' diagonal wide (without bounds: an infinite plane)."""
        from ..colliders import Plane

        out = []
        for p, n in self.planes:
            if bounds is None or n[2] > 0.95:
                out.append(Plane(point=tuple(p), normal=tuple(n)))
                continue
            lo, hi = (np.asarray(b, np.float64) for b in bounds)
            centre = 0.5 * (lo + hi)
            centre = centre - np.dot(centre - p, n) * n  # the subject's centre projected onto the plane
            out.append(PlanePatch(centre, n, 0.6 * float(np.linalg.norm(hi - lo)) + 1e-3))
        return out

    def heightfield_floor(self) -> float | None:
        """Lowest world z of the static heightfields (the level to put the ground grid at, so a
        terrain rests on it), or None when there is none."""
        from ..geometry import shapes as S

        rows = [s for s in self.shape_meshes if int(self.model["shape_type"][s]) == S.HEIGHTFIELD and self.shape_body[s] < 0]
        if not rows:
            return None
        poses = self.shape_poses(None)
        return float(min(np.min(rotate_vectors(poses[s, 3:], self.shape_meshes[s][0])[:, 2] + poses[s, 2]) for s in rows))

    def hidden(self, count: int) -> np.ndarray | None:
        """(N,) bool: particles drawn as a surface, so not as spheres (None when there are none)."""
        if self.surface_triangles is None or self.surface_triangles.size == 0:
            return None
        mask = np.zeros(count, dtype=bool)
        mask[self.surface_triangles.reshape(-1)] = True
        return mask

    def shape_poses(self, body_q) -> np.ndarray:
        """World poses (S, 7) of the shapes for body poses ``body_q (B, 7)`` (None: at rest)."""
        pose = self.shape_local_pose
        if body_q is None or self.shape_count == 0:
            return pose
        body_q = np.asarray(body_q, np.float64)
        out = pose.copy()
        moving = self.shape_body >= 0
        out[moving] = compose_poses(body_q[self.shape_body[moving]], pose[moving])
        return out

    def body_vertices(self, body_q) -> tuple[np.ndarray, np.ndarray] | None:
        """World vertices and normals of every tessellated shape at ``body_q``."""
        if self.local_vertices is None:
            return None
        poses = np.ascontiguousarray(self.shape_poses(body_q))
        v = np.empty_like(self.local_vertices)
        n = np.empty_like(self.local_normals)
        _pose_vertices(self.local_vertices, self.local_normals, self.vertex_shape, poses, v, n)
        return v, n

    def frame(self, positions=None, body_q=None, *, spring_width_px: float = 1.6) -> dict:
        """``{"meshes": [...], "lines": [...]}`` for `Renderer.frame` at one frame."""
        meshes, lines = [], []
        moved = self.body_vertices(body_q)
        if moved is not None:
            meshes.append(TriangleMesh(moved[0], moved[1], self.triangles, self.triangle_colors))
        if positions is not None:
            pos = np.ascontiguousarray(positions, dtype=np.float64)
            if self.surface_triangles is not None and self.surface_triangles.size:
                color = np.array(CLOTH_COLOR, np.float32)
                if self.particle_colors is not None:
                    color = self.particle_colors[self.surface_triangles[:, 0]]
                meshes.append(TriangleMesh(pos, None, self.surface_triangles, color))
            if self.spring_pairs is not None and self.spring_pairs.size:
                lines.append(LineSet(pos, self.spring_pairs, np.array(SPRING_COLOR), spring_width_px))
        return {"meshes": meshes, "lines": lines}

    def bounds_points(self, body_q_frames=None) -> np.ndarray | None:
        """World points (M, 3) bounding the shapes over a run (``body_q_frames (F, B, 7)``), for
        framing the camera: each shape's bounding-box corners at 12 frames spread over the run."""
        if self.local_vertices is None:
            return None
        if body_q_frames is None or len(body_q_frames) == 0:
            return self._shape_box_corners(self.body_vertices(None)[0])
        frames = np.asarray(body_q_frames)
        picks = np.unique(np.linspace(0, len(frames) - 1, min(len(frames), 12)).astype(int))
        return np.concatenate([self._shape_box_corners(self.body_vertices(frames[f])[0]) for f in picks])

    def moving_bounds(self, body_q_frames) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The shapes' reach split for framing: (per-frame corners of the moving shapes' world
        bounding boxes (F, 2 S_moving, 3) for ``body_q_frames (F, B, 7)``, corners of the static
        shapes' boxes (2 S_static, 3)); an entry is None when there is no such shape. The moving
        part is the subject a camera may follow; the static part (a ramp, a terrain) is framed
        with the whole run."""
        if self.local_vertices is None:
            return None, None
        moving = self.shape_body[self.vertex_shape] >= 0
        rest = self.body_vertices(None)[0]
        still = self._shape_box_corners_of(rest, ~moving)
        if not np.any(moving) or body_q_frames is None or len(body_q_frames) == 0:
            return None, still
        frames = np.asarray(body_q_frames, np.float64)
        return np.stack([self._shape_box_corners_of(self.body_vertices(q)[0], moving) for q in frames]), still

    def _shape_box_corners_of(self, vertices: np.ndarray, keep: np.ndarray) -> np.ndarray | None:
        """`_shape_box_corners` of the shapes whose vertices ``keep`` (a per-vertex mask) selects."""
        if not np.any(keep):
            return None
        shape = self.vertex_shape[keep]
        starts = np.flatnonzero(np.r_[True, shape[1:] != shape[:-1]])
        picked = vertices[keep]
        return np.concatenate([np.minimum.reduceat(picked, starts, axis=0), np.maximum.reduceat(picked, starts, axis=0)])

    def _shape_box_corners(self, vertices: np.ndarray) -> np.ndarray:
        """The two extreme corners of each shape's world bounding box (2 S', 3): every shape's reach,
        however many vertices it has (a subsample of the vertices missed the top of a pile)."""
        starts = np.flatnonzero(np.r_[True, self.vertex_shape[1:] != self.vertex_shape[:-1]])
        return np.concatenate([np.minimum.reduceat(vertices, starts, axis=0),
                               np.maximum.reduceat(vertices, starts, axis=0)])


def subject_bounds(states, drawables: "ModelDrawables | None" = None) -> tuple[np.ndarray, np.ndarray] | None:
    """(lower (3,), upper (3,)) of what a run shows: the particles of its first and last frames
    and the shapes' vertices over the run; None when there is nothing finite."""
    points = []
    if states.frame_count and states.particle_count:
        for f in {0, states.frame_count - 1}:
            x = np.asarray(states.positions[f], np.float64).reshape(-1, states.dim)
            points.append(x[np.all(np.isfinite(x), axis=1)])
    if drawables is not None:
        extra = drawables.bounds_points(states.fields.get("body_q"))
        if extra is not None:
            points.append(extra)
    points = [p for p in points if p.size]
    if not points or states.dim != 3:
        return None
    allp = np.concatenate(points)
    return allp.min(axis=0), allp.max(axis=0)


class PlanePatch:
    """A finite square patch of a plane, drawn as a thin box (its back face on the plane):
    ``centre (3,)`` on the plane, unit ``normal (3,)``, ``half_size`` m (half the side)."""

    def __init__(self, centre, normal, half_size: float):
        self.normal = np.asarray(normal, np.float64) / np.linalg.norm(normal)
        helper = np.array([0.0, 0.0, 1.0]) if abs(self.normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        a = np.cross(helper, self.normal)
        a /= np.linalg.norm(a)
        b = np.cross(self.normal, a)
        self.rotation = np.stack([a, b, self.normal], axis=1)  # world from local: columns a, b, n
        self.thickness = 0.01 * float(half_size)
        self.center = np.asarray(centre, np.float64) - 0.5 * self.thickness * self.normal
        self.half_extents = np.array([half_size, half_size, 0.5 * self.thickness])

    def render_primitive(self, t: float = 0.0):
        return "box", {"center": self.center, "half_extents": self.half_extents, "rotation": self.rotation}


#: Colour of motion trails (sRGB) and the opacity of their newest segment.
TRAIL_COLOR = (0.9, 0.93, 1.0)
TRAIL_OPACITY = 0.45


def trail_lines(states, f: int, frames: int, *, active=None, max_particles: int = 4000) -> "LineSet | None":
    """Each particle's path over the last ``frames`` frames up to ``f`` as faint lines (the flow
    made visible: wind, vortices), fading from ``TRAIL_OPACITY`` at the particle to 0; at most
    ``max_particles`` particles (an even stride). Segments touching an inactive slot, a jump
    (respawn) longer than 10x the median step, or a NaN are left out."""
    first = max(0, f - int(frames))
    if frames <= 0 or f == first:
        return None
    n = states.particle_count
    pick = np.arange(0, n, max(1, -(-n // max_particles)))
    path = np.asarray(states.positions[first:f + 1][:, pick], np.float64)  # (K, M, 3), oldest first
    k, m = path.shape[0], path.shape[1]
    ok = np.all(np.isfinite(path), axis=2)
    if "active" in states.fields:
        ok &= np.asarray(states.fields["active"][first:f + 1][:, pick], bool)
    elif active is not None:
        ok &= np.asarray(active, bool)[pick][None]
    step = np.linalg.norm(np.diff(path, axis=0), axis=2)  # (K - 1, M)
    good = ok[1:] & ok[:-1]
    if not good.any():
        return None
    typical = float(np.median(step[good])) if good.any() else 0.0
    if typical > 0:
        good &= step <= 10.0 * typical
    seg, part = np.nonzero(good)
    if seg.size == 0:
        return None
    points = path.reshape(-1, 3)
    pairs = np.stack([seg * m + part, (seg + 1) * m + part], axis=1)
    opacity = TRAIL_OPACITY * (seg + 1.0) / (k - 1.0)
    return LineSet(points, pairs, np.array(TRAIL_COLOR), 1.2, opacity)


def frame_options(drawables: "ModelDrawables | None", states, f: int, active=None, *, trails: int = 0) -> dict:
    """Keyword arguments for `Renderer.frame` at frame ``f`` of a run: ``meshes``, ``lines``
    (springs, and motion trails over the last ``trails`` frames in 3-D) and ``active`` (the
    particles drawn as a surface switched off)."""
    options = {"meshes": [], "lines": []}
    if drawables is not None:
        body_q = states.fields.get("body_q")
        options = drawables.frame(states.positions[f], None if body_q is None else body_q[f])
        options["meshes"] = options["meshes"] + drawables.wheels(states.fields, f)
        hidden = drawables.hidden(states.particle_count)
        if hidden is not None:
            active = ~hidden if active is None else (np.asarray(active, bool) & ~hidden)
    if trails and states.dim == 3:
        trail = trail_lines(states, f, trails, active=active)
        if trail is not None:
            options["lines"] = [trail] + options["lines"]
    options["active"] = active
    return options
