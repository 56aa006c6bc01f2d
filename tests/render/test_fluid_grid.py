"""Colour-map images of 2-D grid fluids (inertia.render.fluid_grid)."""

import numpy as np
import pytest

from inertia.fluids.grid import GridFluid
from inertia.render.fluid_grid import FluidImage, side_by_side
from inertia.render.png import read_png


def _fluid():
    f = GridFluid((16, 8), 1 / 8, scalars=("density",), boundaries={s: "slip" for s in ("x-", "x+", "y-", "y+")})
    f.set_velocity(lambda p: np.stack([np.ones(len(p)), np.zeros(len(p))], 1))
    f.scalar("density")[12:, 6:] = 1.0  # a dense block at the top right
    return f


def test_density_image_orientation_size_and_png_round_trip(tmp_path):
    f = _fluid()
    img = FluidImage(f, "density", pixels_per_cell=3)
    a = img.image()
    assert a.shape == (8 * 3, 16 * 3, 3) and a.dtype == np.uint8
    # the dense block (x cells 12..15, y cells 6..7) is the top-right corner of the image
    top_right = a[:6, 36:].astype(int).sum(axis=2)
    bottom_left = a[-6:, :6].astype(int).sum(axis=2)
    assert top_right.min() > bottom_left.max()
    path = img.write(tmp_path / "d.png")
    assert np.array_equal(read_png(path)[..., :3], a)


def test_tracers_move_with_the_flow_and_streaks_are_drawn():
    f = _fluid()
    img = FluidImage(f, "speed", tracers=20, streak_length=4, seed=1)
    x0 = img.history[-1].copy()
    img.advance_tracers(0.1)
    moved = img.history[-1] - x0
    inside = (x0[:, 0] > 0.13) & (x0[:, 0] < 1.7)  # clear of the slip walls (u = 0 on x = 0, 2 m)
    assert inside.sum() > 10
    assert np.allclose(moved[inside], [0.1, 0.0], atol=1e-9)  # u = 1 m/s for 0.1 s
    a = img.image()
    assert (a.astype(int).sum(axis=2) >= 3 * 250).any()  # the newest streak dots are white


def test_vorticity_map_and_side_by_side_and_bad_input():
    f = _fluid()
    a = FluidImage(f, "vorticity").image()
    both = side_by_side([a, a], gap=2)
    assert both.shape == (a.shape[0], 2 * a.shape[1] + 2, 3)
    with pytest.raises(ValueError, match="quantity"):
        FluidImage(f, "pressure")
    with pytest.raises(ValueError, match="pixels_per_cell"):
        FluidImage(f, "density", pixels_per_cell=0)
