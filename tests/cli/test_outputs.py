"""`inertia.cli.outputs`: what `inertia run` draws and plots for the scenes that have more than particles.

- Containers and kinematic colliders that the world turned into shape-table rows are drawn as the
  colliders they came from (a box cut away toward the camera, the moving paddle), not as infinite
  planes in front of the subject: one frame of ``paddle`` and ``spheres_in_box`` shows its balls.
- The energy plot of a scene without particles has the bodies' curves, and they are right: a body
  in free fall under the soft-step solver (velocities integrated before positions) has
  K(t) = m (g t)^2 / 2 exactly after whole steps, and K + U changes only by the symplectic Euler
  offset m g^2 h t / 2, h = dt / substeps the integration step (Hairer, Lubich and Wanner 2006, ch. IX: a first-order symplectic method
  keeps the energy within O(dt) of its initial value).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from inertia.cli.main import bundled_examples
from inertia.cli.outputs import plot_energy, render_frames
from inertia.io import load_states
from inertia.render.plots import system_series
from inertia.scene import build, read_scene, with_overrides
from inertia.world import Run

MAGENTA = "#ff00ff"


def _run_example(name: str, tmp_path, duration: float = 0.08, fps: float = 25.0):
    loaded = with_overrides(read_scene(bundled_examples()[name]), duration=duration, fps=fps)
    world = build(loaded)
    result = Run(world, tmp_path / name, duration=duration, fps=fps, handle_sigint=False,
                 metadata={"scene_name": name, "render": loaded.model.render.model_dump(mode="json")}).execute()
    return load_states(result.states_path), world


def _magenta_pixels(image: np.ndarray) -> int:
    """Pixels whose hue is magenta (shaded spheres keep r ~ b >> g); the scenes draw nothing else magenta."""
    r, g, b = (image[..., c].astype(np.int32) for c in range(3))
    return int(np.count_nonzero((r > g + 60) & (b > g + 60) & (np.abs(r - b) < 50)))


@pytest.mark.parametrize("name", ["paddle", "spheres_in_box"])
def test_container_scenes_show_their_particles(name, tmp_path):
    states, world = _run_example(name, tmp_path)
    # every particle magenta, so the test counts particle pixels whatever the speed colour map does
    groups = len(states.metadata.get("groups") or [1])
    states = dataclasses.replace(states, metadata={**states.metadata, "group_colors": [MAGENTA] * groups})
    render = {**states.metadata["render"], "width": 240, "height": 136, "color_by": "group"}
    [(_, image)] = list(render_frames(states, render, world.colliders, frames=[states.frame_count - 1]))
    share = _magenta_pixels(image) / (image.shape[0] * image.shape[1])
    # paddle: 72 balls of 5 cm, spheres_in_box: 300 of 4-8 cm, framed on a 5 m / 2 m box: > 0.3 % of the picture
    assert share > 0.003, f"{name}: particles cover {100 * share:.2f}% of the frame"


def test_paddle_is_drawn(tmp_path):
    """The kinematic paddle (a box collider) is drawn: the frame differs where the paddle is, i.e.
    the picture changes between two frames at the paddle's motion even with the balls hidden."""
    states, world = _run_example("paddle", tmp_path, duration=0.4, fps=5.0)
    hidden = dataclasses.replace(states, positions=np.full_like(states.positions, np.nan))
    render = {**states.metadata["render"], "width": 200, "height": 112, "camera": {"azimuth": -90.0, "elevation": 20.0}}
    images = [img for _, img in render_frames(hidden, render, world.colliders, frames=[0, states.frame_count - 1])]
    moved = np.count_nonzero(np.any(images[0].astype(int) != images[1].astype(int), axis=2))
    assert moved > 50  # the paddle moved 1.4 m along x between the two frames


BODY_ONLY = """
format_version = 1
name = "falling_box"
[simulation]
dt = 0.01
duration = 0.3
fps = 10
[rigid]
substeps = 4
[bodies.box]
shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }
mass = 2.0
position = [0.0, 0.0, 5.0]
"""


def test_energy_plot_of_a_body_only_scene_has_the_bodies_curves(tmp_path):
    path = tmp_path / "falling_box.toml"
    path.write_text(BODY_ONLY)
    world = build(read_scene(path))
    result = Run(world, tmp_path / "run", duration=0.3, fps=10, handle_sigint=False,
                 metadata={"scene_name": "falling_box"}).execute()
    states = load_states(result.states_path)
    systems = {s.name: s for s in system_series(states)}
    assert set(systems) == {"bodies"}  # no particles: no empty particle row
    bodies = systems["bodies"]
    t, m, g, h = states.times, 2.0, 9.81, 0.01 / 4  # dt / substeps
    kinetic = bodies.energy["kinetic K"]
    np.testing.assert_allclose(kinetic, 0.5 * m * (g * t) ** 2, rtol=1e-9, atol=1e-12)
    total = bodies.energy["total E = K + U"]
    # symplectic Euler in free fall: E(t) - E(0) = -m g^2 h t / 2 (velocity first, then position)
    np.testing.assert_allclose(total - total[0], -0.5 * m * g * g * h * t, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(bodies.right["pz"], -m * g * t, rtol=1e-9, atol=1e-12)
    assert plot_energy(states, tmp_path / "energy.png").stat().st_size > 10_000


def test_wind_attractor_is_drawn_where_it_pulls():
    from inertia.cli.outputs import attractor_markers
    from inertia.io import States
    from inertia.render.colliders import collider_primitives

    text = (bundled_examples()["wind"]).read_text()
    x = np.random.default_rng(0).uniform(-1.0, 1.0, (2, 50, 3))
    states = States(times=np.array([0.0, 0.1]), positions=x, metadata={"scene": text, "scene_format": "toml"})
    [marker] = attractor_markers(states)
    prims = collider_primitives([marker], 0.0, 3)
    np.testing.assert_allclose(prims.params[0, :3], (1.0, 0.0, 1.0))  # the scene's attractor centre
    assert 0.0 < prims.params[0, 3] <= 0.15  # half its 0.3 m softening, at most 5 % of the 2 m cloud
    assert attractor_markers(States(times=np.zeros(1), positions=x[:1], metadata={"scene": "format_version = 1"})) == []
