"""Golden images: a few rendered frames compared with stored PNGs, with a small tolerance.

Regenerate after an intended change of the look with

    INERTIA_UPDATE_GOLDEN=1 python -m pytest tests/render/test_golden.py

and look at the new files in tests/render/golden/ before committing them.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from render_scenes import colliders_2d, colliders_3d, lattice_3d, swirl_2d  # noqa: E402

from inertia.render import Renderer, read_png, write_png  # noqa: E402

GOLDEN = Path(__file__).parent / "golden"
UPDATE = os.environ.get("INERTIA_UPDATE_GOLDEN") == "1"


def _scene_3d():
    positions, radius, groups = lattice_3d()
    renderer = Renderer(320, 180, color_by="group")
    return renderer.frame(positions, radius=radius, groups=groups, colliders=colliders_3d())


def _scene_2d():
    positions, velocities = swirl_2d()
    renderer = Renderer(320, 180, dim=2, speed_max=2.5)
    return renderer.frame(positions, radius=0.03, velocities=velocities, colliders=colliders_2d())


def _scene_light_container():
    import inertia.colliders as C

    positions, radius, _ = lattice_3d(n_side=5, spacing=0.2, height=0.1)
    renderer = Renderer(320, 180, theme="light", azimuth=30.0, elevation=35.0, color="#d62728")
    container = C.Container(center=(0.0, 0.0, 0.6), half_extents=(0.7, 0.7, 0.6))
    return renderer.frame(positions, radius=0.5 * radius, colliders=[container])


SCENES = {"particles_3d": _scene_3d, "swirl_2d": _scene_2d, "container_light": _scene_light_container}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_frame_matches_golden(name):
    image = SCENES[name]()
    path = GOLDEN / f"{name}.png"
    if UPDATE:
        GOLDEN.mkdir(exist_ok=True)
        write_png(path, image)
        pytest.skip(f"wrote {path}")
    if not path.exists():
        pytest.fail(f"{path} is missing: run with INERTIA_UPDATE_GOLDEN=1 to create it")
    golden = read_png(path)
    assert golden.shape == image.shape
    diff = np.abs(golden.astype(np.int16) - image.astype(np.int16))
    # Same bytes on the machine that made them; a little slack for other CPUs and libms.
    assert diff.mean() < 0.5, f"{name}: mean difference {diff.mean():.3f} (/255)"
    assert np.mean(diff.max(axis=2) > 16) < 0.002, f"{name}: {np.mean(diff.max(axis=2) > 16):.4%} pixels differ by > 16"
