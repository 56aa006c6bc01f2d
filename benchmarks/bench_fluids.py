"""Grid fluids (inertia.fluids.grid) against the peers' stable-fluids and pressure references,
measured in the same run.

1. smoke256: the 256 x 256 plume of /work/shared/peers/bench_fluid_grid.py (unit square,
   h = 1/256, dt = 1/60, no viscosity, density += 100 dt and v += 20 dt in a 16 x 16-cell box at
   the bottom centre) stepped by the peers' NumPy and Numba stable-fluids references (float32,
   20 Jacobi iterations, collocated grid) and by GridFluid (float64, MAC grid, semi-Lagrangian
   RK2 or MacCormack, MGPCG). "Equal final divergence": the references' 20 Jacobi sweeps leave a
   relative divergence r_ref = ||div after|| / ||div before|| (measured here on their own grid
   after 30 steps); GridFluid is timed at tolerance = r_ref and at its default 1e-6.
2. pressure: MGPCG iterations and time per solve at 64^2 .. 1024^2 (closed box, rhs = the
   peers' bench_pressure.py make_rhs: divergence of a seeded random face field), next to the
   peers' own Numba MGPCG on the same right-hand side.
5. ghia: lid-driven cavity at Re 400 and 1000 on 64^2 and 128^2 against Ghia et al. (1982).
4. liquid: a 2-D FLIP (and APIC) dam break with 100,000 particles, ms per 60 Hz frame.
3. smoke3d: a 128^3 smoke step (buoyant plume from a source box, MacCormack and
   semi-Lagrangian, MGPCG 1e-4 and 1e-6): seconds per step. Aim: < 0.5 s on 2 cores.
   smoke128: the same scene (semi-Lagrangian, tol 1e-4) with the CPU time of each stage
   (time.process_time, load-independent up to cache sharing), serial and with the parallel
   kernels (wall time and CPU time), and the state hash after the timed steps.

Timings are medians of repeated steps after warm-up (JIT excluded); the foreign load (other
processes' CPU use) during each measurement is printed, since the machine may be shared.

Run: PYTHONPATH=src python benchmarks/bench_fluids.py [--parts smoke256 pressure smoke3d smoke128
     liquid ghia]
     [--sizes 64 128 256 512 1024] [--reps 5]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import numpy as np

PEERS = os.environ.get("INERTIA_PEERS", "/work/shared/peers")


def load_peer(name):
    """Import a peers' script (it imports the peers' own _common)."""
    if name in sys.modules:
        return sys.modules[name], sys.modules["_peer_common"]
    sys.path.insert(0, PEERS)
    saved = sys.modules.pop("_common", None)
    try:
        mod = importlib.import_module(name)
        sys.modules["_peer_common"] = sys.modules["_common"]
        return mod, sys.modules["_common"]
    finally:
        sys.path.remove(PEERS)
        if saved is not None:
            sys.modules["_common"] = saved


def median_time(fn, reps, warmup=2, load_cls=None):
    for _ in range(warmup):
        fn()
    samples = []
    foreign = float("nan")
    ctx = load_cls() if load_cls else None
    if ctx:
        ctx.__enter__()
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    if ctx:
        ctx.__exit__(None, None, None)
        foreign = ctx.foreign_cores
    return float(np.median(samples)), min(samples), foreign


# ----------------------------------------------------------------------------- 1. smoke 256
def ref_divergence_ratio(sim, n, steps=30):
    """Run `steps` reference steps, then one more split by hand: ||div|| after / before its
    projection, on the reference's own collocated grid."""
    fg = sys.modules["bench_fluid_grid"]
    for _ in range(steps):
        sim.step()
    si, sj = fg.source_slices(n)
    sim.d[si, sj] += np.float32(100.0 * fg.DT)
    sim.v[si, sj] += np.float32(20.0 * fg.DT)
    sim.advect(1, sim.u1, sim.u, sim.u, sim.v)
    sim.advect(2, sim.v1, sim.v, sim.u, sim.v)
    u, v = sim.u1.astype(np.float64), sim.v1.astype(np.float64)

    def div(u, v):
        return 0.5 * n * (u[2:, 1:-1] - u[:-2, 1:-1] + v[1:-1, 2:] - v[1:-1, :-2])

    before = np.linalg.norm(div(u, v))
    sim.project(sim.u1, sim.v1)
    after = np.linalg.norm(div(sim.u1.astype(np.float64), sim.v1.astype(np.float64)))
    return after / before


