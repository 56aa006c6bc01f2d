"""Scene queries over a `RigidWorld`'s shape table: ray casts, shape casts, overlaps, closest points, AABBs.

These are the engine calls game code makes between steps (line of sight, ground probes, "what is in this
box", a character's sweep). Every query reads the bodies' current poses (``world.state.body_q``):
`WorldQueries.refresh` recomputes the shapes' world poses and tight AABBs (one kernel over the S shapes,
the broad phase's ``shape_world_bounds`` at dt = 0 minus the margins), and each query culls shapes by
their AABB before the exact test, in one compiled loop over the shapes.

Exact tests (closed forms and GJK/EPA from ``inertia.geometry``):
- ray cast: per shape the closed forms of ``inertia.geometry.raycast.ray_cast`` (Kay and Kajiya 1986 slabs
  for the AABB cull and boxes; Haines 1991 for hulls); a ray starting inside a solid does not hit it.
- shape cast (a convex shape swept by a translation): conservative advancement on GJK distances
  (Mirtich 1996), ``raycast.shape_cast``; against planes the closed form s = gap / closing speed.
- overlap and closest points: the signed distance of ``convex.shape_distance`` (GJK, then EPA for
  penetration; Gilbert, Johnson and Keerthi 1988; van den Bergen 2001); against planes the support point
  along the inward normal.

Collision filtering: a shape is seen by a query with ``mask`` when ``shape_group & mask != 0``; sensors are
skipped unless ``include_sensors``.

References
- Kay, T. L. and Kajiya, J. T. (1986). Ray tracing complex scenes. SIGGRAPH '86.
- Haines, E. (1991). Fast ray-convex polyhedron intersection. Graphics Gems II.
- Gilbert, E. G., Johnson, D. W. and Keerthi, S. S. (1988). A fast procedure for computing the distance
  between complex objects in three-dimensional space. IEEE J. Robotics and Automation 4(2).
- van den Bergen, G. (2001). Proximity queries and penetration depth computation on 3D game objects. GDC.
- Mirtich, B. (1996). Impulse-based dynamic simulation of rigid body systems. PhD thesis (conservative
  advancement).

Limitations
- The AABB cull is a linear pass over the shapes (O(S) per query, no tree); fine for thousands of shapes
  and a few hundred queries per frame, not for tens of thousands of rays.
- Query shapes must be convex (sphere, box, capsule, cylinder, convex hull). Triangle meshes and
  heightfields are seen by rays (their triangles under the ray's box, Moller-Trumbore) but not yet by
  shape casts, overlaps and closest points.
- Shape casts are translational (no rotation during the sweep) and stop within ``tolerance`` (1e-6 m)
  of contact; a query shape that already overlaps a shape reports fraction 0 for it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .. import math as _m
from ..geometry import shapes as S
from ..geometry.convex import build_convex_hull, shape_distance, support_local
from ..geometry.raycast import ray_cast as _ray_cast_shape
from ..geometry.trimesh_collide import ray_triangles
from ..geometry.raycast import shape_cast as _shape_cast_pair

__all__ = ["RayHit", "ShapeHit", "ClosestPoints", "WorldQueries"]

_CONVEX_QUERY = {"sphere": S.SPHERE, "box": S.BOX, "capsule": S.CAPSULE, "cylinder": S.CYLINDER,
                 "convex_hull": S.CONVEX_HULL}
_CAST_TOLERANCE = 1e-6
_CAST_ITERATIONS = 64


class RayHit(NamedTuple):
    """One ray hit: ``shape`` and ``body`` indices (body -1 = static world), world ``point`` (3,) m, unit
    outward surface ``normal`` (3,), ``fraction`` of the ray's translation in [0, 1], ``distance`` m."""
    shape: int
    body: int
    point: np.ndarray
    normal: np.ndarray
    fraction: float
    distance: float


class ShapeHit(NamedTuple):
    """First contact of a swept shape: ``shape``/``body`` hit, ``fraction`` of the translation at contact,
    ``point`` (3,) on the hit shape, ``normal`` (3,) from the swept shape towards the hit shape."""
    shape: int
    body: int
    fraction: float
    point: np.ndarray
    normal: np.ndarray


class ClosestPoints(NamedTuple):
    """``distance`` m (negative: penetration depth), ``point_a``/``point_b`` (3,) on each shape's surface,
    unit ``normal`` (3,) from A to B."""
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray


