"""The state file: what a run recorded, sampled at the output frame rate.

Format (``format = "inertia-states"``, ``format_version = 1``)
--------------------------------------------------------------
A *state directory* that a run appends to, chunk by chunk::

    run.states/
        header.json           written once: format, version, dim, particle_count, fps and the
                              metadata (scene text, scene path, seed, library versions, ...)
        static.npz            per-particle constants, each (N, ...): e.g. group (int32),
                              radius (float64), mass (float64)
        model.npz             (optional) what the scene *is* beyond particles, arrays of any first
                              axis: the shape table (shape_type, shape_body, shape_local_pose,
                              shape_params, shape_vert_start/count, geom_vertices,
                              shape_tri_start/count, geom_triangles, ...), spring_pairs (P, 2),
                              surface_triangles (T, 3), fluid/<name>/<key> (see `inertia.world.Run`)
        chunk-00000000.npz    frames [start, start + count): times (k,), positions (k, N, D),
                              velocities (k, N, D), and one ``field.NAME`` (k, ...) per field
        chunk-00000001.npz    ...
        index.json            the list of complete chunks, their frame ranges and the field
                              specs (dtype and per-frame shape); rewritten after every chunk

Every file is written atomically (`inertia.io.atomic`). A chunk is written first and listed in
``index.json`` second, so a reader that trusts the index sees only complete chunks: a run
killed at any moment leaves a readable state directory holding every frame up to the last
flush. Appending costs one new chunk file plus a small index rewrite; nothing already written
is rewritten (except by `StateWriter.truncate`, which rewrites at most the one chunk that
straddles the cut).

Chunks are zip archives of ``.npy`` members, i.e. ``.npz`` files that ``numpy.load`` opens;
compression is deflate level 1 by default (``compress=False`` stores them raw, which is
faster for large float data that compresses little).

A single-file form, one ``.npz`` with the same arrays plus the header and index as JSON
members, is written by `States.save` (handy to mail a run around); `load_states` reads both.

Frames and fields
-----------------
``times`` (F,) float64, seconds of simulated time, strictly increasing.
``positions`` (F, N, D) and ``velocities`` (F, N, D), in the dtype handed to the writer
(float64 from a simulation). N is fixed for a run: emitters keep a pool of N slots and
record which are in use in the per-frame field ``active`` (F, N) bool.
Per-frame fields are any arrays whose first axis is the frame, e.g. ``active`` (F, N) bool,
``radius`` (F, N) when radii change, ``kinetic_energy`` (F,), ``momentum`` (F, D).
Per-particle constants live in ``static``: ``group`` (N,) int32 indexes
``metadata["groups"]`` (a list of group names), ``radius`` (N,) float64, ``mass`` (N,).
``model`` (dict, arrays of any first axis) holds the scene's shape table and lines/surfaces; a
world with bodies records ``body_q`` (F, B, 7) (position, quaternion w, x, y, z) per frame.

Limitations: N cannot change during a run (use an ``active`` mask); one writer per
directory at a time (no locking); the single-file form is not appendable.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .._validate import npy_header
from .atomic import atomic_write, write_text_atomic
from .manifest import library_versions

__all__ = ["StateWriter", "States", "load_states", "write_states", "recorded_frame_count", "FORMAT_NAME",
           "FORMAT_VERSION"]

FORMAT_NAME = "inertia-states"
FORMAT_VERSION = 1

_HEADER = "header.json"
_INDEX = "index.json"
_STATIC = "static.npz"
_MODEL = "model.npz"
_MODEL_PREFIX = "model."
_FIELD_PREFIX = "field."
_STATIC_PREFIX = "static."


# ---------------------------------------------------------------------------------------------
# npz chunks
# ---------------------------------------------------------------------------------------------
def _write_npz(path: Path, arrays: Mapping[str, np.ndarray], *, compress: bool, extra_json: Mapping[str, Any] | None = None) -> None:
    """Write ``arrays`` as an ``.npz`` (zip of .npy members) atomically."""
    compression = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with atomic_write(path, "wb") as handle:
        with zipfile.ZipFile(handle, "w", compression=compression, compresslevel=1 if compress else None, allowZip64=True) as archive:
            for name, array in arrays.items():
                with archive.open(name + ".npy", "w", force_zip64=True) as member:
                    np.lib.format.write_array(member, np.ascontiguousarray(array), allow_pickle=False)
            for name, payload in (extra_json or {}).items():
                archive.writestr(name, json.dumps(payload, indent=1, sort_keys=True))


def npz_member_problem(zip_file) -> str | None:
    """A message naming the first member of an open .npz (a `zipfile.ZipFile`) whose .npy header is
    unreadable or promises more bytes (shape x item size) than the member holds; None if all fit.
    Reads the headers only, so a header that lies about its shape is caught before anything the
    size of that shape is allocated."""
    for member in zip_file.infolist():
        if not member.filename.endswith(".npy"):       # (JSON members beside the arrays)
            continue
        name = member.filename.removesuffix(".npy")
        try:
            with zip_file.open(member) as handle:
                shape, dtype, promised = npy_header(handle)
        except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
            return f"array {name!r} is damaged ({type(exc).__name__}: {exc})"
        if promised > member.file_size:
            return (f"array {name!r} is damaged: its header says shape {shape} of {dtype} ({promised:,} bytes) but "
                    f"the archive holds {member.file_size:,} bytes")
    return None


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an .npz (never pickled objects); a damaged file is a ValueError naming it."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files"):
                raise ValueError("a single array, not an archive")
            problem = npz_member_problem(data.zip)
            if problem is not None:
                raise ValueError(problem)
            return {name: data[name] for name in data.files}
    except FileNotFoundError:
        raise ValueError(f"{path}: file is missing (the state directory is incomplete)") from None
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"{path}: file is damaged or truncated ({type(exc).__name__}: {exc})") from None


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"state metadata: {type(value).__name__} is not JSON serialisable")


def _dumps(payload) -> str:
    return json.dumps(payload, indent=1, sort_keys=True, default=_json_default) + "\n"


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------
@dataclass
class States:
    """Recorded frames of a run, as NumPy arrays (see the module docstring for shapes).

    Attributes
    ----------
    times : (F,) float64 -- simulated time of each frame, seconds.
    positions : (F, N, D) -- particle positions per frame.
    velocities : (F, N, D) or None -- particle velocities per frame.
    fields : dict[str, ndarray] -- per-frame arrays, first axis F (``active``, energies, ...).
    static : dict[str, ndarray] -- per-particle constants, first axis N (``group``, ``radius``).
    metadata : dict -- header: ``scene`` (text), ``scene_path``, ``seed``, ``versions``,
        ``fps``, ``dim``, ``groups`` and whatever else the writer was given.
    model : dict[str, ndarray] -- constant scene arrays of any shape (the shape table, ``spring_pairs``,
        ``surface_triangles``, ``fluid/<name>/<key>``); empty when the run recorded none.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None = None
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    static: dict[str, np.ndarray] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    model: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=np.float64)
        self.positions = np.asarray(self.positions)
        if self.positions.ndim != 3:
            raise ValueError(f"States: positions must be (F, N, D), got shape {self.positions.shape}")
        frames = self.positions.shape[0]
        if self.times.shape != (frames,):
            raise ValueError(f"States: times must be ({frames},), got shape {self.times.shape}")
        if self.velocities is not None:
            self.velocities = np.asarray(self.velocities)
            if self.velocities.shape != self.positions.shape:
                raise ValueError(
                    f"States: velocities shape {self.velocities.shape} differs from positions {self.positions.shape}"
                )
        for name, value in self.fields.items():
            if np.shape(value)[:1] != (frames,):
                raise ValueError(f"States: field {name!r} must have {frames} frames first, got shape {np.shape(value)}")
        for name, value in self.static.items():
            if np.shape(value)[:1] != (self.particle_count,):
                raise ValueError(
                    f"States: static {name!r} must have {self.particle_count} particles first, got shape {np.shape(value)}"
                )

    # -- sizes ------------------------------------------------------------------------------
    @property
    def frame_count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def particle_count(self) -> int:
        return int(self.positions.shape[1])

    @property
    def dim(self) -> int:
        return int(self.positions.shape[2])

    @property
    def fps(self) -> float | None:
        """Output frame rate recorded in the header, else estimated from the times."""
        fps = self.metadata.get("fps")
        if fps:
            return float(fps)
        if self.frame_count > 1:
            span = self.times[-1] - self.times[0]
            if span > 0:
                return (self.frame_count - 1) / span
        return None

    def __len__(self) -> int:
        return self.frame_count

    # -- per-frame conveniences ---------------------------------------------------------------
    def radius(self, frame: int | None = None) -> np.ndarray | None:
        """Particle radii (N,) at ``frame``: the per-frame field ``radius`` if recorded, else the
        static ``radius``, else None."""
        if "radius" in self.fields:
            return self.fields["radius"][0 if frame is None else frame]
        return self.static.get("radius")

    def active(self, frame: int) -> np.ndarray | None:
        """Active mask (N,) bool at ``frame``, or None when every slot is always in use."""
        if "active" in self.fields:
            return self.fields["active"][frame]
        if "active" in self.static:
            return self.static["active"]
        return None

    def groups(self) -> np.ndarray | None:
        """Group index (N,) of every particle, or None for a single group."""
        return self.static.get("group")

    def select(self, frames) -> "States":
        """A States holding only ``frames`` (a slice, an index array or a boolean mask)."""
        return States(
            times=self.times[frames],
            positions=self.positions[frames],
            velocities=None if self.velocities is None else self.velocities[frames],
            fields={k: v[frames] for k, v in self.fields.items()},
            static=dict(self.static),
            metadata=dict(self.metadata),
            model=dict(self.model),
        )

    # -- single-file form ---------------------------------------------------------------------
    def save(self, path: str | os.PathLike, *, compress: bool = True) -> Path:
        """Write all frames to one ``.npz`` file (atomically); `load_states` reads it back."""
        path = Path(path)
        arrays: dict[str, np.ndarray] = {"times": self.times, "positions": self.positions}
        if self.velocities is not None:
            arrays["velocities"] = self.velocities
        for name, value in self.fields.items():
            arrays[_FIELD_PREFIX + name] = np.asarray(value)
        for name, value in self.static.items():
            arrays[_STATIC_PREFIX + name] = np.asarray(value)
        for name, value in self.model.items():
            arrays[_MODEL_PREFIX + name] = np.asarray(value)
        header = dict(self.metadata)
        header.update(format=FORMAT_NAME, format_version=FORMAT_VERSION, dim=self.dim, particle_count=self.particle_count)
        _write_npz(path, arrays, compress=compress, extra_json={_HEADER: json.loads(_dumps(header))})
        return path


