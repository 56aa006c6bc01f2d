"""Continuous (a-priori) detection: nothing tunnels, and nothing ends a step inside a collider."""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import inertia as ia

from .conftest import particles

C = ia.colliders
THIN = 0.0005  # half-thickness: a 1 mm thick obstacle


def _sheet(z=0.0, s=1.0):
    v = np.array([[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open sheet: unsigned by design
        return C.Mesh((v, np.array([[0, 1, 2], [0, 2, 3]])), resolution=16, signed=False)


def _thin_box_mesh():
    # a closed 2 m x 2 m x 1 mm box as 12 triangles (watertight)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-THIN, THIN)], float)
    f = np.array([[0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3], [0, 1, 3], [0, 3, 2],
                  [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6]])
    return C.Mesh((v, f), resolution=32)


# every collider type, each a thin obstacle across z = 0 (the particles come from z > 0), with the
# height of its top surface over the footprint the particles aim at (|x|, |y| < 0.5)
COLLIDERS = {
    "plane": (lambda: C.Plane(point=(0, 0, 0), normal=(0, 0, 1)), lambda x, y, t: 0.0),
    "box": (lambda: C.Box(center=(0, 0, 0), half_extents=(1, 1, THIN)), lambda x, y, t: THIN),
    "sphere": (lambda: C.Sphere(center=(0, 0, -0.999), radius=1.0),
               lambda x, y, t: -0.999 + np.sqrt(1 - x ** 2 - y ** 2) if x * x + y * y < 1 else -np.inf),
    "capsule": (lambda: C.Capsule(a=(-1, 0, 0), b=(1, 0, 0), radius=THIN), lambda x, y, t: THIN),
    "cylinder": (lambda: C.Cylinder(center=(0, 0, 0), radius=1.0, half_height=THIN), lambda x, y, t: THIN),
    "container": (lambda: C.Container(center=(0, 0, 5), half_extents=(2, 2, 5)), lambda x, y, t: 0.0),
    "mesh_sheet": (_sheet, lambda x, y, t: 0.0),
    "mesh_thin_box": (_thin_box_mesh, lambda x, y, t: THIN),
    "sdf": (lambda: C.SDF(lambda p: np.abs(p[:, 2]) - THIN), lambda x, y, t: THIN),
    "sdf_baked": (lambda: C.SDF(lambda p: np.abs(p[:, 2]) - 0.01,
                                bake={"bounds": ((-1, -1, -0.1), (1, 1, 0.1)), "resolution": 40}),
                  lambda x, y, t: 0.01),
    "moving_box": (lambda: C.Box(center=(0, 0, 0), half_extents=(1, 1, THIN), motion=lambda t: (0, 0, 2.0 * t)),
                   lambda x, y, t: THIN + 2.0 * t),
}


@pytest.fixture(scope="module", params=sorted(COLLIDERS))
def collider(request):
    build, top = COLLIDERS[request.param]
    return request.param, build(), top


@pytest.mark.parametrize("dt", [1e-4, 1 / 240, 1 / 60, 1 / 30])
def test_nothing_tunnels_at_1000_m_per_s(collider, dt):
    # particles at 1000 m/s (16.7 m per step at 60 Hz) against 1 mm obstacles never get below
    # the obstacle's top surface, and all bounce back up
    name, col, top = collider
    rng = np.random.default_rng(3)
    n = 12
    lateral = 0.0 if name == "capsule" else 0.05  # the capsule is a thin rod along x at y = 0
    start = np.column_stack([rng.uniform(-0.05, 0.05, n), rng.uniform(-lateral, lateral, n),
                             rng.uniform(0.3, 8.0, n)])
    direction = np.column_stack([rng.uniform(-0.05, 0.05, n), rng.uniform(-lateral, lateral, n), -np.ones(n)])
    velocity = 1000.0 * direction / np.linalg.norm(direction, axis=1)[:, None]
    ps = particles(start, velocity, gravity=False)
    ps.add_collider(col, restitution=0.5, friction=0.2)
    sim = ia.Simulation(ps, dt=dt)
    for _ in range(3 if name == "container" else max(3, int(0.02 / dt))):
        sim.step()
        floor = np.array([top(x, y, sim.t) for x, y in ps.x[:, :2]])
        assert np.all(ps.x[:, 2] >= floor - 1e-6), (name, dt, (ps.x[:, 2] - floor).min())
    if name != "container":
        assert np.all(ps.v[:, 2] > 0)  # every particle bounced


def test_thin_obstacle_with_particle_radius():
    # spheres of radius 5 mm stop 5 mm above a 1 mm box
    ps = particles([[0.0, 0.0, 1.0]], [[0.0, 0.0, -1000.0]], gravity=False, radius=0.005)
    ps.add_collider(C.Box(half_extents=(1, 1, THIN)), restitution=0.0)
    sim = ia.Simulation(ps, dt=1 / 60)
    sim.step()
    assert ps.x[0, 2] == pytest.approx(THIN + 0.005, abs=2e-6)
    assert ps.v[0, 2] == pytest.approx(0.0, abs=1e-9)


def test_time_of_impact_splits_the_step_exactly():
    # a-priori: impact at t* = d / v inside the step, then the reflected motion for dt - t*
    # (no gravity: x_end = e v (dt - t*) above the plane)
    v, e, dt = 10.0, 0.8, 0.1
    ps = particles([[0.0, 0.0, 0.3]], [[0.0, 0.0, -v]], gravity=False)
    ps.add_collider(C.Plane(), restitution=e)
    ia.Simulation(ps, dt=dt).step()
    t_star = 0.3 / v
    assert ps.x[0, 2] == pytest.approx(e * v * (dt - t_star), rel=1e-12)
    assert ps.v[0, 2] == pytest.approx(e * v, rel=1e-12)


SHAPES = {
    "plane": lambda: C.Plane(point=(0, 0, 0), normal=(0.2, -0.1, 1.0)),
    "sphere": lambda: C.Sphere(center=(0, 0, -0.5), radius=0.5),
    "box": lambda: C.Box(center=(0, 0, -0.25), half_extents=(0.6, 0.4, 0.25), rotation=(0.3, 0.1, -0.2)),
    "capsule": lambda: C.Capsule(a=(-0.5, 0, -0.3), b=(0.5, 0.1, -0.3), radius=0.3),
    "cylinder": lambda: C.Cylinder(center=(0, 0, -0.3), radius=0.6, half_height=0.3, axis=(0.1, 0.2, 1.0)),
    "container": lambda: C.Container(center=(0, 0, 0.5), half_extents=(1.5, 1.5, 0.9)),
    "mesh": lambda: _thin_box_mesh(),
    "sdf": lambda: C.SDF(lambda p: np.linalg.norm(p - [0, 0, -0.5], axis=1) - 0.5),
}


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shape=st.sampled_from(sorted(SHAPES)),
       speed=st.floats(0.1, 1000.0),
       theta=st.floats(0.0, 1.4),
       phi=st.floats(0.0, 2 * np.pi),
       dt=st.sampled_from([1e-4, 1e-3, 1 / 120, 1 / 30]),
       radius=st.sampled_from([0.0, 0.01, 0.05]),
       restitution=st.floats(0.0, 1.0),
       friction=st.floats(0.0, 1.0),
       mode=st.sampled_from(["a_priori", "a_posteriori"]))
def test_no_particle_ends_a_step_deeper_than_the_tolerance(shape, speed, theta, phi, dt, radius, restitution,
                                                           friction, mode):
    # property: after every step, phi(x) - r >= -tolerance for every particle and collider
    col = SHAPES[shape]()
    direction = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), -np.cos(theta)])
    start = np.array([[0.0, 0.0, 0.3], [0.1, -0.2, 0.6], [-0.3, 0.2, 0.2]])
    ps = particles(start, np.tile(speed * direction, (3, 1)), radius=radius)
    ps.add_collider(col, restitution=restitution, friction=friction)
    ps.collision_mode = mode
    tol = ps._collision.distance_tolerance
    sim = ia.Simulation(ps, dt=dt)
    for _ in range(6):
        sim.step()
        depth = col.signed_distance(ps.x) - radius
        assert depth.min() >= -tol, (depth.min(), mode)
