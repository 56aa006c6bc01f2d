"""Offline, headless rendering: shaded particle spheres, colliders, a ground grid; video and plots.

Public API::

    Renderer(width=1280, height=720, *, dim=3, camera=None, up="z", color_by="auto", ...)
        .frame(positions, *, radius=None, velocities=None, colors=None, groups=None,
               active=None, colliders=(), t=0.0) -> (H, W, 3) uint8
        .fit(positions, *, radius=None, colliders=(), t=0.0, active=None) -> Camera
    Camera.orbit(target, distance, *, azimuth, elevation, up, fov_y), Camera.fit(...), Camera.plane_2d(...)
    render_states(states_or_path, out, *, fps=None, width=1280, height=720, colliders=(), frames=None, ...)
    VideoWriter(path, fps=30), write_video(frames, path, fps=30)
    write_png(path, image), read_png(path), encode_png(image)
    plot_energy(times, kinetic, potential=None, momentum=None, path="energy.png")
    plot_states_energy(states, path, *, masses=None, gravity=None), energy_from_states(states, ...)
    colormap(name, values, vmin=None, vmax=None), COLORMAPS, GROUP_PALETTE

Why a Numba rasterizer and not a rendering library: docs/rendering.md.
"""

from .camera import Camera
from .colormaps import COLORMAPS, GROUP_PALETTE, colormap, group_colors, parse_color, speed_colors
from .plots import energy_from_states, plot_energy, plot_states_energy
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
