"""The offline renderer: particles as shaded spheres, colliders, a ground grid, contact shadows.

A small Numba rasterizer (why not a library: see docs/rendering.md). Usage::

    from inertia.render import Renderer
    renderer = Renderer(1280, 720, dim=3)
    image = renderer.frame(positions, radius=0.02, velocities=v, colliders=[ground, ball], t=t)
    # image: (720, 1280, 3) uint8, sRGB

The camera frames the scene on the first `frame` call unless given (`camera=`) or fitted to a
whole run first (`Renderer.fit`, which `render_states` calls with every frame).

Stages per frame (see `inertia.render.kernels` for what each reads and writes):
background (cached while camera and colliders are still) -> ``underlay`` (2-D grid fluids'
colour maps and streaks, painted under the particles) -> contact shadows -> project ->
sort back to front -> splat spheres band by band (parallel over row bands) -> sRGB bytes.

Colours
-------
``colors=`` per particle ((N, 3) floats in [0, 1] or uint8, or one colour) wins; otherwise
``color_by``: "speed" (|v| through ``colormap``, 0 to ``speed_max``, default the 99th percentile
of the frame), "group" (Tableau 10 by group index), "uniform" (``color``) or "auto" (group when
there are several groups, else speed when velocities are given, else uniform).

Radii are in world units; particles with radius 0 (points) or no radius get
``default_radius`` (default 0.4 % of the scene diagonal). Nothing is drawn smaller than
``min_radius_px`` pixels.

Limitations: opaque spheres only; one directional light; shadows only on ground planes whose
normal is the up axis; 2-D colliders are drawn behind the particles.
"""

from __future__ import annotations

import math
import threading
from typing import Sequence

import numpy as np

from . import kernels as K
from .camera import UP_AXES, Camera
from .colliders import collider_bounds, collider_primitives, trace_signed_distance
from .colormaps import COLORMAPS, DEFAULT_SPEED_MAP, colormap, parse_color, particle_colors, resolve_color_mode, robust_speed_max

__all__ = ["Renderer", "scene_bounds", "nice_step", "THEMES"]

#: Colour themes: background, grid, ground and collider colours (sRGB).
THEMES = {
    "dark": {
        "sky_top": (0.075, 0.082, 0.102), "sky_horizon": (0.19, 0.2, 0.23), "ground": (0.26, 0.27, 0.29),
        "paper": (0.1, 0.105, 0.125), "grid": (0.3, 0.32, 0.36), "ground_line": (0.9, 0.9, 0.9),
        "collider": (0.62, 0.64, 0.68),
        "particle": (0.35, 0.62, 0.95),
    },
    "light": {
        "sky_top": (0.82, 0.86, 0.91), "sky_horizon": (0.96, 0.96, 0.95), "ground": (0.78, 0.78, 0.77),
        "paper": (0.985, 0.985, 0.98), "grid": (0.82, 0.83, 0.85), "ground_line": (0.35, 0.36, 0.38),
        "collider": (0.55, 0.58, 0.63),
        "particle": (0.12, 0.47, 0.71),
    },
}

_COLOR_BY = ("auto", "speed", "group", "uniform")


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _linear_to_srgb_lut(size: int = 4096) -> np.ndarray:
    x = np.linspace(0.0, 1.0, size)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.clip(np.round(s * 255.0), 0, 255).astype(np.uint8)


_LUT = _linear_to_srgb_lut()
# Per-particle kernels (project, gather, colours) run serially below this many particles: they
# take ~10 ns a particle, and a parallel hand-off costs more, much more on a busy machine.
_PARALLEL_MIN = 200_000
# The per-pixel kernels (backgrounds, bands) run in parallel from this many pixels (or, for the
# band kernel, particles): 1280 x 720 and up. Below (the default 960 x 540 frame) they run on one
# thread: a frame costs ~10-40 ms either way, the parallel builds take ~6 s longer to compile
# on a cold cache, and on a busy 2-core machine a parallel hand-off can cost milliseconds.
_PARALLEL_PIXELS = 600_000
_PARALLEL_PARTICLES = 20_000
_LIN_LUT = _srgb_to_linear(np.linspace(0.0, 1.0, 4096)).astype(np.float32)
# Gaussian, sigma = 1.2 texels.
_BLUR_TAPS = np.exp(-0.5 * (np.arange(-3, 4) / 1.2) ** 2)
_BLUR_TAPS /= _BLUR_TAPS.sum()


def nice_step(length: float) -> float:
    """The 1-2-5 x 10^k number nearest below ``length`` (grid spacing)."""
    if not length > 0 or not math.isfinite(length):
        return 1.0
    exponent = math.floor(math.log10(length))
    base = length / 10**exponent
    step = 5.0 if base >= 5 else (2.0 if base >= 2 else 1.0)
    return step * 10**exponent


def scene_bounds(positions, *, active=None, robust: float = 0.001, max_samples: int = 2_000_000):
    """Bounding box (lower, upper) of positions (N, D) or (F, N, D), ignoring NaNs and inactive slots.

    ``robust``: fraction of points allowed outside on each side (0.1 % default), so that a few
    escaped particles do not shrink the view; 0 gives the exact box. Returns (D,) arrays.
    """
    pts = np.asarray(positions)
    dim = pts.shape[-1]
    if active is not None:
        pts = pts[np.asarray(active, dtype=bool)]
    pts = pts.reshape(-1, dim)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if pts.shape[0] == 0:
        return -np.ones(dim), np.ones(dim)
    if pts.shape[0] > max_samples:  # a deterministic stride sample
        pts = pts[:: int(math.ceil(pts.shape[0] / max_samples))]
    if robust > 0 and pts.shape[0] > 1000:
        lo = np.quantile(pts, robust, axis=0)
        hi = np.quantile(pts, 1.0 - robust, axis=0)
    else:
        lo, hi = pts.min(axis=0), pts.max(axis=0)
    return lo.astype(np.float64), hi.astype(np.float64)


