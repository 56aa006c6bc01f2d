"""Sweep metrics: named built-ins, a small safe expression language, and Python callables.

A metric is sampled at every output frame of a variant's run (the scene's ``fps``; sweep
``simulation.fps`` for finer sampling) and reduced to one number per variant.

Built-ins (each is an expression of the language below):

==================  =============================================  =====================
name                expression                                     unit
==================  =============================================  =====================
final_energy        ``final(energy)``                              J
final_kinetic_energy ``final(kinetic_energy)``                     J
energy_change       ``final(energy) - initial(energy)``            J
time_to_rest        ``settle_time(max(speed), 0.01)``              s (NaN: never rests)
max_penetration     ``peak(max(penetration))``                     m
max_speed           ``peak(max(speed))``                           m/s
max_height          ``peak(max(up))``                              m
==================  =============================================  =====================

The expression language (``NAME=EXPR`` on the command line) reads quantities of the state at a
frame and reduces them:

- per-particle arrays (N,) over every group in order: ``x y z`` (m), ``vx vy vz`` (m/s),
  ``speed`` (m/s), ``up`` (m, z in 3-D and y in 2-D), ``mass`` (kg), ``radius`` (m), ``penetration`` (m, how deep each particle's
  sphere is inside the deepest collider of its group, 0 when outside);
- scalars: ``t`` (s), ``kinetic_energy``, ``potential_energy``, ``energy`` (J, particle groups);
- numbers, ``+ - * / ** %``, unary minus, comparisons (true = 1), ``x[i]`` (particle i),
  ``x[i:j]``;
- over the particles: ``max min mean sum`` (an array to a number); element-wise ``abs sqrt exp
  log log10``;
- over the frames (outermost, their argument a number per frame): ``final(e)`` (the last
  frame; what a bare expression means), ``initial(e)``, ``peak(e)`` (largest), ``lowest(e)``,
  ``average(e)`` (mean over frames), ``settle_time(e, threshold)`` (the time of the first frame
  from which ``e < threshold`` holds to the end; NaN when the last frame is not below).

Expressions are parsed with `ast` and checked against this whitelist before anything runs;
nothing is ever evaluated with `eval` (scene text and metric text are data, not code).

In the Python API a metric may also be a callable ``f(world) -> float`` (called once, after the
last frame) or an object with ``observe(world)`` (every frame) and ``result(world) -> float``.
Both are shipped to the workers with cloudpickle.

Limitations: sampling at frames misses what happens between them (a penetration peak inside
one frame interval); 2-D scenes have no ``z``/``vz``.
"""

from __future__ import annotations

import ast
import copy
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .params import SweepInputError

__all__ = ["BUILTINS", "Metric", "parse_metric", "compile_expression", "Probe", "QUANTITIES"]

#: Built-in metrics: name -> (expression, unit, description).
BUILTINS: dict[str, tuple[str, str, str]] = {
    "final_energy": ("final(energy)", "J", "kinetic + potential energy at the end"),
    "final_kinetic_energy": ("final(kinetic_energy)", "J", "kinetic energy at the end"),
    "energy_change": ("final(energy) - initial(energy)", "J", "energy at the end minus at the start"),
    "time_to_rest": ("settle_time(max(speed), 0.01)", "s", "first frame time from which every speed stays < 0.01 m/s"),
    "max_penetration": ("peak(max(penetration))", "m", "deepest penetration of a particle into a collider"),
    "max_speed": ("peak(max(speed))", "m/s", "largest particle speed"),
    "max_height": ("peak(max(up))", "m", "highest particle position along the up axis"),
}

#: name -> (rank, unit, description); rank 1 = one value per particle, 0 = one number.
QUANTITIES = {
    "t": (0, "s", "time"),
    "x": (1, "m", "position x"), "y": (1, "m", "position y"), "z": (1, "m", "position z (3-D)"),
    "vx": (1, "m/s", "velocity x"), "vy": (1, "m/s", "velocity y"), "vz": (1, "m/s", "velocity z (3-D)"),
    "speed": (1, "m/s", "|v|"), "mass": (1, "kg", "particle mass (inf for pinned)"),
    "radius": (1, "m", "particle radius"),
    "up": (1, "m", "position along the up axis (z in 3-D, y in 2-D)"),
    "penetration": (1, "m", "depth inside the deepest collider of the group (0 outside)"),
    "kinetic_energy": (0, "J", "sum over particle groups"), "potential_energy": (0, "J", "sum over particle groups"),
    "energy": (0, "J", "kinetic + potential"),
}