def our_plume(n, advection, tolerance, parallel=None):
    from inertia.fluids.grid import GridFluid
    fg = sys.modules["bench_fluid_grid"]
    h = 1.0 / n
    f = GridFluid((n, n), h, advection=advection, tolerance=tolerance, scalars=("density",),
                  parallel=parallel,
                  boundaries={s: "slip" for s in ("x-", "x+", "y-", "y+")})
    c = n // 2
    f.add_source(((c - 8) * h, 4 * h), ((c + 8) * h, 20 * h), density_rate=100.0,
                 acceleration=(0.0, 20.0))
    return f, fg.DT


def bench_smoke256(reps, load_cls):
    fg, _ = load_peer("bench_fluid_grid")
    n = 256
    print(f"\n== 1. smoke {n}^2, peers' plume scene (dt = 1/60) ==")
    ratios = {}
    rows = []
    for impl in ("numpy", "numba"):
        cls = fg.NumpyFluid if impl == "numpy" else fg.make_numba_fluid()
        sim = cls(n)
        sim.step()
        med, mn, load = median_time(sim.step, reps, load_cls=load_cls)
        ratios[impl] = ref_divergence_ratio(cls(n), n)
        rows.append((f"peer {impl} stable fluids (float32, 20 Jacobi)", med, mn, load,
                     f"||div|| after/before projection {ratios[impl]:.3f}"))
        print(f"  {rows[-1][0]:58s} {med*1e3:9.2f} ms/step (min {mn*1e3:.2f}) "
              f"[foreign {load:.2f}] {rows[-1][4]}", flush=True)
    r_ref = ratios["numba"]
    ref_numba = rows[1][1]
    ref_numpy = rows[0][1]
    for advection in ("semi-lagrangian", "maccormack"):
        for tol, par in ((r_ref, False), (r_ref, True), (1e-6, False), (1e-6, True)):
            f, dt = our_plume(n, advection, tol, par)
            for _ in range(30):
                f.step(dt)
            med, mn, load = median_time(lambda: f.step(dt), reps, load_cls=load_cls)
            it = f.last_pressure_iterations
            print(f"  GridFluid {advection:15s} {'2 threads' if par else 'serial   '} tol {tol:8.2e} ({it} it) "
                  f"{med*1e3:9.2f} ms/step (min {mn*1e3:.2f}) [foreign {load:.2f}]  "
                  f"x{med/ref_numba:.2f} of peer numba, x{med/ref_numpy:.3f} of peer numpy",
                  flush=True)


# ----------------------------------------------------------------------------- 2. pressure
def bench_pressure(sizes, reps, load_cls):
    from inertia.fluids.grid import PoissonSolver
    bp, _ = load_peer("bench_pressure")
    MG, _solve_mg, solve_mgpcg, _res = bp.make_mg()
    print("\n== 2. pressure Poisson, closed box, rhs = peers' make_rhs, rel. residual 1e-6 ==")
    for n in sizes:
        b = bp.make_rhs(n)
        solver = PoissonSolver((n, n, 1), (False, False, False), tolerance=1e-6)
        ones = [np.ones((n + 1, n, 1)), np.ones((n, n + 1, 1)), np.zeros((n, n, 2))]
        ones[0][0] = ones[0][-1] = 0.0
        ones[1][:, 0] = ones[1][:, -1] = 0.0
        solver.set_coefficients(*ones, 1.0 / n, 2)
        rhs = np.zeros((n, n, 1))
        phi = np.zeros((n, n, 1))

        def ours():
            rhs[:, :, 0] = b
            phi[...] = 0.0
            solver.solve(rhs, phi)

        ours()
        med, mn, load = median_time(ours, reps, warmup=1, load_cls=load_cls)
        it = solver.last_iterations
        mg = MG(n)
        solve_mgpcg(mg, b)
        box = {}

        def peer():
            box["r"] = solve_mgpcg(mg, b)

        pmed, pmn, pload = median_time(peer, reps, warmup=1, load_cls=load_cls)
        print(f"  {n:5d}^2: GridFluid MGPCG {it:2d} it, {med*1e3:9.2f} ms/solve (min {mn*1e3:.2f}) "
              f"[foreign {load:.2f}] | peer Numba MGPCG {box['r'][1]:2d} it, {pmed*1e3:9.2f} ms "
              f"[foreign {pload:.2f}] | ratio x{med/pmed:.2f}", flush=True)


