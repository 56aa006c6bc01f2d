"""Every convex pair has a contact: GJK/EPA plus feature clipping (narrowphase._convex_general) against
closed-form gaps, depths, normals and contact points, and resting heights through RigidWorld."""

import math

import numpy as np
import pytest

from inertia.dynamics.contacts import Contacts
from inertia.geometry.broadphase import shape_world_bounds, sort_and_sweep
from inertia.geometry.narrowphase import compact_active, narrow_phase
from inertia.model import ModelBuilder
from inertia.rigid.world import RigidWorld

CONVEX = ("sphere", "box", "capsule", "cylinder", "hull")
# a hull cube of half side 0.1 and a tetrahedron with a flat base at z = 0 and apex at z = 0.15
CUBE = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.1, 0.1) for z in (-0.1, 0.1)])
TETRA = np.array([[0.08, 0.0, 0.0], [-0.04, 0.07, 0.0], [-0.04, -0.07, 0.0], [0.0, 0.0, 0.15]])


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return (math.cos(angle / 2), *(axis * math.sin(angle / 2)))


def _add(b, body, kind):
    """Shape of each kind with half extent 0.1 along the body's x axis."""
    if kind == "sphere":
        b.add_sphere(body, 0.1)
    elif kind == "box":
        b.add_box(body, (0.1, 0.15, 0.12))
    elif kind == "capsule":
        b.add_capsule(body, 0.1, 0.1)
    elif kind == "cylinder":
        b.add_cylinder(body, 0.1, 0.12)
    else:
        b.add_convex_hull(body, CUBE)


