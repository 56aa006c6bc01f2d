"""The rasterizer: where things land on screen, occlusion, colours, colliders, determinism."""

from __future__ import annotations

import sys
from pathlib import Path

import numba
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from render_scenes import colliders_3d, random_cloud  # noqa: E402

import inertia.render.renderer as renderer_module  # noqa: E402
from inertia.render import Camera, Renderer, colormap, parse_color  # noqa: E402
from inertia.render.renderer import THEMES  # noqa: E402

W, H = 160, 120


def _front_camera(distance=4.0):
    # Looking along +y at the origin from y = -distance, z up: world x -> screen right.
    return Camera(position=(0.0, -distance, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov_y=40.0)


def _pixel(image, world, camera):
    px, py, _ = camera.project(np.atleast_2d(world), image.shape[1], image.shape[0])
    return image[int(py[0]), int(px[0])].astype(int)


def test_a_particle_lands_where_the_camera_projects_it():
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False, color_by="uniform", color="#ff0000")
    point = np.array([[0.5, 0.0, 0.3]])
    image = renderer.frame(point, radius=0.1)
    centre = _pixel(image, point, camera)
    assert centre[0] > 150 and centre[1] < 60 and centre[2] < 60  # lit red
    far_corner = image[2, 2].astype(int)
    assert abs(far_corner[0] - far_corner[2]) < 40  # sky, not red


def test_nearer_particle_hides_the_farther_one_in_any_order():
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False)
    points = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])  # second is nearer the eye
    colors = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    a = renderer.frame(points, radius=0.2, colors=colors)
    b = renderer.frame(points[::-1], radius=0.2, colors=colors[::-1])
    assert _pixel(a, points[1], camera)[0] > 120 and _pixel(a, points[1], camera)[2] < 80
    np.testing.assert_array_equal(a, b)


def test_intersecting_spheres_cut_each_other_by_per_pixel_depth():
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False)
    # Two big spheres overlapping; on the left the left one bulges nearer, on the right the right one.
    points = np.array([[-0.25, 0.0, 0.0], [0.25, 0.0, 0.0]])
    image = renderer.frame(points, radius=0.4, colors=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    left = _pixel(image, [[-0.3, 0.0, 0.0]], camera)
    right = _pixel(image, [[0.3, 0.0, 0.0]], camera)
    assert left[0] > left[2] and right[2] > right[0]


def test_inactive_and_non_finite_particles_are_not_drawn():
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False, color_by="uniform", color="#00ff00")
    empty = renderer.frame(np.zeros((0, 3)))
    points = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    hidden = renderer.frame(points, radius=0.2, active=np.array([False, True]))
    np.testing.assert_array_equal(hidden, empty)
    shown = renderer.frame(points, radius=0.2, active=np.array([True, True]))
    assert _pixel(shown, points[:1], camera)[1] > 120


def test_speed_colours_use_the_colour_map():
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False, color_by="speed", speed_max=2.0, shadows=False)
    points = np.array([[-0.6, 0.0, 0.0], [0.6, 0.0, 0.0]])
    velocities = np.array([[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    image = renderer.frame(points, radius=0.15, velocities=velocities)
    slow, fast = _pixel(image, points[:1], camera), _pixel(image, points[1:], camera)
    # The default "speed" map (turbo from 0.1 to 0.9): blue at rest, orange-red at the top.
    assert slow[2] > 100 and slow[2] > slow[0] and fast[0] > 90 and fast[0] > fast[1] and fast[0] > 2 * fast[2]
    expected = renderer.particle_colors(2, velocities=velocities)
    np.testing.assert_allclose(expected, colormap("speed", [0.0, 2.0], vmin=0.0, vmax=2.0))
    # Resting particles stay readable on the dark theme: the map's low end is > 1.3 times as
    # bright (Rec. 709 luma of the sRGB values) as the ground; viridis's is under half.
    luma = np.array([0.2126, 0.7152, 0.0722])
    ground = float(np.array(THEMES["dark"]["ground"]) @ luma)
    assert float(colormap("speed", [0.0], vmin=0.0, vmax=1.0)[0] @ luma) > 1.3 * ground
    assert float(colormap("viridis", [0.0], vmin=0.0, vmax=1.0)[0] @ luma) < 0.5 * ground


def test_group_colours_honour_named_group_colours():
    renderer = Renderer(W, H, color_by="group", group_colors=[None, "#000000"])
    colors = renderer.particle_colors(3, groups=np.array([0, 1, 2]))
    np.testing.assert_allclose(colors[1], 0.0)
    np.testing.assert_allclose(colors[0], parse_color("#1f77b4"), atol=1e-3)


def test_colliders_are_drawn_and_particles_cast_contact_shadows():
    import inertia.colliders as C

    camera = Camera.orbit((0.0, 0.0, 0.5), 5.0, azimuth=-90.0, elevation=20.0)
    renderer = Renderer(W, H, camera=camera)
    renderer.bounds = (np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 1.0]))
    sphere = C.Sphere(center=(0.8, 0.0, 0.4), radius=0.35)
    ground = C.Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))
    empty = renderer.frame(np.zeros((0, 3)), colliders=[ground])
    with_sphere = renderer.frame(np.zeros((0, 3)), colliders=[ground, sphere])
    changed = np.abs(with_sphere.astype(int) - empty).max(axis=2) > 8
    px, py, depth = camera.project([[0.8, 0.0, 0.4]], W, H)
    radius_px = camera.focal_px(H) * 0.35 / depth[0]
    rows, cols = np.nonzero(changed)
    # The changed pixels are the sphere's disc (and its silhouette on the ground behind it).
    assert changed.sum() > 0.6 * np.pi * radius_px**2
    assert np.all(np.hypot(cols + 0.5 - px[0], rows + 0.5 - py[0]) < radius_px + 2)
    # A particle resting on the ground darkens the ground next to it.
    ball = np.array([[-0.6, 0.0, 0.1]])
    shaded = renderer.frame(ball, radius=0.1, colliders=[ground])
    probe = [[-0.6, -0.13, 0.0]]
    assert _pixel(shaded, probe, camera).sum() < _pixel(empty, probe, camera).sum() - 10


