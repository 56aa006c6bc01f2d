"""3-D smoke as a ray-marched, lit participating medium composited over a rendered frame.

The smoke is an absorbing, singly scattering medium (Max 1995, "absorption plus single
scattering" model) whose extinction coefficient is ``sigma_t * density`` (1/m) and whose
scattering albedo is ``albedo`` (per colour channel). Along a camera ray x(s) the radiance is

    L = integral_0^S T(s) sigma_t rho(x(s)) [albedo (L_light T_light(x) + L_ambient) + E(temp)] ds
        + T(S) L_background,        T(s) = exp(-integral_0^s sigma_t rho ds'),

with S the distance to the first opaque surface (the renderer's depth buffer: meshes, colliders,
ground and particles occlude smoke behind them), an isotropic phase function (folded into
``light_color``), and ``T_light(x) = exp(-sigma_t integral rho ds)`` the transmittance from x
towards the one directional light. This is the rendering of Fedkiw, Stam and Jensen (2001) §5
("Rendering": a precomputed light-transmittance grid, then one march per pixel), in the
notation of Max (1995).

Stages (each a Numba kernel):

1. ``occupied_box``: the cell box holding density above a threshold (optical depth per cell
   below 1e-5 is skipped), grown by one cell for the trilinear stencil; nothing is drawn
   when it is empty (the image stays bit for bit).
2. ``light_transmittance`` (parallel over x slabs of cells): from every cell centre in the box,
   a march towards the light in steps of one cell, midpoint samples, clipped to the box:
   ``T_light = exp(-sigma_t sum rho ds)``, or 0 once it enters an opaque (obstacle) cell more
   than a cell from its start. Per frame, so the per-pixel cost stays one march.
3. ``brick_max``: the largest density per brick of 4^3 cells (grown by the trilinear stencil), so
   rays cross empty bricks without sampling them (empty-space skipping).
4. ``march_smoke`` (parallel over pixel rows): per pixel the camera ray (the renderer's
   ``_primary_ray``) is clipped to the box and to the depth buffer and marched front to back in
   steps ``step`` (cells), the last step shortened to end exactly at the exit; per segment of
   length ds, ``a = 1 - exp(-sigma_t rho ds)`` (rho trilinear at the segment midpoint) and
   ``C += T a S``, ``T *= 1 - a``. The march stops when the opacity reaches ``1 - min_transmittance``
   (0.99 default). Only pixels the march touched are rewritten.

Before the march, ``shadow_surfaces`` (with ``shadow_strength`` s > 0 and a depth buffer) darkens
every opaque surface the smoke shades from the light: the surface point p of a pixel (from its
view depth), the point q where the ray from p towards the light enters the smoke's box (p itself
inside it), T_light(q) trilinear from the transmittance grid, colour *= 1 - s (1 - T_light). With
obstacles (``solid``) that grid is marched a second time without them (the renderer already
shades surfaces the obstacles hide from the light), doubling stage 2's cost.

Optional emission (fire-like plumes): ``E(temp) = emission * ramp((temp - t0) / (t1 - t0))``,
a black-body-like ramp dark red -> orange -> pale yellow.

References
----------
- N. Max, "Optical models for direct volume rendering", IEEE TVCG 1(2), 1995 (emission,
  absorption and single scattering; front-to-back compositing).
- R. Fedkiw, J. Stam and H. W. Jensen, "Visual simulation of smoke", SIGGRAPH 2001, §5
  (precomputed light transmittance per voxel, one ray march per pixel).
- J. T. Kajiya and B. P. Von Herzen, "Ray tracing volume densities", SIGGRAPH 1984.

Limitations
-----------
- Single scattering from one directional light plus a constant ambient term; no multiple
  scattering, isotropic phase function.
- Smoke shadows on opaque surfaces (``shadow_strength`` > 0; `paint_volumes` passes the
  renderer's) darken the whole finished pixel by 1 - s (1 - T_light), s the renderer's shadow
  strength, as its mesh shadows do: the frame's shading is not split into direct and ambient
  parts, and T_light at a surface point outside the smoke's box is the box's value where the
  light ray enters it, clamped to the box's cell centres (shadow edges land within about a cell).
  Opaque obstacles shadow the smoke only
  through a cell mask (``solid``: cells whose centre is inside a collider), so their shadows
  are staircased at the cell size and ignore obstacles outside the smoke's box.
- Fixed step along each ray (no jitter): a step of 0.5 cell shows faint banding at grazing
  views of sharp fronts.
- Particles drawn by the renderer are opaque and occlude smoke behind them, but smoke in front
  of them is composited over the finished 8-bit frame (linearised through a 256-entry table).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .._jit import parallel_kernel
from .kernels import _primary_ray

__all__ = ["SmokeStyle", "occupied_box", "light_transmittance", "march_smoke", "shadow_surfaces",
           "render_smoke_linear", "composite_smoke", "emission_color"]

# Layout of the float64 style vector the march kernel reads.
_P_SIGMA, _P_STEP, _P_MIN_T = 0, 1, 2
_P_ALBEDO, _P_LIGHT, _P_AMBIENT = 3, 6, 9
_P_EMISSION, _P_T0, _P_T1, _P_HAS_TEMP, _P_SKIP = 12, 13, 14, 15, 16
_P_SIZE = 17
#: Cells per side of the bricks of `brick_max` (empty-space skipping).
BRICK = 4
# Parallel builds from this many pixels / occupied cells, the renderer's pixel threshold: the
# default 960 x 540 frame and grids up to ~84^3 run the serial twins, the builds `inertia warmup`
# compiles (a parallel build costs several times the compile time, and on a busy 2-core machine
# a parallel hand-off often does not pay).
_PARALLEL_PIXELS = 600_000
_PARALLEL_CELLS = 600_000


def _skip_level(sigma_t: float, cell_size: float) -> float:
    """Density below which a cell is treated as empty: optical depth 1e-5 per cell."""
    return 1e-5 / (sigma_t * cell_size)


class SmokeStyle:
    """How smoke looks (linear RGB, physical units).

    sigma_t : extinction per unit density, 1/m (smoke of density 1 over 1/sigma_t m transmits
        1/e). 20 default; a run picks it from its density range (`sigma_for`).
    albedo : scattering albedo sigma_s / sigma_t per channel, (0.9, 0.9, 0.92) default (grey-white).
    light_color : radiance scattered from the directional light (linear RGB, isotropic phase
        folded in), (1.25, 1.2, 1.1) default (warm key light; lit smoke just below white).
    ambient : radiance scattered from the sky (linear RGB), (0.1, 0.11, 0.14) default (cool fill,
        so the shadowed side stays grey-blue rather than black).
    step : ray-march step in cells, 0.5 default (0.25-1; smaller is smoother and slower).
    min_transmittance : the march stops when the transmittance falls below this, 0.01 default.
    emission : strength of the temperature glow (0 default: off; 2-6 for a candle-like plume).
    temperature_range : (t0, t1) of the glow ramp, in the fluid's temperature units.
    """

    def __init__(self, *, sigma_t=20.0, albedo=(0.9, 0.9, 0.92), light_color=(1.4, 1.32, 1.2),
                 ambient=(0.05, 0.06, 0.08), step=0.5, min_transmittance=0.01, emission=0.0,
                 temperature_range=(0.0, 1.0)):
        if not (np.isfinite(sigma_t) and sigma_t > 0):
            raise ValueError(f"SmokeStyle: sigma_t must be a finite extinction > 0 (1/m); got {sigma_t!r}")
        if not (np.isfinite(step) and 0.05 <= step <= 2.0):
            raise ValueError(f"SmokeStyle: step must be in [0.05, 2] cells; got {step!r}")
        if not (0.0 < min_transmittance < 1.0):
            raise ValueError(f"SmokeStyle: min_transmittance must be in (0, 1); got {min_transmittance!r}")
        if not (np.isfinite(emission) and emission >= 0):
            raise ValueError(f"SmokeStyle: emission must be >= 0; got {emission!r}")
        t0, t1 = (float(v) for v in temperature_range)
        if not t1 > t0:
            raise ValueError(f"SmokeStyle: temperature_range must be (t0, t1) with t1 > t0; got {temperature_range!r}")
        self.sigma_t, self.step, self.min_transmittance = float(sigma_t), float(step), float(min_transmittance)
        self.albedo = np.asarray(albedo, np.float64).reshape(3)
        self.light_color = np.asarray(light_color, np.float64).reshape(3)
        self.ambient = np.asarray(ambient, np.float64).reshape(3)
        self.emission, self.temperature_range = float(emission), (t0, t1)

    def params(self, cell_size: float, has_temperature: bool) -> np.ndarray:
        """The float64 style vector of `march_smoke` (step converted to metres)."""
        p = np.zeros(_P_SIZE)
        p[_P_SIGMA], p[_P_STEP], p[_P_MIN_T] = self.sigma_t, self.step * cell_size, self.min_transmittance
        p[_P_ALBEDO:_P_ALBEDO + 3] = self.albedo
        p[_P_LIGHT:_P_LIGHT + 3] = self.light_color
        p[_P_AMBIENT:_P_AMBIENT + 3] = self.ambient
        p[_P_EMISSION], p[_P_T0], p[_P_T1] = self.emission, *self.temperature_range
        p[_P_HAS_TEMP] = 1.0 if (has_temperature and self.emission > 0) else 0.0
        p[_P_SKIP] = _skip_level(self.sigma_t, cell_size)
        return p


# ----------------------------------------------------------------------------- kernels
@njit(cache=True)
def _trilinear(a, gx, gy, gz):
    """Trilinear sample of cell-centred values ``a`` (nx, ny, nz) at grid coordinates g (cell
    centres at integers), clamped to the outer cell centres."""
    nx, ny, nz = a.shape
    gx = min(max(gx, 0.0), nx - 1.0)
    gy = min(max(gy, 0.0), ny - 1.0)
    gz = min(max(gz, 0.0), nz - 1.0)
    i = min(int(gx), nx - 2) if nx > 1 else 0
    j = min(int(gy), ny - 2) if ny > 1 else 0
    k = min(int(gz), nz - 2) if nz > 1 else 0
    fx, fy, fz = gx - i, gy - j, gz - k
    i1, j1, k1 = min(i + 1, nx - 1), min(j + 1, ny - 1), min(k + 1, nz - 1)
    c00 = a[i, j, k] * (1.0 - fx) + a[i1, j, k] * fx
    c10 = a[i, j1, k] * (1.0 - fx) + a[i1, j1, k] * fx
    c01 = a[i, j, k1] * (1.0 - fx) + a[i1, j, k1] * fx
    c11 = a[i, j1, k1] * (1.0 - fx) + a[i1, j1, k1] * fx
    c0 = c00 * (1.0 - fy) + c10 * fy
    c1 = c01 * (1.0 - fy) + c11 * fy
    return c0 * (1.0 - fz) + c1 * fz


@njit(cache=True)
def _clip_box(ox, oy, oz, dx, dy, dz, lo, hi):
    """Entry and exit distances (t0, t1) of the ray o + t d through the box [lo, hi] (t0 > t1: miss)."""
    t0, t1 = -1e300, 1e300
    o = (ox, oy, oz)
    d = (dx, dy, dz)
    for a in range(3):
        if abs(d[a]) < 1e-300:
            if o[a] < lo[a] or o[a] > hi[a]:
                return 1.0, 0.0
            continue
        inv = 1.0 / d[a]
        ta, tb = (lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv
        if ta > tb:
            ta, tb = tb, ta
        t0 = max(t0, ta)
        t1 = min(t1, tb)
    return t0, t1


@njit(cache=True)
def occupied_box(density, threshold, box):
    """Cell index box (i0, i1, j0, j1, k0, k1), half-open, of the cells with density > threshold,
    grown by one cell (clamped to the grid); written into ``box`` (6,) int64. Returns False when
    no cell is above the threshold. Serial (a reduction): deterministic."""
    nx, ny, nz = density.shape
    i0, j0, k0, i1, j1, k1 = nx, ny, nz, -1, -1, -1
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if density[i, j, k] > threshold:
                    i0, i1 = min(i0, i), max(i1, i)
                    j0, j1 = min(j0, j), max(j1, j)
                    k0, k1 = min(k0, k), max(k1, k)
    if i1 < 0:
        return False
    box[0], box[1] = max(i0 - 1, 0), min(i1 + 2, nx)
    box[2], box[3] = max(j0 - 1, 0), min(j1 + 2, ny)
    box[4], box[5] = max(k0 - 1, 0), min(k1 + 2, nz)
    return True


@parallel_kernel
def light_transmittance(density, solid, box, cell_size, light_dir, sigma_t, out):
    """``out[i, j, k] = exp(-sigma_t integral rho ds)`` from each cell centre of the index box
    ``box`` towards the light (unit ``light_dir``), marched in steps of one cell with midpoint
    trilinear samples, the last step ending at the box's surface (density is zero outside it).
    ``solid`` (nx, ny, nz) uint8, or a (1, 1, 1) dummy for none: opaque cells (obstacles); a
    march that enters one more than a cell from its start is in shadow (0). Cells outside the
    box get 1. Parallel over x slabs; each cell written by one iteration."""
    nx, ny, nz = density.shape
    h = cell_size
    lo = np.array([box[0] * h, box[2] * h, box[4] * h])
    hi = np.array([box[1] * h, box[3] * h, box[5] * h])
    lx, ly, lz = light_dir[0], light_dir[1], light_dir[2]
    has_solid = solid.shape == density.shape
    for i in prange(nx):
        for j in range(ny):
            for k in range(nz):
                if i < box[0] or i >= box[1] or j < box[2] or j >= box[3] or k < box[4] or k >= box[5]:
                    out[i, j, k] = 1.0
                    continue
                ox, oy, oz = (i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h  # grid-local metres
                _, t1 = _clip_box(ox, oy, oz, lx, ly, lz, lo, hi)
                tau, t = 0.0, 0.0
                blocked = False
                while t < t1:
                    ds = min(h, t1 - t)
                    tm = t + 0.5 * ds
                    px, py, pz = ox + tm * lx, oy + tm * ly, oz + tm * lz
                    if has_solid and tm > h:
                        ci, cj, ck = int(px / h), int(py / h), int(pz / h)
                        if 0 <= ci < nx and 0 <= cj < ny and 0 <= ck < nz and solid[ci, cj, ck]:
                            blocked = True
                            break
                    rho = _trilinear(density, px / h - 0.5, py / h - 0.5, pz / h - 0.5)
                    tau += rho * ds
                    t += ds
                out[i, j, k] = 0.0 if blocked else math.exp(-sigma_t * tau)


@parallel_kernel
def shadow_surfaces(cam, width, height, depth, transmit, origin, cell_size, box, light_dir, strength, color, touched):
    """Darken the opaque surfaces the smoke shades from the light (see the module docstring):
    ``color`` (H, W, 3) float32 linear *= 1 - strength (1 - T_light) where ``depth`` (H, W) holds
    a surface (below 1e37); T_light trilinear from ``transmit`` (the `light_transmittance` grid)
    at the surface point, or where its ray to the light enters the cell box ``box`` (6,) (clamped
    to the box's cell centres). ``touched`` (H, W) uint8 set where a pixel changed. Parallel over
    rows; each pixel written once."""
    h = cell_size
    lo = np.array([origin[0] + box[0] * h, origin[1] + box[2] * h, origin[2] + box[4] * h])
    hi = np.array([origin[0] + box[1] * h, origin[1] + box[3] * h, origin[2] + box[5] * h])
    lx, ly, lz = light_dir[0], light_dir[1], light_dir[2]
    fx, fy, fz = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            d = depth[py, px]
            if not d < 1e37:
                continue
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            along = dx * fx + dy * fy + dz * fz
            if along <= 1e-12:
                continue
            t = d / along
            sx, sy, sz = ox + t * dx, oy + t * dy, oz + t * dz
            t0, t1 = _clip_box(sx, sy, sz, lx, ly, lz, lo, hi)
            t0 = max(t0, 0.0)
            if t1 < t0:
                continue
            qx, qy, qz = sx + t0 * lx, sy + t0 * ly, sz + t0 * lz
            gx = min(max((qx - origin[0]) / h - 0.5, box[0]), box[1] - 1.0)
            gy = min(max((qy - origin[1]) / h - 0.5, box[2]), box[3] - 1.0)
            gz = min(max((qz - origin[2]) / h - 0.5, box[4]), box[5] - 1.0)
            tl = _trilinear(transmit, gx, gy, gz)
            if tl >= 1.0:
                continue
            f = 1.0 - strength * (1.0 - tl)
            for c in range(3):
                color[py, px, c] *= f
            touched[py, px] = 1


@njit(cache=True)
def brick_max(density, out):
    """``out[b]``: the largest density over brick b (``BRICK``^3 cells) grown by one cell on every
    side (the trilinear stencil of a point in the brick reaches that far). Serial, deterministic."""
    nx, ny, nz = density.shape
    for bi in range(out.shape[0]):
        for bj in range(out.shape[1]):
            for bk in range(out.shape[2]):
                m = 0.0
                for i in range(max(bi * BRICK - 1, 0), min((bi + 1) * BRICK + 1, nx)):
                    for j in range(max(bj * BRICK - 1, 0), min((bj + 1) * BRICK + 1, ny)):
                        for k in range(max(bk * BRICK - 1, 0), min((bk + 1) * BRICK + 1, nz)):
                            m = max(m, density[i, j, k])
                out[bi, bj, bk] = m


@njit(cache=True)
def emission_color(s, strength):
    """Black-body-like glow of normalised temperature s in [0, 1]: dark red -> orange -> pale
    yellow (linear RGB), times ``strength``."""
    s = min(max(s, 0.0), 1.0)
    return strength * s ** 1.5, strength * 0.55 * s ** 3, strength * 0.18 * s ** 6


@parallel_kernel
def march_smoke(cam, width, height, density, temperature, transmit, bricks, origin, cell_size, lo, hi, style, depth,
                color, touched):
    """Front-to-back march of every pixel's camera ray through the density grid (see the module
    docstring); ``color`` (H, W, 3) float32 linear RGB is the background, overwritten where the
    ray met smoke (``touched`` (H, W) uint8 set to 1 there). ``lo``/``hi``: world box of the
    occupied cells; ``depth`` (H, W) float32: view depth of the first opaque surface.
    ``temperature`` may be a (1, 1, 1) dummy when ``style`` has no emission. ``bricks``: `brick_max`
    of the density; a ray crosses bricks at or below ``style[_P_SKIP]`` without sampling them."""
    sigma, step, min_t, skip = style[_P_SIGMA], style[_P_STEP], style[_P_MIN_T], style[_P_SKIP]
    has_temp = style[_P_HAS_TEMP] > 0.5
    t_lo, t_span = style[_P_T0], style[_P_T1] - style[_P_T0]
    h = cell_size
    fx, fy, fz = cam[9], cam[10], cam[11]
    for py in prange(height):
        for px in range(width):
            ox, oy, oz, dx, dy, dz = _primary_ray(cam, px, py)
            t0, t1 = _clip_box(ox, oy, oz, dx, dy, dz, lo, hi)
            t0 = max(t0, 0.0)
            along = dx * fx + dy * fy + dz * fz
            if along > 1e-12:
                t1 = min(t1, depth[py, px] / along)
            if t1 <= t0:
                continue
            r, g, b = 0.0, 0.0, 0.0
            trans = 1.0
            hit = False
            t = t0
            while t < t1:
                # empty-space skipping: a brick with (almost) no smoke is crossed in one go
                tq = t + 1e-6 * h
                bi = int((ox + tq * dx - origin[0]) / h) // BRICK
                bj = int((oy + tq * dy - origin[1]) / h) // BRICK
                bk = int((oz + tq * dz - origin[2]) / h) // BRICK
                if 0 <= bi < bricks.shape[0] and 0 <= bj < bricks.shape[1] and 0 <= bk < bricks.shape[2] \
                        and bricks[bi, bj, bk] <= skip:
                    _, t_out = _clip_box(ox, oy, oz, dx, dy, dz,
                                         (origin[0] + bi * BRICK * h, origin[1] + bj * BRICK * h, origin[2] + bk * BRICK * h),
                                         (origin[0] + (bi + 1) * BRICK * h, origin[1] + (bj + 1) * BRICK * h,
                                          origin[2] + (bk + 1) * BRICK * h))
                    t = max(t_out, tq)
                    continue
                ds = min(step, t1 - t)
                tm = t + 0.5 * ds
                t += ds
                gx = (ox + tm * dx - origin[0]) / h - 0.5
                gy = (oy + tm * dy - origin[1]) / h - 0.5
                gz = (oz + tm * dz - origin[2]) / h - 0.5
                rho = _trilinear(density, gx, gy, gz)
                if rho <= 0.0:
                    continue
                hit = True
                a = 1.0 - math.exp(-sigma * rho * ds)
                tl = _trilinear(transmit, gx, gy, gz)
                sr = style[_P_ALBEDO] * (style[_P_LIGHT] * tl + style[_P_AMBIENT])
                sg = style[_P_ALBEDO + 1] * (style[_P_LIGHT + 1] * tl + style[_P_AMBIENT + 1])
                sb = style[_P_ALBEDO + 2] * (style[_P_LIGHT + 2] * tl + style[_P_AMBIENT + 2])
                if has_temp:
                    er, eg, eb = emission_color((_trilinear(temperature, gx, gy, gz) - t_lo) / t_span,
                                                style[_P_EMISSION])
                    sr, sg, sb = sr + er, sg + eg, sb + eb
                w = trans * a
                r, g, b = r + w * sr, g + w * sg, b + w * sb
                trans *= 1.0 - a
                if trans < min_t:
                    break
            if not hit:
                continue
            color[py, px, 0] = r + trans * color[py, px, 0]
            color[py, px, 1] = g + trans * color[py, px, 1]
            color[py, px, 2] = b + trans * color[py, px, 2]
            touched[py, px] = 1


@njit(cache=True)
def _bytes_of_touched(color, touched, lut, out):
    """sRGB bytes (``lut``: 4096-entry linear -> sRGB table) of the touched pixels into ``out``."""
    n = lut.shape[0] - 1
    for y in range(color.shape[0]):
        for x in range(color.shape[1]):
            if touched[y, x]:
                for c in range(3):
                    v = min(max(color[y, x, c], 0.0), 1.0)
                    out[y, x, c] = lut[int(v * n + 0.5)]


# ----------------------------------------------------------------------------- Python API
def _check_grid(density, origin, cell_size):
    rho = np.ascontiguousarray(density, dtype=np.float32)
    if rho.ndim != 3 or min(rho.shape) < 2:
        raise ValueError(f"density must be a 3-D grid (nx, ny, nz), each >= 2; got shape {np.shape(density)}")
    if not (np.isfinite(cell_size) and cell_size > 0):
        raise ValueError(f"cell_size must be a finite length > 0 (m); got {cell_size!r}")
    o = np.asarray(origin, np.float64).reshape(-1)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ValueError(f"origin must be 3 finite numbers (m); got {origin!r}")
    return rho, o


def render_smoke_linear(color, camera, density, *, origin, cell_size, light_direction, style=None,
                        depth=None, temperature=None, solid=None, shadow_strength=0.0):
    """Composite smoke over ``color`` (H, W, 3) float32 linear RGB in place; returns the (H, W)
    uint8 mask of the pixels changed (all zero for an empty grid: nothing is written).

    density (nx, ny, nz) at cell centres ``origin + (i + 1/2) h``; ``light_direction`` (3,): unit
    vector towards the light; ``depth`` (H, W) view depth of opaque surfaces (None: none);
    ``temperature`` like density, for the glow when ``style.emission > 0``; ``solid`` (nx, ny, nz)
    bool: opaque cells (obstacles) that shadow the smoke behind them from the light;
    ``shadow_strength`` in [0, 1]: with a ``depth`` buffer, the smoke shades the opaque surfaces
    from the light by that strength (`shadow_surfaces`; 0: no smoke shadows)."""
    style = SmokeStyle() if style is None else style
    if not 0.0 <= shadow_strength <= 1.0:
        raise ValueError(f"shadow_strength must be in [0, 1]; got {shadow_strength!r}")
    rho, o = _check_grid(density, origin, cell_size)
    h_px, w_px = color.shape[:2]
    if color.dtype != np.float32 or color.ndim != 3 or color.shape[2] != 3 or not color.flags.c_contiguous:
        raise ValueError(f"color must be a C-contiguous (H, W, 3) float32 array; got {color.dtype} {color.shape}")
    touched = np.zeros((h_px, w_px), np.uint8)
    box = np.zeros(6, np.int64)
    # Cells whose optical depth over one cell is below 1e-5 are left out of the box.
    threshold = _skip_level(style.sigma_t, float(cell_size))
    if not occupied_box(rho, threshold, box):
        return touched
    light = np.asarray(light_direction, np.float64).reshape(3)
    light = light / np.linalg.norm(light)
    transmit = np.empty_like(rho)
    solid_cells = np.zeros((1, 1, 1), np.uint8) if solid is None else np.ascontiguousarray(solid, dtype=np.uint8)
    if solid is not None and solid_cells.shape != rho.shape:
        raise ValueError(f"solid must have the density's shape {rho.shape}; got {solid_cells.shape}")
    cells = int(np.prod(box[1::2] - box[0::2]))
    (light_transmittance.parallel if cells >= _PARALLEL_CELLS else light_transmittance.serial)(
        rho, solid_cells, box, float(cell_size), light, style.sigma_t, transmit)
    lo = o + float(cell_size) * box[0::2]
    hi = o + float(cell_size) * box[1::2]
    cam = camera.params(w_px, h_px)
    if depth is not None and shadow_strength > 0.0:
        # the smoke's own transmittance: obstacles shade the surfaces already (the renderer's
        # shading and mesh shadows), so their cells must not darken them a second time
        smoke_only = transmit
        if solid is not None:
            smoke_only = np.empty_like(rho)
            (light_transmittance.parallel if cells >= _PARALLEL_CELLS else light_transmittance.serial)(
                rho, np.zeros((1, 1, 1), np.uint8), box, float(cell_size), light, style.sigma_t, smoke_only)
        (shadow_surfaces.parallel if w_px * h_px >= _PARALLEL_PIXELS else shadow_surfaces.serial)(
            cam, w_px, h_px, np.ascontiguousarray(depth, dtype=np.float32), smoke_only, o, float(cell_size), box, light,
            float(shadow_strength), color, touched)
    if depth is None:
        depth = np.full((h_px, w_px), np.float32(3.0e38), np.float32)
    has_temp = temperature is not None
    temp = (np.ascontiguousarray(temperature, dtype=np.float32) if has_temp else np.zeros((1, 1, 1), np.float32))
    if has_temp and temp.shape != rho.shape:
        raise ValueError(f"temperature must have the density's shape {rho.shape}; got {temp.shape}")
    kernel = march_smoke.parallel if w_px * h_px >= _PARALLEL_PIXELS else march_smoke.serial
    bricks = np.empty(tuple(-(-np.array(rho.shape) // BRICK)), np.float32)
    brick_max(rho, bricks)
    kernel(cam, w_px, h_px, rho, temp, transmit, bricks, o, float(cell_size), lo, hi,
                style.params(float(cell_size), has_temp), np.ascontiguousarray(depth, dtype=np.float32), color, touched)
    return touched


_SRGB8_TO_LINEAR = None


def _srgb8_to_linear_table() -> np.ndarray:
    global _SRGB8_TO_LINEAR
    if _SRGB8_TO_LINEAR is None:
        c = np.arange(256) / 255.0
        _SRGB8_TO_LINEAR = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)
    return _SRGB8_TO_LINEAR


def composite_smoke(image, camera, density, *, origin, cell_size, light_direction, style=None, depth=None,
                    temperature=None, solid=None, shadow_strength=0.0):
    """Composite smoke over ``image`` (H, W, 3) uint8 sRGB in place (see `render_smoke_linear`);
    pixels no ray of smoke touched keep their bytes. Returns ``image``."""
    from .renderer import _LUT

    color = _srgb8_to_linear_table()[image]
    touched = render_smoke_linear(color, camera, density, origin=origin, cell_size=cell_size,
                                  light_direction=light_direction, style=style, depth=depth, temperature=temperature,
                                  solid=solid, shadow_strength=shadow_strength)
    if touched.any():
        _bytes_of_touched(color, touched, _LUT, image)
    return image
