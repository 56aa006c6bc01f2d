"""Writing the outputs of a run from its state file: video, PNG frames, energy plot, PLY, USD.

Every file goes through `inertia.io.atomic` (temporary file, then rename), so a run killed
while writing leaves no truncated file. Frames are rendered once and handed to every image
output (MP4, GIF, PNG): frames come from `inertia.render.Renderer` (camera from the scene's
[render] table, group colours from the scene), videos are encoded by
`inertia.render.VideoWriter` (ffmpeg from imageio-ffmpeg) and the plot drawn by
`inertia.render.plots.plot_systems` from what the run recorded per system (particles, bodies, fluids).

Limitations: GIFs are written at half resolution above 640 pixels wide (file size).
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path
from typing import Callable

import numpy as np

__all__ = ["write_outputs", "render_frames", "framed_renderer", "plot_energy", "OUTPUT_NAMES", "renderer_for"]

#: File names inside the output directory.
OUTPUT_NAMES = {
    "mp4": "movie.mp4", "gif": "movie.gif", "frames": "frames", "plot": "energy.png",
    "ply": "ply", "usd": "points.usdc", "manifest": "manifest.json",
    "usd_bodies": "bodies.usdc", "obj": "obj",
}


#: Pixels between a legend and the frame's top and side edges.
_LEGEND_MARGIN_PX = 12


def renderer_for(states, render: dict | None, colliders=(), reserve_top: float = 0.0):
    """A `Renderer` set up from a scene's [render] table and framed on the run's subject: the
    particles and the moving bodies (followed when they travel far, ``follow = "auto"``) and the
    static shapes; ``reserve_top``: share of the frame height kept free at the top (a legend)."""
    from inertia.render.camera import Camera
    from inertia.render.renderer import Renderer

    render = dict(render or {})
    camera = dict(render.get("camera") or {})
    width = int(render.get("width", 960)) // 2 * 2
    height = int(render.get("height", 540)) // 2 * 2
    dim = states.dim
    options = {}
    for key, name in (("azimuth", "azimuth"), ("elevation", "elevation"), ("fov", "fov_y")):
        if camera.get(key) is not None:
            options[name] = float(camera[key])
    # One speed scale for the whole run (as the viewer): a colour is the same speed in every frame.
    from inertia.render.colormaps import run_speed_max

    speed_max = run_speed_max(states.velocities) if states.velocities is not None else None
    renderer = Renderer(width, height, dim=dim, color_by=render.get("color_by", "auto"),
                        theme=render.get("theme", "dark"), speed_max=speed_max,
                        orbit=float(camera.get("orbit") or 0.0),
                        follow="auto" if camera.get("follow") is None else bool(camera["follow"]),
                        reserve_top=reserve_top if dim == 3 else 0.0, **options)
    active = states.fields.get("active")
    draw = colliders if render.get("draw_colliders", True) else ()
    from inertia.render.drawables import ModelDrawables

    drawables = ModelDrawables.from_states(states)  # bodies, cloth, springs (render helper)
    body_q = states.fields.get("body_q")
    positions = states.positions
    if drawables is None:
        moving, extra = None, None
    elif dim == 3 and body_q is not None and len(body_q) == states.frame_count:
        # the moving bodies' boxes per frame join the particles as the subject (a camera may
        # follow them); the static shapes are the scenery, framed with the whole run
        moving, extra = drawables.moving_bounds(body_q)
    else:
        moving, extra = None, drawables.bounds_points(body_q)
    if moving is not None:
        positions = np.concatenate([np.asarray(positions, np.float64).reshape(states.frame_count, -1, 3), moving], axis=1)
        if active is not None:
            active = np.asarray(active, dtype=bool)
            shape = (states.frame_count, moving.shape[1]) if active.ndim == 2 else (moving.shape[1],)
            active = np.concatenate([active, np.ones(shape, bool)], axis=-1)
    floor = None if drawables is None else drawables.heightfield_floor()
    if floor is not None and render.get("ground", "auto") == "auto":
        renderer.ground = floor  # the terrain rests on the ground grid instead of floating above it
    # bodies are never outliers: frame all of them (the particle-only robust trim cut a pile's top)
    robust = 0.0 if drawables is not None and drawables.local_vertices is not None and states.particle_count == 0 else 0.001
    renderer.fit(positions, radius=states.radius(), colliders=draw, active=active, extra_points=extra,
                 times=states.times, robust=robust)
    cam = renderer.camera
    if dim == 2 and camera.get("height") is not None:
        center = camera.get("target") or cam.target[:2]
        renderer.camera = Camera.plane_2d(np.asarray(center, dtype=np.float64)[:2], float(camera["height"]))
    elif camera.get("position") is not None or camera.get("target") is not None or camera.get("distance") is not None:
        position = np.asarray(camera["position"], dtype=np.float64) if camera.get("position") is not None else cam.position
        target = np.asarray(camera["target"], dtype=np.float64) if camera.get("target") is not None else cam.target
        if camera.get("distance") is not None and camera.get("position") is None:
            direction = cam.position - cam.target
            position = target + direction / np.linalg.norm(direction) * float(camera["distance"])
        renderer.camera = Camera(position=position, target=target, up=cam.up, fov_y=cam.fov_y,
                                 projection=cam.projection, ortho_height=cam.ortho_height)
    return renderer


def _group_colors(states, renderer):
    """(N, 3) colours when the scene names group colours and colours by group; else None."""
    names = states.metadata.get("group_colors") or []
    groups = states.groups()
    if groups is None or not any(names) or renderer.color_by not in ("group", "auto"):
        return None
    if renderer.color_by == "auto" and len(names) < 2:
        return None
    from inertia.render.colormaps import group_colors, parse_color

    palette = group_colors(np.arange(len(names))).astype(np.float32)
    if palette.dtype != np.float32 or palette.max() > 1.0:
        palette = palette / 255.0
    for i, name in enumerate(names):
        if name:
            palette[i] = parse_color(name)
    return palette[groups]


def framed_renderer(states, render: dict | None = None, colliders=()):
    """(`Renderer` framed on the run, legend image (h, w, 4) or None) for `render_frames`: where a
    legend is drawn in the top-left corner of a 3-D picture, the subject is framed below it."""
    from inertia.render.drawables import ModelDrawables
    from inertia.render.fluid_particles import fluid_legend, grid_scales

    renderer = renderer_for(states, render, colliders)
    scales = grid_scales(states)
    drawables = ModelDrawables.from_states(states)
    legend = _legend(states, renderer, render)
    legend = fluid_legend(states, renderer, render) if legend is None else legend
    hidden = None if drawables is None else drawables.hidden(states.particle_count)
    shown = states.particle_count - (0 if hidden is None else int(np.count_nonzero(hidden)))
    legend = _quantity_legend(states, renderer, render, scales, shown) if legend is None else legend
    if legend is not None and renderer.dim == 3 and _under_legend(states, renderer, drawables, legend.shape):
        reserve = min((_LEGEND_MARGIN_PX + legend.shape[0] + 4) / renderer.height, _MAX_RESERVE)
        renderer = renderer_for(states, render, colliders, reserve_top=reserve)
    return renderer, legend


#: Largest share of a 3-D picture's height kept free above the subject for a legend.
_MAX_RESERVE = 0.15


def _under_legend(states, renderer, drawables, shape) -> bool:
    """True when some of the run's subject (particles, shapes; 12 frames) is drawn under the
    top-left legend of ``shape`` (h, w, ...) with the renderer's framing."""
    picks = np.unique(np.linspace(0, states.frame_count - 1, min(states.frame_count, 12)).astype(int))
    extra = None if drawables is None else drawables.bounds_points(states.fields.get("body_q"))
    x1, y1 = _LEGEND_MARGIN_PX + shape[1], _LEGEND_MARGIN_PX + shape[0]
    for f in picks:
        pts = np.asarray(states.positions[f], np.float64).reshape(-1, 3)
        if extra is not None:
            pts = np.concatenate([pts, extra])
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        px, py, depth = renderer.camera_at(float(states.times[f])).project(pts, renderer.width, renderer.height)
        if np.any((depth > 0) & (px < x1) & (py < y1)):
            return True
    return False


