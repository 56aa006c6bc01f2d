"""Grid, random and Latin-hypercube designs and variant seeds (src/inertia/sweep/design.py)."""

import numpy as np
import pytest

from inertia.sweep.design import make_design, variant_seed
from inertia.sweep.params import Param, SweepInputError


def test_grid_is_the_product_in_order_last_fastest():
    a = Param("a", values=(1, 2))
    b = Param("b", values=("x", "y", "z"))
    rows = make_design([a, b], design="grid", samples=None, seed=0)
    assert rows == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 1, "b": "z"},
                    {"a": 2, "b": "x"}, {"a": 2, "b": "y"}, {"a": 2, "b": "z"}]


def test_grid_refuses_uncounted_ranges_and_samples():
    with pytest.raises(SweepInputError, match="needs a point count"):
        make_design([Param("a", low=0.0, high=1.0)], design="grid", samples=None, seed=0)
    with pytest.raises(SweepInputError, match="--samples goes with"):
        make_design([Param("a", values=(1,))], design="grid", samples=3, seed=0)
    with pytest.raises(SweepInputError, match="did you mean 'lhs'"):
        make_design([Param("a", values=(1,))], design="lhd", samples=3, seed=0)


def test_latin_hypercube_uses_every_stratum_once():
    # McKay, Beckman & Conover (1979): each of the n equal strata of every parameter holds one point
    n = 50
    params = [Param("a", low=0.0, high=1.0), Param("b", low=10.0, high=20.0)]
    rows = make_design(params, design="lhs", samples=n, seed=7)
    for key, lo, hi in (("a", 0.0, 1.0), ("b", 10.0, 20.0)):
        u = (np.array([r[key] for r in rows]) - lo) / (hi - lo)
        assert sorted(np.floor(u * n).astype(int)) == list(range(n))
    # seeded: the same design again, a different one for another seed
    assert rows == make_design(params, design="lhs", samples=n, seed=7)
    assert rows != make_design(params, design="lhs", samples=n, seed=8)


def test_latin_hypercube_balances_discrete_values():
    rows = make_design([Param("i", values=("rk4", "euler"))], design="lhs", samples=10, seed=1)
    assert sorted(r["i"] for r in rows).count("rk4") == 5


def test_random_design_is_uniform_in_log10():
    rows = make_design([Param("k", low=1.0, high=1e4, scale="log10")], design="random", samples=4000, seed=3)
    logs = np.log10([r["k"] for r in rows])
    # uniform on [0, 4]: mean 2, standard error 4/sqrt(12 * 4000) = 0.018; 5 sigma
    assert abs(logs.mean() - 2.0) < 5 * 4 / np.sqrt(12 * 4000)
    assert logs.min() >= 0 and logs.max() <= 4


def test_variant_seeds_are_fixed_functions_of_sweep_seed_and_index():
    # golden values: a change here changes every published sweep's variants
    assert [variant_seed(0, i) for i in range(3)] == GOLDEN_SEEDS
    seeds = {variant_seed(12, i) for i in range(1000)}
    assert len(seeds) == 1000 and all(0 <= s < 2 ** 31 for s in seeds)


GOLDEN_SEEDS = [821328062, 1817441348, 993632895]