class Renderer:
    """Headless renderer of particle frames (see the module docstring).

    Parameters (all keyword-only but size)
    ----------
    width, height : image size in pixels (1280 x 720 default).
    dim : 2 or 3. 2-D uses an orthographic top view of the x-y plane.
    camera : a `Camera`, or None to frame the scene automatically.
    up : "z" (default, Inertia's gravity is -z) or "y": the ground and orbit axis in 3-D.
    azimuth, elevation, fov_y : orbit of the automatic camera (degrees): -60, 25, 40.
    color_by, colormap, speed_max, color : particle colouring (module docstring).
    group_colors : colour per group index (None entries use the palette).
    theme : "dark" (default) or "light".
    ground : "auto" (a grid plane under the scene unless a collider plane is the ground),
        False (none), or a height along the up axis.
    shadows : contact shadows on the ground (3-D), True default.
    default_radius : radius of point particles, world units; None = 0.4 % of the scene diagonal.
    min_radius_px : smallest drawn radius in pixels, 1.0 default (0.7-2 is sensible).
    band : rows per parallel task of the splat, 16 default (8-64; smaller balances threads
        better, larger scans the particle list fewer times).
    orbit : degrees the automatic 3-D camera turns about the up axis over the run (0 default,
        still; 20-60 shows depth without distracting). `fit` with ``times`` frames every angle;
        `frame` picks the angle from its ``t``.
    follow : False default; True frames the particles near each moment of the run (key
        cameras every ~0.5 s, framed on a window of frames, interpolated by ``t``), so a
        travelling cloud stays large in the picture. Needs `fit` with (F, N, 3) positions and
        ``times``. "auto": follow only when the subject travels, i.e. when framed on the whole
        run its typical window of frames fills less than `FOLLOW_FILL` of the picture (marbles
        rolling away from their ramp); a subject that stays in place keeps a still camera.
    reserve_top : share of the frame height the automatic 3-D framing keeps free at the top for
        a legend drawn there (0 default, 0-0.2 sensible; see `Camera.fit_points`).
    """

    #: follow="auto" follows when the median window of frames fills less than this share of
    #: the picture framed on the whole run (0.12: a subject in a corner of a large travel).
    FOLLOW_FILL = 0.12

    def __init__(
        self,
        width: int = 1280,
        height: int = 720,
        *,
        dim: int = 3,
        camera: Camera | None = None,
        up: str = "z",
        azimuth: float = -60.0,
        elevation: float = 25.0,
        fov_y: float = 40.0,
        color_by: str = "auto",
        colormap: str = DEFAULT_SPEED_MAP,
        speed_max: float | None = None,
        color=None,
        group_colors=None,
        theme: str = "dark",
        ground="auto",
        shadows: bool = True,
        default_radius: float | None = None,
        min_radius_px: float = 1.0,
        band: int = 16,
        orbit: float = 0.0,
        follow: bool | str = False,
        reserve_top: float = 0.0,
    ):
        if dim not in (2, 3):
            raise ValueError(f"Renderer: dim must be 2 or 3, got {dim!r}")
        if not (isinstance(width, int) and isinstance(height, int) and width >= 8 and height >= 8):
            raise ValueError(f"Renderer: width and height must be integers >= 8, got {width!r} x {height!r}")
        if up not in UP_AXES:
            raise ValueError(f"Renderer: up must be one of {sorted(UP_AXES)}, got {up!r}")
        if color_by not in _COLOR_BY:
            raise ValueError(f"Renderer: color_by must be one of {_COLOR_BY}, got {color_by!r}")
        if theme not in THEMES:
            raise ValueError(f"Renderer: theme must be one of {sorted(THEMES)}, got {theme!r}")
        if not (ground == "auto" or ground is False or ground is None or isinstance(ground, (int, float))):
            raise ValueError(f"Renderer: ground must be 'auto', False or a height, got {ground!r}")
        if colormap not in COLORMAPS:
            raise ValueError(f"Renderer: colormap must be one of {COLORMAPS}, got {colormap!r}")
        self.width, self.height, self.dim = width, height, dim
        self.camera = camera
        self.up = up
        self.azimuth, self.elevation, self.fov_y = azimuth, elevation, fov_y
        self.color_by, self.colormap, self.speed_max = color_by, colormap, speed_max
        self.theme = dict(THEMES[theme])
        self.color = parse_color(color) if color is not None else np.array(self.theme["particle"], np.float32)
        #: Colour per group (None entries take the palette), e.g. a state file's metadata["group_colors"].
        self.group_colors = None if group_colors is None else list(group_colors)
        self.ground = ground
        self.shadows = bool(shadows)
        self.default_radius = default_radius
        self.min_radius_px = float(min_radius_px)
        self.band = int(band)
        if not (isinstance(orbit, (int, float)) and math.isfinite(orbit) and abs(orbit) <= 360.0):
            raise ValueError(f"Renderer: orbit must be degrees in [-360, 360], got {orbit!r}")
        #: Degrees the automatic camera turns about the up axis over the run (3-D; 0: still).
        self.orbit = float(orbit)
        if not (isinstance(follow, bool) or follow == "auto"):
            raise ValueError(f"Renderer: follow must be True, False or 'auto', got {follow!r}")
        #: Follow the particles over the run (3-D): the framing moves with them (see `fit`);
        #: "auto" decides in `fit` (then reads True or False).
        self.follow = follow
        if not (isinstance(reserve_top, (int, float)) and not isinstance(reserve_top, bool)
                and 0.0 <= reserve_top < 0.5):
            raise ValueError(f"Renderer: reserve_top must be a number in [0, 0.5), got {reserve_top!r}")
        #: Share of the frame height kept free at the top by the automatic 3-D framing (a legend).
        self.reserve_top = float(reserve_top)
        self._orbit_keys = None
        #: Unit world direction towards the key light (None: chosen from the first camera).
        self.light_direction = None
        #: Share of the direct light a mesh shadow takes from the ground and colliders.
        self.shadow_strength = 0.6
        #: (lower, upper) world box the camera was fitted to; sets the grid and default radius.
        self.bounds: tuple[np.ndarray, np.ndarray] | None = None
        self._background_key = None
        self._background = None
        self._lock = threading.Lock()
        self._allocate()

    # -- buffers ------------------------------------------------------------------------------
    def _allocate(self) -> None:
        h, w = self.height, self.width
        self._color = np.empty((h, w, 3), np.float32)
        self._depth = np.empty((h, w), np.float32)
        n_bands = -(-h // self.band)
        # A stride coprime with the band count, near the golden ratio, spreads bands over threads.
        stride = max(1, int(n_bands * 0.618))
        while math.gcd(stride, n_bands) != 1:
            stride += 1
        self._stride = stride
        self._shadow = np.zeros((1, 1), np.float32)
        self._shadow_scratch = np.zeros((1, 1), np.float32)
        self._mesh_shadow = np.zeros((1, 1), np.float32)

    @staticmethod
    def _kernel(name: str, count: int, threshold: int | None = None):
        """The parallel build of a kernel for `count` >= `threshold` items (``_PARALLEL_MIN``
        particles by default), else its serial twin (``inertia._jit.SizeDispatched``)."""
        kernel = getattr(K, name)
        return kernel.parallel if count >= (_PARALLEL_MIN if threshold is None else threshold) else kernel.serial

    # -- camera -------------------------------------------------------------------------------
    def fit(self, positions, *, radius=None, colliders: Sequence = (), t: float = 0.0, active=None, robust: float = 0.001,
            extra_points=None, times=None) -> Camera:
        """Frame the camera on ``positions`` ((N, D), or (F, N, D) for a whole run) and colliders.

        ``extra_points (M, D)``: more world points to keep in view (mesh vertices over the run);
        a following camera frames them only in its whole-run view, not in its keys (they are the
        still scenery, the positions are the subject).
        ``times (F,)``: the run's frame times; with ``orbit`` set, the camera is framed at
        several angles of the orbit and `frame` interpolates between them by ``t``.
        Sets and returns ``self.camera``; also fixes the grid spacing and default radius.
        """
        camera = self._fit(positions, radius, colliders, t, active, robust, extra_points)
        bounds = self.bounds
        self._orbit_keys = None
        positions = np.asarray(positions)
        timed = positions.ndim == 3 and times is not None and len(times) == positions.shape[0]
        if self.follow == "auto":
            self.follow = bool(timed and self.dim == 3 and self._subject_travels(camera, positions, times, active, radius))
        follow = self.follow and timed
        if (self.orbit or follow) and self.dim == 3 and times is not None and len(times) > 1:
            # Key cameras every <= 15 degrees of the orbit (and, following, every ~0.5 s of the
            # run, each framed on the frames within a window around its time), interpolated by
            # `camera_at`.
            times = np.asarray(times, dtype=np.float64)
            t0, t1 = float(np.min(times)), float(np.max(times))
            count = max(2, int(math.ceil(abs(self.orbit) / 15.0)) + 1)
            if follow:
                count = max(count, min(24, int(math.ceil((t1 - t0) / 0.5)) + 1))
            half_window = max(0.5, 0.75 * (t1 - t0) / (count - 1))
            act = None if active is None else np.asarray(active, dtype=bool)
            base = self.azimuth
            keys = []
            for k in range(count):
                self.azimuth = base + self.orbit * k / (count - 1)
                pos_k, act_k = positions, active
                if follow:
                    tk = t0 + (t1 - t0) * k / (count - 1)
                    near = np.abs(times - tk) <= half_window
                    pos_k = positions[near]
                    act_k = None if act is None else (act[near] if act.ndim == 2 else act)
                cam = self._fit(pos_k, radius, colliders, t, act_k, robust, None if follow else extra_points)
                keys.append([cam.target, float(np.linalg.norm(cam.position - cam.target))])
            # A key's distance is the largest of its neighbours' (the scene never leaves the
            # view between keys, and the zoom changes smoothly).
            distances = [k[1] for k in keys]
            for k in range(count):
                keys[k][1] = max(distances[max(0, k - 1):k + 2])
            self.azimuth = base
            self.camera = camera
            self._orbit_keys = (t0, t1, [tuple(k) for k in keys], camera)
        self.bounds = bounds
        return camera

    @staticmethod
    def _windows(times: np.ndarray, count: int) -> list[np.ndarray]:
        """Masks of the frames near each of ``count`` key times spread over the run (the
        following camera's windows: half a second, or more when the keys are sparser)."""
        t0, t1 = float(np.min(times)), float(np.max(times))
        half_window = max(0.5, 0.75 * (t1 - t0) / (count - 1))
        return [np.abs(times - (t0 + (t1 - t0) * k / (count - 1))) <= half_window for k in range(count)]

    def _subject_travels(self, camera: Camera, positions: np.ndarray, times, active, radius) -> bool:
        """True when the run's subject, framed on the whole run by ``camera``, fills less than
        `FOLLOW_FILL` of the picture in its median window of frames (the windows of `fit`'s
        following keys): the subject travels far compared with its own size."""
        times = np.asarray(times, dtype=np.float64)
        if len(times) < 2 or positions.shape[1] == 0:
            return False
        count = max(2, min(24, int(math.ceil((float(np.ptp(times))) / 0.5)) + 1))
        act = None if active is None else np.asarray(active, dtype=bool)
        pad = float(np.nanmax(np.asarray(radius, dtype=np.float64))) if radius is not None and np.size(radius) else 0.0
        fills = []
        for near in self._windows(times, count):
            pts = positions[near]
            if act is not None:
                pts = pts[act[near]] if act.ndim == 2 else pts[:, act[: pts.shape[1]]]
            pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
            pts = pts[np.all(np.isfinite(pts), axis=1)]
            if pts.shape[0]:
                fills.append(camera.screen_fill(pts[:: max(1, pts.shape[0] // 20_000)], self.width, self.height, pad))
        return bool(fills) and float(np.median(fills)) < self.FOLLOW_FILL

    def camera_at(self, t: float) -> Camera:
        """The camera at time ``t``: ``self.camera``, or on the orbit when one was fitted."""
        # A camera set by hand after `fit` wins over the orbit.
        if self._orbit_keys is None or self._orbit_keys[3] is not self.camera:
            return self.camera
        t0, t1, keys, _ = self._orbit_keys
        s = 0.0 if t1 <= t0 else min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        x = s * (len(keys) - 1)
        k = min(int(x), len(keys) - 2)
        w = x - k
        target = (1 - w) * keys[k][0] + w * keys[k + 1][0]
        distance = (1 - w) * keys[k][1] + w * keys[k + 1][1]
        return Camera.orbit(target, distance, azimuth=self.azimuth + self.orbit * s, elevation=self.elevation,
                            up=self.up, fov_y=self.fov_y)

    def _fit(self, positions, radius, colliders, t, active, robust, extra_points) -> Camera:
        positions = np.asarray(positions)
        if positions.shape[-1] != self.dim:
            raise ValueError(f"Renderer.fit: positions have D = {positions.shape[-1]}, the renderer dim = {self.dim}")
        if extra_points is not None and np.size(extra_points):
            extra = np.asarray(extra_points, dtype=np.float64).reshape(-1, self.dim)
            flat = positions.reshape(-1, self.dim)
            if active is not None:
                flat = flat[np.asarray(active, dtype=bool).reshape(-1)[: flat.shape[0]]]
                active = None
            positions = np.concatenate([flat, extra])
        lo, hi = scene_bounds(positions, active=active, robust=robust)
        pad = 0.0
        if radius is not None and np.size(radius):
            pad = float(np.nanmax(np.asarray(radius, dtype=np.float64)))
        lo, hi = lo - pad, hi + pad
        box = collider_bounds(collider_primitives(colliders, t, self.dim))
        if box is not None:
            lo = np.minimum(lo, box[0][: self.dim])
            hi = np.maximum(hi, box[1][: self.dim])
        # A degenerate box (one particle, a flat sheet) still gets a sensible view.
        size = float(np.max(hi - lo))
        floor = max(size * 0.25, 1e-3 if size > 0 else 1.0)
        grow = np.maximum(floor - (hi - lo), 0.0) / 2
        lo, hi = lo - grow, hi + grow
        self.bounds = (lo, hi)
        aspect = self.width / self.height
        if self.dim == 3:
            # Frame the particles themselves (a sample of every frame, robust outliers dropped)
            # and the finite colliders' boxes, not the corners of their joint bounding box.
            cloud = positions.reshape(-1, 3)
            if active is not None:
                cloud = cloud[np.asarray(active, dtype=bool).reshape(-1)[: cloud.shape[0]]]
            cloud = cloud[:: max(1, cloud.shape[0] // 50_000)]
            inside = np.all((cloud >= lo - 1e-12) & (cloud <= hi + 1e-12), axis=1)
            corners = [cloud[inside]]
            if box is not None:
                signs = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)], dtype=bool)
                blo, bhi = box[0][:3], box[1][:3]
                corners.append(np.where(signs, bhi, blo))
            if box is not None or np.any(inside):
                self.camera = Camera.fit_points(
                    np.vstack(corners), aspect=aspect, up=self.up, azimuth=self.azimuth,
                    elevation=self.elevation, fov_y=self.fov_y, pad=pad, reserve_top=self.reserve_top,
                )
                self._background_key = None
                return self.camera
        self.camera = Camera.fit(
            lo, hi, aspect=aspect, dim=self.dim, up=self.up, azimuth=self.azimuth,
            elevation=self.elevation, fov_y=self.fov_y,
        )
        self._background_key = None
        return self.camera

    def _scene_size(self) -> float:
        if self.bounds is None:
            return 1.0
        return float(np.linalg.norm(self.bounds[1] - self.bounds[0])) or 1.0

    # -- colours ------------------------------------------------------------------------------
    def particle_colors(self, count: int, *, colors=None, velocities=None, groups=None) -> np.ndarray:
        """sRGB colours (N, 3) float32 in [0, 1], as `frame` would draw them (for exporters)."""
        return particle_colors(
            count, colors=colors, velocities=velocities, groups=groups, color_by=self.color_by,
            cmap=self.colormap, speed_max=self.speed_max, color=self.color, group_colors=self.group_colors,
        )

    def _linear_colors(self, count: int, *, colors=None, velocities=None, groups=None) -> np.ndarray:
        """Linear-RGB colours (N, 3) float32 for the kernels (speed colours by a fused kernel)."""
        out = np.empty((count, 3), np.float32)
        if resolve_color_mode(self.color_by, colors, velocities, groups) == "speed":
            v = np.ascontiguousarray(velocities, dtype=np.float64)
            if v.shape != (count, self.dim):
                raise ValueError(f"Renderer: velocities must be ({count}, {self.dim}), got shape {v.shape}")
            table = _srgb_to_linear(colormap(self.colormap, np.linspace(0.0, 1.0, 256), vmin=0.0, vmax=1.0))
            vmax = robust_speed_max(v) if self.speed_max is None else float(self.speed_max)
            self._kernel("speed_colors_linear", count)(v, vmax, np.ascontiguousarray(table), out)
            return out
        srgb = self.particle_colors(count, colors=colors, velocities=velocities, groups=groups)
        self._kernel("srgb_to_linear", count)(np.ascontiguousarray(srgb, dtype=np.float32), _LIN_LUT, out)
        return out

    # -- background ---------------------------------------------------------------------------
    def _light(self, camera: Camera) -> np.ndarray:
        right, cup, forward = camera.basis()
        if self.dim == 2:
            world_up = np.array([0.0, 1.0, 0.0])
            light_cam = np.array([-0.45, 0.55, 0.7])
        else:
            world_up = UP_AXES[self.up][0]
            light_world = self._light_direction(camera)
            light_cam = np.array([light_world @ right, light_world @ cup, -(light_world @ forward)])
        light_cam = light_cam / np.linalg.norm(light_cam)
        up_cam = np.array([world_up @ right, world_up @ cup, -(world_up @ forward)])
        sky = _srgb_to_linear(np.array([0.75, 0.78, 0.85])) * 0.55
        ground = _srgb_to_linear(np.array([0.45, 0.42, 0.4])) * 0.35
        half = light_cam + np.array([0.0, 0.0, 1.0])
        light = np.zeros(21)
        light[0:3], light[3:6], light[6:9], light[9:12] = light_cam, sky, ground, up_cam
        light[12], light[13], light[14] = 0.75, 0.22, 5.0  # shininess 2**5
        light[15:18] = world_up
        light[18:21] = half / np.linalg.norm(half)
        return light

    def _light_direction(self, camera: Camera) -> np.ndarray:
        """Unit direction towards the key light, fixed in the world once chosen (so shadows and
        shading stay put while the camera orbits): from above, a little to the left of and in
        front of the first camera, unless ``self.light_direction`` was set."""
        if self.light_direction is None:
            right, _, forward = camera.basis()
            world_up = UP_AXES[self.up][0]
            light_world = 1.2 * world_up - 0.5 * right - 0.35 * forward
            self.light_direction = light_world / np.linalg.norm(light_world)
        return np.asarray(self.light_direction, np.float64)

    def _ground_rows(self, prims) -> np.ndarray:
        """The automatic ground plane (0 or 1 rows of the primitive table): none in 2-D, none
        when a collider plane faces up (it is the ground), else under the scene."""
        if self.dim == 2:
            return np.zeros((0, 16))
        up = UP_AXES[self.up][0]
        rows = []
        has_ground = any(kind == K.PRIM_PLANE and row[3:6] @ up > 0.95 for row, kind in zip(prims.params, prims.kinds, strict=True))
        if not has_ground and self.ground not in (False, None):
            if self.ground == "auto":
                # Just under the scene, so that a container's floor, if any, stays in front.
                lo = self.bounds[0] if self.bounds is not None else np.zeros(3)
                level = float(lo @ up[: len(lo)]) - 1e-3 * self._scene_size()
            else:
                level = float(self.ground)
            row = np.zeros(16)
            row[0:3], row[3:6] = up * level, up
            rows.append(row)
        return np.array(rows).reshape(-1, 16)

    def _build_background(self, camera: Camera, prims, t: float) -> None:
        h, w = self.height, self.width
        cam = camera.params(w, h)
        light = self._light(camera)
        color = np.empty((h, w, 3), np.float32)
        depth = np.empty((h, w), np.float32)
        collider_lin = _srgb_to_linear(self.theme["collider"])
        if self.dim == 3:
            extra_rows = self._ground_rows(prims)
            params = np.concatenate([prims.params, extra_rows]) if len(extra_rows) else prims.params.copy()
            kinds = np.concatenate([prims.kinds, np.full(len(extra_rows), K.PRIM_PLANE)]).astype(np.int64)
            colors = np.tile(collider_lin, (len(kinds), 1)).astype(np.float32)
            up = UP_AXES[self.up][0]
            spacing = nice_step(self._scene_size() / 12.0)
            ground_lin = _srgb_to_linear(self.theme["ground"])
            levels = []
            for k in range(len(kinds)):
                if kinds[k] == K.PRIM_PLANE:
                    params[k, 6] = spacing
                    # Planes facing up are the ground: ground colour, and they receive shadows.
                    if params[k, 3:6] @ up > 0.95:
                        params[k, 7] = 1.0
                        colors[k] = ground_lin
                        levels.append(float(params[k, 0:3] @ up))
                elif kinds[k] == K.PRIM_CONTAINER:
                    # Walls with a grid; an up-facing floor receives the shadows.
                    params[k, 15] = spacing
                    colors[k] = ground_lin
                    world_from_local = params[k, 6:15].reshape(3, 3).T
                    axis_up = np.abs(world_from_local.T @ up)
                    if axis_up.max() > 0.95:
                        levels.append(float(params[k, 0:3] @ up - axis_up @ params[k, 3:6]))
            ground = np.empty((h, w, 3), np.float32)
            fog = 2.0 * self._scene_size()
            sky_horizon = _srgb_to_linear(self.theme["sky_horizon"]).astype(np.float64)
            grid_line = _srgb_to_linear(self.theme["ground_line"]).astype(np.float64)
            # Sky and planes, then each other kind of primitive by its own kernel (a scene
            # compiles only the intersectors it draws).
            planes = kinds == K.PRIM_PLANE
            self._kernel("background_3d", w * h, _PARALLEL_PIXELS)(
                cam, w, h, np.ascontiguousarray(params[planes]), kinds[planes], np.ascontiguousarray(colors[planes]), light,
                _srgb_to_linear(self.theme["sky_top"]).astype(np.float64), sky_horizon, fog, grid_line, color, depth, ground,
            )
            for kind, name in K.TRACE_KERNELS.items():
                rows = kinds == kind
                if rows.any():
                    self._kernel(name, w * h, _PARALLEL_PIXELS)(
                        cam, w, h, np.ascontiguousarray(params[rows]), np.ascontiguousarray(colors[rows]), light,
                        sky_horizon, fog, grid_line, color, depth, ground,
                    )
            for collider in prims.generic:
                self._trace_generic(collider, t, camera, cam, light, collider_lin, color, depth)
            level = max(levels) if levels else None
            frame = self._shadow_frame()
            texels = np.empty((h, w, 2), np.float32)
            self._kernel("ground_texels", w * h, _PARALLEL_PIXELS)(ground, frame["axis_a"], frame["axis_b"], frame["a0"], frame["b0"], frame["texel"], texels)
            self._background = (color, depth, texels, level, self._to_bytes(color))
        else:
            spacing = nice_step(camera.ortho_height / 8.0)
            extra_sd = np.zeros((0, 0), np.float32)
            if prims.generic:
                # Sample the SDF of the remaining colliders on the pixel grid (min over them).
                f = camera.focal_px(h)
                xs = camera.position[0] + (np.arange(w) + 0.5 - w / 2.0) / f
                ys = camera.position[1] + (h / 2.0 - (np.arange(h) + 0.5)) / f
                grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
                sd = np.full(grid.shape[0], np.inf)
                for collider in prims.generic:
                    sd = np.minimum(sd, np.asarray(collider.signed_distance(grid, t), dtype=np.float64))
                extra_sd = sd.reshape(h, w).astype(np.float32)
            colors = np.tile(collider_lin, (len(prims.kinds), 1)).astype(np.float32)
            params2 = np.ascontiguousarray(prims.params.copy())
            params2[prims.kinds == K.PRIM_CONTAINER, 15] = 0.02 * camera.ortho_height
            self._kernel("background_2d", w * h, _PARALLEL_PIXELS)(
                cam, w, h, params2, prims.kinds, colors,
                _srgb_to_linear(self.theme["paper"]).astype(np.float64),
                _srgb_to_linear(self.theme["grid"]).astype(np.float64), spacing, extra_sd,
                collider_lin.astype(np.float64), color, depth,
            )
            self._background = (color, depth, np.zeros((1, 1, 2), np.float32), None, self._to_bytes(color))

    @staticmethod
    def _to_bytes(color: np.ndarray) -> np.ndarray:
        out = np.empty(color.shape, np.uint8)
        Renderer._kernel("to_srgb8", color.shape[0] * color.shape[1], _PARALLEL_PIXELS)(color, _LUT, out)
        return out

    def _trace_generic(self, collider, t, camera, cam, light, color_lin, color, depth) -> None:
        h, w = self.height, self.width
        right, cup, forward = camera.basis()
        f = camera.focal_px(h)
        sx = (np.arange(w) + 0.5 - w / 2.0) / f
        sy = (h / 2.0 - (np.arange(h) + 0.5)) / f
        gx, gy = np.meshgrid(sx, sy)
        if camera.projection == "orthographic":
            origins = camera.position + gx[..., None] * right + gy[..., None] * cup
            directions = np.broadcast_to(forward, origins.shape)
        else:
            origins = np.broadcast_to(camera.position, (h, w, 3))
            directions = forward + gx[..., None] * right + gy[..., None] * cup
            directions = directions / np.linalg.norm(directions, axis=-1, keepdims=True)
        size = self._scene_size()
        distance, normals = trace_signed_distance(
            collider, t, origins.reshape(-1, 3).copy(), directions.reshape(-1, 3).copy(),
            max_distance=float(np.linalg.norm(camera.position - camera.target)) + 4 * size,
            tolerance=1e-4 * size,
        )
        along = distance * (directions.reshape(-1, 3) @ forward)
        self._kernel("composite_surface", w * h, _PARALLEL_PIXELS)(
            along.reshape(h, w).astype(np.float32), normals.reshape(h, w, 3), color_lin.astype(np.float64),
            cam, light, color, depth,
        )

    # -- one frame ----------------------------------------------------------------------------
    def frame(
        self,
        positions,
        *,
        radius=None,
        velocities=None,
        colors=None,
        groups=None,
        active=None,
        colliders: Sequence = (),
        t: float = 0.0,
        out: np.ndarray | None = None,
        meshes: Sequence = (),
        lines: Sequence = (),
        underlay=None,
    ) -> np.ndarray:
        """Render one frame; returns (height, width, 3) uint8 sRGB (``out`` if given).

        positions (N, D) world positions; radius (N,) or scalar world radii; velocities (N, D)
        for speed colours; colors (N, 3) or one colour; groups (N,) int; active (N,) bool (False
        slots are not drawn); colliders as in `inertia.colliders`, drawn at time ``t``;
        meshes: `inertia.render.meshes.TriangleMesh` s in world space (shaded, casting shadows,
        3-D only); lines: `inertia.render.meshes.LineSet` s (springs); underlay: a callable
        ``paint(image)`` that paints the (H, W, 3) uint8 sRGB background in place and returns the
        (H, W) bool mask of the pixels it changed (or None): drawn under the particles (2-D grid
        fluids' colour maps and streaks).
        """
        with self._lock:
            return self._frame(positions, radius, velocities, colors, groups, active, colliders, t, out,
                               meshes, lines, underlay)

    def _frame(self, positions, radius, velocities, colors, groups, active, colliders, t, out, meshes=(), lines=(),
               underlay=None):
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != self.dim:
            raise ValueError(f"Renderer.frame: positions must be (N, {self.dim}), got shape {pos.shape}")
        n = pos.shape[0]
        if self.camera is None or self.bounds is None:
            if self.camera is None:
                self.fit(pos, radius=radius, colliders=colliders, t=t, active=active)
            else:
                self.bounds = scene_bounds(pos, active=active)
        camera = self.camera_at(t)
        h, w = self.height, self.width

        # Background: rebuilt only when the camera or the colliders changed.
        prims = collider_primitives(colliders, t, self.dim)
        key = (camera.params(w, h).tobytes(), prims.key(), tuple(id(c) for c in prims.generic),
               tuple(float(t) if getattr(c, "motion", None) is not None else 0.0 for c in prims.generic))
        if key != self._background_key:
            self._build_background(camera, prims, t)
            self._background_key = key
        bg_color, bg_depth, ground, ground_level, bg_bytes = self._background

        # Per-particle inputs, 3-D, contiguous.
        if self.dim == 2:
            pos3 = np.zeros((n, 3))
            pos3[:, :2] = pos
        else:
            pos3 = np.ascontiguousarray(pos)
        default_r = self.default_radius if self.default_radius is not None else 0.004 * self._scene_size()
        if radius is None:
            rad = np.full(n, default_r)
        else:
            rad = np.array(np.broadcast_to(np.asarray(radius, dtype=np.float64), (n,)))
            rad[~(rad > 0)] = default_r
        act = np.ones(n, dtype=bool) if active is None else np.ascontiguousarray(np.asarray(active, dtype=bool))
        if act.shape != (n,):
            raise ValueError(f"Renderer.frame: active must be ({n},), got {act.shape}")
        lin = self._linear_colors(n, colors=colors, velocities=velocities, groups=groups)

        cam = camera.params(w, h)
        light = self._light(camera)
        sx, sy, depth = np.empty(n), np.empty(n), np.empty(n)
        rpx, rworld = np.empty(n), np.empty(n)
        visible = np.empty(n, dtype=bool)
        self._kernel("project_spheres", n)(pos3, rad, act, cam, w, h, self.min_radius_px, sx, sy, depth, rpx, rworld, visible)

        # Contact shadows on the ground, from every active particle (on screen or not).
        shadow_box = np.zeros(4, np.int64)
        if self.dim == 3 and self.shadows and ground_level is not None and n > 0:
            shadow_box = self._shadow_map(pos3, rad, act, ground_level, camera)

        # Back to front (a stable counting sort on depth), packed in drawing order.
        order = np.empty(n, np.int64)
        m = K.back_to_front(visible, depth, 65536, order)
        packed = np.empty((m, 5))
        packed_colors = np.empty((m, 3), np.float32)
        row_range = np.empty((m, 2), np.int32)
        self._kernel("gather_sorted", n)(order, m, sx, sy, depth, rpx, rworld, lin, packed, packed_colors, row_range)
        table = self._shading_table(light)
        n_bands = -(-h // self.band)
        band_start = np.empty(n_bands + 1, np.int64)
        items = K.bin_bands(row_range, m, self.band, n_bands, band_start)

        # Start from the cached background (float, depth and bytes), then draw over it.
        if out is None:
            out = np.empty((h, w, 3), np.uint8)
        elif out.shape != (h, w, 3) or out.dtype != np.uint8 or not out.flags.c_contiguous:
            raise ValueError(f"Renderer.frame: out must be a C-contiguous ({h}, {w}, 3) uint8 array")
        np.copyto(self._color, bg_color)
        np.copyto(self._depth, bg_depth)
        if (meshes or lines) and self.dim == 3:
            ground = self._draw_meshes(camera, meshes, lines, ground, out)
        else:
            np.copyto(out, bg_bytes)
        if underlay is not None:
            changed = underlay(out)
            if changed is not None and changed.any():  # the particles blend over the painted pixels
                self._color[changed] = _LIN_LUT[(out[changed].astype(np.int64) * 4095 + 127) // 255]
        parallel = w * h >= _PARALLEL_PIXELS or m >= _PARALLEL_PARTICLES
        (K.render_bands.parallel if parallel else K.render_bands.serial)(ground, self._shadow, shadow_box, packed, packed_colors, row_range, band_start, items, table,
             self.band, self._stride, _LUT, self._color, self._depth, out)
        return out

    def _draw_meshes(self, camera: Camera, meshes, lines, ground_tex, out) -> np.ndarray:
        """Shadows, shaded triangles and lines over the background in ``self._color/_depth``;
        ``out`` gets the sRGB bytes of the whole frame. Returns the ground texel coordinates
        with the pixels the meshes cover removed (so contact shadows stay on the ground)."""
        from . import meshes as M

        h, w = self.height, self.width
        cam = camera.params(w, h)
        near = 1e-4 * self._scene_size()
        mask = np.zeros((h, w), np.uint8)
        if meshes:
            verts, norms, tris, cols, base = [], [], [], [], 0
            for mesh in meshes:
                v = np.ascontiguousarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
                tri = np.ascontiguousarray(mesh.triangles, dtype=np.int64).reshape(-1, 3)
                if mesh.normals is None:
                    n = np.empty_like(v)
                    M.vertex_normals(v, tri, n)
                else:
                    n = np.asarray(mesh.normals, dtype=np.float64).reshape(-1, 3)
                color = np.asarray(mesh.color, dtype=np.float32)
                cols.append(np.broadcast_to(color.reshape(-1, 3), (tri.shape[0], 3)))
                verts.append(v)
                norms.append(n)
                tris.append(tri + base)
                base += v.shape[0]
            verts = np.ascontiguousarray(np.concatenate(verts))
            norms = np.ascontiguousarray(np.concatenate(norms))
            tris = np.ascontiguousarray(np.concatenate(tris))
            albedo = np.ascontiguousarray(_srgb_to_linear(np.clip(np.concatenate(cols), 0.0, 1.0)))
            light_dir = self._light_direction(camera)
            cam_light = self._light(camera)
            light = np.zeros(M.LIGHT_SIZE)
            light[0:3], light[3:6] = light_dir, UP_AXES[self.up][0]
            light[6:9], light[9:12], light[12] = cam_light[3:6], cam_light[6:9], cam_light[12]
            light[13] = self.shadow_strength
            if self.shadows and tris.shape[0]:
                frame = M.light_frame(light_dir, verts[np.unique(tris)])
                if self._mesh_shadow.shape != (M.SHADOW_MAP_SIZE, M.SHADOW_MAP_SIZE):
                    self._mesh_shadow = np.empty((M.SHADOW_MAP_SIZE, M.SHADOW_MAP_SIZE), np.float32)
                depth_map = self._mesh_shadow
                M.shadow_map_depth(verts, tris, frame, depth_map)
                M.shadow_background(cam, frame, depth_map, self.shadow_strength, self._depth, mask, self._color)
            else:
                frame, depth_map = np.zeros(M.SHADOW_FRAME_SIZE), np.full((1, 1), -np.inf, np.float32)
                frame[12] = 1.0
            M.draw_triangles(verts, norms, tris, albedo, cam, light, frame, depth_map, near,
                             self._color, self._depth, mask)
        for line_set in lines:
            pairs = np.ascontiguousarray(line_set.pairs, dtype=np.int64).reshape(-1, 2)
            srgb = np.broadcast_to(np.asarray(line_set.color, np.float64).reshape(-1, 3), (pairs.shape[0], 3))
            color = np.ascontiguousarray(_srgb_to_linear(np.clip(srgb, 0.0, 1.0)), dtype=np.float64)
            opacity = np.ones(pairs.shape[0]) if line_set.opacity is None else np.ascontiguousarray(
                np.broadcast_to(np.asarray(line_set.opacity, np.float64), (pairs.shape[0],)))
            M.draw_lines(np.ascontiguousarray(line_set.points, dtype=np.float64).reshape(-1, 3), pairs, color, opacity,
                         float(line_set.width_px), cam, near, self._color, self._depth)
        self._to_bytes_into(self._color, out)
        if mask.any():
            ground_tex = ground_tex.copy()
            ground_tex[mask.astype(bool)] = np.nan
        return ground_tex

    @staticmethod
    def _to_bytes_into(color: np.ndarray, out: np.ndarray) -> None:
        Renderer._kernel("to_srgb8", color.shape[0] * color.shape[1], _PARALLEL_PIXELS)(color, _LUT, out)

    def _shading_table(self, light: np.ndarray) -> np.ndarray:
        key = light.tobytes()
        if getattr(self, "_table_key", None) != key:
            self._table = np.empty((K.SHADE_LUT_SIZE, K.SHADE_LUT_SIZE, 8), np.float32)
            K.shading_table(light, K.SHADE_LUT_SIZE, self._table)
            self._table_key = key
        return self._table

    def _shadow_frame(self) -> dict:
        """Where the shadow map lies on the ground: axes, origin and texel size (from the bounds)."""
        up, axis_a, axis_b = UP_AXES[self.up]
        lo3, hi3 = np.zeros(3), np.zeros(3)
        if self.bounds is not None:
            lo3[: len(self.bounds[0])], hi3[: len(self.bounds[1])] = self.bounds
        margin = 0.15 * self._scene_size()
        a0, a1 = lo3 @ axis_a - margin, hi3 @ axis_a + margin
        b0, b1 = lo3 @ axis_b - margin, hi3 @ axis_b + margin
        texel = max(a1 - a0, b1 - b0) / 256.0
        shape = (max(int(math.ceil((a1 - a0) / texel)), 1), max(int(math.ceil((b1 - b0) / texel)), 1))
        return {"up": up, "axis_a": axis_a, "axis_b": axis_b, "a0": a0, "b0": b0, "texel": texel, "shape": shape}

    def _shadow_map(self, pos3, rad, act, ground_level, camera) -> np.ndarray:
        """Fill the shadow map; return the pixel box (x0, x1, y0, y1) of the shadowed ground."""
        frame = self._shadow_frame()
        if self._shadow.shape != frame["shape"]:
            self._shadow = np.zeros(frame["shape"], np.float32)
            self._shadow_scratch = np.zeros(frame["shape"], np.float32)
        size = self._scene_size()
        K.shadow_deposit(pos3, rad, act, frame["up"], frame["axis_a"], frame["axis_b"], ground_level,
                         frame["a0"], frame["b0"], frame["texel"], 0.6, 0.2 * size, self._shadow)
        K.blur_shadow.serial(self._shadow, self._shadow_scratch, _BLUR_TAPS)
        # Screen box of the texels that hold any shadow: only those pixels are visited.
        rows = np.flatnonzero(self._shadow.max(axis=1) > 1e-4)
        cols = np.flatnonzero(self._shadow.max(axis=0) > 1e-4)
        if rows.size == 0:
            return np.zeros(4, np.int64)
        a = frame["a0"] + frame["texel"] * np.array([rows[0] - 1, rows[-1] + 2], np.float64)
        b = frame["b0"] + frame["texel"] * np.array([cols[0] - 1, cols[-1] + 2], np.float64)
        corners = np.array([frame["up"] * ground_level + ai * frame["axis_a"] + bi * frame["axis_b"] for ai in a for bi in b])
        px, py, depth = camera.project(corners, self.width, self.height)
        if not np.all(depth > 0):
            return np.array([0, self.width, 0, self.height], np.int64)
        return np.array([
            max(int(np.floor(px.min())) - 1, 0), min(int(np.ceil(px.max())) + 1, self.width),
            max(int(np.floor(py.min())) - 1, 0), min(int(np.ceil(py.max())) + 1, self.height),
        ], np.int64)
