"""A raycast vehicle driving over rolling terrain (a heightfield); writes one PNG figure.

    python examples/rigid_vehicle.py --out out/

Left: the terrain, the car's path (coloured by speed) and the chassis with its four wheel contacts at
the end. Right: speed and the four suspension compressions over time (the static sag m g / (4 k) dashed).
The car accelerates with a constant engine torque and steers a gentle left turn over the hills.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from inertia.model import ModelBuilder
from inertia.rigid.vehicle import RaycastVehicle, Wheel
from inertia.rigid.world import RigidWorld

G, MASS, K = 9.81, 1000.0, 30000.0


def terrain(n=61, spacing=1.0):
    x = (np.arange(n) - (n - 1) / 2) * spacing
    X, Y = np.meshgrid(x, x, indexing="ij")
    H = 0.35 * np.sin(X / 4.0) * np.cos(Y / 5.0) + 0.2 * np.sin((X + Y) / 7.0)
    return X, Y, H


def simulate(seconds=8.0):
    X, Y, H = terrain()
    b = ModelBuilder(gravity=(0, 0, -G))
    b.add_heightfield(H, (1.0, 1.0))
    i0, j0 = 30, 22                                  # start cell: (0, -8) m
    z0 = float(H[i0, j0]) + 0.2 + 0.65 - MASS * G / (4 * K)
    chassis = b.add_body(position=(0.0, -8.0, z0), mass=MASS,
                         inertia=(MASS * (1.8 ** 2 + 0.5 ** 2) / 12, MASS * (4.0 ** 2 + 0.5 ** 2) / 12,
                                  MASS * (4.0 ** 2 + 1.8 ** 2) / 12))
    b.add_box(chassis, (2.0, 0.9, 0.25))
    world = RigidWorld(b.finalize(), enable_sleep=False)
    wheels = [Wheel((sx * 1.3, sy * 0.8, -0.2), stiffness=K, damping=3000.0, friction=0.9, steered=sx > 0,
                    driven=sx < 0) for sx in (1, -1) for sy in (1, -1)]
    car = RaycastVehicle(world, chassis, wheels)
    car.engine_torque, car.steering = 250.0, 0.25
    rec = {"t": [], "pos": [], "speed": [], "comp": []}
    for i in range(int(seconds / world.dt)):
        if i * world.dt > 4.0:
            car.engine_torque = 0.0
        car.update()
        world.step()
        rec["t"].append(world.state.time)
        rec["pos"].append(world.state.body_q[chassis, :3].copy())
        rec["speed"].append(float(np.linalg.norm(world.state.body_qd[chassis, 3:])))
        rec["comp"].append(car.wheel_compression.copy())
    return (X, Y, H), world, car, chassis, {k: np.array(v) for k, v in rec.items()}


def box_faces(q, half):
    w, x, y, z = q[3:]
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    c = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    v = q[:3] + c @ R.T
    idx = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return [v[list(f)] for f in idx]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out", help="output directory (default: out)")
    args = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    (X, Y, H), world, car, chassis, rec = simulate()
    fig = plt.figure(figsize=(13, 5.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    sl = slice(10, 51)
    ax.plot_surface(X[sl, sl], Y[sl, sl], H[sl, sl], cmap="terrain", alpha=0.55, linewidth=0,
                    antialiased=True, vmin=-1.2, vmax=1.2)
    p = rec["pos"]
    sc = ax.scatter(p[::3, 0], p[::3, 1], p[::3, 2] - 0.55, c=rec["speed"][::3], cmap="plasma", s=4)
    ax.add_collection3d(Poly3DCollection(box_faces(world.state.body_q[chassis], np.array([2.0, 0.9, 0.25])),
                                         facecolor="tab:red", edgecolor="k", alpha=0.9))
    cp = car.wheel_contact_point[car.wheel_in_contact]
    ax.scatter(cp[:, 0], cp[:, 1], cp[:, 2], c="k", s=25, depthshade=False)
    ax.set_box_aspect((1, 1, 0.3))
    ax.view_init(elev=35, azim=-60)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_zlim(-1.5, 2.5)
    ax.set_title("raycast vehicle on a heightfield (path coloured by speed)")
    fig.colorbar(sc, ax=ax, shrink=0.6, label="speed (m/s)")
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.plot(rec["t"], rec["speed"], "k", label="speed (m/s)")
    ax3 = ax2.twinx()
    for k in range(4):
        ax3.plot(rec["t"], 100 * rec["comp"][:, k], lw=0.8, label=f"wheel {k} compression")
    ax3.axhline(100 * MASS * G / (4 * K), ls="--", c="gray", label="static sag m g / 4k")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("speed (m/s)")
    ax3.set_ylabel("suspension compression (cm)")
    ax2.legend(loc="upper left")
    ax3.legend(loc="lower right", fontsize=8)
    ax2.set_title("engine on for 4 s, then coasting over the hills")
    fig.tight_layout()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "rigid_vehicle.png", dpi=110)
    print(f"wrote {out / 'rigid_vehicle.png'}")


if __name__ == "__main__":
    main()
