"""SPH dam break benchmark: Inertia's DFSPH (and WCSPH) against the peers' scene and baselines.

Scene (the one of ``/work/shared/peers/bench_sph.py``, so the figures sit side by side): tank
[0, 4] x [0, 4] m, water column [0, 1] x [0, 2] m against the left wall, g = -9.81, rho0 = 1000.
  2D: spacing 0.01 m -> 100 x 200 = 20 000 fluid particles.
  3D: spacing 0.027 m, tank [0, 4] x [0, 4] x [0, 1.08] m (40 spacings deep, SPlisHSPlasH's box),
      the peers' SPlisHSPlasH block: 37 x 74 x 37 = 101 306 particles, a column 37 spacings
      (0.999 m) wide and deep and 74 (1.998 m) tall, centred in z (1.5 spacings of air to each
      side wall, as SPlisHSPlasH's block). Against the back wall and on the floor the lattice
      starts half a spacing from the wall (Inertia's rest distance, boundary particles on the
      same lattice); SPlisHSPlasH's block starts 2 spacings from its volume-map walls (its own
      rest distance is larger; with 1 spacing its column starts 30 % over-dense, peers' script). (Until 2026-11-27 the block filled the depth, 37 x 74 x 40 = 109 520, in
      a tank 2.2 m tall with a ceiling: particles squeezed up the back corners hit the ceiling
      at t ~ 0.14 s and were thrown sideways at 8-12 m/s, and those few set the CFL step for
      the rest of the window: 1.36 ms mean over t = 0.05-0.30 s against SPlisHSPlasH's 3.0 ms.)
Timing: like the peers, one sample = the steps that advance 0.01 s of simulated time inside
t = 0.05-0.30 s (2D, and 3D with ``--steps3d 0``); with ``--steps3d N`` > 0 the 3D case times N
steps after reaching t = 0.02 s (quicker, an indication only: the iteration count and the CFL
step vary along the surge), and "per simulated s" then uses their mean dt. Printed per case: ms per
step (median, min, max over samples), ms per simulated second, mean dt and DFSPH iterations,
the neighbour search's share (sort + neighbour lists), and the surge front at 0.1 / 0.2 / 0.3 s.

Settings (``--settings``): "default" runs Inertia's defaults on this scene (inviscid water,
slip walls, CFL 0.4, steps of at most 5 ms, mean density error 0.1 % in 2D and 0.05 % in 3D as
the peers' scenes, divergence 0.1 %); "matched" also gives the fluid SPlisHSPlasH's viscosity:
its scene's "standard" viscosity 0.01 (Viscosity_Standard: a_i = 2 (D + 2) nu sum_j (m_j / rho_j)
(v_ij . x_ij) / (|x_ij|^2 + 0.01 h^2) grad W_ij, fluid-fluid only, walls slip) is Inertia's laminar
term with rho_j in place of (rho_i + rho_j) / 2, but Inertia divides nu by the lattice's shear
response (``fluid.lattice_shear_response``, 0.75 in 2D and 0.81 in 3D at h = dx), so the same
operator is ``viscosity = 0.01 * lattice_shear_response``. Both use the same CFL rule:
SPlisHSPlasH's dt = cflFactor 0.4 (2 r) / max|v + a dt_prev| (Simulation::updateTimeStepSizeCFL,
cflMethod 1, 2 r = spacing, a = gravity + viscosity) is Inertia's ``cfl`` 0.4 x spacing /
(v_max + |g| dt).

Peers in the same run: the Numba WCSPH reference of the peers' script (imported from
``/work/shared/peers/bench_sph.py``, run in this process with the same window; 2D only), and
SPlisHSPlasH (``pip install pysplishsplash``) and PySPH (``pip install pysph``, builds from source)
through the peers' script's ``--worker`` subprocesses (their own window t = 0.05-0.30 s), when they
are installed; a peer that is missing or fails is reported and skipped. (On the project's
machine, 2026-11-23: ``pip install pysplishsplash`` installs the 2.19.0 wheel; ``pip install pysph``
builds from source and did not finish within a 400 s timeout under load.) Their figures from
``BASELINES.md`` (same kind of 2-core machine, measured separately) are printed too, marked as such.

Same rules on both sides (docs/fluids-sph.md, "Speed"): CFL 0.4 spacing per step at the
largest speed (SPlisHSPlasH cflFactor 1), steps of at most 5 ms, mean density error 0.1 % (2D) /
0.05 % (3D), divergence 0.1 %. With ``--settings default`` the step counts still differ:
SPlisHSPlasH's scene carries its viscosity 0.01, which slows the surge and lengthens its CFL
steps; Inertia's water is inviscid. ``--settings matched`` gives Inertia the same viscosity.
Under load, parallel regions of both (Numba's OpenMP layer, SPlisHSPlasH's OpenMP) wait for
descheduled threads: alternate the cases (``--cases dfsph:2d splishsplash:2d dfsph:2d ...``), or
compare one thread each (``NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1``), and re-measure idle.

Scaling: a 2D block 100 spacings tall (dx = 0.01) and 10^4, 10^5 (10^6 with ``--million``)
particles wide: ms per step and ns per particle and solver pass over ``--scale-steps`` steps
after 5 warm-up steps.

Run:  PYTHONPATH=src python benchmarks/bench_sph.py [--cases dfsph:2d numba:2d splishsplash:2d dfsph:3d
          splishsplash:3d pysph:2d scaling] [--steps3d 10] [--settings default|matched] [--million]
          [--t-stop 0.3]
      (defaults: all cases, about 10 min on 2 cores; --million adds the 10^6 scaling point)
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

import inertia as ia
from inertia.fluids.sph import SPHFluid, sample_block
from inertia.fluids.sph.fluid import lattice_shear_response

PEERS = "/work/shared/peers"
T_WARM, T_STOP, SAMPLE_DT = 0.05, 0.30, 0.01
BASELINES = {  # /work/shared/peers/BASELINES.md, "SPH dam break" rows (median ms per step, s per simulated s)
    "2d": [("SPlisHSPlasH 2.19 DFSPH (float32)", 32.6, 28.0), ("PySPH 1.0b2 WCSPH", 17.6, 291.0),
           ("Numba WCSPH reference", 5.41, 104.0)],
    "3d": [("SPlisHSPlasH 2.19 DFSPH (float32, 101 306)", 427.0, 133.0), ("PySPH 1.0b2 WCSPH", 561.0, 3400.0)],
}


SPLISHSPLASH_VISCOSITY = 0.01   # its shipped dam-break scenes' "standard" viscosity (peers' bench_sph.py)
SETTINGS = ("default", "matched")


def dam_break(dim, dx, method="dfsph", settings="default"):
    """The peers' dam break (see the module docstring) as an SPHFluid; settings "default"
    (inviscid) or "matched" (SPlisHSPlasH's viscosity operator, see the module docstring)."""
    if settings not in SETTINGS:
        raise ValueError(f"settings must be one of {SETTINGS}; got {settings!r}")
    if dim == 2:
        x = sample_block((0.0, 0.0), (1.0, 2.0), dx)
        lo, hi = (0.0, 0.0), (4.0, 4.0)
    else:
        depth = 40 * dx
        x = sample_block((0.0, 0.0, 1.5 * dx), (37 * dx, 74 * dx, 38.5 * dx), dx)   # 37 x 74 x 37
        lo, hi = (0.0, 0.0, 0.0), (4.0, 4.0, depth)
    nu = 0.0
    if settings == "matched":
        nu = SPLISHSPLASH_VISCOSITY * lattice_shear_response("cubic_spline", dim, dx, dx)
    fluid = SPHFluid(x, spacing=dx, domain=(lo, hi), method=method, viscosity=nu, xsph=0.0,
                     density_tolerance=1e-3 if dim == 2 else 5e-4, cfl=0.4, dt_max=0.005,
                     divergence_tolerance=1e-3)
    centre = 0.5 * (np.array(lo) + np.array(hi))
    fluid.add_boundary(ia.colliders.Container(center=centre, half_extents=0.5 * (np.array(hi) - np.array(lo))),
                       slip=True)
    return fluid


def run_inertia(dim, dx, steps3d, settings="default"):
    fluid = dam_break(dim, dx, settings=settings)
    t0 = time.perf_counter()
    fluid.step()
    first = time.perf_counter() - t0
    fronts, samples, iters, dts = [], [], [], []
    checks = [0.1, 0.2, 0.3]
    start_profile = None
    if dim == 2 or steps3d <= 0:
        while fluid.time < T_WARM:
            fluid.step()
        start_profile = dict(fluid.profile)
        window_start, sample_start, sample_steps = time.perf_counter(), time.perf_counter(), 0
        boundary = T_WARM + SAMPLE_DT
        while fluid.time < T_STOP - 1e-12:
            fluid.step()
            sample_steps += 1
            iters.append(fluid.stats["density_iterations"] + fluid.stats["divergence_iterations"])
            dts.append(fluid.last_dt)
            if checks and fluid.time >= checks[0]:
                checks.pop(0)
                fronts.append(fluid.x[:, 0].max())
            if fluid.time >= boundary - 1e-12:
                now = time.perf_counter()
                samples.append((now - sample_start) / sample_steps)
                sample_start, sample_steps, boundary = now, 0, boundary + SAMPLE_DT
        wall = time.perf_counter() - window_start
        sim_t = sum(dts)
    else:
        while fluid.time < 0.02:
            fluid.step()
        start_profile = dict(fluid.profile)
        window_start = time.perf_counter()
        for _ in range(steps3d):
            s0 = time.perf_counter()
            fluid.step()
            samples.append(time.perf_counter() - s0)
            iters.append(fluid.stats["density_iterations"] + fluid.stats["divergence_iterations"])
            dts.append(fluid.last_dt)
        wall = time.perf_counter() - window_start
        sim_t = sum(dts)
    spent = {k: fluid.profile[k] - start_profile.get(k, 0.0) for k in fluid.profile}
    total = sum(spent.values())
    share = (spent.get("sort", 0.0) + spent.get("neighbours", 0.0)) / total
    return dict(n=fluid.particle_count, per_step=samples, wall=wall, sim_t=sim_t, dt=float(np.mean(dts)),
                iters=float(np.mean(iters)), share=share, fronts=fronts, first=first,
                stages={k: v / total for k, v in spent.items()}, nb=fluid.boundary_x.shape[0],
                unconverged=fluid.stats.get("unconverged_solves", 0), steps=fluid.step_count)


def run_numba_peer():
    sys.path.insert(0, PEERS)
    import bench_sph as peer  # noqa: E402  (the peers' script, imported, not copied)
    return peer.run_numba(2)


def run_peer_worker(case, timeout):
    """One case of the peers' script (``--worker``: its own subprocess, its own timing window);
    returns its RESULT dict or raises RuntimeError (not installed, crashed, timed out)."""
    import json
    import subprocess
    try:
        p = subprocess.run([sys.executable, os.path.join(PEERS, "bench_sph.py"), "--worker", case],
                           capture_output=True, text=True, timeout=timeout, cwd=PEERS)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"timed out after {timeout} s") from None
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    if p.returncode != 0 or not lines:
        raise RuntimeError("exit code %d: %s" % (p.returncode, " | ".join((p.stdout + p.stderr).splitlines()[-3:])))
    return json.loads(lines[-1][7:])