def test_kinematic_colliders_move_with_time():
    import inertia.colliders as C

    camera = _front_camera()
    moving = C.Sphere(center=(0.0, 0.0, 0.0), radius=0.2, motion=C.Motion(position=lambda t: (t, 0.0, 0.0)))
    renderer = Renderer(W, H, camera=camera, ground=False)
    at0 = renderer.frame(np.zeros((0, 3)), colliders=[moving], t=0.0)
    at1 = renderer.frame(np.zeros((0, 3)), colliders=[moving], t=1.0)
    sky = renderer.frame(np.zeros((0, 3)))
    for image, x_inside, x_outside in ((at0, 0.0, 1.0), (at1, 1.0, 0.0)):
        assert np.abs(_pixel(image, [[x_inside, -0.2, 0.0]], camera) - _pixel(sky, [[x_inside, -0.2, 0.0]], camera)).max() > 20
        np.testing.assert_array_equal(_pixel(image, [[x_outside, -0.2, 0.0]], camera), _pixel(sky, [[x_outside, -0.2, 0.0]], camera))


def test_generic_sdf_colliders_are_traced_in_3d_and_sampled_in_2d():
    import inertia.colliders as C

    blob3 = C.SDF(lambda p: np.linalg.norm(p, axis=1) - 0.3, dim=3)
    camera = _front_camera()
    renderer = Renderer(W, H, camera=camera, ground=False)
    image = renderer.frame(np.zeros((0, 3)), colliders=[blob3])
    sky = renderer.frame(np.zeros((0, 3)))
    assert np.abs(_pixel(image, [[0.0, -0.3, 0.0]], camera) - _pixel(sky, [[0.0, -0.3, 0.0]], camera)).max() > 20
    np.testing.assert_array_equal(image[:5], sky[:5])

    blob2 = C.SDF(lambda p: np.linalg.norm(p - [0.5, 0.0], axis=1) - 0.2, dim=2)
    renderer2 = Renderer(W, H, dim=2, camera=Camera.plane_2d((0.0, 0.0), 2.0))
    image2 = renderer2.frame(np.zeros((0, 2)), colliders=[blob2])
    paper = image2[5, 5].astype(int)
    assert np.abs(_pixel(image2, [[0.5, 0.0]], renderer2.camera) - paper).max() > 30


def test_2d_frames_and_automatic_framing():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(300, 2)) + [10.0, -5.0]
    renderer = Renderer(W, H, dim=2, color_by="uniform", color="#ff7f0e")
    image = renderer.frame(points, radius=0.05)
    assert renderer.camera.projection == "orthographic"
    px, py, _ = renderer.camera.project(points, W, H)
    inside = (px >= 0) & (px < W) & (py >= 0) & (py < H)
    assert inside.mean() > 0.99  # auto-framed on the particles
    orange = (image[..., 0] > 150) & (image[..., 2] < 90)
    assert orange.sum() > 300