def render_frames(states, render: dict | None = None, colliders=(), frames=None):
    """Yield (frame index, (H, W, 3) uint8 image) for the frames of a run."""
    from inertia.render.drawables import ModelDrawables, frame_options, subject_bounds
    from inertia.render.fluid_particles import (LiquidSurfaces, frame_grids, frame_volumes, grid_scales,
                                                grid_streaks, grid_fluids, paint_grids, paint_volumes, smoke_styles,
                                                sph_surface_wanted, with_fluid_particles)

    states = with_fluid_particles(states)  # SPH fluids' particles after the groups' (coloured by speed)
    renderer, legend = framed_renderer(states, render, colliders)
    scales = grid_scales(states)  # 2-D grids: one colour scale for the run, tracer streaks ([render] streaks)
    drawables = ModelDrawables.from_states(states)  # bodies, cloth, springs (render helper)
    frame_grids(renderer, states)  # 2-D grid fluids: framed when there is no particle, painted below
    frame_volumes(renderer, states, colliders, render)  # 3-D smoke: framed on its grid box, ray-marched below
    smoke = smoke_styles(states)
    streaks = grid_streaks(states, render)
    # particle liquids drawn as their surfaces (mesh in 3-D, filled in 2-D); SPH too unless [render]
    # fluid_surface = false (by default wherever scikit-image, the surface extra, is installed)
    liquids = LiquidSurfaces(states, sph=sph_surface_wanted(render))
    draw = colliders if (render or {}).get("draw_colliders", True) else ()
    draw = list(draw) + attractor_markers(states)  # where the attractors pull (wind)
    if drawables is not None:
        draw = list(draw) + drawables.plane_colliders(subject_bounds(states, drawables))
    colors = _group_colors(states, renderer)
    groups = states.groups()
    radius = states.radius()
    indices = range(states.frame_count) if frames is None else frames
    grids = bool(grid_fluids(states)) and renderer.dim == 2
    axes = _axes_layer(renderer, render) if grids else None  # 2-D fluid maps carry a scale in metres
    for f in indices:
        options = frame_options(drawables, states, f, states.active(f), trails=int((render or {}).get("trails", 0)))
        underlay = (lambda img, f=f: paint_grids(img, states, f, renderer, scales, streaks)) if grids else None
        image = renderer.frame(
            states.positions[f], radius=radius,
            velocities=None if states.velocities is None else states.velocities[f],
            colors=colors, groups=groups, colliders=draw, t=float(states.times[f]), underlay=underlay,
            **liquids.apply(options, f))
        liquids.paint(image, f, renderer)
        paint_volumes(image, states, f, renderer, smoke, colliders)
        if axes is not None:
            from inertia.render.legend import blend

            blend(image, axes)
        if legend is not None:
            from inertia.render.legend import overlay

            overlay(image, legend, margin=_LEGEND_MARGIN_PX,
                    corner="right" if axes is not None else "left")  # clear of the y axis
        yield f, image


