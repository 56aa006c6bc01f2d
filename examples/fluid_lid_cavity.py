"""Lid-driven cavity at Re = 100, 400 and 1000 against Ghia, Ghia and Shin (1982); writes one figure.

    PYTHONPATH=src python examples/fluid_lid_cavity.py --out out/ [--cells 48] [--seconds 40]

A unit square of fluid whose top wall slides at 1 m/s (viscosity 1/Re, no-slip walls), solved on
an n x n MAC grid (MacCormack advection, MGPCG projection, CFL 2) to a steady state. The figure
has one column per Reynolds number: on top u along the vertical centre line x = 0.5, below v along
the horizontal centre line y = 0.5, the grid's profile as a line and Ghia et al.'s 129 x 129
multigrid solution (their Tables I and II) as dots; each panel's title gives the largest error in
units of the lid speed. Measured on 48^2 (``--cells 48``, 4 min on a busy 2-core machine): Re 100
0.008 (u) / 0.005 (v), Re 400 0.063 / 0.076, Re 1000 0.120 / 0.142: the coarse grid cuts the
Re = 1000 peaks, whose wall layers are a few cells thick.

Reference: U. Ghia, K. N. Ghia and C. T. Shin, "High-Re solutions for incompressible flow using
the Navier-Stokes equations and a multigrid method", J. Comput. Phys. 48 (1982) 387-411.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from inertia.fluids.grid import GridFluid, Wall

# Ghia, Ghia and Shin (1982): stations of Table I (y on x = 0.5) and Table II (x on y = 0.5).
GHIA_Y = np.array([1.0, 0.9766, 0.9688, 0.9609, 0.9531, 0.8516, 0.7344, 0.6172, 0.5, 0.4531,
                   0.2813, 0.1719, 0.1016, 0.0703, 0.0625, 0.0547, 0.0])
GHIA_X = np.array([1.0, 0.9688, 0.9609, 0.9531, 0.9453, 0.9063, 0.8594, 0.8047, 0.5, 0.2344,
                   0.2266, 0.1563, 0.0938, 0.0781, 0.0703, 0.0625, 0.0])
# Re: (u at GHIA_Y, Table I; v at GHIA_X, Table II)
GHIA = {
    100: ([1.0, 0.84123, 0.78871, 0.73722, 0.68717, 0.23151, 0.00332, -0.13641, -0.20581, -0.21090,
           -0.15662, -0.10150, -0.06434, -0.04775, -0.04192, -0.03717, 0.0],
          [0.0, -0.05906, -0.07391, -0.08864, -0.10313, -0.16914, -0.22445, -0.24533, 0.05454, 0.17527,
           0.17507, 0.16077, 0.12317, 0.10890, 0.10091, 0.09233, 0.0]),
    400: ([1.0, 0.75837, 0.68439, 0.61756, 0.55892, 0.29093, 0.16256, 0.02135, -0.11477, -0.17119,
           -0.32726, -0.24299, -0.14612, -0.10338, -0.09266, -0.08186, 0.0],
          [0.0, -0.12146, -0.15663, -0.19254, -0.22847, -0.23827, -0.44993, -0.38598, 0.05186, 0.30174,
           0.30203, 0.28124, 0.22965, 0.20920, 0.19713, 0.18360, 0.0]),
    1000: ([1.0, 0.65928, 0.57492, 0.51117, 0.46604, 0.33304, 0.18719, 0.05702, -0.06080, -0.10648,
            -0.27805, -0.38289, -0.29730, -0.22220, -0.20196, -0.18109, 0.0],
           [0.0, -0.21388, -0.27669, -0.33714, -0.39188, -0.51550, -0.42665, -0.31966, 0.02526, 0.32235,
            0.33075, 0.37095, 0.32627, 0.30353, 0.29012, 0.27485, 0.0]),
}


def solve(re: float, n: int, seconds: float) -> GridFluid:
    """The cavity at Reynolds number ``re`` on n x n cells, advanced ``seconds`` (lid speed 1 m/s)."""
    fluid = GridFluid((n, n), 1.0 / n, boundaries={"y+": Wall(velocity=(1.0, 0.0))},
                      viscosity=1.0 / re, cfl=2.0, scalars=())
    for _ in range(int(round(seconds))):
        fluid.advance(1.0)
    return fluid


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--cells", type=int, default=48, help="cells per side (48 default; 32 for a quick look, 96+ for Re 1000)")
    ap.add_argument("--seconds", type=float, default=40.0, help="simulated seconds (steady by ~30 s at Re 1000)")
    a = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(12, 7.2), constrained_layout=True)
    line = np.linspace(0.0, 1.0, 201)
    for col, re in enumerate((100, 400, 1000)):
        t0 = time.perf_counter()
        fluid = solve(re, a.cells, a.seconds if re > 100 else min(a.seconds, 15.0))
        u = fluid.sample_velocity(np.stack([np.full_like(line, 0.5), line], axis=1))[:, 0]
        v = fluid.sample_velocity(np.stack([line, np.full_like(line, 0.5)], axis=1))[:, 1]
        u_at = fluid.sample_velocity(np.stack([np.full_like(GHIA_Y, 0.5), GHIA_Y], axis=1))[:, 0]
        v_at = fluid.sample_velocity(np.stack([GHIA_X, np.full_like(GHIA_X, 0.5)], axis=1))[:, 1]
        eu = float(np.max(np.abs(u_at - GHIA[re][0])))
        ev = float(np.max(np.abs(v_at - GHIA[re][1])))
        print(f"Re {re:5d} on {a.cells}^2: max |u - Ghia| {eu:.3f}, max |v - Ghia| {ev:.3f} of the lid speed "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)

        top, bottom = axes[0, col], axes[1, col]
        top.plot(u, line, color="#1f77b4", lw=1.8, label=f"Inertia, {a.cells}$^2$ MAC grid")
        top.plot(GHIA[re][0], GHIA_Y, "o", color="#d62728", ms=4.5, label="Ghia et al. 1982 (129$^2$)")
        top.set(xlabel="u / U (x = 0.5)", ylabel="y", title=f"Re = {re}: u on the vertical centre line\n"
                f"max error {eu:.3f} U", xlim=(-0.6, 1.05), ylim=(0, 1))
        bottom.plot(line, v, color="#1f77b4", lw=1.8, label=f"Inertia, {a.cells}$^2$ MAC grid")
        bottom.plot(GHIA_X, GHIA[re][1], "o", color="#d62728", ms=4.5, label="Ghia et al. 1982 (129$^2$)")
        bottom.set(xlabel="x", ylabel="v / U (y = 0.5)", title=f"Re = {re}: v on the horizontal centre line\n"
                   f"max error {ev:.3f} U", xlim=(0, 1), ylim=(-0.6, 0.45))
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
            ax.axhline(0, color="0.6", lw=0.6) if ax is bottom else ax.axvline(0, color="0.6", lw=0.6)
    axes[0, 0].legend(loc="lower right", fontsize=8)
    fig.suptitle("Lid-driven cavity: centre-line velocity against Ghia, Ghia and Shin (1982)")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "fluid_lid_cavity.png"
    fig.savefig(path, dpi=110)
    print(f"-> {path}")


if __name__ == "__main__":
    main()
