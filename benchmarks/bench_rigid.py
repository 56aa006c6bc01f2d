"""Rigid bodies: Inertia's RigidWorld vs PyBullet and MuJoCo (CG solver) on the peers' 3D scenes.

Scenes (parameters from ../shared/peers/bench_3d_rigid.py, whose scene code is imported when found):
- pile: N boxes (0.2 m) or spheres (r 0.1 m), density 1000, dropped from a jittered 10 x 10 x 10 grid
  (pitch 0.3 m, lowest layer at 0.5 m, random box orientations, seed 0) onto a plane; 3 s simulated.
- stack: 10 boxes of 0.2 m exactly stacked; 10 s simulated (the 60 s claim: ``--stack-seconds 60``).
- pyramid: 20-base box pyramid, 30 s (``--pyramid``).

Reported for Inertia: ms of wall time per simulated second (whole run, and the last second), contact
manifolds, deepest penetration, bodies asleep at the end, and the per-stage times from
``world.profile``. The peers run in the same process at their own defaults (PyBullet dt 1/240,
50 iterations; MuJoCo dt 0.002 with the CG solver), so the ratio "peer ms per simulated second /
Inertia ms per simulated second" compares equal simulated time, not equal steps.

Rest: after the 3 s window Inertia's pile runs on until every body sleeps (at most 15 s), and the
deepest contact penetration of the last second before that is the resting pile's penetration. The
peers' penetration is read from the lowest body centre at 3 s (their script's measure), which Inertia
also prints.

Run (about 3-5 minutes with both peers installed; peers: ``pip install pybullet mujoco``, bench only):
    PYTHONPATH=src python benchmarks/bench_rigid.py [--n 1000] [--shapes box sphere] [--engines inertia pybullet mujoco] [--pyramid] [--substeps 8]

Measured 2026-11-23 (2 vCPU shared with other jobs, load ~4; pybullet 3.2.7, mujoco CG), default command:
    1000 boxes:   inertia 1630 ms per simulated s (27.2 ms per 1/60 s frame; solve 15.5, narrow 9.4, broad 2.0),
                  all asleep at 6.5 s, 2.74 mm deepest at rest, lowest centre 0.89 mm into the floor;
                  PyBullet 11 318 (x6.95, 4.25 mm), MuJoCo CG 17 003 (x10.4, 8.96 mm)
    1000 spheres: inertia 685 ms per simulated s (11.4 ms per frame: real time); PyBullet 3 511 (x5.1),
                  MuJoCo CG 4 016 (x5.9); only 385 / 1000 asleep at 15 s (no rolling resistance: spheres roll on)
    10-box stack: inertia 33.6 ms per simulated s, top box 0.51 mm after settling; PyBullet 61.6 (x1.8), MuJoCo 56.7 (x1.7)
    --substeps 4: 1000 boxes in 14.4 ms per frame (real time), asleep at 7.1 s, but 5.46 mm deepest at rest and
                  the stack drifts 17 mm: 8 substeps is the default

Measured 2026-11-25 (rigid-perf; load 11-20 on the 2 vCPUs, so only ratios of runs made side by side mean
anything; the pile of inertia_pile, 0-3 s window, ms per 1/60 s frame, serial path):
    HEAD vs now, 8 substeps:  frame 636 -> 557, solve 422 -> 332 (-21 %: the substep loop is one compiled
                  call on the serial path), narrow 166 -> 172 (scratch instead of per-pair arrays: no
                  measurable change), toi stage 3.6 (1 %); pile bit-identical (asleep 6.53 s, 2.74 mm)
    HEAD vs now, 4 substeps:  frame 370 -> 338, solve 198 -> 148 (-25 %); 5.46 mm at rest (unchanged)
    4 substeps, --damping-ratio 5: 3.47 mm deepest at rest (< 5 mm), all asleep at 11.3 s; solve ~0.5x and
                  frame ~0.55x of the 8-substep default measured alongside: at the 27.2 ms idle frame of
                  2026-11-23 that is ~14-15 ms per frame (real time), to be re-measured idle with
                  PYTHONPATH=src python benchmarks/bench_rigid.py --engines inertia --shapes box --substeps 4 --damping-ratio 5
    100-sphere pile (tests/rigid/test_world.py): the default rolling resistance C_rr = 0.002 decelerates the
                  fastest ball by 0.070 m/s per 5 s (C_rr g / 1.4 = 0.0140 m/s^2); all asleep at 85 s, none
                  of the rolling balls ever sleeps without it

Measured 2026-11-25 (rigid-realtime; load 11-15 on the 2 vCPUs, main tree and this one side by side):
    CPU time per stage (thread time, NUMBA_NUM_THREADS=1, serial path, min of two 0-3 s windows; script in
    the report: the pile of inertia_pile, timed with time.thread_time instead of perf_counter):
                  frame 21.80 -> 17.68 and 22.75 -> 17.85 ms (-19 %, -22 %); narrow 7.70 -> 4.17 and
                  7.81 -> 4.22 (the bundles unpacked once per run of pairs, a 4-array ManifoldOut per pair
                  call); solve 12.17 -> 11.61, 12.80 -> 11.66 (per-body integrate helpers inlined; in
                  isolation substeps_serial x0.80-0.96 on three snapshots); pile bit-identical (same hash,
                  asleep 6.53 s, 2.74 mm at rest, 0.89 mm lowest centre), stack 0.508 mm.
                  At the idle 17.5-19.75 ms frame of the issue (narrow 7.5 ms) that is ~14-16 ms: real time,
                  to be re-measured idle with the default command.
    Wall time, default command, near idle (load ~3), this tree / main / this tree / main at 19:07 UTC:
                  16.35, 18.31, 15.09, 19.24 ms per 1/60 s frame (this tree under 16.7 ms: real time; -11 %
                  and -22 % against the main run after each); narrow 4.37, 7.46, 4.11, 7.90; solve 10.03,
                  8.99, 9.11, 9.41 (noise); pile and stack figures identical to main's.
    Wall time, default command, load 14, main then this tree (before the solver inlining): 299.1 -> 253.3 and
                  186.3 -> 157.3 ms per step (x0.85, x0.84); narrow 91.5 -> 51.3, 56.4 -> 34.9.
    Cold compile, box + sphere on a plane, 60 steps, empty NUMBA_CACHE_DIR: 140.9 -> 55.7 s CPU (the
                  narrow phase's pair families are separate kernels and a box-and-sphere scene never
                  compiles GJK/EPA or the triangle routines; one specialisation of the box clipper and of
                  the solve block instead of one per literal True / False argument).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

PEERS = os.environ.get("INERTIA_PEERS", "/work/shared/peers")
EDGE, RAD, DENS, PITCH = 0.2, 0.1, 1000.0, 0.3


def grid_positions(n, seed=0):
    """The peers' jittered grid (same RNG stream), so all engines drop the same pile."""
    if os.path.isdir(PEERS):
        sys.path.insert(0, PEERS)
        try:
            from bench_3d_rigid import grid_positions as peer_grid
            return peer_grid(n, seed)
        except ImportError:
            pass
    nx = 10 if n == 1000 else int(math.ceil(math.sqrt(n / 4)))
    layers = int(math.ceil(n / (nx * nx)))
    rng = np.random.default_rng(seed)
    pos = []
    for k in range(layers):
        for i in range(nx):
            for j in range(nx):
                if len(pos) < n:
                    pos.append(((i - (nx - 1) / 2) * PITCH + rng.uniform(-0.02, 0.02),
                                (j - (nx - 1) / 2) * PITCH + rng.uniform(-0.02, 0.02), 0.5 + k * PITCH))
    q = rng.normal(size=(n, 4))
    return np.array(pos), q / np.linalg.norm(q, axis=1, keepdims=True)


