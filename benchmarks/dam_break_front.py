"""The 20 000-particle 2-D dam break (``bench_sph.dam_break(2, 0.01)``: column a = 1 m wide, 2 m
tall, tank 4 x 4 m) run to T = t sqrt(2 g / a) = 3, its surge front against Martin & Moyce (1952)
with the bounds of ``tests/fluids/sph/test_fluid.py::test_dam_break_surge_front_...`` (front
speed dZ/dT over 1.2 <= T <= 3 within 10 %, front / experiment in (0.95, 1.25)), and ms per step.

Run:  PYTHONPATH=src python benchmarks/dam_break_front.py [--option key=value ...]
      (e.g. --option boundary_pressure=akinci; values parsed as Python literals)
Compare with main in the same run:
      for s in /work/main/src src; do PYTHONPATH=$s python benchmarks/dam_break_front.py; done
"""

import argparse
import ast
import json
import math
import time

import numpy as np

import inertia as ia
from inertia.fluids.sph import SPHFluid, sample_block

MARTIN_MOYCE = np.array([
    (0.832, 1.217), (0.849, 1.245), (1.212, 1.443), (1.219, 1.474), (1.602, 1.884), (1.997, 2.292),
    (2.283, 2.689), (2.547, 2.995), (2.950, 3.728)])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--option", action="append", default=[])
    ap.add_argument("--T", type=float, default=3.0)
    ap.add_argument("--dx", type=float, default=0.01)
    args = ap.parse_args()
    opts = {}
    for o in args.option:
        k, v = o.split("=", 1)
        try:
            opts[k] = ast.literal_eval(v)
        except (ValueError, SyntaxError):
            opts[k] = v
    dx, a = args.dx, 1.0
    x = sample_block((0.0, 0.0), (a, 2 * a), dx)
    fluid = SPHFluid(x, spacing=dx, domain=((0.0, 0.0), (4.0, 4.0)), viscosity=0.0, xsph=0.0,
                     density_tolerance=1e-3, **opts)
    fluid.add_boundary(ia.colliders.Container(center=(2.0, 2.0), half_extents=(2.0, 2.0)), slip=True)
    scale = math.sqrt(2 * 9.81 / a)
    fluid.step()  # compile
    t0 = time.perf_counter()
    steps0 = fluid.step_count
    hist = []
    its = np.zeros(2)   # DFSPH density, divergence iterations summed over the steps
    status = "ok"
    try:
        while fluid.time * scale < args.T:
            fluid.step()
            its += (fluid.stats["density_iterations"], fluid.stats["divergence_iterations"])
            hist.append((fluid.time * scale, (fluid.x[:, 0].max() + dx / 2) / a))
    except ia.errors.SimulationDiverged as e:
        status = f"diverged at T = {fluid.time * scale:.3f}: {str(e)[:200]}"
    wall = time.perf_counter() - t0
    steps = fluid.step_count - steps0
    hist = np.array(hist)
    out = dict(options=opts, status=status, steps=steps, ms_per_step=1e3 * wall / max(steps, 1), wall_s=wall,
               T_reached=fluid.time * scale, n=fluid.particle_count,
               unconverged=fluid.stats.get("unconverged_solves", 0),
               density_iterations_per_step=round(float(its[0]) / max(steps, 1), 2),
               divergence_iterations_per_step=round(float(its[1]) / max(steps, 1), 2))
    T, Z = MARTIN_MOYCE[:, 0], MARTIN_MOYCE[:, 1]
    if hist.size and hist[-1, 0] >= T[-1]:
        sim = np.interp(T, hist[:, 0], hist[:, 1])
        late = T >= 1.2
        out["front_ratio"] = np.round(sim / Z, 3).tolist()
        out["slope_ratio"] = round(float(np.polyfit(T[late], sim[late], 1)[0] / np.polyfit(T[late], Z[late], 1)[0]), 3)
        out["passes"] = bool(np.all(sim / Z < 1.25) and np.all(sim / Z > 0.95) and abs(out["slope_ratio"] - 1) < 0.1)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
