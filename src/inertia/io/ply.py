"""PLY point sequences: one binary PLY file per frame, for Blender, Houdini, MeshLab, ParaView.

Each file holds one ``vertex`` element with the properties::

    float x, y, z            position (2-D scenes get z = 0)
    float vx, vy, vz         velocity (when given)
    float radius             particle radius in scene units (when given); Houdini reads it as
                             the ``radius`` point attribute, Blender as a float attribute
    uchar red, green, blue   colour (when given)
    <extra>                  any further per-point scalar arrays (``attributes=``)

Binary little-endian by default (``binary=False`` writes ASCII). Files are written atomically.

Reference: Turk, G. (1994). The PLY Polygon File Format.

Limitations: points only (no faces); `read_ply` reads what `write_ply` writes and other
vertex-only files with scalar properties (list properties and other elements are skipped only
in ASCII files).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from .atomic import atomic_write

__all__ = ["write_ply", "read_ply", "write_ply_sequence"]

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_NUMPY_TO_PLY = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint", "f4": "float", "f8": "double"}


def _as_3d(array: np.ndarray, name: str, count: int) -> np.ndarray:
    array = np.asarray(array, dtype=np.float32)
    if array.ndim != 2 or array.shape[0] != count or array.shape[1] not in (2, 3):
        raise ValueError(f"write_ply: {name} must be ({count}, 2) or ({count}, 3), got {array.shape}")
    if array.shape[1] == 2:
        array = np.concatenate([array, np.zeros((count, 1), np.float32)], axis=1)
    return array


def write_ply(
    path: str | os.PathLike,
    positions: np.ndarray,
    *,
    velocities: np.ndarray | None = None,
    radius: np.ndarray | float | None = None,
    colors: np.ndarray | None = None,
    attributes: Mapping[str, np.ndarray] | None = None,
    binary: bool = True,
    comment: str | None = None,
) -> Path:
    """Write one point set as a PLY file (atomically). ``colors`` (M, 3) uint8 or float in [0, 1]."""
    positions = np.asarray(positions)
    count = positions.shape[0] if positions.ndim == 2 else -1
    columns: list[tuple[str, np.ndarray]] = []
    xyz = _as_3d(positions, "positions", count)
    columns += [("x", xyz[:, 0]), ("y", xyz[:, 1]), ("z", xyz[:, 2])]
    if velocities is not None:
        vel = _as_3d(velocities, "velocities", count)
        columns += [("vx", vel[:, 0]), ("vy", vel[:, 1]), ("vz", vel[:, 2])]
    if radius is not None:
        columns.append(("radius", np.broadcast_to(np.asarray(radius, dtype=np.float32), (count,))))
    if colors is not None:
        colors = np.asarray(colors)
        if colors.shape != (count, 3):
            raise ValueError(f"write_ply: colors must be ({count}, 3), got {colors.shape}")
        if colors.dtype != np.uint8:
            colors = np.clip(np.round(colors * 255.0), 0, 255).astype(np.uint8)
        columns += [("red", colors[:, 0]), ("green", colors[:, 1]), ("blue", colors[:, 2])]
    for name, values in (attributes or {}).items():
        values = np.asarray(values)
        if values.shape != (count,):
            raise ValueError(f"write_ply: attribute {name!r} must be ({count},), got {values.shape}")
        if values.dtype.kind == "b":
            values = values.astype(np.uint8)
        if values.dtype.str[1:] not in _NUMPY_TO_PLY:
            values = values.astype(np.float32 if values.dtype.kind == "f" else np.int32)
        columns.append((name, values))

    # One structured array in file order, little-endian.
    dtype = np.dtype([(name, "<" + values.dtype.str[1:]) for name, values in columns])
    table = np.empty(count, dtype=dtype)
    for name, values in columns:
        table[name] = values

    lines = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment written by inertia"]
    if comment:
        lines += [f"comment {line}" for line in comment.splitlines()]
    lines.append(f"element vertex {count}")
    lines += [f"property {_NUMPY_TO_PLY[dtype[name].str[1:]]} {name}" for name in dtype.names]
    lines.append("end_header")
    header = ("\n".join(lines) + "\n").encode("ascii")

    with atomic_write(path, "wb") as handle:
        handle.write(header)
        if binary:
            handle.write(table.tobytes())
        else:
            formats = ["%.9g" if dtype[n].kind == "f" else "%d" for n in dtype.names]
            rows = np.column_stack([table[n].astype(np.float64) for n in dtype.names]) if count else np.zeros((0, len(formats)))
            np.savetxt(handle, rows, fmt=formats)
    return Path(path)


def read_ply(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read the ``vertex`` element of a PLY file as {property: (M,) array}."""
    data = Path(path).read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError(f"{path}: not a PLY file")
    body_start = data.index(b"\n", end) + 1
    header = data[:body_start].decode("ascii").splitlines()
    fmt, elements, current = None, [], None
    for line in header:
        words = line.split()
        if not words:
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            current = {"name": words[1], "count": int(words[2]), "props": []}
            elements.append(current)
        elif words[0] == "property":
            if words[1] == "list":
                current["props"].append(("list", words[-1]))
            else:
                current["props"].append((_PLY_TYPES[words[1]], words[2]))
    if not elements or elements[0]["name"] != "vertex":
        raise ValueError(f"{path}: the first PLY element is not 'vertex'")
    vertex = elements[0]
    if any(kind == "list" for kind, _ in vertex["props"]):
        raise ValueError(f"{path}: list properties on vertices are not supported")
    if fmt in ("binary_little_endian", "binary_big_endian"):
        order = "<" if fmt == "binary_little_endian" else ">"
        dtype = np.dtype([(name, order + kind) for kind, name in vertex["props"]])
        table = np.frombuffer(data, dtype=dtype, count=vertex["count"], offset=body_start)
        return {name: table[name].astype(dtype[name].newbyteorder("=")) for name in dtype.names}
    if fmt == "ascii":
        rows = data[body_start:].decode("ascii").split("\n")[: vertex["count"]]
        values = np.array([row.split() for row in rows], dtype=np.float64).reshape(vertex["count"], len(vertex["props"]))
        return {name: values[:, i].astype(kind) for i, (kind, name) in enumerate(vertex["props"])}
    raise ValueError(f"{path}: unknown PLY format {fmt!r}")


