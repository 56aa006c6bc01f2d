"""Benchmark: the first frame of a bundled example from a cold Numba cache (issue 8, "cold start").

    python benchmarks/bench_cold_start.py [fountain bouncing_balls chain] [--duration 0.3]

Each example runs in a fresh process with an empty ``NUMBA_CACHE_DIR`` (the first ``inertia run``
after install), for ``--duration`` simulated seconds, then again with the cache it filled (every
later run). Printed per example: the first frame's wall time (from the start of ``Run.execute``),
the process CPU time (imports included; compilation is single-threaded, so on an idle machine
the wall time is about the CPU time, and on a busy one the CPU time is the steadier figure), the
same for the warm run as the baseline, and the kernels whose compilation took longest.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

_CHILD = r'''
import json, sys, tempfile, time, tomllib
from numba.core import event
compiles, stack = [], []
class Listener(event.Listener):
    def on_start(self, ev):
        stack.append(time.perf_counter())
    def on_end(self, ev):
        t0 = stack.pop()
        if not stack:
            compiles.append((time.perf_counter() - t0, ev.data["dispatcher"].py_func.__qualname__))
event.register("numba:compile", Listener())
from inertia.cli.main import bundled_examples
from inertia.scene import build, parse_scene
from inertia.world import Run
name, duration = sys.argv[1], float(sys.argv[2])
data = tomllib.loads(bundled_examples()[name].read_text())
data["simulation"]["duration"] = duration
data["simulation"]["fps"] = 1.0 / duration
data.pop("output", None)
world = build(parse_scene(json.dumps(data), format="json", source=name))
with tempfile.TemporaryDirectory() as tmp:
    result = Run(world, tmp, duration=world.duration, fps=world.fps, handle_sigint=False).execute()
compiles.sort(reverse=True)
print(json.dumps({"first_frame": result.first_frame_seconds, "cpu": time.process_time(),
                  "compile": sum(t for t, _ in compiles), "top": compiles[:4]}))
'''


def run(name: str, duration: float, cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", _CHILD, name, str(duration)], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("examples", nargs="*", default=["fountain", "bouncing_balls", "chain"])
    parser.add_argument("--duration", type=float, default=0.3, help="simulated seconds (one frame)")
    args = parser.parse_args(argv)
    print(f"cold start: {os.cpu_count()} cpus, load average {os.getloadavg()[0]:.1f}")
    for name in args.examples:
        with tempfile.TemporaryDirectory(prefix="inertia-cold-") as cache:
            cold = run(name, args.duration, cache)
            warm = run(name, args.duration, cache)
        top = ", ".join(f"{n} {t:.1f} s" for t, n in cold["top"])
        print(f"{name:16s} cold: first frame {cold['first_frame']:6.1f} s wall, process CPU {cold['cpu']:5.1f} s "
              f"(compiling {cold['compile']:.1f} s) | warm: first frame {warm['first_frame']:5.2f} s, CPU "
              f"{warm['cpu']:4.1f} s | cold/warm CPU {cold['cpu'] / warm['cpu']:4.1f}x\n{'':16s} longest: {top}")


if __name__ == "__main__":
    main()
