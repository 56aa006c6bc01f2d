"""`inertia view SCENE` simulates into a temporary directory and removes it before serving."""

from __future__ import annotations

import tempfile

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("viser")


def test_view_of_a_scene_leaves_no_temporary_directory(tmp_path, monkeypatch):
    import inertia.viewer as viewer_module
    from inertia.cli.main import app

    temp_root = tmp_path / "tmp"
    temp_root.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp_root))
    seen = {}

    def fake_view(states, **options):
        # Served after the directory is gone: the frames must already be in memory.
        seen["frames"] = states.frame_count
        seen["finite"] = bool(np.all(np.isfinite(states.positions)))
        seen["left"] = sorted(p.name for p in temp_root.iterdir())

    monkeypatch.setattr(viewer_module, "view", fake_view)
    result = CliRunner().invoke(app, ["view", "bouncing_balls", "--duration", "0.2", "--port", "0"])
    assert result.exit_code == 0, result.output
    assert seen["frames"] >= 2 and seen["finite"]
    assert seen["left"] == [] and list(temp_root.iterdir()) == []
