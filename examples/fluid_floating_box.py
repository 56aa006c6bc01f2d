"""A box floating in a liquid tank (2-D APIC liquid, a rigid body of the world); writes one PNG.

    PYTHONPATH=src python examples/fluid_floating_box.py --out out/ [--cells 32] [--duration 4]

A 1.5 m x 1 m tank holds water 0.45 m deep and a 0.25 m wide column 0.75 m high at its left wall.
A wooden box (0.36 m x 0.16 m, density 500 kg/m^3: it floats at half its height) rests on the
water at x = 1 m. The column collapses, its surge reaches the box, lifts and tilts it, and the box
settles back to its Archimedes draft. The box is a `ModelBuilder` body in an `inertia.world.World`
(the users' path): the liquid couples to it through ``advance(dt, world.rigid)`` (pressure on its
cut cells, implicit two-way coupling, `inertia.fluids.grid.liquid_pressure`). The 2-D liquid is a
slab 0.1 m deep in z, as thick as the box, so the box's mass and the liquid's force match.

Panels: four snapshots (particles coloured by speed, the free surface, the box) and the box's
height against time with the Archimedes equilibrium line.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from inertia.fluids.grid import LiquidFluid  # noqa: E402
from inertia.model import ModelBuilder  # noqa: E402
from inertia.world import World  # noqa: E402

G = 9.81
RHO = 1000.0


def box_outline(q, hx, hy):
    """Corners (5, 2) of the box at pose q (x, y, z, qw, qx, qy, qz), rotated about z."""
    w, z = q[3], q[6]
    ang = 2 * np.arctan2(z, w)
    c, s = np.cos(ang), np.sin(ang)
    pts = np.array([(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)])
    return q[:2] + pts @ np.array([[c, s], [-s, c]])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out")
    ap.add_argument("--cells", type=int, default=32, help="cells per metre")
    ap.add_argument("--duration", type=float, default=4.0, help="seconds")
    a = ap.parse_args()
    h = 1.0 / a.cells
    width, height = 1.5, 1.0
    level = 0.45
    hx, hy, hz = 0.18, 0.08, 0.05
    density = 500.0
    draft = density / RHO * 2 * hy

    b = ModelBuilder(gravity=(0.0, -G, 0.0))
    b.add_plane(normal=(0.0, 1.0, 0.0), offset=0.0)       # the tank's floor and side walls for
    b.add_plane(normal=(1.0, 0.0, 0.0), offset=0.0)       # the box (the liquid's own walls are
    b.add_plane(normal=(-1.0, 0.0, 0.0), offset=-width)   # the grid's sides)
    box = b.add_body(position=(1.0, level - draft + hy, 0.0))
    b.add_box(box, half_extents=(hx, hy, hz), density=density)
    world = World(dt=1 / 120, model=b.finalize())
    liquid = LiquidFluid((int(round(width * a.cells)), int(round(height * a.cells))), h,
                         depth=2 * hz, method="apic")
    liquid.add_block((0.0, 0.0), (width, level))
    liquid.add_block((0.0, level), (0.25, 0.75))
    world.add_fluid("water", liquid)
    liquid.bind_rigid(world.rigid)   # (advance would do it) drops the particles inside the box

    shots = [0.0, 0.8, 1.6, a.duration]
    fig, axes = plt.subplots(1, 5, figsize=(24, 3.8))
    ts, ys = [], []
    k = 0
    t0 = time.perf_counter()
    steps = int(round(a.duration / world.dt))
    for n in range(steps + 1):
        t = n * world.dt
        q = world.rigid.state.body_q[box]
        ts.append(t)
        ys.append(q[1])
        if k < len(shots) and t >= shots[k] - 1e-9:
            ax = axes[k]
            speed = np.linalg.norm(liquid.velocities(), axis=1)
            ax.scatter(liquid.positions()[:, 0], liquid.positions()[:, 1], c=speed, s=0.5,
                       cmap="Blues_r", vmin=0, vmax=2.5)
            for line in liquid.surface_mesh():
                ax.plot(line[:, 0], line[:, 1], "k-", lw=0.6)
            corners = box_outline(q, hx, hy)
            ax.fill(corners[:, 0], corners[:, 1], color="peru", ec="saddlebrown", lw=1.5)
            ax.set_xlim(0, width)
            ax.set_ylim(0, height)
            ax.set_aspect("equal")
            ax.set_title(f"t = {t:.2f} s")
            k += 1
        if n < steps:
            world.step()
    wall = time.perf_counter() - t0
    ax = axes[4]
    ax.plot(ts, ys, "-", color="saddlebrown", label="box centre height")
    # Archimedes: the level the water's volume reaches with the box at its draft, minus the draft
    area = liquid.particle_count * (h / 2) ** 2
    eq = (area + 2 * hx * draft) / width - draft + hy
    ax.axhline(eq, color="k", ls="--", lw=0.8, label="Archimedes equilibrium")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="upper right")
    ax.set_title("box height")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "fluid_floating_box.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    last = np.array(ys[len(ys) * 2 // 3:])
    print(f"{liquid.particle_count} particles, {steps} steps in {wall:.1f} s; box height over the "
          f"last third {last.mean():.3f} m (Archimedes {eq:.3f} m); wrote {path}")


if __name__ == "__main__":
    main()
