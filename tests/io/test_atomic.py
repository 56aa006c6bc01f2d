"""Atomic writes: a writer killed at any moment leaves the old file or the new one, never a part."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from inertia.io import (
    StateWriter,
    atomic_path,
    atomic_write,
    load_states,
    remove_stale_partials,
    write_bytes_atomic,
    write_text_atomic,
)
from inertia.io.atomic import PARTIAL_MARKER


def _leftovers(directory: Path) -> list[Path]:
    return [p for p in directory.iterdir() if PARTIAL_MARKER in p.name]


def test_atomic_write_replaces_the_file_whole(tmp_path):
    target = tmp_path / "data.bin"
    write_bytes_atomic(target, b"old")
    with atomic_write(target) as handle:
        handle.write(b"new contents")
        # Until the block ends the old file is still what readers see.
        assert target.read_bytes() == b"old"
    assert target.read_bytes() == b"new contents"
    assert _leftovers(tmp_path) == []


def test_atomic_write_failure_keeps_the_old_file(tmp_path):
    target = tmp_path / "notes.txt"
    write_text_atomic(target, "first")
    with pytest.raises(RuntimeError):
        with atomic_write(target, "w") as handle:
            handle.write("half of the seco")
            raise RuntimeError("writer crashed")
    assert target.read_text() == "first"
    assert _leftovers(tmp_path) == []


def test_atomic_path_keeps_the_suffix_and_renames(tmp_path):
    target = tmp_path / "movie.mp4"
    with atomic_path(target) as temp:
        assert temp.parent == tmp_path and temp.suffix == ".mp4" and temp != target
        temp.write_bytes(b"x" * 10)
    assert target.read_bytes() == b"x" * 10
    with pytest.raises(FileNotFoundError, match="nothing was written"):
        with atomic_path(tmp_path / "other.png"):
            pass
    assert not (tmp_path / "other.png").exists()


def test_atomic_write_names_a_missing_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        write_text_atomic(tmp_path / "missing" / "x.txt", "hi")


_SLOW_WRITER = textwrap.dedent(
    """
    import sys, time
    from inertia.io import atomic_write
    target, ready = sys.argv[1], sys.argv[2]
    with atomic_write(target) as handle:
        handle.write(b"N" * 100_000)
        handle.flush()
        open(ready, "w").close()        # tell the parent we are mid-write
        for _ in range(1000):
            handle.write(b"N" * 1000)
            handle.flush()
            time.sleep(0.01)
    """
)


def _run_and_kill(script: str, args: list[str], ready: Path, *, timeout: float = 60.0) -> None:
    process = subprocess.Popen([sys.executable, "-c", script, *args])
    try:
        deadline = time.monotonic() + timeout
        while not ready.exists():
            if process.poll() is not None:
                raise AssertionError(f"the writer exited early with code {process.returncode}")
            if time.monotonic() > deadline:
                raise AssertionError("the writer never started writing")
            time.sleep(0.02)
        time.sleep(0.1)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL


def test_killed_writer_leaves_no_partial_file_under_the_final_name(tmp_path):
    target = tmp_path / "result.bin"
    write_bytes_atomic(target, b"complete old version")
    _run_and_kill(_SLOW_WRITER, [str(target), str(tmp_path / "ready")], tmp_path / "ready")
    # The final name still holds the complete old file; the partial one is a hidden temporary.
    assert target.read_bytes() == b"complete old version"
    leftovers = _leftovers(tmp_path)
    assert len(leftovers) == 1 and leftovers[0].name.startswith(".result.bin.")
    assert remove_stale_partials(tmp_path) == leftovers
    assert _leftovers(tmp_path) == []


def test_killed_writer_of_a_new_file_leaves_nothing_under_its_name(tmp_path):
    target = tmp_path / "fresh.bin"
    _run_and_kill(_SLOW_WRITER, [str(target), str(tmp_path / "ready")], tmp_path / "ready")
    assert not target.exists()


_STATE_WRITER = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from inertia.io import StateWriter
    path, ready = sys.argv[1], sys.argv[2]
    rng = np.random.default_rng(0)
    with StateWriter(path, dim=3, particle_count=2000, fps=30, chunk_frames=4) as writer:
        for frame in range(100000):
            x = np.full((2000, 3), float(frame))
            writer.append(frame / 30.0, x, rng.normal(size=(2000, 3)))
            if frame == 9:
                open(ready, "w").close()
    """
)


def test_killed_run_leaves_a_readable_state_directory(tmp_path):
    path = tmp_path / "run.states"
    _run_and_kill(_STATE_WRITER, [str(path), str(tmp_path / "ready")], tmp_path / "ready")
    states = load_states(path)
    # Only complete chunks are listed: a whole number of chunks, every frame intact.
    assert states.frame_count >= 8 and states.frame_count % 4 == 0
    frames = np.arange(states.frame_count, dtype=np.float64)
    np.testing.assert_array_equal(states.positions[:, 0, 0], frames)
    np.testing.assert_allclose(states.times, frames / 30.0)
    # And the run can go on from there.
    writer = StateWriter.reopen(path, frame_count=states.frame_count)
    writer.append(10_000.0, np.zeros((2000, 3)), np.zeros((2000, 3)))
    writer.close()
    assert load_states(path).frame_count == states.frame_count + 1
