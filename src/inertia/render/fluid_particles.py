"""Fluids in rendered runs: SPH/FLIP particles coloured by speed with a colour bar, 2-D grids as
colour maps, 3-D smoke as a ray-marched lit volume, liquids as their surfaces.

A run records each particle fluid's ``frame_arrays()`` as fields ``fluid/<name>/x`` (F, C, D),
``fluid/<name>/v`` (F, C, D) and ``fluid/<name>/active`` (F, C) (C: the fluid's capacity) and its
``spacing`` in ``States.model`` (see `inertia.world.Run`). ``with_fluid_particles(states)`` returns
a `States` whose particles are the groups' followed by every fluid's, so the existing renderer
draws them unchanged:

- positions / velocities (F, N + sum C, D): the groups' (velocities zero when not recorded),
  then each fluid's; the ``active`` field masks the fluid's dead rows;
- radius: the groups' radii, and half the lattice spacing for fluid particles (they touch at rest);
- the per-particle ``group`` index is dropped, so ``color_by = "auto"`` colours every particle by
  speed on one scale for the whole run (`inertia.render.colormaps.run_speed_max`).

``speed_colorbar(vmax)`` draws the colour bar (matplotlib's Agg canvas) laid over every frame with
`inertia.render.legend.overlay`.

Recorded 2-D grid fluids (``fluid/<name>/speed`` (F, nx, ny) with ``origin``, ``cell_size`` in
``States.model``) are painted as colour maps under the particles (`Renderer.frame`'s ``underlay``):
``density`` in "magma" when recorded (smoke), else ``speed`` in the speed map, each on one scale for
the whole run (``grid_scales``; the maps of `inertia.render.fluid_grid`), solid cells left
unpainted so obstacles show; over the map, tracer streaks advected through the recorded
cell-centre velocity ``u``, ``v`` (``grid_streaks``: `inertia.render.fluid_grid.GridStreaks`,
``[render] streaks`` tracers, 400 default, 0 none, over ``streak_length`` frames, 8 default);
``frame_grids`` frames the camera on them when there is no particle.

Recorded 3-D smoke (``fluid/<name>/density`` (F, nx, ny, nz) with ``origin``, ``cell_size``) is
ray-marched over each finished frame by `inertia.render.fluid_volume` (``paint_volumes``): lit by a
key light from above and the side (``frame_volumes`` sets it, and frames the camera on where the
smoke goes over the run), occluded by whatever the renderer drew (its depth buffer), shadowed from
the light by the closed colliders (obstacle spheres, boxes: a cell mask), with one
extinction scale for the run (``smoke_styles``: ``SMOKE_OPTICAL_DEPTH`` over ten cells at the run's
99th-percentile density).

Particle liquids with a recorded level set (``fluid/<name>/phi``, `LiquidFluid`) are drawn as
their surface instead of their particles (``LiquidSurfaces``): in 3-D the phi = 0 surface by
marching cubes (scikit-image, the ``surface`` extra) as a shaded mesh among the frame's meshes
(lit, shadowed and z-tested with the bodies); in 2-D the region phi < 0 filled in
``LIQUID_COLOR`` with an anti-aliased edge and a lighter surface line. With ``[render]
fluid_surface = true`` SPH fluids are drawn the same way from their smoothed-particle surface
(the colour field's 1/2 level, `inertia.fluids.sph.surface`, built per frame from the particles).

3-D smoke also shades the opaque surfaces from the key light (``paint_volumes`` passes the
renderer's shadow strength to `inertia.render.fluid_volume`).

Limitations: grid colour maps are nearest cell per pixel, 2-D orthographic cameras only, and
cover the background's grid lines and 2-D colliders other than the fluid's obstacle cells (cells
whose centre is inside; the map's edge around an obstacle is a staircase of cells); runs recorded
before ``u``/``v`` were recorded get no streaks; a 3-D grid without a ``density`` scalar
(viscous flow only) is not drawn. When the groups and the fluid differ in dimension (a 3-D group
with a 2-D fluid) the fluid is not drawn; SPH surfaces use the cubic spline at the recorded
smoothing length whatever the fluid's kernel, leave boundary particles out (the colour field
thins next to walls: the surface can pull off a wall by up to a smoothing length), and cost a splat and (3-D) marching cubes per frame
(a 256^3 node cap, `colour_field`); without scikit-image a 3-D liquid or SPH surface falls back to
its particles (one warning); the 2-D liquid fill is painted over the finished frame
(particles of other groups inside the liquid are covered). Grid fluids (no ``x``) are left to
`inertia.render.fluid_grid`.
"""

