"""Video, GIF and PNG-sequence output, and `render_states`, which renders a whole run.

Formats by the output path:

``*.mp4`` / ``*.mov`` / ``*.mkv``
    H.264 (libx264, yuv420p, so every player opens it, preset "faster") through
    imageio-ffmpeg's bundled ffmpeg; ``quality`` 1-10 (imageio-ffmpeg's scale: CRF =
    51 (1 - quality / 10); 6.5 default, CRF 17). Odd sizes are padded to even.
``*.webm``
    VP9 (libvpx-vp9).
``*.gif``
    ffmpeg with a per-video palette (palettegen/paletteuse, Bayer dither), looping.
``*.png``
    one frame; with ``{frame}`` in the name (``frames/f_{frame:05d}.png``) one file per frame.
a directory (no suffix)
    ``frame_00000.png``, ``frame_00001.png``, ... inside it (created if missing).

Video files are written to a temporary file and renamed when complete (`inertia.io.atomic`);
each PNG is written atomically. Requires imageio-ffmpeg for video (``pip install inertia[cli]``).

Limitations: no audio; frames must all have the size of the first.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..io.atomic import atomic_path
from .png import write_png

__all__ = ["VideoWriter", "write_video", "render_states", "output_kind", "VIDEO_SUFFIXES"]

VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".webm", ".gif")

_CODECS = {".mp4": "libx264", ".mov": "libx264", ".mkv": "libx264", ".webm": "libvpx-vp9", ".gif": "gif"}


def _import_ffmpeg():
    try:
        import imageio_ffmpeg
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError(
            "video output needs imageio-ffmpeg: pip install inertia[cli]  (or: pip install imageio-ffmpeg)"
        ) from error
    return imageio_ffmpeg


def output_kind(path: str | os.PathLike) -> str:
    """"video", "png", "png-sequence" or "directory" for an output path (see the module docstring)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return "video"
    if suffix == ".png":
        return "png-sequence" if "{frame" in path.name else "png"
    if suffix == "":
        return "directory"
    raise ValueError(f"cannot write {path}: use a video ({', '.join(VIDEO_SUFFIXES)}), a .png, or a directory")


class VideoWriter:
    """Stream frames ((H, W, 3) uint8) into a video file; the file appears when `close` succeeds.

    ``fps``: frames per second (30 default). ``quality``: 1-10 for H.264/VP9 (6.5 default;
    8 for near-lossless, 5 for small files).
    Use as a context manager; an exception inside the block discards the partial video.
    """

    def __init__(self, path: str | os.PathLike, *, fps: float = 30.0, quality: float = 6.5):
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in _CODECS:
            raise ValueError(f"VideoWriter: {self.path} must end in one of {', '.join(_CODECS)}")
        if not fps > 0:
            raise ValueError(f"VideoWriter: fps must be > 0, got {fps!r}")
        if not 1.0 <= quality <= 10.0:
            raise ValueError(f"VideoWriter: quality must be in [1, 10], got {quality!r}")
        self.fps, self.quality = float(fps), float(quality)
        self.frame_count = 0
        self._size = None
        self._pad = (0, 0)
        self._generator = None
        self._context = None
        self._temp = None

    def _open(self, height: int, width: int) -> None:
        imageio_ffmpeg = _import_ffmpeg()
        suffix = self.path.suffix.lower()
        self._size = (height, width)
        # yuv420p needs even sizes: pad the last row/column by repetition.
        self._pad = (height % 2, width % 2) if suffix != ".gif" else (0, 0)
        size = (width + self._pad[1], height + self._pad[0])
        self._context = atomic_path(self.path)
        self._temp = self._context.__enter__()
        options = dict(fps=self.fps, macro_block_size=1, ffmpeg_log_level="error", codec=_CODECS[suffix])
        if suffix == ".gif":
            options.update(
                pix_fmt_out="pal8",
                output_params=[
                    "-vf", "split[s0][s1];[s0]palettegen=stats_mode=diff[p];[s1][p]paletteuse=dither=bayer:bayer_scale=3",
                    "-loop", "0",
                ],
            )
        else:
            options.update(pix_fmt_out="yuv420p", quality=self.quality)
            if suffix in (".mp4", ".mov", ".mkv"):
                options["output_params"] = ["-preset", "faster"] + (["-movflags", "+faststart"] if suffix != ".mkv" else [])
        self._generator = imageio_ffmpeg.write_frames(str(self._temp), size, **options)
        self._generator.send(None)

    def write(self, frame: np.ndarray) -> None:
        """Append one frame (H, W, 3) uint8."""
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(f"VideoWriter.write: frames must be (H, W, 3) uint8, got {frame.shape} {frame.dtype}")
        if self._generator is None:
            self._open(frame.shape[0], frame.shape[1])
        elif frame.shape[:2] != self._size:
            raise ValueError(f"VideoWriter.write: frame size {frame.shape[:2]} differs from the first frame's {self._size}")
        if any(self._pad):
            frame = np.pad(frame, ((0, self._pad[0]), (0, self._pad[1]), (0, 0)), mode="edge")
        self._generator.send(np.ascontiguousarray(frame))
        self.frame_count += 1

    def close(self) -> Path:
        """Finish the video and move it into place; returns the path."""
        if self._generator is None:
            raise ValueError(f"VideoWriter: no frames were written to {self.path}")
        self._generator.close()
        self._generator = None
        self._context.__exit__(None, None, None)
        return self.path

    def abort(self) -> None:
        """Discard the partial video (the final path is left untouched)."""
        if self._generator is not None:
            try:
                self._generator.close()
            except Exception:  # noqa: BLE001 - ffmpeg may complain about the cut stream
                pass
            self._generator = None
            error = RuntimeError("aborted")
            try:
                self._context.__exit__(type(error), error, None)
            except RuntimeError:
                pass

    def __enter__(self) -> "VideoWriter":
        return self

    def __exit__(self, kind, value, traceback) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


