"""Particle-particle contact: broad phase against brute force, colouring, conservation laws,
Newton's cradle, a 10,000-sphere pile, determinism across thread counts."""

import numba
import numpy as np
import pytest

import inertia as ia
from inertia.collision import broadphase as bp

from .conftest import particles, state_hash

C = ia.colliders


def _pairs(x, radius, margin=0.0, dense=True):
    n = x.shape[0]
    cell = 2 * radius.max() + margin
    table = bp.table_size_for(n)
    lo, hi, dims = np.zeros(3), np.zeros(3), np.ones(3, np.int64)
    dense = dense and bp.grid_layout(x, cell, np.empty((bp.BOX_CHUNKS, 6)), lo, hi, dims, 4 * n)
    nbuckets = int(np.prod(dims)) if dense else table
    grid = (1 / cell, lo, dims, dense, table - 1)
    key, bucket = np.empty(n, np.int64), np.empty(n, np.int64)
    start, order = np.empty(max(table, nbuckets) + 1, np.int64), np.empty(n, np.int64)
    bp.bin_particles(x, radius, np.ones(n, bool), *grid, key, bucket)
    ns = bp.counting_sort(bucket, nbuckets, start, order)
    xs, rs, ks = np.empty_like(x), np.empty(n), np.empty(n, np.int64)
    bp.gather(order, ns, x, xs)
    bp.gather(order, ns, radius, rs)
    bp.gather(order, ns, key, ks)
    counts, pstart = np.empty(n, np.int64), np.empty(n + 1, np.int64)
    bp.count_pairs(xs, rs, ks, *grid, start, ns, margin, counts)
    total = bp.exclusive_scan(counts, ns, pstart)
    pi, pj = np.empty(total, np.int64), np.empty(total, np.int64)
    bp.fill_pairs(xs, rs, ks, *grid, start, ns, margin, pstart, pi, pj)
    # back to particle indices, smaller first
    a, b = order[pi], order[pj]
    pi, pj = np.minimum(a, b), np.maximum(a, b)
    return pi, pj


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("dense", [True, False])
def test_grid_pairs_equal_brute_force(dim, dense):
    # dense grid and spatial hash find exactly the pairs with |x_i - x_j| < r_i + r_j
    rng = np.random.default_rng(1)
    n = 3000
    x = rng.uniform(-1, 1, size=(n, dim)) * (0.6 if dim == 3 else 0.3)
    radius = rng.uniform(0.005, 0.02, n)
    pi, pj = _pairs(x, radius, dense=dense)
    found = set(zip(pi.tolist(), pj.tolist(), strict=True))
    dist = np.linalg.norm(x[:, None] - x[None], axis=-1)
    i, j = np.nonzero(np.triu(dist < radius[:, None] + radius[None], 1))
    assert found == set(zip(i.tolist(), j.tolist(), strict=True))
    assert len(found) == pi.size  # no duplicates


def test_colouring_makes_write_disjoint_batches():
    rng = np.random.default_rng(2)
    x = rng.uniform(0, 1, size=(4000, 3)) * 0.5
    radius = np.full(4000, 0.02)
    pi, pj = _pairs(x, radius)
    npairs = pi.size
    colour, order = np.empty(npairs, np.int64), np.empty(npairs, np.int64)
    start, cursor = np.zeros(bp.MAX_COLORS + 1, np.int64), np.zeros(bp.MAX_COLORS, np.int64)
    ncol = bp.color_pairs(pi, pj, npairs, np.zeros(4000, np.uint64), colour, start, order, cursor)
    assert 0 < ncol < bp.MAX_COLORS - 1
    for c in range(ncol):
        batch = order[start[c]:start[c + 1]]
        members = np.concatenate([pi[batch], pj[batch]])
        assert np.unique(members).size == members.size  # no particle twice in one colour
    assert np.array_equal(np.sort(order), np.arange(npairs))


def _row(n, gap, radius=0.5):
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * (2 * radius + gap)
    v = np.zeros((n, 3))
    v[0, 0] = 1.0
    ps = particles(x, v, radius=radius, gravity=False)
    ps.self_collisions = True
    C.configure_contacts(ps, self_restitution=1.0)
    return ps


@pytest.mark.parametrize("gap", [0.0, 0.01])
def test_newtons_cradle(gap):
    # 5 equal balls, restitution 1: momentum m v and energy m v^2 / 2 are conserved; with a small
    # gap every collision is a two-ball exchange, so the far ball leaves with the incoming speed
    # (in contact the solver's colour sweeps pass the impulse down the row the same way)
    ps = _row(5, gap)
    sim = ia.Simulation(ps, dt=1e-3)
    sim.run(0.2)
    np.testing.assert_allclose(ps.momentum(), [1.0, 0.0, 0.0], atol=1e-12)
    assert ps.kinetic_energy() == pytest.approx(0.5, rel=1e-12)
    np.testing.assert_allclose(ps.v[:, 0], [0, 0, 0, 0, 1.0], atol=1e-12)