def _legend(states, renderer, render: dict | None):
    """A legend image (h, w, 4) when colours mean groups and there are two or more; else None."""
    from inertia.render.colormaps import group_palette, resolve_color_mode

    names = list(states.metadata.get("groups") or [])
    groups = states.groups()
    if len(names) < 2 or groups is None:
        return None
    if resolve_color_mode(renderer.color_by, None, states.velocities, groups) != "group":
        return None
    try:
        from inertia.render.legend import legend_image
    except ImportError:  # pragma: no cover - matplotlib is in the [cli] extra
        return None
    palette = group_palette(states.metadata.get("group_colors"), len(names))[: len(names)]
    return legend_image(names, palette, frame_height=renderer.height, theme=(render or {}).get("theme", "dark"))


class AttractorMarker:
    """An attractor's centre drawn as a small sphere (``radius`` m): its softening length, at least
    1 % of the scene; it collides with nothing, it only shows where the particles are pulled."""

    def __init__(self, center, radius: float):
        self.center = np.asarray(center, np.float64)
        self.radius = float(radius)

    def render_primitive(self, t: float = 0.0):
        return "sphere", {"center": self.center, "radius": self.radius}


def attractor_markers(states) -> list:
    """`AttractorMarker`s of the ``attractor`` forces in a run's scene text (recorded in its header)."""
    text = states.metadata.get("scene")
    if not text or "attractor" not in text:
        return []
    try:
        if states.metadata.get("scene_format", "toml") == "json":
            import json

            data = json.loads(text)
        else:
            import tomllib

            data = tomllib.loads(text)
    except ValueError:
        return []
    forces = list(data.get("forces") or [])
    for group in data.get("particles") or []:
        forces += list(group.get("forces") or [])
    size = 1.0
    if states.particle_count and states.frame_count:
        x = np.asarray(states.positions[0], np.float64)
        x = x[np.all(np.isfinite(x), axis=1)]
        size = float(np.max(np.ptp(x, axis=0))) if x.shape[0] > 1 else 1.0
    out = []
    for force in forces:
        if isinstance(force, dict) and force.get("type") == "attractor" and force.get("center") is not None:
            center = np.asarray(force["center"], np.float64)
            if center.shape[0] == states.dim:
                radius = max(0.5 * float(force.get("softening") or 0.0), 0.01 * size)
                out.append(AttractorMarker(center, min(radius, 0.05 * size)))
    return out


