"""Regenerate the render images of docs/rendering.md (run from the repository root):

    PYTHONPATH=src python docs/images/render_examples.py OUT_RUNS_DIR

OUT_RUNS_DIR holds finished runs of the bundled examples (``inertia run NAME -o OUT_RUNS_DIR/NAME``
for fountain, wind, cloth and chain). Cloth and chain get the ``model`` entries the world records
(``surface_triangles``, ``spring_pairs``) built here from their grid and chain layout, and a
small rigid-body still life shows meshes with shadows.
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np

from inertia.cli.main import _scene_colliders
from inertia.cli.outputs import render_frames
from inertia.io import load_states
from inertia.io.states import States
from inertia.render import render_states
from inertia.render.png import write_png

HERE = Path(__file__).parent
SIZE = {"width": 640, "height": 360}


def shot(states, name, frame, **extra):
    render = dict(tomllib.loads(states.metadata["scene"]).get("render", {}))
    render.update(SIZE)
    render.update(extra)
    for _, image in render_frames(states, render, _scene_colliders(states), frames=[frame]):
        write_png(HERE / f"render_{name}.png", image)


def grid_triangles(nu, nv):
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    return np.concatenate([np.stack([a, a + nv, a + nv + 1], 1), np.stack([a, a + nv + 1, a + 1], 1)])


def main(runs: Path) -> None:
    shot(load_states(runs / "fountain" / "states"), "fountain", 75, width=560, height=316)  # < 200 KB
    wind = load_states(runs / "wind" / "states")
    shot(wind, "wind", 100, trails=10, camera={"azimuth": -90.0, "elevation": 20.0, "follow": True})
    cloth = load_states(runs / "cloth" / "states")
    cloth.model = {"surface_triangles": grid_triangles(20, 20)}
    shot(cloth, "cloth", 60)
    chain = load_states(runs / "chain" / "states")
    chain.model = {"spring_pairs": np.stack([np.arange(19), np.arange(1, 20)], 1)}
    shot(chain, "chain", 40)
    # Rigid bodies at rest on a plane: box, sphere, capsule, cylinder, a tilted box on top.
    tilt = np.array([np.cos(0.3), 0.0, np.sin(0.3), 0.0])
    model = {
        "shape_type": np.array([6, 1, 0, 2, 3, 1], np.int32),
        "shape_body": np.array([-1, 0, 1, 2, 3, 4], np.int32),
        "shape_local_pose": np.tile([0, 0, 0, 1.0, 0, 0, 0], (6, 1)),
        "shape_params": np.array([[0, 0, 0, 0], [0.3, 0.3, 0.3, 0], [0.3, 0, 0, 0], [0.15, 0.3, 0, 0],
                                  [0.25, 0.3, 0, 0], [0.2, 0.2, 0.2, 0]]),
    }
    body_q = np.array([[[-0.8, 0, 0.3, 1, 0, 0, 0], [0.2, -0.3, 0.3, 1, 0, 0, 0], [0.9, 0.5, 0.15, *tilt],
                        [0.0, 0.8, 0.3, 1, 0, 0, 0], [-0.8, 0.05, 0.85, np.cos(0.4), 0, 0, np.sin(0.4)]]])
    body_q[0, 2, 3:] = [np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0]  # the capsule lies down
    bodies = States(times=np.zeros(1), positions=np.zeros((1, 0, 3)), fields={"body_q": body_q}, metadata={"fps": 25.0})
    bodies.model = model
    render_states(bodies, HERE / "render_bodies.png", azimuth=-55.0, elevation=28.0, **SIZE)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
