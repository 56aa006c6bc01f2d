"""Heightfield rows seen by particles (inertia.collision.heightfield_distance, BodyShape)."""

import numpy as np
import pytest

import inertia as ia
from inertia.collision.heightfield_distance import heightfield_closed_mesh, heightfield_height
from inertia.collision.mesh import _watertight
from inertia.geometry.trimesh_collide import heightfield_vertices
from inertia.model import ModelBuilder
from inertia.world import World


def test_closed_mesh_is_watertight_outward_and_keeps_the_rigid_triangles():
    # divergence theorem: the volume of the closed solid (sum of signed tetrahedra) equals the exact
    # volume under the triangulated surface down to the bottom, which for a bilinear-free planar-per-
    # triangle surface is sum over triangles of area_xy * (mean corner height - bottom); 1e-12.
    rng = np.random.default_rng(0)
    h = rng.uniform(-0.2, 0.3, (5, 4))
    verts, (nx, ny, dx, dy) = heightfield_vertices(h, (0.5, 0.3))
    v, f = heightfield_closed_mesh(verts, int(nx), int(ny), depth=1.0)
    assert _watertight(f)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    bottom = h.min() - 1.0
    top = f[:2 * (int(nx) - 1) * (int(ny) - 1)]
    mean_h = v[top][:, :, 2].mean(axis=1)
    exact = ((mean_h - bottom) * 0.5 * dx * dy).sum()
    assert volume == pytest.approx(exact, rel=1e-12)
    # the surface triangles are the rigid side's: cell (i, j) -> (v00, v10, v11), (v00, v11, v01)
    assert tuple(top[0]) == (0, int(ny), int(ny) + 1)


def _world(heights, spacing, **material):
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    b.add_heightfield(heights, spacing, **material)
    return World(dt=1 / 240, model=b.finalize())


def test_a_particle_slides_down_a_frictionless_heightfield_slope_at_g_sin_theta():
    # closed form: a point mass on a frictionless incline of angle theta travels s = g sin(theta) t^2 / 2;
    # semi-implicit Euler on the resting filter's constant along-slope force gives s at t = n dt within
    # the scheme's O(dt) error, g sin(theta) dt t / 2 relative to s = dt / t (1/120 here): 1 %.
    theta = np.radians(20.0)
    heights = np.tile((-np.tan(theta) * np.array([-1.0, 1.0]))[:, None], (1, 2))
    world = _world(heights, (2.0, 2.0), friction=0.0, restitution=0.0)
    r = 0.01
    x0 = np.array([[-0.5, 0.0, np.tan(theta) * 0.5 + r / np.cos(theta)]])
    ps = ia.ParticleSystem(x0, masses=0.001, radius=r)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
    world.add("p", ps, integrator="semi_implicit_euler")
    steps = 120
    for _ in range(steps):
        world.step()
    t = steps * world.dt
    s = np.linalg.norm(ps.x[0] - x0[0])
    assert s == pytest.approx(0.5 * 9.81 * np.sin(theta) * t * t, rel=1e-2)
    # it stayed on the surface: the gap to the plane is r (within the contact tolerance)
    n = np.array([np.sin(theta), 0.0, np.cos(theta)])
    assert (ps.x[0] - [0.0, 0.0, 0.0]) @ n == pytest.approx(r, abs=1e-6)


def test_particle_rain_on_a_sinusoidal_heightfield_never_goes_below_it():
    # 120 particles (r = 1 cm) fall 0.2-0.5 m onto z = 0.1 sin(2 pi x) cos(2 pi y) sampled on a 21 x 21
    # grid; at every step no particle centre over the grid is lower than r above the triangulated surface
    # (the rigid side's triangles, heightfield_height), within the contact tolerance 1e-6 m.
    g = np.linspace(-1.0, 1.0, 21)
    X, Y = np.meshgrid(g, g, indexing="ij")
    heights = 0.1 * np.sin(2 * np.pi * X) * np.cos(2 * np.pi * Y)
    world = _world(heights, (0.1, 0.1), friction=0.3, restitution=0.3)
    m = world.model
    verts = m.geom_vertices[m.shape_vert_start[0]:m.shape_vert_start[0] + m.shape_vert_count[0]]
    rng = np.random.default_rng(3)
    n, r = 120, 0.01
    x = np.column_stack([rng.uniform(-0.8, 0.8, n), rng.uniform(-0.8, 0.8, n), rng.uniform(0.2, 0.5, n)])
    ps = ia.ParticleSystem(x, masses=0.001, radius=r)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
    world.add("rain", ps, integrator="semi_implicit_euler")
    touched = 0
    for _ in range(200):
        world.step()
        over = (np.abs(ps.x[:, 0]) < 1.0) & (np.abs(ps.x[:, 1]) < 1.0)
        gap = ps.x[over, 2] - r - heightfield_height(verts, 21, 21, ps.x[over, 0], ps.x[over, 1])
        assert gap.min() >= -1e-6
        touched = max(touched, int((gap < 2e-3).sum()))
    assert touched > n // 2            # most of the rain reached the surface