def test_same_input_gives_identical_bytes_at_any_thread_count(monkeypatch):
    positions, velocities = random_cloud(25_000)
    colliders = colliders_3d()[:2]

    def render():
        renderer = Renderer(W * 2, H * 2)
        return renderer.frame(positions, radius=0.01, velocities=velocities, colliders=colliders)

    # The parallel builds of every kernel, on all threads and on one.
    for name in ("_PARALLEL_MIN", "_PARALLEL_PIXELS", "_PARALLEL_PARTICLES"):
        monkeypatch.setattr(renderer_module, name, 0)
    threads = numba.get_num_threads()
    first = render()
    try:
        numba.set_num_threads(1)
        single = render()
    finally:
        numba.set_num_threads(threads)
    # The serial builds.
    for name in ("_PARALLEL_MIN", "_PARALLEL_PIXELS", "_PARALLEL_PARTICLES"):
        monkeypatch.setattr(renderer_module, name, 10**12)
    serial = render()
    np.testing.assert_array_equal(first, single)
    np.testing.assert_array_equal(first, serial)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="dim must be 2 or 3"):
        Renderer(dim=4)
    with pytest.raises(ValueError, match="color_by must be one of"):
        Renderer(color_by="temperature")
    renderer = Renderer(W, H)
    with pytest.raises(ValueError, match=r"positions must be \(N, 3\)"):
        renderer.frame(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"colors must be \(2, 3\)"):
        renderer.frame(np.zeros((2, 3)), colors=np.zeros((3, 3)))


def test_camera_fit_keeps_the_box_in_view():
    lower, upper = np.array([-1.0, -2.0, 0.0]), np.array([3.0, 1.0, 0.5])
    camera = Camera.fit(lower, upper, aspect=16 / 9, azimuth=20.0, elevation=40.0)
    corners = np.array([[x, y, z] for x in (lower[0], upper[0]) for y in (lower[1], upper[1]) for z in (lower[2], upper[2])])
    px, py, depth = camera.project(corners, 1600, 900)
    assert np.all(depth > 0) and np.all((px >= 0) & (px <= 1600) & (py >= 0) & (py <= 900))
    # Tight: some corner is near an edge.
    assert min(px.min(), 1600 - px.max(), py.min(), 900 - py.max()) < 80
    moved = camera.with_orbit(azimuth=110.0)
    assert np.allclose(moved.target, camera.target)
    assert np.isclose(np.linalg.norm(moved.position - moved.target), np.linalg.norm(camera.position - camera.target))


def test_an_orbit_turns_the_camera_over_the_run_and_keeps_the_scene_framed():
    # Orbit 90 degrees over times 0..1: at t = 0 the fitted azimuth, at t = 1 azimuth + 90, the
    # elevation kept; every frame's view holds all the points (framed at each key angle).
    rng = np.random.default_rng(3)
    cloud = rng.uniform([-2.0, -0.3, 0.0], [2.0, 0.3, 1.0], (400, 3))
    renderer = Renderer(W, H, orbit=90.0, azimuth=-60.0, elevation=20.0)
    renderer.fit(cloud, times=np.linspace(0.0, 1.0, 11))
    for t, azimuth in ((0.0, -60.0), (0.5, -15.0), (1.0, 30.0)):
        cam = renderer.camera_at(t)
        offset = (cam.position - cam.target) / np.linalg.norm(cam.position - cam.target)
        assert np.degrees(np.arctan2(offset[1], offset[0])) == pytest.approx(azimuth, abs=1e-9)
        assert np.degrees(np.arcsin(offset[2])) == pytest.approx(20.0, abs=1e-9)
        px, py, depth = cam.project(cloud, W, H)
        assert np.all(depth > 0) and np.all((px >= 0) & (px <= W) & (py >= 0) & (py <= H))
    # A camera set by hand after fit wins over the orbit.
    renderer.camera = _front_camera()
    assert renderer.camera_at(0.7) is renderer.camera
    with pytest.raises(ValueError, match="orbit"):
        Renderer(W, H, orbit=float("nan"))


def test_follow_keeps_a_travelling_cloud_large_and_in_view():
    # A ball of points travels 10 m along x over 4 s; framed on the whole run it spans a small
    # part of the picture, followed it spans a large part, at every frame, and never leaves it.
    rng = np.random.default_rng(5)
    ball = rng.normal(size=(300, 3)) * 0.3
    times = np.linspace(0.0, 4.0, 41)
    run = ball[None] + np.stack([np.linspace(-5, 5, 41), np.zeros(41), np.full(41, 1.0)], axis=1)[:, None]
    still = Renderer(W, H)
    still.fit(run, times=times)
    follow = Renderer(W, H, follow=True)
    follow.fit(run, times=times)
    for f in (0, 13, 20, 33, 40):
        widths = []
        for renderer in (still, follow):
            cam = renderer.camera_at(times[f])
            px, py, depth = cam.project(run[f], W, H)
            assert np.all(depth > 0) and np.all((px >= 0) & (px <= W) & (py >= 0) & (py <= H))
            widths.append(px.max() - px.min())
        assert widths[1] > 2.0 * widths[0]
