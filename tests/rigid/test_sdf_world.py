"""Rigid bodies on baked signed-distance colliders (``inertia.geometry.sdf_collide``) against closed forms.

The baked field is the particle colliders' trilinear grid (``inertia.collision.distance``); a linear field
(a half-space) is reproduced exactly, a curved one within the interpolation error h^2 / (4 rho) of a
distance function of curvature 1 / rho sampled half a cell off its nodes.
"""

import hashlib
import math
import warnings

import numpy as np
import pytest

from inertia.collision.shapes import SDF
from inertia.model import ModelBuilder, with_colliders
from inertia.rigid.world import RigidWorld

G = 9.81
DT, SUBSTEPS = 1.0 / 60.0, 8


def _static_sag():
    """Sag of a soft contact against a static row under its body's weight: g / (2 pi f)^2, f twice the
    contact frequency (60 Hz, capped at a quarter of the substep rate), as rigid/world.py documents."""
    f = 2.0 * min(60.0, 0.25 * SUBSTEPS / DT)
    return G / (2.0 * math.pi * f) ** 2


def _half_space(top=0.0, resolution=16, **kw):
    """Baked SDF of the half-space z <= top (function z - top) over a 2 m x 2 m x 1 m box."""
    return SDF(lambda p: p[:, 2] - top, gradient=lambda p: np.tile([0.0, 0.0, 1.0], (len(p), 1)),
               bake={"bounds": ((-1.0, -1.0, top - 0.5), (1.0, 1.0, top + 0.5)), "resolution": resolution}, **kw)


def test_box_rests_on_a_baked_half_space_at_the_analytic_height_and_sleeps():
    # the trilinear interpolant of a linear field is exact, so the box's centre rests at its half height
    # above the surface, lower only by the soft contact's sag g / (2 pi f)^2 (1.7e-5 m)
    h, top = 0.1, 0.25
    b = ModelBuilder(gravity=(0.0, 0.0, -G))
    body = b.add_body(position=(0.05, -0.02, top + h + 0.05))
    b.add_box(body, (h, h, h))
    world = RigidWorld(with_colliders(b.finalize(), [_half_space(top)]), dt=DT, substeps=SUBSTEPS)
    counts = []
    for _ in range(90):
        world.step()
        c = world.contacts
        counts.extend(c.contact_point_count[c.active[:c.active_count]].tolist())
    assert max(counts) == 4                      # a face on the field: four of its nine samples
    world.step(30)
    z = world.state.body_q[0, 2]
    assert z == pytest.approx(top + h - _static_sag(), abs=2e-6)
    # flat on the face: the body's z axis stays vertical
    q = world.state.body_q[0, 3:]
    assert 1.0 - 2.0 * (q[1] ** 2 + q[2] ** 2) > 1.0 - 1e-8
    assert not world.state.body_awake[0]


def test_sphere_rests_on_a_baked_sphere_at_the_sum_of_the_radii():
    # SDF |x| - R baked on 31 cells over [-0.5, 0.5]^3: the ball's centre sits at x = y = 0, half a cell from
    # the nodes in x and y, where the bilinear interpolant exceeds the distance by
    # sqrt(z^2 + h^2 / 2) - z ~ h^2 / (4 z), z = R + r: the ball settles that much deeper, and by the sag
    R, r, n = 0.3, 0.1, 31
    hcell = 1.0 / n
    field = SDF(lambda p: np.linalg.norm(p, axis=1) - R, bake={"bounds": ((-0.5,) * 3, (0.5,) * 3), "resolution": n})
    b = ModelBuilder(gravity=(0.0, 0.0, -G))
    body = b.add_body(position=(0.0, 0.0, R + r + 0.1))
    b.add_sphere(body, r)
    world = RigidWorld(with_colliders(b.finalize(), [field]), dt=DT, substeps=SUBSTEPS)
    world.step(120)
    z = R + r
    interp = math.sqrt(z * z + 0.5 * hcell * hcell) - z
    dist = float(np.linalg.norm(world.state.body_q[0, :3]))
    assert dist == pytest.approx(R + r - interp - _static_sag(), abs=2e-5)
    assert abs(dist - (R + r)) < 1.5 * hcell ** 2 / (4 * z)
    assert not world.state.body_awake[0]


def test_sphere_bounces_off_a_baked_plane_to_e_squared_h0():
    # restitution e: apex heights h_n = e^(2n) h0 (the rigid plane test's scene and steps, on the SDF row)
    e, h0, r = 0.8, 1.0, 0.05
    b = ModelBuilder()
    body = b.add_body(position=(0, 0, h0 + r))
    b.add_sphere(body, r, restitution=e)
    model = with_colliders(b.finalize(), [_half_space(0.0)], restitution=e)
    world = RigidWorld(model, dt=1.0 / 480.0, substeps=4, restitution_threshold=0.1, enable_sleep=False)
    apexes, prev_vz = [], 0.0
    for _ in range(int(2.2 * 480)):
        world.step()
        vz = world.state.body_qd[0, 5]
        if prev_vz > 0.0 >= vz:
            apexes.append(world.state.body_q[0, 2] - r)
        prev_vz = vz
    assert len(apexes) >= 2
    for k, h in enumerate(apexes[:2], start=1):
        assert h == pytest.approx(e ** (2 * k) * h0, rel=0.03), (k, h)