def write_ply_sequence(
    states,
    directory: str | os.PathLike,
    *,
    pattern: str = "frame_{frame:05d}.ply",
    colors: np.ndarray | Callable[[int], np.ndarray] | None = None,
    active_only: bool = True,
    frames=None,
    binary: bool = True,
) -> list[Path]:
    """Write one PLY per frame of a `States` into ``directory`` (created if missing).

    ``colors``: (N, 3) or (F, N, 3) array, or a callable ``colors(frame) -> (N, 3)``.
    ``active_only``: drop inactive emitter slots (the files then differ in point count).
    ``frames``: a slice or index array of frames to write (default all). File names use the
    frame's index in the state file, through ``pattern``. Also writes ``group`` (when the states
    have groups) as an integer attribute. Returns the paths written, in order.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    indices = np.arange(states.frame_count)[slice(None) if frames is None else frames]
    groups = states.groups()
    written = []
    for f in np.atleast_1d(indices):
        f = int(f)
        keep = states.active(f) if active_only else None
        sel = slice(None) if keep is None else np.asarray(keep, dtype=bool)
        radius = states.radius(f)
        frame_colors = colors(f) if callable(colors) else colors
        if frame_colors is not None and np.ndim(frame_colors) == 3:
            frame_colors = frame_colors[f]
        path = directory / pattern.format(frame=f)
        write_ply(
            path,
            states.positions[f][sel],
            velocities=None if states.velocities is None else states.velocities[f][sel],
            radius=None if radius is None else np.asarray(radius)[sel],
            colors=None if frame_colors is None else np.asarray(frame_colors)[sel],
            attributes=None if groups is None else {"group": np.asarray(groups, dtype=np.int32)[sel]},
            binary=binary,
            comment=f"frame {f} time {states.times[f]!r}",
        )
        written.append(path)
    return written