# ----------------------------------------------------------------------------------------------- kernels
@njit(cache=True)
def _visible(s, shapes, mask, include_sensors):
    if (shapes.shape_group[s] & mask) == 0:
        return False
    if shapes.shape_is_sensor[s] and not include_sensors:
        return False
    return True


@njit(cache=True)
def _ray_hits(shapes, pose, aabb, face_planes, face_start, face_count, origin, translation, mask,
              include_sensors, out_shape, out_t, out_n):
    """All hits of the segment origin + s translation, s in [0, 1]; returns their count (unsorted)."""
    tris = np.zeros((0, 3), np.int32)
    n = 0
    for s in range(shapes.shape_type.shape[0]):
        if not _visible(s, shapes, mask, include_sensors):
            continue
        t = shapes.shape_type[s]
        # slab test of the segment against the shape's AABB
        lo, hi = 0.0, 1.0
        for k in range(3):
            d = translation[k]
            if d == 0.0:
                if origin[k] < aabb[s, k] or origin[k] > aabb[s, 3 + k]:
                    lo, hi = 1.0, 0.0
            else:
                t0 = (aabb[s, k] - origin[k]) / d
                t1 = (aabb[s, 3 + k] - origin[k]) / d
                if t0 > t1:
                    t0, t1 = t1, t0
                lo = max(lo, t0)
                hi = min(hi, t1)
        if lo > hi:
            continue
        if t == S.TRIANGLE_MESH or t == S.HEIGHTFIELD:
            th, nt = ray_triangles(shapes, s, pose[s], origin, translation)
            nrm = np.array(nt)
        else:
            th, nrm = _ray_cast_shape(t, shapes.shape_params[s], pose[s], shapes.geom_vertices,
                                      shapes.shape_vert_start[s], face_planes, face_start[s], face_count[s], tris,
                                      0, 0, origin, translation, 1.0)
        if th <= 1.0:
            out_shape[n] = s
            out_t[n] = th
            out_n[n, :] = nrm
            n += 1
    return n


@njit(cache=True)
def _aabb_overlap(a, b, s):
    for k in range(3):
        if a[k] > b[s, 3 + k] or b[s, k] > a[3 + k]:
            return False
    return True


@njit(cache=True)
def _plane_distance(qtype, qparams, qpose, verts, qstart, qcount, plane_pose):
    """Signed distance of a convex shape to a half-space (solid below local z = 0): deepest point, normal
    from the shape to the plane (-n), point on the plane."""
    q = plane_pose[3:7]
    # n = R(q) z
    n = np.empty(3)
    n[0] = 2.0 * (q[1] * q[3] + q[0] * q[2])
    n[1] = 2.0 * (q[2] * q[3] - q[0] * q[1])
    n[2] = 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2])
    d_local = _m.quat_rotate_inv(qpose[3:7], -n)
    p = _m.transform_point(qpose, support_local(qtype, qparams, verts, qstart, qcount, d_local))
    dist = 0.0
    for k in range(3):
        dist += n[k] * (p[k] - plane_pose[k])
    return dist, p, p - dist * n, -n


@njit(cache=True)
def _cast_first(shapes, pose, aabb, verts, qtype, qparams, qpose, qstart, qcount, qbox, translation, mask,
                include_sensors, skip_body):
    """First shape met by the convex query shape swept along translation: (shape, s, point, normal)."""
    best_s = np.inf
    best = -1
    best_p = np.zeros(3)
    best_n = np.zeros(3)
    sweep = qbox.copy()
    for k in range(3):
        sweep[k] += min(0.0, translation[k])
        sweep[3 + k] += max(0.0, translation[k])
    for s in range(shapes.shape_type.shape[0]):
        if not _visible(s, shapes, mask, include_sensors) or shapes.shape_body[s] == skip_body and skip_body >= 0:
            continue
        if not _aabb_overlap(sweep, aabb, s):
            continue
        t = shapes.shape_type[s]
        if t == S.PLANE:
            d0, p, pp, nrm = _plane_distance(qtype, qparams, qpose, verts, qstart, qcount, pose[s])
            # nrm points from the shape into the plane: the gap closes at translation . nrm
            closing = nrm[0] * translation[0] + nrm[1] * translation[1] + nrm[2] * translation[2]
            if d0 <= _CAST_TOLERANCE:
                sh = 0.0
            elif closing <= 0.0:
                continue
            else:
                sh = d0 / closing
            if sh > 1.0:
                continue
            pt = pp + sh * translation
        elif t == S.TRIANGLE_MESH or t == S.HEIGHTFIELD:
            continue
        else:
            sh, nrm, pt = _shape_cast_pair(qtype, qparams, qpose, qstart, qcount, translation, t,
                                           shapes.shape_params[s], pose[s], shapes.shape_vert_start[s],
                                           shapes.shape_vert_count[s], verts, _CAST_TOLERANCE, _CAST_ITERATIONS)
        if sh < best_s:
            best_s, best, best_p, best_n = sh, s, pt, nrm
    return best, best_s, best_p, best_n


