"""`inertia.cli.outputs.framed_renderer`: the automatic camera fills the picture with the subject.

The subject of a frame is what moves in it: the particles and the moving bodies' bounding boxes
(static scenery such as a ramp is framed with the whole run but not followed). Its screen
bounding box, projected through the camera of that frame (`Renderer.camera_at`), is measured as a
share of the picture (`Camera.screen_fill`); no pixel golden is needed.

- ``marbles``: 20 marbles roll off a 2 m ramp and several metres along the floor. Framed on the
  whole run they filled 0.8 % of the picture in their median frame; a camera that follows a
  travelling subject keeps them at more than 3 % (about 5 %) in the median frame and always in view.
- ``chain``: pinned at its top, the chain was drawn against the top edge, under the speed colour
  bar; the subject now stays below the legend band, and the region it sweeps over the run fills
  more than 30 % of the picture.
"""

from __future__ import annotations

import numpy as np

from inertia.cli.main import bundled_examples
from inertia.cli.outputs import framed_renderer
from inertia.io import load_states
from inertia.render.drawables import ModelDrawables
from inertia.scene import build, read_scene, with_overrides
from inertia.world import Run

W, H = 320, 180


def _run_example(name: str, tmp_path, duration: float, fps: float):
    loaded = with_overrides(read_scene(bundled_examples()[name]), duration=duration, fps=fps)
    world = build(loaded)
    result = Run(world, tmp_path / name, duration=duration, fps=fps, handle_sigint=False,
                 metadata={"scene_name": name, "render": loaded.model.render.model_dump(mode="json")}).execute()
    return load_states(result.states_path), world


def _subject_points(states, f: int) -> np.ndarray:
    """World points of frame ``f``'s subject: particles and the corners of the vertices of the
    moving bodies' shapes (vertices of the tessellated shapes at the frame's body poses)."""
    points = [np.asarray(states.positions[f], np.float64).reshape(-1, 3)]
    drawables = ModelDrawables.from_states(states)
    body_q = states.fields.get("body_q")
    if drawables is not None and drawables.local_vertices is not None and body_q is not None:
        moving = drawables.shape_body[drawables.vertex_shape] >= 0
        points.append(drawables.body_vertices(body_q[f])[0][moving])
    pts = np.concatenate(points)
    return pts[np.all(np.isfinite(pts), axis=1)]


def _fills(states, renderer) -> np.ndarray:
    return np.array([renderer.camera_at(float(states.times[f])).screen_fill(_subject_points(states, f), W, H)
                     for f in range(states.frame_count)])


def test_marbles_fill_the_picture_while_they_roll_away(tmp_path):
    states, world = _run_example("marbles", tmp_path, duration=4.0, fps=10.0)
    render = {**states.metadata["render"], "width": W, "height": H}
    renderer, _ = framed_renderer(states, render, world.colliders)
    fills = _fills(states, renderer)
    assert renderer.follow is True  # the marbles travel ~5 m from a 0.3 m cluster
    assert np.median(fills) > 0.03, f"median fill {np.median(fills):.3f}"
    # every frame shows its whole subject: the screen box is inside the picture
    for f in range(states.frame_count):
        px, py, depth = renderer.camera_at(float(states.times[f])).project(_subject_points(states, f), W, H)
        assert np.all(depth > 0) and px.min() >= -1 and px.max() <= W + 1 and py.min() >= -1 and py.max() <= H + 1, f


def test_chain_is_framed_below_its_legend(tmp_path):
    states, world = _run_example("chain", tmp_path, duration=6.0, fps=5.0)
    render = {**states.metadata["render"], "width": W, "height": H}
    renderer, legend = framed_renderer(states, render, world.colliders)
    assert legend is not None  # coloured by speed: the colour bar is drawn top-left
    tops = []
    for f in range(states.frame_count):
        _, py, _ = renderer.camera_at(float(states.times[f])).project(_subject_points(states, f), W, H)
        tops.append(py.min())
    radius_px = 0.025 * renderer.camera.focal_px(H) / float(np.linalg.norm(renderer.camera.position - renderer.camera.target))
    assert min(tops) - radius_px >= 12 + legend.shape[0], (min(tops), legend.shape)
    # a chain is a line (one frame's box can have no area): the still camera's picture is
    # filled by the region it sweeps over the run
    swept = np.concatenate([_subject_points(states, f) for f in range(states.frame_count)])
    assert renderer.camera.screen_fill(swept, W, H) > 0.3
    assert renderer.follow is False  # the pinned chain stays in place: a still camera


def test_screen_fill_of_a_box_seen_face_on():
    """A square of side 2 seen face-on by an orthographic camera 4 units tall fills (2/4)(2/(4 * 16/9)) of a 16:9 picture."""
    from inertia.render.camera import Camera

    cam = Camera.plane_2d((0.0, 0.0), 4.0)
    square = np.array([[-1.0, -1.0], [1.0, 1.0]])
    assert abs(cam.screen_fill(square, 1600, 900) - (2 / 4) * (2 / (4 * 16 / 9))) < 1e-12
    assert cam.screen_fill(np.array([[100.0, 100.0]]), 1600, 900) == 0.0  # outside: clipped away
