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

The per-step path (`CutCells`) allocates nothing: its work arrays are made once per grid and
the fractions are a Numba kernel (`fractions_into`, the same arithmetic as the NumPy
`face_fractions` kept as the readable reference). Colliders of `inertia.collision.shapes` are
queried into those arrays; an obstacle that only offers ``signed_distance`` / ``velocity``
(duck-typed) still returns new arrays from its own methods.
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
    ((nx+1, ny+1, nz+1), nz+1 = 2 in 2-D with both layers equal). Returns three 3-D arrays.
    The NumPy reference of the step's kernel `fractions_into` (same bits, new arrays)."""
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


# ----------------------------------------------------------------------------- per-step kernels
@njit(cache=True, inline="always")
def _segment_value(a, b):
    """`segment_fraction` of one segment, before the clean-up of `_clean_fraction` (NaN in, NaN
    out where the NumPy version's np.maximum propagates it)."""
    if a > 0 and b > 0:
        return 1.0
    if (a > 0) != (b > 0):
        if a != a or b != b:
            return np.nan
        return max(a, b) / (abs(a) + abs(b))
    return 0.0


@njit(cache=True, inline="always")
def _triangle_value(a, b, c):
    """`_triangle_fraction` of one triangle: the same operations on the sorted vertex values
    (lo <= mid <= hi), so the same bits."""
    npos = (1 if a > 0 else 0) + (1 if b > 0 else 0) + (1 if c > 0 else 0)
    if npos == 3:
        return 1.0
    if npos == 0:
        return 0.0
    if a != a or b != b or c != c:
        return np.nan
    lo, mid, hi = a, b, c
    if lo > mid:
        lo, mid = mid, lo
    if mid > hi:
        mid, hi = hi, mid
    if lo > mid:
        lo, mid = mid, lo
    if npos == 1:    # one positive vertex p = hi: p^2 / ((p - n1)(p - n2))
        return hi * hi / ((hi - lo) * (hi - mid))
    return 1.0 - lo * lo / ((lo - mid) * (lo - hi))   # one negative vertex n = lo


@njit(cache=True, inline="always")
def _square_value(c00, c10, c11, c01):
    """`square_fraction` of one square face (four triangles around the mean of the corners)."""
    centre = 0.25 * (c00 + c10 + c11 + c01)
    total = 0.0
    total = total + _triangle_value(centre, c00, c10)
    total = total + _triangle_value(centre, c10, c11)
    total = total + _triangle_value(centre, c11, c01)
    total = total + _triangle_value(centre, c01, c00)
    return 0.25 * total


@njit(cache=True, inline="always")
def _clean_fraction(f):
    """NaN -> 0, clip to [0, 1], below MIN_FRACTION -> 0 (the end of `face_fractions`)."""
    if f != f:
        return 0.0
    f = min(max(f, 0.0), 1.0)
    return 0.0 if f < MIN_FRACTION else f


@njit(cache=True)
def fractions_into(s, dim, fu, fv, fw):
    """`face_fractions` into fu, fv, fw from the vertex signed distance s ((nx+1, ny+1, nz+1);
    (nx+1, ny+1, 1) in 2-D, where fw is set to 1 as the NumPy version does). Serial."""
    if dim == 2:
        for i in range(fu.shape[0]):
            for j in range(fu.shape[1]):
                fu[i, j, 0] = _clean_fraction(_segment_value(s[i, j, 0], s[i, j + 1, 0]))
        for i in range(fv.shape[0]):
            for j in range(fv.shape[1]):
                fv[i, j, 0] = _clean_fraction(_segment_value(s[i, j, 0], s[i + 1, j, 0]))
        fw[...] = 1.0
        return
    for i in range(fu.shape[0]):
        for j in range(fu.shape[1]):
            for k in range(fu.shape[2]):
                fu[i, j, k] = _clean_fraction(_square_value(s[i, j, k], s[i, j + 1, k],
                                                            s[i, j + 1, k + 1], s[i, j, k + 1]))
    for i in range(fv.shape[0]):
        for j in range(fv.shape[1]):
            for k in range(fv.shape[2]):
                fv[i, j, k] = _clean_fraction(_square_value(s[i, j, k], s[i + 1, j, k],
                                                            s[i + 1, j, k + 1], s[i, j, k + 1]))
    for i in range(fw.shape[0]):
        for j in range(fw.shape[1]):
            for k in range(fw.shape[2]):
                fw[i, j, k] = _clean_fraction(_square_value(s[i, j, k], s[i + 1, j, k],
                                                            s[i + 1, j + 1, k], s[i, j + 1, k]))


@njit(cache=True)
def _take_nearest(d, vel, axis, index, best, best_vel, owner):
    """Where d < best: best = d, best_vel = vel[:, axis], owner = index (one obstacle's turn in
    `CutCells._nearest`)."""
    for m in range(d.shape[0]):
        if d[m] < best[m]:
            best[m] = d[m]
            best_vel[m] = vel[m, axis]
            owner[m] = index


