"""Ray-marched smoke (inertia.render.fluid_volume) against closed forms.

References: Beer-Lambert-Bouguer attenuation T = exp(-sigma_t rho L) for a homogeneous medium
(Max 1995, "Optical models for direct volume rendering", eq. 1-3); the light transmittance
grid of Fedkiw, Stam and Jensen (2001) §5; the camera's pinhole projection (inertia.render.camera).
"""

import numpy as np
import pytest

from inertia.render.camera import Camera
from inertia.render.fluid_volume import (SmokeStyle, composite_smoke, light_transmittance, occupied_box,
                                         render_smoke_linear)

DARK = dict(light_color=(0.0, 0.0, 0.0), ambient=(0.0, 0.0, 0.0))  # no in-scattering: pure extinction


def _top_camera(center, height=1.0, eye_z=5.0):
    c = np.asarray(center, float)
    return Camera(position=np.array([c[0], c[1], eye_z]), target=np.array([c[0], c[1], 0.0]),
                  up=np.array([0.0, 1.0, 0.0]), projection="orthographic", ortho_height=height)


@pytest.mark.parametrize("sigma_t, rho", [(2.0, 0.5), (5.0, 0.4), (0.7, 1.3)])
def test_uniform_slab_transmits_beer_lambert(sigma_t, rho):
    # 16^3 cells of h = 0.1 m filled with rho: every ray crosses L = 1.6 m of smoke (orthographic)
    # and, tilted, L = 1.6 / cos(theta) (perspective, analytic ray-box distance).
    n, h = 16, 0.1
    density = np.full((n, n, n), rho, np.float32)
    bg = np.array([0.7, 0.5, 0.3], np.float32)
    color = np.ascontiguousarray(np.broadcast_to(bg, (40, 40, 3)), dtype=np.float32)
    style = SmokeStyle(sigma_t=sigma_t, **DARK)
    touched = render_smoke_linear(color, _top_camera((0.8, 0.8)), density, origin=(0, 0, 0), cell_size=h,
                                  light_direction=(0, 0, 1), style=style)
    expected = np.exp(-sigma_t * rho * 1.6)
    assert expected > 0.01  # not cut by the early termination
    assert touched.all()
    # brief: within 1e-3; the march is exact up to float32 rounding here (measured 2e-8)
    assert np.max(np.abs(color / bg - expected)) < 1e-5

    # Perspective: the ray through pixel (px, py) enters the top face z = 1.6 and leaves by z = 0.
    cam = Camera(position=np.array([0.8, 0.8, 4.0]), target=np.array([0.8, 0.8, 0.0]), up=np.array([0.0, 1.0, 0.0]),
                 fov_y=12.0)
    color = np.ascontiguousarray(np.broadcast_to(bg, (40, 40, 3)), dtype=np.float32)
    render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=(0, 0, 1), style=style)
    right, up, forward = cam.basis()
    f = cam.focal_px(40)
    for px, py in [(20, 20), (3, 5), (36, 30)]:
        d = forward + (px + 0.5 - 20) / f * right + (20 - (py + 0.5)) / f * up
        d = d / np.linalg.norm(d)
        length = 1.6 / abs(d[2])
        exit_point = cam.position + (4.0 / abs(d[2])) * d
        assert np.all((exit_point[:2] > 0) & (exit_point[:2] < 1.6))  # leaves through the bottom face
        assert abs(color[py, px, 0] / bg[0] - np.exp(-sigma_t * rho * length)) < 1e-5


def test_opaque_surface_stops_the_march_at_its_depth():
    # A depth buffer 0.5 m into the slab: the ray sees 0.5 m of smoke, T = exp(-sigma rho 0.5);
    # a surface in front of the smoke leaves its pixels untouched.
    n, h, sigma_t, rho = 16, 0.1, 3.0, 1.0
    density = np.full((n, n, n), rho, np.float32)
    color = np.ones((20, 20, 3), np.float32)
    depth = np.full((20, 20), 5.0 - 1.6 + 0.5, np.float32)  # eye at z = 5, top of the smoke at z = 1.6
    depth[:, :10] = 1.0                                      # left half: a wall in front of the smoke
    touched = render_smoke_linear(color, _top_camera((0.8, 0.8)), density, origin=(0, 0, 0), cell_size=h,
                                  light_direction=(0, 0, 1), style=SmokeStyle(sigma_t=sigma_t, **DARK), depth=depth)
    assert not touched[:, :10].any() and np.all(color[:, :10] == 1.0)
    assert np.max(np.abs(color[:, 10:] - np.exp(-sigma_t * rho * 0.5))) < 1e-3


