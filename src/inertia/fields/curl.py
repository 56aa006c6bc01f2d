"""Curl-noise: divergence-free procedural flow that goes around solid boundaries.

After Bridson, Hourihan & Nordenstam (2007). The velocity is the curl of a noise potential, so
it is incompressible by construction; its derivatives are the analytic derivatives of the noise
(``noise.py``), never finite differences:

    2-D: a scalar potential psi,            v = (d psi / dy, -d psi / dx)
    3-D: a vector potential (psi0, psi1, psi2) of three uncorrelated noises, v = curl psi

The three 3-D potentials sample the same lattice points (one seeded offset per octave) with
three gradient tables (``noise.component_gradients``: zero mean, exactly zero covariance
between tables), so each octave's lattice walk (cell, corner hashes and weights) serves all
three and a corner costs three dot products. Both kinds walk the lattice for a block of 128
points at a time (``kernels.potential3_block``): a loop of arithmetic only (cells, offsets,
ranks or fades), a loop over the hash chains, then corner by corner a loop without branches
that reads each corner's three gradients as one packed code (``noise.gradient_codes``), so it
has no gather and vectorises. At 10^6 points, 3 octaves, one thread, against inertia before
the batched walk (commit 13a834f), medians of two interleaved rounds, three runs on a shared
2-core machine (load average 1.1-6.1): simplex 4.4-5.7 times faster, Perlin 2.5-3.9 times
(steady or time-varying, free, sphere or container; at the least load, 1.1-1.8, simplex
4.4-5.3 and Perlin 2.9-3.1; ``benchmarks/bench_curl_noise.py --compare-with``, CPU time). Each
potential is still a gradient noise with the range and statistics of ``noise.py``.

Boundaries (any collider of ``inertia.colliders``, static or kinematic). Each point sees the
walls within the boundary width d0: a collider is one wall, a ``Container`` one wall per plane
(its own distance field has kinks on the medial planes, each plane's does not). Wall k has the
signed distance d_k, the normal n_k = grad d_k and Bridson's ramp a_k = ramp(d_k / d0)
(= (15 r - 10 r^3 + 3 r^5) / 8 for |r| < 1, 1 beyond). With alpha = prod_k a_k,
c_k = (1 - a_k) prod_{j != k} a_j and gamma_K = (1 - prod_{k in K} a_k) prod_{k not in K} a_k
for collider K:

    2-D: psi' = alpha psi + sum_K gamma_K psi_R,K
    3-D: psi' = alpha psi + sum_k c_k n_k (n_k . psi) + sum_K gamma_K psi_R,K

With a single wall this is Bridson's psi' = a psi + (1 - a) n (n . psi) + (1 - a) psi_R. Every
weight is a product of C^2 ramps, so psi' and the velocity are continuous where the closest
wall changes (a box's edges and corners, two colliders near each other).

An optional mean flow U joins the noise potential before the ramp (psi_U = U x (x - c) / 2),
so that the wind, too, goes around the obstacles.

On wall k (a_k = 0) only c_k n_k (n_k . psi) and gamma_K psi_R survive; when no other
collider is within d0 there, gamma_K = 1 and psi' - psi_R is normal to the surface (zero in
2-D), so the curl of psi' has the normal component of the collider's own velocity: the flow is
tangent to a static surface and carries no fluid through a moving one. (The flux through a
patch of surface is the circulation of psi' around its rim, which only the tangential part of
psi' carries.) psi_R is the potential of the
collider's rigid motion u_R = V + W x (x - c) (the paper's "moving boundaries"):

    2-D: psi_R = V_x (y - c_y) - V_y (x - c_x) - W (|x - c|^2 - R^2) / 2
    3-D: psi_R = V x (x - c) / 2 + W (R^2 - |x - c|^2) / 2

V and W are read from ``collider.velocity`` at the reference point c and three (two) points
around it; c is the collider's reference point at time t (``collider.pose(t)``, else its
``center`` / ``point``) and R the distance from c to the surface when c is inside (the radius,
for a sphere), which keeps psi_R small near the surface.

References
----------
- Bridson, R., Hourihan, J. & Nordenstam, M. (2007), "Curl-noise for procedural fluid flow",
  ACM Trans. Graph. 26(3), SIGGRAPH 2007: everything above.
- Perlin, K. (1985, 2002) and Gustavson, S. (2005/2012): the noise (see ``noise.py``).

Limitations
-----------
- Several colliders: where a moving collider is within d0 of another collider's surface,
  gamma_K < 1 there and the fluid's normal speed at that surface is only approximately the
  collider's own (static colliders, and a moving one alone within d0, are exact). The mean
  flow's potential is taken about the centre of the nearest wall's collider, so with a mean
  flow U the velocity jumps by O(|U|) where the nearest collider changes (not between the
  walls of one container).
- 3-D boundaries need grad n (the Hessian of the signed distance). A container's planes and a
  ``Plane`` have none; a ``Sphere``'s is the closed form (I - n n^T) / |x - c|; other
  colliders give it by ``distance_hessian(points, t)`` when they have one,
  otherwise it is taken by central differences of ``collider.normal`` with step 1e-3 d0
  (O(step^2) error in the curvature term only; the tangency at the surface does not depend
  on it). Across an edge of a collider's own distance field (a baked mesh's medial surfaces)
  one-sided differences are used; the velocity then jumps in its tangential part there.
- Collider motion is taken as rigid (translation + rotation) at each instant; a deforming
  collider would need a potential for its deformation velocity, which is not built.
- ``jacobian`` / ``divergence`` (analytic) are available without boundaries only.
- Fields added to a bounded curl-noise (``CurlNoise(...) + Uniform(...)``) are not made
  tangent to the boundaries; put the mean flow into the noise's potential instead.
- The spatial amplitude modulation A(x) of the paper is not provided.
- The 3-D field changed when the potentials began to share the lattice walk (before, each
  potential read the lattice at its own offset): the same seed now gives the same statistics
  but different eddies than inertia 0.1.0. The 2-D field is unchanged.
"""

