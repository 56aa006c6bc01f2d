"""Sort-and-sweep against brute force; filters (same body, static pairs, groups/masks)."""

import numpy as np

from inertia.geometry.broadphase import shape_world_bounds, sort_and_sweep
from inertia.model import ModelBuilder


def _bounds(m, dt=0.0):
    st = m.state()
    ns = m.shape_count
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shape_world_bounds(m.shapes(), m.body_type, m.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    return st, aabb


def _pairs(m, aabb, st, cap=4096):
    ns = m.shape_count
    pairs, keys = np.zeros((cap, 2), np.int32), np.zeros(cap, np.int64)
    n = sort_and_sweep(aabb, m.shapes(), m.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    return n, pairs[:n], keys[:n]


def test_sort_and_sweep_matches_brute_force():
    rng = np.random.default_rng(1)
    b = ModelBuilder(default_margin=0.01)
    for k in range(300):
        body = b.add_body(position=rng.uniform(-2, 2, 3))
        if k % 2:
            b.add_sphere(body, rng.uniform(0.05, 0.2))
        else:
            q = rng.normal(size=4)
            b.add_box(body, rng.uniform(0.05, 0.2, 3), orientation=q / np.linalg.norm(q))
    m = b.finalize()
    st, aabb = _bounds(m)
    n, pairs, keys = _pairs(m, aabb, st)
    expected = set()
    for i in range(m.shape_count):
        for j in range(i + 1, m.shape_count):
            if np.all(aabb[i, :3] <= aabb[j, 3:]) and np.all(aabb[j, :3] <= aabb[i, 3:]):
                expected.add((i, j))
    assert {tuple(sorted(p)) for p in pairs.tolist()} == expected
    assert np.all(np.diff(keys) > 0)                   # sorted, unique


def test_aabb_of_rotated_box_is_tight_plus_margin():
    b = ModelBuilder(default_margin=0.0)
    q = (np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8))   # 45 deg about z
    b.add_box(b.add_body(position=(1, 2, 3), orientation=q), (0.1, 0.1, 0.2))
    m = b.finalize()
    _, aabb = _bounds(m)
    r = 0.1 * np.sqrt(2)
    assert np.allclose(aabb[0], [1 - r, 2 - r, 2.8, 1 + r, 2 + r, 3.2])


def test_velocity_sweeps_the_box_forward_only():
    b = ModelBuilder(default_margin=0.0)
    b.add_sphere(b.add_body(position=(0, 0, 0), linear_velocity=(6.0, 0, 0)), 0.1)
    m = b.finalize()
    _, aabb = _bounds(m, dt=0.5)
    assert np.allclose(aabb[0], [-0.1, -0.1, -0.1, 3.1, 0.1, 0.1])


def test_filters_same_body_static_pairs_and_masks():
    b = ModelBuilder()
    b.add_plane()
    b.add_sphere(-1, 0.1)                               # static: never paired with the static plane
    one = b.add_body(position=(0, 0, 0.05))
    b.add_sphere(one, 0.1)
    b.add_sphere(one, 0.1, position=(0.05, 0, 0))       # same body: never paired with its sibling
    two = b.add_body(position=(0.1, 0, 0.05))
    b.add_sphere(two, 0.1, group=2, mask=~1)            # collides with nothing of group 1
    m = b.finalize()
    st, aabb = _bounds(m)
    n, pairs, _ = _pairs(m, aabb, st)
    got = {tuple(sorted(p)) for p in pairs.tolist()}
    assert got == {(0, 2), (0, 3), (1, 2), (1, 3)}
