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


def test_ctrl_c_stops_cleanly_and_resumes(write_scene, tmp_path):
    """A real SIGINT to `python -m inertia.cli run`: exit 130, files consistent, resume completes."""
    scene = write_scene(TINY.replace("duration = 0.2", "duration = 30.0").replace("fps = 20", "fps = 10"))
    out = tmp_path / "o"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "inertia.cli", "run", str(scene), "-o", str(out), "-q", "--no-render"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.time() + 120
    while time.time() < deadline and not (out / "states" / "index.json").exists():
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "stopped" in err and "--resume" in err
    states = load_states(out / "states")
    manifest = read_manifest(out / "manifest.json")
    assert manifest["extra"]["status"] == "interrupted" and manifest["frame_count"] == states.frame_count
    resumed = invoke("run", scene, "-o", out, "-q", "--no-render", "--resume", "--duration", 1.0)
    assert resumed.exit_code == 0, resumed.output
    assert load_states(out / "states").frame_count == max(11, states.frame_count)


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
    # the next run in the same directory cleans the temporary files and refuses to clobber it
    result = invoke("run", scene, "-o", out, "-q")
    assert result.exit_code == 2 and "already holds a run" in result.output
    assert not [p for p in (out / "states").iterdir() if ".partial" in p.name]
