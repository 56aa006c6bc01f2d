"""Sweep parameters: ``KEY=VALUES`` specifications and key-path overrides of scene data.

A parameter names a scene key path, the same paths the scene errors print
(``simulation.integrator``, ``particles[0].restitution``, ``particles[0].forces[1].stiffness``,
``fields.wind.strength``), and the values it takes:

=======================  =====================================================================
``a,b,c``                a list: numbers, ``true``/``false`` or words (``rk4,semi_implicit_euler``)
``[...]``                a JSON list, for values that are themselves lists (``[[1,0,0],[0,1,0]]``)
``lo:hi:N``              N points evenly spaced from lo to hi (both included)
``lo:hi:N:log10``        N points evenly spaced in log10 (lo, hi > 0)
``lo:hi``                the continuous range [lo, hi] (random and Latin-hypercube designs only)
``lo:hi:log10``          the continuous range sampled uniformly in log10
=======================  =====================================================================

A continuous range samples integers when the scene's current value at that key is an integer.
`apply_overrides` writes values into the raw scene dictionary (as parsed from TOML or JSON),
creating missing tables on the way; validation by the scene models then reports unknown keys
(with "did you mean") and values of the wrong type, naming the key path.

Limitations: keys with characters other than letters, digits and ``_`` cannot be addressed
(field names in ``[fields.NAME]`` must be identifiers to be swept); list entries must exist
(a sweep changes values, it does not add groups).
"""

from __future__ import annotations

import copy
import json
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Param", "SweepInputError", "parse_param", "parse_key_path", "apply_overrides", "get_path"]


class SweepInputError(ValueError):
    """A sweep request that cannot run (bad parameter, design, metric or limit)."""


_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]|(\.)")


def parse_key_path(path: str) -> tuple:
    """'particles[0].forces[1].stiffness' -> ('particles', 0, 'forces', 1, 'stiffness')."""
    text = path.strip()
    parts: list = []
    pos = 0
    expect_name = True
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise SweepInputError(f"--param {path!r}: cannot read the key path at {text[pos:]!r} "
                                  "(write keys like particles[0].forces[1].stiffness)")
        name, index, dot = m.groups()
        if dot:
            if expect_name:
                raise SweepInputError(f"--param {path!r}: empty key before '.'")
            expect_name = True
        elif name is not None:
            if not expect_name:
                raise SweepInputError(f"--param {path!r}: a '.' is missing before {name!r}")
            parts.append(name)
            expect_name = False
        else:
            if not parts:
                raise SweepInputError(f"--param {path!r}: a key path starts with a key, not an index")
            parts.append(int(index))
            expect_name = False
        pos = m.end()
    if not parts or expect_name:
        raise SweepInputError(f"--param {path!r}: the key path is empty or ends with '.'")
    return tuple(parts)


def format_key_path(parts) -> str:
    out = ""
    for part in parts:
        out += f"[{part}]" if isinstance(part, int) else ("." if out else "") + part
    return out


def get_path(data: dict, parts) -> Any:
    """The value at a key path of the raw scene data, or None where it is not given."""
    node: Any = data
    for part in parts:
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                return None
            node = node[part]
        else:
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
    return node


def apply_overrides(data: dict, overrides: dict[str, Any]) -> dict:
    """A deep copy of the raw scene `data` with each ``{key path: value}`` written into it."""
    out = copy.deepcopy(data)
    for path, value in overrides.items():
        parts = parse_key_path(path)
        node: Any = out
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            where = format_key_path(parts[:depth]) or "the scene"
            if isinstance(part, int):
                if not isinstance(node, list):
                    raise SweepInputError(f"--param {path}: {where} is not a list (it cannot take [{part}])")
                if part >= len(node):
                    raise SweepInputError(f"--param {path}: {where} has {len(node)} entr{'y' if len(node) == 1 else 'ies'}"
                                          f" (indices 0..{len(node) - 1}); a sweep changes values, it does not add entries")
            elif not isinstance(node, dict):
                raise SweepInputError(f"--param {path}: {where} is a value, not a table (it has no key {part!r})")
            if last:
                node[part] = value
            else:
                if isinstance(part, str) and part not in node:
                    node[part] = {} if isinstance(parts[depth + 1], str) else []
                node = node[part]
    return out


# ---- values --------------------------------------------------------------------------------
def _scalar(text: str):
    t = text.strip()
    if t.lower() in ("true", "false"):
        return t.lower() == "true"
    try:
        return int(t)
    except ValueError:
        pass
    try:
        value = float(t)
    except ValueError:
        return t
    return value