@njit(cache=True)
def _min_into(d, out, first):
    """out = d (first obstacle) or min(out, d) (np.minimum)."""
    for m in range(d.shape[0]):
        if first or d[m] < out[m] or d[m] != d[m]:
            out[m] = d[m]


@njit(cache=True)
def _mark_inside(d, inside, first):
    """inside |= d < 0 (inside = d < 0 for the first obstacle)."""
    for m in range(d.shape[0]):
        if first:
            inside[m] = d[m] < 0.0
        elif d[m] < 0.0:
            inside[m] = True


@njit(cache=True)
def _cut_faces(frac, solid, faces, open_frac):
    """The closed faces (frac < 1) of one axis (flat arrays) in C order: their flat index and
    open fraction; solid = 0 everywhere (`_cut_values` then writes the closed faces). Returns
    the closed-face count."""
    n = 0
    for f in range(frac.shape[0]):
        solid[f] = 0.0
        if frac[f] < 1.0:
            faces[n] = f
            open_frac[n] = frac[f]
            n += 1
    return n


@njit(cache=True)
def _cut_values(n, faces, best_vel, owner, per_node, owner_body, solid, body):
    """solid[faces[m]] = the nearest obstacle's velocity, body[m] = its body, for m < n;
    best_vel / owner are indexed by face (per_node) or by closed-face rank."""
    for m in range(n):
        r = faces[m] if per_node else m
        solid[faces[m]] = best_vel[r]
        body[m] = owner_body[owner[r]]


@njit(cache=True)
def _gather_rows(src, idx, n, out):
    """out[m] = src[idx[m]] for m < n (rows of a points array)."""
    for m in range(n):
        for c in range(src.shape[1]):
            out[m, c] = src[idx[m], c]


def query_into(o, pts, t, d, nrm, vel, kernel):
    """Distance (d (M,)) and surface velocity (vel (M, dim)) of obstacle `o` at pts (M, dim),
    written in place: a `PlaneSlice` or a plain `Collider` through the query kernel (no (M,)
    array made), a collider with its own ``query`` through it, anything else through its
    ``signed_distance`` and ``velocity`` (new arrays)."""
    from ...collision import distance as _d
    from ...collision.shapes import Collider
    if isinstance(o, PlaneSlice):
        o.query_into(pts, t, d, nrm, vel)
    elif isinstance(o, Collider) and type(o).query is Collider.query:
        v, w = o._rigid_velocity(t)
        kernel(pts, _d.kinds_token((o.kind,)), o.kind, o._cf, o._ci, o._packed_pose(t), o._ref, o.moving, v, w,
               d, nrm, vel)
    elif isinstance(o, Collider):
        o.query(pts, t, d, nrm, vel)
    else:
        d[...] = np.asarray(o.signed_distance(pts, t), dtype=np.float64)
        vel[...] = np.asarray(o.velocity(pts, t), dtype=np.float64)


