"""Colour-map images of 2-D grid fluids (density, speed, vorticity or any scalar) with tracer
streaks, written with NumPy (PNG through `inertia.render.png`).

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
``streak_length`` positions, drawn as dots that fade from white to the map colour. Tracers that
leave the domain are re-seeded at their start point (seeded RNG: same image every run).

Limitations: 2-D grids only (3-D smoke needs the volume ray marcher, not written yet); the
image is not anti-aliased; streaks are dots, not lines.
"""

from __future__ import annotations

import numpy as np

from .colormaps import colormap
from .png import write_png

QUANTITIES = ("density", "speed", "vorticity")


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
    """

    def __init__(self, fluid, quantity="density", *, pixels_per_cell=2, tracers=0,
                 streak_length=12, vmax=None, seed=0):
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
        k = self.history.shape[0]
        if self.history.shape[1]:
            h, w = img.shape[:2]
            scale = np.array([w, h]) / (self.hi - self.lo)
            for age in range(k):
                pts = (self.history[age] - self.lo) * scale
                px = np.clip(pts[:, 0].astype(np.int64), 0, w - 1)
                py = np.clip(h - 1 - pts[:, 1].astype(np.int64), 0, h - 1)
                fade = (age + 1) / k
                img[py, px] = (1 - fade) * img[py, px] + fade * 1.0
        return (np.clip(img, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)

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