_REDUCE = {"max": np.max, "min": np.min, "mean": np.mean, "sum": np.sum}
_ELEMENTWISE = {"abs": np.abs, "sqrt": np.sqrt, "exp": np.exp, "log": np.log, "log10": np.log10}
_OVER_TIME = ("final", "initial", "peak", "lowest", "average", "settle_time")
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.true_divide,
           ast.Pow: np.power, ast.Mod: np.mod}
_COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal,
            ast.Eq: np.equal, ast.NotEq: np.not_equal}


class _Frame:
    """The quantities of one frame of a world, computed on first use."""

    def __init__(self, world):
        self.world = world
        self.cache: dict[str, Any] = {}

    def get(self, name: str):
        if name not in self.cache:
            self.cache[name] = self._compute(name)
        return self.cache[name]

    def _compute(self, name: str):
        w = self.world
        dim = w.dim
        if name == "t":
            return float(w.t)
        if name in ("x", "y", "z"):
            axis = "xyz".index(name)
            if axis >= dim:
                raise ValueError(f"{name!r} does not exist in a {dim}-D scene")
            return w.positions()[:, axis]
        if name in ("vx", "vy", "vz"):
            axis = "xyz".index(name[1])
            if axis >= dim:
                raise ValueError(f"{name!r} does not exist in a {dim}-D scene")
            return w.velocities()[:, axis]
        if name == "up":
            return w.positions()[:, dim - 1]
        if name == "speed":
            return np.sqrt(np.sum(w.velocities() ** 2, axis=1))
        if name in ("mass", "radius"):
            out = np.zeros(w.particle_count)
            for g in w.groups:
                out[g.start:g.stop] = getattr(g.system, name, 0.0)
            return out
        if name == "penetration":
            out = np.zeros(w.particle_count)
            for g in w.groups:
                if not g.colliders:
                    continue
                x = np.ascontiguousarray(g.system.x)
                deepest = np.full(len(x), np.inf)
                for collider in g.colliders:
                    deepest = np.minimum(deepest, collider.signed_distance(x, w.t))
                out[g.start:g.stop] = np.maximum(0.0, np.broadcast_to(g.system.radius, deepest.shape) - deepest)
            return out
        if name in ("kinetic_energy", "potential_energy", "energy"):
            kinetic, potential, _ = w.energies()
            particles = [i for i, g in enumerate(w.groups) if g.kind == "particles"]
            if not particles:
                return math.nan
            k, p = float(np.sum(kinetic[particles])), float(np.sum(potential[particles]))
            return {"kinetic_energy": k, "potential_energy": p, "energy": k + p}[name]
        raise KeyError(name)


# ---- compiling ---------------------------------------------------------------------------------
class _Node:
    rank = 0

    def value(self, frame: _Frame):  # pragma: no cover - interface
        raise NotImplementedError


@dataclass
class _Const(_Node):
    number: float
    rank: int = 0

    def value(self, frame):
        return self.number


@dataclass
class _Name(_Node):
    name: str
    rank: int = 0

    def value(self, frame):
        return frame.get(self.name)


@dataclass
class _Apply(_Node):
    function: Callable
    args: list
    rank: int = 0

    def value(self, frame):
        return self.function(*(a.value(frame) for a in self.args))


@dataclass
class _Index(_Node):
    target: _Node
    index: Any
    rank: int = 0

    def value(self, frame):
        array = self.target.value(frame)
        try:
            return array[self.index]
        except IndexError:
            raise ValueError(f"particle index {self.index} is out of range ({len(array)} particles)") from None


