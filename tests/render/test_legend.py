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