def inertia_pile(n, shape, *, substeps, parallel, seconds=3.0, rest_cap=15.0, damping_ratio=10.0):
    """The peers' 3 s window, timed step by step; then on until every body sleeps (at most rest_cap s),
    also timed. Returns the world, per-step times of the window, the lowest body centre at its end,
    and the rest phase's figures."""
    from inertia.model import ModelBuilder
    from inertia.rigid.world import RigidWorld
    pos, quat = grid_positions(n)
    b = ModelBuilder()
    b.add_plane()
    for p, q in zip(pos, quat):
        if shape == "box":
            b.add_box(b.add_body(position=p, orientation=q), (EDGE / 2,) * 3, density=DENS)
        else:
            b.add_sphere(b.add_body(position=p), RAD, density=DENS)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")            # the peers' grid starts with overlapping boxes
        world = RigidWorld(b.finalize(), substeps=substeps, parallel=parallel, contact_damping_ratio=damping_ratio)
        world.step()                               # compile / load the cache outside the timing
    world.profile = {k: 0.0 for k in world.profile}
    steps = int(round(seconds * 60)) - 1
    per_step = []
    for s in range(steps):
        t0 = time.perf_counter()
        world.step()
        per_step.append(time.perf_counter() - t0)
    zmin = float(world.state.body_q[:, 2].min())
    window_profile = dict(world.profile)
    # rest: until all bodies sleep; the deepest penetration of the last second before that
    last_second, rest_steps, t_rest = [], 0, 0.0
    while world.state.body_awake.any() and (steps + rest_steps) < rest_cap * 60:
        t0 = time.perf_counter()
        world.step()
        t_rest += time.perf_counter() - t0
        rest_steps += 1
        last_second = (last_second + [world.max_penetration()])[-60:]
    rest = dict(asleep=int((~world.state.body_awake).sum()), t_sleep=(steps + 1 + rest_steps) / 60.0,
                deepest_at_rest=max(last_second) if last_second else float("nan"),
                rest_ms_per_s=t_rest / max(rest_steps, 1) * 60e3, profile=window_profile)
    return world, np.array(per_step), zmin, rest