def report_inertia(name, r, dim):
    ps = r["per_step"]
    med = float(np.median(ps))
    per_sim_s = r["wall"] / r["sim_t"]
    print(f"{name:12s} {r['n']:7d} fluid + {r['nb']} boundary particles: per step median {med * 1e3:8.2f} ms "
          f"(min {min(ps) * 1e3:.2f}, max {max(ps) * 1e3:.2f}); dt mean {r['dt'] * 1e3:.3f} ms; "
          f"{r['iters']:.1f} pressure iterations/step")
    print(f"{'':12s} {per_sim_s:8.1f} s per simulated s; neighbour search (sort + lists) {100 * r['share']:.0f} % "
          f"of the step; stages " + ", ".join(f"{k} {100 * v:.0f} %" for k, v in r["stages"].items()))
    if r["fronts"]:
        print(f"{'':12s} front x(0.1, 0.2, 0.3 s) = " + ", ".join(f"{f:.3f}" for f in r["fronts"]) +
              " m (Koshizuka & Oka: 1.13, 1.33, 1.68)")
    print(f"{'':12s} setup + first step (JIT) {r['first']:.1f} s; {r['steps']} steps in all, "
          f"{r['unconverged']} density solves stopped at max_iterations (each halves the next steps)")
    for peer, ms, s_per_s in BASELINES[f"{dim}d"]:
        print(f"{'':12s} vs {peer} [BASELINES.md, not this run]: per step x{ms / (med * 1e3):.2f}, "
              f"per simulated s x{s_per_s / per_sim_s:.2f} (>1 = Inertia faster)")
    return med, per_sim_s