def _sphere_density(n, h, center, radius, rho):
    g = (np.arange(n) + 0.5) * h
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    inside = (x - center[0]) ** 2 + (y - center[1]) ** 2 + (z - center[2]) ** 2 <= radius ** 2
    return np.where(inside, rho, 0.0).astype(np.float32), (x, y, z)


def test_light_transmittance_grid_is_beer_lambert_towards_the_light():
    # A ball of constant density, light along +x: from a cell centre at p inside, the light
    # crosses d = sqrt(R^2 - (y-cy)^2 - (z-cz)^2) - (x - cx) of smoke, T = exp(-sigma rho d).
    # Trilinear sampling smears the ball's edge over one cell (a ramp of width h whose midpoint
    # samples err by up to h/2): d is matched within 0.6 h (measured 0.45 h).
    n, h, radius, rho, sigma_t = 24, 0.05, 0.4, 0.8, 4.0
    c = np.array([0.6, 0.6, 0.6])
    density, (x, y, z) = _sphere_density(n, h, c, radius, rho)
    box = np.zeros(6, np.int64)
    assert occupied_box(density, 0.0, box)
    transmit = np.empty_like(density)
    light_transmittance.serial(density, np.zeros((1, 1, 1), np.uint8), box, h, np.array([1.0, 0.0, 0.0]), sigma_t, transmit)
    q = radius ** 2 - (y - c[1]) ** 2 - (z - c[2]) ** 2
    deep = (density > 0) & (q > (2 * h) ** 2)
    d = np.sqrt(q[deep]) - (x[deep] - c[0])
    measured = -np.log(transmit[deep]) / (sigma_t * rho)
    assert deep.sum() > 500
    assert np.max(np.abs(measured - d)) < 0.6 * h
    # cells beyond the ball on the far side from the light are shadowed by a full chord
    assert transmit.min() < np.exp(-sigma_t * rho * (2 * radius - 2 * h))


def test_ball_of_smoke_is_brighter_on_its_lit_side():
    # Side view (camera on -y looking +y), light from +x: the +x half of the ball scatters more
    # (T_light near 1) than the -x half (T_light ~ exp(-sigma rho 2R) ~ 0.04): measured 3.8x.
    n, h, radius, rho = 24, 0.05, 0.4, 1.0
    c = np.array([0.6, 0.6, 0.6])
    density, _ = _sphere_density(n, h, c, radius, rho)
    cam = Camera(position=np.array([0.6, -3.0, 0.6]), target=c, up=np.array([0.0, 0.0, 1.0]), fov_y=22.0)
    w = hgt = 64
    color = np.zeros((hgt, w, 3), np.float32)
    style = SmokeStyle(sigma_t=4.0, light_color=(1.0, 1.0, 1.0), ambient=(0.05, 0.05, 0.05))
    touched = render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=(1, 0, 0),
                                  style=style)
    px, py, _ = cam.project(c[None], w, hgt)
    cx, cy = int(px[0]), int(py[0])
    left = color[cy - 4:cy + 4, cx - 14:cx - 6, 0].mean()   # -x side (screen left)
    right = color[cy - 4:cy + 4, cx + 6:cx + 14, 0].mean()  # +x side, facing the light
    assert touched[cy, cx - 10] and touched[cy, cx + 10]
    assert right > 2.0 * left


def test_empty_grid_leaves_the_image_bit_for_bit():
    rng = np.random.default_rng(3)
    image = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    before = image.copy()
    composite_smoke(image, _top_camera((0.4, 0.4)), np.zeros((8, 8, 8), np.float32), origin=(0, 0, 0), cell_size=0.1,
                    light_direction=(0, 0, 1))
    assert np.array_equal(image, before)
    # smoke outside the view also leaves every byte
    far = np.zeros((8, 8, 8), np.float32)
    far[0, 0, 0] = 1.0
    composite_smoke(image, _top_camera((40.0, 40.0)), far, origin=(0, 0, 0), cell_size=0.1, light_direction=(0, 0, 1))
    assert np.array_equal(image, before)