# ----------------------------------------------------------------------------- 3. smoke 3d
def bench_smoke3d(reps, load_cls, n=128):
    from inertia.fluids.grid import GridFluid
    print(f"\n== 3. smoke {n}^3 (buoyant plume, closed box) ==")
    for advection, tol in (("semi-lagrangian", 1e-4), ("maccormack", 1e-4), ("maccormack", 1e-6)):
        h = 1.0 / n
        f = GridFluid((n, n, n), h, advection=advection, tolerance=tol, buoyancy=(0.1, 2.0),
                      boundaries={s: "slip" for s in ("x-", "x+", "y-", "y+", "z-", "z+")})
        f.add_source((0.4, 0.4, 0.05), (0.6, 0.6, 0.15), density_rate=10.0, temperature_rate=10.0)
        dt = 1.0 / 60.0
        for _ in range(3):
            f.step(dt)
        med, mn, load = median_time(lambda: f.step(dt), reps, warmup=0, load_cls=load_cls)
        print(f"  {advection:15s} tol {tol:.0e}: {med:7.3f} s/step (min {mn:.3f}) "
              f"[foreign {load:.2f}], MGPCG {f.last_pressure_iterations} it", flush=True)


def bench_smoke128(steps=3, n=128):
    """CPU seconds per stage of a 128^3 plume step (the smoke3d scene, semi-Lagrangian, tol 1e-4)."""
    from collections import defaultdict

    from inertia.fluids.grid import GridFluid
    print(f"\n== 3b. smoke {n}^3, CPU time per stage (semi-Lagrangian, tol 1e-4) ==")
    for parallel in (False, True):
        f = GridFluid((n, n, n), 1.0 / n, advection="semi-lagrangian", tolerance=1e-4,
                      buoyancy=(0.1, 2.0), parallel=parallel,
                      boundaries={s: "slip" for s in ("x-", "x+", "y-", "y+", "z-", "z+")})
        f.add_source((0.4, 0.4, 0.05), (0.6, 0.6, 0.15), density_rate=10.0, temperature_rate=10.0)
        acc = defaultdict(float)

        def timed(obj, name, key):
            fn = getattr(obj, name)

            def run(*a, **k):
                t0 = time.process_time()
                r = fn(*a, **k)
                acc[key] += time.process_time() - t0
                return r
            setattr(obj, name, run)
        for name in ("_advect", "_forces", "project", "_dissipate", "_enforce"):
            timed(f, name, name.strip("_"))
        timed(f.pressure, "_precondition", "  of which V-cycles")
        dt = 1.0 / 60.0
        for _ in range(3):
            f.step(dt)
        acc.clear()
        c0, w0 = time.process_time(), time.perf_counter()
        for _ in range(steps):
            f.step(dt)
        cpu = (time.process_time() - c0) / steps
        wall = (time.perf_counter() - w0) / steps
        print(f"  parallel={parallel}: CPU {cpu:.3f} s/step, wall {wall:.3f} s/step, "
              f"MGPCG {f.last_pressure_iterations} it, hash {f.state_hash()[:16]}", flush=True)
        for key, val in sorted(acc.items(), key=lambda kv: -kv[1]):
            print(f"    {key:20s} {val / steps:.3f} s CPU")


