"""SPH fluid particles in rendered runs (inertia.render.fluid_particles): merged after the groups'
particles with their speed, active mask and radius; drawn coloured by speed with a colour bar."""

import numpy as np
import pytest

from inertia.cli.outputs import render_frames, renderer_for
from inertia.io.states import States
from inertia.render.colormaps import DEFAULT_SPEED_MAP, colormap
from inertia.render.fluid_particles import particle_fluids, speed_colorbar, with_fluid_particles


def _states():
    frames = 2
    pos = np.zeros((frames, 1, 2)); pos[:, 0] = [0.0, 1.0]        # one group particle at rest
    x = np.zeros((frames, 3, 2), np.float32); x[:, :, 0] = [-1.0, 1.0, 5.0]
    v = np.zeros((frames, 3, 2), np.float32); v[:, 1, 0] = 2.0      # the second fluid particle moves
    alive = np.array([[True, True, False]] * frames)                 # the third row is a dead slot
    return States(np.array([0.0, 0.1]), pos, np.zeros_like(pos),
                  fields={"fluid/water/x": x, "fluid/water/v": v, "fluid/water/active": alive},
                  static={"radius": np.array([0.05]), "group": np.array([0])},
                  metadata={"dim": 2, "groups": ["balls"]}, model={"fluid/water/spacing": np.array([0.2])})


def test_fluid_particles_follow_the_groups():
    s = with_fluid_particles(_states())
    assert particle_fluids(s) == ["water"]
    assert s.positions.shape == (2, 4, 2) and s.velocities.shape == (2, 4, 2)
    assert np.array_equal(s.positions[1, 1:, 0], [-1.0, 1.0, 5.0])
    assert np.array_equal(s.active(0), [True, True, True, False])
    assert np.allclose(s.radius(), [0.05, 0.1, 0.1, 0.1])          # half the spacing
    assert s.groups() is None                                          # colour by speed, not by group


def test_frames_colour_the_fluid_by_speed_and_carry_a_colour_bar():
    s = _states()
    render = {"width": 320, "height": 160, "camera": {"target": [0.0, 0.5], "height": 3.0}}
    (_, image), = list(render_frames(s, render, frames=[0]))
    merged = with_fluid_particles(s)
    from inertia.cli.outputs import renderer_for
    r = renderer_for(merged, render)
    cam = r.camera
    def pixel(p):
        sx, sy = cam.project(np.array([p[0], p[1], 0.0]), r.width, r.height)[:2]
        return image[int(round(sy)), int(round(sx))].astype(float)
    slow, fast = pixel((-1.0, 0.0)), pixel((1.0, 0.0))
    lo, hi = (np.asarray(colormap(DEFAULT_SPEED_MAP, np.array([t]), vmin=0.0, vmax=1.0))[0, :3] * 255 for t in (0.0, 1.0))
    # Shading changes brightness, not hue much: each disc is nearer its end of the map than the other end.
    assert np.linalg.norm(slow - lo) < np.linalg.norm(slow - hi)
    assert np.linalg.norm(fast - hi) < np.linalg.norm(fast - lo)


def test_colour_bar_runs_through_the_speed_map():
    bar = speed_colorbar(2.0, frame_height=540)
    assert bar.ndim == 3 and bar.shape[2] == 4 and bar.shape[1] > 100
    with pytest.raises(ValueError, match="vmax"):
        speed_colorbar(0.0)


def test_recorded_2d_grid_is_painted_the_right_way_up():
    # A 4 x 4 grid on [0, 1]^2 whose top row (j = 3) moves at 1 m/s and the rest rests: the top
    # quarter of the painted square takes the speed map's top colour, the bottom its bottom colour.
    speed = np.zeros((1, 4, 4), np.float32)
    speed[0, :, 3] = 1.0
    s = States(np.array([0.0]), np.zeros((1, 0, 3)), fields={"fluid/lid/speed": speed},
               model={"fluid/lid/origin": np.zeros(2), "fluid/lid/cell_size": np.array(0.25)})
    (_, image), = list(render_frames(s, {"width": 200, "height": 200}, frames=[0]))
    r = renderer_for(with_fluid_particles(s), {"width": 200, "height": 200})
    from inertia.render.fluid_particles import frame_grids
    frame_grids(r, with_fluid_particles(s))
    px, py, _ = r.camera.project(np.array([[0.5, 0.875], [0.5, 0.125]]), 200, 200)
    top, bottom = (image[int(py[k]), int(px[k])].astype(float) for k in (0, 1))
    lo, hi = (np.asarray(colormap(DEFAULT_SPEED_MAP, np.array([t]), vmin=0.0, vmax=1.0))[0, :3] * 255 for t in (0.0, 1.0))
    assert np.abs(top - hi).max() <= 1 and np.abs(bottom - lo).max() <= 1
