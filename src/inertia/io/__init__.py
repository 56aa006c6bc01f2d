"""Files: atomic writes, the state file, PLY and USD exporters, the run manifest.

Public API::

    atomic_write(path, mode="wb")      context manager -> file object; temp file + fsync + rename
    atomic_path(path)                  context manager -> temp path for libraries that open files
    StateWriter(path, dim=, particle_count=, fps=, static=, metadata=)   append frames in chunks
    load_states(path, frames=None) -> States   (.times, .positions, .velocities, .fields, .static, .metadata)
    write_ply(path, positions, ...), write_ply_sequence(states, directory, ...), read_ply(path)
    write_usd(states, path, ...)       animated UsdGeom.Points (.usdc); needs inertia[usd]
    write_usd_bodies(path, model, body_q_frames, fps=)  animated rigid-body Xforms + shape meshes
    write_obj(path, model, body_q), write_obj_sequence(directory, model, body_q_frames)  body meshes
    write_manifest(path, ...), read_manifest(path), library_versions()

See each module's docstring for the file formats.
"""

from .atomic import atomic_path, atomic_write, remove_stale_partials, write_bytes_atomic, write_text_atomic
from .manifest import library_versions, read_manifest, write_manifest
from .ply import read_ply, write_ply, write_ply_sequence
from .states import FORMAT_VERSION, States, StateWriter, load_states, write_states
from .obj import write_obj, write_obj_sequence
from .usd import write_usd, write_usd_bodies

__all__ = [
    "atomic_write",
    "atomic_path",
    "write_bytes_atomic",
    "write_text_atomic",
    "remove_stale_partials",
    "StateWriter",
    "States",
    "load_states",
    "write_states",
    "FORMAT_VERSION",
    "write_ply",
    "read_ply",
    "write_ply_sequence",
    "write_usd",
    "write_usd_bodies",
    "write_obj",
    "write_obj_sequence",
    "write_manifest",
    "read_manifest",
    "library_versions",
]