@njit(cache=True)
def _overlaps(shapes, pose, aabb, verts, qtype, qparams, qpose, qstart, qcount, qbox, mask, include_sensors,
              out):
    n = 0
    for s in range(shapes.shape_type.shape[0]):
        if not _visible(s, shapes, mask, include_sensors) or not _aabb_overlap(qbox, aabb, s):
            continue
        t = shapes.shape_type[s]
        if t == S.PLANE:
            d = _plane_distance(qtype, qparams, qpose, verts, qstart, qcount, pose[s])[0]
        elif t == S.TRIANGLE_MESH or t == S.HEIGHTFIELD:
            continue
        else:
            d = shape_distance(qtype, qparams, qpose, qstart, qcount, t, shapes.shape_params[s], pose[s],
                               shapes.shape_vert_start[s], shapes.shape_vert_count[s], verts)[0]
        if d < 0.0:
            out[n] = s
            n += 1
    return n


@njit(cache=True)
def _query_box(qtype, qparams, qpose, verts, qstart, qcount):
    """World AABB (6,) of a convex shape from its support points along +-x, +-y, +-z."""
    box = np.empty(6)
    for k in range(3):
        for sgn in (-1.0, 1.0):
            d = np.zeros(3)
            d[k] = sgn
            p = _m.transform_point(qpose, support_local(qtype, qparams, verts, qstart, qcount,
                                                        _m.quat_rotate_inv(qpose[3:7], d)))
            if sgn < 0:
                box[k] = p[k]
            else:
                box[3 + k] = p[k]
    return box


