"""Water poured from an emitter into a glass (3D SPH); writes four snapshots as one PNG and the
last frame's liquid surface as a PLY mesh (marching cubes, needs scikit-image).

    PYTHONPATH=src python examples/sph_pour_glass.py --out out/

The glass is a rigid model (a static floor plate and four wall boxes, ``inertia.model``), sampled
with boundary particles by ``fluid.advance(dt, rigid)``; the jet (width 0.06 m, 1 m/s down)
comes from an emitter above it. Spacing 0.02 m, 1.2 s (about a minute on 2 cores).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from inertia.fluids import sph
from inertia.fluids.sph import surface
from inertia.model import ModelBuilder
from inertia.render import Renderer, speed_colors, write_png
from inertia.rigid.world import RigidWorld


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out")
    ap.add_argument("--duration", type=float, default=1.2)
    a = ap.parse_args()
    dx = 0.02
    size = np.array([0.5, 0.5, 0.7])
    seed = sph.sample_block((0.23, 0.23, 0.05), (0.27, 0.27, 0.09), dx)  # a few drops in the glass
    fluid = sph.SPHFluid(seed, spacing=dx, domain=((0, 0, 0), size), viscosity=1e-3, xsph=0.05, capacity=12000,
                         max_iterations=200, max_speed=3.0)
    fluid.add_emitter(center=(0.25, 0.25, 0.6), velocity=(0.0, 0.0, -1.0), width=0.06)
    b = ModelBuilder(gravity=(0, 0, -9.81))
    b.add_plane((0, 0, 1), 0.0)                                     # table
    glass = b.add_body(position=(0.25, 0.25, 0.0), body_type="static")
    r, wall, height = 0.1, 0.03, 0.3                                 # inner half width, wall, height
    b.add_box(glass, half_extents=(r + wall, r + wall, 0.5 * wall), position=(0, 0, 0.5 * wall))
    for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        half = (0.5 * wall, r + wall, height / 2) if sx else (r + wall, 0.5 * wall, height / 2)
        b.add_box(glass, half_extents=half, position=(sx * (r + wall / 2), sy * (r + wall / 2), height / 2))
    rigid = RigidWorld(b.finalize(), dt=1 / 200)
    renderer = Renderer(400, 400, dim=3)
    renderer.fit(np.array([[0, 0, 0], size]))
    images = []
    for t in np.linspace(0, a.duration, 4)[1:].tolist() + [a.duration]:
        while rigid.state.time < t - 1e-9:
            rigid.step()
            fluid.advance(rigid.dt, rigid)
        walls = fluid.boundary_x
        walls = walls[(np.abs(walls[:, 0] - 0.25) < 0.2) & (walls[:, 1] > 0.2) & (walls[:, 2] > 0.001)]  # glass, front cut away
        shown = np.vstack([fluid.x, walls])
        colors = np.vstack([speed_colors(fluid.v, vmax=2.0), np.tile([[0.7, 0.8, 0.9]], (len(shown) - fluid.particle_count, 1))])
        images.append(renderer.frame(shown, radius=0.5 * dx, colors=colors))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = write_png(out / "sph_pour_glass.png", np.concatenate(images[:4], axis=1))
    print(f"wrote {path} ({fluid.particle_count} particles)")
    try:
        verts, faces = surface.reconstruct(fluid.x, dx)
        print(f"wrote {surface.write_ply_mesh(out / 'sph_pour_glass_surface.ply', verts, faces)}")
    except ImportError as exc:
        print(f"no surface mesh: {exc}")


if __name__ == "__main__":
    main()