from __future__ import annotations

import numpy as np

from ..io.states import States

__all__ = ["particle_fluids", "with_fluid_particles", "speed_colorbar", "fluid_legend", "grid_fluids",
           "frame_grids", "paint_grids", "grid_scales", "grid_streaks", "STREAKS", "STREAK_LENGTH", "volume_fluids", "frame_volumes", "smoke_styles", "paint_volumes",
           "liquid_fluids", "sph_surface_fluids", "LiquidSurfaces", "LIQUID_COLOR"]


def particle_fluids(states) -> list[str]:
    """Names of the particle fluids a run recorded (those with ``fluid/<name>/x`` frames)."""
    names = []
    for key in states.fields:
        parts = key.split("/")
        if len(parts) == 3 and parts[0] == "fluid" and parts[2] == "x" and f"fluid/{parts[1]}/v" in states.fields:
            names.append(parts[1])
    return names


def with_fluid_particles(states) -> States:
    """``states`` with every particle fluid's particles appended (see the module docstring);
    ``states`` itself when there is none to draw."""
    names = particle_fluids(states)
    frames, n = states.frame_count, states.particle_count
    dims = {states.fields[f"fluid/{name}/x"].shape[2] for name in names}
    if not names and n == 0 and states.dim != 2 and grid_fluids(states):
        # a run of 2-D grid fluids alone: a 2-D view (worlds without groups record 3-D positions)
        return States(states.times, np.zeros((frames, 0, 2)), np.zeros((frames, 0, 2)), dict(states.fields),
                      {}, dict(states.metadata, dim=2), states.model)
    if not names or len(dims) != 1 or (n > 0 and dims != {states.dim}):
        return states
    dim = dims.pop()
    pos = [np.asarray(states.positions, np.float64)[:, :, :dim] if n == 0 else np.asarray(states.positions, np.float64)]
    vel = [np.zeros((frames, n, dim)) if states.velocities is None or n == 0 else
           np.asarray(states.velocities, np.float64)]
    active = [np.ones((frames, n), bool) if states.active(0) is None else
              np.broadcast_to(np.asarray([states.active(f) for f in range(frames)], bool), (frames, n))]
    base_radius = states.radius()
    radius = [np.zeros(n) if base_radius is None else np.broadcast_to(np.asarray(base_radius, np.float64), (n,))]
    for name in names:
        x = np.asarray(states.fields[f"fluid/{name}/x"], np.float64)
        cap = x.shape[1]
        pos.append(x)
        vel.append(np.asarray(states.fields[f"fluid/{name}/v"], np.float64))
        alive = states.fields.get(f"fluid/{name}/active")
        active.append(np.ones((frames, cap), bool) if alive is None else np.asarray(alive, bool))
        spacing = states.model.get(f"fluid/{name}/spacing")
        radius.append(np.full(cap, 0.0 if spacing is None else 0.5 * float(np.ravel(spacing)[0])))
    total = sum(p.shape[1] for p in pos)
    fields = dict(states.fields)
    fields["active"] = np.concatenate(active, axis=1)
    static = {"radius": np.concatenate(radius)}
    if "radius" in fields:  # per-frame radii of the groups, then the fluids' constant ones
        fields["radius"] = np.concatenate([np.asarray(fields["radius"], np.float64)[:, :n],
                                           np.broadcast_to(static["radius"][n:], (frames, total - n))], axis=1)
    metadata = dict(states.metadata, dim=dim, particle_count=total)
    return States(states.times, np.concatenate(pos, axis=1), np.concatenate(vel, axis=1), fields, static, metadata,
                  states.model)


