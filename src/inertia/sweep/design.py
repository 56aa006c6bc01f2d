"""Sweep designs: full grids, seeded random samples and Latin hypercubes, and variant seeds.

- ``grid``: the Cartesian product of every parameter's discrete values, in the order the
  parameters were given (the last one varies fastest).
- ``random``: ``samples`` independent draws; continuous ranges uniform (in log10 for log10
  ranges), discrete values with equal probability.
- ``lhs``: a Latin hypercube of ``samples`` points (McKay, Beckman and Conover 1979, "A
  comparison of three methods for selecting values of input variables in the analysis of output
  from a computer code", Technometrics 21(2)): each parameter's unit interval is cut into
  ``samples`` equal strata, each stratum is used exactly once (a random permutation per
  parameter) at a uniform position inside it. Discrete values are mapped from the strata, so
  each value appears ``samples / len(values)`` times (up to rounding).

Random numbers come from NumPy's PCG64 seeded with ``SeedSequence([seed, 0x5EED])``: the
same seed and parameters give the same design on any machine.

Each variant's scene seed (``simulation.seed``) is ``variant_seed(seed, index)``, a 31-bit
integer drawn from ``SeedSequence([seed, index])``, unless ``simulation.seed`` is itself
swept. A variant therefore does not depend on which worker runs it or on the other variants.

Limitations: no space-filling optimisation of the hypercube (maximin, orthogonal arrays); no
constraints between parameters.
"""

from __future__ import annotations

import itertools

import numpy as np

from .params import Param, SweepInputError

__all__ = ["DESIGNS", "make_design", "variant_seed", "design_size"]

DESIGNS = ("grid", "random", "lhs")

_DESIGN_STREAM = 0x5EED


def variant_seed(sweep_seed: int, index: int) -> int:
    """The scene seed of variant `index` of a sweep seeded `sweep_seed` (0 <= seed < 2**31)."""
    state = np.random.SeedSequence([int(sweep_seed), int(index)]).generate_state(1, dtype=np.uint32)[0]
    return int(state) & 0x7FFFFFFF


def design_size(params: list[Param], design: str, samples: int | None) -> int:
    if design == "grid":
        size = 1
        for p in params:
            size *= len(p.values)
        return size
    return int(samples)


def make_design(params: list[Param], *, design: str, samples: int | None, seed: int) -> list[dict]:
    """The variants' parameter values: a list of ``{key: value}`` in variant order."""
    if design not in DESIGNS:
        from ..scene.errors import did_you_mean
        raise SweepInputError(f"--design must be one of {', '.join(DESIGNS)} (got {design!r})"
                              + did_you_mean(design, DESIGNS, show_allowed=False))
    keys = [p.key for p in params]
    if len(set(keys)) != len(keys):
        dup = next(k for k in keys if keys.count(k) > 1)
        raise SweepInputError(f"--param {dup}: given twice")
    if design == "grid":
        if samples is not None:
            raise SweepInputError("--samples goes with --design random or lhs; a grid has one variant per combination")
        for p in params:
            if p.continuous:
                raise SweepInputError(f"--param {p.key}: a continuous range needs a point count for a grid "
                                      f"(lo:hi:N), or use --samples N for a random or Latin-hypercube design")
        return [dict(zip(keys, combo)) for combo in itertools.product(*(p.values for p in params))]
    if samples is None or samples < 1:
        raise SweepInputError(f"--design {design} needs --samples N with N >= 1 (got {samples})")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), _DESIGN_STREAM]))
    columns = []
    for p in params:
        if design == "random":
            u = rng.random(samples)
        else:
            strata = rng.permutation(samples)
            u = (strata + rng.random(samples)) / samples
        columns.append(p.from_unit(u))
    return [dict(zip(keys, row)) for row in zip(*columns)]