def test_small_dense_blob_appears_where_the_camera_projects_it():
    # One dense cell (trilinear: a symmetric tent two cells wide) seen by a perspective camera
    # from an oblique angle: the opacity-weighted centroid of the drawn pixels is the projection
    # of the cell centre within 1 px (the brief's bound; measured 0.02 px).
    n, h = 16, 0.05
    density = np.zeros((n, n, n), np.float32)
    i, j, k = 11, 4, 7
    density[i, j, k] = 50.0
    centre = (np.array([i, j, k]) + 0.5) * h
    cam = Camera.orbit(np.array([0.4, 0.4, 0.4]), 2.0, azimuth=-60.0, elevation=25.0, fov_y=40.0)
    w, hgt = 160, 120
    color = np.zeros((hgt, w, 3), np.float32)
    style = SmokeStyle(sigma_t=10.0, light_color=(0.0, 0.0, 0.0), ambient=(1.0, 1.0, 1.0), albedo=(1, 1, 1), step=0.1)
    render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=(0, 0, 1), style=style)
    alpha = color[..., 0].astype(np.float64)  # = opacity (white smoke, white ambient, black background)
    assert alpha.max() > 0.3
    ys, xs = np.mgrid[0:hgt, 0:w] + 0.5
    cx, cy = (alpha * xs).sum() / alpha.sum(), (alpha * ys).sum() / alpha.sum()
    px, py, _ = cam.project(centre[None], w, hgt)
    assert abs(cx - px[0]) < 1.0 and abs(cy - py[0]) < 1.0


def test_temperature_glows_and_bad_input_is_named():
    n, h = 8, 0.1
    density = np.full((n, n, n), 0.3, np.float32)
    temperature = np.zeros_like(density)
    temperature[:, :, 4:] = 1.0
    cold, hot = np.zeros((20, 20, 3), np.float32), np.zeros((20, 20, 3), np.float32)
    cam = Camera(position=np.array([0.4, -3.0, 0.4]), target=np.array([0.4, 0.4, 0.4]), up=np.array([0.0, 0.0, 1.0]),
                 fov_y=20.0)
    style = SmokeStyle(emission=3.0, temperature_range=(0.0, 1.0))
    render_smoke_linear(cold, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=(0, 0, 1), style=style)
    render_smoke_linear(hot, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=(0, 0, 1), style=style,
                        temperature=temperature)
    assert hot[4, 10, 0] > cold[4, 10, 0] + 0.5   # top half (hot) glows red
    assert abs(hot[16, 10, 0] - cold[16, 10, 0]) < 0.05
    with pytest.raises(ValueError, match="sigma_t"):
        SmokeStyle(sigma_t=-1.0)
    with pytest.raises(ValueError, match="density"):
        render_smoke_linear(cold, cam, np.zeros((4, 4)), origin=(0, 0, 0), cell_size=h, light_direction=(0, 0, 1))
    with pytest.raises(ValueError, match="cell_size"):
        render_smoke_linear(cold, cam, density, origin=(0, 0, 0), cell_size=0.0, light_direction=(0, 0, 1))


def test_an_opaque_obstacle_shadows_the_smoke_behind_it_from_the_light():
    # Uniform smoke, light straight down (+z towards the light), a solid 2 x 2 x 2 cell block in the
    # middle: the cells under it are in full shadow, the cells beside it keep Beer-Lambert
    # exp(-sigma rho d) to the top of the box (d = distance from the cell centre to the top face).
    n, h, rho, sigma_t = 12, 0.1, 0.5, 2.0
    density = np.full((n, n, n), rho, np.float32)
    solid = np.zeros((n, n, n), np.uint8)
    solid[5:7, 5:7, 8:10] = 1
    box = np.array([0, n, 0, n, 0, n], np.int64)
    transmit = np.empty_like(density)
    light_transmittance.serial(density, solid, box, h, np.array([0.0, 0.0, 1.0]), sigma_t, transmit)
    assert np.all(transmit[5:7, 5:7, :7] == 0.0)
    d = (n - (np.arange(n) + 0.5)) * h
    assert np.allclose(transmit[2, 2, :], np.exp(-sigma_t * rho * d), rtol=1e-5)
    assert np.allclose(transmit[5, 5, 10:], np.exp(-sigma_t * rho * d[10:]), rtol=1e-5)  # above it: lit