def speed_colorbar(vmax: float, *, frame_height: int = 540, theme: str = "dark", cmap: str | None = None,
                   label: str = "speed (m/s)") -> np.ndarray:
    """RGBA image (h, w, 4) uint8 of a horizontal colour bar from 0 to ``vmax`` in the colour map
    ``cmap`` (default the renderer's speed map), titled ``label`` (the quantity and its unit), to lay
    over frames."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    from .colormaps import DEFAULT_SPEED_MAP, colormap

    if not np.isfinite(vmax) or vmax <= 0:
        raise ValueError(f"speed_colorbar: vmax must be a finite value > 0 ({label}); got {vmax!r}")
    table = colormap(cmap or DEFAULT_SPEED_MAP, np.linspace(0.0, 1.0, 256), vmin=0.0, vmax=1.0)
    dpi = 100.0 * max(frame_height, 120) / 540.0
    text = "#e6e8ec" if theme == "dark" else "#24262b"
    fig = Figure(figsize=(2.2, 0.62), dpi=dpi)
    fig.patch.set_alpha(0.0)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.08, 0.55, 0.84, 0.2))
    ax.imshow(np.linspace(0.0, 1.0, 256)[None, :], aspect="auto", cmap=ListedColormap(np.asarray(table)[:, :3]),
              extent=(0.0, vmax, 0.0, 1.0))
    ax.set_yticks([])
    ax.set_xticks([0.0, vmax])
    ax.set_xticklabels(["0", f"{vmax:.3g}"], color=text, fontsize=8)
    ax.tick_params(colors=text, length=2, pad=1)
    for spine in ax.spines.values():
        spine.set_visible(False)
    ax.set_title(label, color=text, fontsize=8, pad=2)
    from .legend import cropped_canvas

    return cropped_canvas(canvas)


def fluid_legend(states, renderer, render: dict | None = None) -> np.ndarray | None:
    """The speed colour bar when ``states`` holds fluid particles and the renderer colours by speed."""
    from .colormaps import resolve_color_mode

    if not particle_fluids(states) or states.velocities is None or renderer.speed_max is None:
        return None
    surfaces = LiquidSurfaces(states, sph=sph_surface_wanted(render))
    if set(particle_fluids(states)) <= set(surfaces.names) and surfaces.draws_surfaces:
        return None  # every fluid is drawn as a surface: no speed colours to explain
    if resolve_color_mode(renderer.color_by, None, states.velocities, states.groups()) != "speed":
        return None
    try:
        return speed_colorbar(float(renderer.speed_max), frame_height=renderer.height,
                              theme=(render or {}).get("theme", "dark"), cmap=renderer.colormap)
    except ImportError:  # pragma: no cover - matplotlib is in the [cli] extra
        return None


def grid_fluids(states) -> list[tuple[str, str]]:
    """(name, quantity) of the recorded 2-D grid fluids: ``density`` when recorded, else ``speed``."""
    out = []
    for key, value in states.fields.items():
        parts = key.split("/")
        if len(parts) == 3 and parts[0] == "fluid" and parts[2] == "speed" and np.ndim(value) == 3 \
                and f"fluid/{parts[1]}/origin" in states.model and f"fluid/{parts[1]}/cell_size" in states.model:
            quantity = "density" if f"fluid/{parts[1]}/density" in states.fields else "speed"
            out.append((parts[1], quantity))
    return out


def _extent(states, name):
    origin = np.asarray(states.model[f"fluid/{name}/origin"], np.float64).ravel()[:2]
    shape = np.asarray(states.fields[f"fluid/{name}/speed"].shape[1:3], np.float64)
    return origin, origin + shape * float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0])


def frame_grids(renderer, states) -> None:
    """A 2-D orthographic camera on the grids when the run has grids and no particle to frame."""
    from .camera import Camera

    grids = grid_fluids(states)
    if not grids or renderer.dim != 2 or states.particle_count > 0:
        return
    lo = np.min([_extent(states, n)[0] for n, _ in grids], axis=0)
    hi = np.max([_extent(states, n)[1] for n, _ in grids], axis=0)
    aspect = renderer.width / renderer.height
    height = 1.1 * max(hi[1] - lo[1], (hi[0] - lo[0]) / aspect)
    renderer.camera = Camera.plane_2d(0.5 * (lo + hi), height)


def grid_scales(states) -> dict:
    """name -> colour-map maximum of each recorded 2-D grid: the run's 99th percentile of the mapped
    quantity (over a sample of about 50 frames; 1 when it is not positive)."""
    scales = {}
    for name, quantity in grid_fluids(states):
        data = np.asarray(states.fields[f"fluid/{name}/{quantity}"])
        finite = data[:: max(1, data.shape[0] // 50)]
        vmax = float(np.percentile(finite[np.isfinite(finite)], 99.0)) if np.isfinite(finite).any() else 1.0
        scales[name] = vmax if vmax > 0 else 1.0
    return scales


#: Default number of tracer streaks per 2-D grid fluid in `inertia run` ([render] streaks).
STREAKS = 400
#: Default frames of history per streak ([render] streak_length).
STREAK_LENGTH = 8


def grid_streaks(states, render: dict | None = None) -> dict:
    """name -> `inertia.render.fluid_grid.GridStreaks` for the recorded 2-D grids with a velocity
    (``fluid/<name>/u``, ``v``), ``[render] streaks`` tracers each (0: none) over
    ``streak_length`` frames; seeded by the fluid's position in the run (same streaks every run)."""
    from .fluid_grid import GridStreaks

    render = render or {}
    count = STREAKS if render.get("streaks") is None else int(render["streaks"])
    length = STREAK_LENGTH if render.get("streak_length") is None else int(render["streak_length"])
    if count <= 0:
        return {}
    out = {}
    for k, (name, _) in enumerate(grid_fluids(states)):
        streaks = GridStreaks.from_states(states, name, count=count, length=length, seed=k)
        if streaks is not None:
            out[name] = streaks
    return out