class CutCells:
    """The obstacles stage of both grid fluids with its work arrays made once per grid.

    Built from the grid's vertex, face-centre and cell-centre positions (C order; see
    `solver.MACGrid`); `update` fills, from a list of obstacles at time t:
    open fractions and solid velocities of the faces, the cells whose centre is inside a solid,
    optionally every face node's nearest obstacle (the implicit viscosity's boundary data), and
    ``cut``: per axis (closed flat face indices, their open fractions, owning body), views of
    length ``count[a]`` into preallocated arrays (valid until the next `update`).

    Arrays (written by `update`): ``vertex_sdf`` (V,) m, the union's signed distance at the
    vertices; ``best``, ``near_vel``, ``near`` per axis: the nearest obstacle's signed distance
    (m), velocity component (m/s) and index at the closed faces (first ``count[a]``) or at every
    face node (``nodes=True``); ``d``, ``nrm``, ``vel``: one obstacle's query (scratch)."""

    def __init__(self, vertex_pts, vertex_shape, face_pts, cell_pts, dim, parallel=False):
        from ...collision import distance as _d
        from . import kernels as K
        self.dim = int(dim)
        self.vertex_pts = vertex_pts
        self.vertex_shape = tuple(int(x) for x in vertex_shape)
        self.face_pts = list(face_pts)
        self.cell_pts = cell_pts
        nv, nc = vertex_pts.shape[0], cell_pts.shape[0]
        nf = [p.shape[0] for p in self.face_pts]
        m = max([nv, nc] + nf)
        self.d = np.empty(m)
        self.nrm = np.empty((m, self.dim))
        self.vel = np.empty((m, self.dim))
        self.vertex_sdf = np.empty(nv)
        self.inside = np.zeros(nc, dtype=np.bool_)
        self.best = [np.empty(f) for f in nf]
        self.near_vel = [np.empty(f) for f in nf]
        self.near = [np.empty(f, np.int64) for f in nf]
        self.pts = np.empty((max(nf), self.dim))
        self._faces = [np.empty(f, np.int64) for f in nf]
        self._open = [np.empty(f) for f in nf]
        self._body = [np.empty(f, np.int64) for f in nf]
        self.count = [0, 0, 0]
        # the nearest obstacle's signed distance and index at every cell centre (``cells=True``;
        # allocated on first need): the boundary data of scalars held on obstacles
        self.cell_best = self.cell_near = self._cell_vel = None
        empty = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64))
        self.cut = [empty] * 3
        self._kernel = K.version(_d.query_points, parallel)

    def _query(self, o, pts, t):
        m = pts.shape[0]
        d, nrm, vel = self.d[:m], self.nrm[:m], self.vel[:m]
        query_into(o, pts, t, d, nrm, vel, self._kernel)
        return d, vel

    def _nearest(self, obstacles, pts, t, axis, best, best_vel, owner):
        """At pts: the smallest signed distance over the obstacles, the `axis` velocity component
        of the obstacle attaining it and its index, into best, best_vel, owner."""
        best[...] = np.inf
        best_vel[...] = 0.0
        owner[...] = 0
        for i, o in enumerate(obstacles):
            d, vel = self._query(o, pts, t)
            _take_nearest(d, vel, axis, i, best, best_vel, owner)

    def update(self, obstacles, owner_body, t, frac, solid, cell_solid, nodes=False, cells=False):
        """Fill frac, solid (three face arrays each; in 2-D frac[2] = 0), cell_solid and ``cut``
        from `obstacles` (one or more) at time t; owner_body (len(obstacles),) int64: the body of
        each (-1: none). nodes: also the nearest obstacle of every face node (``best``,
        ``near_vel``, ``near``); cells: also the nearest obstacle of every cell centre
        (``cell_best``, ``cell_near``). Fractions: `face_fractions` (bit for bit); a face's nearest
        obstacle: the one with the smallest signed distance at its centre (the first on a tie)."""
        dim = self.dim
        for i, o in enumerate(obstacles):
            d, _ = self._query(o, self.vertex_pts, t)
            _min_into(d, self.vertex_sdf, i == 0)
        fractions_into(self.vertex_sdf.reshape(self.vertex_shape), dim, frac[0], frac[1], frac[2])
        if dim == 2:
            frac[2][...] = 0.0
            solid[2][...] = 0.0
        for a in range(dim):
            fa, sa = frac[a].reshape(-1), solid[a].reshape(-1)
            faces, open_frac, body = self._faces[a], self._open[a], self._body[a]
            n = _cut_faces(fa, sa, faces, open_frac)
            if nodes:
                self._nearest(obstacles, self.face_pts[a], t, a, self.best[a], self.near_vel[a],
                              self.near[a])
            elif n:
                pts = self.pts[:n]
                _gather_rows(self.face_pts[a], faces, n, pts)
                self._nearest(obstacles, pts, t, a, self.best[a][:n], self.near_vel[a][:n],
                              self.near[a][:n])
            _cut_values(n, faces, self.near_vel[a], self.near[a], nodes, owner_body, sa, body)
            self.count[a] = n
            self.cut[a] = (faces[:n], open_frac[:n], body[:n])
        if cells and self.cell_best is None:
            nc = self.cell_pts.shape[0]
            self.cell_best, self._cell_vel, self.cell_near = np.empty(nc), np.empty(nc), np.empty(nc, np.int64)
        if cells:
            self.cell_best[...] = np.inf
        for i, o in enumerate(obstacles):
            d, vel = self._query(o, self.cell_pts, t)
            _mark_inside(d, self.inside, i == 0)
            if cells:
                _take_nearest(d, vel, 0, i, self.cell_best, self._cell_vel, self.cell_near)
        cell_solid.reshape(-1)[...] = self.inside


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
        """(distance (M,), normal (M, dim), velocity (M, dim)) at points (M, dim) (new arrays)."""
        pts = np.ascontiguousarray(points, dtype=np.float64)
        m = pts.shape[0]
        d, n, v = np.empty(m), np.empty((m, self.dim)), np.empty((m, self.dim))
        return self.query_into(pts, t, d, n, v)

    def query_into(self, pts, t, d, n, v):
        """`query` into d (M,), n (M, dim), v (M, dim) for C-contiguous float64 pts (M, dim);
        returns (d, n, v). A collider of `inertia.collision.shapes` allocates no (M,) array."""
        c = self.collider
        if self._fast:
            vel, omega = c._rigid_velocity(t)
            self._kernel(pts, self._kinds, c.kind, c._cf, c._ci, c._packed_pose(t), c._ref, c.moving,
                         np.ascontiguousarray(vel, dtype=np.float64),
                         np.ascontiguousarray(omega, dtype=np.float64), d, n, v)
            return d, n, v
        m = pts.shape[0]
        if c.dim == self.dim:
            c.query(pts, t, d, n, v)
            return d, n, v
        p3 = np.zeros((m, 3))
        p3[:, :2] = pts[:, :2]
        n3, v3 = np.empty((m, 3)), np.empty((m, 3))
        c.query(p3, t, d, n3, v3)
        n[...] = n3[:, :self.dim]
        v[...] = v3[:, :self.dim]
        return d, n, v

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