def write_video(frames, path: str | os.PathLike, *, fps: float | None = None, quality: float = 6.5, **render_options) -> Path:
    """Write a video (format by suffix); returns the path.

    ``frames``: an iterable of (H, W, 3) uint8 images, or a `States` (or state-file path), which
    is rendered with `render_states(frames, path, fps=fps, **render_options)`.
    """
    from ..io.states import States

    if isinstance(frames, (States, str, os.PathLike)):
        return render_states(frames, path, fps=fps, quality=quality, **render_options)
    if render_options:
        raise TypeError(f"write_video: render options {sorted(render_options)} need a States, not frames")
    with VideoWriter(path, fps=fps or 30.0, quality=quality) as writer:
        for frame in frames:
            writer.write(frame)
    return Path(path)


def _speed_max(states, indices, sample: int = 400_000) -> float | None:
    """The 99th percentile of the speeds over the selected frames (a deterministic sample)."""
    if states.velocities is None:
        return None
    v = states.velocities[indices]
    if "active" in states.fields:
        v = v[states.fields["active"][indices]]
    v = v.reshape(-1, states.dim)
    if v.shape[0] > sample:
        v = v[:: v.shape[0] // sample]
    speed = np.sqrt(np.einsum("ij,ij->i", v, v))
    speed = speed[np.isfinite(speed)]
    if speed.size == 0:
        return None
    vmax = float(np.percentile(speed, 99.0))
    return vmax if vmax > 0 else None


def render_states(
    states,
    out: str | os.PathLike | None = None,
    *,
    fps: float | None = None,
    width: int = 1280,
    height: int = 720,
    colliders: Sequence = (),
    frames=None,
    renderer=None,
    colors=None,
    quality: float = 6.5,
    progress: Callable[[int, int], None] | None = None,
    trails: int = 0,
    **renderer_options,
):
    """Render a run (`inertia.io.States`, or a path to a state file) to a video, PNG(s) or a folder.

    ``out=None`` returns an iterator of (H, W, 3) uint8 frames instead of writing anything.

    ``fps``: output frame rate, default the state file's. ``colliders``: drawn at each frame's
    time. ``frames``: slice or index array of frames (default all). ``renderer``: a configured
    `Renderer` (else one is made with ``width``, ``height`` and ``renderer_options``, e.g.
    ``color_by="group"``, ``azimuth=30``, ``theme="light"``). Unless a camera is given, the view
    is fitted to every frame of the run and speed colours share one scale over the run (the
    same whichever ``frames`` are drawn).
    ``trails``: draw each particle's path over that many previous frames as faint lines (3-D).
    A state file's ``model`` adds its bodies, cloth surfaces and springs
    (`inertia.render.drawables`).
    ``colors``: (N, 3), (F, N, 3) or ``colors(frame) -> (N, 3)``. ``progress(done, total)`` is
    called after each frame. Returns the output path (a list of paths for PNG sequences).

    The renderer's ``group_colors`` default to the state file's ``metadata["group_colors"]``.
    """
    from ..io.states import load_states
    from .renderer import Renderer

    if not (isinstance(trails, (int, np.integer)) and not isinstance(trails, bool) and 0 <= trails <= 100):
        raise ValueError(f"render_states: trails must be an integer number of frames in [0, 100], got {trails!r}")
    if isinstance(states, (str, os.PathLike)):
        states = load_states(states)
    kind = "frames" if out is None else output_kind(out)
    out = None if out is None else Path(out)
    indices = np.atleast_1d(np.arange(states.frame_count)[slice(None) if frames is None else frames])
    if indices.size == 0:
        raise ValueError(f"render_states: no frames selected (the state file has {states.frame_count})")
    if kind == "png" and indices.size != 1:
        raise ValueError(
            f"render_states: {out} is one PNG but {indices.size} frames were selected; "
            "use a name with {frame} (e.g. frame_{frame:05d}.png), a directory, or frames=[k]"
        )

    # The renderer, its camera fitted on the whole run, one speed scale for the run.
    if renderer is None:
        renderer = Renderer(width, height, dim=states.dim, **renderer_options)
    elif renderer_options:
        raise ValueError("render_states: pass renderer options either in `renderer` or as keywords, not both")
    if renderer.dim != states.dim:
        raise ValueError(f"render_states: renderer dim {renderer.dim} but the states are {states.dim}-D")
    active_all = states.fields.get("active")
    # Bodies, cloth surfaces and springs of the state file's model, if any.
    from .drawables import ModelDrawables, frame_options, subject_bounds

    drawables = ModelDrawables.from_states(states)
    if drawables is not None:
        colliders = list(colliders) + drawables.plane_colliders(subject_bounds(states, drawables))
    # The view and the speed scale come from the whole run, whichever frames are drawn, so a
    # single frame looks as it does in the video.
    if renderer.camera is None:
        renderer.fit(states.positions, radius=states.radius(), colliders=colliders,
                     t=float(states.times[0]), active=active_all, times=states.times,
                     extra_points=None if drawables is None else drawables.bounds_points(states.fields.get("body_q")))
    if renderer.speed_max is None:
        renderer.speed_max = _speed_max(states, np.arange(states.frame_count))
    if renderer.group_colors is None and states.metadata.get("group_colors"):
        renderer.group_colors = list(states.metadata["group_colors"])

    groups = states.groups()

    def frame_image(f: int) -> np.ndarray:
        frame_colors = colors(f) if callable(colors) else colors
        if frame_colors is not None and np.ndim(frame_colors) == 3:
            frame_colors = frame_colors[f]
        return renderer.frame(
            states.positions[f],
            radius=states.radius(f),
            velocities=None if states.velocities is None else states.velocities[f],
            colors=frame_colors,
            groups=groups,
            colliders=colliders,
            t=float(states.times[f]),
            **frame_options(drawables, states, f, states.active(f), trails=trails),
        )

    total = int(indices.size)
    if kind == "frames":
        return (frame_image(int(f)) for f in indices)
    if kind == "video":
        rate = float(fps or states.fps or 30.0)
        with VideoWriter(out, fps=rate, quality=quality) as writer:
            for done, f in enumerate(indices, 1):
                writer.write(frame_image(int(f)))
                if progress is not None:
                    progress(done, total)
        return out
    if kind == "png":
        write_png(out, frame_image(int(indices[0])))
        if progress is not None:
            progress(1, 1)
        return out
    if kind == "directory":
        out.mkdir(parents=True, exist_ok=True)
        pattern = str(out / "frame_{frame:05d}.png")
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        pattern = str(out)
    written = []
    for done, f in enumerate(indices, 1):
        path = Path(pattern.format(frame=int(f)))
        write_png(path, frame_image(int(f)))
        written.append(path)
        if progress is not None:
            progress(done, total)
    return written