def _mixed_scene(parallel):
    """Boxes, spheres, capsules, cylinders and hulls dropped on a baked wavy floor, one on a moving
    (kinematic) baked SDF platform."""
    from inertia.colliders import Motion
    rng = np.random.default_rng(5)
    floor = SDF(lambda p: p[:, 2] - 0.05 * np.sin(3.0 * p[:, 0]) * np.cos(3.0 * p[:, 1]),
                bake={"bounds": ((-1.0, -1.0, -0.3), (1.0, 1.0, 0.3)), "resolution": 24})
    platform = SDF(lambda p: np.max(np.abs(p - np.array([0.6, 0.6, 0.4])) - np.array([0.15, 0.15, 0.05]), axis=1),
                   bake={"bounds": ((0.35, 0.35, 0.25), (0.85, 0.85, 0.55)), "resolution": 12},
                   rest_point=(0.6, 0.6, 0.4), motion=Motion(position=lambda t: (0.6, 0.6, 0.4 + 0.1 * t)))
    b = ModelBuilder()
    hull = rng.normal(size=(10, 3)) * 0.06
    for k in range(10):
        q = rng.normal(size=4)
        q /= np.sqrt(np.sum(q * q))
        pos = (0.6, 0.6, 0.6) if k == 0 else (rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 0.3 + 0.1 * k)
        body = b.add_body(position=pos, orientation=q)
        [lambda: b.add_box(body, (0.06, 0.04, 0.05)), lambda: b.add_sphere(body, 0.05),
         lambda: b.add_capsule(body, 0.04, 0.05), lambda: b.add_cylinder(body, 0.05, 0.04),
         lambda: b.add_convex_hull(body, hull)][k % 5]()
    world = RigidWorld(with_colliders(b.finalize(), [floor, platform]), parallel=parallel)
    world.state.body_qd[10, 5] = 0.1             # the platform's kinematic body rises at 0.1 m/s
    return world


# measured at NUMBA_NUM_THREADS=1 and 2 (separate processes, parallel=True) on the x86-64 reference machine;
# re-measured when the gyroscopic term became implicit
GOLDEN_SDF_HASH = "217a6c6d0f1c2ccfc43ffcb14c24e889b7fd816d25322f04a64d06c74ab120c2"


def test_mixed_shapes_on_baked_fields_are_deterministic_at_1_and_2_threads(thread_counts):
    hashes, counts = [], None
    for _ in thread_counts():
        world = _mixed_scene(parallel=True)
        world.step(40)
        hashes.append(hashlib.sha256(world.state.body_q.tobytes() + world.state.body_qd.tobytes()).hexdigest())
    serial = _mixed_scene(parallel=False)
    for _ in range(40):
        serial.step()
        c = serial.contacts
        counts = c.contact_point_count[c.active[:c.active_count]]
        assert counts.max(initial=0) <= 4
    hashes.append(hashlib.sha256(serial.state.body_q.tobytes() + serial.state.body_qd.tobytes()).hexdigest())
    assert hashes[0] == hashes[1] == hashes[2] == GOLDEN_SDF_HASH
    # every body landed on a field (none fell through): all above the floor's lowest point minus a cm
    assert serial.state.body_q[:10, 2].min() > -0.06
    assert serial.max_penetration() < 0.01


def test_unbaked_sdf_warns_once_naming_the_collider():
    field = SDF(lambda p: p[:, 2])
    b = ModelBuilder()
    body = b.add_body(position=(0, 0, 0.5))
    b.add_sphere(body, 0.1)
    model = with_colliders(b.finalize(), [field])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        world = RigidWorld(model)
        world.step(2)
    msgs = [str(w.message) for w in caught if "unbaked SDF" in str(w.message)]
    assert len(msgs) == 1 and "colliders[0]" in msgs[0] and "bake=" in msgs[0]
    assert world.contacts.active_count == 0


def test_scene_file_box_lands_on_a_baked_sdf_collider(tmp_path):
    # a scene's [[colliders]] type = "sdf" (a .npy grid, baked on load) under a [bodies.*] box: the box lands
    # on the grid's surface z = 0.1 (a linear field: exact) at its half height, less the contact sag
    from inertia.scene import load_scene
    n, spacing = 11, 0.1
    origin = np.array([-0.5, -0.5, -0.4])
    z = origin[2] + spacing * np.arange(n)
    np.save(tmp_path / "floor.npy", np.broadcast_to(z - 0.1, (n, n, n)).copy())
    (tmp_path / "scene.toml").write_text("""
format_version = 1
[simulation]
dt = 0.016666666666666666
duration = 1.0
fps = 30
[[colliders]]
name = "floor"
type = "sdf"
file = "floor.npy"
origin = [-0.5, -0.5, -0.4]
spacing = 0.1
[bodies.crate]
shape = { type = "box", half_extents = [0.1, 0.1, 0.05] }
position = [0.0, 0.0, 0.4]
""")
    world = load_scene(tmp_path / "scene.toml")
    assert world.rigid is not None
    for _ in range(60):
        world.step()
    body = world.model.body_index("crate")
    assert world.rigid.state.body_q[body, 2] == pytest.approx(0.1 + 0.05, abs=1e-4)
