"""SPH fluids in rendered runs: the fluid's particles drawn beside the particle groups, coloured
by speed, with a colour bar.

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

Limitations: when the groups and the fluid differ in dimension (a 3-D group with a 2-D fluid)
the fluid is not drawn; fluids are spheres/discs (no liquid surface: that is
`inertia.fluids.sph.surface` through marching cubes, not wired into `inertia run` yet); grid
fluids (no ``x``) are left to `inertia.render.fluid_grid`.
"""

from __future__ import annotations

import numpy as np

from ..io.states import States

__all__ = ["particle_fluids", "with_fluid_particles", "speed_colorbar", "fluid_legend"]


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
    fields = {k: v for k, v in states.fields.items() if not (np.ndim(v) >= 2 and np.shape(v)[1] == n and n > 0)}
    fields["active"] = np.concatenate(active, axis=1)
    static = {"radius": np.concatenate(radius)}
    metadata = dict(states.metadata, dim=dim, particle_count=total)
    return States(states.times, np.concatenate(pos, axis=1), np.concatenate(vel, axis=1), fields, static, metadata,
                  states.model)


def speed_colorbar(vmax: float, *, frame_height: int = 540, theme: str = "dark", cmap: str | None = None) -> np.ndarray:
    """RGBA image (h, w, 4) uint8 of a horizontal colour bar from 0 to ``vmax`` [m/s] in the
    renderer's speed colour map, labelled "speed (m/s)", to lay over frames."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    from .colormaps import DEFAULT_SPEED_MAP, colormap

    if not np.isfinite(vmax) or vmax <= 0:
        raise ValueError(f"speed_colorbar: vmax must be a finite speed > 0 (m/s); got {vmax!r}")
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
    ax.set_title("speed (m/s)", color=text, fontsize=8, pad=2)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba(), dtype=np.uint8).copy()
    rows = np.flatnonzero(image[..., 3].max(axis=1) > 0)
    cols = np.flatnonzero(image[..., 3].max(axis=0) > 0)
    if rows.size and cols.size:
        image = image[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    return np.ascontiguousarray(image)


def fluid_legend(states, renderer, render: dict | None = None) -> np.ndarray | None:
    """The speed colour bar when ``states`` holds fluid particles and the renderer colours by speed."""
    from .colormaps import resolve_color_mode

    if not particle_fluids(states) or states.velocities is None or renderer.speed_max is None:
        return None
    if resolve_color_mode(renderer.color_by, None, states.velocities, states.groups()) != "speed":
        return None
    try:
        return speed_colorbar(float(renderer.speed_max), frame_height=renderer.height,
                              theme=(render or {}).get("theme", "dark"), cmap=renderer.colormap)
    except ImportError:  # pragma: no cover - matplotlib is in the [cli] extra
        return None