def _number(text: str, what: str, path: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise SweepInputError(f"--param {path}: {what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise SweepInputError(f"--param {path}: {what} must be finite (got {text!r})")
    return value


@dataclass(frozen=True)
class Param:
    """One swept key: either discrete ``values`` or a continuous range ``low..high``.

    ``scale``: "linear" or "log10" (continuous ranges); ``integer``: sample whole numbers.
    """

    key: str
    values: tuple | None = None
    low: float | None = None
    high: float | None = None
    scale: str = "linear"
    integer: bool = False

    @property
    def continuous(self) -> bool:
        return self.values is None

    def from_unit(self, u: np.ndarray) -> list:
        """Map numbers in [0, 1) to values of this parameter (stratum -> value)."""
        if not self.continuous:
            idx = np.minimum((u * len(self.values)).astype(np.int64), len(self.values) - 1)
            return [self.values[i] for i in idx]
        if self.scale == "log10":
            lo, hi = math.log10(self.low), math.log10(self.high)
            out = 10.0 ** (lo + (hi - lo) * u)
        else:
            out = self.low + (self.high - self.low) * u
        if self.integer:
            # whole numbers low..high, each with an equal share of [0, 1)
            first, last = math.ceil(self.low), math.floor(self.high)
            n = last - first + 1
            return [first + int(min(k, n - 1)) for k in (u * n).astype(np.int64)]
        return [float(v) for v in out]

    def checked_values(self) -> list:
        """The values to validate up front: every discrete value, or the ends of a range."""
        if not self.continuous:
            return list(self.values)
        if self.integer:
            return [math.ceil(self.low), math.floor(self.high)]
        return [float(self.low), float(self.high)]


def parse_param(spec: str, base: dict | None = None) -> Param:
    """Parse ``KEY=VALUES`` (see the module docstring); `base` is the raw scene data."""
    if "=" not in spec:
        raise SweepInputError(f"--param {spec!r}: expected KEY=VALUES, e.g. particles[0].restitution=0.2,0.5,0.8")
    key, _, text = spec.partition("=")
    key = key.strip()
    parts = parse_key_path(key)
    key = format_key_path(parts)
    text = text.strip()
    if not text:
        raise SweepInputError(f"--param {key}: no values given (empty range)")
    if text.startswith("["):
        try:
            values = json.loads(text)
        except json.JSONDecodeError as exc:
            raise SweepInputError(f"--param {key}: the JSON list of values does not parse ({exc.msg})") from None
        if not isinstance(values, list) or not values:
            raise SweepInputError(f"--param {key}: the JSON list of values is empty (empty range)")
        return Param(key, values=tuple(_freeze(v) for v in values))
    if ":" in text and "," not in text:
        return _parse_range(key, text, base)
    items = [t for t in (s.strip() for s in text.split(",")) if t]
    if not items:
        raise SweepInputError(f"--param {key}: no values given (empty range)")
    return Param(key, values=tuple(_scalar(t) for t in items))


def _freeze(value):
    return tuple(_freeze(v) for v in value) if isinstance(value, list) else value


def thaw(value):
    """Tuples (hashable design values) back to lists for the scene data."""
    return [thaw(v) for v in value] if isinstance(value, tuple) else value


#: Most points one ``lo:hi:N`` range may have (checked before any is made; the design's variant
#: count, the product over the parameters, is checked against ``max_variants`` before it is made).
MAX_RANGE_POINTS = 1_000_000


def _parse_range(key: str, text: str, base: dict | None) -> Param:
    pieces = [p.strip() for p in text.split(":")]
    if len(pieces) < 2 or len(pieces) > 4:
        raise SweepInputError(f"--param {key}: a range is lo:hi, lo:hi:N, lo:hi:log10 or lo:hi:N:log10 (got {text!r})")
    low = _number(pieces[0], "the range start", key)
    high = _number(pieces[1], "the range end", key)
    count, scale = None, "linear"
    for extra in pieces[2:]:
        if extra in ("log10", "log"):
            scale = "log10"
        elif extra in ("lin", "linear"):
            scale = "linear"
        else:
            try:
                count = int(extra)
            except ValueError:
                raise SweepInputError(f"--param {key}: {extra!r} in {text!r} is neither a point count nor "
                                      "a scale (allowed: an integer N, log10, linear)") from None
    if count is not None and count < 1:
        raise SweepInputError(f"--param {key}: the range {text!r} has {count} points (empty range)")
    if count is not None and count > MAX_RANGE_POINTS:
        raise SweepInputError(f"--param {key}: the range {text!r} asks for {count:,} points; a range takes at most "
                              f"{MAX_RANGE_POINTS:,} (a sweep of that many variants would not finish)")
    if high < low or (high == low and count != 1):
        raise SweepInputError(f"--param {key}: the range {text!r} is empty (the end must be above the start)")
    if scale == "log10" and low <= 0:
        raise SweepInputError(f"--param {key}: a log10 range needs a start > 0 (got {pieces[0]})")
    current = get_path(base, parse_key_path(key)) if base is not None else None
    integer = isinstance(current, int) and not isinstance(current, bool)
    if count is not None:
        points = (np.logspace(math.log10(low), math.log10(high), count) if scale == "log10"
                  else np.linspace(low, high, count))
        if integer:
            values = tuple(dict.fromkeys(int(round(v)) for v in points))
        else:
            values = tuple(float(v) for v in points)
        return Param(key, values=values, low=low, high=high, scale=scale)
    if integer and math.floor(high) < math.ceil(low):
        raise SweepInputError(f"--param {key}: the integer range {text!r} holds no whole number")
    return Param(key, low=low, high=high, scale=scale, integer=integer)