def _axes_layer(renderer, render: dict | None) -> np.ndarray | None:
    """The x/y axes in metres of a 2-D orthographic view as a full-frame RGBA layer, or None."""
    camera = renderer.camera
    if (renderer.dim != 2 or camera is None or camera.projection != "orthographic" or getattr(renderer, "orbit", 0)
            or getattr(renderer, "follow", False)):
        return None
    try:
        from inertia.render.legend import axes_image

        return axes_image(camera, renderer.width, renderer.height, theme=(render or {}).get("theme", "dark"))
    except ImportError:  # pragma: no cover - matplotlib is in the [cli] extra
        return None


def _quantity_legend(states, renderer, render: dict | None, scales: dict, shown: int) -> np.ndarray | None:
    """A colour bar with the quantity's unit wherever colour means a quantity and no other legend
    explains it: particles coloured by speed (m/s; ``shown``: how many are drawn as spheres, not as
    a cloth surface), a 2-D grid's colour map (smoke density, or speed in m/s); None otherwise (3-D
    smoke is shaded, not colour-mapped)."""
    from inertia.render.colormaps import resolve_color_mode
    from inertia.render.fluid_particles import grid_fluids, speed_colorbar

    theme = (render or {}).get("theme", "dark")
    try:
        grids = grid_fluids(states) if renderer.dim == 2 else []
        if grids:
            name, quantity = grids[0]
            vmax = float(scales.get(name, 1.0))
            label = "smoke density (per unit volume)" if quantity == "density" else "flow speed (m/s)"
            return speed_colorbar(vmax, frame_height=renderer.height, theme=theme,
                                  cmap="magma" if quantity == "density" else "speed", label=label)
        if shown > 0 and states.velocities is not None and renderer.speed_max:
            if resolve_color_mode(renderer.color_by, None, states.velocities, states.groups()) == "speed":
                return speed_colorbar(float(renderer.speed_max), frame_height=renderer.height, theme=theme,
                                      cmap=renderer.colormap)
    except (ImportError, ValueError):  # matplotlib is in the [cli] extra; a zero scale has no bar
        return None
    return None


