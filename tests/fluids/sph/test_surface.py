"""Surface reconstruction (inertia.fluids.sph.surface): colour field + marching cubes."""

import numpy as np
import pytest

from inertia.fluids.sph import sample_block, surface

pytest.importorskip("skimage")


def _ball(radius, dx):
    x = sample_block((-radius - dx,) * 3, (radius + dx,) * 3, dx)
    return x[np.linalg.norm(x, axis=1) < radius]


def test_sphere_of_particles_gives_the_sphere_within_half_a_spacing():
    # A ball of lattice particles (radius R = 10 spacings) fills the volume 4/3 pi R^3 (one
    # particle per dx^3), so its surface is the sphere of radius R: every vertex of the 1/2
    # colour level lies within half a spacing of it (curvature pulls the level in by O(h^2 / R)).
    dx, radius = 0.01, 0.1
    x = _ball(radius, dx)
    r_eff = (3 * x.shape[0] * dx ** 3 / (4 * np.pi)) ** (1 / 3)   # the sphere of the same volume
    assert abs(r_eff - radius) < 0.05 * dx
    verts, faces = surface.reconstruct(x, dx)
    dist = np.linalg.norm(verts, axis=1) - radius
    assert faces.shape[0] > 1000
    assert np.abs(dist).max() < 0.5 * dx, (dist.min(), dist.max())
    # outward orientation: the face normals point away from the centre
    a, b, c = (verts[faces[:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    assert np.mean(np.einsum("ij,ij->i", normal, (a + b + c) / 3) > 0) > 0.99


def test_mesh_files_round_trip(tmp_path):
    x = _ball(0.05, 0.01)
    verts, faces = surface.reconstruct(x, 0.01)
    obj = surface.write_obj(tmp_path / "s.obj", verts, faces).read_text().splitlines()
    assert sum(line.startswith("v ") for line in obj) == len(verts)
    assert sum(line.startswith("f ") for line in obj) == len(faces)
    paths = surface.write_mesh_sequence([x, (x + 0.1, np.ones(len(x), bool))], tmp_path / "seq", 0.01)
    data = paths[1].read_bytes()
    header, body = data.split(b"end_header\n")
    assert b"element face %d" % len(faces) in header
    assert len(body) == 12 * len(verts) + 13 * len(faces)
    with pytest.raises(ValueError, match="fmt"):
        surface.write_mesh_sequence([x], tmp_path, 0.01, fmt="stl")
