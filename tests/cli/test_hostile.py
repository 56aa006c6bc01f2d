"""A corpus of hostile inputs through the `inertia` command: scene files with bodies, grids, SPH and
simulation settings; sweep specifications; damaged checkpoints and state files; output directories
that are links. Every input ends as exit 2 with a message naming the problem (the key path, the
array, the file or the fact), or as a correct run; never as an internal error (exit 1), a crash, a
hang or a memory blow-up.

Inputs that cannot crash the interpreter run in this process (`CliRunner`, one process for the
whole corpus); those that once crashed it (an SPH checkpoint whose particle count exceeds the
arrays: SIGSEGV) or that would allocate or loop without bound if not refused run in a subprocess
with a time limit and an address-space limit (``RLIMIT_AS``), so a regression fails the test instead
of taking the machine down.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from inertia.cli.main import app

SRC = str(Path(__file__).resolve().parents[2] / "src")
MEMORY_LIMIT = 3 * 1024 ** 3          # bytes of address space for the subprocess cases
TIME_LIMIT = 120                      # seconds (a cold Numba cache compiles within it)

RIGID = """
format_version = 1
name = "crates"
[simulation]
dt = 0.01
duration = 0.2
fps = 20
[bodies.ground]
motion = "static"
shape = { type = "plane" }
[bodies.box]
shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }
position = [0.0, 0.0, 0.3]
array = { count = [2, 1, 1], spacing = [0.3, 0.3, 0.3] }
[output]
video = []
plot = false
"""

SPH = """
format_version = 1
name = "dam"
[simulation]
dim = 2
dt = 0.005
duration = 0.1
fps = 20
[[colliders]]
type = "container"
name = "tank"
center = [0.4, 0.3]
half_extents = [0.4, 0.3]
[sph.water]
spacing = 0.04
domain = [[0, 0], [0.8, 0.6]]
fluid = [{ box = [[0, 0], [0.2, 0.4]] }]
boundaries = ["tank"]
[output]
video = []
plot = false
"""

GRID = """
format_version = 1
name = "cavity"
[simulation]
dim = 2
dt = 0.01
duration = 0.1
fps = 20
[fluids.cavity]
shape = [8, 8]
cell_size = 0.125
viscosity = 0.01
scalars = []
[fluids.cavity.boundaries]
"x-" = { type = "no-slip" }
"x+" = { type = "no-slip" }
"y-" = { type = "no-slip" }
"y+" = { type = "wall", velocity = [1.0, 0.0] }
[output]
video = []
plot = false
"""

PARTICLES = """
format_version = 1
name = "drop"
[simulation]
dt = 0.01
duration = 0.1
fps = 20
integrator = "semi_implicit_euler"
[[particles]]
name = "ball"
positions = [[0.0, 0.0, 0.3]]
radius = 0.05
[output]
video = []
plot = false
"""


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def replaced(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new)


def hull_points(n: int) -> str:
    rng = np.random.default_rng(1)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1)[:, None] * 10
    return "[" + ",".join(f"[{a:.4f},{b:.4f},{c:.4f}]" for a, b, c in p) + "]"


def lying_npy(path: Path) -> Path:
    """A .npy whose header claims (100000, 100000) float64 (80 GB) but holds 16 bytes."""
    header = {"descr": "<f8", "fortran_order": False, "shape": (100000, 100000)}
    with open(path, "wb") as handle:
        np.lib.format.write_array_header_1_0(handle, header)
        handle.write(np.zeros(2).tobytes())
    return path


# ---- scene files: (id, base scene, (old, new) edits, command, words the message must hold) ------
# command "validate" checks and builds without running; "run" goes as far as the run (a refusal
# before anything is simulated, or a divergence stopped with its cause).
SCENES = [
    # bodies, materials, shapes
    ("body-velocity-1e300", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nvelocity = [1e300, 0, 0]")],
     "validate", ["bodies.box.velocity[0]", "1e+300"]),
    ("body-velocity-above-max-speed", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nvelocity = [2e4, 0, 0]")],
     "validate", ["bodies.box.velocity", "max_speed"]),
    ("body-position-1e308", RIGID, [("[0.0, 0.0, 0.3]", "[0.0, 0.0, 1e308]")], "validate", ["bodies.box.position[2]"]),
    ("body-mass-bool", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nmass = true")],
     "validate", ["bodies.box.mass", "must be a number"]),
    ("body-mass-string", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nmass = \"2\"")],
     "validate", ["bodies.box.mass"]),
    ("body-mass-nan", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nmass = nan")],
     "validate", ["bodies.box.mass", "finite"]),
    ("body-half-extent-negative", RIGID, [("half_extents = [0.1, 0.1, 0.1]", "half_extents = [-0.1, 0.1, 0.1]")],
     "validate", ["half_extents[0]", "> 0"]),
    ("body-array-too-many", RIGID, [("count = [2, 1, 1]", "count = [1000, 1000, 1]")], "validate",
     ["bodies.box", "1,000,000 bodies"]),
    ("material-friction-bool", RIGID, [("[bodies.ground]", "[materials.wood]\nfriction = true\n[bodies.ground]")],
     "validate", ["materials.wood.friction"]),
    ("material-unknown", RIGID, [("position = [0.0, 0.0, 0.3]", "position = [0.0, 0.0, 0.3]\nmaterial = \"wod\"")],
     "validate", ["bodies.box.material", "wod"]),
    ("hull-huge", RIGID, [("shape = { type = \"box\", half_extents = [0.1, 0.1, 0.1] }",
                           "shape = { type = \"hull\", points = HULL }")], "run", ["bodies.box.shape.points", "20,001 points"]),
    ("mesh-system-file", RIGID, [("shape = { type = \"plane\" }", "shape = { type = \"mesh\", file = \"/etc/passwd\" }")],
     "validate", ["/etc/passwd", "not a mesh file type"]),
    ("mesh-index-beyond-int64", RIGID, [("shape = { type = \"plane\" }", "shape = { type = \"mesh\", vertices = "
                                         "[[0,0,0],[1,0,0],[0,1,0]], triangles = [[0, 1, 18446744073709551616]] }")],
     "validate", ["triangles[0][2]", "64-bit"]),
    ("heightfield-lying-npy", RIGID, [("shape = { type = \"plane\" }",
                                       "shape = { type = \"heightfield\", file = \"lie.npy\", spacing = [0.1, 0.1] }")],
     "validate", ["bodies.ground.shape.file", "header says shape (100000, 100000)"]),
    ("heightfield-not-npy", RIGID, [("shape = { type = \"plane\" }",
                                     "shape = { type = \"heightfield\", file = \"scene.toml\", spacing = [0.1, 0.1] }")],
     "validate", ["bodies.ground.shape.file", "expected a .npy"]),
    # SPH
    ("sph-spacing-zero", SPH, [("spacing = 0.04", "spacing = 0")], "validate", ["sph.water.spacing"]),
    ("sph-spacing-bool", SPH, [("spacing = 0.04", "spacing = true")], "validate", ["sph.water.spacing", "must be a number"]),
    ("sph-spacing-string", SPH, [("spacing = 0.04", "spacing = \"0.02\"")], "validate", ["sph.water.spacing"]),
    ("sph-dt-max-tiny", SPH, [("spacing = 0.04", "spacing = 0.04\ndt_max = 1e-300")], "validate", ["sph.water.dt_max"]),
    ("sph-box-outside-domain", SPH, [("[[0, 0], [0.2, 0.4]]", "[[0, 0], [2.0, 0.4]]")], "validate",
     ["sph.water.fluid[0].box", "inside the domain"]),
    ("sph-box-inverted", SPH, [("[[0, 0], [0.2, 0.4]]", "[[0.2, 0], [0.0, 0.4]]")], "validate", ["sph.water.fluid[0].box"]),
    ("sph-viscosity-negative", SPH, [("spacing = 0.04", "spacing = 0.04\nviscosity = -1.0")], "validate",
     ["sph.water.viscosity"]),
    ("sph-unknown-boundary", SPH, [("boundaries = [\"tank\"]", "boundaries = [\"tnak\"]")], "validate",
     ["sph.water.boundaries[0]"]),
    # grid fluids
    ("grid-cell-size-tiny", GRID, [("cell_size = 0.125", "cell_size = 1e-300")], "validate", ["fluids.cavity.cell_size"]),
    ("grid-shape-negative", GRID, [("shape = [8, 8]", "shape = [-5, 8]")], "validate", ["fluids.cavity.shape[0]"]),
    ("grid-viscosity-bool", GRID, [("viscosity = 0.01", "viscosity = true")], "validate", ["fluids.cavity.viscosity"]),
    ("grid-inflow-no-outlet", GRID, [("\"x-\" = { type = \"no-slip\" }", "\"x-\" = { type = \"inflow\", velocity = [1.0, 0.0] }")],
     "validate", ["fluids.cavity.boundaries.x-", "outflow"]),
    ("grid-huge", GRID, [("shape = [8, 8]", "shape = [900000, 900000]")], "validate", ["fluids.cavity.shape", "memory"]),
    ("grid-source-outside", GRID, [("scalars = []", "scalars = []\nsources = [{ lower = [5.0, 5.0], upper = [6.0, 6.0] }]")],
     "validate", ["fluids.cavity.sources[0]", "inside the grid"]),
    ("grid-runaway", GRID, [("\"x-\" = { type = \"no-slip\" }", "\"x-\" = { type = \"inflow\", velocity = [1e12, 0.0] }"),
                            ("\"x+\" = { type = \"no-slip\" }", "\"x+\" = { type = \"outflow\" }")], "run",
     ["grid fluid step", "CFL substeps", "inflow too strong"]),
    # simulation settings and plain values
    ("duration-max-float", PARTICLES, [("duration = 0.1", "duration = 1.7976931348623157e308")], "validate",
     ["simulation.duration"]),
    ("duration-too-long", PARTICLES, [("duration = 0.1", "duration = 1e14")], "run", ["simulation.duration", "--force"]),
    ("fps-no-frame", PARTICLES, [("fps = 20", "fps = 0.5"), ("video = []", "video = [\"mp4\"]")], "run",
     ["simulation.fps", "at least 2 frames"]),
    ("mesh-collider-garbage", PARTICLES, [("[output]", "[[colliders]]\ntype = \"mesh\"\nfile = \"bad.obj\"\n[output]")],
     "validate", ["colliders[0]", "bad.obj"]),
    ("positions-1e300", PARTICLES, [("[[0.0, 0.0, 0.3]]", "[[1e300, 0.0, 0.3]]")], "validate", ["particles[0].positions[0][0]"]),
]


@pytest.fixture(scope="module")
def corpus_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("hostile")


@pytest.mark.parametrize("case", SCENES, ids=[c[0] for c in SCENES])
def test_hostile_scene_files_end_in_a_named_error(case, corpus_dir):
    name, base, edits, command, words = case
    text = textwrap.dedent(base)
    for old, new in edits:
        text = replaced(text, old, new.replace("HULL", hull_points(20_001)) if "HULL" in new else new)
    folder = corpus_dir / name
    folder.mkdir()
    lying_npy(folder / "lie.npy")
    (folder / "bad.obj").write_bytes(bytes(range(256)) * 4)
    scene = folder / "scene.toml"
    scene.write_text(text)
    args = ["validate", scene] if command == "validate" else ["run", scene, "--out", folder / "out", "--quiet"]
    started = time.perf_counter()
    result = invoke(*args)
    assert result.exit_code == 2, (name, result.exit_code, result.output)
    flat = " ".join(result.output.split())
    for word in words:
        assert word in flat, (name, word, result.output)
    assert "internal error" not in result.output and "Traceback" not in result.output
    assert time.perf_counter() - started < 60


def test_a_scene_file_too_large_to_parse_quickly_is_refused_unread(tmp_path):
    scene = tmp_path / "huge.toml"
    with open(scene, "wb") as handle:
        handle.truncate(100_000_000)          # 100 MB (sparse): refused by its size, never read
    result = invoke("validate", scene)
    assert result.exit_code == 2 and "100 MB" in result.output and "at most 32 MB" in result.output, result.output


def test_json_scenes_with_a_lone_surrogate_or_a_5000_digit_integer(tmp_path):
    surrogate = tmp_path / "surrogate.json"
    surrogate.write_text('{"format_version": 1, "name": "a\\ud800b", "particles": []}')
    result = invoke("validate", surrogate)
    assert result.exit_code == 2 and "name" in result.output and "Unicode" in result.output, result.output
    digits = tmp_path / "digits.json"
    digits.write_text('{"format_version": 1, "simulation": {"seed": ' + "9" * 5000 + "}}")
    result = invoke("validate", digits)
    assert result.exit_code == 2 and "invalid JSON" in result.output, result.output


# ---- sweeps ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("args, words", [
    (["-p", "particles[0].radius=0.01:0.1:1000000000000"], ["1,000,000,000,000 points"]),
    (["-p", "particles[0].radius=0.01:0.1:1000000", "-p", "simulation.dt=0.001:0.01:1000000"],
     ["1,000,000,000,000 variants"]),
    (["-p", "particles[0].radius=0.01:0.1", "--samples", "1000000000000"], ["1,000,000,000,000 variants"]),
    (["-p", "particles[0].radius=0.01,0.02", "--workers", "0"], ["--workers", ">= 1"]),
])
def test_hostile_sweeps_are_refused_at_once_naming_the_count(args, words, tmp_path):
    scene = tmp_path / "drop.toml"
    scene.write_text(textwrap.dedent(PARTICLES))
    started = time.process_time()       # CPU time: the refusal's own cost, whatever the machine's load
    result = invoke("sweep", scene, "--out", tmp_path / "out", "--quiet", *args)
    elapsed = time.process_time() - started
    assert result.exit_code == 2, result.output
    flat = " ".join(result.output.split())
    for word in words:
        assert word in flat, (word, result.output)
    assert elapsed < 1.0 or "--workers" in words, elapsed


# ---- checkpoints and state files ------------------------------------------------------------------
def _read(path):
    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    return json.loads(str(arrays.pop("tree")[()])), arrays


def _write(path, tree, arrays):
    arrays = dict(arrays)
    arrays["tree"] = np.array(json.dumps(tree))
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def _array(tree, arrays, *path):
    node = tree
    for p in path:
        node = node[p]
    return node["__array__"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A finished small run of each part (3 s per part with a warm Numba cache)."""
    root = tmp_path_factory.mktemp("runs")
    out = {}
    for name, text in (("rigid", RIGID), ("sph", SPH), ("grid", GRID)):
        scene = root / f"{name}.toml"
        scene.write_text(textwrap.dedent(text))
        result = invoke("run", scene, "--out", root / name, "--quiet", "--no-render")
        assert result.exit_code == 0, result.output
        out[name] = (scene, root / name)
    return out