def plot_energy(states, path) -> Path:
    """Energy and momentum over time (PNG), one row per system the run recorded: particles,
    rigid bodies, each fluid (`inertia.render.plots.system_series`), with units."""
    from inertia.render.plots import plot_systems, system_series

    systems = system_series(states)
    if not systems:
        raise ValueError("the run recorded no energies and no velocities")
    title = f"{states.metadata.get('scene_name', 'run')}: energy and momentum per system"
    return plot_systems(states.times, systems, path, title=title)


def write_outputs(states, out_dir, output: dict, render: dict | None = None, colliders=(),
                  progress: Callable[[str, int, int], None] | None = None) -> dict[str, Path]:
    """Write the outputs a scene's [output] table asks for; returns {kind: path}.

    ``progress(stage, done, total)`` is called while frames are rendered.
    """
    from inertia.io import write_ply_sequence, write_usd
    from inertia.render import VideoWriter, write_png

    out = Path(out_dir)
    written: dict[str, Path] = {}
    fps = float(states.fps or 30.0)
    videos = [v for v in output.get("video", []) if v in ("mp4", "gif")]
    want_frames = bool(output.get("frames"))
    if (videos or want_frames) and states.frame_count:
        with contextlib.ExitStack() as stack:
            writers = {}
            for kind in videos:
                path = out / OUTPUT_NAMES[kind]
                writers[kind] = stack.enter_context(VideoWriter(path, fps=fps))
                written[kind] = path
            frame_dir = out / OUTPUT_NAMES["frames"]
            if want_frames:
                frame_dir.mkdir(exist_ok=True)
                written["frames"] = frame_dir
            total = states.frame_count
            for f, image in render_frames(states, render, colliders):
                for kind, writer in writers.items():
                    if kind == "gif" and image.shape[1] > 640:
                        writer.write(np.ascontiguousarray(image[::2, ::2]))
                    else:
                        writer.write(image)
                if want_frames:
                    write_png(frame_dir / f"frame_{f:05d}.png", image)
                if progress is not None:
                    progress("render", f + 1, total)
    if output.get("plot"):
        from inertia.render.plots import system_series

        if system_series(states):  # a run with nothing recorded to plot writes no plot
            written["plot"] = plot_energy(states, out / OUTPUT_NAMES["plot"])
    if output.get("ply"):
        directory = out / OUTPUT_NAMES["ply"]
        write_ply_sequence(states, directory)
        written["ply"] = directory
    bodies = _body_frames(states)
    if output.get("usd") and (bodies is None or states.particle_count):
        written["usd"] = write_usd(states, out / OUTPUT_NAMES["usd"], up_axis="Z" if states.dim == 3 else "Y")
    if bodies is not None and output.get("usd"):
        from inertia.io import write_usd_bodies

        written["usd_bodies"] = write_usd_bodies(out / OUTPUT_NAMES["usd_bodies"], bodies[0], bodies[1], fps=fps)
    if bodies is not None and output.get("obj"):
        from inertia.io import write_obj_sequence

        written["obj"] = write_obj_sequence(out / OUTPUT_NAMES["obj"], bodies[0], bodies[1])
    return written


def _body_frames(states):
    """(model dict, body_q (F, B, 7)) when the state file recorded rigid bodies, else None."""
    model = getattr(states, "model", None) or {}
    body_q = (states.fields or {}).get("body_q") if hasattr(states, "fields") else None
    if body_q is None or "shape_type" not in model:
        return None
    return model, np.asarray(body_q)


def frame_count_for(duration: float, fps: float) -> int:
    """Frames of a run of `duration` at `fps`, frame 0 (the initial state) included."""
    return int(math.floor(duration * fps + 1e-6)) + 1
