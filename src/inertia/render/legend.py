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

__all__ = ["legend_image", "overlay"]


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


def overlay(frame: np.ndarray, legend: np.ndarray, *, margin: int = 12) -> np.ndarray:
    """Alpha-blend ``legend`` (h, w, 4) into the top-left corner of ``frame`` (H, W, 3) uint8, in
    place (cropped if the frame is smaller); returns the frame."""
    h = min(legend.shape[0], frame.shape[0] - margin)
    w = min(legend.shape[1], frame.shape[1] - margin)
    if h <= 0 or w <= 0:
        return frame
    region = frame[margin:margin + h, margin:margin + w].astype(np.float32)
    rgba = legend[:h, :w].astype(np.float32)
    alpha = rgba[..., 3:4] / 255.0
    # Agg writes premultiplied-looking edges only at the box's rim; straight alpha blend.
    frame[margin:margin + h, margin:margin + w] = np.clip(
        np.round(region * (1.0 - alpha) + rgba[..., :3] * alpha), 0, 255).astype(np.uint8)
    return frame
