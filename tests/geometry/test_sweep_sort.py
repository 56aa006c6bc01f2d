"""Sort-and-sweep's in-place merge sort keeps NumPy's order (the pair order is part of determinism)."""

import numpy as np

from inertia.geometry.broadphase import _stable_argsort_into


def test_stable_argsort_into_equals_numpy_mergesort_with_ties_and_nan():
    # the world's broad phase used np.argsort(kind="mergesort") (stable: ties by index, NaN last);
    # its scratch-based replacement must give the same permutation, or the candidate pairs, the
    # contact rows and the golden hashes change. Ties (integers), NaN, strided views (a column of the
    # AABB table) and int64 keys; sizes around the merge widths.
    rng = np.random.default_rng(0)
    for n in [0, 1, 2, 3, 7, 8, 9, 31, 64, 65, 257]:
        for trial in range(4):
            v = rng.integers(0, n // 3 + 1, n).astype(float) if trial < 3 else rng.normal(size=n)
            if trial == 2 and n:
                v[rng.integers(0, n, n // 4 + 1)] = np.nan
            idx, tmp = np.full(n, -1, np.int64), np.zeros(n, np.int64)
            table = np.zeros((n, 6))
            table[:, 1] = v
            _stable_argsort_into(table[:, 1], idx, tmp, n)
            np.testing.assert_array_equal(idx, np.argsort(v, kind="mergesort"))
            keys = rng.permutation(4 * n + 1)[:n].astype(np.int64)
            _stable_argsort_into(keys, idx, tmp, n)
            np.testing.assert_array_equal(idx, np.argsort(keys, kind="mergesort"))
