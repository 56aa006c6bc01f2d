"""Scene errors: one message per problem, naming the file, the key path and what is allowed.

``SceneError`` holds a list of ``Issue(path, message)``; its text reads::

    fountain.toml: 2 problems
      particles[0].forces[1].stiffness: must be >= 0 (got -5.0)
      particles[0].emiter: unknown key 'emiter'; did you mean 'emitters'? (allowed: name, mass, ...)

`from_validation_error` turns a pydantic ``ValidationError`` into these messages: it walks the
models along each error location to drop the internal parts of the location (the ``type`` tag
of tagged unions, the member names of plain unions) and to find the keys allowed where an
unknown key was found, for the "did you mean" suggestion (difflib).
"""

from __future__ import annotations

import difflib
import re
import types
import typing
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ValidationError

__all__ = ["SceneError", "Issue", "format_path", "did_you_mean", "from_validation_error", "scene_changes",
           "read_mesh_file", "read_npy_file", "check_mesh_suffix", "MESH_SUFFIXES"]


@dataclass(frozen=True)
class Issue:
    """One problem: ``path`` like ``particles[1].forces[0].stiffness`` ("" for the whole file)."""

    path: str
    message: str

    def __str__(self):
        return f"{self.path}: {self.message}" if self.path else self.message


class SceneError(ValueError):
    """A scene file (or scene dictionary) is invalid. ``issues``: the list of `Issue`."""

    def __init__(self, source: str | Path | None, issues: list[Issue]):
        self.source = None if source is None else str(source)
        self.issues = list(issues)
        super().__init__(self._text())

    def _text(self) -> str:
        where = self.source or "scene"
        if len(self.issues) == 1:
            return f"{where}: {self.issues[0]}"
        lines = [f"{where}: {len(self.issues)} problems"]
        lines += [f"  {issue}" for issue in self.issues]
        return "\n".join(lines)


def format_path(parts) -> str:
    """('particles', 1, 'forces', 0, 'k') -> 'particles[1].forces[0].k'."""
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def did_you_mean(word: str, choices, *, show_allowed: bool = True) -> str:
    """'; did you mean 'x'?' (difflib) plus the allowed choices, for an unknown word."""
    choices = [str(c) for c in choices]
    close = difflib.get_close_matches(str(word), choices, n=1, cutoff=0.6)
    text = f"; did you mean {close[0]!r}?" if close else ""
    if show_allowed and choices:
        text += f" (allowed: {', '.join(choices)})"
    return text


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# ---- walking the model types along an error location ------------------------------------------
def _unwrap(tp):
    """Strip Annotated and Optional: the type that data at this place is validated as."""
    while True:
        origin = typing.get_origin(tp)
        if origin is typing.Annotated:
            tp = typing.get_args(tp)[0]
            continue
        if origin in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            if len(args) == 1:
                tp = args[0]
                continue
        return tp


def _is_model(tp) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _type_tag(model) -> str | None:
    field = model.model_fields.get("type")
    if field is None:
        return None
    args = typing.get_args(field.annotation)
    return args[0] if args else None


def _allowed_keys(model) -> list[str]:
    return [f.alias or name for name, f in model.model_fields.items()]


def _walk(root, loc):
    """Follow `loc` through the model types from `root`.

    Returns (display parts, model where the last key was looked up or None, union member flag).
    """
    parts: list = []
    tp = root
    parent_model = None
    via_union = False
    for element in loc:
        tp = _unwrap(tp)
        origin = typing.get_origin(tp)
        if _is_model(tp):
            parent_model = tp
            fields = tp.model_fields
            if element in fields:
                parts.append(element)
                tp = fields[element].annotation
            else:
                parts.append(element)
                tp = None
            continue
        if origin in (typing.Union, types.UnionType):
            members = [_unwrap(a) for a in typing.get_args(tp) if a is not type(None)]
            tagged = {_type_tag(m): m for m in members if _is_model(m) and _type_tag(m)}
            if isinstance(element, str) and element in tagged:
                tp = tagged[element]       # the tag of a tagged union: not part of the key path
                continue
            via_union = True
            if isinstance(element, int):
                lists = [m for m in members if typing.get_origin(m) is list]
                if lists:
                    tp = lists[0]
                    parts.append(element)
                    tp = typing.get_args(tp)[0]
                    continue
            # a plain union member name such as 'float' or 'list[float]': skip it
            match = [m for m in members if str(element).startswith(getattr(typing.get_origin(m) or m, "__name__", "?"))]
            tp = match[0] if match else None
            continue
        if origin is list:
            parts.append(element)
            tp = typing.get_args(tp)[0]
            continue
        if origin is dict:
            parts.append(element)
            tp = typing.get_args(tp)[1]
            continue
        if isinstance(element, (int,)) or (isinstance(element, str) and not element.startswith(("function", "list[", "float", "int"))):
            parts.append(element)
        tp = None
    return parts, parent_model, via_union


