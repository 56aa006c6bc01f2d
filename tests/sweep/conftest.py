import os
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[2] / "src")

# One ball dropped onto a plane: its lowest point starts h0 = 1 m above the ground.
BALL = """
format_version = 1
name = "ball"
[simulation]
dt = 0.001
duration = {duration}
fps = 100
integrator = "velocity_verlet"
[[forces]]
type = "gravity"
[[colliders]]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[particles]]
name = "ball"
positions = [[0.0, 0.0, 1.05]]
radius = 0.05
restitution = 0.5
collision_mode = "a_priori"
"""


@pytest.fixture
def ball_scene(tmp_path):
    def write(duration=1.0, name="ball.toml"):
        path = tmp_path / name
        path.write_text(BALL.format(duration=duration))
        return path
    return write


@pytest.fixture(scope="package")
def cluster_client():
    """A LocalCluster of 2 single-threaded worker processes on 127.0.0.1, no dashboard; closed after the
    sweep tests (its threads would otherwise run beside the rest of the suite in the same process)."""
    distributed = pytest.importorskip("distributed")
    import logging

    env = {"NUMBA_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join(filter(None, [SRC, os.environ.get("PYTHONPATH")]))}
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                       dashboard_address=None, scheduler_kwargs={"dashboard": False}, silence_logs=logging.ERROR, env=env)
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()
