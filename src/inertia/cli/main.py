"""The `inertia` command (typer + rich).

    inertia run SCENE [--out DIR] [--duration S] [--fps N] [--seed N] [--resume] [--overwrite] [--force]
                      [--camera PRESET] [--eye X,Y,Z] [--target X,Y,Z] [--resolution WxH]
    inertia validate SCENE
    inertia render STATES [--out DIR] [--video mp4,gif] [--frames]
    inertia view SCENE|STATES
    inertia examples [--copy NAME DIR]
    inertia warmup
    inertia bench [NAME ...]
    inertia schema [--out FILE]

SCENE is a .toml/.json file or the name of a bundled example (``inertia run fountain``); a name
that looks like a path (``./fountain.toml``) and does not exist is an error, never an example.

``run`` into a directory holding a finished run (completed or diverged) of the same scene file
replaces it, so the same command works twice, and so does a run of it killed before its first
checkpoint (nothing there can be resumed); a run that did not finish is kept for
``--resume`` (which continues with the duration, fps and seed the run was started with; a
longer ``--duration`` extends it, other values are refused), another scene's run is kept
unless ``--overwrite``. The output directory is resolved once (links followed) and every file is
written inside it: an ``--out`` that is a symbolic link is followed with a warning naming its
target, a scene file's ``output.directory`` that leads outside the working directory is refused,
and links inside the directory where the run writes (``states``, ``checkpoint.npz``, outputs) are
refused. A scene that would not fit in memory, a part too large for its method (a hull of more
than 10 000 points), or a run that would take more than a day even at full speed, is refused
before anything is written (``--force`` proceeds). On ``--resume`` the checkpoint is checked
against the scene (every array's shape and dtype, every count and index, the frame count against
the state directory) before anything of it is used; ``render`` validates the state file's
recorded render settings as a scene's.

Exit codes: 0 done; 1 an internal error (a bug: the message says to rerun with --debug for the
traceback); 2 bad input (invalid scene, missing file, unwritable output directory, a checkpoint
that does not match, a scene that diverges); 130 stopped by Ctrl-C (what was simulated is
written and ``--resume`` continues it).
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, ProgressColumn, TaskProgressColumn, TextColumn, TimeRemainingColumn
from rich.table import Table
from rich.text import Text

_STARTED = time.perf_counter()

app = typer.Typer(
    name="inertia",
    help="Physically based simulation for games and graphics: run, check, render and view scenes.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
)

console = Console(stderr=True, highlight=False)
out_console = Console(highlight=False)

EXIT_INPUT = 2
EXIT_INTERRUPTED = 130


class InputError(Exception):
    """A problem with what the user asked for (exit code 2, no traceback)."""


# ------------------------------------------------------------------------------------------------
# error handling: one clear message, exit 2 for input errors, traceback only with --debug
# ------------------------------------------------------------------------------------------------
def _debug_enabled(kwargs) -> bool:
    return bool(kwargs.get("debug")) or os.environ.get("INERTIA_DEBUG", "") not in ("", "0")


def handle_errors(command):
    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from inertia.errors import SimulationDiverged
        from inertia.scene.errors import SceneError

        debug = _debug_enabled(kwargs)
        _interrupt_note[0] = ""
        try:
            return command(*args, **kwargs)
        except typer.Exit:
            raise
        # input the user controls (scene files, options, checkpoints and state files): exit 2 naming the
        # key, the file or the array; anything else reaching the last branch is a bug (exit 1)
        except (SceneError, InputError) as exc:
            if debug:
                raise
            _error(str(exc))
            raise typer.Exit(EXIT_INPUT) from None
        except SimulationDiverged as exc:
            if debug:
                raise
            _error(str(exc))
            raise typer.Exit(EXIT_INPUT) from None
        except KeyboardInterrupt:
            if debug:
                raise
            _error("interrupted" + (f": {_interrupt_note[0]}" if _interrupt_note[0] else ""))
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except Exception as exc:  # noqa: BLE001 - the last resort: say what and how to see more
            if debug:
                raise
            world = sys.modules.get("inertia.world")     # (loaded by every command that reads checkpoints)
            if world is not None and isinstance(exc, world.CheckpointError):
                _error(str(exc))
                raise typer.Exit(EXIT_INPUT) from None
            _error(f"internal error: {type(exc).__name__}: {exc}\n"
                   "  This is a bug in inertia; rerun with --debug for the traceback.")
            raise typer.Exit(1) from None

    return wrapper


# What a KeyboardInterrupt that reaches `handle_errors` means for the files (set by the command).
_interrupt_note = [""]


def _error(message: str) -> None:
    text = Text("error: ", style="bold red")
    text.append(message)
    console.print(text, soft_wrap=True)


DebugOption = Annotated[bool, typer.Option("--debug", help="Show tracebacks.")]


# ------------------------------------------------------------------------------------------------
# finding scenes
# ------------------------------------------------------------------------------------------------
def examples_dir() -> Path:
    return Path(__file__).resolve().parent.parent / "examples"


def bundled_examples() -> dict[str, Path]:
    return {p.stem: p for p in sorted(examples_dir().glob("*.toml"))}


def _looks_like_path(name: str) -> bool:
    """A name with a directory part, a scene suffix, or a leading '.'/'~' is a path, never an example name."""
    return ("/" in name or "\\" in name or name.startswith((".", "~"))
            or Path(name).suffix.lower() in (".toml", ".json"))


def resolve_scene(name: str) -> Path:
    """A scene file path, or the bundled example of that name.

    Only a bare name (``fountain``) can mean a bundled example; a name that looks like a path
    (``./fountain.toml``, ``scenes/x.toml``, ``fountain.toml``) and does not exist is an error.
    """
    from inertia.scene.errors import Issue, SceneError, did_you_mean

    path = Path(name).expanduser()
    if path.exists():
        return path
    examples = bundled_examples()
    if not _looks_like_path(name):
        if name in examples:
            return examples[name]
        hint = did_you_mean(name, list(examples), show_allowed=False)
        raise SceneError(path, [Issue("", "file not found" + hint.replace("did you mean", "did you mean the example")
                                      + f" (bundled examples: {', '.join(examples)})")])
    stem = path.name.split(".")[0]
    extra = f"; to run the bundled example of that name: inertia run {stem}" if stem in examples else ""
    raise SceneError(path, [Issue("", "file not found" + extra)])


def _finished_run(out: Path) -> tuple[str, str] | None:
    """(status, scene path) of the finished run recorded in out/manifest.json, or None."""
    from inertia.io import read_manifest

    try:
        manifest = read_manifest(out / "manifest.json")
        status = manifest["extra"]["status"]
    except Exception:  # noqa: BLE001 - no readable manifest: not a finished run
        return None
    return (status, str(manifest.get("scene_path"))) if status in ("completed", "diverged") else None


def _resolve_out_dir(out: Path, *, from_scene: bool) -> Path:
    """The output directory as one absolute path with every symbolic link followed, resolved once;
    every file of the run is written inside it. A directory named by a scene file
    (``output.directory``) must stay inside the working directory even through links (refused
    otherwise); an ``--out`` that is (or passes through) a link is the user's choice, said clearly."""
    given = Path(out).expanduser()
    cwd = Path.cwd().resolve()
    absolute = given if given.is_absolute() else cwd / given
    try:
        real = absolute.resolve()
    except (OSError, RuntimeError) as exc:          # a loop of links
        raise InputError(f"output directory {given}: cannot be resolved ({exc})") from None
    if from_scene and not real.is_relative_to(cwd):
        raise InputError(f"output.directory: {given} leads outside the working directory (to {real}) through a "
                         "symbolic link; pass --out to choose that directory yourself")
    if real != Path(os.path.normpath(absolute)):
        console.print(f"[yellow]warning[/]: output directory {given} is a symbolic link (or passes through one): "
                      f"writing into {real}")
    return real