from __future__ import annotations

import numpy as np

from .._validate import as_points, as_vector, positive_scalar
from ..collision.shapes import Plane, Sphere
from . import kernels as K
from .base import Field
from .noise import NoiseParameters, component_gradients, gradient_codes, lattice_tables

__all__ = ["CurlNoise"]


# Step of the central differences of collider normals (relative to the boundary width d0).
_HESSIAN_STEP = 1e-3
# A normal turning by more than this (radians, roughly) over one step marks an edge of the
# distance field, not curvature (that would be a radius of curvature below 0.01 step / 1e-3).
_KINK = 0.1


class CurlNoise(Field):
    """Divergence-free procedural velocity field (Bridson et al. 2007); see the module docstring.

    Parameters
    ----------
    dim : int
        2 or 3; 3 default.
    seed : int
        0 default; same seed, same flow.
    kind : {"simplex", "perlin"}
        Noise used for the potential; "simplex" default (faster: D + 1 lattice corners).
    frequency : float
        Lattice cells per unit length of the first octave; 1.0 default. Eddies are about
        0.5 / frequency across.
    octaves, lacunarity, gain : int, float, float
        Fractal sum of the potential: 1, 2.0, 0.5 default (see ``Noise``). With gain 0.5 and
        lacunarity 2 every octave contributes about equally to the velocity.
    speed : float
        RMS speed of the noise flow away from boundaries, m/s; 1.0 default (0.1-5 for
        smoke at human scale). Peak speeds are 3-4 times it. The potential is scaled to give
        it: each component is bounded by ``potential_amplitude`` = speed / (RMS speed of the
        unit-amplitude field), measured once at construction over 16384 quasi-random points
        spread over 64 lattice cells per axis at t = 0. (For Perlin noise with
        ``time_frequency`` > 0 the RMS drifts by up to ~10 % with time, as the time axis
        crosses lattice planes.)
    time_frequency : float
        Lattice cells per second along the noise's time axis; 0.0 default (steady flow);
        0.1-1 for smoke whose eddies evolve as it moves.
    mean_velocity : (D,) or None
        A uniform wind U in m/s carried by the potential (psi_U = U x (x - c) / 2 about each
        collider's centre c), so that it also flows around the boundaries; None (0) default.
        Smoke rising past an obstacle: ``mean_velocity=(0, 0, 1)``.
    boundaries : sequence of colliders
        Colliders of ``inertia.colliders`` (anything with ``dim``, ``signed_distance``,
        ``normal`` and ``velocity``); empty default.
    boundary_width : float
        d0, the distance over which the flow is bent to run along a boundary; 0.5 / frequency
        default (one eddy); 0.5-2 eddies. Must be > 0.
    """

    def __init__(self, dim: int = 3, *, seed: int = 0, kind: str = "simplex",
                 frequency: float = 1.0, octaves: int = 1, lacunarity: float = 2.0,
                 gain: float = 0.5, speed: float = 1.0, time_frequency: float = 0.0,
                 mean_velocity=None, boundaries=(), boundary_width: float | None = None):
        if dim not in (2, 3):
            raise ValueError(f"dim must be one of [2, 3]; got {dim!r}")
        self.dim = int(dim)
        self.params = NoiseParameters.check(
            seed=seed, kind=kind, frequency=frequency, octaves=octaves, lacunarity=lacunarity,
            gain=gain, amplitude=1.0, time_frequency=time_frequency)
        self.speed = positive_scalar(speed, "speed", allow_zero=True)
        self.lattice_dim = self.dim + (1 if self.params.time_frequency != 0.0 else 0)
        self.components = 1 if self.dim == 2 else 3
        # One kernel per dimension: a 3-D scene never compiles the 2-D path.
        self._kernel = K.curl_noise3 if self.dim == 3 else K.curl_noise2
        # One lattice offset per octave, shared by the components; one gradient table per
        # component (``component_gradients``): (C, 256, D) for the per-component kernels and
        # (256, C, D) for the batched one, which reads a corner's three gradients together.
        self._perm, self._offsets = lattice_tables(self.params.seed, 1, self.params.octaves)
        self._grads = component_gradients(self.params.seed, self.components, self.lattice_dim)
        self._table = np.ascontiguousarray(self._grads.transpose(1, 0, 2))
        # 3-D reads the same gradients packed per corner (``gradient_codes``), as the codes of
        # its kind; the other kind's None (and both in 2-D) keeps that kind's block walk out of
        # the compiled kernel.
        codes = gradient_codes(self._table, self._perm) if self.dim == 3 else None
        perlin = self.params.kind == "perlin"
        self._codes = (None if perlin else codes, codes if perlin else None)
        self._scale = self.params.scale(self.lattice_dim)
        # Calibrate: scale the unit-amplitude potential so that the RMS speed is `speed`.
        unit_rms = self._unit_rms_speed()
        self.potential_amplitude = self.speed / unit_rms
        self._scale *= self.potential_amplitude
        if boundary_width is None:
            boundary_width = 0.5 / self.params.frequency
        self.boundary_width = positive_scalar(boundary_width, "boundary_width")
        self.boundaries = _Boundaries(boundaries, self.dim, self.boundary_width)
        self.mean_velocity = (np.zeros(self.dim) if mean_velocity is None
                              else as_vector(mean_velocity, "mean_velocity", self.dim))
        # Empty boundary arrays for the boundary-free kernel path.
        D = self.dim
        self._none = _no_boundaries(D)

    def __repr__(self):
        p = self.params
        b = f", boundaries={list(self.boundaries.colliders)!r}" if self.boundaries.colliders else ""
        return (f"CurlNoise(dim={self.dim}, seed={p.seed}, kind={p.kind!r}, frequency={p.frequency}, "
                f"octaves={p.octaves}, speed={self.speed}, time_frequency={p.time_frequency}{b})")

    def _unit_rms_speed(self) -> float:
        """RMS speed of this field with unit-amplitude potentials, over a fixed point set."""
        # Roberts' R_D quasi-random sequence (additive recurrence with the generalised golden
        # ratio): deterministic, even coverage of [0, 64)^D lattice cells.
        D = self.dim
        phi = 2.0
        for _ in range(30):
            phi = (1.0 + phi) ** (1.0 / (D + 1))
        alpha = phi ** -np.arange(1, D + 1)
        n = np.arange(1, 16385)[:, None]
        pts = np.ascontiguousarray(((0.5 + n * alpha) % 1.0) * (64.0 / self.params.frequency))
        out = np.empty_like(pts)
        p = self.params
        # The serial build: a scene with a few tracers then never compiles the parallel one.
        self._kernel.serial(pts, self._offsets, self._perm, self._grads[0], self._table,
                            *self._codes,
                            *_no_boundaries(D), np.zeros(D), out,
                            0.0, p.kind_code, p.frequency, p.lacunarity, p.gain, p.octaves,
                            p.time_frequency, self._scale, 1.0)
        return float(np.sqrt(np.mean(np.sum(out * out, axis=1))))

    # -- velocity ---------------------------------------------------------------------------
    def sample(self, points: np.ndarray, t: float, out: np.ndarray) -> None:
        """Fill `out` (M, D) with the velocity at `points` (M, D), time `t` (analytic curl)."""
        self._check_out(points, out)
        t = float(t)
        bnd = self.boundaries.prepare(points, t) if self.boundaries.colliders else self._none
        p = self.params
        self._kernel(points, self._offsets, self._perm, self._grads[0], self._table, *self._codes,
                     *bnd,
                     self.mean_velocity, out,
                     t, p.kind_code, p.frequency, p.lacunarity, p.gain, p.octaves,
                     p.time_frequency, self._scale, self.boundary_width)

    def sample_jacobian(self, points, t, out) -> None:
        """Analytic Jacobian dv_a/dx_b (boundary-free fields only), out (M, D, D)."""
        if self.boundaries.colliders:
            raise NotImplementedError(
                "CurlNoise.jacobian is analytic only without boundaries (it would need third "
                "derivatives of the colliders' signed distance); use central differences of "
                "the velocity instead")
        if points.ndim != 2 or points.shape[1] != self.dim or out.shape != (points.shape[0], self.dim, self.dim):
            raise ValueError(f"points must be (M, {self.dim}) and out (M, {self.dim}, {self.dim}); "
                             f"got {points.shape} and {out.shape}")
        p = self.params
        K.curl_noise_jacobian(points, self._offsets, self._perm, self._grads, out, float(t),
                              p.kind_code, p.frequency, p.lacunarity, p.gain, p.octaves,
                              p.time_frequency, self._scale)

    # -- potential --------------------------------------------------------------------------
    def potential(self, points, t: float = 0.0) -> np.ndarray:
        """The (boundary-modified) potential psi' whose curl is the velocity.

        Returns (M,) in 2-D (a stream function) and (M, 3) in 3-D. Slower than ``sample``
        (NumPy, not fused); meant for checks and visualisation.
        """
        pts = as_points(points, "points", dim=self.dim)
        t = float(t)
        M = pts.shape[0]
        p = self.params
        psi = np.empty((M, self.components))
        value = np.empty(M)
        for c in range(self.components):
            K.fractal_noise(pts, self._offsets[0], self._perm, self._grads[c],
                            value, np.empty((0, self.dim)), np.empty((0, self.dim, self.dim)),
                            t, p.kind_code, 0, p.frequency, p.lacunarity, p.gain, p.octaves,
                            p.time_frequency, self._scale)
            psi[:, c] = value
        U = self.mean_velocity
        if not self.boundaries.colliders:
            if self.dim == 2:
                psi[:, 0] += U[0] * pts[:, 1] - U[1] * pts[:, 0]
            else:
                psi += 0.5 * np.cross(U, pts)
            return psi[:, 0].copy() if self.dim == 2 else psi
        # With boundaries: point by point, the formula of `kernels.curl_noise3_range` / `curl_noise2_range` (a second,
        # independent implementation that the tests difference against the kernel's curl).
        slot, count, dist, normal, _, coll, V, W, C, R2 = self.boundaries.prepare(pts, t)
        d0 = self.boundary_width
        for i in range(M):
            if slot[i] < 0:
                if self.dim == 2:
                    psi[i, 0] += U[0] * pts[i, 1] - U[1] * pts[i, 0]
                else:
                    psi[i] += 0.5 * np.cross(U, pts[i])
                continue
            rows = np.arange(slot[i], slot[i] + count[i])
            r = np.clip(dist[rows] / d0, -1.0, 1.0)
            a = (15 * r - 10 * r**3 + 3 * r**5) / 8
            walls_of = coll[rows]
            x = pts[i] - C[walls_of[np.argmin(dist[rows])]]
            total = psi[i] + (0.5 * np.cross(U, x) if self.dim == 3 else U[0] * x[1] - U[1] * x[0])
            new = np.prod(a) * total
            if self.dim == 3:
                for j, row in enumerate(rows):
                    c_j = (1 - a[j]) * np.prod(np.delete(a, j))
                    new = new + c_j * normal[row] * (normal[row] @ total)
            for k in np.unique(walls_of):
                gamma = (1 - np.prod(a[walls_of == k])) * np.prod(a[walls_of != k])
                xk = pts[i] - C[k]
                if self.dim == 2:
                    psi_r = V[k, 0] * xk[1] - V[k, 1] * xk[0] - 0.5 * W[k, 0] * (xk @ xk - R2[k])
                else:
                    psi_r = 0.5 * np.cross(V[k], xk) + 0.5 * (R2[k] - xk @ xk) * W[k]
                new = new + gamma * psi_r
            psi[i] = new
        return psi[:, 0].copy() if self.dim == 2 else psi


