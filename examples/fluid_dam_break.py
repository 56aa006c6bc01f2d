"""2-D liquid dam break with APIC (or FLIP) particles on a MAC grid; writes one PNG figure.

    PYTHONPATH=src python examples/fluid_dam_break.py --out out/ [--method flip] [--cells 16]
        [--viscosity 0.01 --walls no-slip]     # honey-like (nu in m^2/s)

A water column a = 0.2 m wide and 2a high collapses in a 5a x 3a tank with slip walls
(the scene of Martin and Moyce 1952). Four snapshots show the particles coloured by speed and
the free surface (the zero contour of the particle level set, scikit-image); the last panel
plots the surge front Z = x / a against T = t sqrt(2 g / a) next to the experiment's points
(tests/fluids/grid/test_liquid.py checks them). With ``--viscosity`` the liquid is viscous
(implicit, traction-free surface; tests/fluids/grid/test_viscosity.py) and the front lags the
inviscid experiment.
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

G = 9.81
MARTIN_MOYCE = np.array([(0.832, 1.217), (0.849, 1.245), (1.212, 1.443), (1.219, 1.474),
                         (1.602, 1.884), (1.997, 2.292), (2.283, 2.689), (2.547, 2.995),
                         (2.950, 3.728)])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="out")
    ap.add_argument("--method", default="apic", choices=("apic", "flip", "pic"))
    ap.add_argument("--cells", type=int, default=16, help="cells across the column")
    ap.add_argument("--viscosity", type=float, default=0.0, help="kinematic viscosity, m^2/s")
    ap.add_argument("--walls", default="slip", choices=("slip", "no-slip"))
    a = ap.parse_args()
    col = 0.2
    h = col / a.cells
    f = LiquidFluid((5 * a.cells, 3 * a.cells), h, method=a.method, viscosity=a.viscosity,
                    walls=a.walls)
    f.add_block((0.0, 0.0), (col, 2 * col))
    scale = np.sqrt(2 * G / col)
    shots = [0.0, 1.0, 2.0, 3.0]
    fig, axes = plt.subplots(1, 5, figsize=(22, 3.6))
    front = []
    k = 0
    t0 = time.perf_counter()
    while True:
        T = f.time * scale
        if k < len(shots) and T >= shots[k] - 1e-9:
            ax = axes[k]
            speed = np.linalg.norm(f.velocities(), axis=1)
            ax.scatter(f.positions()[:, 0], f.positions()[:, 1], c=speed, s=1, cmap="viridis",
                       vmin=0, vmax=2.0)
            for line in f.surface_mesh():
                ax.plot(line[:, 0], line[:, 1], "k-", lw=0.8)
            ax.set_xlim(0, 5 * col)
            ax.set_ylim(0, 3 * col)
            ax.set_aspect("equal")
            ax.set_title(f"T = {T:.1f} ({a.method})")
            k += 1
        if T >= 3.0:
            break
        f.step(min(f.stable_dt(), 0.02 / scale))
        front.append((f.time * scale, f.x[:, 0].max() / col))
    front = np.array(front)
    label = f"{a.method}, {a.cells} cells across" + (f", nu = {a.viscosity:g}" if a.viscosity else "")
    axes[4].plot(front[:, 0], front[:, 1], label=label)
    axes[4].plot(MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1], "ko", label="Martin & Moyce (1952)")
    axes[4].set_xlabel("T = t sqrt(2g/a)")
    axes[4].set_ylabel("Z = front / a")
    axes[4].legend()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "fluid_dam_break.png"
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    print(f"{f.particle_count} particles, {f.step_index} steps in {time.perf_counter() - t0:.1f} s -> {path}")


if __name__ == "__main__":
    main()
