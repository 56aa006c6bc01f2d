"""World queries against closed forms and brute force over the shapes (inertia.rigid.queries)."""

import math

import numpy as np
import pytest

from inertia.geometry import shapes as S
from inertia.geometry.convex import build_convex_hull
from inertia.geometry.raycast import ray_cast as ray_cast_shape
from inertia.model import ModelBuilder
from inertia.rigid.queries import WorldQueries
from inertia.rigid.world import RigidWorld

CUBE = np.array([[x, y, z] for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (-0.3, 0.3)])
QZ30 = (math.cos(math.pi / 12), 0.0, 0.0, math.sin(math.pi / 12))   # 30 degrees about z


def scene():
    b = ModelBuilder(gravity=(0, 0, 0))
    b.add_plane()                                                       # 0: ground z <= 0
    b.add_sphere(-1, 0.5, position=(2.0, 0.0, 1.0))                     # 1: static sphere
    box = b.add_body(position=(0.0, 0.0, 1.0), orientation=QZ30)
    b.add_box(box, (0.5, 0.25, 0.4))                                    # 2: rotated box
    cap = b.add_body(position=(-2.0, 0.0, 1.0))
    b.add_capsule(cap, 0.2, 0.5)                                        # 3: vertical capsule
    hull = b.add_body(position=(0.0, 2.0, 1.0), mass=1.0, inertia=(0.1, 0.1, 0.1))
    b.add_convex_hull(hull, CUBE)                                       # 4: cube hull
    b.add_sphere(-1, 0.3, position=(0.0, -2.0, 1.0), group=2)           # 5: sphere in group 2
    b.add_cylinder(-1, 0.3, 0.2, position=(2.0, 2.0, 1.0))              # 6: upright cylinder
    model = b.finalize()
    world = RigidWorld(model, enable_sleep=False)
    return model, world, WorldQueries(world)


@pytest.fixture(scope="module")
def sc():
    return scene()


def test_ray_into_sphere_closed_form(sc):
    model, world, q = sc
    for b_off in (0.0, 0.2, 0.45):
        hit = q.ray_cast((2.0 + b_off, 0.0, 10.0), (0.0, 0.0, -20.0))
        z = 1.0 + math.sqrt(0.25 - b_off ** 2)                  # entry at |p - c| = r
        assert hit.shape == 1 and hit.body == -1
        np.testing.assert_allclose(hit.point, (2.0 + b_off, 0.0, z), atol=1e-12)
        np.testing.assert_allclose(hit.normal, (b_off / 0.5, 0.0, (z - 1.0) / 0.5), atol=1e-12)
        assert hit.fraction == pytest.approx((10.0 - z) / 20.0, abs=1e-14)
        assert hit.distance == pytest.approx(10.0 - z, abs=1e-12)
    # a ray that misses everything but the ground hits the plane at z = 0 with normal +z
    hit = q.ray_cast((5.0, 5.0, 3.0), (0.0, 0.0, -6.0))
    assert hit.shape == 0 and hit.fraction == pytest.approx(0.5)
    np.testing.assert_allclose(hit.normal, (0, 0, 1), atol=1e-15)
    assert q.ray_cast((5.0, 5.0, 3.0), (0.0, 0.0, -2.0)) is None    # too short


def test_ray_all_hits_sorted_and_rotated_box(sc):
    model, world, q = sc
    # along +x at z = 1: capsule (x = -2 -/+ 0.2), box, sphere (x = 2 -/+ 0.5)
    hits = q.ray_cast_all((-5.0, 0.0, 1.0), (10.0, 0.0, 0.0))
    assert [h.shape for h in hits] == [3, 2, 1]
    assert hits[0].point[0] == pytest.approx(-2.2, abs=1e-12)
    assert hits[2].point[0] == pytest.approx(1.5, abs=1e-12)
    # rotated box: the ray along x enters the face x' = -0.5 or y' = -0.25 of the box rotated 30 deg;
    # entry = max over slabs of the box frame (Kay-Kajiya) computed here by hand
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    d_local = np.array([c, -s])              # R^T (1, 0)
    o_local = np.array([c * -5.0, -s * -5.0])
    t_in = max(((-0.5 if d_local[0] > 0 else 0.5) - o_local[0]) / d_local[0],
               ((-0.25 if d_local[1] > 0 else 0.25) - o_local[1]) / d_local[1])
    assert hits[1].distance == pytest.approx(t_in, abs=1e-12)
    assert np.all(np.diff([h.fraction for h in hits]) > 0)


def test_ray_mask_and_group(sc):
    model, world, q = sc
    o, d = (0.0, -2.0, 5.0), (0.0, 0.0, -10.0)
    assert q.ray_cast(o, d).shape == 5
    assert q.ray_cast(o, d, mask=1).shape == 0            # group-2 sphere filtered: the ground is next
    assert q.ray_cast(o, d, mask=2).shape == 5
    assert q.ray_cast(o, d, mask=4) is None


