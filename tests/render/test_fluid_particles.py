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
    # particles, not the liquid surface (the default where scikit-image is installed)
    render = {"width": 320, "height": 160, "camera": {"target": [0.0, 0.5], "height": 3.0}, "fluid_surface": False}
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


# ----------------------------------------------------------------------------- 3-D smoke in runs
def _smoke_states(with_smoke=True):
    # A 12^3 grid on [0, 0.6]^3 (h = 0.05): frame 0 empty, frame 1 a ball of smoke (radius 0.2)
    # at the centre; 3-D, no particles.
    n, h = 12, 0.05
    g = (np.arange(n) + 0.5) * h
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    ball = ((x - 0.3) ** 2 + (y - 0.3) ** 2 + (z - 0.3) ** 2 <= 0.2 ** 2).astype(np.float32)
    density = np.stack([np.zeros_like(ball), ball if with_smoke else np.zeros_like(ball)])
    fields = {"fluid/smoke/density": density, "fluid/smoke/speed": np.zeros_like(density)}
    return States(np.array([0.0, 0.1]), np.zeros((2, 0, 3)), fields=fields,
                  model={"fluid/smoke/origin": np.zeros(3), "fluid/smoke/cell_size": np.array(h)},
                  metadata={"dim": 3})


def test_3d_smoke_is_ray_marched_into_run_frames_behind_opaque_colliders():
    import inertia.colliders as C

    from inertia.render.fluid_particles import volume_fluids

    # camera on -y looking at the ball's centre; a solid sphere collider between them covers the
    # middle of the ball of smoke
    render = {"width": 96, "height": 72, "camera": {"position": [0.3, -1.5, 0.3], "target": [0.3, 0.3, 0.3]}}
    blocker = [C.Sphere(center=(0.3, -0.6, 0.3), radius=0.05)]
    smoky, clear = _smoke_states(True), _smoke_states(False)
    assert volume_fluids(smoky) == ["smoke"]
    a = dict(render_frames(smoky, render, blocker))
    b = dict(render_frames(clear, render, blocker))
    assert np.array_equal(a[0], b[0])                          # an empty grid changes no byte
    r = renderer_for(smoky, render, blocker)
    px, py, _ = r.camera.project(np.array([[0.3, 0.3, 0.3], [0.3 + 0.14, 0.3, 0.3], [0.3, -0.6, 0.3]]), 96, 72)
    centre, side, block = [(int(py[k]), int(px[k])) for k in range(3)]
    assert np.abs(a[1][side].astype(int) - b[1][side]).max() > 20   # smoke drawn over the background
    assert np.array_equal(a[1][block], b[1][block])                  # the sphere in front hides it
    assert centre == block


def test_3d_smoke_frames_the_camera_on_the_smoke():
    from inertia.render.fluid_particles import frame_volumes

    s = _smoke_states(True)
    r = renderer_for(s, {"width": 96, "height": 72})
    frame_volumes(r, s)
    # the ball's 99th-percentile density is 1: cells above 2 % of it span [0.1, 0.5]^3 (whole cells)
    lo, hi = r.bounds
    assert np.allclose(lo, 0.1) and np.allclose(hi, 0.5)
    px, py, depth = r.camera.project(np.array([[0.3, 0.3, 0.3]]), 96, 72)
    assert depth[0] > 0 and abs(px[0] - 48) < 10 and abs(py[0] - 36) < 10
    # an orbiting camera keeps turning over the run with smoke alone (the box is framed per frame)
    r = renderer_for(s, {"width": 96, "height": 72, "camera": {"orbit": 40.0}})
    frame_volumes(r, s, (), {"camera": {"orbit": 40.0}})
    a, b = r.camera_at(0.0), r.camera_at(0.1)
    turn = np.degrees(np.arccos(np.dot(*(np.delete(c.position - c.target, 2) / np.linalg.norm(np.delete(c.position - c.target, 2))
                                          for c in (a, b)))))
    assert abs(turn - 40.0) < 1e-6


