"""One variant of a sweep, run on a worker: the same code path as ``inertia run``.

`run_variant` writes the variant's values (and its seed) into the raw scene data, validates it
with the scene models, builds the world with `inertia.scene.build`, and runs it with
`inertia.world.Run` exactly as ``inertia run`` does (the state file and checkpoint go to a
scratch directory in memory, ``/dev/shm``, unless ``states`` outputs were asked for). The metrics sample the world
after every recorded frame through the run's progress callback, so nothing in the loop changes.

Every failure is a row, never an exception: ``status`` is ``completed``, ``diverged`` (a
`SimulationDiverged`, metrics NaN) or ``error`` (a value the scene models refuse, or any other
exception, with its message). Only a dying worker process loses a variant; the scheduler then
runs it again elsewhere.

Limitations: the scene's relative file references (meshes, grids) resolve against the original
scene file's folder; a written ``scene.json`` next to a variant's outputs resolves them against
that folder instead (copy the referenced files, or run it with ``inertia run`` from a copy).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

from .params import apply_overrides, thaw

__all__ = ["run_variant", "variant_data", "OUTPUT_KINDS", "variant_folder"]

#: Heavy outputs a sweep writes per variant only when asked.
OUTPUT_KINDS = ("scene", "states", "plot", "mp4", "gif")


def variant_folder(out_dir, index: int) -> Path:
    return Path(out_dir) / "variants" / f"{index:05d}"


def variant_data(job: dict, values: dict, seed: int) -> dict:
    """The raw scene data of a variant: the base scene with its values and seed written in."""
    overrides = {k: thaw(v) for k, v in values.items()}
    if "simulation.seed" not in overrides:
        overrides["simulation.seed"] = int(seed)
    return apply_overrides(job["scene_data"], overrides)


def _scratch_dir() -> str | None:
    """Where a variant's throw-away state file goes: $INERTIA_SWEEP_SCRATCH, else /dev/shm (memory: the
    atomic writer's fsyncs cost nothing there), else the system's temporary folder."""
    for candidate in (os.environ.get("INERTIA_SWEEP_SCRATCH"), "/dev/shm"):
        if candidate and os.path.isdir(candidate) and os.access(candidate, os.W_OK | os.X_OK):
            return candidate
    return None


def _limit_threads(threads: int | None) -> None:
    if not threads:
        return
    try:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    except Exception:  # noqa: BLE001 - a thread limit is an optimisation, never a failure
        pass


def run_variant(job: dict, index: int, values: dict, seed: int) -> dict:
    """Run variant `index` of a sweep; returns its table row (parameters, metrics, status, wall time).

    ``job``: ``scene_data`` (raw dict), ``scene_path`` (str or None), ``metrics`` (list of
    `Metric`), ``outputs`` (subset of `OUTPUT_KINDS`), ``out_dir`` (str or None),
    ``numba_threads`` (int or None).
    """
    from ..errors import SimulationDiverged
    from ..scene import Scene, build, validate
    from ..world import Run
    from .metrics import Probe

    started, cpu_started = time.perf_counter(), time.process_time()
    _limit_threads(job.get("numba_threads"))
    # the seed the scene runs with: derived from the sweep seed and index, unless simulation.seed is swept
    used_seed = values.get("simulation.seed", seed)
    row: dict[str, Any] = {"variant": int(index), "seed": int(used_seed) if isinstance(used_seed, (int, float)) else -1}
    metric_names = [m.name for m in job["metrics"]]
    outputs = set(job.get("outputs") or ())
    keep = job.get("out_dir") is not None and bool(outputs & {"states", "plot", "mp4", "gif"})
    run_dir = None
    status, error = "completed", ""
    results = {name: math.nan for name in metric_names}
    try:
        data = variant_data(job, values, seed)
        source = job.get("scene_path")
        model = validate(data, source)
        text = json.dumps(data, indent=1)
        scene = Scene(model, text, Path(source) if source else None, "json")
        if job.get("out_dir") is not None and "scene" in outputs:
            folder = variant_folder(job["out_dir"], index)
            folder.mkdir(parents=True, exist_ok=True)
            from ..io import write_text_atomic
            write_text_atomic(folder / "scene.json", text + "\n")
        world = build(scene)
        sim = model.simulation
        probe = Probe(job["metrics"], world.dim)
        if keep:
            run_dir = variant_folder(job["out_dir"], index)
            run_dir.mkdir(parents=True, exist_ok=True)
        else:
            run_dir = Path(tempfile.mkdtemp(prefix=f"inertia-sweep-{index:05d}-", dir=_scratch_dir()))
        sampled = [0]

        def observe(progress):
            # called after every recorded frame (and between frames, which are skipped here)
            if progress.frame > sampled[0]:
                sampled[0] = progress.frame
                probe.observe(world)

        metadata = {"scene": text, "scene_format": "json", "scene_path": str(Path(source).resolve()) if source else "",
                    "scene_name": scene.name, "seed": sim.seed, "render": model.render.model_dump(mode="json"),
                    "sweep_variant": int(index)}
        runner = Run(world, run_dir, duration=sim.duration, fps=sim.fps, fingerprint=world.fingerprint,
                     metadata=metadata, checkpoint_interval=math.inf, progress=observe, handle_sigint=False)
        result = runner.execute()
        if result.status == "diverged":
            status, error = "diverged", str(result.error)
        elif result.status != "completed":
            status, error = "error", f"run ended as {result.status}"
        else:
            results = probe.results(world)
            if keep and outputs & {"plot", "mp4", "gif"}:
                _write_heavy(result.states_path, run_dir, outputs, model, world)
    except SimulationDiverged as exc:
        status, error = "diverged", str(exc)
    except Exception as exc:  # noqa: BLE001 - a failed variant is a row, the sweep goes on
        status = "error"
        error = f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, ValueError):
            error += "\n" + "".join(traceback.format_exception(exc)[-3:])
    finally:
        if run_dir is not None and not keep:
            shutil.rmtree(run_dir, ignore_errors=True)
    row.update({k: _cell(v) for k, v in values.items()})
    row.update(results)
    row["status"] = status
    row["error"] = error
    row["wall_time"] = time.perf_counter() - started
    row["cpu_time"] = time.process_time() - cpu_started
    row["pid"] = os.getpid()
    return row


def _cell(value):
    """A table cell: scalars as they are, lists as JSON text."""
    return json.dumps(thaw(value)) if isinstance(value, (tuple, list)) else value


def _write_heavy(states_path, run_dir, outputs, model, world) -> None:
    from ..cli.outputs import write_outputs
    from ..io import load_states

    states = load_states(states_path)
    wanted = {"video": [v for v in ("mp4", "gif") if v in outputs], "plot": "plot" in outputs,
              "frames": False, "ply": False, "usd": False}
    write_outputs(states, run_dir, wanted, model.render.model_dump(mode="json"), world.colliders)
