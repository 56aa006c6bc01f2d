"""Parameter sweeps: many variants of one scene on dask.distributed, gathered into one table.

    import inertia as ia
    table = ia.sweep("bouncing_balls", {"particles[0].restitution": "0.1:0.9:9"},
                     metrics=["time_to_rest", "peak_z=peak(max(z))"])
    table[["particles[0].restitution", "time_to_rest"]]

``inertia sweep SCENE --param KEY=VALUES ... [--samples N --seed S] [--scheduler ADDRESS]
[--out DIR] [--resume]`` is the same from the command line (`inertia.cli.sweep`).

Modules: `params` (KEY=VALUES and key-path overrides), `design` (grid, random, Latin hypercube;
variant seeds), `metrics` (built-ins, the expression language, callables), `runner` (one
variant, the ``inertia run`` code path), `table` (journal, Parquet/CSV, plot), `engine`
(`sweep` itself: cluster, scheduling, fault tolerance, resume). Recipes for SLURM
(dask-jobqueue) and Kubernetes: ``docs/sweep.md``.

Needs the ``sweep`` extra: dask[distributed], pandas, pyarrow (`require_dependencies` says so
when they are missing).
"""

from .design import DESIGNS, make_design, variant_seed
from .engine import (DEFAULT_MAX_VARIANTS, DEFAULT_METRICS, SweepInterrupted, SweepProgress, require_dependencies,
                     sweep)
from .metrics import BUILTINS, QUANTITIES, Metric, compile_expression, parse_metric
from .params import Param, SweepInputError, apply_overrides, parse_key_path, parse_param
from .runner import OUTPUT_KINDS, run_variant, variant_data

__all__ = ["sweep", "SweepProgress", "SweepInterrupted", "SweepInputError", "Param", "Metric", "parse_param",
           "parse_metric", "parse_key_path", "apply_overrides", "compile_expression", "make_design", "variant_seed",
           "run_variant", "variant_data", "require_dependencies", "BUILTINS", "QUANTITIES", "DESIGNS",
           "OUTPUT_KINDS", "DEFAULT_METRICS", "DEFAULT_MAX_VARIANTS"]


# `ia.sweep(...)`: the package itself calls `sweep`, so exporting it from `inertia` as ``from . import sweep``
# keeps both ``ia.sweep(scene, params)`` and ``ia.sweep.params`` working (a function of the same name as
# the package would hide the package from ``import inertia.sweep as s``).
import sys as _sys
import types as _types


class _CallablePackage(_types.ModuleType):
    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


_sys.modules[__name__].__class__ = _CallablePackage
