"""Solid obstacles on the MAC grid: open face fractions from signed distances.

The open fraction A_f of a face is the part of its area outside every obstacle, estimated
from the signed distance at the face's corners (grid vertices) with the solid boundary taken
as the zero level set of the linear interpolant: exact for a segment (2-D), and for a square
face (3-D) split into four triangles around its centre (centre value = mean of the corners).
These fractions are the weights of the variational pressure projection of Batty, Bertails and
Bridson (2007), "A fast variational framework for accurate solid-fluid coupling" (SIGGRAPH),
which makes curved walls act smoothly instead of as staircases.

Limitations: features thinner than a cell are lost between vertices; fractions below
``MIN_FRACTION`` are set to 0 (they would only worsen the pressure system's conditioning).
"""

from __future__ import annotations

import numpy as np
from numba import njit

MIN_FRACTION = 1e-3


@njit(cache=True, inline="always")
def low_cell(axis, i, j, k):
    """The cell on the low side of face (i, j, k) of ``axis`` (the face's high-side cell is (i, j, k))."""
    if axis == 0:
        return i - 1, j, k
    if axis == 1:
        return i, j - 1, k
    return i, j, k - 1


@njit(cache=True, inline="always")
def add_axis_impulse(lin, ang, b, axis, J, x, y, z):
    """Accumulate an impulse J along axis ``axis`` applied at r = (x, y, z) from body ``b``'s centre:
    lin[b, axis] += J and ang[b] += r x (J e_axis)."""
    lin[b, axis] += J
    if axis == 0:      # r x (J e_x) = (0, z J, -y J)
        ang[b, 1] += z * J
        ang[b, 2] -= y * J
    elif axis == 1:    # r x (J e_y) = (-z J, 0, x J)
        ang[b, 0] -= z * J
        ang[b, 2] += x * J
    else:              # r x (J e_z) = (y J, -x J, 0)
        ang[b, 0] += y * J
        ang[b, 1] -= x * J


