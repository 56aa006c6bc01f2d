"""Legends for rendered frames: what each particle colour means, drawn once, laid over every frame.

``legend_image(labels, colors)`` draws a small box with a coloured disc and a label per entry
(matplotlib's Agg canvas, no display needed) and returns it as (h, w, 4) uint8 RGBA;
``overlay(frame, legend)`` alpha-blends it into a corner of an (H, W, 3) uint8 frame in place.
`inertia run` adds one to the video when particles are coloured by group and there are at
least two groups (the group names come from the scene, e.g. bouncing_balls' "e=0.20" ...).

Limitations: labels are single lines; the legend is scaled with the frame height (readable from
about 240 pixels up) and always sits in the top-left corner.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["axes_image", "blend", "legend_image", "overlay"]


def legend_image(labels: Sequence[str], colors, *, frame_height: int = 540, theme: str = "dark") -> np.ndarray:
    """RGBA image (h, w, 4) uint8 of a legend: one coloured disc (sRGB ``colors`` (G, 3) in
    [0, 1]) and one label per entry, on a translucent box matching the ``theme``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    labels = [str(s) for s in labels]
    colors = np.clip(np.asarray(colors, dtype=np.float64).reshape(-1, 3), 0.0, 1.0)
    if len(labels) != colors.shape[0] or not labels:
        raise ValueError(f"legend_image: need one colour per label; got {len(labels)} labels and {colors.shape[0]} colours")
    dpi = 100.0 * max(frame_height, 120) / 540.0
    text = "#e6e8ec" if theme == "dark" else "#24262b"
    face = (0.08, 0.09, 0.11, 0.72) if theme == "dark" else (0.98, 0.98, 0.97, 0.8)
    longest = max(len(s) for s in labels)
    fig = Figure(figsize=(0.55 + 0.085 * longest, 0.12 + 0.24 * len(labels)), dpi=dpi)
    fig.patch.set_alpha(0.0)
    canvas = FigureCanvasAgg(fig)
    handles = [Line2D([], [], linestyle="none", marker="o", markersize=8, markerfacecolor=c,
                      markeredgecolor=c) for c in colors]
    legend = fig.legend(handles, labels, loc="center", frameon=True, fontsize=10, labelcolor=text,
                        handletextpad=0.4, borderpad=0.5, labelspacing=0.35, fancybox=True)
    legend.get_frame().set_facecolor(face)
    legend.get_frame().set_edgecolor("none")
    return cropped_canvas(canvas)


def cropped_canvas(canvas) -> np.ndarray:
    """Draw a matplotlib Agg canvas with a transparent background and return its RGBA pixels
    (H, W, 4) uint8, cropped to what was drawn (legends, colour bars)."""
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba(), dtype=np.uint8).copy()
    rows = np.flatnonzero(image[..., 3].max(axis=1) > 0)
    cols = np.flatnonzero(image[..., 3].max(axis=0) > 0)
    if rows.size and cols.size:
        image = image[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    return np.ascontiguousarray(image)


def overlay(frame: np.ndarray, legend: np.ndarray, *, margin: int = 12, corner: str = "left") -> np.ndarray:
    """Alpha-blend ``legend`` (h, w, 4) into the top-left (``corner="left"``) or top-right
    (``"right"``) corner of ``frame`` (H, W, 3) uint8, in place (cropped if the frame is smaller);
    returns the frame."""
    if corner not in ("left", "right"):
        raise ValueError(f"overlay: corner must be 'left' or 'right', got {corner!r}")
    h = min(legend.shape[0], frame.shape[0] - margin)
    w = min(legend.shape[1], frame.shape[1] - margin)
    if h <= 0 or w <= 0:
        return frame
    x0 = margin if corner == "left" else frame.shape[1] - margin - w
    region = frame[margin:margin + h, x0:x0 + w].astype(np.float32)
    rgba = legend[:h, :w].astype(np.float32)
    alpha = rgba[..., 3:4] / 255.0
    # Agg writes premultiplied-looking edges only at the box's rim; straight alpha blend.
    frame[margin:margin + h, x0:x0 + w] = np.clip(
        np.round(region * (1.0 - alpha) + rgba[..., :3] * alpha), 0, 255).astype(np.uint8)
    return frame


def axes_image(camera, width: int, height: int, *, theme: str = "dark", unit: str = "m") -> np.ndarray:
    """RGBA image (height, width, 4) uint8 of axes with ticks in world units along the bottom and left
    edges of a 2-D orthographic view (``camera``: `Camera.plane_2d`), the last tick of each axis
    carrying the unit ("2.5 m"), transparent elsewhere: ``blend(frame, axes_image(...))`` puts a scale on a 2-D map."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100.0
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
    fig.patch.set_alpha(0.0)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.patch.set_alpha(0.0)
    half_h = 0.5 * float(camera.ortho_height)
    half_w = half_h * width / height
    cx, cy = float(camera.target[0]), float(camera.target[1])
    ax.set_xlim(cx - half_w, cx + half_w)
    ax.set_ylim(cy - half_h, cy + half_h)
    text = "#e6e8ec" if theme == "dark" else "#24262b"
    size = max(7.0, 9.0 * height / 540.0)
    # ticks inside the frame; none near the lower-left corner where the two axes meet; the last
    # tick of each axis carries the unit ("2.5 m")
    for axis, lo, hi, pixels in ((ax.xaxis, cx - half_w, cx + half_w, width), (ax.yaxis, cy - half_h, cy + half_h, height)):
        span = hi - lo
        ticks = [t for t in axis.get_major_locator().tick_values(lo, hi)
                 if lo + 0.08 * span * 540.0 / max(pixels, 1) * 2 <= t <= hi - 0.02 * span]
        axis.set_ticks(ticks)
        axis.set_ticklabels([f"{t:g}" + (f" {unit}" if i == len(ticks) - 1 else "") for i, t in enumerate(ticks)])
    ax.set_xlim(cx - half_w, cx + half_w)
    ax.set_ylim(cy - half_h, cy + half_h)
    ax.tick_params(direction="in", colors=text, labelsize=size, length=0.8 * size, width=1.0)
    ax.tick_params(axis="x", pad=-2.4 * size)
    ax.tick_params(axis="y", pad=-1.2 * size)
    for label in ax.get_yticklabels():
        label.set_horizontalalignment("left")
    for spine in ("top", "right"):
        ax.spines[spine].set_visible(False)
    for spine in ("bottom", "left"):
        ax.spines[spine].set_color(text)
        ax.spines[spine].set_linewidth(2.0)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba(), dtype=np.uint8).copy()


def blend(frame: np.ndarray, layer: np.ndarray) -> np.ndarray:
    """Alpha-blend a full-frame RGBA ``layer`` (H, W, 4) into ``frame`` (H, W, 3) uint8 in place."""
    h, w = min(frame.shape[0], layer.shape[0]), min(frame.shape[1], layer.shape[1])
    alpha = layer[:h, :w, 3:4].astype(np.float32) / 255.0
    frame[:h, :w] = np.clip(np.round(frame[:h, :w] * (1.0 - alpha) + layer[:h, :w, :3] * alpha), 0, 255).astype(np.uint8)
    return frame
