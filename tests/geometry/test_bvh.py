"""BVH over triangles (inertia.geometry.bvh) against brute force."""

import numpy as np
import pytest

from inertia.geometry.bvh import LEAF_SIZE, build_bvh, bvh_query_box


def _random_tris(rng, n):
    c = rng.uniform(-10, 10, (n, 1, 3))
    return c + rng.normal(scale=0.4, size=(n, 3, 3))


def test_nodes_bound_their_triangles_and_partition_them():
    rng = np.random.default_rng(0)
    tv = _random_tris(rng, 500)
    order, bounds, nodes = build_bvh(tv)
    assert sorted(order.tolist()) == list(range(500))              # a permutation
    t = tv[order]
    seen = np.zeros(500, int)
    for k in range(len(nodes)):
        if nodes[k, 2] > 0:
            assert nodes[k, 2] <= LEAF_SIZE
            tri = t[nodes[k, 0]:nodes[k, 0] + nodes[k, 2]].reshape(-1, 3)
            assert np.all(tri >= bounds[k, :3]) and np.all(tri <= bounds[k, 3:])
            seen[nodes[k, 0]:nodes[k, 0] + nodes[k, 2]] += 1
        else:
            for child in nodes[k, :2]:                               # children inside the parent
                assert np.all(bounds[child, :3] >= bounds[k, :3]) and np.all(bounds[child, 3:] <= bounds[k, 3:])
    assert np.all(seen == 1)                                         # every triangle in exactly one leaf


def test_box_query_finds_every_overlapping_triangle():
    rng = np.random.default_rng(1)
    tv = _random_tris(rng, 2000)
    order, bounds, nodes = build_bvh(tv)
    t = tv[order]
    lo_t, hi_t = t.min(axis=1), t.max(axis=1)
    out = np.zeros(4096, np.int64)
    sizes = []
    for _ in range(200):
        lo = rng.uniform(-11, 10, 3)
        hi = lo + rng.uniform(0.1, 3.0, 3)
        n = bvh_query_box(bounds, nodes, 0, lo, hi, out)
        got = set(out[:n].tolist())
        assert len(got) == n                                          # no duplicates
        brute = set(np.flatnonzero(np.all(lo_t <= hi, axis=1) & np.all(hi_t >= lo, axis=1)).tolist())
        assert brute <= got                                           # nothing missed
        # exactly the triangles of the leaves whose boxes overlap (a leaf's ancestors contain it)
        leaves = set()
        for k in np.flatnonzero(nodes[:, 2] > 0):
            if np.all(bounds[k, :3] <= hi) and np.all(bounds[k, 3:] >= lo):
                leaves |= set(range(nodes[k, 0], nodes[k, 0] + nodes[k, 2]))
        assert got == leaves
        sizes.append(n)
    assert np.mean(sizes) < 100                                       # culls: 2000 triangles in all


def test_query_reports_overflow_count():
    rng = np.random.default_rng(2)
    tv = _random_tris(rng, 100)
    order, bounds, nodes = build_bvh(tv)
    small = np.zeros(5, np.int64)
    n = bvh_query_box(bounds, nodes, 0, np.full(3, -100.0), np.full(3, 100.0), small)
    assert n == 100


def test_bad_input():
    with pytest.raises(ValueError, match="tri_vertices"):
        build_bvh(np.zeros((0, 3, 3)))