# ----------------------------------------------------------------------------- 4. liquid
def bench_liquid(reps, load_cls, particles=100_000):
    """2-D FLIP dam break (column a x 2a against the left wall of a 4a x 4a tank, the peers'
    SPH scene scaled to a = 1 m) with about `particles` particles (4 per cell): ms per 60 Hz
    frame (CFL-1 substeps) inside t = 0.1 .. 0.3 s, and the front position. Pressure:
    LiquidFluid's default MGPCG (before: Jacobi-PCG, ~750 iterations per solve at this size)."""
    from inertia.fluids.grid.liquid import LiquidFluid
    cells_a = int(round(np.sqrt(particles / 8)))  # a x 2a column at 4 particles per cell
    a = 1.0
    h = a / cells_a
    print(f"\n== 4. liquid: 2-D FLIP dam break, column {cells_a} x {2 * cells_a} cells, "
          f"tank {4 * cells_a}^2, h = {h:.4f} m ==")
    for method in ("flip", "apic"):
        f = LiquidFluid((4 * cells_a, 4 * cells_a), h, method=method)
        f.add_block((0.0, 0.0), (a, 2 * a))
        frame = 1.0 / 60.0
        t0 = time.perf_counter()
        f.advance(frame)  # JIT + first frame
        first = time.perf_counter() - t0
        while f.time < 0.1:
            f.advance(frame)
        samples = []
        subs = []
        iters = []
        ctx = load_cls() if load_cls else None
        if ctx:
            ctx.__enter__()
        while f.time < 0.3 - 1e-9:
            t0 = time.perf_counter()
            subs.append(f.advance(frame))
            samples.append(time.perf_counter() - t0)
            iters.append(f.last_pressure_iterations)
        load = float("nan")
        if ctx:
            ctx.__exit__(None, None, None)
            load = ctx.foreign_cores
        print(f"  {method}: {f.particle_count} particles, {np.median(samples)*1e3:8.1f} ms/frame "
              f"(min {min(samples)*1e3:.1f}, max {max(samples)*1e3:.1f}) [foreign {load:.2f}], "
              f"{np.mean(subs):.1f} substeps/frame, ~{np.mean(iters):.0f} {f.pressure_solver} it; "
              f"front at t = {f.time:.2f} s: {f.x[:, 0].max():.2f} m (Koshizuka & Oka 1.68 m at 0.3 s); "
              f"first frame incl. JIT {first:.1f} s", flush=True)
    # the pressure solvers from one saved state (same run): one step each, serial kernels
    from inertia.fluids.grid.liquid_pressure import LiquidPressure
    f = LiquidFluid((4 * cells_a, 4 * cells_a), h, method="flip", parallel=False)
    f.add_block((0.0, 0.0), (a, 2 * a))
    f.advance(1.0 / 60.0)
    state = f.save_state()
    solvers = {m: LiquidPressure(f.liquid.shape, method=m, tolerance=f.tolerance,
                                 max_iterations=f.max_iterations, parallel=False)
               for m in ("mgpcg", "jacobi")}
    times = {m: [] for m in solvers}
    for rep in range(3):   # the first round compiles the serial kernels
        for m, sol in solvers.items():
            f.restore_state(state)
            f._pressure = sol
            t0 = time.perf_counter()
            f.step(0.004)
            if rep:
                times[m].append(time.perf_counter() - t0)
    print("  same state, one step (serial kernels): " + ", ".join(
        f"{m} {np.median(t) * 1e3:.0f} ms ({solvers[m].last_iterations} it)" for m, t in times.items()),
        flush=True)


# ----------------------------------------------------------------------------- 5. Ghia
GHIA_Y = np.array([1.0, 0.9766, 0.9688, 0.9609, 0.9531, 0.8516, 0.7344, 0.6172, 0.5, 0.4531,
                   0.2813, 0.1719, 0.1016, 0.0703, 0.0625, 0.0547, 0.0])