def scaling(million, steps):
    # A block 100 spacings tall (dx = 0.01 m) and N / 100 wide in a tank 1 m longer: the cost per
    # particle and solver pass at 10^4, 10^5 (10^6) particles with the same column height, so the
    # iteration count stays comparable. (The dam-break column itself at 10^5 / 10^6 particles is
    # 447 / 1414 rows tall: its start from rest runs away at step ~9, the relaxed-Jacobi
    # limitation recorded in docs/fluids-sph.md.)
    dx, rows_h = 0.01, 100
    targets = [10_000, 100_000] + ([1_000_000] if million else [])
    rows = []
    for target in targets:
        width = target // rows_h * dx
        x = sample_block((0.0, 0.0), (width, rows_h * dx), dx)
        lo, hi = np.array([0.0, 0.0]), np.array([width + 1.0, rows_h * dx + 0.5])
        fluid = SPHFluid(x, spacing=dx, domain=(lo, hi), viscosity=0.0, xsph=0.0)
        fluid.add_boundary(ia.colliders.Container(center=0.5 * (lo + hi), half_extents=0.5 * (hi - lo)), slip=True)
        for _ in range(5):
            fluid.step()
        t0 = time.perf_counter()
        its = 0
        for _ in range(steps):
            fluid.step()
            its += fluid.stats["density_iterations"] + fluid.stats["divergence_iterations"] + 2
        wall = time.perf_counter() - t0
        per, per_it = wall / steps, wall / its
        rows.append((fluid.particle_count, per_it))
        print(f"scaling      {fluid.particle_count:8d} particles: {per * 1e3:9.2f} ms per step, {its / steps:.0f} "
              f"solver passes per step, {per_it * 1e3:.3f} ms per pass = "
              f"{per_it / fluid.particle_count * 1e9:6.1f} ns per particle-pass", flush=True)
    for (n0, t0), (n1, t1) in zip(rows, rows[1:]):
        print(f"scaling      x{n1 / n0:.1f} particles -> x{t1 / t0:.2f} time per solver pass "
              f"(exponent {math.log(t1 / t0) / math.log(n1 / n0):.2f}; 1 = linear; the iteration count per step "
              f"depends on the column height in particles, so per-pass cost is what scales)")


