"""The metric expression language, built-ins and callables (src/inertia/sweep/metrics.py)."""

import math

import numpy as np
import pytest

from inertia.sweep.metrics import BUILTINS, Probe, compile_expression, parse_metric
from inertia.sweep.params import SweepInputError


class _Group:
    def __init__(self, system, start, stop):
        self.system, self.start, self.stop, self.kind, self.colliders = system, start, stop, "particles", []


class _System:
    mass = 2.0
    radius = 0.1


class FakeWorld:
    """Two particles moving on straight lines: x = x0 + v t, with known energies."""

    dim = 3
    particle_count = 2

    def __init__(self):
        self.t = 0.0
        self.groups = [_Group(_System(), 0, 2)]

    def positions(self):
        return np.array([[0.0, 0.0, 1.0 + self.t], [1.0, 0.0, 2.0 - self.t]])

    def velocities(self):
        return np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]) * (self.t < 2.0)

    def energies(self):
        return np.array([2.0 * self.t]), np.array([10.0]), np.zeros((1, 3))


def run(texts, times=(0.0, 1.0, 2.0, 3.0)):
    world = FakeWorld()
    exprs = [compile_expression(t) for t in texts]
    for t in times:
        world.t = t
        for e in exprs:
            e.observe(world)
    return [e.result(world) for e in exprs]


def test_reductions_over_particles_and_frames():
    values = run(["max(z)", "peak(max(z))", "lowest(min(z))", "initial(mean(z))", "average(energy)",
                  "final(kinetic_energy) - initial(kinetic_energy)", "z[1]", "sum(z > 0)", "settle_time(max(speed), 0.5)",
                  "peak(max(z)) * 2 + 1", "sqrt(abs(-4))", "mean(z[0:2])"])
    assert values[0] == 4.0                   # a bare expression is its value at the last frame
    assert values[1] == 4.0 and values[2] == -1.0 and values[3] == 1.5
    assert values[4] == pytest.approx(np.mean([10.0, 12.0, 14.0, 16.0]))
    assert values[5] == 6.0
    assert values[6] == -1.0 and values[7] == 1.0
    assert values[8] == 2.0                   # speeds are 1 at t = 0, 1 and 0 from t = 2 on
    assert values[9] == 9.0 and values[10] == 2.0 and values[11] == 1.5


def test_settle_time_is_nan_when_the_last_frame_is_not_at_rest():
    assert math.isnan(run(["settle_time(max(speed), 0.5)"], times=(0.0, 1.0))[0])
    assert run(["settle_time(max(speed), 5.0)"])[0] == 0.0       # never above: the first frame


@pytest.mark.parametrize("text, words", [
    ("__import__('os').system('true')", "only the listed functions|not allowed|only numbers"),
    ("z.__class__", "not allowed"),
    ("(lambda: 1)()", "only the listed functions"),
    ("open('x')", "unknown function 'open'"),
    ("spead", "did you mean 'speed'"),
    ("z", "reduce it"),
    ("peak(z)", "reduce the particles first"),
    ("peak(peak(max(z)))", "cannot be nested"),
    ("max(z) if 1 else 0", "not allowed"),
    ("'text'", "only numbers"),
    ("max(z", "cannot parse"),
    ("z[t]", "whole number"),
])
def test_everything_outside_the_whitelist_is_refused_before_running(text, words):
    with pytest.raises(SweepInputError, match=words):
        compile_expression(text)


def test_metric_specs_builtins_named_expressions_and_callables():
    assert parse_metric("time_to_rest").expression == BUILTINS["time_to_rest"][0]
    m = parse_metric("zmax = peak(max(z))")
    assert (m.name, m.expression) == ("zmax", "peak(max(z))")
    with pytest.raises(SweepInputError, match="did you mean 'time_to_rest'"):
        parse_metric("time_to_rst")
    with pytest.raises(SweepInputError, match="needs a name"):
        parse_metric(lambda w: 1.0)
    for name, (text, _, _) in BUILTINS.items():
        compile_expression(text, name=name)

    class Counter:
        def __init__(self):
            self.frames = 0

        def observe(self, world):
            self.frames += 1

        def result(self, world):
            return self.frames

    probe = Probe([parse_metric(Counter(), "frames"), parse_metric(lambda w: w.t, "t_end"),
                   parse_metric("zmax=peak(max(z))")], dim=3)
    world = FakeWorld()
    for t in (0.0, 1.0, 2.0):
        world.t = t
        probe.observe(world)
    assert probe.results(world) == {"frames": 3.0, "t_end": 2.0, "zmax": 3.0}