def paint_grids(image, states, frame: int, renderer, scales: dict | None = None, streaks: dict | None = None):
    """Paint every recorded 2-D grid fluid of ``frame`` into ``image`` (H, W, 3) uint8 in place:
    its colour map (nearest cell per pixel inside the grid's rectangle, solid cells left as they
    were so obstacles show), then its tracer streaks (``streaks``: name -> `GridStreaks`, see
    `grid_streaks`). ``scales``: name -> colour-map maximum (default `grid_scales`). Returns the
    (H, W) bool mask of the pixels painted (`Renderer.frame`'s ``underlay`` contract)."""
    from .colormaps import colormap

    h, w = image.shape[:2]
    changed = np.zeros((h, w), np.bool_)
    if renderer.dim != 2 or renderer.camera is None:
        return changed
    scales = grid_scales(states) if scales is None else scales
    for name, quantity in grid_fluids(states):
        data = states.fields[f"fluid/{name}/{quantity}"]
        vmax = scales.get(name, 1.0)
        lo, hi = _extent(states, name)
        px, py, _ = renderer.camera.project(np.array([lo, hi]), w, h)
        x0, x1 = int(np.clip(np.ceil(min(px)), 0, w)), int(np.clip(np.floor(max(px)), 0, w))
        y0, y1 = int(np.clip(np.ceil(min(py)), 0, h)), int(np.clip(np.floor(max(py)), 0, h))
        if x1 <= x0 or y1 <= y0:
            continue
        nx, ny = data.shape[1:3]
        ci = np.clip(((np.arange(x0, x1) + 0.5 - min(px)) / (max(px) - min(px)) * nx).astype(int), 0, nx - 1)
        cj = np.clip(((max(py) - np.arange(y0, y1) - 0.5) / (max(py) - min(py)) * ny).astype(int), 0, ny - 1)
        values = np.asarray(data[frame])[ci[None, :], cj[:, None]]
        rgb = colormap("magma" if quantity == "density" else "speed", values, vmin=0.0, vmax=vmax)
        rgb = np.clip(np.round(np.asarray(rgb)[..., :3] * 255.0), 0, 255).astype(np.uint8)
        solid = states.fields.get(f"fluid/{name}/solid")
        fluid = np.ones(values.shape, bool) if solid is None else np.asarray(solid[frame])[ci[None, :], cj[:, None]] == 0
        block = image[y0:y1, x0:x1]
        block[fluid] = rgb[fluid]
        changed[y0:y1, x0:x1] |= fluid
        if streaks and name in streaks:
            bx, by = (px[1] - px[0]) / (hi[0] - lo[0]), (py[1] - py[0]) / (hi[1] - lo[1])
            streaks[name].paint(image, frame, (px[0] - bx * lo[0], bx, py[0] - by * lo[1], by),
                                width_px=max(1.0, 1.5 * h / 540.0), changed=changed)
    return changed