def test_closest_ray_hit_equals_brute_force(sc):
    """AABB culling never drops the nearest hit: compare with ray_cast over every shape."""
    model, world, q = sc
    rng = np.random.default_rng(3)
    pose = q.shape_pose
    planes = build_convex_hull(CUBE).face_planes
    tris = np.zeros((0, 3), np.int32)
    n_hit = 0
    for _ in range(300):
        o = rng.uniform((-3, -3, 0.1), (3, 3, 3))
        d = rng.normal(size=3) * 5.0
        best, best_s = np.inf, -1
        for s in range(model.shape_count):
            fp = planes if model.shape_type[s] == S.CONVEX_HULL else np.zeros((0, 4))
            t, _ = ray_cast_shape(model.shape_type[s], model.shape_params[s], pose[s], model.geom_vertices,
                                  model.shape_vert_start[s], fp, 0, len(fp), tris, 0, 0, o, d, 1.0)
            if t < best:
                best, best_s = t, s
        hit = q.ray_cast(o, d)
        if best_s < 0:
            assert hit is None
        else:
            n_hit += 1
            assert hit.shape == best_s and hit.fraction == pytest.approx(best, abs=1e-12)
    assert n_hit > 100


def test_shape_cast_closed_forms(sc):
    model, world, q = sc
    # sphere r = 0.25 falling onto the static sphere: touches when the centres are 0.75 apart
    hit = q.shape_cast("sphere", (0.25,), (0.0, 0.0, -5.0), position=(2.0, 0.0, 5.0))
    assert hit.shape == 1
    assert hit.fraction == pytest.approx((5.0 - 1.75) / 5.0, abs=1e-6)
    np.testing.assert_allclose(hit.normal, (0, 0, -1), atol=1e-6)
    np.testing.assert_allclose(hit.point, (2.0, 0.0, 1.5), atol=1e-5)
    # a box tilted 30 deg about z dropped onto the ground far from the rest: lowest face at z = 0.3
    hit = q.shape_cast("box", (0.2, 0.2, 0.3), (0.0, 0.0, -4.0), position=(5.0, -5.0, 3.0), orientation=QZ30)
    assert hit.shape == 0 and hit.fraction == pytest.approx(2.7 / 4.0, abs=1e-12)
    # a capsule swept sideways into the cube hull: its side (radius 0.1) meets the face x = -0.3
    hit = q.shape_cast("capsule", (0.1, 0.2), (2.0, 0.0, 0.0), position=(-1.0, 2.0, 1.0))
    assert hit.shape == 4
    assert hit.fraction == pytest.approx((1.0 - 0.3 - 0.1) / 2.0, abs=1e-6)
    np.testing.assert_allclose(hit.normal, (1, 0, 0), atol=1e-5)
    # ignore_body skips the hull's own body; mask filters the group-2 sphere
    assert q.shape_cast("capsule", (0.1, 0.2), (2.0, 0.0, 0.0), position=(-1.0, 2.0, 1.0),
                        ignore_body=int(model.shape_body[4])) is None
    assert q.shape_cast("sphere", (0.1,), (0, 0, -3), position=(0.0, -2.0, 3.0), mask=1).shape == 0
    # a sweep that ends short of everything
    assert q.shape_cast("sphere", (0.1,), (0.0, 0.0, 1.0), position=(5.0, 5.0, 1.0)) is None


def _sphere_box_distance(c, r, centre, quat, h):
    w, x, y, z = quat
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    p = R.T @ (c - centre)
    outside = np.linalg.norm(np.maximum(np.abs(p) - h, 0.0))
    inside = min(0.0, np.max(np.abs(p) - h))
    return outside + inside - r


def test_overlap_sphere_brute_force(sc):
    """Sphere overlaps against closed-form signed distances of every shape."""
    model, world, q = sc
    rng = np.random.default_rng(7)
    r = 0.3
    pose = q.shape_pose
    n_nonempty = 0
    for _ in range(300):
        c = rng.uniform((-3, -3, 0.0), (3, 3, 2))
        d = {0: c[2] - r,
             1: np.linalg.norm(c - (2, 0, 1)) - 0.5 - r,
             2: _sphere_box_distance(c, r, pose[2, :3], pose[2, 3:], np.array((0.5, 0.25, 0.4))),
             3: np.linalg.norm(c - (-2.0, 0.0, np.clip(c[2], 0.5, 1.5))) - 0.2 - r,
             4: _sphere_box_distance(c, r, pose[4, :3], pose[4, 3:], np.full(3, 0.3)),
             5: np.linalg.norm(c - (0, -2, 1)) - 0.3 - r}
        rho, dz = math.hypot(c[0] - 2, c[1] - 2), abs(c[2] - 1.0)
        d[6] = math.hypot(max(rho - 0.3, 0), max(dz - 0.2, 0)) + min(0.0, max(rho - 0.3, dz - 0.2)) - r
        if min(abs(v) for v in d.values()) < 1e-6:
            continue
        expect = sorted(s for s, v in d.items() if v < 0)
        got = q.overlap("sphere", (r,), position=c)
        assert got.tolist() == expect, (c, d)
        n_nonempty += bool(expect)
    assert n_nonempty > 50


