"""KEY=VALUES parsing and key-path overrides (src/inertia/sweep/params.py)."""

import numpy as np
import pytest

from inertia.sweep.params import Param, SweepInputError, apply_overrides, parse_key_path, parse_param

BASE = {"format_version": 1, "simulation": {"dt": 0.001, "substeps": 2},
        "particles": [{"positions": [[0, 0, 1]], "forces": [{"type": "drag"}, {"type": "springs", "stiffness": 10.0}]}]}


def test_key_paths_read_like_the_scene_errors():
    assert parse_key_path("particles[0].forces[1].stiffness") == ("particles", 0, "forces", 1, "stiffness")
    assert parse_key_path("simulation.integrator") == ("simulation", "integrator")
    for bad in ("", "a..b", "[0].x", "a.", "a b", "particles[x]"):
        with pytest.raises(SweepInputError):
            parse_key_path(bad)


def test_lists_ranges_and_json_values():
    p = parse_param("simulation.integrator=rk4, semi_implicit_euler", BASE)
    assert p.values == ("rk4", "semi_implicit_euler")
    p = parse_param("particles[0].forces[1].stiffness=100:1000:3:log10", BASE)
    np.testing.assert_allclose(p.values, [100.0, 10 ** 2.5, 1000.0])
    p = parse_param("particles[0].forces[1].stiffness=100:1000:log10", BASE)
    assert p.continuous and p.scale == "log10" and not p.integer
    values = p.from_unit(np.array([0.0, 0.5, 0.999999]))
    np.testing.assert_allclose(values, [100.0, 10 ** 2.5, 1000.0], rtol=1e-5)
    p = parse_param("simulation.dt=0.001:0.003:3", BASE)
    np.testing.assert_allclose(p.values, [0.001, 0.002, 0.003])
    p = parse_param("particles[0].velocity=[[1,0,0],[0,1,0]]", BASE)
    assert p.values == ((1, 0, 0), (0, 1, 0))
    assert parse_param("particles[0].collide=true,false", BASE).values == (True, False)


def test_integer_keys_sample_whole_numbers():
    p = parse_param("simulation.substeps=1:4", BASE)      # the scene holds an integer there
    assert p.integer
    drawn = p.from_unit(np.linspace(0, 0.999, 40))
    assert set(drawn) == {1, 2, 3, 4} and all(isinstance(v, int) for v in drawn)
    assert set(parse_param("simulation.substeps=1.5:3.5", BASE).from_unit(np.linspace(0, 0.999, 20))) == {2, 3}
    with pytest.raises(SweepInputError, match="holds no whole number"):
        parse_param("simulation.substeps=1.2:1.8", BASE)


@pytest.mark.parametrize("spec, words", [
    ("simulation.dt=", "empty range"),
    ("simulation.dt=0.1:0.1", "empty"),
    ("simulation.dt=0.2:0.1:3", "empty"),
    ("simulation.dt=0.1:0.2:0", "empty range"),
    ("simulation.dt=0:1:log10", "start > 0"),
    ("simulation.dt=0.1:0.2:fast", "neither a point count nor a scale"),
    ("simulation.dt", "KEY=VALUES"),
    ("simulation.dt=[]", "empty range"),
])
def test_bad_values_name_the_key(spec, words):
    with pytest.raises(SweepInputError, match=words) as info:
        parse_param(spec, BASE)
    assert "simulation.dt" in str(info.value) or "KEY=VALUES" in str(info.value)


def test_overrides_copy_create_tables_and_refuse_missing_entries():
    out = apply_overrides(BASE, {"particles[0].forces[1].stiffness": 50.0, "render.camera.azimuth": 10.0})
    assert out["particles"][0]["forces"][1]["stiffness"] == 50.0
    assert out["render"] == {"camera": {"azimuth": 10.0}}
    assert BASE["particles"][0]["forces"][1]["stiffness"] == 10.0          # the base is untouched
    with pytest.raises(SweepInputError, match=r"has 1 entry \(indices 0..0\)"):
        apply_overrides(BASE, {"particles[3].radius": 0.1})
    with pytest.raises(SweepInputError, match="not a table"):
        apply_overrides(BASE, {"simulation.dt.x": 1})


def test_param_checked_values_cover_range_ends():
    assert Param("k", low=1.0, high=2.0).checked_values() == [1.0, 2.0]
    assert Param("k", values=(1, 2, 3)).checked_values() == [1, 2, 3]