# ----------------------------------------------------------------------------- 3-D smoke volumes
def volume_fluids(states) -> list[str]:
    """Names of the recorded 3-D grid fluids with a ``density`` scalar (smoke): fields
    ``fluid/<name>/density`` (F, nx, ny, nz) and ``origin`` / ``cell_size`` in ``States.model``."""
    names = []
    for key, value in states.fields.items():
        parts = key.split("/")
        if len(parts) == 3 and parts[0] == "fluid" and parts[2] == "density" and np.ndim(value) == 4 \
                and f"fluid/{parts[1]}/origin" in states.model and f"fluid/{parts[1]}/cell_size" in states.model:
            names.append(parts[1])
    return names


def _box3(states, name):
    origin = np.asarray(states.model[f"fluid/{name}/origin"], np.float64).ravel()[:3]
    shape = np.asarray(states.fields[f"fluid/{name}/density"].shape[1:4], np.float64)
    return origin, origin + shape * float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0])


def frame_volumes(renderer, states, colliders=(), render: dict | None = None) -> None:
    """Frame the 3-D camera on where the smoke goes over the run (the cells above 2 % of the run's
    99th-percentile density in a sample of frames, else the grid's box), the particles and the
    colliders, unless the scene's [render] camera sets a position or target."""
    names = volume_fluids(states)
    camera = dict((render or {}).get("camera") or {})
    if not names or renderer.dim != 3 or camera.get("position") is not None or camera.get("target") is not None:
        return
    corners = []
    for name in names:
        lo, hi = _smoke_extent(states, name)
        corners += [np.where([a, b, c], hi, lo) for a in (0, 1) for b in (0, 1) for c in (0, 1)]
    extra = np.array(corners)
    positions = np.asarray(states.positions, np.float64)
    if positions.shape[1] == 0:  # smoke alone: its box in every frame (so an orbit keeps its keys)
        positions = np.ascontiguousarray(np.broadcast_to(extra, (max(len(states.times), 1),) + extra.shape))
        extra = None
    renderer.fit(positions, radius=states.radius(), colliders=colliders, active=None, extra_points=extra,
                 times=states.times if positions.shape[0] == len(states.times) else None)
    if renderer.light_direction is None:
        # A key light from above and the side, a little behind the smoke: the plume's lit and
        # shadowed sides both face the camera (the renderer's default light is near the view).
        from .camera import UP_AXES

        right, _, forward = renderer.camera.basis()
        light = 1.5 * UP_AXES[renderer.up][0] + 0.9 * right + 0.25 * forward
        renderer.light_direction = light / np.linalg.norm(light)


