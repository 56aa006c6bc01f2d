"""Colour-map images of 2-D grid fluids (density, speed, vorticity or any scalar) with tracer
streaks, written with NumPy (PNG through `inertia.render.png`), and the tracer streaks of
recorded runs (`GridStreaks`, drawn by `inertia run` over the colour maps).

    from inertia.render.fluid_grid import FluidImage
    img = FluidImage(fluid, "vorticity", pixels_per_cell=2, tracers=400)
    for frame in range(100):
        fluid.advance(1 / 30)
        img.advance_tracers(1 / 30)
        img.write(f"out/frame_{frame:04d}.png")

The field is sampled at cell centres and scaled up by nearest-cell blocks (one cell =
``pixels_per_cell`` pixels), y pointing up. Colour maps (`inertia.render.colormaps`): density
and other scalars "magma" from 0 to the frame's maximum, speed "speed" (turbo), vorticity
"coolwarm" symmetric about 0 (red counter-clockwise). Tracers are massless points carried by the
fluid velocity (RK2 midpoint, `GridFluid.sample_velocity`); each keeps its last
``streak_length`` positions. Tracers that leave the domain are re-seeded at their start point
(seeded RNG: same image every run).

Streaks (both paths) are anti-aliased polylines through a tracer's last positions
(`streak_alpha`): a pixel's coverage of a segment is ``clamp(width/2 + 1/2 - d, 0, 1)`` with d
the distance in pixels from the pixel centre to the segment (a box-filtered capsule), times an
opacity that falls linearly with the segment's age from 1 (newest) to ``STREAK_TAIL_ALPHA``
(oldest); overlapping streaks take the maximum (order-independent: identical images), and the
colour is laid over the map with that opacity.

Recorded runs (`GridStreaks`): a 2-D `GridFluid` records its cell-centre velocity ``u``, ``v``
(float32) and ``solid`` cells per frame (`GridFluid.frame_arrays`). Tracers are seeded uniformly
in the fluid cells with a seeded RNG and carried from frame to frame by RK2 (midpoint) on the
bilinear interpolation of the cell-centre field, linear in time between the two recorded frames,
in substeps of at most one cell (CFL 1 on the larger of the two frames' maximum speeds, at most
``MAX_SUBSTEPS``). A tracer that leaves the grid, enters a solid cell or reaches its lifetime
(4 K frames, initial ages staggered) is re-seeded (a new uniform point in the fluid cells) and
starts a fresh streak. The streak of frame f joins the
tracer's positions at frames f - K .. f (K = ``length``), so in a uniform flow U it is a straight
segment of length U K dt.

References: RK2 midpoint rule (e.g. E. Hairer, S. P. Norsett and G. Wanner, "Solving Ordinary
Differential Equations I", 1993, II.1); B. Jobard and W. Lefer, "Creating evenly-spaced
streamlines of arbitrary density", 1997 (streak/streamline seeding for flow pictures).

Limitations: 2-D grids only (3-D smoke is ray-marched by `inertia.render.fluid_volume`); the
colour map is nearest-cell (not smoothed); tracers near a wall see the clamped (constant)
extrapolation of the first cell centre's velocity over the last half cell; re-seeding keeps the
tracer density even only on average (no Jobard-Lefer spacing control); the recorded field is
the frame's, so flow features faster than a frame are not followed; streaks of `GridStreaks`
need frames 0..f to be advected before frame f can be drawn (a jump back restarts from 0).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .colormaps import colormap
from .png import write_png

__all__ = ["FluidImage", "side_by_side", "GridStreaks", "streak_alpha", "advect_tracers", "blend_streaks",
           "STREAK_TAIL_ALPHA", "MAX_SUBSTEPS"]

QUANTITIES = ("density", "speed", "vorticity")
#: Opacity of a streak's oldest segment (its newest has 1).
STREAK_TAIL_ALPHA = 0.15
#: Most RK2 substeps per frame for a tracer (the CFL count is capped here).
MAX_SUBSTEPS = 64


# ----------------------------------------------------------------------------- kernels
@njit(cache=True)
def _bilinear(field, gx, gy):
    """Bilinear value of the cell-centred ``field`` (nx, ny) at grid coordinates (gx, gy) (cell
    (i, j)'s centre at (i, j)); clamped to the outermost centres."""
    nx, ny = field.shape
    gx = min(max(gx, 0.0), nx - 1.0)
    gy = min(max(gy, 0.0), ny - 1.0)
    i0 = min(int(gx), max(nx - 2, 0))
    j0 = min(int(gy), max(ny - 2, 0))
    i1 = min(i0 + 1, nx - 1)
    j1 = min(j0 + 1, ny - 1)
    fx = gx - i0
    fy = gy - j0
    return ((1.0 - fy) * ((1.0 - fx) * field[i0, j0] + fx * field[i1, j0])
            + fy * ((1.0 - fx) * field[i0, j1] + fx * field[i1, j1]))


@njit(cache=True)
def _velocity(u0, v0, u1, v1, gx, gy, s):
    a0 = _bilinear(u0, gx, gy)
    b0 = _bilinear(v0, gx, gy)
    a1 = _bilinear(u1, gx, gy)
    b1 = _bilinear(v1, gx, gy)
    return (1.0 - s) * a0 + s * a1, (1.0 - s) * b0 + s * b1


@njit(cache=True)
def advect_tracers(x, lost, u0, v0, u1, v1, solid, origin_x, origin_y, h, dt, substeps):
    """Carry tracers ``x`` (M, 2) world positions through dt seconds in ``substeps`` RK2
    (midpoint) steps on the cell-centre velocity (u, v) (nx, ny), linear in time from (u0, v0)
    to (u1, v1). A tracer that leaves the grid or lands in a ``solid`` (nx, ny) uint8 cell stops
    there and gets ``lost[m] = True`` (the caller re-seeds it). Serial, in tracer order."""
    nx, ny = u0.shape
    hs = dt / substeps
    inv_h = 1.0 / h
    for m in range(x.shape[0]):
        if lost[m]:
            continue
        gx = (x[m, 0] - origin_x) * inv_h - 0.5
        gy = (x[m, 1] - origin_y) * inv_h - 0.5
        for k in range(substeps):
            s0 = k / substeps
            sm = (k + 0.5) / substeps
            ka, kb = _velocity(u0, v0, u1, v1, gx, gy, s0)
            mx = gx + 0.5 * hs * ka * inv_h
            my = gy + 0.5 * hs * kb * inv_h
            ka, kb = _velocity(u0, v0, u1, v1, mx, my, sm)
            gx += hs * ka * inv_h
            gy += hs * kb * inv_h
            if not (gx >= -0.5 and gx <= nx - 0.5 and gy >= -0.5 and gy <= ny - 0.5):
                lost[m] = True
                break
            i = min(int(gx + 0.5), nx - 1)
            j = min(int(gy + 0.5), ny - 1)
            if solid[i, j] != 0:
                lost[m] = True
                break
        x[m, 0] = origin_x + (gx + 0.5) * h
        x[m, 1] = origin_y + (gy + 0.5) * h


@njit(cache=True)
def streak_alpha(history, count, ax, bx, ay, by, width, tail, alpha):
    """Coverage of tracer streaks into ``alpha`` (H, W) float32 (maximum with what it holds).

    history (P, M, 2): world positions, newest first (row 0: now); count (M,): how many rows of
    each tracer are valid (1: a fresh tracer, nothing drawn). A point maps to pixel coordinates
    (ax + bx x, ay + by y), pixel centres at +0.5. Segment k (rows k and k + 1) has opacity
    1 - (1 - tail) k / (P - 2) and covers pixels within ``width`` / 2 (anti-aliased over one pixel).
    """
    hgt, wid = alpha.shape
    p = history.shape[0]
    denom = max(p - 2, 1)
    reach = 0.5 * width + 0.5
    for m in range(history.shape[1]):
        for k in range(min(count[m], p) - 1):
            opacity = 1.0 - (1.0 - tail) * k / denom
            x0 = ax + bx * history[k, m, 0]
            y0 = ay + by * history[k, m, 1]
            x1 = ax + bx * history[k + 1, m, 0]
            y1 = ay + by * history[k + 1, m, 1]
            dx = x1 - x0
            dy = y1 - y0
            len2 = dx * dx + dy * dy
            if len2 <= 1e-12:
                continue
            c0 = max(int(math.floor(min(x0, x1) - reach)), 0)
            c1 = min(int(math.ceil(max(x0, x1) + reach)), wid - 1)
            r0 = max(int(math.floor(min(y0, y1) - reach)), 0)
            r1 = min(int(math.ceil(max(y0, y1) + reach)), hgt - 1)
            for r in range(r0, r1 + 1):
                py = r + 0.5
                for c in range(c0, c1 + 1):
                    px = c + 0.5
                    t = ((px - x0) * dx + (py - y0) * dy) / len2
                    t = min(max(t, 0.0), 1.0)
                    ex = x0 + t * dx - px
                    ey = y0 + t * dy - py
                    cover = reach - math.sqrt(ex * ex + ey * ey)
                    if cover <= 0.0:
                        continue
                    a = opacity * min(cover, 1.0)
                    if a > alpha[r, c]:
                        alpha[r, c] = a


@njit(cache=True)
def blend_streaks(image, alpha, color, changed):
    """image (H, W, 3) uint8 = image (1 - a) + color a (sRGB bytes, rounded); ``changed`` (H, W)
    bool marks the pixels with a > 0."""
    hgt, wid = alpha.shape
    for r in range(hgt):
        for c in range(wid):
            a = alpha[r, c]
            if a <= 0.0:
                continue
            changed[r, c] = True
            for ch in range(3):
                value = image[r, c, ch] * (1.0 - a) + color[ch] * a
                image[r, c, ch] = np.uint8(min(max(value + 0.5, 0.0), 255.0))


class FluidImage:
    """Images of a 2-D `GridFluid` (see the module docstring).

    Parameters
    ----------
    fluid : a 2-D GridFluid.
    quantity : "density", "speed", "vorticity" or the name of one of the fluid's scalars.
    pixels_per_cell : integer >= 1.
    tracers : number of tracer points (0: none), seeded uniformly in the domain.
    streak_length : positions kept per tracer (>= 1).
    vmax : colour-map upper bound (default: the frame's maximum; vorticity: max |omega|).
    seed : tracer seeding.
    width_px : streak width in pixels (anti-aliased polylines, see the module docstring).
    """

    def __init__(self, fluid, quantity="density", *, pixels_per_cell=2, tracers=0,
                 streak_length=12, vmax=None, seed=0, width_px=1.2):
        if getattr(fluid, "dim", None) != 2:
            raise ValueError("fluid must be a 2-D GridFluid (3-D smoke needs a volume renderer)")
        if quantity not in QUANTITIES and quantity not in fluid.scalar_names:
            raise ValueError(f"quantity must be one of {QUANTITIES} or a scalar "
                             f"{fluid.scalar_names}; got {quantity!r}")
        if int(pixels_per_cell) != pixels_per_cell or pixels_per_cell < 1:
            raise ValueError(f"pixels_per_cell must be an integer >= 1; got {pixels_per_cell!r}")
        if int(streak_length) < 1:
            raise ValueError(f"streak_length must be >= 1; got {streak_length!r}")
        self.fluid = fluid
        self.quantity = quantity
        self.ppc = int(pixels_per_cell)
        self.vmax = vmax
        self.width_px = float(width_px)
        g = fluid.grid
        self.lo = g.origin[:2].astype(np.float64)
        self.hi = self.lo + g.size[:2]
        rng = np.random.default_rng(seed)
        n = int(tracers)
        self.start = self.lo + rng.random((n, 2)) * (self.hi - self.lo)
        self.history = np.repeat(self.start[None], int(streak_length), axis=0)  # (K, M, 2)

    def field(self):
        """The (nx, ny) cell values of the quantity."""
        f = self.fluid
        if self.quantity == "vorticity":
            return f.vorticity()
        if self.quantity == "speed":
            return f.frame_arrays()["speed"].astype(np.float64)
        return np.asarray(f.scalar(self.quantity), dtype=np.float64)

    def advance_tracers(self, dt):
        """Move the tracers by dt through the current velocity (RK2 midpoint)."""
        if self.history.shape[1] == 0:
            return
        x = self.history[-1]
        v = self.fluid.sample_velocity(x)
        xm = np.clip(x + 0.5 * dt * v, self.lo, self.hi)
        x1 = x + dt * self.fluid.sample_velocity(xm)
        out = np.any((x1 < self.lo) | (x1 > self.hi), axis=1)
        x1[out] = self.start[out]
        self.history = np.roll(self.history, -1, axis=0)
        self.history[-1] = x1
        if out.any():  # a re-seeded tracer starts a fresh streak
            self.history[:, out] = x1[out]

    def image(self):
        """(H, W, 3) uint8 image, row 0 at the top (largest y)."""
        a = self.field()
        if self.quantity == "vorticity":
            m = self.vmax if self.vmax is not None else max(float(np.max(np.abs(a))), 1e-12)
            rgb = colormap("coolwarm", a, vmin=-m, vmax=m)
        else:
            cmap = "speed" if self.quantity == "speed" else "magma"
            hi = self.vmax if self.vmax is not None else max(float(np.max(a)), 1e-12)
            rgb = colormap(cmap, a, vmin=0.0, vmax=hi)
        img = np.repeat(np.repeat(rgb, self.ppc, axis=0), self.ppc, axis=1)  # (W, H, 3)
        img = np.ascontiguousarray(np.transpose(img, (1, 0, 2))[::-1])         # (H, W, 3)
        img = (np.clip(img[..., :3], 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
        k, m = self.history.shape[:2]
        if m and k > 1:
            h, w = img.shape[:2]
            scale = np.array([w, h]) / (self.hi - self.lo)
            alpha = np.zeros((h, w), np.float32)
            newest_first = np.ascontiguousarray(self.history[::-1])
            streak_alpha(newest_first, np.full(m, k, np.int64), -self.lo[0] * scale[0], scale[0],
                         h + self.lo[1] * scale[1], -scale[1], self.width_px, STREAK_TAIL_ALPHA, alpha)
            blend_streaks(img, alpha, np.full(3, 255.0), np.zeros((h, w), np.bool_))
        return img

    def write(self, path):
        """Write the current image as a PNG; returns the path."""
        return write_png(path, self.image())


def side_by_side(images, gap=4):
    """Join (H, W, 3) uint8 images left to right with a black gap (e.g. vorticity confinement
    on and off); heights must match."""
    hs = {im.shape[0] for im in images}
    if len(hs) != 1:
        raise ValueError(f"images must have the same height; got {sorted(hs)}")
    h = hs.pop()
    parts = []
    for i, im in enumerate(images):
        if i:
            parts.append(np.zeros((h, gap, 3), dtype=np.uint8))
        parts.append(im)
    return np.concatenate(parts, axis=1)


# ----------------------------------------------------------------------------- recorded runs
class GridStreaks:
    """Tracer streaks of one recorded 2-D grid fluid (see the module docstring).

    Parameters
    ----------
    u, v : (F, nx, ny) cell-centre velocity per frame, m/s (``fluid/<name>/u``, ``.../v``).
    times : (F,) frame times, s.
    origin : (2,) lower corner of the grid, m; cell_size : h, m.
    solid : (F, nx, ny) cells inside obstacles (nonzero) or None.
    count : number of tracers (>= 1); length : K, frames of history a streak spans (>= 1).
    lifetime : frames a tracer lives before it is re-seeded (default 4 K; initial ages are
        staggered uniformly), so tracer density stays even where the flow brings none in
        (downstream of an inflow); 0: immortal.
    seed : seeds the RNG of seeding and re-seeding (same streaks every run).

    ``at(f)`` returns (history (K + 1, M, 2) world positions newest first, count (M,) valid rows)
    at frame f, advecting from the last frame asked for (or from frame 0 when f is earlier).
    """

    def __init__(self, u, v, times, origin, cell_size, *, solid=None, count=400, length=8, lifetime=None, seed=0):
        self.u, self.v = u, v
        if np.ndim(u) != 3 or np.shape(u) != np.shape(v):
            raise ValueError(f"GridStreaks: u and v must be (F, nx, ny) arrays of one shape; got "
                             f"{np.shape(u)} and {np.shape(v)}")
        if int(count) != count or count < 1:
            raise ValueError(f"GridStreaks: count must be an integer >= 1; got {count!r}")
        if int(length) != length or length < 1:
            raise ValueError(f"GridStreaks: length must be an integer >= 1 (frames); got {length!r}")
        if not cell_size > 0:
            raise ValueError(f"GridStreaks: cell_size must be > 0; got {cell_size!r}")
        self.times = np.asarray(times, np.float64)
        self.origin = np.asarray(origin, np.float64).ravel()[:2]
        self.h = float(cell_size)
        self.solid = solid
        self.shape = tuple(np.shape(u)[1:3])
        self.count, self.length, self.seed = int(count), int(length), int(seed)
        self.lifetime = 4 * self.length if lifetime is None else int(lifetime)
        if self.lifetime < 0:
            raise ValueError(f"GridStreaks: lifetime must be >= 0 frames (0: immortal); got {lifetime!r}")
        self._reset()

    @classmethod
    def from_states(cls, states, name, **options):
        """The streaks of fluid ``name`` of a recorded run; None when it recorded no ``u``/``v``."""
        f = states.fields
        if f"fluid/{name}/u" not in f or f"fluid/{name}/v" not in f:
            return None
        return cls(f[f"fluid/{name}/u"], f[f"fluid/{name}/v"], states.times,
                   states.model[f"fluid/{name}/origin"], float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0]),
                   solid=f.get(f"fluid/{name}/solid"), **options)

    def _solid(self, frame):
        if self.solid is None:
            return np.zeros(self.shape, np.uint8)
        return np.ascontiguousarray(self.solid[frame], dtype=np.uint8)

    def _seed_points(self, n, solid):
        """n uniform points in the grid's fluid cells (rejection sampling with the run's RNG)."""
        out = np.empty((n, 2))
        size = np.array(self.shape, np.float64) * self.h
        filled = 0
        if not (solid == 0).any():  # nothing but solid: points anywhere (they re-seed next frame)
            return self.origin + self._rng.random((n, 2)) * size
        while filled < n:
            pts = self.origin + self._rng.random((n - filled, 2)) * size
            cell = np.minimum(((pts - self.origin) / self.h).astype(np.int64), np.array(self.shape) - 1)
            keep = pts[solid[cell[:, 0], cell[:, 1]] == 0]
            out[filled:filled + len(keep)] = keep
            filled += len(keep)
        return out

    def _reset(self):
        self._rng = np.random.default_rng(self.seed)
        self.frame = 0
        x = self._seed_points(self.count, self._solid(0))
        self.history = np.repeat(x[None], self.length + 1, axis=0)
        self.valid = np.ones(self.count, np.int64)
        self.age = (self._rng.integers(0, self.lifetime, self.count) if self.lifetime > 0
                    else np.zeros(self.count, np.int64))

    def substeps(self, f0, f1):
        """RK2 substeps from frame f0 to f1: CFL 1 (one cell) on the larger frame maximum speed."""
        dt = float(self.times[f1] - self.times[f0])
        vmax = max(float(np.max(np.abs(self.u[f0]))), float(np.max(np.abs(self.v[f0]))),
                   float(np.max(np.abs(self.u[f1]))), float(np.max(np.abs(self.v[f1]))))
        if not math.isfinite(vmax):
            return MAX_SUBSTEPS
        return int(min(max(math.ceil(vmax * abs(dt) / self.h), 1), MAX_SUBSTEPS))

    def _step(self):
        f0, f1 = self.frame, self.frame + 1
        x = self.history[0].copy()  # advected apart from the history, then shifted in
        lost = np.zeros(self.count, np.bool_)
        solid = self._solid(f1)
        u0, v0 = (np.ascontiguousarray(a[f0], dtype=np.float64) for a in (self.u, self.v))
        u1, v1 = (np.ascontiguousarray(a[f1], dtype=np.float64) for a in (self.u, self.v))
        advect_tracers(x, lost, u0, v0, u1, v1, solid, self.origin[0], self.origin[1], self.h,
                       float(self.times[f1] - self.times[f0]), self.substeps(f0, f1))
        self.history[1:] = self.history[:-1]
        self.history[0] = x
        self.valid = np.minimum(self.valid + 1, self.length + 1)
        self.age += 1
        if self.lifetime > 0:
            lost |= self.age >= self.lifetime
        if lost.any():  # re-seeded tracers start fresh streaks
            fresh = self._seed_points(int(lost.sum()), solid)
            self.history[:, lost] = fresh[None]
            self.valid[lost] = 1
            self.age[lost] = 0
        self.frame = f1

    def at(self, frame):
        """(history (K + 1, M, 2), valid (M,)) at ``frame`` (see the class docstring)."""
        frame = int(frame)
        if not 0 <= frame < len(self.times):
            raise ValueError(f"GridStreaks.at: frame must be in [0, {len(self.times) - 1}]; got {frame}")
        if frame < self.frame:
            self._reset()
        while self.frame < frame:
            self._step()
        return self.history, self.valid

    def paint(self, image, frame, to_pixels, *, width_px=1.5, color=(255.0, 255.0, 255.0), changed=None):
        """Draw the streaks of ``frame`` over ``image`` (H, W, 3) uint8 in place. ``to_pixels``:
        (ax, bx, ay, by), pixel = (ax + bx x, ay + by y). Returns the (H, W) bool mask of the
        pixels changed (``changed`` is updated when given)."""
        history, valid = self.at(frame)
        h, w = image.shape[:2]
        alpha = np.zeros((h, w), np.float32)
        ax, bx, ay, by = (float(c) for c in to_pixels)
        streak_alpha(history, valid, ax, bx, ay, by, float(width_px), STREAK_TAIL_ALPHA, alpha)
        if changed is None:
            changed = np.zeros((h, w), np.bool_)
        blend_streaks(image, alpha, np.asarray(color, np.float64), changed)
        return changed
