"""What `inertia run` prints and the options that shape its pictures: the progress line fits 80
columns and keeps its label, the timings line counts first frame and total from the command's start,
a body-only scene says what it holds, `python -m inertia`, and --camera / --eye / --target / --resolution."""

from __future__ import annotations

import io
import subprocess
import sys
import textwrap

import numpy as np
from rich.console import Console
from typer.testing import CliRunner

import inertia
from inertia.cli import main as cli
from inertia.io import read_manifest
from inertia.render import read_png

runner = CliRunner()

TINY = """
format_version = 1
name = "tiny"
[simulation]
dt = 0.01
duration = 0.1
fps = 20
[[particles]]
name = "balls"
mass = 0.01
radius = 0.05
lattice = { origin = [0.0, 0.0, 0.3], counts = [3, 3, 1], spacing = 0.2 }
[[forces]]
type = "gravity"
[[colliders]]
name = "ground"
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[output]
video = []
frames = true
plot = false
"""

BODY_ONLY = """
format_version = 1
name = "one_box"
[simulation]
dt = 0.02
duration = 0.1
fps = 10
[bodies.ground]
motion = "static"
shape = { type = "plane" }
[bodies.box]
shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }
position = [0.0, 0.0, 0.5]
[output]
video = []
plot = false
"""


def _scene(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def test_progress_line_fits_80_columns_and_keeps_its_label():
    buffer = io.StringIO()
    console = Console(file=buffer, width=80, force_terminal=True, color_system=None, legacy_windows=False)
    bar = cli._progress(False, to=console)
    task = bar.add_task("simulating", total=12.0, frame=151, frames=301, rate=123456.0)
    bar.update(task, completed=6.25)
    # the compile notice arrives through the steady view of the bar: the label does not change
    cli._SteadyLabel(bar).update(task, description="compiling kernels (first run only)")
    assert bar.tasks[0].description == "simulating"
    console.print(bar.get_renderable())
    lines = [line for line in buffer.getvalue().splitlines() if line.strip()]
    assert len(lines) == 1 and len(lines[0]) <= 80, lines
    assert "frame 151/301" in lines[0] and "123.5k st/s" in lines[0]


def test_timings_first_frame_within_total_and_frames_at_resolution(tmp_path):
    scene = _scene(tmp_path, TINY)
    out = tmp_path / "run"
    result = runner.invoke(cli.app, ["run", scene, "-o", str(out), "--resolution", "320x180", "--camera", "top"])
    assert result.exit_code == 0, result.output
    timings = read_manifest(out / "manifest.json")["timings"]
    assert 0 < timings["first_frame"] <= timings["total"]
    assert timings["run"] <= timings["total"]
    line = [ln for ln in result.output.splitlines() if ln.startswith("timings:")][0]
    assert line.startswith("timings: first frame ") and ", total " in line
    frame = read_png(out / "frames" / "frame_00000.png")
    assert frame.shape[:2] == (180, 320)


def test_camera_eye_and_target_move_the_picture(tmp_path):
    scene = _scene(tmp_path, TINY)
    images = []
    for name, extra in (("a", []), ("b", ["--eye", "3,0,0.5", "--target", "0.2,0.2,0.2"])):
        out = tmp_path / name
        result = runner.invoke(cli.app, ["run", scene, "-o", str(out), "-q", "--resolution", "160x90", *extra])
        assert result.exit_code == 0, result.output
        images.append(read_png(out / "frames" / "frame_00001.png").astype(int))
    assert np.count_nonzero(np.any(images[0] != images[1], axis=2)) > 1000


def test_bad_camera_options_name_the_option(tmp_path):
    scene = _scene(tmp_path, TINY)
    for args, words in ((["--camera", "sideways"], ["--camera", "front", "iso"]),
                        (["--eye", "1,2"], ["--eye", "X,Y,Z"]),
                        (["--resolution", "100"], ["--resolution", "WIDTHxHEIGHT"]),
                        (["--resolution", "8x8"], ["--resolution", "16 <= width"])):
        result = runner.invoke(cli.app, ["run", scene, "-o", str(tmp_path / "bad"), "-q", *args])
        assert result.exit_code == 2, (args, result.output)
        assert all(w in result.output for w in words), (args, result.output)
    assert not (tmp_path / "bad" / "states").exists()  # refused before anything ran


def test_body_only_scene_says_what_it_holds(tmp_path):
    scene = _scene(tmp_path, BODY_ONLY)
    result = runner.invoke(cli.app, ["run", scene, "-o", str(tmp_path / "run"), "--no-render"])
    assert result.exit_code == 0, result.output
    first = result.output.splitlines()[0]
    assert first.startswith("one_box: 1 rigid body (1 dynamic), 2 shapes;"), first


def test_python_dash_m_inertia():
    done = subprocess.run([sys.executable, "-m", "inertia", "--version"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"inertia {inertia.__version__}"
