"""Triangle meshes, shadows and lines (inertia.render.meshes) against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from inertia.render import Camera, Renderer
from inertia.render import meshes as M
from inertia.render.kernels import FAR

W, H = 200, 200


def _top_camera(extent=4.0):
    """Orthographic, looking down -z at the origin: ``extent`` world units over the image height."""
    return Camera(position=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                  projection="orthographic", ortho_height=extent)


def _buffers(w=W, h=H):
    return np.zeros((h, w, 3), np.float32), np.full((h, w), FAR, np.float32), np.zeros((h, w), np.uint8)


def _light(direction, *, sky=(0.3, 0.3, 0.3), ground=(0.1, 0.1, 0.1), diffuse=0.8):
    light = np.zeros(M.LIGHT_SIZE)
    d = np.asarray(direction, float)
    light[0:3], light[3:6] = d / np.linalg.norm(d), (0.0, 0.0, 1.0)
    light[6:9], light[9:12], light[12] = sky, ground, diffuse
    return light


def _no_shadow():
    frame = np.zeros(M.SHADOW_FRAME_SIZE)
    frame[12] = 1.0
    return frame, np.full((1, 1), -np.inf, np.float32)


def _mesh_volume(v, t):
    """Divergence theorem: V = sum over triangles of a . (b x c) / 6 (outward winding)."""
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_tessellated_shapes_are_closed_outward_and_have_their_volume():
    model = {"shape_type": np.array([0, 1, 2, 3], np.int32),
             "shape_params": np.array([[0.5, 0, 0, 0], [0.2, 0.3, 0.4, 0], [0.25, 0.5, 0, 0], [0.3, 0.6, 0, 0]])}
    # Box: exact; cylinder of n = 32 sides: the prism's exact volume (n/2) r^2 sin(2 pi/n) 2h.
    v, n, t = M.tessellate_shape(model, 1)
    assert _mesh_volume(v, t) == pytest.approx(8 * 0.2 * 0.3 * 0.4, rel=1e-12)
    v, n, t = M.tessellate_shape(model, 3)
    assert _mesh_volume(v, t) == pytest.approx(16 * 0.3**2 * math.sin(2 * math.pi / 32) * 1.2, rel=1e-12)
    # Sphere and capsule: the polyhedron is inscribed, within 3 % of 4/3 pi r^3 (+ pi r^2 2h).
    v, n, t = M.tessellate_shape(model, 0)
    assert _mesh_volume(v, t) == pytest.approx(4 / 3 * math.pi * 0.125, rel=0.03)
    assert _mesh_volume(v, t) < 4 / 3 * math.pi * 0.125
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and np.all(np.einsum("ij,ij->i", n, v) > 0)
    v, n, t = M.tessellate_shape(model, 2)
    assert _mesh_volume(v, t) == pytest.approx(4 / 3 * math.pi * 0.25**3 + math.pi * 0.25**2 * 1.0, rel=0.03)


def test_a_lit_plane_is_ambient_plus_lambert():
    # A square facing +z; reference: c = albedo (ground + (sky - ground)(1 + n.up)/2 + k_d max(0, n.l)).
    v = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    n = np.tile([0.0, 0.0, 1.0], (4, 1))
    albedo = np.tile(np.array([0.5, 0.25, 0.8], np.float32), (2, 1))
    cam = _top_camera().params(W, H)
    for direction in ([0.0, 0.6, 0.8], [0.5, 0.0, 0.1], [0.3, 0.2, -0.9]):
        color, depth, mask = _buffers()
        light = _light(direction)
        M.draw_triangles(v, n, t, albedo, cam, light, *_no_shadow(), 1e-6, color, depth, mask)
        lam = max(0.0, light[2])  # n = +z
        expected = albedo[0] * (0.3 + lam * 0.8)  # n.up = 1: the sky ambient
        assert np.allclose(color[H // 2, W // 2], expected, rtol=1e-5)
        # The square covers 2 x 2 of the 4 x 4 world units in view: a quarter of the pixels.
        assert mask.sum() == pytest.approx(W * H / 4, rel=0.02)
        assert depth[H // 2, W // 2] == pytest.approx(10.0)


def test_box_silhouette_area_in_an_orthographic_view():
    # Projected area of a convex body along unit d: (1/2) sum_faces A_i |n_i . d|; a box of half
    # extents (a, b, c): 4 (b c |d_x| + a c |d_y| + a b |d_z|).
    a, b, c = 0.6, 0.35, 0.5
    v, n, t = M.tessellate_shape({"shape_type": np.array([1]), "shape_params": np.array([[a, b, c, 0.0]])}, 0)
    colors = np.full((t.shape[0], 3), 0.5, np.float32)
    d = np.array([0.4, -0.5, -0.75])
    d /= np.linalg.norm(d)
    camera = Camera(position=-5 * d, target=(0, 0, 0), up=(0, 0, 1), projection="orthographic", ortho_height=3.0)
    w = h = 400
    color, depth, mask = _buffers(w, h)
    M.draw_triangles(v, n, t, colors, camera.params(w, h), _light([0, 0, 1]), *_no_shadow(), 1e-6, color, depth, mask)
    pixel_area = (3.0 / h) ** 2
    expected = 4 * (b * c * abs(d[0]) + a * c * abs(d[1]) + a * b * abs(d[2]))
    assert mask.sum() * pixel_area == pytest.approx(expected, rel=0.01)


def test_the_shadow_of_a_sphere_falls_along_the_light():
    # A sphere of radius r centred at c above the ground z = 0, light towards L: its shadow is the
    # sphere's projection along L, an ellipse centred at c - L c_z / L_z of area pi r^2 / |L_z|.
    r, c = 0.4, np.array([0.3, -0.2, 1.2])
    v, n, t = M.tessellate_shape({"shape_type": np.array([0]), "shape_params": np.array([[r, 0, 0, 0.0]])}, 0)
    v = v + c
    L = np.array([0.35, 0.25, 0.9])
    L /= np.linalg.norm(L)
    frame = M.light_frame(L, v)
    depth_map = np.empty((M.SHADOW_MAP_SIZE, M.SHADOW_MAP_SIZE), np.float32)
    M.shadow_map_depth(v, t, frame, depth_map)
    camera = _top_camera(extent=4.0)
    w = h = 400
    color, _, mask = _buffers(w, h)
    color[:] = 1.0
    depth = np.full((h, w), 10.0, np.float32)  # the ground z = 0, seen from z = 10
    M.shadow_background(camera.params(w, h), frame, depth_map, 1.0, depth, mask, color)
    dark = 1.0 - color[..., 0]  # 1 inside the shadow, partial on its filtered rim
    px = 4.0 / h
    ys, xs = np.mgrid[0:h, 0:w]
    wx, wy = (xs + 0.5 - w / 2) * px, (h / 2 - (ys + 0.5)) * px
    centre = np.array([(dark * wx).sum(), (dark * wy).sum()]) / dark.sum()
    expected = c[:2] - L[:2] * c[2] / L[2]
    assert np.linalg.norm(centre - expected) < 2 * px
    # Inscribed tessellation (12 x 24): the area is a little under the sphere's.
    assert dark.sum() * px * px == pytest.approx(math.pi * r * r / L[2], rel=0.04)


def test_a_mesh_shadows_another_mesh_and_not_itself():
    # A small square at z = 1 over a big one at z = 0, light straight down: the lower square is
    # dark exactly under the upper one, and the lit upper one is not shadowed by itself.
    big = np.array([[-2.0, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]])
    small = np.array([[-0.5, -0.5, 1], [0.5, -0.5, 1], [0.5, 0.5, 1], [-0.5, 0.5, 1]])
    v = np.concatenate([big, small])
    t = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    n = np.tile([0.0, 0.0, 1.0], (8, 1))
    albedo = np.full((4, 3), 1.0, np.float32)
    light = _light([0, 0, 1], sky=(0.2, 0.2, 0.2), ground=(0.2, 0.2, 0.2), diffuse=0.8)
    frame = M.light_frame(light[0:3], v)
    depth_map = np.empty((M.SHADOW_MAP_SIZE, M.SHADOW_MAP_SIZE), np.float32)
    M.shadow_map_depth(v, t, frame, depth_map)
    color, depth, mask = _buffers()
    camera = Camera(position=(0.0, -0.01, 10.0), target=(0, 0, 0), up=(0, 1, 0), projection="orthographic", ortho_height=5.0)
    M.draw_triangles(v, n, t, albedo, camera.params(W, H), light, frame, depth_map, 1e-6, color, depth, mask)
    px = 5.0 / H

    def at(x, y):
        return color[int(H / 2 - y / px), int(W / 2 + x / px), 0]

    assert at(0.0, 0.0) == pytest.approx(1.0, rel=1e-5)      # the top square, lit: 0.2 + 0.8
    assert at(1.2, 0.0) == pytest.approx(1.0, rel=1e-5)      # the ground beside it, lit
    # Light straight down: the shadow hides under the square, so check the shadow map itself:
    # the texels under the small square hold its p . L (height 1).
    u = (np.array([0.0, 0.0, 0.0]) - frame[0:3]) @ frame[3:6] / frame[12]
    vv = (np.array([0.0, 0.0, 0.0]) - frame[0:3]) @ frame[6:9] / frame[12]
    assert depth_map[int(u), int(vv)] == pytest.approx(1.0 * light[2] / np.linalg.norm(light[0:3]), abs=1e-6)
    # An oblique light moves the shadow out from under the square onto visible ground.
    light = _light([0.5, 0.0, 1.0], sky=(0.2, 0.2, 0.2), ground=(0.2, 0.2, 0.2), diffuse=0.8)
    frame = M.light_frame(light[0:3], v)
    M.shadow_map_depth(v, t, frame, depth_map)
    color, depth, mask = _buffers()
    M.draw_triangles(v, n, t, albedo, camera.params(W, H), light, frame, depth_map, 1e-6, color, depth, mask)
    # The shadow of the square [-0.5, 0.5]^2 at height 1 falls shifted by -L_xy / L_z = -0.5 in x.
    assert at(-0.8, 0.0) == pytest.approx(0.2, abs=1e-5)         # ambient only
    lit = 0.2 + 0.8 * light[2]
    assert at(0.0, 0.0) == pytest.approx(lit, rel=1e-5)          # the square itself, not self-shadowed
    assert at(1.2, 0.0) == pytest.approx(lit, rel=1e-5)


def test_a_line_covers_its_width():
    # Sum of coverage across a horizontal line = its width in pixels (box-filtered edge).
    color, depth, _ = _buffers()
    camera = _top_camera(extent=4.0)
    px = 4.0 / H
    y = 0.3 * px  # off the pixel centres
    points = np.array([[-1.0, y, 0.0], [1.0, y, 0.0]])
    for width in (1.0, 2.5, 4.0):
        color[:] = 0.0
        depth[:] = FAR
        M.draw_lines(points, np.array([[0, 1]]), np.ones((1, 3)), np.ones(1), width, camera.params(W, H), 1e-6, color, depth)
        column = color[:, W // 2, 0]
        assert column.sum() == pytest.approx(width, rel=0.05)
        assert color[:, 5, 0].sum() == 0.0  # beyond the segment's end
    # Opacity scales the coverage (blending over black) and leaves the depth buffer alone.
    color[:] = 0.0
    depth[:] = FAR
    M.draw_lines(points, np.array([[0, 1]]), np.ones((1, 3)), np.full(1, 0.25), 2.5, camera.params(W, H), 1e-6, color, depth)
    assert color[:, W // 2, 0].sum() == pytest.approx(0.25 * 2.5, rel=0.05)
    assert np.all(depth == FAR)


def test_renderer_draws_meshes_with_particles_in_front_and_behind():
    camera = Camera(position=(0.0, -6.0, 2.0), target=(0, 0, 0.5), up=(0, 0, 1))
    renderer = Renderer(W, H, camera=camera, color_by="uniform", color="#ff0000")
    renderer.bounds = (np.array([-2.0, -2, 0]), np.array([2.0, 2, 2]))
    v, n, t = M.tessellate_shape({"shape_type": np.array([1]), "shape_params": np.array([[0.5, 0.5, 0.5, 0]])}, 0)
    box = M.TriangleMesh(v + [0, 0, 0.5], n, t, (0.1, 0.3, 0.9))
    front = np.array([[0.0, -1.0, 0.5]])
    behind = np.array([[0.0, 1.5, 0.5]])
    img_front = renderer.frame(front, radius=0.15, meshes=[box])
    img_behind = renderer.frame(behind, radius=0.15, meshes=[box])
    px, py, _ = camera.project(front, W, H)
    assert img_front[int(py[0]), int(px[0]), 0] > 150      # the red particle in front of the box
    px, py, _ = camera.project(behind, W, H)
    pixel = img_behind[int(py[0]), int(px[0])].astype(int)
    assert pixel[2] > pixel[0]                               # hidden behind the blue box
    again = renderer.frame(front, radius=0.15, meshes=[box])
    assert np.array_equal(again, img_front)                  # deterministic bytes


def test_hulls_meshes_and_heightfields_from_the_shape_table():
    # Rows as the contract stores them: a convex hull of a cube's 8 corners plus an inside point
    # (volume 1 exactly), a triangle soup (3 vertices per triangle) of a tetrahedron (volume
    # 1/6), and a 3 x 4 heightfield on a tilted plane z = 0.5 x (normals (-0.5, 0, 1) / |.|).
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) - 0.5
    hull_points = np.concatenate([cube, [[0.1, 0.0, 0.0]]])
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 0, 1], [1, 0, 0],
                    [0, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 0, 1], [0, 1, 0]], float)
    gx, gy = np.meshgrid((np.arange(3) - 1.0) * 0.5, (np.arange(4) - 1.5) * 0.5, indexing="ij")
    field = np.stack([gx.ravel(), gy.ravel(), 0.5 * gx.ravel()], axis=1)
    verts = np.concatenate([hull_points, tet, field])
    model = {"shape_type": np.array([4, 5, 7], np.int32), "shape_params": np.array([[0, 0, 0, 0], [4, 0, 0, 0], [3, 4, 0.5, 0.5]]),
             "shape_vert_start": np.array([0, 9, 21], np.int32), "shape_vert_count": np.array([9, 12, 12], np.int32),
             "geom_vertices": verts}
    v, n, t = M.tessellate_shape(model, 0)
    assert t.shape == (12, 3) and _mesh_volume(v, t) == pytest.approx(1.0, rel=1e-12)
    v, n, t = M.tessellate_shape(model, 1)
    assert t.shape == (4, 3) and abs(_mesh_volume(v, t)) == pytest.approx(1 / 6, rel=1e-12)
    v, n, t = M.tessellate_shape(model, 2)
    assert t.shape == (2 * 2 * 3, 3)
    assert np.allclose(n, np.array([-0.5, 0.0, 1.0]) / math.sqrt(1.25))
    # The grid's triangles tile its footprint: total projected area (2 cells x 3 cells of 0.5 m).
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    assert np.abs(np.cross(b - a, c - a)[:, 2]).sum() / 2 == pytest.approx(1.0 * 1.5)
    assert M.tessellate_shape({"shape_type": np.array([6]), "shape_params": np.zeros((1, 4))}, 0) is None