def _damaged_copy(runs, part, tmp_path, damage):
    scene, source = runs[part]
    out = tmp_path / part
    shutil.copytree(source, out)
    damage(out / "checkpoint.npz")
    return scene, out


def _edit(fn):
    def damage(path):
        tree, arrays = _read(path)
        fn(tree, arrays)
        _write(path, tree, arrays)
    return damage


def _flip(fraction):
    def damage(path):
        data = bytearray(path.read_bytes())
        data[int(len(data) * fraction)] ^= 0x10
        path.write_bytes(bytes(data))
    return damage


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _reshape(part, *key):
    def fn(tree, arrays):
        k = _array(tree, arrays, *key)
        arrays[k] = arrays[k][:-1]
    return _edit(fn)


def _retype(*key):
    def fn(tree, arrays):
        k = _array(tree, arrays, *key)
        arrays[k] = arrays[k].astype(np.float32)
    return _edit(fn)


def _set_item(value, *key, index=None):
    def fn(tree, arrays):
        if index is None:
            node = tree
            for p in key[:-1]:
                node = node[p]
            node[key[-1]] = value
            return
        k = _array(tree, arrays, *key)
        a = arrays[k].copy()
        a[index] = value
        arrays[k] = a
    return _edit(fn)


def _frames_plus(n):
    def fn(tree, arrays):
        tree["info"]["frame_count"] += n
    return _edit(fn)