def main():
    global T_STOP
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["dfsph:2d", "numba:2d", "splishsplash:2d", "dfsph:3d",
                                                   "splishsplash:3d", "pysph:2d", "scaling"])
    ap.add_argument("--steps3d", type=int, default=10, help="3D: steps timed after t = 0.02 s; 0 = the peers' "
                    "window t = 0.05-0.30 s")
    ap.add_argument("--settings", choices=SETTINGS, default="default",
                    help="Inertia's defaults, or SPlisHSPlasH's viscosity as well (see the module docstring)")
    ap.add_argument("--scale-steps", type=int, default=10)
    ap.add_argument("--million", action="store_true")
    ap.add_argument("--peer-timeout", type=float, default=600.0, help="seconds per peer subprocess")
    ap.add_argument("--t-stop", type=float, default=T_STOP, help="end of the 2D timing window (s); 0.30 = the peers'")
    a = ap.parse_args()
    T_STOP = a.t_stop
    import numba
    print(f"numba {numba.__version__}, {numba.get_num_threads()} threads, {os.cpu_count()} cpus; Inertia settings "
          f"{a.settings!r}; load average {os.getloadavg()[0]:.1f}")
    ours = ours3 = None
    for case in a.cases:
        if case in ("dfsph:2d", "dfsph:3d"):
            dim = int(case[-2])
            try:
                r = run_inertia(dim, 0.01 if dim == 2 else 0.027, a.steps3d, a.settings)
            except ia.errors.SimulationDiverged as e:
                print(f"inertia {dim}D  diverged: {e}")
                continue
            if dim == 2:
                ours = report_inertia("inertia 2D", r, 2)
            else:
                ours3 = report_inertia("inertia 3D", r, 3)
        elif case == "numba:2d":
            try:
                r = run_numba_peer()
            except Exception as e:  # noqa: BLE001  (report and go on)
                print(f"numba:2d peer failed: {e}")
                continue
            med = float(np.median(r["per_step"]))
            per_sim_s = r["wall"] / r["sim_t"]
            print(f"numba WCSPH  {r['n']:7d} fluid particles (peers' reference, this run): per step median "
                  f"{med * 1e3:.2f} ms, dt {r['dt_mean'] * 1e3:.4f} ms, {per_sim_s:.1f} s per simulated s; fronts "
                  + ", ".join(f"{x:.3f}" for _, _, x in r["fronts"]))
            if ours:
                print(f"{'':12s} inertia DFSPH vs numba WCSPH (same run): per step x{med / ours[0]:.2f}, "
                      f"per simulated s x{per_sim_s / ours[1]:.2f} (>1 = Inertia faster)")
        elif case.startswith(("splishsplash:", "pysph:")):
            try:
                r = run_peer_worker(case, a.peer_timeout)
            except RuntimeError as e:
                print(f"{case:12s} peer not run: {e}")
                continue
            med = float(np.median(r["per_step"]))
            per_sim_s = r["wall"] / r["sim_t"]
            print(f"{case:12s} {r['n']:7d} fluid particles (peer, this run, window t = 0.05-0.30 s): per step median "
                  f"{med * 1e3:.2f} ms, dt {r['dt_mean'] * 1e3:.3f} ms, {per_sim_s:.1f} s per simulated s; "
                  f"{r.get('version', '')}")
            mine = ours if case.endswith("2d") else ours3
            if mine:
                print(f"{'':12s} inertia vs {case} (same run): per step x{med / mine[0]:.2f}, per simulated s "
                      f"x{per_sim_s / mine[1]:.2f} (>1 = Inertia faster)")
        elif case == "scaling":
            try:
                scaling(a.million, a.scale_steps)
            except ia.errors.SimulationDiverged as e:
                print(f"scaling      diverged: {e}")
        else:
            raise SystemExit(f"unknown case {case!r}")


if __name__ == "__main__":
    main()