class _Boundaries:
    """Gathers, for each sample, the walls within the boundary width d0 of every point.

    A wall is one collider, or one plane of a ``Container`` (whose distance is the least of its
    planes', with a normal that jumps across the medial planes; each plane alone is smooth).
    ``prepare(points, t)`` returns the arrays the ``curl_noise3`` / ``curl_noise2`` kernels read:
      slot (M,) int64         -- first row of the point's walls below, -1 where none is within d0
      count (M,) int64        -- how many walls are within d0 (rows slot .. slot + count - 1)
      distance (w,)           -- signed distance d to the wall (positive in the free space)
      normal (w, D)           -- its unit normal grad d
      hessian (w, D, D)       -- grad n (3-D; zero for planes), or (0, D, D) when every wall
                                 is flat (2-D, containers, planes: the kernel skips the term)
      collider (w,) int64     -- which collider the wall belongs to
      velocity (K, D), spin (K, D), center (K, D), radius2 (K,) -- rigid motion per collider
    Rows of one point are in a fixed order (collider, then plane), so results do not depend on
    the thread count. The arrays are views of buffers kept between calls (no allocation per
    step once the largest batch has been seen); a caller must not hold them across calls.
    """

    def __init__(self, colliders, dim: int, width: float):
        if colliders is None:
            colliders = ()
        if not isinstance(colliders, (list, tuple)):
            colliders = (colliders,)
        for c in colliders:
            missing = [m for m in ("signed_distance", "normal", "velocity") if not callable(getattr(c, m, None))]
            if missing or not hasattr(c, "dim"):
                raise ValueError("boundaries must be colliders (with dim, signed_distance, normal and "
                                 f"velocity, e.g. inertia.colliders.Sphere); {type(c).__name__} lacks "
                                 f"{missing or ['dim']}")
            if c.dim != dim:
                raise ValueError(f"boundaries must be {dim}-D colliders for a {dim}-D field; "
                                 f"got a {c.dim}-D {type(c).__name__}")
        self.colliders = tuple(colliders)
        self.dim = dim
        self.width = width
        self._slot = np.empty(0, np.int64)
        self._buffers = {}  # name -> flat array reused between calls (`_buffer`)

    def _buffer(self, name, shape, dtype=np.float64):
        """A C-contiguous array of `shape` backed by a buffer kept between calls (grown when
        too small): sampling every step allocates, and page-faults, nothing new."""
        size = int(np.prod(shape))
        buf = self._buffers.get(name)
        if buf is None or buf.size < size or buf.dtype != dtype:
            buf = np.empty(max(size, 1), dtype=dtype)
            self._buffers[name] = buf
        return buf[:size].reshape(shape)

    def prepare(self, points, t):
        """The wall lists the kernel reads (see the class docstring).

        The arrays returned are views of buffers this object reuses at the next call."""
        D = self.dim
        M = points.shape[0]
        cols = self.colliders
        h = _HESSIAN_STEP * self.width
        # A container's walls are its planes (a smooth distance each), any other collider is
        # one wall whose distance and normal come from its query.
        stack = points.size < K.SERIAL_BELOW
        # How grad n is had in 3-D: "plane" (zero: a container's faces, a Plane), "sphere"
        # (closed form (I - n n^T) / |x - c|), "hessian" (the collider's distance_hessian),
        # "fd" (central differences of its normals).
        how = [_hessian_source(c, D) for c in cols]
        fd = [h_k == "fd" for h_k in how]
        # Walls in a fixed order (collider, then plane). wall_plane[w] >= 0: row of a plane
        # (a container's face: its distance is computed in `K.wall_counts` / `K.wall_rows`);
        # < 0: -1 - the row of query_distance that holds the collider's signed distance.
        wall_plane, wall_collider, plane_point, plane_normal, queries = [], [], [], [], []
        n_queries = sum(1 for c in cols if _planes(c, t, D) is None)
        query_distance = self._buffer("query_distance", (n_queries, M))
        for k, c in enumerate(cols):
            planes = _planes(c, t, D)
            if planes is not None:
                for p0, n0 in zip(*planes, strict=True):
                    wall_plane.append(len(plane_point))
                    wall_collider.append(k)
                    plane_point.append(p0)
                    plane_normal.append(n0)
                continue
            q = len(queries)
            rows = M * (2 * D + 1) if (fd[k] and stack) else M
            query_points = points if rows == M else _shifted_stack(points, h)
            if callable(getattr(c, "query", None)):
                d_k = query_distance[q] if rows == M else np.empty(rows)
                n_k = self._buffer(f"normal{q}", (rows, D))
                c.query(query_points, t, d_k, n_k, self._buffer(f"velocity{q}", (rows, D)))
                if rows != M:
                    query_distance[q] = d_k[:M]
            else:
                query_distance[q] = np.asarray(c.signed_distance(query_points, t), dtype=np.float64)[:M]
                n_k = None if rows == M else np.asarray(c.normal(query_points, t), dtype=np.float64)
            wall_plane.append(-1 - q)
            wall_collider.append(k)
            queries.append((len(wall_plane) - 1, k, n_k, c))
        wall_plane = np.array(wall_plane, dtype=np.int64)
        wall_collider = np.array(wall_collider, dtype=np.int64)
        plane_point = _padded3(plane_point)
        plane_normal = _padded3(plane_normal)
        # Per point, the walls within d0: CSR lists built by two compiled passes.
        slot = self._buffer("slot", (M,), np.int64)
        count = self._buffer("count", (M,), np.int64)
        total = K.wall_counts(points, wall_plane, plane_point, plane_normal, query_distance,
                              self.width, slot, count)
        dist = self._buffer("dist", (total,))
        normal = self._buffer("normal", (total, D))
        coll = self._buffer("coll", (total,), np.int64)
        wall_of_row = self._buffer("wall_of_row", (total,), np.int64)
        point_of_row = self._buffer("point_of_row", (total,), np.int64)
        K.wall_rows(points, wall_plane, wall_collider, plane_point, plane_normal, query_distance,
                    self.width, dist, normal, coll, wall_of_row, point_of_row)
        # grad n only where some wall is curved; an empty array tells the kernel "all flat".
        curved = D == 3 and any(h_k != "plane" for h_k in how)
        hessian = self._buffer("hessian", (total if curved else 0, D, D))
        if curved:
            hessian[:] = 0.0
        # Normals (and 3-D Hessians) of the collider walls, at their rows only.
        for w, k, n_k, c in queries:
            flat = D != 3 or how[k] == "plane"
            if n_k is not None and (flat or how[k] == "sphere"):
                # The query's normals and, for a sphere, the closed form, compiled, row by row:
                # no index arrays, nothing allocated.
                K.collider_wall_normals(wall_of_row, point_of_row, w, n_k, normal)
                if not flat:
                    K.sphere_hessian(points, wall_of_row, point_of_row, w, normal,
                                     _reference_point(c, t, D), hessian, h)
                continue
            rows = np.flatnonzero(wall_of_row == w)
            if rows.size == 0:
                continue
            idx = point_of_row[rows]
            nk = (np.asarray(c.normal(np.ascontiguousarray(points[idx]), t), dtype=np.float64)
                  if n_k is None else np.ascontiguousarray(n_k[idx]))
            normal[rows] = nk
            if flat:
                continue
            if how[k] == "sphere":
                K.sphere_hessian(points, wall_of_row, point_of_row, w, normal,
                                 _reference_point(c, t, D), hessian, h)
                continue
            pts = np.ascontiguousarray(points[idx])
            if how[k] == "hessian":
                hessian[rows] = np.asarray(c.distance_hessian(pts, t), dtype=np.float64)
                continue
            if n_k is None or n_k.shape[0] == M:
                shifted = np.asarray(c.normal(_shifted_stack(pts, h)[pts.shape[0]:], t),
                                     dtype=np.float64).reshape(2 * D, -1, D)
                at = np.arange(pts.shape[0])
            else:
                shifted = n_k[M:].reshape(2 * D, M, D)
                at = idx
            H = np.empty((idx.shape[0], D, D))
            K.hessian_from_normals(nk, shifted, at, H, h, _KINK)
            hessian[rows] = H
        velocity, spin, center, radius2 = self._rigid_motion(t)
        return (slot, count, dist, normal, hessian, coll, velocity, spin, center, radius2)

    def _rigid_motion(self, t):
        """Per collider: V (K, D), W (K, D) (2-D: W[:, 0] = omega), centre c (K, D), R^2 (K,)."""
        D = self.dim
        Kc = len(self.colliders)
        V = np.zeros((Kc, D))
        W = np.zeros((Kc, D))
        C = np.zeros((Kc, D))
        R2 = np.zeros(Kc)
        for k, col in enumerate(self.colliders):
            c = _reference_point(col, t, D)
            C[k] = c
            if getattr(col, "moving", None) is False:
                continue  # declared static
            # u(c + e_a) - u(c) = W x e_a for a rigid motion u(x) = V + W x (x - c).
            probe = np.vstack([c, c + np.eye(D)])
            u = np.asarray(col.velocity(probe, t), dtype=np.float64).reshape(D + 1, D)
            if not np.any(u):
                continue  # static
            V[k] = u[0]
            du = u[1:] - u[0]  # du[a] = W x e_a
            if D == 2:
                # W x e_x = (0, w), W x e_y = (-w, 0)
                W[k, 0] = 0.5 * (du[0, 1] - du[1, 0])
            else:
                # W x e_x = (0, Wz, -Wy), W x e_y = (-Wz, 0, Wx), W x e_z = (Wy, -Wx, 0)
                W[k, 0] = 0.5 * (du[1, 2] - du[2, 1])
                W[k, 1] = 0.5 * (du[2, 0] - du[0, 2])
                W[k, 2] = 0.5 * (du[0, 1] - du[1, 0])
            d_c = float(np.asarray(col.signed_distance(c[None, :], t)).reshape(-1)[0])
            R2[k] = d_c * d_c if d_c < 0 else 0.0
        return V, W, C, R2