def test_a_mesh_behind_a_dense_slab_is_darker_by_the_light_transmittance():
    # A horizontal quad mesh at z = 0 seen from above (orthographic), a slab of smoke (rho, 0.4 m
    # thick, x in [0.8, 1.6]) at z in [1.0, 1.4], the light along (0.6, 0, 0.8): the light reaching
    # the quad at x in [0.05, 0.55] crosses L = 0.4 / 0.8 = 0.5 m of smoke (Beer-Lambert,
    # T = exp(-sigma rho L)), so with the renderer's shadow strength s those pixels are darker by
    # 1 - s (1 - T) than without smoke shadows (Fedkiw, Stam and Jensen 2001, §5: the light
    # transmittance grid); the slab's smear by trilinear sampling is within 0.6 h of L (as above).
    # Pixels whose light ray passes beside the slab (by more than the one-cell clamp at the box's
    # edge) keep their colour bit for bit.
    from inertia.render.fluid_volume import _srgb8_to_linear_table
    from inertia.render.meshes import TriangleMesh
    from inertia.render.renderer import Renderer

    n, h, rho, sigma_t = 16, 0.1, 1.0, 3.0
    density = np.zeros((n, n, n), np.float32)
    density[8:, :, 10:14] = rho
    cam = _top_camera((0.8, 0.8), height=1.6)
    r = Renderer(32, 32, dim=3, camera=cam, ground=False)
    quad = TriangleMesh(np.array([[-1.0, -1.0, 0.0], [3.0, -1.0, 0.0], [3.0, 3.0, 0.0], [-1.0, 3.0, 0.0]]), None,
                        np.array([[0, 1, 2], [0, 2, 3]]), (0.7, 0.7, 0.7))
    base = r.frame(np.zeros((0, 3)), meshes=[quad]).copy()
    depth = r._depth.copy()
    assert np.all(depth < 1e30)                                        # the quad covers the frame
    light = np.array([0.6, 0.0, 0.8])
    images = {}
    for s in (0.0, r.shadow_strength):
        color = np.ascontiguousarray(_srgb8_to_linear_table()[base])
        render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=light,
                            style=SmokeStyle(sigma_t=sigma_t, **DARK), depth=depth, shadow_strength=s)
        images[s] = color
    ratio = images[r.shadow_strength] / np.maximum(images[0.0], 1e-9)
    cols = ((np.arange(32) + 0.5) * 0.05)                               # pixel centres' x (1 px = 5 cm)
    shadowed = (cols > 0.1) & (cols < 0.5)
    clear = cols > 1.05       # light rays beside the slab (x + 0.75 z > 1.6 + one cell for the clamped edge)
    t_light = 1 - (1 - ratio[:, shadowed, 0]) / r.shadow_strength
    length = -np.log(t_light) / (sigma_t * rho)
    assert np.exp(-sigma_t * rho * 0.5) < 0.3                           # a dense slab: a visible shadow
    assert np.abs(length - 0.5).max() < 0.6 * h, (length.min(), length.max())
    assert np.array_equal(images[r.shadow_strength][:, clear], images[0.0][:, clear])
    # An obstacle row of cells inside the slab, across the light rays of the pixels at x ~ 0.14-0.24:
    # the renderer shades surfaces hidden by obstacles itself, so the smoke shadow is unchanged
    # (bit for bit; the obstacle-blocked grid of the smoke's own lighting would make it black).
    solid = np.zeros((n, n, n), bool)
    solid[10, :, 11] = True
    color = np.ascontiguousarray(_srgb8_to_linear_table()[base])
    render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=light,
                        style=SmokeStyle(sigma_t=sigma_t, **DARK), depth=depth, shadow_strength=r.shadow_strength,
                        solid=solid)
    assert np.array_equal(color, images[r.shadow_strength])
    with pytest.raises(ValueError, match="shadow_strength"):
        render_smoke_linear(color, cam, density, origin=(0, 0, 0), cell_size=h, light_direction=light, shadow_strength=2.0)
