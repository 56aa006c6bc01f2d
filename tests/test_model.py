"""ModelBuilder: mass properties (closed forms, parallel axis, principal axes) and bad input."""

import math

import numpy as np
import pytest

from inertia.geometry.mass import shape_mass_properties
from inertia.model import ModelBuilder
from inertia.geometry import shapes as S


def primitive_mass_properties(shape_type, params, density):
    props = shape_mass_properties(shape_type, params, density)
    return props.mass, props.inertia


def test_primitive_mass_properties_closed_forms():
    rho = 500.0
    m, i = primitive_mass_properties(S.SPHERE, (0.2, 0, 0, 0), rho)
    assert m == pytest.approx(rho * 4 / 3 * math.pi * 0.2 ** 3, rel=1e-12)
    assert np.diag(i) == pytest.approx([0.4 * m * 0.04] * 3, rel=1e-12)
    m, i = primitive_mass_properties(S.BOX, (0.1, 0.2, 0.3), rho)
    assert m == pytest.approx(rho * 0.2 * 0.4 * 0.6, rel=1e-12)
    assert np.diag(i) == pytest.approx([m * (0.16 + 0.36) / 12, m * (0.04 + 0.36) / 12,
                                        m * (0.04 + 0.16) / 12], rel=1e-12)
    m, i = primitive_mass_properties(S.CYLINDER, (0.1, 0.25, 0, 0), rho)
    assert m == pytest.approx(rho * math.pi * 0.01 * 0.5, rel=1e-12)
    assert np.diag(i) == pytest.approx([m * (3 * 0.01 + 0.25) / 12] * 2 + [0.5 * m * 0.01], rel=1e-12)
    # capsule = cylinder + sphere (two hemispheres); about the axis the moments simply add
    r, hl = 0.1, 0.3
    m, i = primitive_mass_properties(S.CAPSULE, (r, hl, 0, 0), rho)
    mc, ms = rho * math.pi * r * r * 2 * hl, rho * 4 / 3 * math.pi * r ** 3
    assert m == pytest.approx(mc + ms, rel=1e-12)
    assert i[2, 2] == pytest.approx(0.5 * mc * r * r + 0.4 * ms * r * r, rel=1e-12)
    # transverse: two hemispheres (83/320 m r^2 each about their centroids, 3r/8 from the flat face)
    d = hl + 3 * r / 8
    expected = mc * (3 * r * r + 4 * hl * hl) / 12 + 2 * (83 / 320 * ms / 2 * r * r + ms / 2 * d * d)
    assert i[0, 0] == pytest.approx(expected, rel=1e-12)


def test_compound_body_parallel_axis_and_principal_frame():
    # two equal spheres 1 m apart: centre of mass between them; transverse moment 2 (2/5 m r^2 + m d^2)
    b = ModelBuilder()
    body = b.add_body(position=(1.0, 2.0, 3.0))
    b.add_sphere(body, 0.1, position=(0.0, 0.0, 0.0))
    b.add_sphere(body, 0.1, position=(1.0, 0.0, 0.0))
    m = b.finalize()
    ms = 1000 * 4 / 3 * math.pi * 0.001
    assert m.body_mass[0] == pytest.approx(2 * ms, rel=1e-12)
    assert m.state().body_q[0, :3] == pytest.approx([1.5, 2.0, 3.0], abs=1e-12)
    moments = np.sort(m.body_inertia[0])
    assert moments[0] == pytest.approx(2 * 0.4 * ms * 0.01, rel=1e-12)
    assert moments[1:] == pytest.approx([2 * (0.4 * ms * 0.01 + ms * 0.25)] * 2, rel=1e-12)
    # the shapes now sit at +-0.5 m from the body frame's origin along one principal axis
    assert np.sort(np.linalg.norm(m.shape_local_pose[:, :3], axis=1)) == pytest.approx([0.5, 0.5], abs=1e-12)


def test_explicit_mass_scales_the_inertia():
    b = ModelBuilder()
    body = b.add_body(mass=3.0)
    b.add_box(body, (0.1, 0.1, 0.1))
    m = b.finalize()
    assert m.body_mass[0] == 3.0
    assert m.body_inertia[0] == pytest.approx([3.0 * 0.08 / 12] * 3, rel=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda b: b.add_sphere(b.add_body(), 0.1, density=0.0), "density"),
    (lambda b: b.add_sphere(b.add_body(), -0.1), "radius"),
    (lambda b: b.add_body(mass=-1.0), "mass"),
    (lambda b: b.add_body(orientation=(1.0, 0.1, 0.0, 0.0)), "unit quaternion"),
    (lambda b: b.add_body(orientation=(0.0, 0.0, 0.0, 0.0)), "orientation"),
    (lambda b: b.add_sphere(b.add_body(), 0.1, material="rubber"), "unknown material key 'rubber'"),
    (lambda b: b.add_body(body_type="frozen"), "body_type"),
    (lambda b: b.add_shape(b.add_body(), "torus"), "shape_type"),
    (lambda b: b.add_sphere(7, 0.1), "body"),
    (lambda b: b.add_convex_hull(b.add_body(), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]), "coplanar"),
    (lambda b: b.add_convex_hull(b.add_body(), [[0, 0, 0], [1, 0, 0], [0, 1, 0]]), "N >= 4"),
    (lambda b: b.add_plane(body=b.add_body()), "plane"),
    (lambda b: b.add_material("ice", friction=-0.1), "friction"),
    (lambda b: b.add_material("ice", restitution=1.5), "restitution"),
])
def test_bad_input_names_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call(ModelBuilder())