CHECKPOINTS = [
    ("truncated", "rigid", _truncate, ["checkpoint"]),
    ("bit-flip-30%", "rigid", _flip(0.3), ["checkpoint"]),
    ("bit-flip-60%", "grid", _flip(0.6), ["checkpoint"]),
    ("bit-flip-95%", "sph", _flip(0.95), ["checkpoint"]),
    ("rigid-body_q-reshaped", "rigid", _reshape("rigid", "rigid", "body_q"), ["rigid.body_q", "shape"]),
    ("rigid-body_q-dtype", "rigid", _retype("rigid", "body_q"), ["rigid.body_q", "dtype float32"]),
    ("rigid-contact-count", "rigid", _set_item(10 ** 6, "rigid", "contacts_count"), ["rigid.contacts_count"]),
    ("rigid-contact-body", "rigid", _set_item(10 ** 6, "rigid", "contacts/contact_body", index=0),
     ["rigid.contacts/contact_body"]),
    ("rigid-frame-count", "rigid", _frames_plus(3), ["frame_count"]),
    ("grid-vel-reshaped", "grid", _reshape("grid", "fluids", "cavity", "vel0"), ["fluids.cavity.vel0", "shape"]),
    ("grid-dt-negative", "grid", _set_item(-1.0, "fluids", "cavity", "phi_dt", index=()), ["phi_dt"]),
    ("grid-time-nan", "grid", _set_item(np.nan, "fluids", "cavity", "time", index=()), ["time"]),
    ("sph-x-dtype", "sph", _retype("fluids", "water", "fluid_x"), ["fluids.water.fluid_x", "dtype"]),
    ("sph-count-small-excess", "sph", _set_item(55.0, "fluids", "water", "counters", index=3),
     ["counters", "capacity"]),
    ("sph-frame-count", "sph", _frames_plus(-2), ["frame_count"]),
]


