"""Rigid-body exports: OBJ mesh sequences and animated USD transforms, checked against body_q."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from inertia.io import write_obj, write_obj_sequence, write_usd_bodies
from inertia.io.obj import shape_meshes
from inertia.model import ModelBuilder
from inertia.rigid.world import RigidWorld


def _run(frames=4):
    b = ModelBuilder()
    b.add_plane()
    box = b.add_body(position=(0, 0, 0.5), orientation=(np.cos(0.3), np.sin(0.3), 0, 0), name="crate",
                     angular_velocity=(1.0, 2.0, 0.5))
    b.add_box(box, (0.1, 0.2, 0.3))
    ball = b.add_body(position=(1, 0, 0.5), name="ball")
    b.add_sphere(ball, 0.1)
    b.add_capsule(ball, 0.05, 0.1, position=(0, 0, 0.2))       # compound: the COM moves off the origin
    hull = b.add_body(position=(-1, 0, 0.5), name="rock")
    b.add_convex_hull(hull, np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.2], [0.1, 0.1, 0.1]]) - 0.05)
    model = b.finalize()
    world = RigidWorld(model)
    qs = [world.state.body_q.copy()]
    for _ in range(frames - 1):
        world.step(5)
        qs.append(world.state.body_q.copy())
    return model, np.array(qs)


def _read_obj(path):
    verts, faces = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:]])
        elif line.startswith("f "):
            faces.append([int(x) - 1 for x in line.split()[1:]])
    return np.array(verts), np.array(faces)


def test_obj_frame_vertices_are_the_transformed_box(tmp_path):
    """The OBJ box corners equal body_q applied to the corners (+-hx, +-hy, +-hz) (scipy rotation)."""
    model, qs = _run()
    path = write_obj(tmp_path / "f.obj", model, qs[-1], include_static=False)
    verts, faces = _read_obj(path)
    q = qs[-1][0]                                   # the crate: one box, its frame = the box frame
    corners = np.array([[sx * 0.1, sy * 0.2, sz * 0.3] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    expected = q[:3] + Rotation.from_quat([q[4], q[5], q[6], q[3]]).apply(corners)
    np.testing.assert_allclose(verts[:8], expected, atol=1e-8)
    assert faces.max() < len(verts) and faces.min() >= 0
    # every body's vertex count: box 8, sphere + capsule, hull 5 points
    sizes = [len(v) for v, _ in shape_meshes(model)]
    assert len(verts) == sum(sizes[1:])


def test_hull_mesh_is_closed_and_outward():
    """The hull tessellation is a closed surface with outward faces: its divergence-theorem volume is positive
    and equals the exact volume of the tetrahedron-plus-point hull (0.2^3 / 6 + the extra point's pyramid)."""
    model, _ = _run(1)
    v, f = shape_meshes(model)[-1]
    vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0
    from scipy.spatial import ConvexHull
    assert vol == pytest.approx(ConvexHull(v).volume, rel=1e-12) and vol > 0
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)                      # closed: every edge shared by two faces


def test_obj_sequence_one_file_per_frame(tmp_path):
    model, qs = _run()
    d = write_obj_sequence(tmp_path / "obj", model, qs)
    files = sorted(d.glob("*.obj"))
    assert [p.name for p in files] == [f"frame_{i:05d}.obj" for i in range(len(qs))]
    a, _ = _read_obj(files[0])
    b, _ = _read_obj(files[-1])
    assert a.shape == b.shape and not np.allclose(a, b)


def test_usd_body_transform_matches_body_q(tmp_path):
    """Read back with pxr: a shape's local-to-world transform at frame k places its origin at
    body_q[k] composed with the shape's local pose, and rotates as the body's quaternion."""
    pxr = pytest.importorskip("pxr")
    from pxr import Usd, UsdGeom

    model, qs = _run()
    path = write_usd_bodies(tmp_path / "bodies.usda", model, qs, fps=12.0)
    stage = Usd.Stage.Open(str(path))
    assert stage.GetStartTimeCode() == 1.0 and stage.GetEndTimeCode() == len(qs)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    for k in (0, len(qs) - 1):
        for b, name in enumerate(["crate", "ball", "rock"]):
            prim = stage.GetPrimAtPath(f"/World/Bodies/{name}")
            m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(1.0 + k)))
            q = qs[k][b]
            rot = Rotation.from_quat([q[4], q[5], q[6], q[3]]).as_matrix()
            # USD matrices are row-vector: translation in the last row, rotation transposed
            np.testing.assert_allclose(m[3, :3], q[:3], atol=1e-9)
            np.testing.assert_allclose(m[:3, :3], rot.T, atol=1e-9)
        # the crate's box mesh corner in world space equals the transformed corner
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Bodies/crate/shape_1"))
        xf = np.array(mesh.ComputeLocalToWorldTransform(Usd.TimeCode(1.0 + k)))
        corner = np.array(mesh.GetPointsAttr().Get()[7], float)
        world_corner = np.append(corner, 1.0) @ xf
        q = qs[k][0]
        expected = q[:3] + Rotation.from_quat([q[4], q[5], q[6], q[3]]).apply([0.1, 0.2, 0.3])
        np.testing.assert_allclose(world_corner[:3], expected, atol=1e-6)


def test_output_keys_write_body_exports(tmp_path):
    """[output] obj / usd write the body files when the state file recorded body_q and the shape table."""
    pytest.importorskip("pxr")
    from types import SimpleNamespace

    from inertia.cli.outputs import write_outputs
    from inertia.io.obj import model_arrays

    model, qs = _run(3)
    states = SimpleNamespace(fps=10.0, frame_count=len(qs), particle_count=0, dim=3,
                             fields={"body_q": qs}, model=model_arrays(model))
    written = write_outputs(states, tmp_path, {"video": [], "plot": False, "obj": True, "usd": True})
    assert sorted(written) == ["obj", "usd_bodies"]
    assert len(list((tmp_path / "obj").glob("*.obj"))) == 3 and (tmp_path / "bodies.usdc").is_file()