def test_overlap_box_and_hull_query(sc):
    model, world, q = sc
    # a thin box just above the ground overlapping the rotated box's base and nothing else
    assert q.overlap("box", (0.1, 0.1, 0.05), position=(0.0, 0.0, 0.65)).tolist() == [2]
    assert q.overlap("box", (0.1, 0.1, 0.05), position=(0.0, 0.0, 0.04)).tolist() == [0]
    assert q.overlap("convex_hull", None, vertices=CUBE, position=(0.0, 2.55, 1.0)).tolist() == [4]
    assert q.overlap("convex_hull", None, vertices=CUBE, position=(0.0, 2.65, 1.0)).tolist() == []


def test_closest_points_closed_forms(sc):
    model, world, q = sc
    # sphere (shape 1) to cylinder (shape 6): centres (2, 0, 1) and (2, 2, 1): gap 2 - 0.5 - 0.3
    cp = q.closest_points(1, 6)
    assert cp.distance == pytest.approx(1.2, abs=1e-9)
    np.testing.assert_allclose(cp.point_a, (2.0, 0.5, 1.0), atol=1e-9)
    np.testing.assert_allclose(cp.point_b, (2.0, 1.7, 1.0), atol=1e-9)
    np.testing.assert_allclose(cp.normal, (0, 1, 0), atol=1e-9)
    # rotated box (shape 2) to the ground: lowest face at z = 1 - 0.4
    cp = q.closest_points(2, 0)
    assert cp.distance == pytest.approx(0.6, abs=1e-12)
    np.testing.assert_allclose(cp.normal, (0, 0, -1), atol=1e-12)
    assert cp.point_b[2] == pytest.approx(0.0, abs=1e-12)
    cp = q.closest_points(0, 3)                                          # plane first: normal flips
    assert cp.distance == pytest.approx(1.0 - 0.5 - 0.2, abs=1e-12)
    np.testing.assert_allclose(cp.normal, (0, 0, 1), atol=1e-12)


def test_aabb_query_brute_force(sc):
    model, world, q = sc
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    ex_box = (c * 0.5 + s * 0.25, s * 0.5 + c * 0.25, 0.4)
    boxes = {1: ((2, 0, 1), (0.5,) * 3), 2: ((0, 0, 1), ex_box), 3: ((-2, 0, 1), (0.2, 0.2, 0.7)),
             4: ((0, 2, 1), (0.3,) * 3), 5: ((0, -2, 1), (0.3,) * 3), 6: ((2, 2, 1), (0.3, 0.3, 0.2))}
    rng = np.random.default_rng(11)
    for _ in range(200):
        lo = rng.uniform((-3, -3, -0.5), (3, 3, 2))
        hi = lo + rng.uniform(0.05, 1.5, 3)
        expect = [0] if lo[2] <= 0.0 else []
        for sh, (cen, ex) in boxes.items():
            if np.all(np.array(cen) - ex <= hi) and np.all(np.array(cen) + ex >= lo):
                expect.append(sh)
        assert q.aabb_query(lo, hi).tolist() == sorted(expect)


def test_queries_follow_the_moving_bodies():
    b = ModelBuilder()                                                  # gravity -9.81 z
    b.add_plane()
    ball = b.add_body(position=(0.0, 0.0, 5.0))
    b.add_sphere(ball, 0.5)
    world = RigidWorld(b.finalize())
    q = WorldQueries(world)
    world.step(30)
    z = world.state.body_q[ball, 2]
    hit = q.ray_cast((0.0, 0.0, 10.0), (0.0, 0.0, -20.0))
    assert hit.body == ball and hit.point[2] == pytest.approx(z + 0.5, abs=1e-12)
    assert z < 4.0


def test_bad_input(sc):
    model, world, q = sc
    with pytest.raises(ValueError, match="translation"):
        q.ray_cast((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="origin"):
        q.ray_cast((0, 0), (0, 0, 1))
    with pytest.raises(ValueError, match="shape_type"):
        q.overlap("plane", ())
    with pytest.raises(ValueError, match="params"):
        q.overlap("sphere", (-1.0,))
    with pytest.raises(ValueError, match="orientation"):
        q.overlap("sphere", (1.0,), orientation=(2, 0, 0, 0))
    with pytest.raises(ValueError, match="shape_b"):
        q.closest_points(0, 99)
    with pytest.raises(ValueError, match="lower"):
        q.aabb_query((1, 1, 1), (0, 0, 0))
