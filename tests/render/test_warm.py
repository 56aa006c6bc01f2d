"""inertia.render.warm_kernels: after it, rendering a run compiles nothing new."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"


def test_warm_kernels_leaves_nothing_to_compile_for_a_run(tmp_path):
    # A fresh Numba cache: warm, then render a 3-D frame with a plane, speed colours, a mesh and a
    # line; count the compilations the frame triggers (Numba's compile events).
    script = """
import numpy as np
from numba.core import event
from inertia.render import Renderer, warm_kernels
from inertia.render.meshes import LineSet, TriangleMesh
from inertia.colliders import Plane
warm_kernels(dims=(3,), primitives=False)
names = []
class Listener(event.Listener):
    def on_start(self, e): names.append(e.data["dispatcher"].py_func.__name__)
    def on_end(self, e): pass
event.register("numba:compile", Listener())
r = Renderer(320, 180, dim=3)
rng = np.random.default_rng(1)
pos = rng.uniform(-1, 1, (500, 3)); pos[:, 2] += 1.2
r.frame(pos, radius=0.03, velocities=rng.normal(size=(500, 3)), colliders=[Plane(point=(0, 0, 0), normal=(0, 0, 1))],
        meshes=[TriangleMesh(pos[:3], None, np.array([[0, 1, 2]]), (0.5, 0.5, 0.5))],
        lines=[LineSet(pos, np.array([[3, 4]]), (1.0, 1.0, 1.0), 2.0)])
print("COMPILED", sorted(set(names)))
"""
    env = {"PYTHONPATH": str(SRC), "NUMBA_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
    assert result.returncode == 0, result.stderr
    assert "COMPILED []" in result.stdout, result.stdout