class _OverTime(_Node):
    """A reduction over frames: accumulates its argument at every frame."""

    rank = 0

    def __init__(self, kind: str, arg: _Node, threshold: float | None = None):
        self.kind, self.arg, self.threshold = kind, arg, threshold
        self.reset()

    def reset(self):
        self.first = self.last = None
        self.total, self.count = 0.0, 0
        self.high, self.low = -math.inf, math.inf
        self.last_above_time: float | None = None
        self.after_above: float | None = None
        self.first_time: float | None = None
        self.pending_next = False

    def observe(self, frame: _Frame):
        v = float(np.asarray(self.arg.value(frame), dtype=float).reshape(()))
        t = frame.get("t")
        if self.first is None:
            self.first, self.first_time = v, t
        self.last = v
        self.total += v
        self.count += 1
        self.high, self.low = max(self.high, v), min(self.low, v)
        if self.kind == "settle_time":
            if self.pending_next:
                self.after_above, self.pending_next = t, False
            if not (v < self.threshold):
                self.last_above_time, self.after_above, self.pending_next = t, None, True

    def value(self, frame):
        if self.count == 0:
            return math.nan
        if self.kind == "final":
            return self.last
        if self.kind == "initial":
            return self.first
        if self.kind == "peak":
            return self.high
        if self.kind == "lowest":
            return self.low
        if self.kind == "average":
            return self.total / self.count
        # settle_time: never above -> the first frame; above at the last frame -> NaN
        if self.last_above_time is None:
            return self.first_time
        return math.nan if self.after_above is None else self.after_above


class Expression:
    """A compiled metric expression: `observe(world)` per frame, then `result(world)`."""

    def __init__(self, text: str, root: _Node, over_time: list[_OverTime]):
        self.text, self.root, self.over_time = text, root, over_time

    def observe(self, world) -> None:
        frame = _Frame(world)
        for node in self.over_time:
            node.observe(frame)

    def result(self, world) -> float:
        value = np.asarray(self.root.value(_Frame(world)), dtype=float)
        if value.size != 1:
            raise ValueError(f"{self.text!r} gives {value.size} values; reduce them with max, min, mean or sum")
        return float(value.reshape(()))


def compile_expression(text: str, *, dim: int = 3, name: str = "metric") -> Expression:
    """Parse and check a metric expression (see the module docstring); raises SweepInputError."""

    def fail(msg: str):
        raise SweepInputError(f"--metric {name}: {msg} in {text!r}")

    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        fail(f"cannot parse ({exc.msg})")
    over_time: list[_OverTime] = []

    def build(node, inside_time: bool) -> _Node:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                fail(f"only numbers are allowed as constants (got {node.value!r})")
            return _Const(float(node.value))
        if isinstance(node, ast.Name):
            if node.id not in QUANTITIES:
                from ..scene.errors import did_you_mean
                fail(f"unknown quantity {node.id!r}" + did_you_mean(node.id, list(QUANTITIES)))
            if node.id in ("z", "vz") and dim < 3:
                fail(f"{node.id!r} does not exist in a {dim}-D scene")
            return _Name(node.id, QUANTITIES[node.id][0])
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            arg = build(node.operand, inside_time)
            return _Apply(np.negative if isinstance(node.op, ast.USub) else np.positive, [arg], arg.rank)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            a, b = build(node.left, inside_time), build(node.right, inside_time)
            return _Apply(_BINARY[type(node.op)], [a, b], max(a.rank, b.rank))
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
            a, b = build(node.left, inside_time), build(node.comparators[0], inside_time)
            op = _COMPARE[type(node.ops[0])]
            return _Apply(lambda u, v, op=op: op(u, v).astype(float), [a, b], max(a.rank, b.rank))
        if isinstance(node, ast.Subscript):
            target = build(node.value, inside_time)
            if target.rank != 1:
                fail("only per-particle arrays can be indexed")
            s = node.slice
            if isinstance(s, ast.Constant) and isinstance(s.value, int) and not isinstance(s.value, bool):
                return _Index(target, s.value, 0)
            if isinstance(s, ast.UnaryOp) and isinstance(s.op, ast.USub) and isinstance(s.operand, ast.Constant) \
                    and isinstance(s.operand.value, int):
                return _Index(target, -s.operand.value, 0)
            if isinstance(s, ast.Slice) and s.step is None and all(
                    b is None or (isinstance(b, ast.Constant) and isinstance(b.value, int)) for b in (s.lower, s.upper)):
                return _Index(target, slice(None if s.lower is None else s.lower.value,
                                            None if s.upper is None else s.upper.value), 1)
            fail("an index must be a whole number or a slice i:j of whole numbers")
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.keywords:
                fail("only the listed functions may be called, with positional arguments")
            fname = node.func.id
            if fname in _REDUCE or fname in _ELEMENTWISE:
                if len(node.args) != 1:
                    fail(f"{fname}() takes one argument")
                arg = build(node.args[0], inside_time)
                if fname in _REDUCE:
                    return _Apply(_REDUCE[fname], [arg], 0)
                return _Apply(_ELEMENTWISE[fname], [arg], arg.rank)
            if fname in _OVER_TIME:
                if inside_time:
                    fail(f"{fname}() cannot be nested inside another reduction over frames")
                wanted = 2 if fname == "settle_time" else 1
                if len(node.args) != wanted:
                    fail(f"{fname}() takes {wanted} argument{'s' if wanted > 1 else ''}")
                arg = build(node.args[0], True)
                if arg.rank != 0:
                    fail(f"{fname}() needs one number per frame: reduce the particles first, e.g. {fname}(max(...))")
                threshold = None
                if fname == "settle_time":
                    t = node.args[1]
                    if not (isinstance(t, ast.Constant) and isinstance(t.value, (int, float))):
                        fail("settle_time(e, threshold): the threshold must be a number")
                    threshold = float(t.value)
                agg = _OverTime(fname, arg, threshold)
                over_time.append(agg)
                return agg
            from ..scene.errors import did_you_mean
            fail(f"unknown function {fname!r}" + did_you_mean(fname, [*_REDUCE, *_ELEMENTWISE, *_OVER_TIME]))
        fail(f"{type(node).__name__} is not allowed (numbers, quantities, + - * / ** %, comparisons, "
             "indexing and the listed functions are)")

    root = build(tree.body, False)
    if root.rank != 0:
        fail("the result is one value per particle; reduce it with max, min, mean or sum")
    if not isinstance(root, _OverTime) and not over_time:
        # a bare expression means its value at the last frame
        root = _OverTime("final", root)
        over_time.append(root)
    elif not isinstance(root, _OverTime):
        # parts outside a reduction over frames are read at the last frame
        def finalize(node):
            if isinstance(node, _OverTime):
                return node
            if isinstance(node, _Apply):
                node.args = [finalize(a) for a in node.args]
                return node
            if isinstance(node, _Index):
                node.target = finalize(node.target)
                return node
            return node
        root = finalize(root)
    return Expression(text, root, over_time)


