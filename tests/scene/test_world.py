"""The run loop: frame sampling decoupled from dt, checkpoints that resume bit for bit."""

import numpy as np
import pytest

from inertia.io import load_states
from inertia.scene import load_scene
from inertia.world import Run, frame_steps, load_checkpoint

MIXED = """
format_version = 1
[simulation]
dt = 0.004
duration = 0.4
fps = 25
seed = 4
integrator = "semi_implicit_euler"

[[particles]]
name = "spray"
mass = 0.01
radius = 0.02
[[particles.emitters]]
rate = 400.0
source = { type = "sphere", center = [0.0, 0.0, 0.3], radius = 0.05 }
cone = { direction = [0.0, 0.0, 1.0], speed = 2.0, spread = 0.4 }
lifetime = [0.1, 0.3]

[[particles]]
name = "chain"
integrator = "implicit_euler"
mass = 0.02
chain = { start = [0, 0, 1], end = [0.5, 0, 1], count = 6, stiffness = 500.0, damping = 0.1 }

[[particles]]
name = "balls"
integrator = "rk45"
integrator_options = { rtol = 1e-7 }
radius = 0.05
lattice = { origin = [-0.5, 0, 0.2], counts = [2, 2, 1], spacing = 0.2 }

[[forces]]
type = "gravity"

[[forces]]
type = "wind"
velocity = [0.5, 0.0, 0.0]
gust_amplitude = 0.3
groups = ["spray"]

[[colliders]]
name = "ground"
type = "plane"
point = [0, 0, 0]
normal = [0, 0, 1]
restitution = 0.6

[fields.spin]
type = "rotation"
center = [0, 0, 0]

[[tracers]]
field = "spin"
integrator = "rk4"
positions = [[1, 0, 0], [0, 2, 0]]
"""


def test_frame_steps():
    assert [frame_steps(k, 30, 1 / 600) for k in range(4)] == [0, 20, 40, 60]
    # 1/fps not a multiple of dt: the first step boundary at or after each frame time
    assert [frame_steps(k, 30, 0.01) for k in range(4)] == [0, 4, 7, 10]


def _run(path, out, **kw):
    world = load_scene(path)
    run = Run(world, out, duration=world.duration, fps=world.fps, fingerprint=world.fingerprint,
              handle_sigint=False, **kw)
    return run, run.execute()


def test_run_records_frames_at_fps(write_scene, tmp_path):
    path = write_scene(MIXED)
    run, result = _run(path, tmp_path / "a")
    assert result.status == "completed" and result.frame_count == run.frame_count == 11
    states = load_states(result.states_path)
    np.testing.assert_allclose(states.times, np.arange(11) * 0.04, atol=1e-12)
    assert states.metadata["groups"] == ["spray", "chain", "balls", "tracers0"]
    assert states.metadata["integrators"] == ["semi_implicit_euler", "implicit_euler", "rk45", "rk4"]
    assert states.fields["active"].shape == (11, states.particle_count)
    assert states.fields["momentum"].shape == (11, 3)
    assert np.all(states.static["group"][-2:] == 3)
    # the first frame is the initial state
    assert states.times[0] == 0.0 and not states.fields["active"][0, :states.particle_count - 12].any()


@pytest.mark.parametrize("stop_after", [1, 4])
def test_resume_is_bit_identical(write_scene, tmp_path, stop_after):
    """Stop after k frames, resume, compare with an uninterrupted run: every array equal."""
    path = write_scene(MIXED)
    _, full = _run(path, tmp_path / "full")
    run, part = _run(path, tmp_path / "part", stop_after_frames=stop_after)
    assert part.status == "interrupted" and part.frame_count == stop_after
    state, info = load_checkpoint(part.checkpoint_path)
    assert info["frame_count"] == stop_after
    _, resumed = _run(path, tmp_path / "part", resume=True)
    assert resumed.status == "completed" and resumed.frame_count == full.frame_count
    a, b = load_states(full.states_path), load_states(resumed.states_path)
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    for name in a.fields:
        np.testing.assert_array_equal(a.fields[name], b.fields[name])