# ----------------------------------------------------------------------------------------------- facade
class WorldQueries:
    """Queries over ``world``'s shapes at the bodies' current poses.

    >>> q = WorldQueries(world)
    >>> hit = q.ray_cast((0, 0, 5), (0, 0, -10))       # closest hit or None
    >>> q.overlap("sphere", (0.5,), position=(0, 0, 1))  # shape indices

    Poses and AABBs are refreshed automatically when the world's step index changes; call `refresh`
    after moving bodies by hand."""

    def __init__(self, world):
        self.world = world
        m = world.model
        self.model = m
        self._shapes = m.shapes()
        ns = m.shape_count
        self._pose = np.zeros((ns, 7))
        self._aabb = np.zeros((ns, 6))
        # hull face planes (ray casts need them; the model stores only hull vertices)
        planes, start, count = [], np.zeros(ns, np.int32), np.zeros(ns, np.int32)
        nf = 0
        for s in range(ns):
            if m.shape_type[s] == S.CONVEX_HULL:
                v = m.geom_vertices[m.shape_vert_start[s]:m.shape_vert_start[s] + m.shape_vert_count[s]]
                fp = build_convex_hull(v).face_planes
                start[s], count[s] = nf, len(fp)
                planes.append(fp)
                nf += len(fp)
        self._face_planes = np.concatenate(planes) if planes else np.zeros((0, 4))
        self._face_start, self._face_count = start, count
        self._hit_shape = np.zeros(ns, np.int64)
        self._hit_t = np.zeros(ns)
        self._hit_n = np.zeros((ns, 3))
        self._stamp = None
        self.refresh()

    # ------------------------------------------------------------------ bookkeeping
    def refresh(self) -> None:
        """Recompute shape world poses and tight AABBs from ``world.state.body_q``."""
        w, m = self.world, self.model
        st = w.state
        w._k.shape_world_bounds(self._shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, 0.0,
                                self._pose, self._aabb)
        # shape_world_bounds fattens by the margin: take it off (infinite plane boxes stay infinite)
        self._aabb[:, :3] += m.shape_margin[:, None]
        self._aabb[:, 3:] -= m.shape_margin[:, None]
        self._stamp = int(st.step_index[0])

    def _fresh(self):
        if self._stamp != int(self.world.state.step_index[0]):
            self.refresh()

    @property
    def shape_pose(self) -> np.ndarray:
        """(S, 7) world poses of the shapes at the last refresh."""
        self._fresh()
        return self._pose

    @property
    def shape_aabb(self) -> np.ndarray:
        """(S, 6) tight world AABBs (min xyz, max xyz) at the last refresh; planes are unbounded (1e30)."""
        self._fresh()
        return self._aabb

    # ------------------------------------------------------------------ rays
    def ray_cast_all(self, origin, translation, *, mask: int = -1, include_sensors: bool = False) -> list[RayHit]:
        """Every shape the segment ``origin`` -> ``origin + translation`` enters, nearest first."""
        o = _vec3(origin, "origin")
        d = _vec3(translation, "translation")
        length = float(np.linalg.norm(d))
        if length == 0.0:
            raise ValueError("translation must be a non-zero vector (the ray's direction times its length)")
        self._fresh()
        n = _ray_hits(self._shapes, self._pose, self._aabb, self._face_planes, self._face_start,
                      self._face_count, o, d, np.int32(mask), bool(include_sensors), self._hit_shape,
                      self._hit_t, self._hit_n)
        order = np.lexsort((self._hit_shape[:n], self._hit_t[:n]))
        out = []
        for i in order:
            s, t = int(self._hit_shape[i]), float(self._hit_t[i])
            out.append(RayHit(s, int(self.model.shape_body[s]), o + t * d, self._hit_n[i].copy(), t, t * length))
        return out

    def ray_cast(self, origin, translation, *, mask: int = -1, include_sensors: bool = False) -> RayHit | None:
        """The nearest hit of the segment ``origin`` -> ``origin + translation``, or None."""
        hits = self.ray_cast_all(origin, translation, mask=mask, include_sensors=include_sensors)
        return hits[0] if hits else None

    # ------------------------------------------------------------------ shapes
    def _query_shape(self, shape_type, params, position, orientation, vertices):
        if shape_type not in _CONVEX_QUERY:
            raise ValueError(f"shape_type must be one of {sorted(_CONVEX_QUERY)}; got {shape_type!r}")
        code = _CONVEX_QUERY[shape_type]
        p = np.zeros(4)
        params = np.asarray(() if params is None else params, dtype=np.float64).reshape(-1)
        need = {S.SPHERE: 1, S.BOX: 3, S.CAPSULE: 2, S.CYLINDER: 2}.get(code, 0)
        if len(params) > 4:
            raise ValueError(f"params of a {shape_type} query must have at most 4 numbers; got {len(params)}")
        p[:len(params)] = params
        if np.any(~np.isfinite(p)) or np.any(p[:need] <= 0):
            raise ValueError(f"params of a {shape_type} query must be {need} positive finite numbers; got "
                             f"{params.tolist()}")
        pose = np.concatenate([_vec3(position, "position"), _unit_quat(orientation)])
        verts = self.model.geom_vertices
        start = count = 0
        if code == S.CONVEX_HULL:
            hv = build_convex_hull(vertices, name="vertices").vertices
            start, count = len(verts), len(hv)
            verts = np.concatenate([verts, hv])
        box = _query_box(code, p, pose, verts, start, count)
        return code, p, pose, verts, start, count, box

    def shape_cast(self, shape_type: str, params, translation, *, position=(0.0, 0.0, 0.0),
                   orientation=(1.0, 0.0, 0.0, 0.0), vertices=None, mask: int = -1,
                   include_sensors: bool = False, ignore_body: int = -1) -> ShapeHit | None:
        """Sweep a convex shape from its pose along ``translation``; the first shape it touches, or None.

        ``params`` as in the shape table (`inertia.geometry.shapes`); ``vertices`` for a convex hull;
        ``ignore_body`` skips that body's shapes (a character sweeping its own collider)."""
        code, p, pose, verts, start, count, box = self._query_shape(shape_type, params, position, orientation,
                                                                    vertices)
        d = _vec3(translation, "translation")
        self._fresh()
        s, frac, pt, nrm = _cast_first(self._shapes, self._pose, self._aabb, verts, code, p, pose, start, count,
                                       box, d, np.int32(mask), bool(include_sensors), int(ignore_body))
        if s < 0:
            return None
        return ShapeHit(int(s), int(self.model.shape_body[s]), float(frac), pt, nrm)

    def overlap(self, shape_type: str, params, *, position=(0.0, 0.0, 0.0), orientation=(1.0, 0.0, 0.0, 0.0),
                vertices=None, mask: int = -1, include_sensors: bool = False) -> np.ndarray:
        """Indices (ascending) of the shapes that a convex query shape at the given pose overlaps
        (signed distance < 0; touching does not count)."""
        code, p, pose, verts, start, count, box = self._query_shape(shape_type, params, position, orientation,
                                                                    vertices)
        self._fresh()
        n = _overlaps(self._shapes, self._pose, self._aabb, verts, code, p, pose, start, count, box,
                      np.int32(mask), bool(include_sensors), self._hit_shape)
        return self._hit_shape[:n].copy()

    def closest_points(self, shape_a: int, shape_b: int) -> ClosestPoints:
        """Signed distance, surface points and normal (A -> B) between two shapes of the world (convex shapes
        or a convex shape and a plane)."""
        m = self.model
        for name, s in (("shape_a", shape_a), ("shape_b", shape_b)):
            if not isinstance(s, (int, np.integer)) or not 0 <= s < m.shape_count:
                raise ValueError(f"{name} must be a shape index in [0, {m.shape_count - 1}]; got {s!r}")
        ta, tb = int(m.shape_type[shape_a]), int(m.shape_type[shape_b])
        bad = (S.TRIANGLE_MESH, S.HEIGHTFIELD)
        if ta in bad or tb in bad or (ta == S.PLANE and tb == S.PLANE):
            raise ValueError("closest_points takes two convex shapes or a convex shape and a plane; got types "
                             f"{ta} and {tb} (allowed: sphere, box, capsule, cylinder, convex_hull, plane)")
        self._fresh()
        P, V = self._pose, m.geom_vertices
        if tb == S.PLANE:
            d, pa, pb, n = _plane_distance(ta, m.shape_params[shape_a], P[shape_a], V, m.shape_vert_start[shape_a],
                                           m.shape_vert_count[shape_a], P[shape_b])
            return ClosestPoints(float(d), pa, pb, n)
        if ta == S.PLANE:
            d, pb, pa, n = _plane_distance(tb, m.shape_params[shape_b], P[shape_b], V, m.shape_vert_start[shape_b],
                                           m.shape_vert_count[shape_b], P[shape_a])
            return ClosestPoints(float(d), pa, pb, -n)
        d, pa, pb, n = shape_distance(ta, m.shape_params[shape_a], P[shape_a], m.shape_vert_start[shape_a],
                                      m.shape_vert_count[shape_a], tb, m.shape_params[shape_b], P[shape_b],
                                      m.shape_vert_start[shape_b], m.shape_vert_count[shape_b], V)
        return ClosestPoints(float(d), pa, pb, n)

    def aabb_query(self, lower, upper, *, mask: int = -1, include_sensors: bool = False) -> np.ndarray:
        """Indices (ascending) of the shapes whose tight world AABB overlaps the box [lower, upper]."""
        lo, hi = _vec3(lower, "lower"), _vec3(upper, "upper")
        if np.any(lo > hi):
            raise ValueError(f"lower must be <= upper componentwise; got {lo.tolist()} and {hi.tolist()}")
        self._fresh()
        a = self._aabb
        m = self.model
        hit = np.all(a[:, :3] <= hi, axis=1) & np.all(a[:, 3:] >= lo, axis=1)
        hit &= (m.shape_group & np.int32(mask)) != 0
        if not include_sensors:
            hit &= ~m.shape_is_sensor
        return np.flatnonzero(hit)


def _vec3(v, name):
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers; got {v!r}")
    return a


def _unit_quat(q):
    a = np.asarray(q, dtype=np.float64).reshape(-1)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or abs(math.sqrt(a @ a) - 1.0) > 1e-6:
        raise ValueError(f"orientation must be a unit quaternion (w, x, y, z); got {q!r}")
    return a