@pytest.mark.parametrize("case", CHECKPOINTS, ids=[c[0] for c in CHECKPOINTS])
def test_damaged_checkpoints_are_refused_naming_the_array(case, runs, tmp_path):
    name, part, damage, words = case
    scene, out = _damaged_copy(runs, part, tmp_path, damage)
    result = invoke("run", scene, "--out", out, "--resume", "--quiet", "--no-render", "--duration", "0.3")
    assert result.exit_code == 2, (name, result.output)
    flat = " ".join(result.output.split())
    for word in words:
        assert word in flat, (name, word, result.output)
    assert "internal error" not in result.output


def test_a_checkpoint_from_another_scene_names_what_changed(runs, tmp_path):
    scene, source = runs["rigid"]
    out = tmp_path / "rigid"
    shutil.copytree(source, out)
    other = tmp_path / "other.toml"
    other.write_text(scene.read_text().replace("half_extents = [0.1, 0.1, 0.1]", "half_extents = [0.1, 0.1, 0.2]"))
    header = json.loads((out / "states" / "header.json").read_text())
    header["scene_path"] = str(other.resolve())
    (out / "states" / "header.json").write_text(json.dumps(header))
    result = invoke("run", other, "--out", out, "--resume", "--quiet", "--no-render")
    assert result.exit_code == 2, result.output
    flat = " ".join(result.output.split())
    assert "bodies.box.shape.half_extents[2]: 0.1 -> 0.2" in flat, result.output


