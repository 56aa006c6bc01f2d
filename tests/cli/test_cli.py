"""`inertia` end to end: real scenes into temporary directories, every output opened, exit codes."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
from typer.testing import CliRunner

from inertia.cli.main import app
from inertia.io import load_states, read_manifest, read_ply

runner = CliRunner()

TINY = """
format_version = 1
name = "tiny"
[simulation]
dt = 0.005
duration = 0.2
fps = 20
seed = 3
integrator = "semi_implicit_euler"

[[particles]]
name = "spray"
mass = 0.01
radius = 0.02
capacity = 60
[[particles.emitters]]
rate = 200.0
position = [0.0, 0.0, 0.2]
cone = { direction = [0.0, 0.0, 1.0], speed = 1.5, spread = 0.3 }
lifetime = 1.0

[[particles]]
name = "chain"
integrator = "rk4"
mass = 0.05
radius = 0.02
chain = { start = [0.3, 0, 0.5], end = [0.6, 0, 0.5], count = 4, stiffness = 100.0 }

[[forces]]
type = "gravity"

[[colliders]]
name = "ground"
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
restitution = 0.5

[output]
video = ["mp4", "gif"]
frames = true
plot = true
ply = true
usd = true

[render]
width = 96
height = 64
"""

FRAMES = 5   # 0.2 s at 20 fps, frame 0 included


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_run_writes_every_output(write_scene, tmp_path):
    scene = write_scene(TINY)
    out = tmp_path / "out"
    result = invoke("run", scene, "--out", out, "--quiet")
    assert result.exit_code == 0, result.output
    states = load_states(out / "states")
    assert states.frame_count == FRAMES and states.particle_count == 64
    assert states.metadata["scene_name"] == "tiny" and "format_version = 1" in states.metadata["scene"]
    assert states.metadata["seed"] == 3
    # videos decode with the right frame count
    import imageio.v3 as iio
    import imageio_ffmpeg

    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(out / "movie.mp4"))
    assert frames == FRAMES
    assert iio.imread(out / "movie.mp4", index=0).shape == (64, 96, 3)
    assert iio.imread(out / "movie.gif", index=None).shape[0] == FRAMES
    # PNG frames, plot
    pngs = sorted((out / "frames").glob("*.png"))
    assert len(pngs) == FRAMES and iio.imread(pngs[-1]).shape == (64, 96, 3)
    assert iio.imread(out / "energy.png").ndim == 3
    # PLY: one per frame, loadable, holding the active particles
    plys = sorted((out / "ply").glob("*.ply"))
    assert len(plys) == FRAMES
    last = read_ply(plys[-1])
    assert len(last["x"]) == int(states.fields["active"][-1].sum())
    # USD: time samples of the points, one per frame
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out / "points.usdc"))
    points = [p for p in stage.Traverse() if p.IsA(UsdGeom.Points)]
    assert points
    assert len(UsdGeom.Points(points[0]).GetPointsAttr().GetTimeSamples()) == FRAMES
    # manifest
    manifest = read_manifest(out / "manifest.json")
    assert manifest["frame_count"] == FRAMES and manifest["step_count"] == 40
    assert manifest["extra"]["status"] == "completed" and manifest["seed"] == 3
    assert set(manifest["outputs"]) >= {"states", "checkpoint", "mp4", "gif", "frames", "plot", "ply", "usd"}
    assert "first_frame" in manifest["timings"]
    assert not [p for p in out.iterdir() if ".partial" in p.name]


def test_resume_through_the_cli_is_bit_identical(write_scene, tmp_path):
    scene = write_scene(TINY.replace("duration = 0.2", "duration = 0.4"))
    full, part = tmp_path / "full", tmp_path / "part"
    assert invoke("run", scene, "-o", full, "-q", "--no-render").exit_code == 0
    stopped = invoke("run", scene, "-o", part, "-q", "--no-render", "--stop-after", 3)
    assert stopped.exit_code == 130 and "--resume" in stopped.output
    assert load_states(part / "states").frame_count == 3
    # an existing run is not replaced by accident
    again = invoke("run", scene, "-o", part, "-q")
    assert again.exit_code == 2 and "already holds a run" in again.output
    resumed = invoke("run", scene, "-o", part, "-q", "--resume")
    assert resumed.exit_code == 0, resumed.output
    a, b = load_states(full / "states"), load_states(part / "states")
    assert a.frame_count == b.frame_count == 9
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    np.testing.assert_array_equal(a.fields["active"], b.fields["active"])
    assert (part / "movie.mp4").exists()


def test_input_errors_exit_2_without_traceback(write_scene, tmp_path):
    bad = write_scene(TINY.replace("restitution = 0.5", "restitutoin = 0.5"), "bad.toml")
    result = invoke("run", bad, "-o", tmp_path / "o")
    assert result.exit_code == 2
    assert "colliders[0].restitutoin: unknown key 'restitutoin'; did you mean 'restitution'?" in result.output
    assert "Traceback" not in result.output
    assert invoke("validate", bad).exit_code == 2
    # a missing file, and a near-miss example name
    missing = invoke("run", tmp_path / "nope.toml")
    assert missing.exit_code == 2 and "file not found" in missing.output
    near = invoke("run", "fountian")
    assert near.exit_code == 2 and "did you mean the example 'fountain'" in near.output
    # an output directory that cannot be created or written
    blocker = tmp_path / "file"
    blocker.write_text("x")
    scene = write_scene(TINY)
    unwritable = invoke("run", scene, "-o", blocker / "sub")
    assert unwritable.exit_code == 2 and "cannot create output directory" in unwritable.output
    not_a_dir = invoke("run", scene, "-o", blocker)
    assert not_a_dir.exit_code == 2 and "is not a directory" in not_a_dir.output
    # resume with nothing to resume; overrides that make no sense
    nothing = invoke("run", scene, "-o", tmp_path / "empty", "--resume")
    assert nothing.exit_code == 2 and "nothing to resume" in nothing.output
    fast = invoke("run", scene, "-o", tmp_path / "f", "--fps", 1000)
    assert fast.exit_code == 2 and "simulation: fps = 1000" in fast.output


def test_debug_shows_the_traceback(write_scene):
    bad = write_scene(TINY.replace("dt = 0.005", "dt = -1"))
    result = invoke("validate", bad, "--debug")
    assert result.exit_code != 0 and result.exception is not None
    assert "simulation.dt: must be > 0" in str(result.exception)


def test_diverging_scene_names_the_scene(write_scene, tmp_path):
    scene = write_scene("""
        format_version = 1
        [simulation]
        dt = 0.05
        duration = 5.0
        fps = 10
        integrator = "euler"
        [[particles]]
        mass = 0.001
        positions = [[0, 0, 0], [1, 0, 0]]
        velocities = [[0, 0, 0], [0, 0, 1]]
        forces = [{ type = "springs", pairs = [[0, 1]], stiffness = 1e12 }]
    """, "blowup.toml")
    out = tmp_path / "o"
    result = invoke("run", scene, "-o", out, "-q")
    assert result.exit_code == 2
    assert str(scene) in result.output and "diverged" in result.output and "Traceback" not in result.output
    assert load_states(out / "states").frame_count >= 1
    assert read_manifest(out / "manifest.json")["extra"]["status"] == "diverged"


def test_validate_examples_schema_and_render(write_scene, tmp_path):
    ok = invoke("validate", "chain")
    assert ok.exit_code == 0 and "ok" in ok.output and "chain" in ok.output
    listing = invoke("examples")
    assert listing.exit_code == 0 and "fountain" in listing.output and "vortex" in listing.output
    copied = invoke("examples", "--copy", "vortex", tmp_path / "mine")
    assert copied.exit_code == 0 and (tmp_path / "mine" / "vortex.toml").exists()
    assert invoke("examples", "--copy", "vortex", tmp_path / "mine").exit_code == 2   # no overwrite
    assert invoke("examples", "--copy", "vortx", tmp_path / "mine").exit_code == 2
    schema = invoke("schema")
    assert schema.exit_code == 0 and json.loads(schema.stdout)["title"] == "Inertia scene"
    # render a recorded run again, elsewhere
    scene = write_scene(TINY.replace('video = ["mp4", "gif"]', "video = []"))
    out = tmp_path / "run"
    assert invoke("run", scene, "-o", out, "-q", "--no-render").exit_code == 0
    assert not (out / "movie.mp4").exists()
    rendered = invoke("render", out / "states", "-o", tmp_path / "again", "--video", "gif", "--no-plot",
                      "--width", 64, "--height", 48, "-q")
    assert rendered.exit_code == 0, rendered.output
    import imageio.v3 as iio
    assert iio.imread(tmp_path / "again" / "movie.gif", index=None).shape[0] == FRAMES
    assert invoke("render", tmp_path / "missing").exit_code == 2
    assert invoke("render", out / "states", "--video", "avi").exit_code == 2


def test_warmup_runs_its_scenes():
    result = invoke("warmup", "--only", "3-D tracers, rk4", "-q")
    assert result.exit_code == 0, result.output
    assert invoke("warmup", "--only", "no such scene").exit_code == 2


def test_bench_runs_the_scripts(tmp_path):
    bench = tmp_path / "benchmarks"
    bench.mkdir()
    (bench / "bench_hello.py").write_text("print('ratio 1.0')\n")
    result = invoke("bench", "--dir", bench)
    assert result.exit_code == 0
    assert invoke("bench", "nope", "--dir", bench).exit_code == 2
    assert invoke("bench", "--dir", tmp_path / "none").exit_code == 2


def test_view_hands_the_run_to_the_viewer(write_scene, tmp_path, monkeypatch):
    """`inertia view` simulates a scene (or loads a state file) and serves it (viewer stubbed here;
    tests/viewer drives the real one in a browser)."""
    import inertia.viewer as viewer

    calls = []
    monkeypatch.setattr(viewer, "view", lambda states, **kw: calls.append((states, kw)), raising=False)
    scene = write_scene(TINY)
    assert invoke("view", scene, "--port", 0).exit_code == 0
    states, kw = calls[-1]
    assert states.frame_count == FRAMES and kw["port"] == 0 and len(kw["colliders"]) == 1
    out = tmp_path / "o"
    assert invoke("run", scene, "-o", out, "-q", "--no-render").exit_code == 0
    assert invoke("view", out / "states").exit_code == 0
    assert calls[-1][0].frame_count == FRAMES and len(calls[-1][1]["colliders"]) == 1


def _wait_for(condition, proc, timeout=120.0):
    """Poll `condition()` until true; fail at once if the process ends first."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert proc.poll() is None, f"the run ended before the point waited for: {proc.communicate()}"
        assert time.monotonic() < deadline, "timed out waiting for the run"
        time.sleep(0.01)