def _smoke_extent(states, name):
    """World box (lo, hi) of the cells holding smoke in a sample of frames (the grid's box if none)."""
    lo, hi = _box3(states, name)
    data = states.fields[f"fluid/{name}/density"]
    sample = np.nan_to_num(np.asarray(data[:: max(1, data.shape[0] // 12)]), nan=0.0)
    level = 0.02 * _density_scale(sample)
    occupied = np.argwhere(np.max(sample, axis=0) > level)
    if occupied.size == 0:
        return lo, hi
    h = float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0])
    return lo + occupied.min(axis=0) * h, lo + (occupied.max(axis=0) + 1) * h


def _density_scale(sample) -> float:
    """The 99th percentile of the smoky cells' density (those above 1e-3 of the maximum)."""
    top = float(np.max(sample)) if sample.size else 0.0
    smoky = sample[sample > 1e-3 * top] if top > 0 else sample[:0]
    return float(np.percentile(smoky, 99.0)) if smoky.size else 1.0


#: Optical depth of a plume ten cells across at the run's 99th-percentile density (sets sigma_t).
SMOKE_OPTICAL_DEPTH = 4.0


def smoke_styles(states) -> dict:
    """A `inertia.render.fluid_volume.SmokeStyle` per 3-D smoke of the run, on one scale for the
    whole run: ``sigma_t = SMOKE_OPTICAL_DEPTH / (rho_99 10 h)``, so a plume ten cells across at
    the run's 99th percentile density (over its smoky cells) has that optical depth."""
    from .fluid_volume import SmokeStyle

    styles = {}
    for name in volume_fluids(states):
        data = states.fields[f"fluid/{name}/density"]
        rho = _density_scale(np.nan_to_num(np.asarray(data[:: max(1, data.shape[0] // 12)]), nan=0.0))
        h = float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0])
        styles[name] = SmokeStyle(sigma_t=SMOKE_OPTICAL_DEPTH / (max(rho, 1e-12) * 10.0 * h))
    return styles


def _solid_cells(states, name, colliders, t):
    """(nx, ny, nz) bool: cells of the smoke grid whose centre is inside a closed collider (spheres,
    boxes, capsules, ...; planes and containers are walls, not obstacles), or None."""
    solids = [c for c in colliders if type(c).__name__ not in ("Plane", "Container") and hasattr(c, "signed_distance")]
    if not solids:
        return None
    lo, _ = _box3(states, name)
    shape = states.fields[f"fluid/{name}/density"].shape[1:4]
    h = float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0])
    axes = [lo[a] + (np.arange(shape[a]) + 0.5) * h for a in range(3)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    inside = np.zeros(points.shape[0], bool)
    for collider in solids:
        try:
            inside |= np.asarray(collider.signed_distance(points, t)).reshape(-1) < 0.0
        except (TypeError, ValueError):  # a collider without a 3-D signed distance: not an obstacle here
            continue
    return inside.reshape(shape) if inside.any() else None


def paint_volumes(image, states, frame: int, renderer, styles: dict | None = None, colliders=()) -> np.ndarray:
    """Composite every recorded 3-D smoke of ``frame`` over ``image`` (H, W, 3) uint8 in place, lit
    by the renderer's key light, occluded by what the renderer drew (its depth buffer) and shadowed
    from the light by the closed ``colliders`` (obstacles); see `inertia.render.fluid_volume`."""
    from .fluid_volume import composite_smoke

    names = volume_fluids(states)
    if not names or renderer.dim != 3 or renderer.camera is None:
        return image
    styles = smoke_styles(states) if styles is None else styles
    camera = renderer.camera_at(float(states.times[frame]))
    light = renderer._light_direction(camera)
    depth = renderer._depth if renderer._depth.shape == image.shape[:2] else None
    for name in names:
        density = states.fields[f"fluid/{name}/density"][frame]
        lo, _ = _box3(states, name)
        composite_smoke(image, camera, density, origin=lo,
                        cell_size=float(np.ravel(states.model[f"fluid/{name}/cell_size"])[0]),
                        light_direction=light, style=styles.get(name), depth=depth,
                        solid=_solid_cells(states, name, colliders, float(states.times[frame])),
                        shadow_strength=renderer.shadow_strength if renderer.shadows else 0.0)
    return image


# ----------------------------------------------------------------------------- liquid surfaces
#: Colour of liquid surfaces (sRGB): a 3-D shaded mesh, a filled region in 2-D.
LIQUID_COLOR = (0.22, 0.52, 0.86)


def liquid_fluids(states) -> list[str]:
    """Names of the recorded particle liquids with a level set: ``fluid/<name>/phi`` (F, nx, ny[, nz])
    beside their particles ``x``, and ``origin`` / ``cell_size`` in ``States.model``."""
    return [name for name in particle_fluids(states)
            if f"fluid/{name}/phi" in states.fields and f"fluid/{name}/origin" in states.model
            and f"fluid/{name}/cell_size" in states.model]


def _surface_mesh_3d(phi, origin, h):
    """(vertices (V, 3) m, triangles (T, 3)) of the phi = 0 surface of cell-centred ``phi``
    (negative inside) by scikit-image's marching cubes, closed against the walls (padded with air)."""
    from skimage import measure

    padded = np.pad(np.asarray(phi, np.float32), 1, constant_values=3.0 * h)
    if not (padded.min() < 0.0 < padded.max()):
        return None
    verts, faces, _, _ = measure.marching_cubes(padded, 0.0, spacing=(h, h, h))
    return verts + (np.asarray(origin, np.float64)[:3] - 0.5 * h), faces.astype(np.int64)


def sph_surface_wanted(render: dict | None) -> bool:
    """``[render] fluid_surface``: True or False as given; unset (None), True when the ``surface``
    extra (scikit-image) is installed, so SPH reads as a liquid wherever it can be drawn as one."""
    value = (render or {}).get("fluid_surface")
    if value is not None:
        return bool(value)
    try:
        import skimage  # noqa: F401
    except ImportError:
        return False
    return True


def sph_surface_fluids(states) -> list[str]:
    """Names of the recorded particle fluids without a level set but with a ``spacing`` (SPH): the
    ones ``[render] fluid_surface`` draws as smoothed-particle surfaces."""
    liquids = set(liquid_fluids(states))
    return [name for name in particle_fluids(states)
            if name not in liquids and f"fluid/{name}/spacing" in states.model]


class LiquidSurfaces:
    """Liquid surfaces of a run's particle liquids (`liquid_fluids`) in place of their particles.

    With ``sph=True`` (``[render] fluid_surface = true``) SPH fluids (`sph_surface_fluids`) too:
    their level set is built per frame from the active particles, the colour field of
    `inertia.fluids.sph.surface` (Mueller, Charypar and Gross 2003: c = sum_j V_j W(x - x_j, h),
    V_j = spacing^D, cubic spline at the recorded ``smoothing_length``, on a grid of spacing / 2)
    turned into phi = (1/2 - c) / |grad c| (`inertia.fluids.sph.surface.level_set`), then drawn
    as the liquids' are.

    3-D: the recorded level set's phi = 0 surface (marching cubes, the ``surface`` extra's
    scikit-image) as a shaded `TriangleMesh` among the frame's meshes (lit, shadowed, z-tested
    with everything else); without scikit-image the particles are drawn instead, with a one-line
    warning. 2-D: the region phi < 0 (bilinear phi per pixel) filled in ``LIQUID_COLOR`` with a
    lighter surface line, painted after the frame (2-D orthographic cameras).
    ``merged`` is the `States` from `with_fluid_particles` (groups' particles, then each fluid's).
    """

    def __init__(self, merged, *, color=LIQUID_COLOR, sph=False):
        self.states = merged
        self.color = np.asarray(color, np.float32)
        self.sph_names = sph_surface_fluids(merged) if sph else []
        self.names = liquid_fluids(merged) + self.sph_names
        self.mesh_ok = True
        if self.names and merged.dim == 3:
            try:
                import skimage.measure  # noqa: F401
            except ImportError:
                import warnings

                warnings.warn("liquid surfaces need scikit-image (pip install 'inertia[surface]'): drawing the "
                              "liquid's particles instead", stacklevel=2)
                self.mesh_ok = False
        # rows of each liquid's particles in the merged particle list
        self.rows = {}
        caps = {name: merged.fields[f"fluid/{name}/x"].shape[1] for name in particle_fluids(merged)}
        start = merged.particle_count - sum(caps.values())
        for name, cap in caps.items():
            if name in self.names:
                self.rows[name] = (start, start + cap)
            start += cap

    @property
    def draws_surfaces(self) -> bool:
        """True when the liquids are drawn as surfaces (not as particles)."""
        return bool(self.names) and (self.states.dim == 2 or self.mesh_ok)

    def _grid(self, name):
        m = self.states.model
        return np.asarray(m[f"fluid/{name}/origin"], np.float64).ravel(), float(np.ravel(m[f"fluid/{name}/cell_size"])[0])

    def level_set(self, name, f: int):
        """(phi (nx, ny[, nz]) cell-centred, negative inside, origin (D,) of the grid's corner, cell
        size) of fluid ``name`` at frame ``f``; None when an SPH fluid has no live particle."""
        if name not in self.sph_names:
            origin, h = self._grid(name)
            return np.asarray(self.states.fields[f"fluid/{name}/phi"][f], np.float64), origin, h
        from ..fluids.sph.surface import colour_field, level_set

        fields, m = self.states.fields, self.states.model
        x = np.asarray(fields[f"fluid/{name}/x"][f], np.float64)
        alive = fields.get(f"fluid/{name}/active")
        keep = np.all(np.isfinite(x), axis=1) if alive is None else np.asarray(alive[f], bool) & np.all(np.isfinite(x), axis=1)
        if not keep.any():
            return None
        spacing = float(np.ravel(m[f"fluid/{name}/spacing"])[0])
        h = m.get(f"fluid/{name}/smoothing_length")
        field, lo, cell = colour_field(x[keep], spacing, smoothing_length=None if h is None else float(np.ravel(h)[0]))
        # node i of the colour field sits at lo + i cell: the centre of cell i of a grid whose corner is lo - cell / 2
        return level_set(field, cell), lo - 0.5 * cell, cell

    def apply(self, options: dict, f: int) -> dict:
        """Add the surfaces of frame ``f`` to `Renderer.frame` keyword ``options`` (meshes, 3-D) and
        switch the liquids' particles off (``active``); returns ``options``."""
        if not self.draws_surfaces:
            return options
        from .meshes import TriangleMesh

        n = self.states.particle_count
        active = options.get("active")
        active = np.ones(n, bool) if active is None else np.array(active, bool)
        meshes = list(options.get("meshes") or [])
        for name in self.names:
            a, b = self.rows[name]
            active[a:b] = False
            if self.states.dim == 3:
                grid = self.level_set(name, f)
                mesh = None if grid is None else _surface_mesh_3d(grid[0], grid[1], grid[2])
                if mesh is not None:
                    meshes.append(TriangleMesh(mesh[0], None, mesh[1], self.color))
        options = dict(options, active=active, meshes=meshes)
        return options

    def paint(self, image, f: int, renderer) -> np.ndarray:
        """2-D: fill each liquid's region phi < 0 of frame ``f`` into ``image`` (H, W, 3) uint8."""
        if not self.names or renderer.dim != 2 or renderer.camera is None:
            return image
        h_px, w_px = image.shape[:2]
        cam = renderer.camera
        f_px = cam.focal_px(h_px)
        # world point of every pixel centre
        xs = cam.position[0] + (np.arange(w_px) + 0.5 - w_px / 2.0) / f_px
        ys = cam.position[1] + (h_px / 2.0 - (np.arange(h_px) + 0.5)) / f_px
        fill = np.round(self.color * 255.0)
        edge = np.round(np.minimum(self.color * 1.6 + 0.15, 1.0) * 255.0)
        for name in self.names:
            grid = self.level_set(name, f)
            if grid is None:
                continue
            phi, origin, h = grid
            nx, ny = phi.shape
            gx = (xs - origin[0]) / h - 0.5
            gy = (ys - origin[1]) / h - 0.5
            inside_x = (gx >= -0.5) & (gx <= nx - 0.5)
            inside_y = (gy >= -0.5) & (gy <= ny - 0.5)
            if not inside_x.any() or not inside_y.any():
                continue
            cols, rows = np.flatnonzero(inside_x), np.flatnonzero(inside_y)
            gx, gy = np.clip(gx[cols], 0, nx - 1), np.clip(gy[rows], 0, ny - 1)
            i0 = np.minimum(gx.astype(np.int64), max(nx - 2, 0))
            j0 = np.minimum(gy.astype(np.int64), max(ny - 2, 0))
            fx, fy = (gx - i0)[None, :], (gy - j0)[:, None]
            i1, j1 = np.minimum(i0 + 1, nx - 1), np.minimum(j0 + 1, ny - 1)
            value = ((1 - fy) * ((1 - fx) * phi[i0[None, :], j0[:, None]] + fx * phi[i1[None, :], j0[:, None]])
                     + fy * ((1 - fx) * phi[i0[None, :], j1[:, None]] + fx * phi[i1[None, :], j1[:, None]]))
            # coverage from the signed distance in pixels (anti-aliased edge), a lighter line on the surface
            d_px = value * f_px
            cover = np.clip(0.5 - d_px, 0.0, 1.0)[..., None]
            line = np.clip(1.0 - np.abs(d_px + 1.0) / 1.2, 0.0, 1.0)[..., None]
            block = image[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1].astype(np.float64)
            block = block * (1 - cover) + fill * cover
            block = block * (1 - line) + edge * line
            image[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] = np.clip(np.round(block), 0, 255).astype(np.uint8)
        return image