# ---- messages ------------------------------------------------------------------------------
_KIND = {
    "float": "a number", "int": "an integer", "bool": "true or false", "string": "a string",
    "list": "a list", "dict": "a table", "model": "a table", "literal": "one of the listed values",
}


def _message(error: dict, parent_model) -> str:
    kind = error["type"]
    ctx = error.get("ctx") or {}
    got = error.get("input")
    loc = error["loc"]
    if kind == "extra_forbidden":
        key = loc[-1]
        allowed = _allowed_keys(parent_model) if parent_model is not None else []
        return f"unknown key {key!r}" + did_you_mean(key, allowed)
    if kind == "missing":
        return "required key is missing"
    if kind == "union_tag_invalid":
        tags = [t.strip().strip("'") for t in str(ctx.get("expected_tags", "")).split(",")]
        return f"unknown type {ctx.get('tag')!r}" + did_you_mean(ctx.get("tag"), tags)
    if kind == "union_tag_not_found":
        return "missing key 'type' (it says which kind of entry this is)"
    if kind == "literal_error":
        expected = str(ctx.get("expected", ""))
        choices = [c.strip().strip("'") for c in expected.replace(" or ", ", ").split(",") if c.strip()]
        return f"must be one of {expected} (got {_show(got)})" + (
            did_you_mean(got, choices, show_allowed=False) if isinstance(got, str) else "")
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}[kind]
        bound = next(iter(ctx.values()))
        bound = f"{bound:g}" if isinstance(bound, float) else bound
        return f"must be {op} {bound} (got {_show(got)})"
    if kind in ("too_short", "too_long"):
        field_type = ctx.get("field_type", "List")
        lo, hi = ctx.get("min_length"), ctx.get("max_length")
        n = ctx.get("actual_length")
        if kind == "too_short":
            return f"{field_type.lower()} needs at least {lo} item(s) (got {n})"
        return f"{field_type.lower()} takes at most {hi} item(s) (got {n})"
    if kind.endswith("_parsing") or kind.endswith("_type"):
        base = kind.split("_")[0]
        if base == "model" or kind in ("model_type", "dict_type", "model_attributes_type"):
            return f"must be a table (got {_show(got)})"
        return f"must be {_KIND.get(base, base)} (got {_show(got)})"
    if kind == "finite_number":
        return f"must be a finite number (got {_show(got)}): inf and nan are not allowed"
    if kind == "value_error":
        return str(ctx.get("error", error["msg"])).removeprefix("Value error, ")
    if kind == "assertion_error":
        return error["msg"].removeprefix("Assertion failed, ")
    return f"{error['msg'][:1].lower()}{error['msg'][1:]} (got {_show(got)})"


_KEY_FIRST = re.compile(r"^([A-Za-z_][\w\-+]*(?:\[\d+\])*(?:\.[A-Za-z_][\w\-+]*(?:\[\d+\])*)*): ")


def from_validation_error(error: ValidationError, root, source) -> SceneError:
    """Convert a pydantic error for model class `root` into a `SceneError` for `source`."""
    by_path: dict[str, list[tuple[str, bool]]] = {}
    order: list[str] = []
    for e in error.errors(include_url=False):
        parts, parent, via_union = _walk(root, e["loc"])
        path = format_path(parts)
        message = _message(e, parent)
        # a relation between keys checked on a whole table names its key first ("box: ..."): move it
        # into the path
        if e["type"] == "value_error":
            match = _KEY_FIRST.match(message)
            if match:
                path = f"{path}.{match.group(1)}" if path else match.group(1)
                message = message[match.end():]
        if path not in by_path:
            by_path[path] = []
            order.append(path)
        by_path[path].append((message, via_union))
    issues = []
    for path in order:
        entries = by_path[path]
        messages = list(dict.fromkeys(m for m, _ in entries))
        if len(messages) > 1 and all(u for _, u in entries):
            # keep the branch that matches the shape of the input (a number vs a list)
            is_list = messages and any(m.startswith("must be a list") for m in messages)
            scalar_input = " (got [" not in messages[0]
            if is_list and scalar_input:
                rest = [m for m in messages if not m.startswith("must be a list")]
                if rest and not all(m.startswith("must be a number") for m in rest):
                    messages = rest
            # every member of a plain union failed: say what the alternatives were
            kinds = []
            for m in messages:
                text = m.split(" (got")[0].removeprefix("must be ")
                if text not in kinds:
                    kinds.append(text)
            got = entries[0][0].split(" (got", 1)
            tail = f" (got{got[1]}" if len(got) > 1 else ""
            issues.append(Issue(path, f"must be {' or '.join(kinds)}{tail}"))
        else:
            issues.extend(Issue(path, m) for m in messages)
    return SceneError(source, issues)


