"""Offline, headless rendering: shaded particle spheres, colliders, a ground grid; video and plots.

Public API::

    Renderer(width=1280, height=720, *, dim=3, camera=None, up="z", color_by="auto", ...)
        .frame(positions, *, radius=None, velocities=None, colors=None, groups=None,
               active=None, colliders=(), t=0.0, meshes=(), lines=()) -> (H, W, 3) uint8
        .fit(positions, *, radius=None, colliders=(), t=0.0, active=None, extra_points=None, times=None) -> Camera
        orbit=DEG, follow=False: a camera that turns / follows the particles over the run
    meshes.TriangleMesh(vertices, normals, triangles, color), meshes.LineSet(points, pairs, color, width_px, opacity)
    drawables.ModelDrawables(states.model): bodies (body_q), cloth surfaces, springs of a run
    warm_kernels() -> seconds: compile the kernels `inertia run` uses (for `inertia warmup`)
    Camera.orbit(target, distance, *, azimuth, elevation, up, fov_y), Camera.fit(...), Camera.plane_2d(...)
    render_states(states_or_path, out, *, fps=None, width=1280, height=720, colliders=(), frames=None, trails=0, ...)
    VideoWriter(path, fps=30), write_video(frames, path, fps=30)
    write_png(path, image), read_png(path), encode_png(image)
    plot_energy(times, kinetic, potential=None, momentum=None, path="energy.png")
    plot_states_energy(states, path, *, masses=None, gravity=None), energy_from_states(states, ...)
    system_series(states) -> [SystemSeries] (particles, bodies, fluids), plot_systems(times, systems, path)
    colormap(name, values, vmin=None, vmax=None), COLORMAPS, GROUP_PALETTE

Why a Numba rasterizer and not a rendering library: docs/rendering.md.
"""

from .camera import Camera
from .colormaps import COLORMAPS, GROUP_PALETTE, colormap, group_colors, parse_color, speed_colors
from .plots import SystemSeries, energy_from_states, plot_energy, plot_states_energy, plot_systems, system_series
from .png import encode_png, read_png, write_png
from .renderer import THEMES, Renderer, scene_bounds
from .video import VIDEO_SUFFIXES, VideoWriter, render_states, write_video

__all__ = [
    "Renderer",
    "Camera",
    "render_states",
    "VideoWriter",
    "write_video",
    "VIDEO_SUFFIXES",
    "write_png",
    "read_png",
    "encode_png",
    "plot_energy",
    "plot_states_energy",
    "plot_systems",
    "system_series",
    "SystemSeries",
    "energy_from_states",
    "colormap",
    "speed_colors",
    "group_colors",
    "parse_color",
    "COLORMAPS",
    "GROUP_PALETTE",
    "THEMES",
    "scene_bounds",
]


def warm_kernels(*, dims=(2, 3), primitives: bool = True, meshes: bool = True) -> float:
    """Compile (or load from Numba's cache) the render kernels `inertia run` uses; returns seconds.

    Renders one tiny frame per case: 3-D particles over a ground plane coloured by speed and by
    group, with contact shadows; every analytic collider kind (``primitives``); shaded meshes with
    shadows and lines (``meshes``); 2-D (in ``dims``). Small frames pick the serial kernel builds,
    which is what the default 960 x 540 output uses (frames from 1280 x 720 up use the parallel
    builds, not warmed here). For `inertia warmup`.
    """
    import time

    import numpy as np

    from .. import colliders as C
    from .meshes import LineSet, TriangleMesh, tessellate_shape

    start = time.perf_counter()
    rng = np.random.default_rng(0)
    if 3 in dims:
        pos = rng.uniform(-0.5, 0.5, (64, 3)) + [0.0, 0.0, 0.6]
        vel = rng.normal(size=(64, 3))
        colliders = [C.Plane(point=(0, 0, 0), normal=(0, 0, 1))]
        if primitives:
            colliders += [C.Sphere(center=(0.8, 0, 0.3), radius=0.2), C.Box(center=(-0.8, 0, 0.3), half_extents=(0.2, 0.2, 0.2)),
                          C.Capsule(a=(0, 0.8, 0.2), b=(0, 0.8, 0.6), radius=0.1),
                          C.Cylinder(center=(0, -0.8, 0.3), radius=0.15, half_height=0.2),
                          C.Container(center=(0, 0, 0.5), half_extents=(1.5, 1.5, 1.5))]
        renderer = Renderer(64, 48, dim=3)
        renderer.frame(pos, radius=0.02, velocities=vel, colliders=colliders)
        renderer.frame(pos, radius=0.02, groups=np.arange(64) % 2, colliders=colliders[:1])
        if meshes:
            v, n, t = tessellate_shape({"shape_type": np.array([1]), "shape_params": np.array([[0.2, 0.2, 0.2, 0.0]])}, 0)
            renderer.frame(pos, radius=0.02, velocities=vel, colliders=colliders[:1],
                           meshes=[TriangleMesh(v + [0, 0, 0.3], n, t, (0.8, 0.3, 0.2)),
                                   TriangleMesh(pos[:3], None, np.array([[0, 1, 2]]), (0.5, 0.5, 0.5))],
                           lines=[LineSet(pos, np.array([[0, 1], [1, 2]]), (1.0, 1.0, 1.0), 1.5)])
    if 2 in dims:
        pos2 = rng.uniform(-0.5, 0.5, (64, 2))
        colliders2 = [C.Plane(point=(0, -0.6), normal=(0, 1))]
        if primitives:
            colliders2 += [C.Sphere(center=(0.3, 0.3), radius=0.1), C.Box(center=(-0.3, 0.3), half_extents=(0.1, 0.1)),
                           C.Container(center=(0, 0), half_extents=(1.0, 1.0))]
        renderer = Renderer(64, 48, dim=2)
        renderer.frame(pos2, radius=0.02, velocities=rng.normal(size=(64, 2)), colliders=colliders2)
    return time.perf_counter() - start


__all__.append("warm_kernels")