@njit(cache=True, inline="always")
def face_cells(f, axis, nx, ny, nz):
    """The cells on either side of face ``f`` (flat index into the (nx+[axis==0], ny+[axis==1],
    nz+[axis==2]) face array of ``axis``): (i, j, k) the high side, (il, jl, kl) the low side, and
    whether the face is interior (not on the domain's side)."""
    fy = ny + (1 if axis == 1 else 0)
    fz = nz + (1 if axis == 2 else 0)
    k = f % fz
    j = (f // fz) % fy
    i = f // (fz * fy)
    idx = i if axis == 0 else (j if axis == 1 else k)
    na = nx if axis == 0 else (ny if axis == 1 else nz)
    il, jl, kl = low_cell(axis, i, j, k)
    return i, j, k, il, jl, kl, idx != 0 and idx != na


def segment_fraction(a, b):
    """Fraction of the segment where the linear interpolant of end values a, b is > 0."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    out = np.where((a > 0) & (b > 0), 1.0, 0.0)
    mixed = (a > 0) != (b > 0)
    pos = np.maximum(a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(mixed, pos / (np.abs(a) + np.abs(b)), out)
    return out


def _triangle_fraction(a, b, c):
    """Area fraction of a triangle where the linear interpolant of vertex values is > 0."""
    npos = (a > 0).astype(int) + (b > 0) + (c > 0)
    out = np.where(npos == 3, 1.0, 0.0)
    # sort the values so the lone vertex is identifiable: lone positive (npos 1) or negative (2)
    v = np.stack([a, b, c])
    with np.errstate(invalid="ignore", divide="ignore"):
        # one positive vertex p, two negative n1, n2: fraction p^2 / ((p - n1)(p - n2))
        p1 = np.max(v, axis=0)
        others = np.sort(v, axis=0)[:2]
        f1 = p1 * p1 / ((p1 - others[0]) * (p1 - others[1]))
        # one negative vertex n, two positive: 1 - n^2 / ((n - p1)(n - p2))
        n1 = np.min(v, axis=0)
        others2 = np.sort(v, axis=0)[1:]
        f2 = 1.0 - n1 * n1 / ((n1 - others2[0]) * (n1 - others2[1]))
    out = np.where(npos == 1, f1, out)
    out = np.where(npos == 2, f2, out)
    return out


def square_fraction(c00, c10, c11, c01):
    """Area fraction of a square (corners in order around it) outside the solid."""
    centre = 0.25 * (c00 + c10 + c11 + c01)
    corners = [c00, c10, c11, c01]
    total = 0.0
    for q in range(4):
        total = total + _triangle_fraction(centre, corners[q], corners[(q + 1) % 4])
    return 0.25 * total


def face_fractions(vertex_sdf, dim):
    """Open fractions of the u, v, w faces from the signed distance at the grid vertices
    ((nx+1, ny+1, nz+1), nz+1 = 2 in 2-D with both layers equal). Returns three 3-D arrays."""
    s = vertex_sdf
    if dim == 2:
        s2 = s[:, :, 0]
        fu = segment_fraction(s2[:, :-1], s2[:, 1:])[:, :, None]
        fv = segment_fraction(s2[:-1, :], s2[1:, :])[:, :, None]
        fw = np.ones((s.shape[0] - 1, s.shape[1] - 1, 2))
    else:
        fu = square_fraction(s[:, :-1, :-1], s[:, 1:, :-1], s[:, 1:, 1:], s[:, :-1, 1:])
        fv = square_fraction(s[:-1, :, :-1], s[1:, :, :-1], s[1:, :, 1:], s[:-1, :, 1:])
        fw = square_fraction(s[:-1, :-1, :], s[1:, :-1, :], s[1:, 1:, :], s[:-1, 1:, :])
    out = []
    for f in (fu, fv, fw):
        f = np.clip(np.nan_to_num(f, nan=0.0), 0.0, 1.0)
        f[f < MIN_FRACTION] = 0.0
        out.append(np.ascontiguousarray(f))
    return out


# ----------------------------------------------------------------------------- shared by fluids
def obstacle_fractions(obstacles, vertex_pts, vertex_shape, dim, t):
    """(sdf (V,), per-axis open fractions) of the faces from the union of the obstacles: the
    smallest signed distance at the grid vertices (C order of `vertex_shape`), then
    `face_fractions` (a 2-D grid is one cell thick: its vertex layer is doubled in z)."""
    sdf = None
    for o in obstacles:
        d = np.asarray(o.signed_distance(vertex_pts, t), dtype=np.float64)
        sdf = d if sdf is None else np.minimum(sdf, d)
    vs = sdf.reshape(vertex_shape)
    if dim == 2:
        vs = np.concatenate([vs, vs], axis=2)
    return sdf, face_fractions(vs, dim)


def nearest_obstacle(obstacles, pts, t, axis):
    """At (M, dim) points: the smallest signed distance over the obstacles, the `axis` velocity
    component of the obstacle attaining it, and its index (one query per obstacle)."""
    from ...collision.shapes import Collider
    m = pts.shape[0]
    best = np.full(m, np.inf)
    vel = np.zeros(m)
    owner = np.zeros(m, np.int64)
    if m == 0:
        return best, vel, owner
    d = np.empty(m)
    nrm = np.empty(pts.shape)
    v = np.empty(pts.shape)
    for i, o in enumerate(obstacles):
        if isinstance(o, Collider):      # fills preallocated outputs: one query for both
            o.query(pts, t, d, nrm, v)
            di, vi = d, v[:, axis]
        elif isinstance(o, PlaneSlice):  # one serial query for both
            di, _, vv = o.query(pts, t)
            vi = vv[:, axis]
        else:
            di = np.asarray(o.signed_distance(pts, t), dtype=np.float64)
            vi = np.asarray(o.velocity(pts, t), dtype=np.float64)[:, axis]
        take = di < best
        best = np.where(take, di, best)
        vel = np.where(take, vi, vel)
        owner = np.where(take, i, owner)
    return best, vel, owner


def solid_faces(obstacles, owners, vertex_pts, face_pts, vertex_shape, dim, t, frac, solid):
    """Open fractions and solid velocities of every face from a list of obstacles (the
    obstacle part of `GridFluid`'s obstacles stage as a function, so `LiquidFluid` uses the
    same cut cells).

    obstacles : objects with ``signed_distance(points, t)`` and ``velocity(points, t)`` taking
        (M, dim) points; owners : (len(obstacles),) int, the rigid body of each (-1: none).
    vertex_pts : (V, dim) grid vertices, C order of `vertex_shape` ((nx+1, ny+1, nz+1), or
        (nx+1, ny+1, 1) in 2-D); face_pts : per axis (F_a, dim) face centres in C order.
    frac, solid : three face arrays each, written: open fraction (from `face_fractions`) and,
        on faces with fraction < 1, the velocity component of the nearest obstacle (the one
        with the smallest signed distance at the face centre). In 2-D frac[2] is set to 0.
    Returns, per axis, (closed flat face indices, their open fractions, owner body per face),
    the faces whose pressure pushes a body. Domain sides are left to the caller."""
    _, fr = obstacle_fractions(obstacles, vertex_pts, vertex_shape, dim, t)
    owners = np.asarray(owners, np.int64)
    cut = []
    for a in range(3):
        frac[a][...] = fr[a]
        solid[a][...] = 0.0
    if dim == 2:
        frac[2][...] = 0.0
    for a in range(dim):
        closed = np.flatnonzero(frac[a].reshape(-1) < 1.0)
        owner = np.full(closed.size, -1, np.int64)
        if closed.size:
            _, vel, nearest = nearest_obstacle(obstacles, face_pts[a][closed], t, a)
            owner = owners[nearest]
            solid[a].reshape(-1)[closed] = vel
        cut.append((closed.astype(np.int64), frac[a].reshape(-1)[closed].copy(), owner))
    if dim == 2:
        cut.append((np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)))
    return cut


class PlaneSlice:
    """A collider as a fluid obstacle of dimension `dim`, queried by a serial kernel.

    For dim 2 and a 3-D collider (e.g. a `BodyShape` of the rigid shape table) this is its
    z = 0 slice: a 2-D fluid coupled to 3-D rigid bodies moving in the x-y plane sees their
    cross-sections (points (M, 2) are taken at z = 0; normals and velocities keep x and y).
    Boxes, cylinders and capsules whose (body-frame) axis is along z are then extended along z
    by `EXTEND` m on a copy of the collider: inside a thin slab the nearest surface would
    otherwise be a z face, and the in-plane signed distance and normal (used to push particles
    out) would be wrong. Other shapes (spheres, shapes lying in the plane) are sliced as they are.

    Queries of the colliders of `inertia.collision.shapes` run the serial version of their
    kernel (the parallel one pays a thread launch per call, which dominates on the few thousand
    points a fluid asks about per step); colliders with their own ``query`` use it."""

    EXTEND = 1e3

    def __init__(self, collider, dim=2):
        import copy
        from ...collision import distance as _d
        from ...collision.shapes import Collider
        self.dim = int(dim)
        kind = getattr(collider, "kind", None)
        cf = getattr(collider, "_cf", None)
        if self.dim == 2 and collider.dim == 3 and cf is not None \
                and kind in (_d.BOX, _d.CYLINDER, _d.CAPSULE):
            cf = cf.copy()
            if kind == _d.BOX:   # [centre (3), rotation (3x3, row-major), half extents (3)]
                k = int(np.argmax(np.abs(cf[9:12])))     # local axis closest to z
                if abs(cf[9 + k]) > 0.99:
                    cf[12 + k] = self.EXTEND
            elif kind == _d.CYLINDER:   # [centre (3), axis (3), radius, half height]
                if abs(cf[5]) > 0.99:
                    cf[7] = self.EXTEND
            else:   # capsule [a (3), b (3), radius]
                ax = cf[3:6] - cf[0:3]
                if np.linalg.norm(ax) > 0 and abs(ax[2]) > 0.99 * np.linalg.norm(ax):
                    cf[2], cf[5] = -self.EXTEND, self.EXTEND
            collider = copy.copy(collider)
            collider._cf = cf
        self.collider = collider
        self.motion = getattr(collider, "motion", None)
        self._fast = isinstance(collider, Collider) and type(collider).query is Collider.query
        if self._fast:
            self._kernel = _d.query_points.serial   # small batches: the serial twin
            self._kinds = _d.kinds_token((collider.kind,))   # compile this kind's distance only

    def query(self, points, t=0.0):
        """(distance (M,), normal (M, dim), velocity (M, dim)) at points (M, dim)."""
        c = self.collider
        pts = np.ascontiguousarray(points, dtype=np.float64)
        m = pts.shape[0]
        d, n, v = np.empty(m), np.empty((m, self.dim)), np.empty((m, self.dim))
        if self._fast:
            vel, omega = c._rigid_velocity(t)
            self._kernel(pts, self._kinds, c.kind, c._cf, c._ci, c._packed_pose(t), c._ref, c.moving,
                         np.ascontiguousarray(vel, dtype=np.float64),
                         np.ascontiguousarray(omega, dtype=np.float64), d, n, v)
            return d, n, v
        if c.dim == self.dim:
            c.query(pts, t, d, n, v)
            return d, n, v
        p3 = np.zeros((m, 3))
        p3[:, :2] = pts[:, :2]
        n3, v3 = np.empty((m, 3)), np.empty((m, 3))
        c.query(p3, t, d, n3, v3)
        return d, n3[:, :self.dim].copy(), v3[:, :self.dim].copy()

    def signed_distance(self, points, t=0.0):
        return self.query(points, t)[0]

    def normal(self, points, t=0.0):
        return self.query(points, t)[1]

    def velocity(self, points, t=0.0):
        return self.query(points, t)[2]

    def __repr__(self):
        return f"PlaneSlice({self.collider!r}, dim={self.dim})"


def rigid_shape_obstacles(rigid):
    """The shape rows of a rigid world (anything with ``.model`` and ``.state``) as obstacles: one
    `BodyShape` per row the signed distance covers (SDF rows are skipped), bound to the live pose and
    velocity of its body when it moves. Returns (obstacles, owner body per obstacle (-1: static row))."""
    from ...collision.shapes import BodyShape
    model = rigid.model
    obst, owner = [], []
    for s in range(int(model.shape_count)):
        bs = BodyShape(model, s)
        if getattr(bs, "unsupported", False):
            continue
        if bs.moving:
            b = bs.body
            bs.bind(lambda t, b=b: rigid.state.body_q[b], lambda t, b=b: rigid.state.body_qd[b])
        obst.append(bs)
        owner.append(bs.body if bs.moving else -1)
    return obst, np.asarray(owner, np.int64)


def rigid_obstacles(rigid, dim):
    """`rigid_shape_obstacles` wrapped in `PlaneSlice` (serial queries; in 2-D the z = 0 cross-section):
    the liquid's obstacles. Returns (obstacles, owner body per obstacle (-1: static row))."""
    obst, owner = rigid_shape_obstacles(rigid)
    return [PlaneSlice(o, dim) for o in obst], owner