def _read_line(proc, prefix, timeout=120.0):
    """The first stdout line starting with `prefix` (a known point of the run, reported on stdout)."""
    import selectors

    selector = selectors.DefaultSelector()
    selector.register(proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if selector.select(timeout=max(0.0, deadline - time.monotonic())):
            line = proc.stdout.readline()
            assert line, f"the run ended before printing {prefix!r}: {proc.communicate()}"
            if line.startswith(prefix):
                return line
    raise AssertionError(f"no {prefix!r} line within {timeout} s")


def _start_long_run(scene, out):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "inertia.cli", "run", str(scene), "-o", str(out), "-q",
                             "--no-render", "--report-frames"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def test_ctrl_c_stops_cleanly_and_resumes(write_scene, tmp_path):
    """A real SIGINT to `python -m inertia.cli run` at known points: exit 130, the resume hint,
    files consistent, and resume completes the run with its own duration."""
    scene = write_scene(TINY.replace("duration = 0.2", "duration = 30.0").replace("fps = 20", "fps = 10"))
    # 1. after a frame was recorded (the run reports it on stdout)
    out = tmp_path / "o"
    proc = _start_long_run(scene, out)
    assert _read_line(proc, "frame ").startswith("frame 1/301")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "stopped" in err and "--resume" in err
    states = load_states(out / "states")
    manifest = read_manifest(out / "manifest.json")
    assert manifest["extra"]["status"] == "interrupted" and manifest["frame_count"] == states.frame_count >= 1
    resumed = invoke("run", scene, "-o", out, "-q", "--no-render", "--resume")
    assert resumed.exit_code == 0, resumed.output
    assert load_states(out / "states").frame_count == 301
    # 2. the moment the state directory appears, before any frame: still a clean, resumable stop
    early = tmp_path / "early"
    proc = _start_long_run(scene, early)
    _wait_for(lambda: (early / "states").exists(), proc)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "stopped" in err and "--resume" in err, err
    assert load_states(early / "states").frame_count == read_manifest(early / "manifest.json")["frame_count"]


def test_a_killed_run_leaves_readable_files(write_scene, tmp_path):
    """SIGKILL mid-run: the state directory still loads (only complete chunks are listed)."""
    scene = write_scene(TINY.replace("duration = 0.2", "duration = 30.0").replace("fps = 20", "fps = 100")
                        .replace("dt = 0.005", "dt = 0.002"))
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "inertia.cli", "run", str(scene), "-o", str(out), "-q", "--no-render"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and not list((out / "states").glob("chunk-*.npz")):
        time.sleep(0.1)
    time.sleep(0.5)
    proc.kill()
    proc.wait(timeout=60)
    states = load_states(out / "states")
    assert states.frame_count >= 64 and np.all(np.diff(states.times) > 0)
    # the next run in the same directory cleans the temporary files; killed before its first
    # checkpoint, the run cannot be resumed, so a plain re-run of the same scene replaces it (issue 22;
    # with a checkpoint it is kept for --resume, see test_ctrl_c_stops_cleanly_and_resumes)
    if not (out / "checkpoint.npz").exists():
        result = invoke("run", scene, "-o", out, "-q", "--no-render", "--duration", "0.2")
        assert result.exit_code == 0, result.output
        assert load_states(out / "states").frame_count == 21
    else:
        result = invoke("run", scene, "-o", out, "-q")
        assert result.exit_code == 2 and "already holds a run" in result.output
    assert not [p for p in (out / "states").iterdir() if ".partial" in p.name]


# ---- issue 8: bad input is exit 2, paths stay the user's, runs are the run's own --------------
def test_a_path_that_does_not_exist_never_runs_an_example(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name in ("./fountain.toml", "fountain.toml", "scenes/fountain.toml", "./fountain"):
        result = invoke("validate", name)
        assert result.exit_code == 2, (name, result.output)
        assert "file not found" in result.output and "inertia run fountain" in result.output
    assert invoke("validate", "fountain", "--no-build").exit_code == 0


def test_bad_input_is_exit_2_with_a_clear_message(write_scene, tmp_path):
    cases = [
        (TINY.replace("duration = 0.2", "duration = inf"), "scene.toml", "simulation.duration: must be a finite number"),
        (TINY.replace("dt = 0.005", "dt = inf"), "scene.toml", "simulation.dt: must be a finite number"),
        ('{"format_version": 1, "particles": ' + "[" * 100_000 + "]" * 100_000 + "}", "deep.json", "nested deeper"),
        (TINY.replace("mass = 0.01", "mass = true"), "scene.toml", "particles[0].mass: must be a number"),
        (TINY.replace("mass = 0.01", 'mass = "0.01"'), "scene.toml", "particles[0].mass: must be a number"),
        (TINY.replace('name = "tiny"', 'name = "/tmp/elsewhere"'), "scene.toml", "name: must be a plain name"),
        (TINY + '\n[output.x]\n', "scene.toml", "output.x"),
        (TINY.replace("[output]", '[output]\ndirectory = "../../elsewhere"'), "scene.toml",
         "output.directory: must be a relative path inside the working directory"),
    ]
    for text, name, expected in cases:
        scene = write_scene(text, name)
        for command in (("validate", scene), ("run", scene, "-o", tmp_path / "o", "-q")):
            result = invoke(*command)
            assert result.exit_code == 2, (expected, result.output)
            assert expected in result.output and "internal error" not in result.output, result.output
    assert not (tmp_path / "o").exists() and not (tmp_path.parent / "elsewhere").exists()
    scene = write_scene(TINY)
    inf = invoke("run", scene, "-o", tmp_path / "o", "--duration", "inf")
    assert inf.exit_code == 2 and "simulation.duration: must be a finite number" in inf.output


def test_damaged_state_files_are_exit_2_naming_the_file(write_scene, tmp_path):
    scene = write_scene(TINY.replace('video = ["mp4", "gif"]', "video = []"))
    out = tmp_path / "run"
    assert invoke("run", scene, "-o", out, "-q", "--no-render").exit_code == 0
    chunk = next((out / "states").glob("chunk-*.npz"))
    chunk.write_bytes(chunk.read_bytes()[:100])
    result = invoke("render", out / "states", "-o", tmp_path / "r", "--video", "none", "--no-plot", "-q")
    assert result.exit_code == 2 and chunk.name in result.output and "damaged" in result.output, result.output
    (out / "states" / "index.json").write_text('{"chunks": [')
    for command in (("render", out / "states", "-q"), ("view", out / "states")):
        result = invoke(*command)
        assert result.exit_code == 2 and "index.json" in result.output, result.output
    resumed = invoke("run", scene, "-o", out, "-q", "--resume")
    assert resumed.exit_code == 2 and "internal error" not in resumed.output, resumed.output


def test_huge_and_endless_scenes_are_refused_before_running(write_scene, tmp_path):
    huge = write_scene(TINY.replace("count = 4,", "count = 1_000_000_000,"), "huge.toml")
    started = time.perf_counter()
    result = invoke("validate", huge)
    elapsed = time.perf_counter() - started
    assert result.exit_code == 2, result.output
    assert "particles[1].chain.count" in result.output and "of memory" in result.output and "available" in result.output
    print(f"validate refused count = 1e9 in {elapsed:.3f} s")
    endless = write_scene(TINY.replace("duration = 0.2", "duration = 1e12"), "endless.toml")
    result = invoke("run", endless, "-o", tmp_path / "o", "-q")
    assert result.exit_code == 2 and "simulation.duration" in result.output and "--force" in result.output
    assert not (tmp_path / "o").exists()
    warned = invoke("validate", endless)
    assert warned.exit_code == 0 and "warning" in warned.output and "years" in warned.output


def test_resume_uses_the_runs_own_duration_fps_and_seed(write_scene, tmp_path):
    scene = write_scene(TINY.replace("duration = 0.2", "duration = 0.4"))
    full, part = tmp_path / "full", tmp_path / "part"
    overrides = ("--duration", 0.3, "--seed", 11, "--fps", 10)
    assert invoke("run", scene, "-o", full, "-q", "--no-render", *overrides).exit_code == 0
    assert invoke("run", scene, "-o", part, "-q", "--no-render", "--stop-after", 2, *overrides).exit_code == 130
    # a different value is refused, naming what the run was started with
    for option, value, expected in (("--duration", 0.2, "--duration 0.3"), ("--seed", 3, "--seed 11"),
                                    ("--fps", 20, "--fps 10")):
        refused = invoke("run", scene, "-o", part, "-q", "--no-render", "--resume", option, value)
        assert refused.exit_code == 2 and expected in refused.output, refused.output
    # without the options, the run's own values are used: the same run as the uninterrupted one
    resumed = invoke("run", scene, "-o", part, "-q", "--no-render", "--resume")
    assert resumed.exit_code == 0, resumed.output
    a, b = load_states(full / "states"), load_states(part / "states")
    assert a.frame_count == b.frame_count == 4
    np.testing.assert_array_equal(a.positions, b.positions)
    assert read_manifest(part / "manifest.json")["extra"]["duration"] == 0.3
    # a longer --duration, asked for explicitly, extends the finished run on the same trajectory
    longer = invoke("run", scene, "-o", part, "-q", "--no-render", "--resume", "--duration", 0.5)
    assert longer.exit_code == 0, longer.output
    assert load_states(part / "states").frame_count == 6
    np.testing.assert_array_equal(load_states(part / "states").positions[:4], a.positions)


def test_the_readme_command_works_twice(tmp_path, monkeypatch, write_scene):
    """`inertia run fountain --out out/fountain` run twice: a finished run of the same scene is
    replaced; an unfinished run or another scene's run is not."""
    monkeypatch.chdir(tmp_path)
    command = ("run", "fountain", "--out", "out/fountain", "--duration", 0.1, "-q", "--no-render")
    first = invoke(*command)
    assert first.exit_code == 0, first.output
    manifest_path = tmp_path / "out/fountain/manifest.json"
    # the manifest's `created` has whole seconds, so two quick runs can share it: the second run's
    # manifest is a new file (written atomically beside the old one, then renamed over it)
    first_file = manifest_path.stat()
    second = invoke(*command)
    assert second.exit_code == 0, second.output
    second_file = manifest_path.stat()
    assert (second_file.st_ino, second_file.st_mtime_ns) != (first_file.st_ino, first_file.st_mtime_ns)
    assert read_manifest(manifest_path)["extra"]["status"] == "completed"
    # another scene's finished run in that directory is kept
    other = invoke("run", write_scene(TINY), "--out", "out/fountain", "-q", "--no-render")
    assert other.exit_code == 2 and "already holds a run of another scene" in other.output
    # an unfinished run is kept for --resume
    stopped = invoke(*command, "--stop-after", 1, "--overwrite")
    assert stopped.exit_code == 130
    again = invoke(*command)
    assert again.exit_code == 2 and "--resume" in again.output


def test_ctrl_c_before_anything_is_written_says_so(write_scene, tmp_path, monkeypatch):
    import inertia.scene as scene_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(scene_module, "build", interrupted)
    result = invoke("run", write_scene(TINY), "-o", tmp_path / "o", "-q")
    assert result.exit_code == 130 and "nothing was written" in result.output
    assert not (tmp_path / "o" / "states").exists()


def test_view_cleans_up_its_temporary_directory(write_scene, tmp_path, monkeypatch):
    import tempfile

    import inertia.viewer as viewer

    system_tmp = tmp_path / "systmp"
    system_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    monkeypatch.setattr(viewer, "view", lambda states, **kw: None, raising=False)
    assert invoke("view", write_scene(TINY), "--port", 0).exit_code == 0
    assert list(system_tmp.iterdir()) == []

    def stopped(states, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(viewer, "view", stopped, raising=False)
    assert invoke("view", write_scene(TINY), "--port", 0).exit_code == 130
    assert list(system_tmp.iterdir()) == []
