"""Smoke-like tracers rising through 3-D curl-noise around a sphere; writes a video.

    python examples/curl_noise_sphere.py --out out/

Tracers are released from a disc below a sphere and carried by divergence-free curl-noise
(Bridson, Hourihan & Nordenstam 2007) with a rising mean flow. The sphere is a boundary of the
field: the smoke parts around it, runs along its surface and never enters it. Tracers that
leave the top are released again at the bottom, so the plume is continuous.

Writes ``curl_noise_sphere.mp4`` (or PNG frames if ffmpeg is not installed) and a still
``curl_noise_sphere.png`` in ``--out``; prints the closest any tracer came to the sphere.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

import inertia as ia


def build_scene(tracer_count=10_000, seed=7):
    """The sphere, the flow around it, and the tracers' starting positions."""
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.25)
    flow = ia.fields.CurlNoise(dim=3, seed=seed, frequency=2.5, octaves=2, speed=0.4,
                               time_frequency=0.3, mean_velocity=(0.0, 0.0, 0.6),
                               boundaries=[sphere], boundary_width=0.2)
    rng = np.random.default_rng(seed)
    # Spread the initial tracers along the plume's height so the video starts full.
    start = emit(rng, tracer_count)
    start[:, 2] = rng.uniform(-0.9, 0.9, tracer_count)
    start = start[sphere.signed_distance(start) > 0.01]
    return sphere, flow, start, rng


def emit(rng, count):
    """Positions on the emitter: a disc of radius 0.2 in the plane z = -0.9."""
    r = 0.2 * np.sqrt(rng.uniform(0.0, 1.0, count))
    a = rng.uniform(0.0, 2 * np.pi, count)
    return np.stack([r * np.cos(a), r * np.sin(a), np.full(count, -0.9)], axis=1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory")
    parser.add_argument("--frames", type=int, default=120, help="frames at 30 fps")
    parser.add_argument("--tracers", type=int, default=10_000)
    parser.add_argument("--size", type=int, nargs=2, default=(640, 480), metavar=("W", "H"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    sphere, flow, start, rng = build_scene(args.tracers)
    tracers = ia.Tracers(start, flow)
    fps, substeps = 30.0, 1  # RK4 at 1/30 s: a tracer moves ~1/6 of the boundary width
    sim = ia.Simulation(tracers, integrator="rk4", dt=1.0 / (fps * substeps))

    renderer = ia.render.Renderer(*args.size, dim=3, up="z", azimuth=-60.0, elevation=12.0,
                                  ground=False, shadows=False)
    renderer.fit(np.array([[-0.45, -0.45, -0.95], [0.45, 0.45, 1.0]]), colliders=[sphere])
    age = rng.uniform(0.0, 3.0, len(start))

    def frames():
        nonlocal age
        for _ in range(args.frames):
            for _ in range(substeps):
                sim.step()
            age += 1.0 / fps
            # Re-release tracers that left the top (the plume is continuous).
            gone = tracers.x[:, 2] > 1.0
            if gone.any():
                tracers.x[gone] = emit(rng, int(gone.sum()))
                age[gone] = 0.0
                tracers.state_modified()
            frames.closest = min(frames.closest, float(sphere.signed_distance(tracers.x).min()))
            # Smoke colour: bright when fresh, fading to grey-blue with age.
            shade = np.exp(-age / 2.5)[:, None]
            colors = shade * np.array([1.0, 0.85, 0.6]) + (1 - shade) * np.array([0.45, 0.55, 0.75])
            yield renderer.frame(tracers.x, radius=0.005, colors=colors, colliders=[sphere])
    frames.closest = np.inf

    last = None
    if importlib.util.find_spec("imageio_ffmpeg") is not None:
        video = args.out / "curl_noise_sphere.mp4"
        with ia.render.VideoWriter(video, fps=fps) as writer:
            for last in frames():
                writer.write(last)
        print(f"wrote {video}")
    else:  # no ffmpeg: a PNG sequence
        frame_dir = args.out / "curl_noise_sphere_frames"
        frame_dir.mkdir(exist_ok=True)
        for k, last in enumerate(frames()):
            ia.render.write_png(frame_dir / f"frame_{k:05d}.png", last)
        print(f"wrote PNG frames to {frame_dir} (pip install imageio-ffmpeg for video)")
    ia.render.write_png(args.out / "curl_noise_sphere.png", last)
    print(f"closest approach of any tracer to the sphere surface: {frames.closest:.2e} "
          f"(never inside: {frames.closest > 0})")


if __name__ == "__main__":
    main()