def inertia_stack(seconds, substeps):
    from inertia.model import ModelBuilder
    from inertia.rigid.world import RigidWorld
    b = ModelBuilder()
    b.add_plane()
    for k in range(10):
        b.add_box(b.add_body(position=(0, 0, EDGE / 2 + k * EDGE)), (EDGE / 2,) * 3)
    world = RigidWorld(b.finalize(), substeps=substeps, enable_sleep=False)
    p0 = world.state.body_q[-1, :3].copy()
    world.step(60)
    settled = world.state.body_q[-1, :3].copy()
    t0 = time.perf_counter()
    world.step(int(round((seconds - 1) * 60)))
    wall = time.perf_counter() - t0
    p1 = world.state.body_q[-1, :3]
    return wall / (seconds - 1), p0, settled, p1.copy()


def inertia_pyramid(base=20, seconds=30.0, substeps=8):
    from inertia.model import ModelBuilder
    from inertia.rigid.world import RigidWorld
    h = EDGE / 2
    b = ModelBuilder()
    b.add_plane()
    for row in range(base):
        for k in range(base - row):
            b.add_box(b.add_body(position=((k - (base - row - 1) / 2) * 2.05 * h, 0, h + 2 * h * row)), (h, h, h))
    world = RigidWorld(b.finalize(), substeps=substeps)
    q0 = world.state.body_q.copy()
    t0 = time.perf_counter()
    world.step(int(round(seconds * 60)))
    wall = time.perf_counter() - t0
    disp = np.linalg.norm(world.state.body_q[:, :3] - q0[:, :3], axis=1)
    return wall / seconds, disp.max(), int(world.state.body_awake.sum()), world.model.body_count