# ----------------------------------------------------------------------------- liquid surfaces
def _liquid_states(dim):
    # A particle liquid filling the lower half of a 1 m box (level set phi = y - 0.5, or z - 0.5):
    # its particles recorded as fluid/water/x, v and its level set as fluid/water/phi.
    n, h = 8, 0.125
    c = (np.arange(n) + 0.5) * h
    grids = np.meshgrid(*([c] * dim), indexing="ij")
    phi = (grids[-1] - 0.5).astype(np.float32)
    pts = np.stack([gg.ravel() for gg in grids], axis=1)
    pts = pts[pts[:, -1] < 0.5].astype(np.float32)
    x = np.stack([pts, pts])
    fields = {"fluid/water/x": x, "fluid/water/v": np.zeros_like(x), "fluid/water/phi": np.stack([phi, phi])}
    return States(np.array([0.0, 0.1]), np.zeros((2, 0, dim)), fields=fields,
                  model={"fluid/water/origin": np.zeros(dim), "fluid/water/cell_size": np.array(h)},
                  metadata={"dim": dim})


def test_2d_liquid_is_filled_below_its_surface():
    from inertia.render.fluid_particles import LIQUID_COLOR, liquid_fluids

    s = _liquid_states(2)
    assert liquid_fluids(s) == ["water"]
    render = {"width": 120, "height": 120, "camera": {"target": [0.5, 0.5], "height": 1.2}}
    (_, image), = list(render_frames(s, render, frames=[1]))
    r = renderer_for(with_fluid_particles(s), render)
    px, py, _ = r.camera.project(np.array([[0.5, 0.3], [0.5, 0.7], [0.5, 0.5 - 0.1]]), 120, 120)
    water, air = image[int(py[0]), int(px[0])], image[int(py[1]), int(px[1])]
    assert np.abs(water.astype(int) - np.round(np.array(LIQUID_COLOR) * 255)).max() <= 1
    assert np.abs(air.astype(int) - np.round(np.array(LIQUID_COLOR) * 255)).max() > 40
    # the filled edge is the phi = 0 line (within one pixel): rows below y = 0.5 are water
    col = image[:, int(px[0])].astype(int)
    is_water = np.abs(col - np.round(np.array(LIQUID_COLOR) * 255)).max(axis=1) <= 1
    surface_row = py[0] - (0.2 / 1.2) * 120  # pixel row of y = 0.5
    assert is_water[int(surface_row) + 3:int(py[0])].all() and not is_water[:int(surface_row) - 1].any()


def test_3d_liquid_is_a_shaded_surface_mesh_instead_of_particles():
    pytest.importorskip("skimage")
    from inertia.render.fluid_particles import LiquidSurfaces

    s = with_fluid_particles(_liquid_states(3))
    liquids = LiquidSurfaces(s)
    options = liquids.apply({"meshes": [], "lines": [], "active": None}, 1)
    assert not options["active"].any()                        # the particles are not drawn
    (mesh,) = options["meshes"]
    v = np.asarray(mesh.vertices)
    top = v[(v[:, 0] > 0.1) & (v[:, 0] < 0.9) & (v[:, 1] > 0.1) & (v[:, 1] < 0.9) & (v[:, 2] > 0.25)]
    # marching cubes of phi = z - 0.5 (linear, so exact): the free surface is the plane z = 0.5
    assert top.shape[0] > 20 and np.allclose(top[:, 2], 0.5, atol=1e-6)
    (_, image), = list(render_frames(_liquid_states(3), {"width": 96, "height": 72}, frames=[1]))
    assert image.std() > 5                                     # something is drawn