def test_intact_checkpoints_still_resume(runs, tmp_path):
    for part in ("rigid", "sph", "grid"):
        scene, out = _damaged_copy(runs, part, tmp_path, lambda path: None)
        result = invoke("run", scene, "--out", out, "--resume", "--quiet", "--no-render", "--duration", "0.3")
        assert result.exit_code == 0, (part, result.output)


def test_render_refuses_recorded_settings_out_of_range(runs, tmp_path):
    _, source = runs["rigid"]
    out = tmp_path / "run"
    shutil.copytree(source, out)
    header = json.loads((out / "states" / "header.json").read_text())
    header["render"]["width"] = 0
    (out / "states" / "header.json").write_text(json.dumps(header))
    result = invoke("render", out / "states", "--no-plot", "--video", "none")
    assert result.exit_code == 2 and "render.width" in result.output, result.output


def test_render_refuses_a_header_with_a_lone_surrogate(runs, tmp_path):
    _, source = runs["rigid"]
    out = tmp_path / "run"
    shutil.copytree(source, out)
    path = out / "states" / "header.json"
    path.write_text(path.read_text().replace('"crates"', '"cr\\ud800tes"', 1))
    result = invoke("render", out / "states", "--no-plot", "--video", "none")
    assert result.exit_code == 2 and "not valid Unicode" in " ".join(result.output.split()), result.output