#: mesh file types a scene may name (read with trimesh)
MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")


def check_mesh_suffix(file, path: str, fail) -> None:
    """Refuse (``fail(key_path, message)``) a mesh file whose type is not one trimesh reads."""
    suffix = Path(file).suffix.lower()
    if suffix not in MESH_SUFFIXES:
        fail(path, f"{file}: not a mesh file type inertia reads (got {suffix or 'no suffix'!r}; allowed: "
                   f"{', '.join(MESH_SUFFIXES)})")


def read_npy_file(file, path: str, fail, *, ndim: int | None = None, max_bytes: float | None = None) -> np.ndarray:
    """A numeric array from a ``.npy`` file, its header checked before anything is allocated: the
    ``.npy`` suffix, a numeric dtype, ``ndim`` dimensions, and the bytes the header promises against
    the file's size (a header that lies about its shape) and against ``max_bytes`` (default: the
    memory available); values must be finite. ``fail(key_path, message)`` reports every problem."""
    from .._validate import npy_header
    from .resources import _human_bytes, available_memory

    file = Path(file)
    if file.suffix.lower() != ".npy":
        fail(path, f"{file}: expected a .npy file (got {file.suffix or 'no suffix'!r})")
    try:
        with open(file, "rb") as handle:
            shape, dtype, promised = npy_header(handle)
            offset = handle.tell()
        size = file.stat().st_size
    except Exception as exc:  # noqa: BLE001 - any unreadable header is an input error
        fail(path, f"cannot read {file} as a .npy array: {exc}")
    if dtype.hasobject or dtype.kind not in "fiub":
        fail(path, f"{file}: holds {dtype} values; a numeric array is needed")
    if ndim is not None and len(shape) != ndim:
        fail(path, f"{file}: holds a {len(shape)}-D array of shape {shape}; a {ndim}-D array is needed")
    if promised > size - offset:
        fail(path, f"{file}: its header says shape {shape} of {dtype} ({promised:,} bytes) but the file holds "
                   f"{size - offset:,} bytes of data (damaged or not written by numpy)")
    limit = max_bytes if max_bytes is not None else available_memory()
    if limit is not None and 2 * promised > limit:
        fail(path, f"{file}: an array of shape {shape} ({_human_bytes(promised)}) does not fit in the memory "
                   f"available ({_human_bytes(limit)})")
    try:
        array = np.load(file, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001
        fail(path, f"cannot read {file} as a .npy array: {exc}")
    if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
        fail(path, f"{file}: holds values that are not finite (inf or nan)")
    return array


def read_mesh_file(file, path: str, fail, scale: float = 1.0):
    """(vertices (V, 3) float64 scaled by ``scale``, faces (F, 3) int64) of a mesh file read with
    trimesh; ``fail(key_path, message)`` reports a missing extra or an unreadable file."""
    check_mesh_suffix(file, f"{path}.file", fail)
    try:
        import trimesh
    except ImportError:
        fail(path, "mesh files need trimesh: pip install inertia[mesh]")
    try:
        mesh = trimesh.load(str(file), force="mesh")
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds
        fail(f"{path}.file", f"cannot read {file} as a mesh: {exc}")
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64) * scale, np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0 or not np.all(np.isfinite(vertices)):
        fail(f"{path}.file", f"{file}: " + ("holds no triangles" if len(faces) == 0 else "holds vertices that are not finite"))
    return vertices, faces


def _scene_dict(text: str, fmt: str):
    import json
    import tomllib
    return json.loads(text) if fmt == "json" else tomllib.loads(text)


def scene_changes(old_text: str, old_format: str, new_text: str, new_format: str, *, limit: int = 6) -> list[str]:
    """The keys whose values differ between two scene texts, as ``path: old -> new`` lines (at most
    `limit`; ``[]`` if either text does not parse). Says what changed when a checkpoint of one scene
    meets another."""
    try:
        old, new = _scene_dict(old_text, old_format), _scene_dict(new_text, new_format)
    except Exception:  # noqa: BLE001 - a text that does not parse names nothing
        return []
    out: list[str] = []

    def walk(a, b, parts):
        if len(out) >= limit:
            return
        if isinstance(a, dict) and isinstance(b, dict):
            for key in list(a) + [k for k in b if k not in a]:
                if key in ("name", "description", "output", "render"):
                    if not parts:
                        continue
                walk(a.get(key, "(absent)"), b.get(key, "(absent)"), parts + [key])
            return
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b)):
                walk(x, y, parts + [i])
            return
        if a != b:
            out.append(f"{format_path(parts)}: {_show(a)} -> {_show(b)}")

    walk(old, new, [])
    return out
