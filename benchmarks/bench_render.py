"""Render throughput at 1280 x 720: frames per second for 10^4 and 10^5 particles.

    python benchmarks/bench_render.py [--frames 20] [--sizes 10000 100000] [--width 1280 --height 720]

Scene: a box of particles (radius 0.01 in a 2 x 2 x 1.5 volume, so ~2 px discs) above a
ground plane with a sphere collider, coloured by speed, contact shadows on: the default look.
The camera and background are set up once (as in a video); each timed frame projects, sorts,
shades and converts every particle. The first call (Numba compilation, cached on disk after the
first run) is excluded and reported separately.

Baseline measured in the same run (STYLE.md 18): the time to copy one frame's buffers
(float colour, depth and byte image, 17.5 MB at 1280 x 720) with NumPy, i.e. the memory
traffic any frame must pay; the ratio frame time / copy time says how far above that floor
a frame is.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "render"))
from render_scenes import random_cloud  # noqa: E402

import inertia.colliders as C  # noqa: E402
from inertia.render import Renderer  # noqa: E402


def _copy_baseline(width: int, height: int, repeats: int) -> float:
    """Seconds to copy the frame buffers once (NumPy memcpy), median of ``repeats``."""
    color = np.random.default_rng(0).random((height, width, 3)).astype(np.float32)
    depth = np.ones((height, width), np.float32)
    image = np.zeros((height, width, 3), np.uint8)
    dst = [np.empty_like(color), np.empty_like(depth), np.empty_like(image)]
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.copyto(dst[0], color)
        np.copyto(dst[1], depth)
        np.copyto(dst[2], image)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench(count: int, width: int, height: int, frames: int) -> dict:
    positions, velocities = random_cloud(count)
    colliders = [C.Plane(point=(0, 0, 0), normal=(0, 0, 1)), C.Sphere(center=(1.5, 0.0, 0.4), radius=0.4)]
    renderer = Renderer(width, height, speed_max=3.0)
    out = np.empty((height, width, 3), np.uint8)
    t0 = time.perf_counter()
    renderer.frame(positions, radius=0.01, velocities=velocities, colliders=colliders, out=out)
    first = time.perf_counter() - t0
    rng = np.random.default_rng(1)
    times = []
    for _ in range(frames):
        # Particles move a little between frames, as in a run.
        positions += rng.normal(scale=1e-3, size=positions.shape)
        t0 = time.perf_counter()
        renderer.frame(positions, radius=0.01, velocities=velocities, colliders=colliders, out=out)
        times.append(time.perf_counter() - t0)
    frame = statistics.median(times)
    return {"count": count, "first": first, "frame": frame, "best": min(times), "fps": 1.0 / frame}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    args = parser.parse_args(argv)

    copy = _copy_baseline(args.width, args.height, 50)
    print(f"render benchmark {args.width}x{args.height}, {numba.get_num_threads()} Numba threads "
          f"({numba.threading_layer() if hasattr(numba, 'threading_layer') else '?'})")
    print(f"baseline: copy one frame's buffers {copy * 1e3:.2f} ms")
    print(f"{'particles':>10} {'first (s)':>10} {'frame (ms)':>11} {'best (ms)':>10} {'frames/s':>9} {'x copy':>8}")
    for count in args.sizes:
        r = bench(count, args.width, args.height, args.frames)
        print(f"{r['count']:>10} {r['first']:>10.2f} {r['frame'] * 1e3:>11.1f} {r['best'] * 1e3:>10.1f} "
              f"{r['fps']:>9.1f} {r['frame'] / copy:>8.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
