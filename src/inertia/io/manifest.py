"""The run manifest: one JSON file saying what was run, with what, and how long it took.

Keys written by `write_manifest` (``manifest_version = 1``)::

    manifest_version  1
    created           ISO 8601 UTC time the manifest was written
    scene             the scene text (TOML/JSON) as run, or null
    scene_path        where it was read from, or null
    seed              the random seed, or null
    step_count        simulation steps taken
    frame_count       output frames recorded
    simulated_time    seconds of simulated time
    timings           {name: seconds}: wall-clock times (e.g. "compile", "simulate", "render")
    outputs           {kind: path}: files written by the run, relative to the manifest if inside
    versions          {python, numpy, numba, inertia, platform, ...}
    extra             anything else the caller passes

Limitations: versions of optional packages are listed only when they are already imported
or importable without side effects (their distribution metadata is read, nothing is imported).
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import sys
from importlib import metadata as _metadata
from pathlib import Path
from typing import Any, Mapping

from .atomic import write_text_atomic

__all__ = ["library_versions", "write_manifest", "read_manifest", "MANIFEST_VERSION"]

MANIFEST_VERSION = 1

# Distributions whose version matters for reproducing a run or its outputs.
_CORE = ("numpy", "numba", "scipy", "inertia")
_OPTIONAL = ("imageio", "imageio-ffmpeg", "matplotlib", "usd-core", "viser", "pydantic", "typer")


def _distribution_version(name: str) -> str | None:
    try:
        return _metadata.version(name)
    except _metadata.PackageNotFoundError:
        return None


def library_versions(*, optional: bool = True) -> dict[str, str]:
    """Versions of Python, the platform, and the libraries a run depends on (read from metadata)."""
    versions = {
        "python": platform.python_version(),
        "implementation": sys.implementation.name,
        "platform": platform.platform(),
        "machine": platform.machine(),
    }
    for name in _CORE + (_OPTIONAL if optional else ()):
        version = _distribution_version(name)
        if version is not None:
            versions[name] = version
    return versions


def _relative(path: str | os.PathLike, base: Path) -> str:
    path = Path(path)
    try:
        return str(path.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(path)


def write_manifest(
    path: str | os.PathLike,
    *,
    scene: str | None = None,
    scene_path: str | os.PathLike | None = None,
    seed: int | None = None,
    step_count: int | None = None,
    frame_count: int | None = None,
    simulated_time: float | None = None,
    timings: Mapping[str, float] | None = None,
    outputs: Mapping[str, str | os.PathLike] | None = None,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Write the run manifest as JSON (atomically) and return the dictionary written."""
    path = Path(path)
    manifest = {
        "manifest_version": MANIFEST_VERSION,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "scene": scene,
        "scene_path": None if scene_path is None else str(scene_path),
        "seed": seed,
        "step_count": step_count,
        "frame_count": frame_count,
        "simulated_time": simulated_time,
        "timings": {k: float(v) for k, v in (timings or {}).items()},
        "outputs": {k: _relative(v, path.parent) for k, v in (outputs or {}).items()},
        "versions": library_versions(),
        "extra": dict(extra or {}),
    }
    write_text_atomic(path, json.dumps(manifest, indent=2, sort_keys=False, default=str) + "\n")
    return manifest


def read_manifest(path: str | os.PathLike) -> dict[str, Any]:
    """Read a manifest written by `write_manifest`."""
    with open(path, encoding="utf-8") as handle:
        manifest = json.load(handle)
    if "manifest_version" not in manifest:
        raise ValueError(f"{path}: not an Inertia run manifest (no manifest_version)")
    return manifest
