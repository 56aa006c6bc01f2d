"""Cameras: a perspective orbit camera for 3-D scenes, an orthographic camera for 2-D ones.

Conventions
-----------
World space is right-handed with the *up axis* ``"z"`` by default, as Inertia's gravity
``(0, 0, -9.81)`` implies; ``up="y"`` is accepted for y-up scenes. 2-D scenes live in the x-y
plane with y up and are seen from +z by an orthographic camera.

Camera space: ``right`` (screen x), ``up`` (screen y, upwards), ``forward`` (into the screen).
A point p projects to pixel coordinates (pixel centres at +0.5)::

    perspective:   px = cx + f * (p - eye).right / depth,  py = cy - f * (p - eye).up / depth
    orthographic:  px = cx + s * (p - eye).right,          py = cy - s * (p - eye).up
    depth = (p - eye).forward,   f = (height / 2) / tan(fov_y / 2),   s = height / ortho_height

Orbit parameters: ``azimuth`` (degrees, around the up axis, 0 = looking from +x, -90 = from
-y for z-up / from +z for y-up), ``elevation`` (degrees above the horizontal plane),
``distance`` from ``target``.

Limitations: no roll; no lens distortion; the near plane is a fixed fraction of the distance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = ["Camera", "UP_AXES"]

#: Up axis name -> (up, first horizontal axis, second horizontal axis) for orbiting.
UP_AXES = {
    "z": (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
    "y": (np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])),
}


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise ValueError("camera: zero-length direction (eye equals target?)")
    return v / n


@dataclass(frozen=True)
class Camera:
    """A pinhole (``projection="perspective"``) or orthographic camera.

    position, target : (3,) world points (eye and look-at point).
    up : (3,) world up vector (need not be orthogonal to the view direction).
    fov_y : vertical field of view in degrees (perspective), 40 default; 25-60 is sensible.
    projection : "perspective" or "orthographic".
    ortho_height : world units visible vertically (orthographic).
    """

    position: np.ndarray
    target: np.ndarray
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    fov_y: float = 40.0
    projection: str = "perspective"
    ortho_height: float = 1.0

    def __post_init__(self):
        for name in ("position", "target", "up"):
            value = np.asarray(getattr(self, name), dtype=np.float64).reshape(-1)
            if value.shape == (2,):
                value = np.append(value, 0.0)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(f"Camera: {name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, value)
        if self.projection not in ("perspective", "orthographic"):
            raise ValueError(f"Camera: projection must be 'perspective' or 'orthographic', got {self.projection!r}")
        if not 1.0 <= self.fov_y <= 170.0:
            raise ValueError(f"Camera: fov_y must be in [1, 170] degrees, got {self.fov_y!r}")
        if not self.ortho_height > 0:
            raise ValueError(f"Camera: ortho_height must be > 0, got {self.ortho_height!r}")

    # -- constructors -------------------------------------------------------------------------
    @classmethod
    def orbit(
        cls,
        target,
        distance: float,
        *,
        azimuth: float = -60.0,
        elevation: float = 25.0,
        up: str = "z",
        fov_y: float = 40.0,
    ) -> "Camera":
        """A perspective camera on a sphere of radius ``distance`` around ``target``."""
        if up not in UP_AXES:
            raise ValueError(f"Camera.orbit: up must be one of {sorted(UP_AXES)}, got {up!r}")
        if not -89.9 <= elevation <= 89.9:
            raise ValueError(f"Camera.orbit: elevation must be in [-89.9, 89.9] degrees, got {elevation!r}")
        if not distance > 0:
            raise ValueError(f"Camera.orbit: distance must be > 0, got {distance!r}")
        u, a, b = UP_AXES[up]
        az, el = math.radians(azimuth), math.radians(elevation)
        offset = math.cos(el) * (math.cos(az) * a + math.sin(az) * b) + math.sin(el) * u
        target = np.asarray(target, dtype=np.float64)
        return cls(position=target + distance * offset, target=target, up=u.copy(), fov_y=fov_y)

    @classmethod
    def fit(
        cls,
        lower,
        upper,
        *,
        aspect: float,
        dim: int = 3,
        up: str = "z",
        azimuth: float = -60.0,
        elevation: float = 25.0,
        fov_y: float = 40.0,
        margin: float = 1.08,
    ) -> "Camera":
        """Frame the axis-aligned box [lower, upper]: the whole box is in view with ``margin``.

        3-D: an orbit camera whose distance makes the box's bounding sphere fit the narrower
        field of view. 2-D: an orthographic camera looking down -z at the box.
        """
        lower = np.asarray(lower, dtype=np.float64)
        upper = np.asarray(upper, dtype=np.float64)
        if dim == 2:
            lower, upper = lower[:2], upper[:2]
            center = 0.5 * (lower + upper)
            extent = np.maximum(upper - lower, 1e-9)
            height = max(extent[1], extent[0] / aspect) * margin
            if not height > 0 or not np.isfinite(height):
                height = 1.0
            return cls.plane_2d(center, height)
        center = 0.5 * (lower + upper)
        half = 0.5 * (upper - lower)
        if not np.all(np.isfinite(half)) or not np.any(half > 0):
            half = np.full(3, 0.5)
        # The nearest orbit distance at which all 8 corners of the box are inside the view:
        # a corner c (relative to the centre) at screen offsets x = c.right, y = c.up and depth
        # d + c.forward needs d >= max(|x| / tan_h, |y| / tan_v) - c.forward.
        probe = cls.orbit(center, 1.0, azimuth=azimuth, elevation=elevation, up=up, fov_y=fov_y)
        right, cam_up, forward = probe.basis()
        tan_v = math.tan(math.radians(fov_y) / 2.0) / margin
        tan_h = tan_v * aspect
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        corners = signs * half
        distance = float(np.max(np.maximum(np.abs(corners @ right) / tan_h, np.abs(corners @ cam_up) / tan_v) - corners @ forward))
        # Keep the eye outside the box's bounding sphere.
        distance = max(distance, 1.05 * float(np.linalg.norm(half)))
        return cls.orbit(center, distance, azimuth=azimuth, elevation=elevation, up=up, fov_y=fov_y)

    @classmethod
    def fit_points(
        cls,
        points,
        *,
        aspect: float,
        up: str = "z",
        azimuth: float = -60.0,
        elevation: float = 25.0,
        fov_y: float = 40.0,
        margin: float = 1.1,
        iterations: int = 4,
        pad: float = 0.0,
        reserve_top: float = 0.0,
    ) -> "Camera":
        """Frame a 3-D point cloud (M, 3) tightly: every point in view with ``margin``, and the
        cloud's picture centred in the frame.

        Where `fit` frames the bounding box (whose empty corners, above a fountain's spray, waste
        a quarter of the picture), this frames the points themselves. For the orbit direction
        (azimuth, elevation) with basis right r, up u, forward f and a target c, a point p at
        x = (p - c).r, y = (p - c).u, z = (p - c).f is in view at distance d when
        d >= (|x| + pad) / tan_h - z and d >= (|y| + pad) / tan_v - z (``pad``: the particles'
        radius, so spheres at the edge stay whole). Starting from the points' mean, each
        iteration takes the least such d, then moves c sideways by the centre of the points'
        screen box (times d) so the picture is centred; the last d is recomputed for the moved c.
        ``reserve_top``: the share of the frame height kept free at the top (for a legend drawn
        there), 0 default, in [0, 0.5): the window the points are fitted into runs from
        y = -tan_v to y = (1 - 2 reserve_top) tan_v, and the points are centred in it.
        """
        if not 0.0 <= reserve_top < 0.5:
            raise ValueError(f"Camera.fit_points: reserve_top must be in [0, 0.5), got {reserve_top!r}")
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if pts.shape[0] == 0:
            return cls.fit(np.full(3, -0.5), np.full(3, 0.5), aspect=aspect, up=up, azimuth=azimuth,
                           elevation=elevation, fov_y=fov_y)
        probe = cls.orbit(np.zeros(3), 1.0, azimuth=azimuth, elevation=elevation, up=up, fov_y=fov_y)
        right, cam_up, forward = probe.basis()
        tan_v = math.tan(math.radians(fov_y) / 2.0) / margin
        tan_h = tan_v * aspect
        tan_top = tan_v * (1.0 - 2.0 * reserve_top)  # the window's top edge (tan_v below it: bottom)
        window_y = -reserve_top * tan_v  # the window's centre, below the screen centre
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        size = max(float(np.linalg.norm(hi - lo)), 1e-6)
        target = 0.5 * (lo + hi)
        distance = size
        for k in range(iterations + 1):
            rel = pts - target
            x, y, z = rel @ right, rel @ cam_up, rel @ forward
            distance = float(np.max(np.maximum(np.maximum((np.abs(x) + pad) / tan_h, (pad - y) / tan_v),
                                               (y + pad) / tan_top) - z))
            distance = max(distance, 0.05 * size)
            if k == iterations:
                break
            depth = np.maximum(distance + z, 1e-9 * size)
            sx_lo, sx_hi = (x - pad) / depth, (x + pad) / depth
            sy_lo, sy_hi = (y - pad) / depth, (y + pad) / depth
            target = target + distance * (0.5 * (sx_lo.min() + sx_hi.max()) * right
                                          + (0.5 * (sy_lo.min() + sy_hi.max()) - window_y) * cam_up)
        return cls.orbit(target, distance, azimuth=azimuth, elevation=elevation, up=up, fov_y=fov_y)

    @classmethod
    def plane_2d(cls, center, height: float) -> "Camera":
        """An orthographic camera looking down -z at the x-y plane, ``height`` world units tall."""
        center = np.asarray(center, dtype=np.float64).reshape(-1)[:2]
        position = np.array([center[0], center[1], 1.0])
        target = np.array([center[0], center[1], 0.0])
        return cls(position=position, target=target, up=np.array([0.0, 1.0, 0.0]), projection="orthographic", ortho_height=float(height))

    def with_orbit(self, *, azimuth: float | None = None, elevation: float | None = None, distance: float | None = None, up: str = "z") -> "Camera":
        """The same camera moved on its orbit around ``target`` (None keeps the current value)."""
        u, a, b = UP_AXES[up]
        offset = self.position - self.target
        r = float(np.linalg.norm(offset))
        el = math.degrees(math.asin(np.clip(offset @ u / r, -1.0, 1.0)))
        az = math.degrees(math.atan2(offset @ b, offset @ a))
        return replace(
            Camera.orbit(
                self.target,
                r if distance is None else distance,
                azimuth=az if azimuth is None else azimuth,
                elevation=el if elevation is None else elevation,
                up=up,
                fov_y=self.fov_y,
            ),
            projection=self.projection,
            ortho_height=self.ortho_height,
        )

    # -- projection ---------------------------------------------------------------------------
    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward) unit vectors of camera space, in world coordinates."""
        forward = _unit(self.target - self.position)
        right = np.cross(forward, self.up)
        if np.linalg.norm(right) < 1e-9:  # looking along the up vector: pick any right
            right = np.cross(forward, np.array([1.0, 0.0, 0.0]) if abs(forward[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
        right = _unit(right)
        up = np.cross(right, forward)
        return right, up, forward

    def focal_px(self, height: int) -> float:
        """Focal length in pixels (perspective) or pixels per world unit (orthographic)."""
        if self.projection == "orthographic":
            return height / self.ortho_height
        return (height / 2.0) / math.tan(math.radians(self.fov_y) / 2.0)

    def params(self, width: int, height: int) -> np.ndarray:
        """The camera as the float64 vector the render kernels read (see `kernels.CAM_*`)."""
        right, up, forward = self.basis()
        ortho = 1.0 if self.projection == "orthographic" else 0.0
        return np.concatenate(
            [self.position, right, up, forward, [self.focal_px(height), width / 2.0, height / 2.0, ortho]]
        ).astype(np.float64)

    def screen_fill(self, points, width: int, height: int, pad: float = 0.0) -> float:
        """The share of the ``width`` x ``height`` picture covered by the screen bounding box of
        world ``points`` (M, 2 or 3), each grown by ``pad`` world units, clipped to the frame; in
        [0, 1], 0 when no point is in front of the camera. A measure of how well a framing fills
        the picture with its subject (1: the subject's box is the whole frame)."""
        px, py, depth = self.project(np.asarray(points, dtype=np.float64).reshape(-1, np.shape(points)[-1]),
                                     width, height)
        keep = np.isfinite(px) & np.isfinite(py) & ((depth > 0) | (self.projection == "orthographic"))
        if not np.any(keep):
            return 0.0
        grow = self.focal_px(height) * pad / (1.0 if self.projection == "orthographic" else depth[keep])
        x0 = float(np.clip(np.min(px[keep] - grow), 0.0, width))
        x1 = float(np.clip(np.max(px[keep] + grow), 0.0, width))
        y0 = float(np.clip(np.min(py[keep] - grow), 0.0, height))
        y1 = float(np.clip(np.max(py[keep] + grow), 0.0, height))
        return (x1 - x0) * (y1 - y0) / float(width * height)

    def project(self, points, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel coordinates (px, py) and depth of world points (M, 2 or 3)."""
        points = np.asarray(points, dtype=np.float64)
        if points.shape[-1] == 2:
            points = np.concatenate([points, np.zeros(points.shape[:-1] + (1,))], axis=-1)
        right, up, forward = self.basis()
        rel = points - self.position
        x, y, depth = rel @ right, rel @ up, rel @ forward
        f = self.focal_px(height)
        if self.projection == "orthographic":
            return width / 2.0 + f * x, height / 2.0 - f * y, depth
        with np.errstate(divide="ignore", invalid="ignore"):
            return width / 2.0 + f * x / depth, height / 2.0 - f * y / depth, depth
