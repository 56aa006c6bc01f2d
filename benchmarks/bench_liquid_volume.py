"""Cost and effect of the liquid's volume stage (`LiquidFluid(volume_correction=)`).

    PYTHONPATH=src python benchmarks/bench_liquid_volume.py [--cells 32] [--frames 30] [--reps 2]

1. Cost: the 2-D dam break of Martin and Moyce (column a x 2a, a = 0.2 m, tank 5a x 3a, `--cells`
   cells across the column, 4 particles per cell), FLIP, 60 Hz frames of CFL substeps from rest:
   CPU time per step (`time.process_time`, so foreign load on a shared machine inflates it less
   than wall time) with the volume stage on (beta = 1, the default) and off (0), run alternately
   `--reps` times; the minimum of the reps is printed with the pressure iterations per solve.
2. Effect: the same scene at 16 cells across the column for 6 s (APIC and FLIP): liquid cells /
   initial, the mean particles per inner cell / 4 (rho / rho_0; inner: the four face neighbours
   hold particles) and the mean height of liquid cells per column against the height the volume
   gives (a 2a / 5a = 0.08 m).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from inertia.fluids.grid.liquid import LiquidFluid

A = 0.2


def dam_break(cells, method, beta):
    h = A / cells
    f = LiquidFluid((5 * cells, 3 * cells), h, method=method, volume_correction=beta)
    f.add_block((0.0, 0.0), (A, 2 * A))
    return f


def cost(cells, frames, beta):
    f = dam_break(cells, "flip", beta)
    f.advance(1 / 60)        # compile
    steps, its = 0, []
    c0 = time.process_time()
    for _ in range(frames):
        n = f.advance(1 / 60)
        steps += n
        its.append(f.last_pressure_iterations)
    return (time.process_time() - c0) / steps * 1e3, steps, float(np.mean(its)), f.particle_count


def effect(method, beta, seconds=6):
    cells = 16
    h = A / cells
    f = dam_break(cells, method, beta)
    f.step(1e-6)
    cells0 = int(f.liquid.sum())
    rows = []
    for _ in range(seconds):
        f.advance(1.0)
        nx, ny = f.liquid.shape[:2]
        cnt = np.zeros((nx, ny))
        idx = np.floor(f.x[:, :2] / h).astype(int)
        np.add.at(cnt, (np.clip(idx[:, 0], 0, nx - 1), np.clip(idx[:, 1], 0, ny - 1)), 1)
        liq = cnt > 0
        inner = liq.copy()
        inner[:, 1:] &= liq[:, :-1]
        inner[:, :-1] &= liq[:, 1:]
        inner[1:] &= liq[:-1]
        inner[:-1] &= liq[1:]
        rows.append((f.time, liq.sum() / cells0, cnt[inner].mean() / 4, liq.sum(axis=1).mean() * h))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=32)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--reps", type=int, default=2)
    a = ap.parse_args()
    print(f"== cost: FLIP dam break, {a.cells} cells across the column, {a.frames} frames ==")
    best = {}
    for _ in range(a.reps):
        for beta in (1.0, 0.0):
            ms, steps, its, n = cost(a.cells, a.frames, beta)
            best[beta] = min(best.get(beta, (np.inf,)), (ms, steps, its, n))
    for beta, (ms, steps, its, n) in best.items():
        print(f"  volume_correction={beta}: {ms:.2f} ms CPU per step ({steps} steps, {n} particles, "
              f"{its:.1f} pressure iterations per solve)")
    print(f"  cost of the volume stage: {best[1.0][0] / best[0.0][0] - 1:+.1%} per step")
    print("== effect: 16 cells across the column, 6 s (volume gives 0.0800 m) ==")
    for method in ("apic", "flip"):
        for beta in (0.0, 1.0):
            for t, cells, rho, level in effect(method, beta):
                if t > 2.5:
                    print(f"  {method} volume_correction={beta} t={t:.0f} s: liquid cells "
                          f"{cells:.3f} of initial, rho/rho_0 {rho:.3f}, level {level:.4f} m")


if __name__ == "__main__":
    main()
