"""The sweep engine: a design of variants of one scene, run on dask.distributed, gathered into a table.

Stages of `sweep`:

1. ``read``     the scene (file, bundled example name, or `inertia.scene.Scene`), its raw data;
2. ``design``   parameters -> variants (`inertia.sweep.design`), limit check, every distinct
                value validated once against the scene models (errors name the key path);
3. ``resume``   with an output folder: ``sweep.json`` must match; finished variants are read
                from ``journal.jsonl`` and skipped;
4. ``cluster``  the given client, a scheduler address (connected within ``connect_timeout``),
                or an embedded `LocalCluster` on 127.0.0.1 (one single-threaded worker process
                per core, Numba threads per worker = cores // workers);
5. ``run``      one task per variant (`inertia.sweep.runner.run_variant`); rows are journalled
                as they arrive; the table is rewritten atomically every few seconds;
6. ``finish``   Parquet + CSV, the summary plot, the DataFrame.

Fault tolerance: a variant that fails is a row with its error (the runner never raises); a worker
process that dies has its variants rescheduled by dask (``distributed.scheduler.allowed-failures``,
3 by default); a variant lost beyond that is recorded with status ``lost`` and is the only kind a
resume runs again. Rows are keyed by variant index, so the table never holds a variant twice.

Reference: Rocklin, M. (2015), "Dask: Parallel computation with blocked algorithms and task
scheduling", Proc. 14th Python in Science Conference (the scheduler this builds on).

Limitations: every task carries the whole scene data (fine for scenes up to a few MB; very
large explicit position lists make submission slower); the ETA assumes variants of similar cost.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .design import design_size, make_design, variant_seed
from .metrics import Metric, parse_metric
from .params import Param, SweepInputError, _freeze, apply_overrides, parse_param, thaw
from .runner import OUTPUT_KINDS, _cell, run_variant
from .table import (CSV_NAME, JOURNAL_NAME, PARQUET_NAME, PLOT_NAME, SPEC_NAME, Journal, plot_summary,
                    rows_to_frame, write_table)

__all__ = ["sweep", "SweepProgress", "DEFAULT_METRICS", "DEFAULT_MAX_VARIANTS", "require_dependencies",
           "SweepInterrupted"]

DEFAULT_METRICS = ("final_energy", "time_to_rest", "max_penetration")
DEFAULT_MAX_VARIANTS = 10_000
TABLE_INTERVAL = 2.0          # seconds between atomic rewrites of the table while running
SPEC_VERSION = 1


class SweepInterrupted(Exception):
    """The sweep stopped early (Ctrl-C or ``stop_after``); ``frame`` holds the rows so far."""

    def __init__(self, message: str, frame):
        super().__init__(message)
        self.frame = frame


@dataclass
class SweepProgress:
    """Handed to the progress callback after every finished variant (and at the start)."""

    total: int            # variants in the design
    completed: int        # finished (any status), skipped ones from a resume included
    failed: int           # of them: diverged, error or lost
    running: int          # submitted and not finished, at most the workers' threads
    skipped: int          # finished in an earlier session (resume)
    elapsed: float        # seconds in this session
    eta: float | None     # seconds left (None until a variant finished in this session)
    dashboard: str | None
    client: Any = None


def require_dependencies() -> None:
    """Raise SweepInputError naming the extra when dask.distributed, pandas or pyarrow are missing."""
    missing = []
    for module in ("distributed", "pandas", "pyarrow"):
        try:
            __import__(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise SweepInputError(f"inertia sweep needs {', '.join(missing)} (not installed): "
                              "pip install 'inertia[sweep]'  (dask[distributed], pandas, pyarrow)")


# ---- reading the scene -----------------------------------------------------------------------------
def _read(scene):
    import tomllib

    from ..scene import Scene, read_scene

    if isinstance(scene, Scene):
        loaded = scene
    else:
        path = Path(scene)
        if not path.exists():
            examples = Path(__file__).resolve().parent.parent / "examples"
            stem = path.stem if path.suffix in (".toml", ".json") else path.name
            if path.parent == Path(".") and (examples / f"{stem}.toml").exists():
                path = examples / f"{stem}.toml"
        loaded = read_scene(path)
    data = json.loads(loaded.text) if loaded.format == "json" else tomllib.loads(loaded.text)
    return loaded, data


def _params(params, data) -> list[Param]:
    if isinstance(params, (str, Param)):
        params = [params]
    out = []
    items = params.items() if isinstance(params, dict) else [(None, p) for p in params]
    for key, spec in items:
        if isinstance(spec, Param):
            out.append(spec)
        elif key is None:
            out.append(parse_param(str(spec), data))
        elif isinstance(spec, str):
            out.append(parse_param(f"{key}={spec}", data))
        elif isinstance(spec, (list, tuple)):
            if not spec:
                raise SweepInputError(f"param {key}: no values given (empty range)")
            out.append(Param(parse_param(f"{key}=0").key, values=tuple(_freeze(v) for v in spec)))
        else:
            raise SweepInputError(f"param {key}: give a list of values or a VALUES text such as '0.1:0.9:5' "
                                  f"(got {spec!r})")
    if not out:
        raise SweepInputError("a sweep needs at least one --param KEY=VALUES")
    return out


def _metrics(metrics) -> list[Metric]:
    if metrics is None:
        metrics = DEFAULT_METRICS
    if isinstance(metrics, (str, Metric)) or callable(metrics):
        metrics = [metrics]
    out = []
    items = metrics.items() if isinstance(metrics, dict) else [(None, m) for m in metrics]
    for name, spec in items:
        out.append(spec if isinstance(spec, Metric) else parse_metric(spec, name))
    names = [m.name for m in out]
    for n in names:
        if names.count(n) > 1:
            raise SweepInputError(f"--metric {n}: given twice")
        if n in ("variant", "seed", "status", "error", "wall_time", "cpu_time", "pid"):
            raise SweepInputError(f"--metric {n}: the name is taken by a table column; choose another")
    if not out:
        raise SweepInputError("a sweep needs at least one metric")
    return out


def _check_values(params: list[Param], data: dict, source) -> None:
    """Validate every distinct value (ends of continuous ranges) once, alone on the base scene."""
    from ..scene import validate
    from ..scene.errors import SceneError

    for p in params:
        for value in p.checked_values():
            try:
                validate(apply_overrides(data, {p.key: thaw(value)}), source)
            except SceneError as exc:
                problems = "; ".join(str(i) for i in exc.issues)
                raise SweepInputError(f"--param {p.key}={value!r}: {problems}") from None


# ---- the cluster -------------------------------------------------------------------------------------
def _usable_cores() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def _connect(client, scheduler, workers, dashboard, connect_timeout):
    """Yield (client or None for in-process, numba threads per variant, dashboard link)."""
    if client == "serial":
        yield None, None, None
        return
    if client is not None:
        yield client, None, getattr(client, "dashboard_link", None)
        return
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            c = Client(scheduler, timeout=f"{float(connect_timeout)}s")
        except (OSError, TimeoutError) as exc:
            raise SweepInputError(f"--scheduler {scheduler}: cannot reach a dask scheduler there within "
                                  f"{connect_timeout:g} s ({type(exc).__name__}: {exc})") from None
        except ValueError as exc:
            raise SweepInputError(f"--scheduler {scheduler}: not a scheduler address ({exc}); "
                                  "e.g. tcp://10.0.0.5:8786") from None
        try:
            yield c, None, c.dashboard_link
        finally:
            c.close()
        return
    cores = _usable_cores()
    n = cores if workers is None else int(workers)
    if n < 1:
        raise SweepInputError(f"--workers must be >= 1 (got {workers})")
    threads = max(1, cores // n)
    src = str(Path(__file__).resolve().parents[2])
    env = {"NUMBA_NUM_THREADS": str(threads), "OMP_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join(dict.fromkeys([src, *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]))}
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address="127.0.0.1:0" if dashboard else None,
                           scheduler_kwargs=None if dashboard else {"dashboard": False},
                           silence_logs=logging.ERROR, env=env)
    try:
        c = Client(cluster)
        try:
            yield c, threads, c.dashboard_link if dashboard else None
        finally:
            c.close()
    finally:
        cluster.close()


# ---- the sweep ---------------------------------------------------------------------------------------
def _spec(loaded, params, design, samples, seed, metrics) -> dict:
    return {"version": SPEC_VERSION,
            "scene": loaded.name,
            "scene_sha256": hashlib.sha256(loaded.text.encode()).hexdigest(),
            "params": [{"key": p.key, "values": None if p.values is None else [thaw(v) for v in p.values],
                        "low": p.low, "high": p.high, "scale": p.scale, "integer": p.integer} for p in params],
            "design": design, "samples": samples, "seed": seed,
            "metrics": [{"name": m.name, "definition": m.describe()} for m in metrics]}


def _prepare_out(out: Path, spec: dict, *, resume: bool, overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise SweepInputError(f"--out {out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepInputError(f"--out: cannot create {out}: {exc.strerror or exc}") from None
    from ..io import remove_stale_partials, write_text_atomic

    remove_stale_partials(out)
    spec_path = out / SPEC_NAME
    if resume:
        if not spec_path.exists():
            raise SweepInputError(f"nothing to resume: {out} has no {SPEC_NAME} (run without --resume)")
        old = json.loads(spec_path.read_text(encoding="utf-8"))
        diffs = [k for k in spec if old.get(k) != spec[k]]
        if diffs:
            raise SweepInputError(f"cannot resume the sweep in {out}: {', '.join(diffs)} changed since it started "
                                  "(run without --resume and with --overwrite to start over)")
        return
    if spec_path.exists() or (out / JOURNAL_NAME).exists():
        if not overwrite:
            raise SweepInputError(f"{out} already holds a sweep; pass --resume to continue it or --overwrite to replace it")
        for name in (JOURNAL_NAME, PARQUET_NAME, CSV_NAME, PLOT_NAME):
            with contextlib.suppress(FileNotFoundError):
                (out / name).unlink()
        shutil.rmtree(out / "variants", ignore_errors=True)
    write_text_atomic(spec_path, json.dumps(spec, indent=2) + "\n")


def sweep(scene, params, metrics=None, *, client=None, design: str | None = None, samples: int | None = None,
          seed: int | None = None, scheduler: str | None = None, workers: int | None = None, out=None,
          resume: bool = False, overwrite: bool = False, outputs=(), max_variants: int = DEFAULT_MAX_VARIANTS,
          connect_timeout: float = 10.0, dashboard: bool = True,
          progress: Callable[[SweepProgress], None] | None = None, stop_after: int | None = None):
    """Run variants of a scene over a design of parameters; returns a pandas DataFrame, one row per variant.

    Parameters
    ----------
    scene : a scene file, a bundled example name, or an `inertia.scene.Scene`.
    params : ``{"particles[0].restitution": [0.2, 0.5, 0.8], "simulation.dt": "1e-4:1e-2:5:log10"}`` or a
        list of ``"KEY=VALUES"`` texts (see `inertia.sweep.params` for the VALUES forms).
    metrics : built-in names, ``"NAME=EXPR"`` texts, or ``{name: expression text | callable(world) |
        object with observe(world)/result(world)}``; default final_energy, time_to_rest, max_penetration.
    client : a ``distributed.Client`` to run on; ``"serial"`` runs the variants one after another in this
        process (debugging, baselines); None: `scheduler` or an embedded LocalCluster.
    design : "grid" (default without `samples`), "random" or "lhs" (default with `samples`).
    samples : variants of a random or Latin-hypercube design.
    seed : the sweep seed (design draws and variant seeds); default the scene's simulation.seed.
    scheduler : address of a running dask scheduler (``tcp://host:8786``).
    workers : LocalCluster worker processes (default: one per usable core).
    out : folder for sweep.json, journal.jsonl, results.parquet/.csv, summary.png and variants/; None keeps
        everything in memory.
    resume : continue the sweep in `out`, skipping variants already finished.
    overwrite : replace a sweep already in `out`.
    outputs : heavy per-variant outputs written into ``out/variants/NNNNN/``: any of "scene" (the variant as a
        scene.json ``inertia run`` takes), "states" (state file + checkpoint), "plot", "mp4", "gif".
    max_variants : refuse larger designs (10 000 default; raise it deliberately).
    connect_timeout : seconds to reach `scheduler` before giving up.
    dashboard : serve the dask dashboard of an embedded cluster (on 127.0.0.1, a free port).
    progress : ``callback(SweepProgress)`` after every finished variant.
    stop_after : stop after this many variants finished in this session (tests; raises SweepInterrupted).

    Raises `SweepInputError` (a ValueError) for bad requests, `inertia.scene.SceneError` for a bad scene.
    The DataFrame columns: variant, seed, one per parameter (its key path), one per metric, status
    ("completed", "diverged", "error", "lost"), error, wall_time and cpu_time (s, of the process that ran
    the variant, from scene validation to the last metric), pid (that process).
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise SweepInputError(f"--workers must be an integer >= 1 (got {workers!r})")
    if not isinstance(max_variants, int) or isinstance(max_variants, bool) or max_variants < 1:
        raise SweepInputError(f"--max-variants must be an integer >= 1 (got {max_variants!r})")
    started = time.perf_counter()
    loaded, data = _read(scene)
    params = _params(params, data)
    metric_list = _metrics(metrics)
    outputs = tuple(outputs or ())
    for kind in outputs:
        if kind not in OUTPUT_KINDS:
            from ..scene.errors import did_you_mean
            raise SweepInputError(f"--outputs: unknown output {kind!r}" + did_you_mean(kind, OUTPUT_KINDS))
    if outputs and out is None:
        raise SweepInputError("per-variant outputs need an output folder (--out)")
    design = design or ("grid" if samples is None else "lhs")
    seed = int(loaded.model.simulation.seed if seed is None else seed)
    if seed < 0:
        raise SweepInputError(f"--seed must be >= 0 (got {seed})")
    for p in params:
        if p.values is None and design == "grid":
            make_design([p], design="grid", samples=None, seed=seed)      # the clear message
    if design in ("random", "lhs") and (samples is None or samples < 1):
        raise SweepInputError(f"--design {design} needs --samples N with N >= 1 (got {samples})")
    size = design_size(params, design, samples) if design in ("grid", "random", "lhs") else 0
    if size > max_variants:
        raise SweepInputError(f"the design has {size:,} variants, more than the limit of {max_variants:,}; "
                              f"raise it with --max-variants {size}")
    require_dependencies()       # after the design's size is known: a refusal needs no dask
    variants = make_design(params, design=design, samples=samples, seed=seed)
    _check_values(params, data, loaded.path)

    spec = _spec(loaded, params, design, samples, seed, metric_list)
    keys = [p.key for p in params]
    names = [m.name for m in metric_list]
    journal = None
    done: dict[int, dict] = {}
    if out is not None:
        out = Path(out)
        _prepare_out(out, spec, resume=resume, overwrite=overwrite)
        journal = Journal(out / JOURNAL_NAME)
        if resume:
            done = {i: r for i, r in journal.read().items() if r.get("status") != "lost" and i < len(variants)}
    elif resume:
        raise SweepInputError("--resume needs the output folder of the sweep (--out)")

    job = {"scene_data": data, "scene_path": str(loaded.path) if loaded.path else None, "metrics": metric_list,
           "outputs": outputs, "out_dir": str(out) if out is not None else None, "numba_threads": None}
    todo = [i for i in range(len(variants)) if i not in done]
    skipped = len(done)
    rows = dict(done)
    state = {"finished": 0, "failed": sum(1 for r in done.values() if r.get("status") != "completed"),
             "last_table": time.perf_counter()}

    def flush_table(final=False):
        if out is None:
            return
        frame = rows_to_frame(rows, keys, names)
        write_table(frame, out)
        if final and len(frame):
            try:
                plot_summary(frame, params, names, out / PLOT_NAME)
            except Exception as exc:  # noqa: BLE001 - a plot must not lose the table
                logging.getLogger(__name__).warning("summary plot not written: %s", exc)
        state["last_table"] = time.perf_counter()

    def record(row, *, running, link, client_obj):
        rows[row["variant"]] = row
        if journal is not None:
            journal.append([row])
        state["finished"] += 1
        if row["status"] != "completed":
            state["failed"] += 1
        if out is not None and time.perf_counter() - state["last_table"] > TABLE_INTERVAL:
            flush_table()
        report(running, link, client_obj)

    def report(running, link, client_obj):
        if progress is None:
            return
        elapsed = time.perf_counter() - session_start
        n = state["finished"]
        eta = elapsed / n * (len(todo) - n) if n else None
        progress(SweepProgress(len(variants), skipped + n, state["failed"], running, skipped, elapsed, eta,
                               link, client_obj))

    session_start = time.perf_counter()
    interrupted = None
    # nothing left to run (a finished sweep resumed): no cluster is started
    connection = _connect(client, scheduler, workers, dashboard, connect_timeout) if todo else \
        contextlib.nullcontext((None, None, None))
    with connection as (c, threads, link):
        job["numba_threads"] = threads
        report(0, link, c)
        try:
            if c is None:
                for i in todo:
                    record(run_variant(job, i, variants[i], variant_seed(seed, i)), running=1, link=None, client_obj=None)
                    if stop_after is not None and state["finished"] >= stop_after and state["finished"] < len(todo):
                        interrupted = f"stopped after {state['finished']} variants"
                        break
            else:
                interrupted = _run_on_cluster(c, job, todo, variants, seed, spec, record, stop_after, state, link)
        except KeyboardInterrupt:
            interrupted = "interrupted"
    flush_table(final=interrupted is None)
    frame = rows_to_frame(rows, keys, names)
    frame.attrs.update({"sweep_seed": seed, "design": design, "computed": state["finished"], "skipped": skipped,
                        "seconds": time.perf_counter() - started, "dashboard": link,
                        "out": str(out) if out is not None else None})
    if interrupted:
        raise SweepInterrupted(f"{interrupted}: {len(rows)} of {len(variants)} variants finished"
                               + (f"; continue with --resume (--out {out})" if out is not None else ""), frame)
    return frame


def _run_on_cluster(c, job, todo, variants, seed, spec, record, stop_after, state, link):
    from distributed import as_completed

    token = hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:12]
    stamp = f"{time.time_ns():x}"
    futures = [c.submit(run_variant, job, i, variants[i], variant_seed(seed, i),
                        key=f"inertia-variant-{token}-{stamp}-{i:06d}", pure=False) for i in todo]
    index_of = {f.key: i for f, i in zip(futures, todo)}
    slots = max(1, sum(c.nthreads().values())) if todo else 1
    pending = len(futures)
    try:
        for future in as_completed(futures):
            pending -= 1
            i = index_of[future.key]
            if future.status == "finished":
                row = future.result()
            else:
                exc = future.exception()
                used = variants[i].get("simulation.seed", variant_seed(seed, i))
                row = {"variant": i, "seed": int(used) if isinstance(used, (int, float)) else -1,
                       **{k: _cell(v) for k, v in variants[i].items()},
                       "status": "lost", "error": f"{type(exc).__name__}: {exc}", "wall_time": math.nan,
                       "cpu_time": math.nan}
            record(row, running=min(pending, slots), link=link, client_obj=c)
            if stop_after is not None and state["finished"] >= stop_after and pending:
                return f"stopped after {state['finished']} variants"
        return None
    finally:
        c.cancel([f for f in futures if not f.done()])