def _manifolds(builder, dt=1.0 / 60.0):
    m = builder.finalize()
    st = m.state()
    ns = m.shape_count
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shapes = m.shapes()
    shape_world_bounds(shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    pairs, keys = np.zeros((64, 2), np.int32), np.zeros(64, np.int64)
    n = sort_and_sweep(aabb, shapes, m.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    c = Contacts(64)
    narrow_phase(pairs, keys, n, shapes, pose, st.body_qd, m.body_bound_radius, dt, c.arrays())
    c.count = n
    c.active_count = compact_active(c.arrays(), n)
    return c, m


def _only(c):
    act = c.manifolds()
    assert len(act) == 1, f"{len(act)} manifolds"
    i = act[0]
    k = c.contact_point_count[i]
    return (c.contact_shape[i], c.contact_normal[i], c.contact_point[i, :k], c.contact_separation[i, :k],
            c.contact_feature[i, :k])


@pytest.mark.parametrize("kind_a", CONVEX)
@pytest.mark.parametrize("kind_b", CONVEX)
@pytest.mark.parametrize("gap", [0.03, -0.004])
def test_every_convex_pair_gap_and_normal_along_x(kind_a, kind_b, gap):
    """Two shapes side by side on the x axis, each reaching exactly 0.1 m along x from its centre: the
    gap is |x_b - x_a| - 0.2 (closed form), separated (1e-9) or shallowly overlapping; the normal is +-x
    (from the lower shape index to the higher one)."""
    b = ModelBuilder(default_margin=0.05)
    _add(b, b.add_body(position=(0.0, 0.0, 0.0)), kind_a)
    _add(b, b.add_body(position=(0.2 + gap, 0.0, 0.0)), kind_b)
    shp, n, p, s, _ = _only(_manifolds(b)[0])
    sign = 1.0 if shp[0] == 0 else -1.0
    assert n == pytest.approx([sign, 0, 0], abs=1e-9)
    assert s.min() == pytest.approx(gap, abs=1e-9)
    # contact points midway between the surfaces: x = 0.1 + gap / 2
    assert p[:, 0] == pytest.approx(np.full(len(p), 0.1 + 0.5 * gap), abs=1e-9)


@pytest.mark.parametrize("kind_a", CONVEX)
@pytest.mark.parametrize("kind_b", CONVEX)
def test_every_convex_pair_tilted_far_and_near(kind_a, kind_b):
    """Rotated shapes (general poses, no closed form): a pair farther apart than the margin gives no
    manifold; the same pair overlapping gives one with a unit normal, 1..4 points, a negative deepest
    separation and distinct feature keys (a smoke test of the general path; the exact values are checked
    by the closed-form tests above and below)."""
    b = ModelBuilder(default_margin=0.01)
    _add(b, b.add_body(position=(0, 0, 0), orientation=_rot((1, 2, 3), 0.7)), kind_a)
    _add(b, b.add_body(position=(0.6, 0.1, 0.05), orientation=_rot((3, -1, 1), 1.1)), kind_b)
    c, _ = _manifolds(b)
    assert len(c.manifolds()) == 0
    b = ModelBuilder(default_margin=0.01)
    _add(b, b.add_body(position=(0, 0, 0), orientation=_rot((1, 2, 3), 0.7)), kind_a)
    _add(b, b.add_body(position=(0.17, 0.02, 0.01), orientation=_rot((3, -1, 1), 1.1)), kind_b)
    shp, n, p, s, f = _only(_manifolds(b)[0])
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    assert 1 <= len(s) <= 4 and s.min() < 0.0
    assert len(set(f.tolist())) == len(f)


def _ground_box(b):
    # a static box whose top face is z = 0
    b.add_box(-1, (0.5, 0.5, 0.1), position=(0.0, 0.0, -0.1))


def test_cylinder_standing_on_its_cap_on_a_box():
    """Cap down, 2 mm deep: the rim gives four points at depth 2 mm (closed form), normal +z (box -> cylinder),
    points midway: z = -1 mm, on the rim circle of radius r."""
    b = ModelBuilder(default_margin=0.01)
    _ground_box(b)
    r, h = 0.1, 0.15
    b.add_cylinder(b.add_body(position=(0.05, -0.02, h - 0.002)), r, h)
    shp, n, p, s, f = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert len(s) == 4 and s == pytest.approx([-0.002] * 4, abs=1e-12)
    assert p[:, 2] == pytest.approx([-0.001] * 4, abs=1e-12)
    assert np.hypot(p[:, 0] - 0.05, p[:, 1] + 0.02) == pytest.approx([r] * 4, abs=1e-12)
    assert len(set(f.tolist())) == 4


def test_cylinder_lying_on_a_box():
    """Axis horizontal (along y), 2 mm deep: two points at the ends of the lowest line, y = +-h, depth 2 mm."""
    b = ModelBuilder(default_margin=0.01)
    _ground_box(b)
    r, h = 0.1, 0.15
    b.add_cylinder(b.add_body(position=(0.0, 0.0, r - 0.002), orientation=_rot((1, 0, 0), math.pi / 2)), r, h)
    shp, n, p, s, f = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert s == pytest.approx([-0.002, -0.002], abs=1e-12)
    assert sorted(p[:, 1]) == pytest.approx([-h, h], abs=1e-12)
    assert p[:, 0] == pytest.approx([0, 0], abs=1e-12)


def test_hull_tetrahedron_on_a_hull_cube():
    """Tetrahedron base (a triangle at its local z = 0) 3 mm inside the cube's top face: three points, the
    base corners, depth 3 mm, normal along z from the cube to the tetrahedron."""
    b = ModelBuilder(default_margin=0.01)
    b.add_convex_hull(-1, CUBE)
    b.add_convex_hull(b.add_body(position=(0.01, 0.0, 0.1 - 0.003)), TETRA)
    c, m = _manifolds(b)
    shp, n, p, s, f = _only(c)
    cube_first = shp[0] == 0
    assert n == pytest.approx([0, 0, 1 if cube_first else -1], abs=1e-12)
    assert s == pytest.approx([-0.003] * 3, abs=1e-12)
    base = TETRA[:3, :2] + [0.01, 0.0]
    got = sorted(map(tuple, np.round(p[:, :2], 9)))
    assert got == sorted(map(tuple, np.round(base, 9)))
    assert p[:, 2] == pytest.approx([0.1 - 0.0015] * 3, abs=1e-12)


def test_box_on_a_tilted_hull_edge_gives_a_segment():
    """A hull cube rotated 45 deg about x rests on its edge on a box: two points at the edge's ends."""
    b = ModelBuilder(default_margin=0.01)
    _ground_box(b)
    e = 0.1 * math.sqrt(2.0)
    b.add_convex_hull(b.add_body(position=(0.0, 0.0, e - 0.001), orientation=_rot((1, 0, 0), math.pi / 4)), CUBE)
    shp, n, p, s, f = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert s == pytest.approx([-0.001, -0.001], abs=1e-12)
    assert sorted(p[:, 0]) == pytest.approx([-0.1, 0.1], abs=1e-12)


@pytest.mark.parametrize("ground", ["plane", "heightfield", "mesh"])
@pytest.mark.parametrize("kind", CONVEX)
def test_every_convex_shape_on_every_ground(ground, kind):
    """Each convex shape resting 2 mm deep on a flat plane, heightfield and triangle mesh (z = 0): the
    deepest separation is -2 mm (closed form) and the normal is vertical."""
    b = ModelBuilder(default_margin=0.01)
    if ground == "plane":
        b.add_plane()
    elif ground == "heightfield":
        b.add_heightfield(np.zeros((9, 9)), (0.25, 0.25))
    else:
        v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
        b.add_triangle_mesh(v, np.array([[0, 1, 2], [0, 2, 3]]))
    low = {"sphere": 0.1, "box": 0.12, "capsule": 0.2, "cylinder": 0.12, "hull": 0.1}[kind]
    _add(b, b.add_body(position=(0.013, 0.021, low - 0.002)), kind)
    shp, n, p, s, f = _only(_manifolds(b)[0])
    assert abs(n[2]) == pytest.approx(1.0, abs=1e-12)
    assert s.min() == pytest.approx(-0.002, abs=1e-12)


def _rest_height(build, seconds=2.0):
    b = ModelBuilder()
    body = build(b)
    w = RigidWorld(b.finalize())
    for _ in range(int(seconds * 60)):
        w.step()
    return w, body


def test_cylinder_standing_on_a_box_comes_to_rest_at_its_half_height():
    """Dropped from 5 mm, a cylinder (h = 0.15) on a static box top (z = 0) rests with its centre at
    z = h (closed form) within 0.5 mm, and still."""
    def build(b):
        _ground_box(b)
        body = b.add_body(position=(0.0, 0.0, 0.155))
        b.add_cylinder(body, 0.1, 0.15, density=500)
        return body
    w, body = _rest_height(build)
    assert w.state.body_q[body, 2] == pytest.approx(0.15, abs=5e-4)
    assert np.abs(w.state.body_qd[body]).max() < 1e-2


def test_hull_tetrahedron_resting_on_a_hull_cube():
    """A hull tetrahedron dropped flat on a static hull cube (top z = 0.1) rests with its base at z = 0.1:
    its centre of mass at 0.1 + (apex height / 4) (centroid of a tetrahedron) within 0.5 mm."""
    def build(b):
        b.add_convex_hull(-1, CUBE)
        body = b.add_body(position=(0.0, 0.0, 0.104))
        b.add_convex_hull(body, TETRA, density=500)
        return body
    w, body = _rest_height(build)
    # the body frame sits at the centre of mass: base plane + 0.15 / 4
    assert w.state.body_q[body, 2] == pytest.approx(0.1 + 0.15 / 4, abs=5e-4)
    assert np.abs(w.state.body_qd[body]).max() < 1e-2


# ------------------------------------------------------------------------------ box-capsule, exact
def _box_capsule(pos, q, r=0.05, hl=0.1, box=(0.2, 0.2, 0.1), margin=0.1):
    b = ModelBuilder(default_margin=margin)
    b.add_box(b.add_body(position=(0, 0, 0)), box)
    b.add_capsule(b.add_body(position=pos, orientation=q), r, hl)
    return _only(_manifolds(b)[0])


def test_box_capsule_parallel_to_a_face_gives_the_two_segment_ends():
    shp, n, p, s, f = _box_capsule((0.03, 0.02, 0.1 + 0.05 - 0.0015), _rot((0, 1, 0), math.pi / 2))
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert s == pytest.approx([-0.0015, -0.0015], abs=1e-12)
    assert sorted(p[:, 0]) == pytest.approx([0.03 - 0.1, 0.03 + 0.1], abs=1e-12)
    assert p[:, 2] == pytest.approx([0.1 - 0.00075] * 2, abs=1e-12)


def test_box_capsule_tilted_end_above_the_face():
    """Tilted 40 deg about y, lower end over the face: gap = c_z - hl cos(40) - hz - r (closed form)."""
    th = math.radians(40)
    cz = 0.1 + 0.05 + 0.1 * math.cos(th) + 0.004
    shp, n, p, s, f = _box_capsule((0.05, 0.0, cz), _rot((0, 1, 0), th))
    assert len(s) == 1 and s[0] == pytest.approx(0.004, abs=1e-9)
    assert n == pytest.approx([0, 0, 1], abs=1e-9)
    assert p[0] == pytest.approx([0.05 - 0.1 * math.sin(th), 0.0, 0.1 + 0.002], abs=1e-9)


@pytest.mark.parametrize("a", [0.05, 0.03])
def test_box_capsule_across_an_edge(a):
    """Segment in the plane y = 0 crossing the box's top +x edge at right angles, at distance sqrt(2) a from
    it: gap sqrt(2) a - r (separated for a = 0.05, overlapping for a = 0.03), normal (1, 0, 1)/sqrt(2)."""
    shp, n, p, s, f = _box_capsule((0.2 + a, 0.0, 0.1 + a), _rot((0, 1, 0), math.radians(135)))
    gap = math.sqrt(2.0) * a - 0.05
    assert len(s) == 1 and s[0] == pytest.approx(gap, abs=1e-9)
    assert n == pytest.approx([2 ** -0.5, 0, 2 ** -0.5], abs=1e-9)
    edge = np.array([0.2, 0.0, 0.1])
    assert p[0] == pytest.approx(edge + 0.5 * gap * n, abs=1e-9)


def test_box_capsule_segment_inside_the_box():
    """Core 2 cm under the top face: the shortest way out is up, depth 0.02 + r = 0.07 (closed form)."""
    shp, n, p, s, f = _box_capsule((0.0, 0.0, 0.08), _rot((0, 1, 0), math.pi / 2))
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert s == pytest.approx([-0.07, -0.07], abs=1e-12)