def peer_pile(engine, n, shape, mj_solver="cg"):
    sys.path.insert(0, PEERS)
    import bench_3d_rigid as peers
    if engine == "mujoco":
        peers.MJ_SOLVER[0] = mj_solver
        times, _load, dt, info = peers.mujoco_pile(n, shape)
    else:
        times, _load, dt, info = peers.pybullet_pile(n, shape)
    return np.array(times), dt, info


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--shapes", nargs="+", default=["box", "sphere"])
    ap.add_argument("--engines", nargs="+", default=["inertia", "pybullet", "mujoco"])
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--stack-seconds", type=float, default=10.0,
                    help="simulated seconds of the 10-box stack, > 1 (the first second settles it, the rest is timed)")
    ap.add_argument("--damping-ratio", type=float, default=10.0,
                    help="the piles' contact_damping_ratio (5 with --substeps 4: the real-time pile profile)")
    ap.add_argument("--parallel", choices=["auto", "yes", "no"], default="no",
                    help="Inertia's parallel colour-batch kernels (default no: on a loaded 2-core machine "
                         "every parallel launch waits for a time slice)")
    ap.add_argument("--pyramid", action="store_true", help="also run the 20-base pyramid for 30 s")
    a = ap.parse_args()
    if not a.stack_seconds > 1.0:
        ap.error(f"--stack-seconds must be more than 1 (the first second settles the stack); got {a.stack_seconds}")
    import numba
    print(f"numba threads {numba.config.NUMBA_NUM_THREADS}, cpu count {os.cpu_count()}")
    results = {}
    for shape in a.shapes:
        if "inertia" in a.engines:
            par = {"auto": "auto", "yes": True, "no": False}[a.parallel]
            world, per_step, zmin, rest = inertia_pile(a.n, shape, substeps=a.substeps, parallel=par,
                                                       damping_ratio=a.damping_ratio)
            ms_per_s = per_step.sum() / (len(per_step) / 60.0) * 1e3
            results[("inertia", shape)] = ms_per_s
            prof = ", ".join(f"{k} {v / len(per_step) * 1e3:.2f}" for k, v in rest["profile"].items())
            depth = (EDGE / 2 if shape == "box" else RAD) - zmin
            print(f"inertia  pile N={a.n} {shape:6s} dt=1/60 substeps={a.substeps} damping ratio {a.damping_ratio:g} "
                  f"parallel={a.parallel}: "
                  f"{ms_per_s:9.1f} ms per simulated s over 0-3 s ({per_step.mean() * 1e3:.2f} ms per 1/60 s "
                  f"step, max {per_step.max() * 1e3:.1f}), lowest centre {zmin:.4f} m "
                  f"(>= {max(depth, 0) * 1e3:.2f} mm into the floor)")
            print(f"         per-stage ms per step (0-3 s): {prof}")
            print(f"         at rest: {rest['asleep']}/{a.n} asleep at t = {rest['t_sleep']:.2f} s, deepest contact "
                  f"penetration in the last second before {rest['deepest_at_rest'] * 1e3:.2f} mm; "
                  f"{rest['rest_ms_per_s']:.1f} ms per simulated s from 3 s until asleep")
        for eng in ("pybullet", "mujoco"):
            if eng not in a.engines:
                continue
            try:
                __import__(eng)
            except ImportError:
                print(f"{eng:8s} not installed")
                continue
            times, dt, info = peer_pile(eng, a.n, shape)
            ms_per_s = times.mean() / dt * 1e3
            last = times[-10:].mean() / dt * 1e3
            results[(eng, shape)] = ms_per_s
            # deepest penetration of the lowest layer from the lowest body centre
            depth = (EDGE / 2 if shape == "box" else RAD) - info["zmin"]
            print(f"{eng:8s} pile N={a.n} {shape:6s} dt={dt:.5f}: {ms_per_s:9.1f} ms per simulated s (last 1 s "
                  f"{last:8.1f}), {info['ncon_end']} contacts at the end, lowest centre {info['zmin']:.4f} m "
                  f"(>= {max(depth, 0) * 1e3:.2f} mm into the floor)")
            if ("inertia", shape) in results:
                print(f"         ratio {eng} / inertia = {ms_per_s / results[('inertia', shape)]:.2f}")
    if "inertia" in a.engines:
        per_s, p0, settled, p1 = inertia_stack(a.stack_seconds, a.substeps)
        print(f"inertia  stack of 10 boxes, {a.stack_seconds:.0f} s: {per_s * 1e3:.2f} ms per simulated s; top box "
              f"moved {np.linalg.norm(p1 - settled) * 1e3:.3f} mm after settling in the first second "
              f"(sag {(p0[2] - settled[2]) * 1e3:.2f} mm, lateral {np.linalg.norm(p1[:2] - p0[:2]) * 1e3:.3f} mm)")
        stack_ms = per_s * 1e3
        for eng in ("pybullet", "mujoco"):
            if eng not in a.engines:
                continue
            try:
                __import__(eng)
            except ImportError:
                continue
            sys.path.insert(0, PEERS)
            import bench_3d_rigid as peers
            if eng == "mujoco":
                peers.MJ_SOLVER[0] = "cg"
                times, _load, dt, q0, q1 = peers.mujoco_stack()
            else:
                times, _load, dt, q0, q1 = peers.pybullet_stack()
            ms = np.mean(times) / dt * 1e3
            print(f"{eng:8s} stack of 10 boxes, 10 s, dt={dt:.5f}: {ms:.2f} ms per simulated s; top box moved "
                  f"{np.linalg.norm(q1 - q0) * 1e3:.2f} mm from its start; ratio {eng} / inertia = {ms / stack_ms:.2f}")
        if a.pyramid:
            per_s, disp, awake, nb = inertia_pyramid()
            print(f"inertia  pyramid base 20 ({nb} boxes), 30 s: {per_s * 1e3:.1f} ms per simulated s, largest "
                  f"displacement {disp * 1e3:.2f} mm, {nb - awake}/{nb} asleep at the end")


if __name__ == "__main__":
    main()
