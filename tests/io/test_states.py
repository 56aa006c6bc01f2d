"""The state file: round trips, chunked appends, resume truncation, the single-file form."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from inertia.io import States, StateWriter, load_states, write_states
from inertia.io.states import FORMAT_VERSION


def _frames(count, n=5, d=3, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(count, n, d)), rng.normal(size=(count, n, d))


def _write(path, x, v, *, chunk_frames=4, fps=30.0, **kw):
    n, d = x.shape[1], x.shape[2]
    static = {"group": (np.arange(n) % 2).astype(np.int32), "radius": np.linspace(0.1, 0.5, n), "mass": np.ones(n)}
    meta = {"scene": "[simulation]\ndt = 0.001\n", "scene_path": "/tmp/x.toml", "seed": 7, "groups": ["a", "b"]}
    with StateWriter(path, dim=d, particle_count=n, fps=fps, static=static, metadata=meta, chunk_frames=chunk_frames, **kw) as w:
        for f in range(x.shape[0]):
            w.append(f / fps, x[f], v[f], active=np.arange(n) <= f, kinetic_energy=np.float64(f), momentum=np.full(d, f, float))
    return path


def test_round_trip_keeps_every_array_and_the_header(tmp_path):
    x, v = _frames(10)
    states = load_states(_write(tmp_path / "run.states", x, v))
    assert (states.frame_count, states.particle_count, states.dim) == (10, 5, 3)
    np.testing.assert_array_equal(states.positions, x)
    np.testing.assert_array_equal(states.velocities, v)
    np.testing.assert_allclose(states.times, np.arange(10) / 30.0)
    assert states.fields["active"].dtype == bool and states.fields["active"].shape == (10, 5)
    np.testing.assert_array_equal(states.fields["kinetic_energy"], np.arange(10.0))
    assert states.fields["momentum"].shape == (10, 3)
    assert states.static["group"].dtype == np.int32
    np.testing.assert_array_equal(states.groups(), [0, 1, 0, 1, 0])
    np.testing.assert_allclose(states.radius(3), np.linspace(0.1, 0.5, 5))
    np.testing.assert_array_equal(states.active(2), [True, True, True, False, False])
    meta = states.metadata
    assert meta["scene"].startswith("[simulation]") and meta["seed"] == 7 and meta["groups"] == ["a", "b"]
    assert meta["format"] == "inertia-states" and meta["format_version"] == FORMAT_VERSION
    assert {"python", "numpy", "numba"} <= set(meta["versions"])
    assert states.fps == 30.0


def test_chunks_are_written_as_frames_arrive(tmp_path):
    path = tmp_path / "run.states"
    x, v = _frames(9)
    writer = StateWriter(path, dim=3, particle_count=5, fps=10, chunk_frames=4)
    for f in range(9):
        writer.append(f * 0.1, x[f], v[f])
        # Whole chunks are on disk (and readable) while the run goes on.
        assert load_states(path).frame_count == (f + 1) // 4 * 4
    writer.flush()
    assert load_states(path).frame_count == 9
    chunks = sorted(p.name for p in path.glob("chunk-*.npz"))
    assert chunks == ["chunk-00000000.npz", "chunk-00000004.npz", "chunk-00000008.npz"]
    writer.close()


def test_reopen_truncates_to_the_checkpoint_and_continues(tmp_path):
    path = tmp_path / "run.states"
    x, v = _frames(10)
    _write(path, x, v)
    writer = StateWriter.reopen(path, frame_count=6)  # the checkpoint was at frame 6
    assert writer.frame_count == 6
    for f in range(6, 10):
        writer.append(f / 30.0, x[f] + 100, v[f], active=np.ones(5, bool), kinetic_energy=np.float64(-f),
                      momentum=np.zeros(3))
    writer.close()
    states = load_states(path)
    np.testing.assert_array_equal(states.positions[:6], x[:6])
    np.testing.assert_array_equal(states.positions[6:], x[6:] + 100)
    assert states.metadata["seed"] == 7
    # Files no longer listed in the index were removed.
    listed = {c["file"] for c in json.loads((path / "index.json").read_text())["chunks"]}
    assert {p.name for p in path.glob("chunk-*.npz")} == listed


@settings(max_examples=25, deadline=None)
@given(total=st.integers(1, 12), chunk=st.integers(1, 5), cut=st.integers(0, 12), more=st.integers(0, 5))
def test_any_truncate_and_append_gives_the_expected_frames(tmp_path_factory, total, chunk, cut, more):
    path = tmp_path_factory.mktemp("s") / "run.states"
    cut = min(cut, total)
    x, v = _frames(total + more, n=3, d=2)
    writer = StateWriter(path, dim=2, particle_count=3, fps=1.0, chunk_frames=chunk)
    for f in range(total):
        writer.append(float(f), x[f], v[f])
    writer.close()
    writer = StateWriter.reopen(path, frame_count=cut, chunk_frames=chunk)
    for f in range(cut, cut + more):
        writer.append(float(f), x[f], v[f])
    writer.close()
    states = load_states(path)
    assert states.frame_count == cut + more
    np.testing.assert_array_equal(states.positions, x[: cut + more])
    np.testing.assert_array_equal(states.times, np.arange(cut + more, dtype=float))


def test_frame_selection_reads_only_what_is_asked(tmp_path):
    x, v = _frames(10)
    path = _write(tmp_path / "run.states", x, v)
    some = load_states(path, frames=slice(3, 9, 2))
    np.testing.assert_array_equal(some.positions, x[3:9:2])
    picked = load_states(path, frames=np.array([7, 1]))
    np.testing.assert_array_equal(picked.positions, x[[7, 1]])
    np.testing.assert_array_equal(picked.fields["kinetic_energy"], [7.0, 1.0])


def test_single_file_form_round_trips(tmp_path):
    x, v = _frames(6, d=2)
    states = load_states(_write(tmp_path / "run.states", x, v))
    states.save(tmp_path / "run.npz")
    again = load_states(tmp_path / "run.npz")
    np.testing.assert_array_equal(again.positions, states.positions)
    np.testing.assert_array_equal(again.fields["active"], states.fields["active"])
    np.testing.assert_array_equal(again.static["radius"], states.static["radius"])
    assert again.metadata["scene"] == states.metadata["scene"] and again.dim == 2
    # And back to a directory.
    write_states(tmp_path / "copy.states", again)
    np.testing.assert_array_equal(load_states(tmp_path / "copy.states").velocities, v)


def test_float32_frames_and_no_velocities(tmp_path):
    path = tmp_path / "f32.states"
    with StateWriter(path, dim=3, particle_count=4, fps=24) as writer:
        for f in range(3):
            writer.append(f / 24, np.full((4, 3), f, np.float32))
    states = load_states(path)
    assert states.positions.dtype == np.float32 and states.velocities is None


def test_bad_input_is_refused_with_a_clear_message(tmp_path):
    path = tmp_path / "run.states"
    writer = StateWriter(path, dim=3, particle_count=2, fps=10)
    with pytest.raises(ValueError, match=r"positions must be \(2, 3\)"):
        writer.append(0.0, np.zeros((3, 3)))
    writer.append(0.0, np.zeros((2, 3)), np.zeros((2, 3)), active=np.ones(2, bool))
    with pytest.raises(ValueError, match="times must increase"):
        writer.append(0.0, np.zeros((2, 3)), np.zeros((2, 3)), active=np.ones(2, bool))
    with pytest.raises(ValueError, match="differ from the first frame"):
        writer.append(0.1, np.zeros((2, 3)), np.zeros((2, 3)))
    writer.close()
    with pytest.raises(ValueError, match="append after close"):
        writer.append(1.0, np.zeros((2, 3)))
    with pytest.raises(FileExistsError, match="not empty"):
        StateWriter(path, dim=3, particle_count=2)
    with pytest.raises(FileNotFoundError):
        load_states(tmp_path / "nope.states")
    (tmp_path / "junk.txt").write_text("hello")
    with pytest.raises(ValueError, match="not an Inertia state file"):
        load_states(tmp_path / "junk.txt")
    with pytest.raises(ValueError, match="not an Inertia state directory"):
        load_states(tmp_path)
    with pytest.raises(ValueError, match="dim must be 2 or 3"):
        StateWriter(tmp_path / "x", dim=4, particle_count=1)
    # overwrite replaces a state directory, never some other directory.
    StateWriter(path, dim=2, particle_count=1, overwrite=True).close()
    assert load_states(path).dim == 2
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("precious")
    with pytest.raises(FileExistsError, match="not a state directory"):
        StateWriter(tmp_path / "mine", dim=3, particle_count=1, overwrite=True)
    assert (tmp_path / "mine" / "thesis.tex").exists()


def test_states_validates_shapes():
    with pytest.raises(ValueError, match=r"positions must be \(F, N, D\)"):
        States(times=np.zeros(2), positions=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="field 'e' must have 2 frames"):
        States(times=np.zeros(2), positions=np.zeros((2, 3, 3)), fields={"e": np.zeros(3)})


# ---- damaged files give a ValueError naming the file (issue 8) -------------------------------
def _damaged_copy(tmp_path, name):
    x, v = _frames(10)
    return _write(tmp_path / name, x, v, chunk_frames=4)


def test_a_truncated_chunk_names_the_chunk(tmp_path):
    path = _damaged_copy(tmp_path, "run.states")
    chunk = path / "chunk-00000004.npz"
    chunk.write_bytes(chunk.read_bytes()[: chunk.stat().st_size // 2])
    with pytest.raises(ValueError, match="chunk-00000004.npz.*damaged"):
        load_states(path)
    # frames in the intact chunks still load
    assert load_states(path, frames=slice(0, 4)).frame_count == 4
    single = tmp_path / "one.npz"
    load_states(_damaged_copy(tmp_path, "again.states")).save(single)
    single.write_bytes(single.read_bytes()[:-200])
    with pytest.raises(ValueError, match="one.npz"):
        load_states(single)


@pytest.mark.parametrize("text", ["{not json", '{"chunks": 5}', '{"chunks": [{"file": "../../../etc/passwd", "start": 0, "count": 1}]}',
                                  '{"chunks": [{"file": "chunk-00000000.npz"}]}', "[" * 100_000])
def test_a_corrupt_index_names_the_file(tmp_path, text):
    path = _damaged_copy(tmp_path, "run.states")
    (path / "index.json").write_text(text)
    with pytest.raises(ValueError, match="index.json"):
        load_states(path)


def test_a_corrupt_header_names_the_file(tmp_path):
    path = _damaged_copy(tmp_path, "run.states")
    (path / "header.json").write_text("{")
    with pytest.raises(ValueError, match="header.json"):
        load_states(path)
    with pytest.raises(ValueError, match="header.json"):
        StateWriter.reopen(path)


def test_recorded_frame_count_reads_the_index_alone(tmp_path):
    from inertia.io.states import recorded_frame_count

    writer = StateWriter(tmp_path / "s", dim=2, particle_count=3, fps=10.0, chunk_frames=2)
    for k in range(5):
        writer.append(0.1 * k, np.zeros((3, 2)))
    writer.close()
    assert recorded_frame_count(tmp_path / "s") == 5
    assert recorded_frame_count(tmp_path / "empty") == 0
    (tmp_path / "s" / "index.json").write_text("{not json")
    with pytest.raises(ValueError, match="index.json"):
        recorded_frame_count(tmp_path / "s")


def _one_chunk(tmp_path):
    writer = StateWriter(tmp_path / "s", dim=2, particle_count=3, fps=10.0, chunk_frames=4, compress=False)
    for k in range(2):
        writer.append(0.1 * k, np.zeros((3, 2)), energy=np.float64(k))
    writer.close()
    return next((tmp_path / "s").glob("chunk-*.npz"))


def test_a_chunk_whose_npy_header_lies_about_its_shape_is_refused_before_allocating(tmp_path):
    import io
    import zipfile

    chunk = _one_chunk(tmp_path)
    with zipfile.ZipFile(chunk) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    lie = io.BytesIO()             # says 10^9 frames (48 GB), holds 16 bytes
    np.lib.format.write_array_header_1_0(lie, {"descr": "<f8", "fortran_order": False, "shape": (10 ** 9, 3, 2)})
    members["positions.npy"] = lie.getvalue() + bytes(16)
    with zipfile.ZipFile(chunk, "w") as archive:
        for name, blob in members.items():
            archive.writestr(name, blob)
    with pytest.raises(ValueError, match="header says shape"):
        load_states(tmp_path / "s")


def test_a_chunk_array_of_the_wrong_shape_is_named(tmp_path):
    chunk = _one_chunk(tmp_path)
    with np.load(chunk) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["positions"] = arrays["positions"][:, :2]
    np.savez(chunk, **arrays)
    with pytest.raises(ValueError, match="positions has shape"):
        load_states(tmp_path / "s")