def test_rigid_runs_record_finite_energy_and_momentum(runs):
    from inertia.io import load_states

    states = load_states(runs["rigid"][1] / "states")
    for key in ("kinetic_energy", "potential_energy", "momentum"):
        assert np.all(np.isfinite(states.fields[key])), key
    assert states.metadata["diagnostics_cover"] == ["bodies"]


# ---- output directories ---------------------------------------------------------------------------
def test_an_output_directory_that_is_a_link_is_said_and_written_inside_its_target(runs, tmp_path):
    scene, _ = runs["rigid"]
    target = tmp_path / "elsewhere"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target)
    result = invoke("run", scene, "--out", link, "--quiet", "--no-render")
    assert result.exit_code == 0, result.output
    flat = "".join(result.output.split())
    assert "symboliclink" in flat and "".join(str(target.resolve()).split()) in flat, result.output
    assert (target / "checkpoint.npz").exists()


def test_a_link_inside_the_output_directory_is_refused(runs, tmp_path):
    scene, _ = runs["rigid"]
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "victim").mkdir()
    (out / "states").symlink_to(tmp_path / "victim")
    result = invoke("run", scene, "--out", out, "--quiet", "--no-render")
    assert result.exit_code == 2 and "symbolic link" in " ".join(result.output.split()), result.output
    assert not any((tmp_path / "victim").iterdir())


def test_a_run_killed_before_its_first_checkpoint_is_replaced_by_a_plain_rerun(runs, tmp_path):
    scene, source = runs["rigid"]
    out = tmp_path / "out"
    shutil.copytree(source, out)
    (out / "checkpoint.npz").unlink()
    (out / "manifest.json").unlink()
    (out / ".movie.mp4.0123abcd.partial.mp4").write_bytes(b"half a video")
    result = invoke("run", scene, "--out", out, "--quiet", "--no-render")
    assert result.exit_code == 0, result.output
    assert (out / "checkpoint.npz").exists()
    assert not list(out.glob("*.partial*"))


# ---- cases that once crashed or could exhaust the machine: subprocess with limits ------------------
def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _cli(*args, cwd):
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "inertia.cli", *[str(a) for a in args]], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=TIME_LIMIT, preexec_fn=_limited)


def test_limited_process_cases(runs, tmp_path):
    """SPH count far beyond capacity (was SIGSEGV), SPH spacing 1e-4 (millions of particles), a grid
    beyond memory, a body array that does not fit: each exit 2 naming the key, under 3 GB."""
    scene, source = runs["sph"]
    out = tmp_path / "sph"
    shutil.copytree(source, out)
    _set_item(1e6, "fluids", "water", "counters", index=3)(out / "checkpoint.npz")
    tiny = tmp_path / "tiny.toml"
    tiny.write_text(replaced(textwrap.dedent(SPH), "spacing = 0.04", "spacing = 1e-4"))
    wide = tmp_path / "wide.toml"
    wide.write_text(replaced(textwrap.dedent(GRID), "shape = [8, 8]", "shape = [20000, 20000]"))
    crowd = tmp_path / "crowd.toml"
    crowd.write_text(replaced(textwrap.dedent(RIGID), "count = [2, 1, 1]", "count = [100, 100, 10]"))
    cases = [
        (["run", scene, "--out", out, "--resume", "--quiet", "--no-render", "--duration", "0.3"],
         ["counters", "capacity"]),
        (["run", tiny, "--out", tmp_path / "o1", "--quiet"], ["sph.water.spacing", "memory"]),
        (["run", wide, "--out", tmp_path / "o2", "--quiet"], ["fluids.cavity.shape", "memory"]),
        (["run", crowd, "--out", tmp_path / "o3", "--quiet"], ["bodies.box.array.count", "100,000 rigid bodies"]),
    ]
    for args, words in cases:
        result = _cli(*args, cwd=tmp_path)
        assert result.returncode == 2, (args, result.returncode, result.stderr[-2000:])
        flat = " ".join(result.stderr.split())
        for word in words:
            assert word in flat, (args, word, result.stderr[-2000:])
