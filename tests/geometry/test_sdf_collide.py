"""Convex shapes against baked SDF rows (``inertia.geometry.sdf_collide``): samples, manifolds, scratch."""

import math

import numpy as np
import pytest

from inertia.collision.shapes import SDF
from inertia.dynamics.contacts import Contacts
from inertia.geometry import shapes as S
from inertia.geometry.broadphase import shape_world_bounds, sort_and_sweep
from inertia.geometry.narrowphase import compact_active, narrow_phase
from inertia.geometry.sdf_collide import SAMPLES_BOX, SAMPLES_CYLINDER, sample_point, sdf_arrays
from inertia.model import ModelBuilder, with_colliders


def _half_space(rest_point=(0.0, 0.0, 0.0)):
    """Baked SDF of z <= 0 (exact on the grid: the field is linear), its row frame at ``rest_point``."""
    return SDF(lambda p: p[:, 2], bake={"bounds": ((-3.0, -1.0, -0.5), (3.0, 1.0, 0.5)), "resolution": 12},
               rest_point=rest_point)


def _contacts(model, dt=1.0 / 60.0, cap=128):
    st = model.state()
    ns = model.shape_count
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shapes = model.shapes()
    shape_world_bounds(shapes, model.body_type, model.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    pairs, keys = np.zeros((cap, 2), np.int32), np.zeros(cap, np.int64)
    n = sort_and_sweep(aabb, shapes, model.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    c = Contacts(cap)
    narrow_phase(pairs, keys, n, shapes, pose, st.body_qd, model.body_bound_radius, dt, c.arrays(),
                 sdf=sdf_arrays(model))
    c.count = n
    c.active_count = compact_active(c.arrays(), n)
    return c, (pairs, n, shapes, pose, st.body_qd, model.body_bound_radius, dt, c.arrays())


def test_samples_lie_on_the_shape_surfaces():
    """Box: the 26 points of {-h, 0, h}^3 without the centre (corners first by index parity, all on the
    boundary); cylinder: 2 x 12 rim points at radius r on the caps and the two cap centres; capsule: both
    segment ends and the middle, each carrying the radius."""
    hb = np.array([0.3, 0.2, 0.1])
    pts = np.array([sample_point.py_func(S.BOX, k, hb, np.zeros((0, 3)), 0)[0] for k in range(SAMPLES_BOX)])
    assert len({tuple(p) for p in pts}) == 26
    assert np.all(np.max(np.abs(pts) / hb, axis=1) == 1.0)                # on the box's boundary
    assert np.sum(np.all(np.abs(pts) == hb, axis=1)) == 8                  # eight corners
    r, hh = 0.25, 0.4
    cyl = np.array([sample_point.py_func(S.CYLINDER, k, np.array([r, hh, 0, 0]), np.zeros((0, 3)), 0)[0]
                    for k in range(SAMPLES_CYLINDER)])
    assert np.allclose(np.hypot(cyl[:24, 0], cyl[:24, 1]), r, atol=1e-15)
    assert np.allclose(np.abs(cyl[:, 2]), hh) and np.allclose(cyl[24:, :2], 0.0)
    caps = [sample_point.py_func(S.CAPSULE, k, np.array([0.1, 0.3, 0, 0]), np.zeros((0, 3)), 0) for k in range(3)]
    assert [c[0][2] for c in caps] == [-0.3, 0.3, 0.0] and all(c[1] == 0.1 for c in caps)


def test_tilted_box_on_a_baked_half_space_gets_its_four_lowest_face_corners():
    """A box tilted 0.02 rad about x, its lowest edge 1 mm into the field z <= 0 (row frame off the origin, so
    the rest-frame offset in shape_params is used): normal -z (box A -> SDF B), four points, each the
    separation of its sample z_k (the linear field is exact on the grid), midway z_k / 2, feature = sample.
    The bottom face's nine samples are all within the 2 cm margin; the reduction keeps its corners."""
    a, hb = 0.02, np.array([0.3, 0.2, 0.1])
    zc = hb[2] * math.cos(a) + hb[1] * math.sin(a) - 0.001
    b = ModelBuilder()
    body = b.add_body(position=(0.4, 0.1, zc), orientation=(math.cos(a / 2), math.sin(a / 2), 0, 0))
    b.add_box(body, hb)
    model = with_colliders(b.finalize(), [_half_space(rest_point=(0.5, -0.3, 0.2))])
    assert model.shape_type[1] == S.SDF and model.shape_sdf_start[1, 0] >= 0
    c, _ = _contacts(model)
    act = c.manifolds()
    assert len(act) == 1
    i = act[0]
    k = c.contact_point_count[i]
    assert k == 4
    assert c.contact_normal[i] == pytest.approx([0, 0, -1], abs=1e-12)
    rot = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    for j in range(k):
        f = int(c.contact_feature[i, j])
        local = np.array(sample_point.py_func(S.BOX, f, hb, np.zeros((0, 3)), 0)[0])
        world = np.array([0.4, 0.1, zc]) + rot @ local
        assert c.contact_separation[i, j] == pytest.approx(world[2], abs=1e-12)
        assert c.contact_point[i, j] == pytest.approx([world[0], world[1], 0.5 * world[2]], abs=1e-12)
        assert np.all(np.abs(local) == hb)                                  # a corner
    # the two corners of the lowest edge, 1 mm deep, are among them
    assert np.sort(c.contact_separation[i, :k])[:2] == pytest.approx([-0.001, -0.001], abs=1e-12)


def test_sphere_above_a_baked_plane_is_speculative_within_the_margin_only():
    """A sphere's one sample (its centre, radius r): gap d - r kept when below the speculative distance
    (margin 0.02 m at rest), dropped beyond it."""
    for gap, expect in ((0.015, 1), (0.03, 0)):
        b = ModelBuilder()
        b.add_sphere(b.add_body(position=(0.0, 0.0, 0.1 + gap)), 0.1)
        c, _ = _contacts(with_colliders(b.finalize(), [_half_space()]))
        act = c.manifolds()
        assert len(act) == expect
        if expect:
            assert c.contact_separation[act[0], 0] == pytest.approx(gap, abs=1e-12)


def test_sdf_pairs_allocate_nothing_per_pair(alloc):
    """The samples' scratch rows are the run's row of the narrow phase's mesh bank (made once per world):
    Numba's NRT allocation counter, less the wrapping of the arguments, is zero over runs of 6 and 60 pairs
    (before the bank, each run made four arrays)."""
    from inertia.geometry.narrowphase import new_narrow_work, scene_mesh_rows
    from inertia.geometry.sdf_collide import _narrow_range_sdf
    for npairs in (6, 60):
        rng = np.random.default_rng(1)
        b = ModelBuilder()
        hull = rng.normal(size=(12, 3)) * 0.01
        for k in range(npairs):
            # each shape's lowest point 1 mm into the field
            z = -hull[:, 2].min() - 0.001 if k % 3 == 2 else 0.099
            body = b.add_body(position=(-2.8 + 5.6 * k / npairs, 0.0, z))
            [lambda: b.add_box(body, (0.02, 0.02, 0.1)), lambda: b.add_cylinder(body, 0.02, 0.1),
             lambda: b.add_convex_hull(body, hull)][k % 3]()
        model = with_colliders(b.finalize(), [_half_space()])
        c, (pairs, n, shapes, pose, qd, radius, dt, ca) = _contacts(model, cap=2 * npairs + 8)
        assert n == npairs and (c.contact_point_count[:n] > 0).all()
        bank = new_narrow_work(False, scene_mesh_rows(model.shape_type, model.shape_vert_count)).mesh
        args = (0, n, pairs, shapes, sdf_arrays(model), pose, qd, radius, dt, ca, bank, 3)
        _narrow_range_sdf(*args)
        assert alloc.kernel_allocations(lambda: _narrow_range_sdf(*args), 60) == {}, npairs
        assert (c.contact_point_count[:n] > 0).all()
