"""PLY sequences, USD animated points and the run manifest open and hold what was written."""

from __future__ import annotations

import numpy as np
import pytest

from inertia.io import States, read_manifest, read_ply, write_manifest, write_ply, write_ply_sequence, write_usd


def _states(frames=4, n=6, dim=3, groups=None, active=True):
    rng = np.random.default_rng(3)
    x = rng.normal(size=(frames, n, dim))
    v = rng.normal(size=(frames, n, dim))
    fields = {}
    if active:
        fields["active"] = np.tile(np.arange(n) < n - 1, (frames, 1))
        fields["active"][-1, 0] = False
    static = {"radius": np.full(n, 0.05)}
    meta = {"fps": 24.0}
    if groups is not None:
        static["group"] = np.asarray(groups, np.int32)
        meta["groups"] = ["water", "sand grains"]
    return States(times=np.arange(frames) / 24.0, positions=x, velocities=v, fields=fields, static=static, metadata=meta)


@pytest.mark.parametrize("binary", [True, False])
def test_ply_round_trip(tmp_path, binary):
    rng = np.random.default_rng(0)
    x, v = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    colors = rng.integers(0, 256, size=(7, 3)).astype(np.uint8)
    path = write_ply(tmp_path / "p.ply", x, velocities=v, radius=0.25, colors=colors,
                     attributes={"group": np.arange(7, dtype=np.int32)}, binary=binary)
    data = read_ply(path)
    assert list(data) == ["x", "y", "z", "vx", "vy", "vz", "radius", "red", "green", "blue", "group"]
    np.testing.assert_allclose(np.column_stack([data["x"], data["y"], data["z"]]), x, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(data["vz"], v[:, 2], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(data["red"], colors[:, 0])
    np.testing.assert_array_equal(data["group"], np.arange(7))
    assert path.read_bytes().startswith(b"ply\nformat " + (b"binary_little_endian" if binary else b"ascii"))


def test_ply_opens_in_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    x = np.random.default_rng(1).normal(size=(50, 3))
    write_ply(tmp_path / "cloud.ply", x, colors=np.full((50, 3), 0.5))
    cloud = trimesh.load(tmp_path / "cloud.ply")
    np.testing.assert_allclose(cloud.vertices, x, rtol=1e-6, atol=1e-6)


def test_ply_sequence_one_file_per_frame_active_only(tmp_path):
    states = _states(dim=2, groups=[0, 0, 1, 1, 1, 0])
    paths = write_ply_sequence(states, tmp_path / "ply", colors=lambda f: np.full((6, 3), f / 10.0))
    assert [p.name for p in paths] == [f"frame_{f:05d}.ply" for f in range(4)]
    first, last = read_ply(paths[0]), read_ply(paths[-1])
    assert first["x"].size == 5 and last["x"].size == 4  # inactive slots are dropped
    np.testing.assert_allclose(first["z"], 0.0)  # 2-D scenes in the plane z = 0
    np.testing.assert_array_equal(first["group"], [0, 0, 1, 1, 1])
    np.testing.assert_allclose(first["x"], states.positions[0, :5, 0], rtol=1e-6)


def test_ply_rejects_wrong_shapes(tmp_path):
    with pytest.raises(ValueError, match=r"colors must be \(3, 3\)"):
        write_ply(tmp_path / "x.ply", np.zeros((3, 3)), colors=np.zeros((2, 3)))
    assert not (tmp_path / "x.ply").exists()


def test_usd_animated_points_open_with_usd_core(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    states = _states(frames=5)
    path = write_usd(states, tmp_path / "points.usdc", colors=np.full((6, 3), 0.5))
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 24.0 and stage.GetFramesPerSecond() == 24.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1.0, 5.0)
    assert stage.GetDefaultPrim().GetPath() == "/World"
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles"))
    assert points.GetPointsAttr().GetTimeSamples() == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert len(points.GetVelocitiesAttr().GetTimeSamples()) == 5
    assert len(points.GetWidthsAttr().GetTimeSamples()) == 5
    at3 = np.array(points.GetPointsAttr().Get(3.0))
    np.testing.assert_allclose(at3, states.positions[2, :5], rtol=1e-6)
    np.testing.assert_allclose(np.array(points.GetWidthsAttr().Get(1.0)), 0.1, rtol=1e-6)
    np.testing.assert_array_equal(np.array(points.GetIdsAttr().Get(5.0)), [1, 2, 3, 4])
    assert points.GetDisplayColorPrimvar().GetInterpolation() == UsdGeom.Tokens.vertex


def test_usd_one_prim_per_group(tmp_path):
    pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    states = _states(frames=3, groups=[0, 1, 0, 1, 0, 1], active=False)
    stage = Usd.Stage.Open(str(write_usd(states, tmp_path / "g.usda", up_axis="Y", fps=12)))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y and stage.GetTimeCodesPerSecond() == 12.0
    water = UsdGeom.Points(stage.GetPrimAtPath("/World/water"))
    sand = UsdGeom.Points(stage.GetPrimAtPath("/World/sand_grains"))
    assert len(water.GetPointsAttr().Get(2.0)) == 3 and len(sand.GetPointsAttr().Get(2.0)) == 3


def test_manifest_records_the_run(tmp_path):
    (tmp_path / "movie.mp4").write_bytes(b"")
    written = write_manifest(tmp_path / "manifest.json", scene="[simulation]\n", scene_path="s.toml", seed=3,
                             step_count=1200, frame_count=61, simulated_time=2.0,
                             timings={"simulate": 1.5, "render": 3.25}, outputs={"mp4": tmp_path / "movie.mp4"})
    again = read_manifest(tmp_path / "manifest.json")
    assert again == written
    assert again["seed"] == 3 and again["step_count"] == 1200 and again["timings"]["render"] == 3.25
    assert again["outputs"]["mp4"] == "movie.mp4"
    assert {"python", "numpy", "numba", "inertia"} <= set(again["versions"])