def test_interrupt_mid_frame_resumes_identically(write_scene, tmp_path):
    """A stop between frames (as Ctrl-C does) checkpoints the exact step, not the last frame."""
    path = write_scene(MIXED)
    _, full = _run(path, tmp_path / "full")
    world = load_scene(path)
    run = Run(world, tmp_path / "part", duration=world.duration, fps=world.fps,
              fingerprint=world.fingerprint, handle_sigint=False)
    steps = {"n": 0}

    def progress(p):
        pass

    original = world.step

    def step():
        original()
        steps["n"] += 1
        if steps["n"] == 37:        # between frames 3 (step 30) and 4 (step 40)
            run.request_stop()

    world.step = step
    result = run.execute()
    assert result.status == "interrupted" and result.step_count == 37 and result.frame_count == 4
    _, resumed = _run(path, tmp_path / "part", resume=True)
    a, b = load_states(full.states_path), load_states(resumed.states_path)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.velocities, b.velocities)


def test_resume_refuses_another_scene(write_scene, tmp_path):
    path = write_scene(MIXED)
    _run(path, tmp_path / "a", stop_after_frames=2)
    other = write_scene(MIXED.replace("restitution = 0.6", "restitution = 0.7"), "other.toml")
    with pytest.raises(ValueError, match="the scene's physics changed"):
        _run(other, tmp_path / "a", resume=True)
    # a longer duration is fine: it continues the same trajectory
    world = load_scene(path, duration=0.6)
    result = Run(world, tmp_path / "a", duration=0.6, fps=world.fps, resume=True, fingerprint=world.fingerprint,
                 handle_sigint=False).execute()
    assert result.frame_count == 16


def test_divergence_keeps_the_frames(write_scene, tmp_path):
    path = write_scene("""
        format_version = 1
        [simulation]
        dt = 0.05
        duration = 5.0
        fps = 10
        integrator = "euler"
        [[particles]]
        mass = 0.001
        chain = { start = [0, 0, 0], end = [1, 0, 0], count = 3, stiffness = 1e12 }
    """)
    world = load_scene(path)
    world["particles0"].v[1] = [0.0, 0.0, 1.0]
    result = Run(world, tmp_path, duration=5.0, fps=10, handle_sigint=False).execute()
    assert result.status == "diverged" and "diverged" in str(result.error)
    assert load_states(result.states_path).frame_count == result.frame_count >= 1


