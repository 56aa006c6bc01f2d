"""Legends (src/inertia/render/legend.py): one disc of each group's colour and its label."""

import numpy as np
import pytest

from inertia.render.legend import legend_image, overlay


def test_legend_shows_each_colour_and_overlays_only_its_corner():
    colors = np.array([[0.84, 0.15, 0.16], [0.17, 0.63, 0.17]])
    image = legend_image(["e=0.20", "e=0.95"], colors, frame_height=540)
    assert image.dtype == np.uint8 and image.shape[2] == 4
    assert 20 < image.shape[0] < 200 and 40 < image.shape[1] < 300
    opaque = image[image[..., 3] == 255][:, :3].astype(int)
    for c in np.round(colors * 255).astype(int):  # each swatch colour appears (anti-aliasing aside)
        assert (np.abs(opaque - c).max(axis=1) <= 3).sum() > 10
    frame = np.full((300, 400, 3), 40, np.uint8)
    before = frame.copy()
    overlay(frame, image)
    changed = np.argwhere(np.any(frame != before, axis=2))
    assert changed.size and changed[:, 0].max() < 12 + image.shape[0] and changed[:, 1].max() < 12 + image.shape[1]


def test_legend_needs_one_colour_per_label():
    with pytest.raises(ValueError, match="one colour per label"):
        legend_image(["a", "b"], [[1.0, 0.0, 0.0]])


def test_axes_of_a_2d_map_mark_the_view_in_metres():
    """Ticks sit where the camera puts their world coordinate: for a view 2 m tall centred at
    (1, 0.5) on 320 x 180 pixels, x = 1 m is the middle column and the axes hug the bottom and left;
    the last tick label carries the unit."""
    from inertia.render.camera import Camera
    from inertia.render.legend import axes_image, blend

    layer = axes_image(Camera.plane_2d((1.0, 0.5), 2.0), 320, 180, theme="dark")
    assert layer.shape == (180, 320, 4)
    drawn = layer[..., 3] > 0
    assert drawn[-1, :].mean() > 0.95 and drawn[:, 0].mean() > 0.95        # bottom and left spines
    assert drawn[:40, 60:].mean() < 0.02 and drawn[60:120, 120:200].mean() == 0  # the map stays clear
    # the tick at x = 1 m: a short vertical mark above the bottom spine, in the middle column
    ticks = np.flatnonzero(drawn[-5:-3, :].any(axis=0))
    assert np.min(np.abs(ticks - 159.5)) <= 2
    frame = np.zeros((180, 320, 3), np.uint8)
    blend(frame, layer)
    assert frame[-1].max() > 150 and frame[90, 160].max() == 0
