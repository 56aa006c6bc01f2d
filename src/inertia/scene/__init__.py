"""Scene files: TOML (or JSON) -> validated models -> a `World` of systems.

    import inertia as ia
    world = ia.load_scene("fountain.toml")     # or inertia.scene.load_scene
    world.run()                                # the scene's duration
    world["fountain"].x                        # positions of the group named "fountain"

``load_scene(path, duration=None, fps=None, seed=None)`` reads, validates (`SceneError` lists
every problem with its key path) and builds the scene; the keyword arguments override the
``[simulation]`` settings. ``read_scene`` stops after validation. ``scene_schema()`` is the JSON
Schema of the format (shipped as ``inertia/scene/schema.json`` for editors).

The format is described key by key in `inertia.scene.models` and in the schema.
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from .errors import Issue, SceneError
from .models import FORMAT_VERSION, SceneModel

__all__ = ["load_scene", "read_scene", "parse_scene", "build", "scene_schema", "SceneError", "Scene",
           "FORMAT_VERSION", "SCHEMA_PATH", "with_overrides"]

#: The JSON Schema shipped with the package.
SCHEMA_PATH = Path(__file__).with_name("schema.json")


@dataclass(frozen=True)
class Scene:
    """A validated scene: the model, the text it came from, and where."""

    model: SceneModel
    text: str
    path: Path | None
    format: str            # "toml" or "json"

    @property
    def name(self) -> str:
        return self.model.name or (self.path.stem if self.path else "scene")

    @property
    def base_dir(self) -> Path:
        return self.path.parent if self.path else Path.cwd()


#: Deepest nesting of tables and lists a scene file may have (real scenes nest about 5 deep).
MAX_NESTING = 32
#: Largest scene file read (TOML parses at about 4 MB/s: 32 MB is ~10 s before validation).
MAX_SCENE_BYTES = 32_000_000


def _nesting_depth(data, limit: int) -> int:
    """Depth of nested dicts/lists (iterative, stops counting past `limit`)."""
    deepest, stack = 0, [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            deepest = max(deepest, depth)
            if deepest > limit:
                return deepest
            stack.extend((v, depth + 1) for v in (value.values() if isinstance(value, dict) else value))
    return deepest


def _parse_text(text: str, fmt: str, source) -> dict:
    too_deep = Issue("", f"nested deeper than {MAX_NESTING} levels of tables and lists; a scene nests about 5 "
                         "(is this a scene file?)")
    if fmt == "json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SceneError(source, [Issue("", f"invalid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})")]) from None
        except ValueError as exc:        # e.g. an integer of more than 4300 digits
            raise SceneError(source, [Issue("", f"invalid JSON: {exc}")]) from None
        except RecursionError:
            raise SceneError(source, [too_deep]) from None
    else:
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(source, [Issue("", f"invalid TOML: {exc}")]) from None
        except RecursionError:
            raise SceneError(source, [too_deep]) from None
    if not isinstance(data, dict):
        raise SceneError(source, [Issue("", f"a scene must be a table at the top level (got {type(data).__name__})")])
    if _nesting_depth(data, MAX_NESTING) > MAX_NESTING:
        raise SceneError(source, [too_deep])
    return data


#: Largest magnitude of a number in a scene file: beyond it squares and products of positions,
#: velocities and forces leave the range where float64 physics (and the camera) stays finite.
MAX_MAGNITUDE = 1e15
_INT64 = (-(2 ** 63), 2 ** 63 - 1)


def _value_issues(data, limit: int = 8) -> list[Issue]:
    """Values no key accepts, found before the models run (each named by its key path): text that
    is not valid Unicode (a lone surrogate from a JSON escape), integers outside 64 bits, numbers of
    magnitude above `MAX_MAGNITUDE`."""
    from .errors import format_path

    issues: list[Issue] = []
    stack = [(data, ())]
    while stack and len(issues) < limit:
        value, parts = stack.pop()
        if isinstance(value, dict):
            for k, v in value.items():
                if isinstance(k, str) and not _encodable(k):
                    issues.append(Issue(format_path(parts), f"a key holds text that is not valid Unicode ({k!r:.40})"))
                    continue
                stack.append((v, parts + (k,)))
        elif isinstance(value, list):
            stack.extend((v, parts + (i,)) for i, v in enumerate(value))
        elif isinstance(value, str):
            if not _encodable(value):
                issues.append(Issue(format_path(parts), f"text that is not valid Unicode (a lone surrogate?): {value!r:.60}"))
        elif isinstance(value, bool):
            continue
        elif isinstance(value, int):
            if not _INT64[0] <= value <= _INT64[1]:
                issues.append(Issue(format_path(parts), f"the integer ({len(str(abs(value)))} digits) is outside the "
                                                        "64-bit range"))
        elif isinstance(value, float) and math.isfinite(value) and abs(value) > MAX_MAGNITUDE:
            issues.append(Issue(format_path(parts), f"{value:g} is beyond +-{MAX_MAGNITUDE:g}: numbers this large "
                                                    "overflow in the physics (squares, products); use smaller units"))
    return issues


def _encodable(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def validate(data: dict, source=None) -> SceneModel:
    """Validate a scene dictionary; raises `SceneError` listing every problem."""
    from .errors import from_validation_error

    if "format_version" not in data:
        raise SceneError(source, [Issue("format_version", f"required key is missing: start the scene with "
                                                          f"format_version = {FORMAT_VERSION}")])
    issues = _value_issues(data)
    if issues:
        raise SceneError(source, issues)
    try:
        return SceneModel.model_validate(data)
    except ValidationError as exc:
        raise from_validation_error(exc, SceneModel, source) from None


def parse_scene(text: str, *, format: str = "toml", source=None) -> Scene:
    """Validate scene text ("toml" or "json")."""
    if format not in ("toml", "json"):
        raise ValueError(f"format must be 'toml' or 'json'; got {format!r}")
    model = validate(_parse_text(text, format, source), source)
    return Scene(model, text, Path(source) if source else None, format)


def read_scene(path) -> Scene:
    """Read and validate a scene file (.toml or .json); raises `SceneError` (or FileNotFoundError)."""
    path = Path(path)
    if not path.exists():
        raise SceneError(path, [Issue("", "file not found")])
    if path.is_dir():
        raise SceneError(path, [Issue("", "is a directory, not a scene file")])
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise SceneError(path, [Issue("", f"cannot read the file: {exc}")]) from None
    if size > MAX_SCENE_BYTES:
        raise SceneError(path, [Issue("", (
            f"the file is {size / 1e6:.0f} MB; a scene file holds at most {MAX_SCENE_BYTES / 1e6:.0f} MB (parsing more "
            "takes minutes): lay particles out with lattice or random, and give large grids as .npy files"))])
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(path, [Issue("", f"cannot read the file: {exc}")]) from None
    fmt = "json" if path.suffix.lower() == ".json" else "toml"
    model = validate(_parse_text(text, fmt, path), path)
    return Scene(model, text, path, fmt)


def with_overrides(scene: Scene, *, duration=None, fps=None, seed=None) -> Scene:
    """The scene with [simulation] duration, fps or seed replaced (validated like the file)."""
    update: dict[str, Any] = {}
    checks = (("duration", duration, lambda v: v > 0), ("fps", fps, lambda v: v > 0),
              ("seed", seed, lambda v: v >= 0 and float(v) == int(v)))
    for key, value, ok in checks:
        if value is None:
            continue
        if not ok(value):
            raise SceneError(scene.path, [Issue(f"simulation.{key}", f"override must be > 0 (got {value!r})"
                                                if key != "seed" else f"override must be an integer >= 0 (got {value!r})")])
        update[key] = int(value) if key == "seed" else float(value)
    if not update:
        return scene
    from .errors import from_validation_error
    from .models import Simulation

    try:
        simulation = Simulation.model_validate({**scene.model.simulation.model_dump(), **update})
    except ValidationError as exc:
        error = from_validation_error(exc, Simulation, scene.path)
        raise SceneError(scene.path, [Issue(f"simulation{'.' if i.path else ''}{i.path}", i.message + " (after the overrides)")
                                      for i in error.issues]) from None
    return Scene(scene.model.model_copy(update={"simulation": simulation}), scene.text, scene.path, scene.format)


def build(scene: Scene, *, check_memory: bool = True):
    """Build the `World` of a validated `Scene`.

    ``check_memory``: first estimate what the scene allocates (`inertia.scene.resources`) and
    raise `SceneError` naming the key, the estimate and the available memory if it does not fit,
    or naming a part too large for its method (a hull of more than 10 000 points, ...).
    """
    from .builder import build_world, scene_fingerprint

    if check_memory:
        from .resources import estimate_resources

        estimate = estimate_resources(scene.model)
        problem = estimate.memory_problem() or estimate.size_problem()
        if problem is not None:
            raise SceneError(scene.path, [Issue(*problem)])

    world = build_world(scene.model, source=scene.path, base_dir=scene.base_dir)
    sim = scene.model.simulation
    world.name = scene.name
    world.duration, world.fps, world.seed = sim.duration, sim.fps, sim.seed
    world.scene = scene
    world.fingerprint = scene_fingerprint(scene.model)
    return world


def load_scene(path, *, duration: float | None = None, fps: float | None = None, seed: int | None = None):
    """Read, validate and build a scene file: a `World` ready to ``step()`` or ``run()``.

    ``duration``, ``fps`` and ``seed`` override the scene's [simulation] settings.
    Raises `SceneError` (a ValueError) naming the file and the key path of every problem.
    """
    return build(with_overrides(read_scene(path), duration=duration, fps=fps, seed=seed))


def scene_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the scene format, generated from the models."""
    schema = SceneModel.model_json_schema(mode="validation")
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema.setdefault("description", "Inertia scene file, format_version 1 (TOML or JSON).")
    return schema


def write_schema(path=SCHEMA_PATH) -> Path:
    """Regenerate the shipped schema file (``python -m inertia.scene.schema``)."""
    Path(path).write_text(json.dumps(scene_schema(), indent=2) + "\n", encoding="utf-8")
    return Path(path)
