"""The bundled `smoke_sphere` scene (3-D smoke rising around a sphere): it validates, and a copy cut to
a tiny grid runs two frames through `inertia run`'s recording and rendering path in seconds."""

import tomllib
from pathlib import Path

import numpy as np

import inertia as ia
from inertia.scene import parse_scene, read_scene
from inertia.scene import build

SCENE = Path(ia.__file__).parent / "examples" / "smoke_sphere.toml"


def test_smoke_sphere_scene_has_a_sphere_obstacle_over_a_buoyant_source():
    scene = read_scene(SCENE).model
    smoke = scene.fluids["smoke"]
    assert scene.simulation.dim == 3 and len(smoke.shape) == 3
    assert smoke.obstacles == ["ball"] and smoke.buoyancy[1] > 0 and smoke.vorticity_confinement > 0
    ball = next(c for c in scene.colliders if c.name == "ball")
    source = smoke.sources[0]
    # the source lies under the ball: the plume has to split around it
    assert source.upper[2] < ball.center[2] - ball.radius
    assert source.lower[0] < ball.center[0] < source.upper[0]


def test_smoke_sphere_runs_and_renders_two_frames_on_a_tiny_grid(tmp_path):
    from inertia.cli.outputs import render_frames
    from inertia.io import load_states
    from inertia.world import Run

    data = tomllib.loads(SCENE.read_text())
    smoke = data["fluids"]["smoke"]
    smoke["shape"] = [8, 8, 12]          # 1 x 1 x 1.5 m at h = 0.125 m
    smoke["cell_size"] = 0.125
    data["simulation"].update(duration=0.5, fps=2.0)
    import json

    world = build(parse_scene(json.dumps(data), format="json", source="smoke_sphere (tiny)"))
    result = Run(world, tmp_path, duration=0.5, fps=2.0, handle_sigint=False).execute()
    states = load_states(result.states_path)
    density = states.fields["fluid/smoke/density"]
    assert density.shape == (2, 8, 8, 12) and density.dtype == np.float32
    assert density[0].max() == 0.0 and density[1].max() > 0.0      # the source has emitted smoke
    frames = dict(render_frames(states, {**data["render"], "width": 96, "height": 64}, world.colliders))
    assert sorted(frames) == [0, 1]
    assert not np.array_equal(frames[0], frames[1])                  # the smoke is drawn in frame 1
