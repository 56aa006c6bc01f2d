"""Neighbour lists from the counting-sort grid equal a brute-force search (also periodic)."""

import numpy as np
import pytest

from inertia.fluids.sph import SPHFluid


def _brute(x, support, length, periodic):
    rel = x[:, None, :] - x[None, :, :]
    for d in range(x.shape[1]):
        if periodic[d]:
            rel[..., d] -= length[d] * np.round(rel[..., d] / length[d])
    r = np.linalg.norm(rel, axis=2)
    np.fill_diagonal(r, np.inf)
    return [set(np.flatnonzero(row < support)) for row in r]


@pytest.mark.parametrize("dim,periodic,stride,spacing", [(2, (False, False), None, 0.05),
                                                         (2, (True, False), None, 0.05),
                                                         (3, (True, True, True), None, 0.05),
                                                         (2, (False, False), 3, 0.05),
                                                         (2, (True, True), None, 1 / 6)])
def test_neighbour_lists_match_brute_force(dim, periodic, stride, spacing):
    # stride=3: the one-pass rows overflow (random points have up to ~15 neighbours here), so
    # the two-pass fill runs and the stride grows past the widest row. spacing 1/6: the
    # shortest period allowed (3 supports = 6 cells of half a support), where every block of
    # 5 x 5 cells wraps around on both axes (neighbours.REACH)
    rng = np.random.default_rng(3)
    lo, hi = np.zeros(dim), np.full(dim, 1.0)
    x = rng.uniform(0.0, 1.0, size=(400 if dim == 2 else 600, dim))
    fluid = SPHFluid(x, spacing=spacing, domain=(lo, hi), periodic=periodic, gravity=np.zeros(dim))
    fluid._finalize_boundary()
    from inertia.fluids.sph import kernels as K
    fluid._K = K.kernel_set(fluid.particle_count)
    fluid._sort_fluid()
    if stride is not None:
        fluid._stride, fluid._strided = stride, fluid._alloc_strided(stride)
    nl, total = fluid._neighbour_lists(fluid._F.x, fluid._cell_start, True, fluid._nf)
    if stride is not None:
        assert fluid._stride > np.diff(nl.start[:fluid.particle_count + 1]).max()
    xs = fluid.x.copy()
    want = _brute(xs, fluid.support, hi - lo, periodic)
    got = [set(nl.j[nl.start[i]:nl.start[i + 1]].tolist()) for i in range(fluid.particle_count)]
    assert got == want
    assert total == sum(len(s) for s in want)
    # the stored gradients are the kernel gradients of the minimum-image displacement
    i = 7
    js = nl.j[nl.start[i]:nl.start[i + 1]]
    rel = xs[i] - xs[js]
    for d in range(dim):
        if periodic[d]:
            rel[:, d] -= np.round(rel[:, d])
    from inertia.fluids.sph import kernel_gradient
    assert np.allclose(nl.g[nl.start[i]:nl.start[i + 1]], kernel_gradient("cubic_spline", rel, fluid.h))
