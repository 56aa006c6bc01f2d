"""A state file's model drawn: bodies moved by body_q, cloth surfaces, spring lines."""

from __future__ import annotations

import math

import numpy as np
import pytest

from inertia.io.states import States
from inertia.render import Camera, Renderer, render_states
from inertia.render.drawables import TRAIL_OPACITY, ModelDrawables, frame_options, trail_lines


def _states(frames=3, *, model, body_q=None, positions=None):
    positions = np.zeros((frames, 0, 3)) if positions is None else positions
    fields = {} if body_q is None else {"body_q": body_q}
    states = States(times=np.arange(frames) / 10.0, positions=positions, fields=fields, metadata={"fps": 10.0})
    states.model = model  # the contract's States.model (core-world adds the attribute)
    return states


def _box_model():
    return {
        "shape_type": np.array([6, 1], np.int32), "shape_body": np.array([-1, 0], np.int32),
        "shape_local_pose": np.array([[0, 0, 0, 1.0, 0, 0, 0], [0, 0, 0, 1.0, 0, 0, 0]]),
        "shape_params": np.array([[0, 0, 0, 0], [0.3, 0.3, 0.3, 0.0]]),
        "shape_color": np.array([[0.5, 0.5, 0.5], [1.0, 0.1, 0.1]], np.float32),
    }


def test_bodies_move_with_body_q_and_the_ground_plane_comes_from_the_model():
    # A red box slides along x over three frames; its pixels follow the projected centre.
    xs = [-1.0, 0.0, 1.0]
    body_q = np.array([[[x, 0.0, 0.3, 1.0, 0.0, 0.0, 0.0]] for x in xs])
    states = _states(model=_box_model(), body_q=body_q)
    drawables = ModelDrawables.from_states(states)
    assert len(drawables.planes) == 1 and np.allclose(drawables.planes[0][1], [0, 0, 1])
    camera = Camera(position=(0.0, -6.0, 3.0), target=(0, 0, 0.3), up=(0, 0, 1))
    renderer = Renderer(240, 160, camera=camera)
    images = list(render_states(states, None, renderer=renderer))
    for x, image in zip(xs, images, strict=True):
        red = (image[..., 0].astype(int) - image[..., 2] > 60) & (image[..., 1] < 90)
        ys, cols = np.nonzero(red)
        px, py, _ = camera.project(np.array([[x, 0.0, 0.3]]), 240, 160)
        assert red.sum() > 100
        assert abs(cols.mean() - px[0]) < 3 and abs(ys.mean() - py[0]) < 6
    # Rotating the box 45 degrees about z widens its silhouette by sqrt(2) in a top view.
    top = Camera(position=(0, 0, 8), target=(0, 0, 0), up=(0, 1, 0), projection="orthographic", ortho_height=3.0)
    widths = []
    for q in ([1.0, 0, 0, 0], [math.cos(math.pi / 8), 0, 0, math.sin(math.pi / 8)]):
        frame = drawables.frame(None, np.array([[0.0, 0.0, 0.3, *q]]))
        r = Renderer(300, 300, camera=top, shadows=False)
        image = r.frame(np.zeros((0, 3)), **frame)
        red = (image[..., 0].astype(int) - image[..., 2] > 60)
        widths.append(np.count_nonzero(red[150]))
    assert widths[1] / widths[0] == pytest.approx(math.sqrt(2), rel=0.03)


def test_cloth_is_a_surface_and_springs_are_lines():
    # A 5 x 5 sheet of particles and a 3-particle rope: surface triangles hide the sheet's particles;
    # the rope's springs are lines, the sheet's springs are shown by its surface (no lines).
    n = 5
    g = np.stack(np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n), indexing="ij"), -1).reshape(-1, 2)
    sheet = np.concatenate([g, np.full((n * n, 1), 0.5)], axis=1)
    rope = np.array([[1.5, -1.0, 0.5], [1.5, 0.0, 0.5], [1.5, 1.0, 0.5]])
    pos = np.concatenate([sheet, rope])[None].repeat(2, axis=0)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    tris = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    rope_springs = np.array([[n * n, n * n + 1], [n * n + 1, n * n + 2]])
    springs = np.concatenate([np.stack([a, a + 1], 1), np.stack([a, a + n], 1), rope_springs])
    states = _states(2, model={"surface_triangles": tris, "spring_pairs": springs}, positions=pos)
    drawables = ModelDrawables.from_states(states)
    np.testing.assert_array_equal(drawables.spring_pairs, rope_springs)
    options = frame_options(drawables, states, 0, None)
    assert not options["active"][: n * n].any()  # every sheet particle is a cloth vertex
    assert options["active"][n * n:].all()       # the rope's particles stay spheres
    assert len(options["meshes"]) == 1 and len(options["lines"]) == 1
    top = Camera(position=(0, 0, 8), target=(0, 0, 0), up=(0, 1, 0), projection="orthographic", ortho_height=4.0)
    image = Renderer(200, 200, camera=top, shadows=False).frame(pos[0], radius=0.05, **options)
    # The sheet covers [-1, 1]^2 = a quarter of the 4 x 4 view, in the cloth colour (reddish).
    cloth = (image[..., 0].astype(int) - image[..., 2] > 40)
    assert cloth.sum() == pytest.approx(200 * 200 / 4, rel=0.05)