def test_dynamic_body_without_mass_is_rejected_at_finalize():
    b = ModelBuilder()
    b.add_body(name="ghost")
    with pytest.raises(ValueError, match="ghost"):
        b.finalize()


def test_materials_combine_by_geometric_mean_and_max():
    # checked through the contact buffer in tests/geometry; here the table columns are filled
    b = ModelBuilder()
    b.add_material("rubber", friction=0.9, restitution=0.8, density=1100)
    s = b.add_sphere(b.add_body(), 0.1, material="rubber")
    m = b.finalize()
    assert (m.shape_friction[s], m.shape_restitution[s], m.shape_density[s]) == (0.9, 0.8, 1100.0)


def test_hull_body_takes_the_polyhedral_mass_properties():
    # a cube given as hull points, off-centre in its shape frame: m = rho a^3, I = m a^2 / 6 about the
    # centre of mass (geometry.mass integrates the polyhedron exactly), the body frame at the centroid
    a, rho = 0.2, 750.0
    corners = np.array([[x, y, z] for x in (0, a) for y in (0, a) for z in (0, a)], dtype=float)
    b = ModelBuilder()
    body = b.add_body(position=(0.0, 0.0, 1.0))
    b.add_convex_hull(body, corners, density=rho)
    model = b.finalize()
    m = rho * a ** 3
    assert model.body_mass[0] == pytest.approx(m, rel=1e-12)
    assert model.body_inertia[0] == pytest.approx([m * a * a / 6] * 3, rel=1e-9)
    state = model.state()
    assert state.body_q[0, :3] == pytest.approx([a / 2, a / 2, 1.0 + a / 2], abs=1e-12)


# ---- one shape table: particle colliders as rows (model.with_colliders) ---------------------------
def test_collider_rows_reproduce_the_colliders_geometry():
    # each collider's rows, posed by the table, give the same signed distance as the collider itself
    import inertia as ia
    from inertia.collision.shapes import BodyShape
    from inertia.model import with_colliders
    cols = [ia.colliders.Sphere(center=(0.3, 0.1, 0.2), radius=0.25),
            ia.colliders.Box(center=(-1.0, 0.5, 0.3), half_extents=(0.2, 0.3, 0.4), rotation=(0.3, -0.2, 0.5)),
            ia.colliders.Capsule(a=(0.0, 0.0, 0.0), b=(0.4, 0.3, 0.2), radius=0.1),
            ia.colliders.Cylinder(center=(1.0, -1.0, 0.0), radius=0.3, half_height=0.2, axis=(1.0, 1.0, 0.0)),
            ia.colliders.Plane(point=(0.0, 0.0, -0.5), normal=(0.2, 0.1, 1.0))]
    model = with_colliders(None, cols)
    assert list(model.shape_type) == [0, 1, 2, 3, 6] and list(model.shape_source) == [0, 1, 2, 3, 4]
    pts = np.random.default_rng(0).uniform(-1.5, 1.5, (200, 3))
    for s, col in enumerate(cols):
        row = BodyShape(model, s)
        np.testing.assert_allclose(row.signed_distance(pts), col.signed_distance(pts), atol=1e-12)


def test_a_plane_collider_is_ground_for_bodies_and_a_moving_box_collider_pushes_them():
    # one table: the rigid world sees the particle colliders. A ball dropped on an ia.colliders.Plane
    # rests on it at its radius; a box collider with a Motion (a kinematic body carrying the motion's
    # velocity) sweeps a resting ball along +x at its own speed, 0.5 m/s.
    import inertia as ia
    from inertia.world import World
    b = ModelBuilder()
    ball = b.add_body(position=(0.0, 0.0, 0.3))
    b.add_sphere(ball, 0.1, friction=0.0)
    pusher = ia.colliders.Box(center=(-0.4, 0.0, 0.1), half_extents=(0.1, 0.3, 0.1),
                              motion=lambda t: (-0.4 + 0.5 * t, 0.0, 0.1))
    world = World(dt=1 / 60, colliders=[ia.colliders.Plane(), pusher], model=b.finalize(),
                  rigid_options={"substeps": 4, "contact_hertz": 120.0})
    assert world.model.body_count == 2 and world.model.body_type[1] == 2 - 1   # kinematic
    for _ in range(30):
        world.step()
    q = world.rigid.state.body_q
    assert q[ball, 2] == pytest.approx(0.1, abs=2e-3)
    assert q[1, 0] == pytest.approx(-0.4 + 0.5 * 0.5, abs=1e-12)             # the pusher follows its motion
    for _ in range(60):
        world.step()
    assert world.rigid.state.body_qd[ball, 3] == pytest.approx(0.5, rel=0.05)
    assert q[ball, 0] == pytest.approx(q[1, 0] + 0.2, abs=5e-3)              # touching the pusher's face


def test_a_lone_particle_system_owns_a_small_shape_table():
    import inertia as ia
    from inertia.geometry import shapes as S
    ps = ia.ParticleSystem(np.zeros((1, 3)))
    ps.add_collider(ia.colliders.Plane())
    ps.add_collider(ia.colliders.Container(half_extents=(1.0, 1.0, 1.0)))
    table = ps._collision.shape_table()
    assert list(table.shape_type) == [S.PLANE] * 7 and list(table.shape_source) == [0] + [1] * 6
    assert table.body_count == 0