def test_inelastic_pair_conserves_momentum():
    # unequal masses, restitution 0.3 and friction: sum m v is conserved to rounding
    rng = np.random.default_rng(4)
    x = rng.uniform(0, 0.3, size=(200, 3))
    ps = particles(x, rng.normal(0, 2, size=(200, 3)), radius=0.02, gravity=False,
                   masses=rng.uniform(0.5, 2.0, 200))
    ps.self_collisions = True
    C.configure_contacts(ps, self_restitution=0.3, self_friction=0.4)
    p0 = ps.momentum()
    sim = ia.Simulation(ps, dt=1e-3)
    sim.step()
    assert ps._collision.pair_count > 100
    sim.run(0.1)
    np.testing.assert_allclose(ps.momentum(), p0, atol=1e-12 * np.abs(p0).max() * 200)


def _pile(n_side=25, layers=16, r=0.02, seed=0, jitter=0.6):
    rng = np.random.default_rng(seed)
    spacing = (2.0 + jitter) * r
    g = (np.arange(n_side) - (n_side - 1) / 2) * spacing
    xs, ys, zs = np.meshgrid(g, g, r * (1 + jitter) + 0.002 + np.arange(layers) * spacing, indexing="ij")
    x = np.column_stack([xs.ravel(), ys.ravel(), zs.ravel()]) + rng.uniform(-jitter / 2, jitter / 2, (xs.size, 3)) * r
    ps = particles(x, radius=r)
    half = n_side * spacing / 2 + 3 * r
    ps.add_collider(C.Container(center=(0, 0, 1.0), half_extents=(half, half, 1.0)), restitution=0.2,
                    friction=0.4)
    ps.self_collisions = True
    C.configure_contacts(ps, self_restitution=0.2, self_friction=0.4, iterations=8)
    return ps


def test_ten_thousand_sphere_pile_settles_without_explosion():
    # 10,000 spheres (r = 2 cm) dropped as a loose, jittered block into a box collapse into a
    # pile: energy only leaves (kinetic energy << the potential energy released), nothing is
    # thrown up or out, overlaps stay a small fraction of the radius and the pile comes to rest
    ps = _pile()
    assert ps.particle_count == 10_000
    r = 0.02
    sim = ia.Simulation(ps, integrator="semi_implicit_euler", dt=2e-3)
    top0, z0 = ps.x[:, 2].max(), ps.x[:, 2].mean()
    speeds = []
    for _ in range(8):
        sim.run(0.1)
        speeds.append(np.sqrt(np.mean(np.sum(ps.v ** 2, axis=1))))
        assert np.all(np.isfinite(ps.state))
        assert ps.x[:, 2].max() <= top0  # nothing thrown up
    container = ps._collision.colliders[0]
    assert np.all(container.signed_distance(ps.x) >= r - 1e-6)  # inside the box
    released = 9.81 * (z0 - ps.x[:, 2].mean()) * ps.particle_count
    assert released > 0.0 and ps.kinetic_energy() < 1e-3 * released
    assert speeds[-1] < 0.06 and speeds[-1] < 0.1 * max(speeds)  # settling (rms speed, m/s)
    assert np.linalg.norm(ps.v, axis=1).max() < 1.0
    pi, pj = _pairs(ps.x, ps.radius)
    overlap = 2 * r - np.linalg.norm(ps.x[pi] - ps.x[pj], axis=1)
    assert overlap.max() < 0.25 * r


@pytest.mark.filterwarnings("ignore:.*start inside colliders")  # the sphere cuts into the block
def test_deterministic_at_1_and_2_threads(monkeypatch):
    # the same scene gives the same state at any Numba thread count (colour batches are
    # write-disjoint; all sorts are stable and serial)
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 Numba threads")
    # force the parallel kernels and the parallel colour batches, whatever the scene size
    monkeypatch.setattr(ia._jit, "SERIAL_BELOW", 0)
    hashes = []
    before = numba.get_num_threads()
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            ps = _pile(n_side=12, layers=8, seed=3)
            ps.add_collider(C.Sphere(center=(0.1, 0.0, 0.1), radius=0.1), restitution=0.5, friction=0.2)
            sim = ia.Simulation(ps, dt=2e-3)
            sim.run(0.16)  # the block lands at ~0.12 s: contacts with the floor, sphere and pairs
            hashes.append(state_hash(ps))
    finally:
        numba.set_num_threads(before)
    assert hashes[0] == hashes[1]