def test_trails_follow_each_particle_back_in_time_and_fade():
    # Two particles moving at constant velocity; a respawned (teleported) one breaks its trail.
    frames = 8
    t = np.arange(frames)[:, None]
    a = np.concatenate([0.1 * t, 0 * t, 0 * t + 1.0], axis=1)
    b = np.concatenate([0 * t, 0.1 * t, 0 * t + 1.0], axis=1)
    b[5:] += 50.0  # a jump at frame 5 (respawn)
    pos = np.stack([a, b], axis=1)
    states = States(times=np.arange(frames) / 10.0, positions=pos, metadata={"fps": 10.0})
    lines = trail_lines(states, 7, 4)
    # Frames 3..7: particle 0 has 4 segments; particle 1 loses its 4 -> 5 segment.
    assert lines.pairs.shape == (7, 2)
    seg = lines.points[lines.pairs]
    lengths = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    assert np.allclose(lengths, 0.1)
    # Opacity grows towards the present: the newest segment is the most opaque.
    ends = lines.points[lines.pairs[:, 1]]
    newest = lines.opacity[np.flatnonzero(np.all(np.isclose(ends, a[7]), axis=1))[0]]
    assert newest == pytest.approx(TRAIL_OPACITY) and lines.opacity.min() == pytest.approx(TRAIL_OPACITY / 4)
    assert trail_lines(states, 0, 4) is None
    with pytest.raises(ValueError, match="trails"):
        list(render_states(states, None, trails=-1))


def test_scene_collider_rows_are_left_to_the_colliders_and_a_terrain_sets_the_ground_level():
    """Rows a scene collider added (shape_source >= 0: a container's walls) are not drawn as planes
    (the collider draws itself, cut away); a static heightfield puts the ground grid at its lowest
    point, so the terrain rests on it."""
    from inertia.model import ModelBuilder
    from inertia.world import World, model_file_arrays
    import inertia.colliders as C

    b = ModelBuilder()
    heights = np.array([[0.3, 0.5, 0.4], [0.2, 0.6, 0.35], [0.45, 0.25, 0.5]])
    b.add_heightfield(heights, (1.0, 1.0), position=(0.0, 0.0, 1.0))
    world = World(dt=0.01, model=b.finalize(), colliders=[C.Container(center=(0, 0, 1), half_extents=(2, 2, 2))])
    model = model_file_arrays(world)
    assert np.count_nonzero(model["shape_source"] >= 0) == 6  # the container's six wall rows
    drawables = ModelDrawables(model)
    assert drawables.planes == []                                   # walls left to the container
    assert drawables.heightfield_floor() == pytest.approx(1.0 + heights.min())
    assert len(ModelDrawables(model, include_collider_rows=True).planes) == 6


def test_vehicle_wheels_are_closed_cylinders_at_the_recorded_wheel_poses():
    """Each recorded wheel is a closed cylinder (every edge shared by two triangles, outward normals)
    of the wheel's radius, centred on its recorded pose with its axle along the chassis's y."""
    turn = [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)]  # chassis turned 90 deg about z
    pose = np.array([[[1.0, 2.0, 0.4, *turn], [-1.0, 2.0, 0.4, *turn]]])
    drawables = ModelDrawables({"vehicle/0/wheel_radius": np.array([0.4, 0.4])})
    [mesh] = drawables.wheels({"vehicle/0/wheel_pose": pose}, 0)
    v, n, t = mesh.vertices, mesh.normals, mesh.triangles
    half = v.shape[0] // 2
    for wheel, centre in ((slice(0, half), pose[0, 0, :3]), (slice(half, None), pose[0, 1, :3])):
        rel = v[wheel] - centre
        # axle along the turned chassis's y = world -x: the rim is a circle of radius 0.4 in the y-z plane
        assert np.abs(rel[:, 0]).max() == pytest.approx(0.12, abs=1e-9)       # half of 0.6 x radius
        assert np.hypot(rel[:, 1], rel[:, 2]).max() == pytest.approx(0.4, abs=1e-9)
    # caps and sides have their own vertices (flat shading): weld them by position before counting edges
    _, weld = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    tw = weld.ravel()[t]
    edges = np.sort(np.concatenate([tw[:, [0, 1]], tw[:, [1, 2]], tw[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)
    centroid = v[t].mean(axis=1)
    normal = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    wheel_centre = np.where((t[:, 0] < half)[:, None], pose[0, 0, :3], pose[0, 1, :3])
    assert np.all(np.einsum("ij,ij->i", normal, centroid - wheel_centre) > 0)  # wound outward