def _check_header(header: Mapping[str, Any], where: Path) -> None:
    if header.get("format") != FORMAT_NAME:
        raise ValueError(f"{where}: not an Inertia state file (format is {header.get('format')!r}, expected {FORMAT_NAME!r})")
    version = header.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ValueError(
            f"{where}: state format_version {version!r} is newer than this Inertia reads ({FORMAT_VERSION}); upgrade inertia"
        )


def _load_single_file(path: Path, frames) -> States:
    try:
        with zipfile.ZipFile(path) as archive:
            if _HEADER not in archive.namelist():
                raise ValueError(f"{path}: not an Inertia state file (no {_HEADER} inside the archive)")
            header = json.loads(archive.read(_HEADER))
    except (OSError, EOFError, zipfile.BadZipFile, zlib.error, RecursionError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: file is damaged or truncated ({type(exc).__name__}: {exc})") from None
    if not isinstance(header, dict):
        raise ValueError(f"{path}: damaged {_HEADER} (not a JSON object)")
    _check_header(header, path)
    arrays = _read_npz(path)
    sel = slice(None) if frames is None else frames
    return States(
        times=arrays["times"][sel],
        positions=arrays["positions"][sel],
        velocities=arrays["velocities"][sel] if "velocities" in arrays else None,
        fields={k[len(_FIELD_PREFIX):]: v[sel] for k, v in arrays.items() if k.startswith(_FIELD_PREFIX)},
        static={k[len(_STATIC_PREFIX):]: v for k, v in arrays.items() if k.startswith(_STATIC_PREFIX)},
        metadata=header,
        model={k[len(_MODEL_PREFIX):]: v for k, v in arrays.items() if k.startswith(_MODEL_PREFIX)},
    )


def _read_json(path: Path):
    """A JSON object from `path`; anything else (damaged, too deep, not an object) is a ValueError naming it."""
    try:
        with open(path, encoding="utf-8") as handle:
            value = json.load(handle)
    except FileNotFoundError:
        raise ValueError(f"{path}: file is missing (the state directory is incomplete)") from None
    except (OSError, ValueError, RecursionError) as exc:     # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise ValueError(f"{path}: not valid JSON, the file is damaged ({type(exc).__name__})") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path}: damaged (expected a JSON object, got {type(value).__name__})")
    return value


def _check_index(index: dict, where: Path) -> dict:
    """The chunk list must name plain chunk files with integer frame ranges in order."""
    chunks = index.get("chunks")
    fields = index.get("fields", {})
    if not isinstance(chunks, list) or not isinstance(fields, (dict, type(None))):
        raise ValueError(f"{where}: damaged ('chunks' must be a list and 'fields' a table)")
    expected = 0
    for i, chunk in enumerate(chunks):
        try:
            name, start, count = chunk["file"], chunk["start"], chunk["count"]
        except (KeyError, TypeError):
            raise ValueError(f"{where}: damaged (chunk {i} lacks file, start or count)") from None
        if (not isinstance(name, str) or not name.startswith("chunk-") or not name.endswith(".npz")
                or "/" in name or "\\" in name or ".." in name):
            raise ValueError(f"{where}: damaged (chunk {i} names {name!r}, not a chunk file of this directory)")
        if not isinstance(start, int) or not isinstance(count, int) or start != expected or count < 0:
            raise ValueError(f"{where}: damaged (chunk {i} covers frames {start!r}+{count!r}; expected start {expected})")
        expected += count
    for name, spec in (fields or {}).items():
        if not isinstance(spec, dict) or not isinstance(spec.get("shape"), list) or "dtype" not in spec:
            raise ValueError(f"{where}: damaged (field {name!r} lacks dtype or shape)")
    return index


def recorded_frame_count(path: str | os.PathLike) -> int:
    """Frames a state directory holds, from its index alone (0 without an index; the chunk files
    themselves are not opened). A damaged index is a ValueError naming it."""
    index_path = Path(path) / _INDEX
    if not index_path.exists():
        return 0
    index = _check_index(_read_json(index_path), index_path)
    return sum(int(c["count"]) for c in index["chunks"])


def _check_chunk(arrays: dict, count: int, particles: tuple, specs: dict, where: Path) -> None:
    """Every array of a chunk holds `count` frames of the shape the header and index give (times (F,),
    positions and velocities (F, N, D), each field (F, *shape) of its dtype); a ValueError names the
    array otherwise (so a damaged state file never reaches the renderer)."""
    for name, value in arrays.items():
        if name == "times":
            expected, dtype = (count,), None
        elif name in ("positions", "velocities"):
            expected, dtype = (count, *particles), None
        elif name.startswith(_FIELD_PREFIX) and name[len(_FIELD_PREFIX):] in specs:
            spec = specs[name[len(_FIELD_PREFIX):]]
            expected, dtype = (count, *spec["shape"]), spec["dtype"]
        else:
            continue
        if tuple(value.shape) != tuple(expected):
            raise ValueError(f"{where}: damaged ({name} has shape {value.shape}; the index and header say {expected})")
        if value.dtype.kind not in "fiub" or (dtype is not None and value.dtype != np.dtype(dtype)):
            raise ValueError(f"{where}: damaged ({name} has dtype {value.dtype}"
                             + (f"; the index says {dtype})" if dtype is not None else ")"))


def _load_directory(path: Path, frames) -> States:
    header_path = path / _HEADER
    if not header_path.exists():
        raise ValueError(f"{path}: not an Inertia state directory (no {_HEADER})")
    header = _read_json(header_path)
    _check_header(header, path)
    index = _check_index(_read_json(path / _INDEX), path / _INDEX) if (path / _INDEX).exists() else {"chunks": [], "fields": {}}
    static = _read_npz(path / _STATIC) if (path / _STATIC).exists() else {}
    model = _read_npz(path / _MODEL) if (path / _MODEL).exists() else {}
    try:
        n, d = int(header["particle_count"]), int(header["dim"])
        dtype = np.dtype(header.get("position_dtype") or "float64")
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{header_path}: damaged ({type(exc).__name__}: {exc})") from None
    total = sum(int(c["count"]) for c in index["chunks"])

    # Which frames to read; load only the chunks that hold them.
    wanted = np.arange(total)[slice(None) if frames is None else frames]
    wanted = np.atleast_1d(wanted)
    parts: dict[str, list[np.ndarray]] = {}
    for chunk in index["chunks"]:
        start, count = int(chunk["start"]), int(chunk["count"])
        local = wanted[(wanted >= start) & (wanted < start + count)] - start
        if local.size == 0:
            continue
        arrays = _read_npz(path / chunk["file"])
        _check_chunk(arrays, count, (n, d), index.get("fields") or {}, path / chunk["file"])
        for name, value in arrays.items():
            parts.setdefault(name, []).append(value[local])

    def gather(name, tail, dt):
        if name in parts:
            return np.concatenate(parts[name], axis=0)
        return np.zeros((0, *tail), dtype=dt)

    # Re-order to the requested order if `frames` was not monotone.
    order = np.argsort(np.argsort(wanted, kind="stable"), kind="stable")
    def reorder(a):
        return a if a.shape[0] == 0 else a[order]

    has_velocity = bool(index.get("velocities", header.get("has_velocities", True)))
    specs = index.get("fields", {})
    return States(
        times=reorder(gather("times", (), np.float64)),
        positions=reorder(gather("positions", (n, d), dtype)),
        velocities=reorder(gather("velocities", (n, d), dtype)) if has_velocity and ("velocities" in parts or not parts) else None,
        fields={
            name: reorder(gather(_FIELD_PREFIX + name, tuple(spec["shape"]), np.dtype(spec["dtype"])))
            for name, spec in specs.items()
        },
        static=static,
        metadata=header,
        model=model,
    )


def load_states(path: str | os.PathLike, *, frames=None) -> States:
    """Read a state directory (what `StateWriter` writes) or a single-file ``.npz`` (`States.save`).

    ``frames``: None for all, or a slice / index array selecting frames; only the chunks that
    hold them are read. Raises ``FileNotFoundError`` or ``ValueError`` (with the path) for
    anything that is not an Inertia state file.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"state file {path} does not exist")
    if path.is_dir():
        return _load_directory(path, frames)
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{path}: not an Inertia state file (expected a state directory or a .npz archive)")
    return _load_single_file(path, frames)


# ---------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------
class StateWriter:
    """Append frames to a state directory during a run; chunks are flushed atomically.

    Parameters
    ----------
    path : directory to create (it must not exist, or be empty, or ``overwrite=True``).
    dim, particle_count : D and N of every frame.
    fps : output frame rate (frames per second of simulated time), stored in the header.
    static : per-particle constants ({name: (N, ...) array}), e.g. ``group``, ``radius``.
    model : constant scene arrays of any shape ({name: array}: the shape table, ``spring_pairs``,
        ``surface_triangles``, ...), written once to ``model.npz``.
    metadata : JSON-able header entries. The conventional keys are ``scene`` (the scene text),
        ``scene_path``, ``seed`` and ``groups`` (list of group names, indexed by ``group``);
        ``versions`` is filled with `library_versions` unless given.
    chunk_frames : frames per chunk, 64 default (a flush also happens every ``chunk_bytes``
        of buffered data, 64 MiB default, and on `flush`/`close`). 16-256 is sensible.
    compress : deflate chunks (level 1). True default; False is faster for big float frames.

    Use `flush()` before writing a checkpoint so that the state directory and the checkpoint
    agree; `StateWriter.reopen(path, frame_count=k)` continues after a resume, dropping frames
    recorded after the checkpoint.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        dim: int,
        particle_count: int,
        fps: float | None = None,
        static: Mapping[str, np.ndarray] | None = None,
        metadata: Mapping[str, Any] | None = None,
        model: Mapping[str, np.ndarray] | None = None,
        chunk_frames: int = 64,
        chunk_bytes: int = 64 << 20,
        compress: bool = True,
        overwrite: bool = False,
        _reopen: bool = False,
    ):
        if dim not in (2, 3):
            raise ValueError(f"StateWriter: dim must be 2 or 3, got {dim!r}")
        if particle_count < 0:
            raise ValueError(f"StateWriter: particle_count must be >= 0, got {particle_count!r}")
        if chunk_frames < 1:
            raise ValueError(f"StateWriter: chunk_frames must be >= 1, got {chunk_frames!r}")
        self.path = Path(path)
        self.dim = int(dim)
        self.particle_count = int(particle_count)
        self.chunk_frames = int(chunk_frames)
        self.chunk_bytes = int(chunk_bytes)
        self.compress = bool(compress)
        self._buffer: list[tuple[float, np.ndarray, np.ndarray | None, dict[str, np.ndarray]]] = []
        self._buffer_bytes = 0
        self._closed = False
        if _reopen:
            return
        # Create the directory and the files written once.
        if self.path.exists():
            if not self.path.is_dir():
                raise FileExistsError(f"StateWriter: {self.path} exists and is not a directory")
            if any(self.path.iterdir()):
                if not overwrite:
                    raise FileExistsError(f"StateWriter: {self.path} is not empty (pass overwrite=True to replace it)")
                if not (self.path / _HEADER).exists():
                    # Never delete a directory that is not a state directory.
                    raise FileExistsError(f"StateWriter: {self.path} is not empty and is not a state directory; refusing to replace it")
                shutil.rmtree(self.path)
        self.path.mkdir(parents=True, exist_ok=True)
        header = dict(metadata or {})
        header.setdefault("versions", library_versions())
        header.update(
            format=FORMAT_NAME,
            format_version=FORMAT_VERSION,
            dim=self.dim,
            particle_count=self.particle_count,
            fps=None if fps is None else float(fps),
        )
        self._header = header
        self._static = {k: np.asarray(v) for k, v in (static or {}).items()}
        for name, value in self._static.items():
            if value.shape[:1] != (self.particle_count,):
                raise ValueError(f"StateWriter: static {name!r} must be ({self.particle_count}, ...), got {value.shape}")
        self._index: dict[str, Any] = {"chunks": [], "fields": None, "velocities": None, "frame_count": 0}
        self._last_time = -math.inf
        self._header["position_dtype"] = None
        _write_npz(self.path / _STATIC, self._static, compress=self.compress)
        if model:
            arrays = {k: np.asarray(v) for k, v in model.items()}
            for name, value in arrays.items():
                if value.dtype.hasobject:
                    raise ValueError(f"StateWriter: model array {name!r} holds Python objects; numeric arrays only")
            _write_npz(self.path / _MODEL, arrays, compress=self.compress)
        self._write_header()
        self._write_index()

    # -- reopening ----------------------------------------------------------------------------
    @classmethod
    def reopen(cls, path: str | os.PathLike, *, frame_count: int | None = None, **options) -> "StateWriter":
        """Continue writing an existing state directory (after ``--resume``).

        ``frame_count``: keep only the first ``frame_count`` frames (those recorded up to the
        checkpoint being resumed); None keeps all. ``options``: chunk_frames, chunk_bytes, compress.
        """
        path = Path(path)
        header = _read_json(path / _HEADER)
        _check_header(header, path)
        writer = cls(path, dim=header["dim"], particle_count=header["particle_count"], _reopen=True, **options)
        writer._header = header
        writer._static = _read_npz(path / _STATIC) if (path / _STATIC).exists() else {}
        writer._index = _check_index(_read_json(path / _INDEX), path / _INDEX)
        writer._index.setdefault("frame_count", sum(int(c["count"]) for c in writer._index["chunks"]))
        writer._last_time = -math.inf
        if frame_count is not None:
            writer.truncate(frame_count)
        if not writer._index["chunks"]:
            # no frame kept: the next frame fixes the layout again (a run stopped before frame 0)
            writer._index["fields"], writer._index["velocities"] = None, None
        if writer._index["chunks"]:
            last = writer._index["chunks"][-1]
            times = _read_npz(path / last["file"])["times"]
            writer._last_time = float(times[-1]) if times.size else -math.inf
        return writer

    # -- properties ---------------------------------------------------------------------------
    @property
    def frame_count(self) -> int:
        """Frames appended so far (flushed or buffered)."""
        return int(self._index["frame_count"]) + len(self._buffer)

    @property
    def metadata(self) -> dict[str, Any]:
        return dict(self._header)

    # -- appending ----------------------------------------------------------------------------
    def append(self, t: float, positions: np.ndarray, velocities: np.ndarray | None = None, **fields: np.ndarray) -> None:
        """Record one frame at time ``t``: positions (N, D), velocities (N, D), per-frame fields.

        The arrays are copied, so the caller may keep stepping the views it passed. Every frame
        must carry the same fields with the same shapes and dtypes as the first one.
        """
        if self._closed:
            raise ValueError(f"StateWriter({self.path}): append after close")
        t = float(t)
        if not t > self._last_time:
            raise ValueError(f"StateWriter: times must increase; got t={t!r} after {self._last_time!r}")
        shape = (self.particle_count, self.dim)
        positions = np.array(positions, copy=True)
        if positions.shape != shape:
            raise ValueError(f"StateWriter: positions must be {shape}, got {positions.shape}")
        if velocities is not None:
            velocities = np.array(velocities, dtype=positions.dtype, copy=True)
            if velocities.shape != shape:
                raise ValueError(f"StateWriter: velocities must be {shape}, got {velocities.shape}")
        frame_fields = {name: np.array(value, copy=True) for name, value in fields.items()}

        # The first frame fixes the layout; later frames must match it.
        specs = {name: {"dtype": value.dtype.str, "shape": list(value.shape)} for name, value in frame_fields.items()}
        if self._index["fields"] is None:
            self._index["fields"] = specs
            self._index["velocities"] = velocities is not None
            self._header["position_dtype"] = positions.dtype.str
            self._write_header()
        else:
            if specs != self._index["fields"]:
                raise ValueError(f"StateWriter: frame fields {specs} differ from the first frame's {self._index['fields']}")
            if (velocities is not None) != bool(self._index["velocities"]):
                raise ValueError("StateWriter: every frame must have velocities, or none")
            if positions.dtype.str != self._header["position_dtype"]:
                raise ValueError(
                    f"StateWriter: positions dtype {positions.dtype} differs from the first frame's {self._header['position_dtype']}"
                )
        self._buffer.append((t, positions, velocities, frame_fields))
        self._last_time = t
        self._buffer_bytes += positions.nbytes + (0 if velocities is None else velocities.nbytes)
        self._buffer_bytes += sum(v.nbytes for v in frame_fields.values())
        if len(self._buffer) >= self.chunk_frames or self._buffer_bytes >= self.chunk_bytes:
            self.flush()

    def flush(self) -> None:
        """Write the buffered frames as one chunk, then the index (both atomically)."""
        if not self._buffer:
            return
        start = int(self._index["frame_count"])
        arrays: dict[str, np.ndarray] = {
            "times": np.array([f[0] for f in self._buffer], dtype=np.float64),
            "positions": np.stack([f[1] for f in self._buffer]),
        }
        if self._index["velocities"]:
            arrays["velocities"] = np.stack([f[2] for f in self._buffer])
        for name in self._index["fields"]:
            arrays[_FIELD_PREFIX + name] = np.stack([f[3][name] for f in self._buffer])
        name = f"chunk-{start:08d}.npz"
        _write_npz(self.path / name, arrays, compress=self.compress)
        self._index["chunks"].append({"file": name, "start": start, "count": len(self._buffer)})
        self._index["frame_count"] = start + len(self._buffer)
        self._write_index()
        self._buffer.clear()
        self._buffer_bytes = 0

    def truncate(self, frame_count: int) -> None:
        """Keep only the first ``frame_count`` frames (flushed or buffered)."""
        if frame_count < 0:
            raise ValueError(f"StateWriter.truncate: frame_count must be >= 0, got {frame_count}")
        flushed = int(self._index["frame_count"])
        if frame_count >= flushed:
            del self._buffer[frame_count - flushed :]
            return
        self._buffer.clear()
        self._buffer_bytes = 0
        kept, stale = [], []
        for chunk in self._index["chunks"]:
            start, count = int(chunk["start"]), int(chunk["count"])
            if start + count <= frame_count:
                kept.append(chunk)
            elif start < frame_count:
                # This chunk straddles the cut: rewrite its head under a new name.
                arrays = _read_npz(self.path / chunk["file"])
                arrays = {k: v[: frame_count - start] for k, v in arrays.items()}
                new_name = f"chunk-{start:08d}-{frame_count - start}.npz"
                _write_npz(self.path / new_name, arrays, compress=self.compress)
                kept.append({"file": new_name, "start": start, "count": frame_count - start})
                stale.append(chunk["file"])
            else:
                stale.append(chunk["file"])
        self._index["chunks"] = kept
        self._index["frame_count"] = frame_count
        self._write_index()
        # Files no longer listed are removed only after the index stopped naming them.
        for file in stale:
            if file not in {c["file"] for c in kept}:
                try:
                    (self.path / file).unlink()
                except FileNotFoundError:
                    pass
        self._last_time = -math.inf
        if kept:
            times = _read_npz(self.path / kept[-1]["file"])["times"]
            self._last_time = float(times[-1]) if times.size else -math.inf

    def close(self) -> None:
        """Flush what is buffered. Appending after close is an error; closing twice is not."""
        if not self._closed:
            self.flush()
            self._closed = True

    def __enter__(self) -> "StateWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals ----------------------------------------------------------------------------
    def _write_header(self) -> None:
        write_text_atomic(self.path / _HEADER, _dumps(self._header))

    def _write_index(self) -> None:
        payload = dict(self._index)
        if payload["fields"] is None:
            payload["fields"] = {}
        write_text_atomic(self.path / _INDEX, _dumps(payload))


def write_states(path: str | os.PathLike, states: States, **options) -> Path:
    """Write a whole `States` as a state directory (one writer, all frames)."""
    with StateWriter(
        path,
        dim=states.dim,
        particle_count=states.particle_count,
        fps=states.metadata.get("fps"),
        static=states.static,
        model=states.model,
        metadata={k: v for k, v in states.metadata.items() if k not in ("format", "format_version", "dim", "particle_count", "fps", "position_dtype")},
        **options,
    ) as writer:
        for i in range(states.frame_count):
            writer.append(
                states.times[i],
                states.positions[i],
                None if states.velocities is None else states.velocities[i],
                **{k: v[i] for k, v in states.fields.items()},
            )
    return Path(path)