GHIA_X = np.array([1.0, 0.9688, 0.9609, 0.9531, 0.9453, 0.9063, 0.8594, 0.8047, 0.5, 0.2344,
                   0.2266, 0.1563, 0.0938, 0.0781, 0.0703, 0.0625, 0.0])
# Ghia, Ghia and Shin (1982), J. Comput. Phys. 48, Tables I (u on x = 0.5) and II (v on y = 0.5)
GHIA = {
    400: ([1.0, 0.75837, 0.68439, 0.61756, 0.55892, 0.29093, 0.16256, 0.02135, -0.11477,
           -0.17119, -0.32726, -0.24299, -0.14612, -0.10338, -0.09266, -0.08186, 0.0],
          [0.0, -0.12146, -0.15663, -0.19254, -0.22847, -0.23827, -0.44993, -0.38598, 0.05186,
           0.30174, 0.30203, 0.28124, 0.22965, 0.20920, 0.19713, 0.18360, 0.0]),
    1000: ([1.0, 0.65928, 0.57492, 0.51117, 0.46604, 0.33304, 0.18719, 0.05702, -0.06080,
            -0.10648, -0.27805, -0.38289, -0.29730, -0.22220, -0.20196, -0.18109, 0.0],
           [0.0, -0.21388, -0.27669, -0.33714, -0.39188, -0.51550, -0.42665, -0.31966, 0.02526,
            0.32235, 0.33075, 0.37095, 0.32627, 0.30353, 0.29012, 0.27485, 0.0]),
}


def bench_ghia(sizes=(64, 128), t_end=40.0):
    """Lid-driven cavity at Re 400 and 1000 on finer grids than the tests: max centre-line
    errors against Ghia et al. (1982) (fraction of the lid speed) and wall time."""
    from inertia.fluids.grid import GridFluid, Wall
    print(f"\n== 5. lid-driven cavity vs Ghia et al. (1982), MacCormack, CFL 2, t = {t_end:.0f} ==")
    for re in (400, 1000):
        for n in sizes:
            t0 = time.perf_counter()
            f = GridFluid((n, n), 1.0 / n, boundaries={"y+": Wall(velocity=(1.0, 0.0))},
                          viscosity=1.0 / re, cfl=2.0, scalars=())
            for _ in range(int(t_end)):
                f.advance(1.0)
            u = f.sample_velocity(np.stack([np.full_like(GHIA_Y, 0.5), GHIA_Y], 1))[:, 0]
            v = f.sample_velocity(np.stack([GHIA_X, np.full_like(GHIA_X, 0.5)], 1))[:, 1]
            eu = np.max(np.abs(u - GHIA[re][0]))
            ev = np.max(np.abs(v - GHIA[re][1]))
            print(f"  Re {re:5d} {n:4d}^2: max |u - Ghia| {eu:.4f}, max |v - Ghia| {ev:.4f} "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--parts", nargs="+", default=["smoke256", "pressure", "smoke3d"])
    ap.add_argument("--sizes", nargs="+", type=int, default=[64, 128, 256, 512, 1024])
    ap.add_argument("--reps", type=int, default=5)
    a = ap.parse_args()
    import numba
    _, common = load_peer("bench_fluid_grid")
    common.header()
    print(f"numba {numba.__version__}, {numba.get_num_threads()} threads")
    load_cls = getattr(common, "Load", None)
    if "smoke256" in a.parts:
        bench_smoke256(a.reps, load_cls)
    if "pressure" in a.parts:
        bench_pressure(a.sizes, a.reps, load_cls)
    if "smoke3d" in a.parts:
        bench_smoke3d(max(2, a.reps // 2), load_cls)
    if "smoke128" in a.parts:
        bench_smoke128()
    if "liquid" in a.parts:
        bench_liquid(a.reps, load_cls)
    if "ghia" in a.parts:
        bench_ghia()


if __name__ == "__main__":
    main()
