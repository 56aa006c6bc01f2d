"""Videos decode with the right frame count; PNGs, plots and colour maps hold what they should."""

from __future__ import annotations

import numpy as np
import pytest

from inertia.io import States, StateWriter
from inertia.render import (
    COLORMAPS,
    VideoWriter,
    colormap,
    encode_png,
    plot_energy,
    plot_states_energy,
    read_png,
    render_states,
    write_png,
    write_video,
)
from inertia.render.colormaps import group_palette, parse_color


def _falling_run(path=None, frames=12, n=200, dim=3):
    rng = np.random.default_rng(2)
    x = rng.random((n, dim)) + np.eye(dim)[-1]
    v = rng.normal(size=(n, dim)) * 0.3
    g = -9.81 * np.eye(dim)[-1]
    dt = 1 / 24
    xs, vs = [], []
    for _ in range(frames):
        xs.append(x.copy())
        vs.append(v.copy())
        v = v + g * dt
        x = x + v * dt
        below = x[:, -1] < 0.02
        x[below, -1], v[below, -1] = 0.02, -0.6 * v[below, -1]
    states = States(
        times=np.arange(frames) * dt, positions=np.array(xs), velocities=np.array(vs),
        static={"radius": np.full(n, 0.03), "mass": np.ones(n), "group": (np.arange(n) % 2).astype(np.int32)},
        metadata={"fps": 24.0, "groups": ["a", "b"], "group_colors": ["#ff0000", None]},
    )
    return states


def _count_frames(path):
    import imageio_ffmpeg

    return imageio_ffmpeg.count_frames_and_secs(str(path))[0]


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_rendered_video_decodes_with_every_frame(tmp_path, suffix):
    pytest.importorskip("imageio_ffmpeg")
    states = _falling_run()
    out = render_states(states, tmp_path / f"run{suffix}", width=160, height=90)
    assert out.exists() and _count_frames(out) == states.frame_count
    import imageio.v3 as iio

    first = iio.imread(out, index=0)
    assert first.shape[:2] == (90, 160)


def test_video_writer_pads_odd_sizes_and_discards_aborted_videos(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    frames = [np.full((45, 81, 3), 40 * k, np.uint8) for k in range(5)]
    path = write_video(frames, tmp_path / "odd.mp4", fps=10)
    assert _count_frames(path) == 5
    with pytest.raises(RuntimeError):
        with VideoWriter(tmp_path / "broken.mp4", fps=10) as writer:
            writer.write(frames[0])
            raise RuntimeError("renderer crashed")
    assert not (tmp_path / "broken.mp4").exists()
    assert not [p for p in tmp_path.iterdir() if "partial" in p.name]


def test_png_frames_directory_pattern_and_iterator(tmp_path):
    states = _falling_run(frames=4)
    paths = render_states(states, tmp_path / "frames", width=64, height=48)
    assert [p.name for p in paths] == [f"frame_{f:05d}.png" for f in range(4)]
    assert read_png(paths[2]).shape == (48, 64, 3)
    pattern = render_states(states, tmp_path / "seq" / "f_{frame:03d}.png", frames=slice(1, 3), width=64, height=48)
    assert [p.name for p in pattern] == ["f_001.png", "f_002.png"]
    one = render_states(states, tmp_path / "last.png", frames=[3], width=64, height=48)
    frames = list(render_states(states, width=64, height=48))
    assert len(frames) == 4 and frames[0].dtype == np.uint8
    np.testing.assert_array_equal(read_png(one), frames[3])
    with pytest.raises(ValueError, match="one PNG but 4 frames"):
        render_states(states, tmp_path / "x.png")
    with pytest.raises(ValueError, match="use a video"):
        render_states(states, tmp_path / "x.avi")


def test_render_states_reads_a_state_directory_and_honours_group_colours(tmp_path):
    states = _falling_run(frames=3, dim=2)
    with StateWriter(tmp_path / "run.states", dim=2, particle_count=states.particle_count, fps=24,
                     static=states.static, metadata={"groups": ["a", "b"], "group_colors": ["#ff0000", None]}) as w:
        for f in range(3):
            w.append(states.times[f], states.positions[f], states.velocities[f])
    image = next(render_states(tmp_path / "run.states", width=200, height=150, color_by="group", shadows=False))
    red = (image[..., 0] > 150) & (image[..., 1] < 80) & (image[..., 2] < 80)
    assert red.sum() > 50


def test_png_encoding_is_deterministic_and_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(17, 23, 3), dtype=np.uint8)
    assert encode_png(image) == encode_png(image.copy())
    np.testing.assert_array_equal(read_png(write_png(tmp_path / "a.png", image)), image)
    rgba = rng.integers(0, 256, size=(5, 4, 4), dtype=np.uint8)
    np.testing.assert_array_equal(read_png(write_png(tmp_path / "b.png", rgba)), rgba)
    # Files written by another encoder (matplotlib / Pillow filters) read back too.
    pil = pytest.importorskip("PIL.Image")
    pil.fromarray(image).save(tmp_path / "pil.png", optimize=True)
    np.testing.assert_array_equal(read_png(tmp_path / "pil.png"), image)


def test_energy_plot_from_arrays_and_from_states(tmp_path):
    pytest.importorskip("matplotlib")
    t = np.linspace(0, 2, 50)
    path = plot_energy(t, 1 + np.sin(t) ** 2, np.cos(t) ** 2, np.column_stack([t, -t, 0 * t]), tmp_path / "e.png",
                       title="pendulum")
    image = read_png(path)
    assert image.shape[0] > 300 and image.shape[1] > 600
    states = _falling_run()
    assert read_png(plot_states_energy(states, tmp_path / "s.png", gravity=(0, 0, -9.81))).shape[2] in (3, 4)
    assert plot_energy(states, tmp_path / "poly.png").exists()  # the States form
    with pytest.raises(ValueError, match="kinetic must have the shape"):
        plot_energy(t, np.zeros(3), path=tmp_path / "bad.png")


def test_colour_maps_and_colour_parsing():
    for name in COLORMAPS:
        c = colormap(name, np.array([0.0, 0.5, 1.0, np.nan]))
        assert c.shape == (4, 3) and c.dtype == np.float32 and np.all((c >= 0) & (c <= 1))
        np.testing.assert_array_equal(c[3], c[0])
    np.testing.assert_allclose(colormap("viridis", [0.0, 1.0]), [[0.267, 0.005, 0.329], [0.993, 0.906, 0.144]], atol=2e-3)
    np.testing.assert_allclose(parse_color("#ff8000"), [1.0, 128 / 255, 0.0], atol=1e-6)
    np.testing.assert_allclose(parse_color((255, 0, 0)), [1, 0, 0])
    assert group_palette(["#000000"], 12).shape == (12, 3)
    with pytest.raises(ValueError, match="unknown colour"):
        parse_color("plaid")
    with pytest.raises(ValueError, match="unknown map"):
        colormap("rainbow", [0.0])
