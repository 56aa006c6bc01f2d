"""`inertia sweep` (src/inertia/cli/sweep.py): bad input exits 2 with a clear message; a small sweep end to end
on the embedded LocalCluster."""

import builtins
import textwrap

import pytest
from typer.testing import CliRunner

from inertia.cli.main import app

BALL = textwrap.dedent("""
    format_version = 1
    [simulation]
    dt = 0.001
    duration = 0.2
    fps = 50
    integrator = "velocity_verlet"
    [[forces]]
    type = "gravity"
    [[colliders]]
    type = "plane"
    point = [0.0, 0.0, 0.0]
    normal = [0.0, 0.0, 1.0]
    [[particles]]
    positions = [[0.0, 0.0, 0.3]]
    radius = 0.05
    restitution = 0.5
""")


def invoke(*args):
    return CliRunner().invoke(app, ["sweep", *[str(a) for a in args]])


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "ball.toml"
    path.write_text(BALL)
    return path


@pytest.mark.parametrize("args, words", [
    (["-p", "particles[0].restitutoin=0.1,0.2"], ["particles[0].restitutoin", "did you mean 'restitution'"]),
    (["-p", "simulaton.dt=0.1,0.2"], ["simulaton", "did you mean 'simulation'"]),
    (["-p", "particles[0].restitution=high,low"], ["particles[0].restitution", "must be a number"]),
    (["-p", "particles[0].restitution=0.2,1.5"], ["particles[0].restitution", "must be <= 1"]),
    (["-p", "simulation.integrator=rk5"], ["simulation.integrator", "did you mean 'rk45'"]),
    (["-p", "particles[0].restitution=0.5:0.5"], ["particles[0].restitution", "empty"]),
    (["-p", "particles[0].restitution="], ["empty range"]),
    (["-p", "particles[4].restitution=0.1"], ["particles", "has 1 entry"]),
    (["-p", "particles[0].restitution=0:1"], ["needs a point count"]),
    (["-p", "particles[0].restitution=0:1:200", "-p", "simulation.dt=0.001:0.002:60"],
     ["12,000 variants", "--max-variants 12000"]),
    (["-p", "particles[0].restitution=0.1", "-m", "time_to_rst"], ["did you mean 'time_to_rest'"]),
    (["-p", "particles[0].restitution=0.1", "-m", "bad=__import__('os')"], ["--metric bad"]),
    (["-p", "particles[0].restitution=0.1", "--design", "lhd", "--samples", "3"], ["did you mean 'lhs'"]),
    (["-p", "particles[0].restitution=0.1", "--outputs", "video"], ["unknown output 'video'"]),
    ([], ["at least one --param"]),
])
def test_bad_input_exits_2_with_the_key_and_what_is_allowed(scene, tmp_path, args, words):
    result = invoke(scene, "--out", tmp_path / "out", "--quiet", *args)
    assert result.exit_code == 2, result.output
    for w in words:
        assert w in result.output, (w, result.output)
    assert "Traceback" not in result.output


def test_the_variant_limit_can_be_raised(scene, tmp_path):
    result = invoke(scene, "--out", tmp_path / "out", "--quiet", "-p", "particles[0].restitution=0.1,0.2,0.3",
                    "--max-variants", "2")
    assert result.exit_code == 2 and "--max-variants 3" in result.output


def test_an_unreachable_scheduler_is_an_error_within_the_timeout(scene, tmp_path):
    import time
    started = time.perf_counter()
    result = invoke(scene, "--out", tmp_path / "out", "--quiet", "-p", "particles[0].restitution=0.1",
                    "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "1")
    assert result.exit_code == 2, result.output
    assert "cannot reach a dask scheduler" in result.output and "tcp://127.0.0.1:9" in result.output
    assert time.perf_counter() - started < 20


def test_missing_extra_is_named(scene, tmp_path, monkeypatch):
    real_import = builtins.__import__

    def no_pyarrow(name, *args, **kwargs):
        if name == "pyarrow":
            raise ImportError("No module named 'pyarrow'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pyarrow)
    result = invoke(scene, "--out", tmp_path / "out", "--quiet", "-p", "particles[0].restitution=0.1")
    assert result.exit_code == 2 and "inertia[sweep]" in result.output and "pyarrow" in result.output


def test_a_sweep_end_to_end_on_the_embedded_cluster(scene, tmp_path):
    # the default cluster: one worker per usable core, 127.0.0.1, the dashboard on a free local port
    pytest.importorskip("distributed")
    import pandas as pd

    from inertia import load_scene

    load_scene(scene).run()          # compile once here (on-disk cache): the workers then load, not compile
    out = tmp_path / "out"
    result = invoke(scene, "--out", out, "-p", "particles[0].restitution=0.2:0.8:3",
                    "-m", "max_height", "-m", "vmax=peak(max(speed))")
    assert result.exit_code == 0, result.output
    assert "dask dashboard: http://127.0.0.1:" in result.output
    assert "3/3 done" in result.output and "0 failed" in result.output
    table = pd.read_parquet(out / "results.parquet")
    assert list(table.columns) == ["variant", "seed", "particles[0].restitution", "max_height", "vmax", "status",
                                   "error", "wall_time", "cpu_time", "pid"]
    assert list(table["status"]) == ["completed"] * 3
    csv = pd.read_csv(out / "results.csv")
    assert list(csv["variant"]) == [0, 1, 2]
    assert (out / "summary.png").stat().st_size > 1000
    # the same folder again: refused without --resume/--overwrite; --resume has nothing left to do
    again = invoke(scene, "--out", out, "--quiet", "-p", "particles[0].restitution=0.2:0.8:3",
                   "-m", "max_height", "-m", "vmax=peak(max(speed))")
    assert again.exit_code == 2 and "--resume" in again.output
    resumed = invoke(scene, "--out", out, "--resume", "-p", "particles[0].restitution=0.2:0.8:3",
                     "-m", "max_height", "-m", "vmax=peak(max(speed))", "--workers", "1", "--no-dashboard")
    assert resumed.exit_code == 0 and "0 run now, 3 from before" in resumed.output