# ----------------------------------------------------------------------------- 2-D grids: streaks, particles over the map
def test_cylinder_scene_run_draws_tracer_streaks_over_the_speed_map(tmp_path):
    # examples/fluid_cylinder_2d.toml cut to a 32 x 8 grid and 0.3 s: the run records u, v and the
    # cylinder's cells; the frames drawn with [render] streaks = 400 differ from those with 0 only
    # by lighter pixels (white streaks laid over the map) inside the channel, and not on the cylinder.
    import json
    import tomllib
    from pathlib import Path

    from inertia.io import load_states
    from inertia.render.fluid_particles import frame_grids
    from inertia.scene import build, parse_scene
    from inertia.world import Run

    scene = Path(__file__).parents[2] / "examples" / "fluid_cylinder_2d.toml"
    data = tomllib.loads(scene.read_text())
    data["fluids"]["channel"].update(shape=[32, 8], cell_size=0.125)
    data["simulation"]["duration"] = 0.3
    assert data["render"]["streaks"] == 400
    world = build(parse_scene(json.dumps(data), format="json", source="fluid_cylinder_2d (tiny)"))
    states = load_states(Run(world, tmp_path, duration=0.3, fps=20.0, handle_sigint=False).execute().states_path)
    assert states.fields["fluid/channel/u"].shape == (7, 32, 8)
    assert states.fields["fluid/channel/solid"][0].sum() > 0                 # the cylinder's cells
    render = dict(data["render"], width=320, height=100)
    with_streaks = dict(render_frames(states, render, world.colliders))
    without = dict(render_frames(states, dict(render, streaks=0), world.colliders))
    again = dict(render_frames(states, render, world.colliders, frames=[6]))
    assert np.array_equal(again[6], with_streaks[6])                          # same image, bit for bit
    a, b = with_streaks[6].astype(int), without[6].astype(int)
    changed = np.any(a != b, axis=2)
    assert changed.sum() > 200
    assert np.all(a[changed].sum(axis=1) >= b[changed].sum(axis=1))          # streaks only lighten
    r = renderer_for(with_fluid_particles(states), render, world.colliders)
    frame_grids(r, with_fluid_particles(states))
    (x0, x1), (y1, y0), _ = r.camera.project(np.array([[0.0, 0.0], [4.0, 1.0]]), 320, 100)
    ys, xs = np.nonzero(changed)
    assert xs.min() >= np.floor(x0) and xs.max() <= np.ceil(x1) and ys.min() >= np.floor(y0) and ys.max() <= np.ceil(y1)
    cx, cy, _ = r.camera.project(np.array([[0.8, 0.52]]), 320, 100)
    assert not changed[int(cy[0]), int(cx[0])]                                # the cylinder is not painted
    assert np.array_equal(with_streaks[0], without[0])                        # frame 0: fresh tracers, no streak yet


def test_particles_of_the_frame_are_drawn_over_a_grid_map():
    # A 2-D run with a 4 x 4 speed grid on [0, 1]^2 (all at the top of the map) and one particle
    # group: the particle at the grid's centre keeps its own colour, the map shows around it.
    speed = np.ones((1, 4, 4), np.float32)
    pos = np.array([[[0.5, 0.5]]])
    s = States(np.array([0.0]), pos, np.zeros_like(pos), fields={"fluid/lid/speed": speed},
               static={"radius": np.array([0.1])}, metadata={"dim": 2, "groups": ["ball"]},
               model={"fluid/lid/origin": np.zeros(2), "fluid/lid/cell_size": np.array(0.25)})
    render = {"width": 200, "height": 200, "color_by": "uniform", "camera": {"target": [0.5, 0.5], "height": 1.2}}
    (_, image), = list(render_frames(s, render, frames=[0]))
    r = renderer_for(with_fluid_particles(s), render)
    px, py, _ = r.camera.project(np.array([[0.5, 0.5], [0.9, 0.9]]), 200, 200)
    centre, corner = (image[int(py[k]), int(px[k])].astype(float) for k in (0, 1))
    top = np.asarray(colormap(DEFAULT_SPEED_MAP, np.array([1.0]), vmin=0.0, vmax=1.0))[0, :3] * 255
    assert np.abs(corner - top).max() <= 1                                    # the map around the particle
    assert np.abs(centre - top).max() > 40                                    # the particle over it


# ----------------------------------------------------------------------------- SPH surfaces ([render] fluid_surface)
def _sph_block_states(dim, n=10, dx=0.02):
    # An SPH fluid recorded as fluid/water/x (a lattice block of n^dim particles, one spare dead row)
    # with its spacing and smoothing length (SPHFluid.static_arrays).
    g = (np.arange(n) + 0.5) * dx + 0.1
    pts = np.stack(np.meshgrid(*([g] * dim), indexing="ij"), -1).reshape(-1, dim)
    x = np.concatenate([pts, np.full((1, dim), np.nan)]).astype(np.float32)[None]
    alive = np.concatenate([np.ones(len(pts), bool), [False]])[None]
    return States(np.array([0.0]), np.zeros((1, 0, dim)),
                  fields={"fluid/water/x": x, "fluid/water/v": np.zeros_like(x), "fluid/water/active": alive},
                  model={"fluid/water/spacing": np.array([dx]), "fluid/water/smoothing_length": np.array([dx])},
                  metadata={"dim": dim})