def _hessian_source(collider, dim):
    """How `prepare` gets grad n of a collider's wall in 3-D (see there); "plane" in 2-D."""
    if dim != 3 or getattr(collider, "plane_normals", None) is not None or isinstance(collider, Plane):
        return "plane"
    if isinstance(collider, Sphere):
        return "sphere"
    if callable(getattr(collider, "distance_hessian", None)):
        return "hessian"
    return "fd"


def _padded3(rows):
    """A list of 2-D or 3-D vectors as a (n, 3) array, zero-padded."""
    out = np.zeros((len(rows), 3))
    for r, v in enumerate(rows):
        out[r, :len(v)] = v
    return out


def _shifted_stack(points, h):
    """[points; points + h e_0; points - h e_0; points + h e_1; ...]: ((2 D + 1) M, D)."""
    M, D = points.shape
    out = np.empty((2 * D + 1, M, D))
    out[:] = points
    for a in range(D):
        out[1 + 2 * a, :, a] += h
        out[2 + 2 * a, :, a] -= h
    return out.reshape(-1, D)


def _no_boundaries(D):
    """Empty boundary arrays: the kernel's boundary-free path."""
    return (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0), np.empty((0, D)), np.empty((0, D, D)),
            np.empty(0, np.int64), np.empty((0, D)), np.empty((0, D)), np.empty((0, D)),
            np.empty(0))