def _check_no_links_inside(out: Path) -> None:
    """Refuse an output directory whose entries inertia writes are symbolic links (they would lead
    the run's files outside the directory)."""
    from inertia.world import CHECKPOINT_NAME, STATES_NAME

    from .outputs import OUTPUT_NAMES

    for name in (CHECKPOINT_NAME, STATES_NAME, *OUTPUT_NAMES.values()):
        entry = out / name
        if entry.is_symlink():
            raise InputError(f"{entry} is a symbolic link (to {os.readlink(entry)}); inertia writes only inside the "
                             "output directory: remove the link or choose another --out")


def _stale_start(out: Path, scene_path: Path | None) -> bool:
    """True when `out` holds only the start of a run of `scene_path` killed before its first checkpoint
    (a state directory, no checkpoint, no finished manifest): nothing there can be resumed."""
    from inertia.world import CHECKPOINT_NAME, STATES_NAME

    if (out / CHECKPOINT_NAME).exists() or not (out / STATES_NAME).exists() or scene_path is None:
        return False
    try:
        header = json.loads((out / STATES_NAME / "header.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return True                          # not even a header: the run died while starting
    return isinstance(header, dict) and header.get("scene_path") == str(scene_path.resolve())


def _prepare_out_dir(out: Path, *, resume: bool, overwrite: bool, scene_path: Path | None = None) -> None:
    """Create the output directory or say clearly why it cannot be used.

    A finished run (completed or diverged) of the same scene file is replaced, so the same
    command can be run again; a run that did not finish is kept for ``--resume``, and another
    scene's run is kept, unless ``--overwrite``.
    """
    from inertia.world import CHECKPOINT_NAME, STATES_NAME

    if out.exists() and not out.is_dir():
        raise InputError(f"output directory {out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output directory {out}: {exc.strerror or exc}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"output directory {out} is not writable")
    probe = out / f".inertia-write-test-{os.getpid()}"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"output directory {out} is not writable: {exc.strerror or exc}") from None
    # temporary files left by a run that was killed mid-write (never the files themselves); cleaned
    # first, so that a refused run also leaves the directory tidy
    from inertia.io import remove_stale_partials
    for directory in (out, out / STATES_NAME):
        if directory.is_dir():
            remove_stale_partials(directory)
    _check_no_links_inside(out)
    for directory in (out / "frames",):
        if directory.is_dir() and not directory.is_symlink():
            remove_stale_partials(directory)
    has_run = (out / CHECKPOINT_NAME).exists() or (out / STATES_NAME).exists()
    if has_run and not resume and not overwrite and _stale_start(out, scene_path):
        has_run = False                      # killed before its first checkpoint: a plain re-run replaces it
    if resume:
        if not (out / CHECKPOINT_NAME).exists():
            raise InputError(f"nothing to resume: {out} has no {CHECKPOINT_NAME} (run without --resume)")
    elif has_run and not overwrite:
        finished = _finished_run(out)
        if finished is None:
            raise InputError(f"{out} already holds a run that did not finish; pass --resume to continue it or "
                             "--overwrite to replace it")
        if scene_path is None or finished[1] != str(scene_path.resolve()):
            raise InputError(f"{out} already holds a run of another scene ({finished[1]}); pass --overwrite to "
                             "replace it or choose another --out")


# ------------------------------------------------------------------------------------------------
# progress display
# ------------------------------------------------------------------------------------------------
# One line that fits 80 columns: "simulating ━━━━━━━━━━━━  42% t 2.52/6 s frame 63/151 1.2k st/s 0:00:12"; its label never changes while it runs (a cold Numba cache
# is said once, on a line of its own, by `warm.compile_notice_on` through `_SteadyLabel`).
class _RateColumn(ProgressColumn):
    def render(self, task):
        rate = task.fields.get("rate")
        if not rate:
            return Text("")
        text = f"{rate / 1000:.1f}k" if rate >= 1000 else f"{rate:.0f}"
        return Text(f"{text} st/s", style="cyan")


class _SimColumn(ProgressColumn):
    def render(self, task):
        f = task.fields
        return Text(f"t {task.completed:.2f}/{task.total:g} s frame {f.get('frame', 0)}/{f.get('frames', 0)}",
                    no_wrap=True, overflow="ellipsis")


def _progress(quiet: bool, to: Console | None = None) -> Progress:
    return Progress(TextColumn("[bold]{task.description}"), BarColumn(bar_width=12), TaskProgressColumn(),
                    _SimColumn(), _RateColumn(), TimeRemainingColumn(compact=True), console=to or console,
                    disable=quiet, transient=False, expand=False)


class _SteadyLabel:
    """The progress bar as `warm.compile_notice_on` sees it: the once-printed compile notice goes
    through, changes of the task's label are dropped, so the line does not flip between labels."""

    def __init__(self, bar):
        self._bar = bar
        self.console = bar.console
        self.disable = getattr(bar, "disable", False)

    def update(self, task, **fields):
        fields.pop("description", None)
        if fields:
            self._bar.update(task, **fields)


#: `inertia run --camera` presets: (azimuth, elevation) in degrees about the framed subject.
CAMERA_PRESETS = {"front": (-90.0, 12.0), "side": (0.0, 12.0), "top": (-90.0, 89.0), "iso": (-45.0, 30.0),
                  "low": (-60.0, 5.0)}


def _vector_option(text: str, name: str) -> list[float]:
    """'X,Y,Z' -> three finite floats, or an InputError naming the option."""
    import math as _math

    parts = [p for p in text.replace(" ", "").split(",") if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(_math.isfinite(v) for v in values):
        raise InputError(f"{name} must be three finite numbers X,Y,Z (got {text!r})")
    return values


def _render_overrides(render: dict, *, camera: str | None, eye: str | None, target: str | None,
                      resolution: str | None) -> dict:
    """The scene's [render] table with the command line's camera and resolution options applied."""
    render = dict(render)
    cam = dict(render.get("camera") or {})
    if camera is not None:
        if camera not in CAMERA_PRESETS:
            raise InputError(f"--camera must be one of {', '.join(CAMERA_PRESETS)} (got {camera!r}); "
                             "or give --eye X,Y,Z and --target X,Y,Z")
        cam.update(azimuth=CAMERA_PRESETS[camera][0], elevation=CAMERA_PRESETS[camera][1], position=None,
                   target=None, distance=None, orbit=0.0)
    if eye is not None:
        cam["position"] = _vector_option(eye, "--eye")
    if target is not None:
        cam["target"] = _vector_option(target, "--target")
    if cam.get("position") is not None and cam.get("target") is not None and cam["position"] == cam["target"]:
        raise InputError("--eye and --target must be different points")
    render["camera"] = cam
    if resolution is not None:
        try:
            w, h = (int(v) for v in resolution.lower().split("x"))
        except ValueError:
            w = h = 0
        if not (16 <= w <= 7680 and 16 <= h <= 4320):
            raise InputError(f"--resolution must be WIDTHxHEIGHT with 16 <= width <= 7680 and 16 <= height <= 4320 "
                             f"(got {resolution!r}, e.g. 1280x720)")
        render["width"], render["height"] = w, h
    return render


# ------------------------------------------------------------------------------------------------
# inertia run
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def run(
    scene: Annotated[str, typer.Argument(help="Scene file (.toml/.json) or a bundled example name.")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Output directory (default: out/NAME).")] = None,
    duration: Annotated[Optional[float], typer.Option(help="Simulated seconds (overrides the scene).")] = None,
    fps: Annotated[Optional[float], typer.Option(help="Output frames per second (overrides the scene).")] = None,
    seed: Annotated[Optional[int], typer.Option(help="Random seed (overrides the scene).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Continue the run stopped in --out.")] = False,
    overwrite: Annotated[bool, typer.Option("--overwrite", "-f", help="Replace a run already in --out.")] = False,
    render: Annotated[bool, typer.Option("--render/--no-render", help="Write video/images/plots after the run.")] = True,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
    debug: DebugOption = False,
    stop_after: Annotated[Optional[int], typer.Option(hidden=True, help="Stop as if interrupted after N frames (tests).")] = None,
    force: Annotated[bool, typer.Option("--force", help="Run even if the run-time or memory estimate says it will not finish or fit.")] = False,
    report_frames: Annotated[bool, typer.Option("--report-frames", hidden=True, help="Print 'frame K' on stdout as frames are recorded (tests, scripts).")] = False,
    camera: Annotated[Optional[str], typer.Option("--camera", help=f"Camera preset: {', '.join(CAMERA_PRESETS)} (framed on the subject).")] = None,
    eye: Annotated[Optional[str], typer.Option("--eye", metavar="X,Y,Z", help="Camera position in metres (with --target, or looking at the framed centre).")] = None,
    target: Annotated[Optional[str], typer.Option("--target", metavar="X,Y,Z", help="Point the camera looks at, in metres.")] = None,
    resolution: Annotated[Optional[str], typer.Option("--resolution", metavar="WxH", help="Image size in pixels, e.g. 1280x720.")] = None,
):
    """Run a scene: simulate, record the state file, then write video, plot and exports."""
    from inertia.io import write_manifest
    from inertia.scene import build, read_scene, with_overrides
    from inertia.world import CheckpointError, Run

    from .warm import compile_notice_on

    t_start = time.perf_counter()
    _interrupt_note[0] = "nothing was written (stopped before the run started)"
    path = resolve_scene(scene)
    loaded = read_scene(path)
    out = _resolve_out_dir(out if out is not None else Path(loaded.model.output.directory or Path("out") / loaded.name),
                           from_scene=out is None and loaded.model.output.directory is not None)
    if resume:
        duration, fps, seed = _resume_settings(out, duration, fps, seed)
    loaded = with_overrides(loaded, duration=duration, fps=fps, seed=seed)
    model = loaded.model
    render_table = _render_overrides(model.render.model_dump(mode="json"), camera=camera, eye=eye, target=target,
                                     resolution=resolution)
    _check_resources(loaded, force=force)
    _check_frames(loaded, render)
    _prepare_out_dir(out, resume=resume, overwrite=overwrite, scene_path=path)
    world = build(loaded, check_memory=not force)
    sim = model.simulation
    t_loaded = time.perf_counter()
    metadata = {
        "scene": loaded.text, "scene_format": loaded.format, "scene_path": str(path.resolve()),
        "scene_name": loaded.name, "seed": sim.seed, "render": render_table,
    }
    runner = Run(world, out, duration=sim.duration, fps=sim.fps, resume=resume, fingerprint=world.fingerprint,
                 metadata=metadata, checkpoint_interval=model.output.checkpoint_interval,
                 stop_after_frames=stop_after)
    if not quiet:
        console.print(f"[bold]{loaded.name}[/]: {_world_summary(world)}; dt = {sim.dt:g} s x {sim.substeps} substeps, "
                      f"{sim.duration:g} s at {sim.fps:g} fps -> {out}")
    dropped: dict = {}
    outputs: dict = {}
    timings: dict = {}
    extra: dict = {}

    def manifest():
        write_manifest(out / "manifest.json", scene=loaded.text, scene_path=path.resolve(), seed=sim.seed,
                       step_count=result.step_count, frame_count=result.frame_count,
                       simulated_time=result.time, timings=timings, outputs=outputs, extra=extra)

    # Ctrl-C stops the run cleanly from before its first write until the manifest is written
    with _progress(quiet) as bar, runner.catching_sigint():
        task = bar.add_task("simulating", total=sim.duration, frame=0, frames=runner.frame_count, rate=0.0)
        last_frame = [-1]

        def report(p):
            bar.update(task, completed=min(p.time, sim.duration), frame=p.frame, frames=p.frame_count,
                       rate=p.steps_per_second)
            if report_frames and p.frame != last_frame[0]:
                last_frame[0] = p.frame
                print(f"frame {p.frame}/{p.frame_count} t = {p.time:.6g} s", flush=True)

        runner.progress = report
        try:
            with compile_notice_on(_SteadyLabel(bar), task, "simulating"):  # a cold Numba cache says so
                result = runner.execute()
        except CheckpointError as exc:       # a checkpoint that does not fit this scene, or damaged
            raise InputError(str(exc)) from None
        except ValueError as exc:            # a damaged state directory met on --resume
            if resume and str(out) in str(exc):
                raise InputError(f"cannot resume from {out}: {exc}") from None
            raise
        bar.update(task, completed=min(world.t, sim.duration), frame=result.frame_count)
        # every figure is wall time; first_frame and total count from the command's start (imports
        # included), so first_frame <= total; "run" is the simulation loop's own total
        run_timings = dict(result.timings)
        timings.update({"load": t_loaded - t_start, **run_timings})
        timings["run"] = timings.pop("total", sum(run_timings.values()))
        if result.first_frame_seconds is not None:
            timings["first_frame"] = (t_loaded - _STARTED) + result.first_frame_seconds
        timings["total"] = time.perf_counter() - _STARTED
        outputs["states"] = result.states_path
        if result.checkpoint_path is not None:
            outputs["checkpoint"] = result.checkpoint_path
        dropped.update({g.name: sum(e.dropped for e in g.system.emitters) for g in world.groups
                        if getattr(g.system, "emitters", None)})
        extra.update({"status": result.status, "fingerprint": world.fingerprint, "dt": sim.dt,
                      "substeps": sim.substeps, "fps": sim.fps, "duration": sim.duration,
                      "groups": [g.name for g in world.groups], "integrators": [g.integrator for g in world.groups],
                      "profile": dict(world.profile), "emitter_dropped": dropped, "resumed": resume})
        manifest()

    if result.status == "diverged":
        raise InputError(f"{path}: {result.error}\n  The {result.frame_count} frames before it are in "
                         f"{result.states_path}.")
    if result.status == "interrupted":
        console.print(f"[yellow]stopped[/] at t = {result.time:.4g} s after {result.frame_count} frames; "
                      f"saved in {out}.\n  Continue with: inertia run {scene} --out {out} --resume"
                      f"\n  Render what is there with: inertia render {result.states_path}")
        raise typer.Exit(EXIT_INTERRUPTED)
    for name, count in dropped.items():
        if count:
            console.print(f"[yellow]warning[/]: the emitters of group {name!r} dropped {count} particles "
                          "(pool full): raise its `capacity`")
    if render:
        _interrupt_note[0] = (f"the run itself is complete in {out}; write its outputs with: "
                              f"inertia render {result.states_path}")
        t0 = time.perf_counter()
        outputs.update(_write_outputs(result.states_path, out, model.output.model_dump(), render_table,
                                      world.colliders, quiet))
        timings["outputs"] = time.perf_counter() - t0
        timings["total"] = time.perf_counter() - _STARTED
        manifest()
    outputs["manifest"] = out / "manifest.json"
    if not quiet:
        _summary(outputs, result, timings)


def _resume_settings(out: Path, duration, fps, seed) -> tuple[float, float, int]:
    """The duration, fps and seed the run in `out` was started with; refuse other values."""
    from inertia.world import CHECKPOINT_NAME, STATES_NAME, CheckpointError, read_checkpoint_info

    checkpoint = out / CHECKPOINT_NAME
    if not checkpoint.exists():
        raise InputError(f"nothing to resume: {out} has no {CHECKPOINT_NAME} (run without --resume)")
    try:
        info = read_checkpoint_info(checkpoint)
    except CheckpointError as exc:
        raise InputError(str(exc)) from None
    header = {}
    if "duration" not in info or "seed" not in info:      # checkpoints written before these were stored
        try:
            header = json.loads((out / STATES_NAME / "header.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            header = {}
    started = {"duration": info.get("duration", header.get("duration")), "fps": info.get("fps"),
               "seed": info.get("seed", header.get("seed"))}
    given = {"duration": duration, "fps": fps, "seed": seed}
    unknown = [k for k, v in started.items() if not isinstance(v, (int, float)) or isinstance(v, bool)]
    if unknown:
        raise InputError(f"cannot resume from {out}: its checkpoint does not say the {', '.join(unknown)} it was "
                         "started with; run without --resume to start over")
    # fps and seed are the run's; a longer --duration extends it (asked for explicitly), a shorter one
    # would call a run "completed" that is not the one started
    wrong = [k for k in given if given[k] is not None and float(given[k]) != float(started[k])
             and not (k == "duration" and float(given[k]) > float(started[k]))]
    if wrong:
        expected = " ".join(f"--{k} {started[k]:g}" for k in started)
        got = ", ".join(f"--{k} {given[k]:g}" for k in wrong)
        raise InputError(f"cannot resume from {out} with {got}: the run was started with {expected}; leave these "
                         "options out to continue it as it was started (a longer --duration extends it), or "
                         "start over with --overwrite")
    return (float(duration if duration is not None else started["duration"]), float(started["fps"]),
            int(started["seed"]))


def _check_frames(loaded, render: bool) -> None:
    """A video needs frames: refuse a frame rate so low that the run records fewer than two, or
    below one frame per second (the video encoder's least), before anything is written."""
    from inertia.scene.errors import Issue, SceneError

    from .outputs import frame_count_for

    sim, output = loaded.model.simulation, loaded.model.output
    if not render or not output.video:
        return
    frames = frame_count_for(sim.duration, sim.fps)
    if frames < 2 or sim.fps < 1.0:
        raise SceneError(loaded.path, [Issue("simulation.fps", (
            f"{sim.fps:g} frames per second over {sim.duration:g} s records {frames} frame(s); a video "
            f"({', '.join(output.video)}) needs at least 2 frames and fps >= 1: raise fps or duration, or set "
            "output.video = [] (or --no-render)"))])


def _check_resources(loaded, *, force: bool, warn_only: bool = False) -> None:
    """Refuse (or with `force`/`warn_only`, warn about) a scene too big for memory or too long to run."""
    from inertia.scene.errors import Issue, SceneError
    from inertia.scene.resources import estimate_resources

    estimate = estimate_resources(loaded.model)
    size = estimate.size_problem()
    if size is not None:
        if not (force or warn_only):
            raise SceneError(loaded.path, [Issue(*size)])
        console.print(f"[yellow]warning[/]: {size[0]}: {size[1]}")
    memory = estimate.memory_problem()
    if memory is not None:
        if not force:
            raise SceneError(loaded.path, [Issue(*memory)])
        console.print(f"[yellow]warning[/]: {memory[0]}: {memory[1]} (--force: building anyway)")
    slow = estimate.run_time_problem()
    if slow is not None:
        if force or warn_only:
            console.print(f"[yellow]warning[/]: {slow}" + (" (--force: running anyway)" if force else ""))
        else:
            raise InputError(f"{loaded.path}: {slow}")


def _write_outputs(states_path, out, output, render, colliders, quiet) -> dict:
    from inertia.io import load_states

    from .outputs import write_outputs
    from .warm import compile_notice_on

    states = load_states(states_path)
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(bar_width=20), TaskProgressColumn(),
                  TextColumn("{task.completed}/{task.total} frames"), TimeRemainingColumn(compact=True),
                  console=console, disable=quiet, expand=False) as bar:
        task = bar.add_task("writing outputs", total=states.frame_count)
        with compile_notice_on(_SteadyLabel(bar), task, "writing outputs"):
            return write_outputs(states, out, output, render, colliders,
                                 progress=lambda stage, done, total: bar.update(task, completed=done))


def _summary(outputs: dict, result, timings: dict) -> None:
    table = Table(title=f"{result.frame_count} frames, {result.step_count} steps, t = {result.time:.4g} s",
                  show_header=True, header_style="bold")
    table.add_column("output")
    table.add_column("path")
    table.add_column("size", justify="right")
    for kind, p in outputs.items():
        p = Path(p)
        size = sum(f.stat().st_size for f in p.rglob("*") if f.is_file()) if p.is_dir() else (p.stat().st_size if p.exists() else 0)
        table.add_row(kind, str(p), _human(size))
    console.print(table)
    console.print(f"[dim]{_timings_line(timings)}[/]")


def _timings_line(timings: dict) -> str:
    """'timings: first frame 3.1 s, total 9.8 s (load 0.4 s, simulate 5.2 s, ...)': the two figures a
    user waits for, counted from the command's start, then the stages."""
    head = [f"{label} {timings[key]:.2f} s" for key, label in (("first_frame", "first frame"), ("total", "total"))
            if key in timings]
    parts = [f"{k} {v:.2f} s" for k, v in timings.items() if k not in ("first_frame", "total")]
    return "timings: " + ", ".join(head) + (f" ({', '.join(parts)})" if parts else "")


def _world_summary(world) -> str:
    """What a world holds, for the run's first line: particle groups, rigid bodies, fluids."""
    parts = [f"{g.name} ({g.particle_count} {g.kind}, {g.integrator})" for g in world.groups]
    model = getattr(world, "model", None)
    if model is not None and getattr(model, "body_count", 0):
        import numpy as np

        dynamic = int(np.count_nonzero(np.asarray(model.body_type) == 0))
        bodies = "1 rigid body" if model.body_count == 1 else f"{model.body_count} rigid bodies"
        parts.append(f"{bodies} ({dynamic} dynamic), {model.shape_count} shape{'s' if model.shape_count != 1 else ''}")
    for name, fluid in getattr(world, "fluids", {}).items():
        parts.append(f"{name} ({type(fluid).__name__})")
    return ", ".join(parts) or "an empty world"


def _human(size: int) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if size < 1024 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    return str(size)


# ------------------------------------------------------------------------------------------------
# inertia validate
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def validate(
    scene: Annotated[str, typer.Argument(help="Scene file (.toml/.json) or a bundled example name.")],
    build_scene: Annotated[bool, typer.Option("--build/--no-build", help="Also build the systems (checks indices, files, dimensions).")] = True,
    debug: DebugOption = False,
):
    """Check a scene file and summarise it (exit code 2 and every problem if it is invalid)."""
    from inertia.scene import build, read_scene
    from inertia.world import frame_steps

    path = resolve_scene(scene)
    loaded = read_scene(path)
    sim = loaded.model.simulation
    _check_resources(loaded, force=False, warn_only=True)
    if not build_scene:
        out_console.print(f"[green]ok[/]: {path} is a valid scene (format_version {loaded.model.format_version})")
        return
    world = build(loaded)
    table = Table(title=f"{loaded.name}: {sim.dim}-D, dt = {sim.dt:g} s x {sim.substeps}, {sim.duration:g} s at {sim.fps:g} fps")
    for column in ("group", "kind", "particles", "integrator", "forces", "colliders"):
        table.add_column(column)
    for g in world.groups:
        forces = ", ".join(type(f).__name__ for f in getattr(g.system, "forces", [])) or "-"
        colliders = ", ".join(getattr(c, "name", type(c).__name__) for c in g.colliders) or "-"
        table.add_row(g.name, g.kind, str(g.particle_count), g.integrator, forces, colliders)
    if world.groups:
        out_console.print(table)
    rigid = getattr(world, "rigid_scene", None)
    if rigid is not None:
        m = rigid.model
        out_console.print(f"{m.body_count} rigid bodies, {m.shape_count} shapes "
                          f"({', '.join(f'{n} {t}' for t, n in _shape_counts(m).items())})")
    frames = int(sim.duration * sim.fps + 1e-6) + 1
    steps = frame_steps(frames - 1, sim.fps, sim.dt)
    period = 1.0 / (sim.fps * sim.dt)
    note = "" if abs(period - round(period)) < 1e-6 else (
        " [yellow](1/fps is not a whole number of steps: frames are taken at the first step after each frame time)[/]")
    out_console.print(f"[green]ok[/]: {path}: {frames} frames, {steps} steps{note}")


def _shape_counts(model) -> dict:
    from inertia.geometry import shapes as S

    import numpy as np

    names = {v: k for k, v in S.SHAPE_NAMES.items()}
    codes, counts = np.unique(np.asarray(model.shape_type), return_counts=True)
    return {names.get(int(c), str(c)): int(n) for c, n in zip(codes, counts)}


# ------------------------------------------------------------------------------------------------
# inertia render
# ------------------------------------------------------------------------------------------------
def _scene_colliders(states) -> list:
    """Rebuild the colliders of a recorded run from the scene text in its header."""
    meta = states.metadata
    text = meta.get("scene")
    if not text:
        return []
    from inertia.scene import parse_scene
    from inertia.scene.builder import build_colliders

    scene_path = meta.get("scene_path")
    loaded = parse_scene(text, format=meta.get("scene_format", "toml"), source=scene_path)
    base = Path(scene_path).parent if scene_path else None
    return build_colliders(loaded.model, source=scene_path, base_dir=base)


def _checked_render(render: dict, states_path: Path) -> dict:
    """The render settings recorded in a state file (with the command's overrides), validated as a
    scene's [render] table is; a bad value is an error naming ``render.KEY``."""
    from pydantic import ValidationError

    from inertia.scene.errors import from_validation_error
    from inertia.scene.models import Render

    try:
        return Render.model_validate(render).model_dump(mode="json")
    except ValidationError as exc:
        error = from_validation_error(exc, Render, states_path)
        issues = "; ".join(f"render.{i.path}: {i.message}" if i.path else i.message for i in error.issues)
        raise InputError(f"{states_path}: the recorded render settings are invalid: {issues}") from None


@app.command("render")
@handle_errors
def render_command(
    states_path: Annotated[Path, typer.Argument(metavar="STATES", help="A state directory (OUT/states) or .npz state file.")],
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Output directory (default: the run directory holding STATES).")] = None,
    video: Annotated[str, typer.Option(help="Video formats, comma separated: mp4, gif, or none.")] = "mp4",
    frames: Annotated[bool, typer.Option("--frames", help="Also write a PNG per frame.")] = False,
    plot: Annotated[bool, typer.Option("--plot/--no-plot", help="Energy and momentum plot.")] = True,
    ply: Annotated[bool, typer.Option("--ply", help="PLY point files per frame.")] = False,
    usd: Annotated[bool, typer.Option("--usd", help="Animated USD points (.usdc).")] = False,
    width: Annotated[Optional[int], typer.Option(help="Image width in pixels.")] = None,
    height: Annotated[Optional[int], typer.Option(help="Image height in pixels.")] = None,
    color_by: Annotated[Optional[str], typer.Option(help="auto, speed, group or uniform.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q")] = False,
    debug: DebugOption = False,
):
    """Render a recorded run (video, frames, plot, PLY, USD) from its state file."""
    from inertia.io import load_states

    if not states_path.exists():
        raise InputError(f"{states_path}: state file not found")
    try:
        states = load_states(states_path)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    kinds = [v.strip() for v in video.split(",") if v.strip() and v.strip() != "none"]
    bad = [v for v in kinds if v not in ("mp4", "gif")]
    if bad:
        raise InputError(f"--video: unknown format {bad[0]!r}; allowed: mp4, gif, none")
    if color_by is not None and color_by not in ("auto", "speed", "group", "uniform"):
        raise InputError(f"--color-by must be one of auto, speed, group, uniform (got {color_by!r})")
    out = _resolve_out_dir(out or states_path.parent, from_scene=False)
    _prepare_out_dir(out, resume=False, overwrite=True)
    try:
        json.dumps(states.metadata, ensure_ascii=False).encode("utf-8")
    except (UnicodeEncodeError, TypeError, ValueError) as exc:
        raise InputError(f"{states_path}: its header holds text that is not valid Unicode or not JSON data "
                         f"({type(exc).__name__}); the file is damaged") from None
    render = states.metadata.get("render") or {}
    if not isinstance(render, dict):
        raise InputError(f"{states_path}: its recorded render settings are damaged (not a table)")
    render = dict(render)
    for key, value in (("width", width), ("height", height), ("color_by", color_by)):
        if value is not None:
            render[key] = value
    render = _checked_render(render, states_path)
    output = {"video": kinds, "frames": frames, "plot": plot, "ply": ply, "usd": usd}
    try:
        colliders = _scene_colliders(states)
    except Exception as exc:  # noqa: BLE001 - drawing without colliders beats failing
        console.print(f"[yellow]warning[/]: colliders not drawn ({exc})")
        colliders = []
    written = _write_outputs(states_path, out, output, render, colliders, quiet)
    for kind, p in written.items():
        out_console.print(f"{kind}: {p}")


# ------------------------------------------------------------------------------------------------
# inertia view
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def view(
    target: Annotated[str, typer.Argument(metavar="SCENE|STATES", help="A scene (simulated first) or a recorded state file.")],
    port: Annotated[int, typer.Option(help="Port of the web viewer (0: any free port).")] = 8080,
    host: Annotated[str, typer.Option(help="Address to serve on (0.0.0.0 to reach it from elsewhere).")] = "127.0.0.1",
    open_browser: Annotated[bool, typer.Option("--open", help="Open the page in the default browser.")] = False,
    duration: Annotated[Optional[float], typer.Option(help="Simulated seconds (scenes only).")] = None,
    debug: DebugOption = False,
):
    """Open the interactive viewer (play, pause, step, scrub, orbit) on a scene or a recorded run."""
    import tempfile

    from inertia.io import load_states

    try:
        import inertia.viewer as viewer_module
    except ImportError as exc:
        raise InputError(f"the viewer is not available: {exc}") from None
    show = getattr(viewer_module, "view", None)
    if show is None:
        raise InputError("this installation of inertia has no viewer (inertia.viewer.view)")
    path = Path(target)
    if path.is_dir() or path.suffix == ".npz":
        try:
            states = load_states(path)
        except (ValueError, FileNotFoundError) as exc:
            raise InputError(str(exc)) from None
        colliders = _scene_colliders(states)
    else:
        from inertia.scene import build, read_scene, with_overrides
        from inertia.world import Run

        scene_path = resolve_scene(target)
        loaded = with_overrides(read_scene(scene_path), duration=duration)
        _check_resources(loaded, force=False)
        world = build(loaded)
        sim = loaded.model.simulation
        # the run goes to a temporary directory, removed as soon as its frames are in memory
        tmp = Path(tempfile.mkdtemp(prefix="inertia-view-"))
        try:
            runner = Run(world, tmp, duration=sim.duration, fps=sim.fps, fingerprint=world.fingerprint,
                         metadata={"scene": loaded.text, "scene_format": loaded.format,
                                   "scene_path": str(scene_path.resolve()), "scene_name": loaded.name})
            with _progress(False) as bar:
                task = bar.add_task("simulating", total=sim.duration, frame=0, frames=runner.frame_count, rate=0.0)
                runner.progress = lambda p: bar.update(task, completed=min(p.time, sim.duration), frame=p.frame,
                                                       frames=p.frame_count, rate=p.steps_per_second)
                result = runner.execute()
            if result.status == "diverged":
                raise InputError(f"{scene_path}: {result.error}")
            states = load_states(result.states_path)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        colliders = world.colliders
    render = states.metadata.get("render") or {}
    show(states, colliders=colliders, port=port, host=host, open_browser=open_browser,
         color_by=render.get("color_by", "auto"))


# ------------------------------------------------------------------------------------------------
# inertia examples
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def examples(
    copy: Annotated[Optional[tuple[str, Path]], typer.Option("--copy", metavar="NAME DIR", help="Copy example NAME into DIR.")] = None,
    debug: DebugOption = False,
):
    """List the bundled example scenes, or copy one out to edit it."""
    import tomllib

    found = bundled_examples()
    if copy is not None:
        name, directory = copy
        name = name.removesuffix(".toml")
        if name not in found:
            from inertia.scene.errors import did_you_mean
            raise InputError(f"no example named {name!r}" + did_you_mean(name, list(found)))
        directory = Path(directory)
        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"cannot create {directory}: {exc.strerror or exc}") from None
        target = directory / f"{name}.toml"
        if target.exists():
            raise InputError(f"{target} already exists")
        try:
            shutil.copyfile(found[name], target)
        except OSError as exc:
            raise InputError(f"cannot write {target}: {exc.strerror or exc}") from None
        out_console.print(f"copied {name} to {target}; run it with: inertia run {target}")
        return
    table = Table(title="bundled examples (inertia run NAME)", show_header=True, header_style="bold")
    table.add_column("name")
    table.add_column("description")
    for name, path in found.items():
        try:
            description = tomllib.loads(path.read_text()).get("description", "")
        except (OSError, tomllib.TOMLDecodeError):
            description = "(unreadable)"
        table.add_row(name, description)
    out_console.print(table)


# ------------------------------------------------------------------------------------------------
# inertia warmup
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def warmup(
    only: Annotated[Optional[str], typer.Option(help="Only the warm-up scenes whose name contains this text.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q")] = False,
    debug: DebugOption = False,
):
    """Compile the Numba kernels ahead of time (into the on-disk cache) by running tiny scenes."""
    from .warm import warm_all

    started = time.perf_counter()
    with _spinner(quiet) as report:
        names = warm_all(report, only=only)
    if not names:
        raise InputError(f"no warm-up scene matches {only!r}")
    if not quiet:
        console.print(f"[green]warmed[/] {len(names)} scenes in {time.perf_counter() - started:.1f} s "
                      f"(cache: {os.environ.get('NUMBA_CACHE_DIR') or 'beside the sources'})")


class _spinner:
    def __init__(self, quiet):
        self.quiet = quiet

    def __enter__(self):
        self.status = None if self.quiet else console.status("warming up")
        if self.status:
            self.status.__enter__()
        return self.report

    def report(self, name):
        if self.status:
            self.status.update(f"warming up: {name}")

    def __exit__(self, *exc):
        if self.status:
            self.status.__exit__(*exc)


# ------------------------------------------------------------------------------------------------
# inertia bench
# ------------------------------------------------------------------------------------------------
def _benchmarks_dir(given: Path | None) -> Path:
    candidates = [given] if given else [Path.cwd() / "benchmarks", Path(__file__).resolve().parents[3] / "benchmarks"]
    for c in candidates:
        if c is not None and c.is_dir():
            return c
    raise InputError("no benchmarks directory found" + (f" at {given}" if given else
                                                        " (looked in ./benchmarks and beside the sources); pass --dir"))


@app.command()
@handle_errors
def bench(
    names: Annotated[Optional[list[str]], typer.Argument(help="Benchmarks to run (file names without .py); default all.")] = None,
    directory: Annotated[Optional[Path], typer.Option("--dir", help="Directory of benchmark scripts.")] = None,
    debug: DebugOption = False,
):
    """Run the benchmark scripts (benchmarks/*.py); each prints its ratios against a baseline."""
    root = _benchmarks_dir(directory)
    scripts = {p.stem: p for p in sorted(root.glob("*.py")) if not p.name.startswith("_")}
    if not scripts:
        raise InputError(f"{root} holds no benchmark scripts")
    chosen = list(scripts) if not names else [n.removesuffix(".py") for n in names]
    for n in chosen:
        if n not in scripts:
            from inertia.scene.errors import did_you_mean
            raise InputError(f"no benchmark named {n!r}" + did_you_mean(n, list(scripts)))
    failed = []
    for n in chosen:
        console.rule(f"[bold]{n}")
        code = subprocess.call([sys.executable, str(scripts[n])], cwd=str(root.parent))
        if code != 0:
            failed.append(n)
    if failed:
        _error(f"benchmarks failed: {', '.join(failed)}")
        raise typer.Exit(1)


# ------------------------------------------------------------------------------------------------
# inertia schema
# ------------------------------------------------------------------------------------------------
@app.command()
@handle_errors
def schema(
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Write to this file instead of printing.")] = None,
    debug: DebugOption = False,
):
    """Print the JSON Schema of scene files (for editor autocompletion)."""
    from inertia.scene import scene_schema

    text = json.dumps(scene_schema(), indent=2) + "\n"
    if out is None:
        sys.stdout.write(text)
    else:
        from inertia.io import write_text_atomic
        write_text_atomic(out, text)
        out_console.print(f"wrote {out}")


from .sweep import register as _register_sweep  # noqa: E402 - inertia sweep (src/inertia/cli/sweep.py)
_register_sweep(app)


@app.callback(invoke_without_command=True)
def _main(version: Annotated[bool, typer.Option("--version", help="Print the version and exit.")] = False):
    """Inertia: physically based simulation for games and graphics."""
    if version:
        import inertia
        out_console.print(f"inertia {inertia.__version__}")
        raise typer.Exit(0)


def main() -> None:  # pragma: no cover - console entry point alternative
    app()


if __name__ == "__main__":  # pragma: no cover
    app()
