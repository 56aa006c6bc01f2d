"""Atomic file writes: every file Inertia writes goes through here.

A writer never opens the final path. It writes a temporary file in the *same directory*
(so the final rename stays on one file system), flushes and fsyncs it, then
``os.replace``-s it onto the final name and fsyncs the directory. A process killed at any
moment therefore leaves either the previous file (or none) or the complete new one under the
final name, never a truncated one. What a kill can leave behind is a hidden temporary file
``.NAME.<token>.partial<suffix>``; `remove_stale_partials` deletes those.

Two forms:

``atomic_write(path, mode="wb")``
    a context manager yielding an open file object, for code that writes a stream itself;
``atomic_path(path)``
    a context manager yielding a temporary *path* with the final file's suffix, for libraries
    that insist on opening the file themselves and pick the format from the extension
    (ffmpeg, usd-core, matplotlib).

Both discard the temporary file when the block raises. `write_bytes_atomic` and
`write_text_atomic` are the one-call forms.

Limitations: atomicity is per file. A writer that produces several files (a PNG sequence, a
chunked state directory) is consistent per file; the state directory adds an index written
last so that a reader sees only complete chunks (see `inertia.io.states`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path
from typing import IO, Iterator

__all__ = [
    "atomic_write",
    "atomic_path",
    "write_bytes_atomic",
    "write_text_atomic",
    "remove_stale_partials",
    "PARTIAL_MARKER",
]

#: Every temporary file has this marker in its name: ``.NAME.<token>.partial<suffix>``.
PARTIAL_MARKER = ".partial"


def _temp_path_for(path: Path) -> Path:
    # Same directory (one file system, so os.replace is atomic), hidden, unique, and ending
    # in the final suffix so that format-sniffing libraries see the right extension.
    token = secrets.token_hex(4)
    return path.with_name(f".{path.name}.{token}{PARTIAL_MARKER}{path.suffix}")


def _fsync_directory(directory: Path) -> None:
    # Make the rename itself durable. Not every platform can open a directory.
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # pragma: no cover - Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - some file systems refuse
        pass
    finally:
        os.close(fd)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _check_directory(path: Path) -> None:
    parent = path.parent
    if not parent.exists():
        raise FileNotFoundError(f"cannot write {path}: directory {parent} does not exist")
    if not parent.is_dir():
        raise NotADirectoryError(f"cannot write {path}: {parent} is not a directory")
    if not os.access(parent, os.W_OK):
        raise PermissionError(f"cannot write {path}: directory {parent} is not writable")


def _commit(temp: Path, final: Path) -> None:
    os.replace(temp, final)
    _fsync_directory(final.parent)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "wb", *, encoding: str | None = None) -> Iterator[IO]:
    """Open a temporary file beside ``path``; on a clean exit, fsync it and rename it onto ``path``.

    ``mode`` is ``"wb"`` (default) or ``"w"`` (text, ``encoding`` default utf-8). If the block
    raises, the temporary file is removed and ``path`` is left as it was.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"atomic_write: mode must be 'wb' or 'w', got {mode!r}")
    final = Path(path)
    _check_directory(final)
    temp = _temp_path_for(final)
    if mode == "w":
        handle = open(temp, "x", encoding=encoding or "utf-8", newline="")
    else:
        handle = open(temp, "xb")
    try:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        _commit(temp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            temp.unlink()
        raise


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path (same directory, same suffix) to write; rename it onto ``path`` on exit.

    For libraries that open the file themselves. The block must have written the file when it
    exits; if it raises, or wrote nothing, the temporary file is removed and ``path`` is untouched.
    """
    final = Path(path)
    _check_directory(final)
    temp = _temp_path_for(final)
    try:
        yield temp
        if not temp.exists():
            raise FileNotFoundError(f"atomic_path: nothing was written for {final}")
        _fsync_file(temp)
        _commit(temp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            temp.unlink()
        raise


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    with atomic_write(path, "wb") as handle:
        handle.write(data)
    return Path(path)


def write_text_atomic(path: str | os.PathLike, text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_write(path, "w", encoding=encoding) as handle:
        handle.write(text)
    return Path(path)


def remove_stale_partials(directory: str | os.PathLike) -> list[Path]:
    """Delete temporary files left in ``directory`` by writers that were killed; returns them.

    Only call this when no writer is running in the directory.
    """
    removed = []
    for entry in Path(directory).iterdir():
        if entry.name.startswith(".") and PARTIAL_MARKER in entry.name and entry.is_file():
            with contextlib.suppress(OSError):
                entry.unlink()
                removed.append(entry)
    return removed