# ---- metric specifications ---------------------------------------------------------------------
@dataclass
class Metric:
    """A named metric: ``expression`` text or a Python ``function``."""

    name: str
    expression: str | None = None
    function: Any = None

    def describe(self) -> str:
        if self.function is not None:
            return f"python:{getattr(self.function, '__qualname__', type(self.function).__name__)}"
        return self.expression


def parse_metric(spec, name: str | None = None) -> Metric:
    """``"time_to_rest"`` (built-in), ``"NAME=EXPR"``, or (name, callable)."""
    if callable(spec) or hasattr(spec, "observe"):
        name = name or getattr(spec, "__name__", None)
        if not name or not name.isidentifier():
            raise SweepInputError("a Python metric needs a name: pass metrics={'name': callable}")
        return Metric(name, function=spec)
    if not isinstance(spec, str):
        raise SweepInputError(f"a metric is a name, NAME=EXPR or a callable (got {spec!r})")
    if name is not None:
        text = spec
    elif "=" in spec and not spec.split("=", 1)[0].strip().endswith(("<", ">", "!", "=")):
        name, _, text = spec.partition("=")
        name = name.strip()
    else:
        name = spec.strip()
        if name not in BUILTINS:
            from ..scene.errors import did_you_mean
            raise SweepInputError(f"--metric {name!r}: not a built-in metric" + did_you_mean(name, list(BUILTINS))
                                  + "; or define one as NAME=EXPR")
        text = BUILTINS[name][0]
    if not name.isidentifier():
        raise SweepInputError(f"--metric {name!r}: a metric name must be a word (letters, digits, _)")
    compile_expression(text.strip(), name=name)   # check now, not on a worker
    return Metric(name, expression=text.strip())


class Probe:
    """The metrics of one variant run: `observe(world)` at every frame, `results(world)` at the end."""

    def __init__(self, metrics: list[Metric], dim: int):
        self.items = []
        for m in metrics:
            if m.function is not None:
                # a stateful metric object starts fresh for every variant
                fn = copy.deepcopy(m.function) if hasattr(m.function, "observe") else m.function
                self.items.append((m.name, fn))
            else:
                self.items.append((m.name, compile_expression(m.expression, dim=dim, name=m.name)))

    def observe(self, world) -> None:
        for _, item in self.items:
            if hasattr(item, "observe"):
                item.observe(world)

    def results(self, world) -> dict[str, float]:
        out = {}
        for name, item in self.items:
            value = item.result(world) if hasattr(item, "result") else item(world)
            out[name] = float(value)
        return out