def _planes(collider, t, dim):
    """World points (P, D) and unit normals (P, D) of a container's planes at time t, else None."""
    normals = getattr(collider, "plane_normals", None)
    points = getattr(collider, "plane_points", None)
    if normals is None or points is None or not callable(getattr(collider, "pose", None)):
        return None
    p, rot = collider.pose(t)
    rest = np.zeros((len(points), 3))
    rest[:, :dim] = points
    rest_n = np.zeros((len(normals), 3))
    rest_n[:, :dim] = normals
    ref = np.zeros(3)
    ref[:dim] = np.asarray(getattr(collider, "rest_point", np.zeros(dim)), dtype=np.float64)[:dim]
    world = p + (rest - ref) @ rot.T
    world_n = rest_n @ rot.T
    world_n /= np.linalg.norm(world_n, axis=1)[:, None]
    return np.ascontiguousarray(world[:, :dim]), np.ascontiguousarray(world_n[:, :dim])


def _reference_point(collider, t, dim):
    """A point that moves with the collider (its centre) at time t; the origin if unknown.

    Uses ``collider.pose(t)`` (position of the reference point, ``inertia.colliders``) when
    present, else a ``center`` / ``point`` attribute.
    """
    pose = getattr(collider, "pose", None)
    if callable(pose):
        p = np.asarray(pose(t)[0], dtype=np.float64).reshape(-1)
        if p.shape[0] >= dim:
            return p[:dim].copy()
    for name in ("center", "point"):
        value = getattr(collider, name, None)
        if value is not None and not callable(value):
            arr = np.asarray(value, dtype=np.float64).reshape(-1)
            if arr.shape == (dim,):
                return arr
    return np.zeros(dim)
