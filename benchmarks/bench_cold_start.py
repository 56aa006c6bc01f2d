"""Benchmark: CPU seconds from an empty Numba cache to a bundled example's first frame.

    python benchmarks/bench_cold_start.py                 # every bundled example, then the rigid pipeline
    python benchmarks/bench_cold_start.py pile fountain   # some examples, then the rigid pipeline
    python benchmarks/bench_cold_start.py --no-rigid      # without the rigid-pipeline row

Each example runs in a fresh process with an empty ``NUMBA_CACHE_DIR`` (the first ``inertia run`` after
an install), with the example's own time step and frame rate, and stops once the first frame after
time zero is recorded; then again with the cache that run filled (every later run). The figure is CPU
time, not wall time: the child process's user + system time (its threads and any children included,
read with ``getrusage(RUSAGE_CHILDREN)`` in this process), so other work on the machine does not blur it.
Printed per example: cold CPU to the first frame (imports, scene build, compilation and the steps), the
part of it spent compiling (Numba's ``numba:compile`` events, outermost only), the warm CPU to the same
frame, and the three kernels whose compilation took longest.

The last row, "rigid pipeline", runs every bundled example with rigid bodies one after another in one
process from one empty cache: what compiling the whole rigid step (broad phase, every closed-form and
general pair family the examples meet, meshes and heightfields, islands, solver, restitution, sleeping)
costs once.

Limitations: one sample per cell (compile times vary by a few per cent from run to run); the first
frame is the simulation's (the state recorded at the first frame time), not a rendered image: `inertia
run` renders its video after the run, and the render kernels compile then.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile

_CHILD = r'''
import json, sys, tempfile, time, tomllib
from numba.core import event
compiles, stack = [], []
class Listener(event.Listener):
    def on_start(self, ev):
        stack.append(time.process_time())
    def on_end(self, ev):
        t0 = stack.pop()
        if not stack:
            compiles.append((time.process_time() - t0, ev.data["dispatcher"].py_func.__qualname__))
event.register("numba:compile", Listener())
from inertia.cli.main import bundled_examples
from inertia.scene import build, parse_scene
from inertia.world import Run
names = sys.argv[1].split(",")
for name in names:
    data = tomllib.loads(bundled_examples()[name].read_text())
    data.pop("output", None)
    world = build(parse_scene(json.dumps(data), format="json", source=name))
    with tempfile.TemporaryDirectory() as tmp:
        # frame 0 is the initial state; frame 1 is the first one the steps produce
        Run(world, tmp, duration=world.duration, fps=world.fps, handle_sigint=False,
            stop_after_frames=2).execute()
compiles.sort(reverse=True)
print(json.dumps({"compile": sum(t for t, _ in compiles), "top": compiles[:3]}))
'''

#: The bundled examples with rigid bodies (the "rigid pipeline" row runs them in one process).
RIGID_EXAMPLES = ("box_pyramid", "dominoes", "pile", "marbles", "rain_on_stack", "vehicle_terrain")


def _child_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run(names: str, cache: str) -> dict:
    """Run the examples `names` (comma-separated) in a fresh process on the Numba cache `cache`; returns
    the child's CPU seconds ("cpu"), its compile seconds and longest compiles."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    before = _child_cpu()
    out = subprocess.run([sys.executable, "-c", _CHILD, names], env=env, check=True, capture_output=True,
                         text=True).stdout
    result = json.loads(out.strip().splitlines()[-1])
    result["cpu"] = _child_cpu() - before
    return result


def cold_and_warm(names: str) -> tuple[dict, dict]:
    with tempfile.TemporaryDirectory(prefix="inertia-cold-") as cache:
        return run(names, cache), run(names, cache)


def main(argv=None):
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src"))
    from inertia.cli.main import bundled_examples

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("examples", nargs="*", help="bundled example names (default: all)")
    parser.add_argument("--no-rigid", action="store_true", help="skip the rigid-pipeline row")
    args = parser.parse_args(argv)
    names = args.examples or sorted(bundled_examples())
    print(f"cold start: {os.cpu_count()} cpus, load average {os.getloadavg()[0]:.1f}")
    print(f"| {'example':16s} | cold CPU to first frame (s) | of which compiling (s) | warm CPU (s) | "
          "longest compiles (s) |")
    print(f"|{'-' * 18}|----------------------------:|-----------------------:|-------------:|---|")
    total_cold = total_warm = 0.0
    rows = [(name, name) for name in names]
    if not args.no_rigid:
        rows.append(("rigid pipeline", ",".join(RIGID_EXAMPLES)))
    for label, run_names in rows:
        cold, warm = cold_and_warm(run_names)
        if label in names:
            total_cold += cold["cpu"]
            total_warm += warm["cpu"]
        top = ", ".join(f"{n} {t:.1f}" for t, n in cold["top"])
        print(f"| {label:16s} | {cold['cpu']:27.1f} | {cold['compile']:22.1f} | {warm['cpu']:12.1f} | {top} |",
              flush=True)
        if label == names[-1]:
            print(f"| {'total':16s} | {total_cold:27.1f} | {'':22s} | {total_warm:12.1f} | |", flush=True)


if __name__ == "__main__":
    main()