# ---- checkpoints hold arrays and JSON only (issue 8, security item 1) ---------------------------
def _rewrite_checkpoint(path, edit):
    """Rewrite a checkpoint's JSON tree and arrays with `edit(tree, arrays)` (a tampered file)."""
    import json

    with np.load(path, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    tree = json.loads(str(arrays.pop("tree")[()]))
    edit(tree, arrays)
    arrays["tree"] = np.array(json.dumps(tree))
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


class _Boom:
    """Unpickling this runs code: what a crafted checkpoint would do."""

    def __reduce__(self):
        return (exec, ("import pathlib; pathlib.Path(__import__('os').environ['INERTIA_PWNED']).write_text('pwned')",))


def test_a_checkpoint_holding_a_pickle_is_refused(write_scene, tmp_path, monkeypatch):
    import pickle

    from inertia.world import CheckpointError

    path = write_scene(MIXED)
    run, part = _run(path, tmp_path / "a", stop_after_frames=2)
    marker = tmp_path / "pwned"
    monkeypatch.setenv("INERTIA_PWNED", str(marker))
    payload = np.frombuffer(pickle.dumps(_Boom()), dtype=np.uint8)

    def inject(tree, arrays):
        arrays["evil"] = payload
        tree["groups"][0]["extra"] = {"__pickle__": "evil"}

    _rewrite_checkpoint(part.checkpoint_path, inject)
    with pytest.raises(CheckpointError, match="pickled object.*refused"):
        load_checkpoint(part.checkpoint_path)
    with pytest.raises(CheckpointError, match="pickled object.*refused"):
        _run(path, tmp_path / "a", resume=True)
    assert not marker.exists()
    # an object array (numpy's own pickle) is refused the same way
    _rewrite_checkpoint(part.checkpoint_path, lambda tree, arrays: arrays.update(a0=np.array([_Boom()], dtype=object)))
    with pytest.raises(CheckpointError, match="refused"):
        load_checkpoint(part.checkpoint_path)
    assert not marker.exists()


def test_the_fingerprint_is_checked_before_anything_is_decoded(write_scene, tmp_path):
    from inertia.world import CheckpointError

    path = write_scene(MIXED)
    _, part = _run(path, tmp_path / "a", stop_after_frames=2)
    # the tree points at an array that is not there: decoding would fail, the fingerprint first
    def break_arrays(tree, arrays):
        tree["info"]["fingerprint"] = "0123456789abcdef"
        tree["groups"][0]["system"] = {"__array__": "missing"}

    _rewrite_checkpoint(part.checkpoint_path, break_arrays)
    with pytest.raises(CheckpointError, match="another scene"):
        load_checkpoint(part.checkpoint_path, fingerprint=load_scene(path).fingerprint)
    with pytest.raises(ValueError, match="the scene's physics changed"):
        _run(path, tmp_path / "a", resume=True)


def test_a_state_that_is_not_arrays_and_json_is_not_saved(tmp_path):
    from inertia.simulation import SimulationState
    from inertia.world import WorldState, save_checkpoint

    state = WorldState(0, [SimulationState(0.0, 0, {"x": np.zeros(3)}, {}, {"thing": object()})])
    with pytest.raises(TypeError, match="groups\\[0\\].extra.thing"):
        save_checkpoint(tmp_path / "c.npz", state, {})


def test_a_damaged_checkpoint_names_the_file(tmp_path):
    from inertia.world import CheckpointError

    bad = tmp_path / "checkpoint.npz"
    bad.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(CheckpointError, match="checkpoint.npz"):
        load_checkpoint(bad)


def test_ctrl_c_is_caught_from_the_first_write_to_the_last(write_scene, tmp_path):
    """The SIGINT handler covers creating the state directory and the final checkpoint (issue 8):
    a Ctrl-C at any moment after the first write stops cleanly instead of raising."""
    import signal

    path = write_scene(MIXED)
    world = load_scene(path)
    run = Run(world, tmp_path / "a", duration=world.duration, fps=world.fps, fingerprint=world.fingerprint)
    seen = {}
    original_static, original_save = run._static, world.save_state

    def static():                      # called just before the state directory is created
        seen["first write"] = signal.getsignal(signal.SIGINT)
        return original_static()

    def save_state():                  # called by the last checkpoint
        seen["last write"] = signal.getsignal(signal.SIGINT)
        return original_save()

    run._static, world.save_state = static, save_state
    before = signal.getsignal(signal.SIGINT)
    result = run.execute()
    assert result.status == "completed"
    for moment, handler in seen.items():
        assert handler is not before and handler is not signal.default_int_handler, moment
    assert signal.getsignal(signal.SIGINT) is before
    # a Ctrl-C that arrives while the state directory is being created stops the run at frame 0,
    # with a checkpoint to resume from
    world = load_scene(path)
    run = Run(world, tmp_path / "b", duration=world.duration, fps=world.fps, fingerprint=world.fingerprint)
    original_static = run._static

    def interrupted_static():
        signal.raise_signal(signal.SIGINT)
        return original_static()

    run._static = interrupted_static
    result = run.execute()
    assert result.status == "interrupted" and result.frame_count == 0 and result.checkpoint_path.exists()
    _, resumed = _run(path, tmp_path / "b", resume=True)
    assert resumed.status == "completed" and resumed.frame_count == run.frame_count