def test_sph_surface_option_round_trips_from_a_scene_file(tmp_path):
    from inertia.scene import read_scene

    path = tmp_path / "dam.toml"
    path.write_text('format_version = 1\n[simulation]\ndim = 2\n[sph.water]\nspacing = 0.02\n'
                    'domain = [[0, 0], [0.8, 0.6]]\nfluid = [{ box = [[0, 0], [0.2, 0.4]] }]\n'
                    '[render]\nfluid_surface = true\nstreaks = 50\nstreak_length = 4\n')
    render = read_scene(path).model.render
    assert render.fluid_surface is True and render.streaks == 50 and render.streak_length == 4
    dumped = render.model_dump(mode="json")
    assert dumped["fluid_surface"] is True
    path.write_text(path.read_text().replace("fluid_surface = true", "fluid_surface = 1"))
    with pytest.raises(Exception, match="fluid_surface"):
        read_scene(path)


def test_2d_sph_fluid_is_filled_as_its_smoothed_surface_when_asked():
    """fluid_surface = false draws the particles; true fills the liquid; unset is the surface when
    scikit-image is installed (the default a user sees)."""
    from inertia.render.fluid_particles import LIQUID_COLOR

    s = _sph_block_states(2)
    render = {"width": 200, "height": 200, "color_by": "uniform", "camera": {"target": [0.2, 0.2], "height": 0.4}}
    (_, plain), = list(render_frames(s, dict(render, fluid_surface=False), frames=[0]))
    (_, filled), = list(render_frames(s, dict(render, fluid_surface=True), frames=[0]))
    r = renderer_for(with_fluid_particles(s), render)
    fill = np.round(np.array(LIQUID_COLOR) * 255)
    # the gap between four particles (x = 0.1 + 3 dx) is background without the option, liquid with it
    gx, gy, _ = r.camera.project(np.array([[0.16, 0.16], [0.2, 0.2]]), 200, 200)
    assert np.abs(filled[int(gy[0]), int(gx[0])].astype(int) - fill).max() <= 1
    assert np.abs(plain[int(gy[0]), int(gx[0])].astype(int) - fill).max() > 20
    # the filled region is the block [0.1, 0.3]^2 (its c = 1/2 line) to within two pixels (1 px = 2 mm)
    px, _, _ = r.camera.project(np.array([[0.1, 0.2], [0.3, 0.2]]), 200, 200)
    row = np.abs(filled[int(gy[1])].astype(int) - fill).max(axis=1) <= 1
    cols = np.flatnonzero(row)
    assert abs(cols.min() - px[0]) <= 2 and abs(cols.max() + 1 - px[1]) <= 2


def test_3d_sph_fluid_is_a_surface_mesh_enclosing_the_block_when_asked():
    pytest.importorskip("skimage")
    from inertia.render.fluid_particles import LiquidSurfaces

    s = with_fluid_particles(_sph_block_states(3))
    assert LiquidSurfaces(s).names == []                                     # not asked: particles
    liquids = LiquidSurfaces(s, sph=True)
    options = liquids.apply({"meshes": [], "lines": [], "active": None}, 0)
    assert not options["active"].any()
    (mesh,) = options["meshes"]
    v, t = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    a, b, c = (v[t[:, k]] for k in range(3))
    volume = abs(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
    L, h = 0.2, 0.02
    # the block's volume less its rounded edges, within the smoothing bound of tests/fluids/sph/test_surface.py
    assert 0 < L**3 - volume < 12 * L * (1 - np.pi / 4) * (2 * h) ** 2
    (_, image), = list(render_frames(_sph_block_states(3), {"width": 96, "height": 72, "fluid_surface": True}, frames=[0]))
    assert image.std() > 5
