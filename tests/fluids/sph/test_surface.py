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


def _block(n, dx, dim):
    g = (np.arange(n) + 0.5) * dx
    return np.stack(np.meshgrid(*([g] * dim), indexing="ij"), -1).reshape(-1, dim)


def _mesh_volume(verts, faces):
    a, b, c = (verts[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0


@pytest.mark.parametrize("h_over_dx", [1.0, 1.5])
def test_block_surface_encloses_the_block_volume_within_the_smoothing_bound(h_over_dx):
    # A cube of n^3 lattice particles stands for the cube L = n dx (one particle per dx^3). Where the
    # kernel support (2h) lies inside the block the colour field sums to 1 (partition of unity of
    # the lattice, to ~0.3 % at h = dx), so the 1/2 level is the block's face (measured 1.5e-3 dx off at
    # h = dx, bound 0.01 dx) and only the 12
    # edges round off, each within the support: a quarter-round of radius <= 2h removes at most
    # (1 - pi/4)(2h)^2 per unit edge length. Bound: 0 < L^3 - V < 12 L (1 - pi/4)(2h)^2; measured
    # ~0.24 * 12 L h^2 (an edge radius of ~1.06 h), a quarter of the bound.
    dx, n = 0.02, 10
    h, L = h_over_dx * dx, n * dx
    verts, faces = surface.reconstruct(_block(n, dx, 3), dx, smoothing_length=h)
    deficit = L**3 - _mesh_volume(verts, faces)
    bound = 12 * L * (1 - np.pi / 4) * (2 * h) ** 2
    assert 0 < deficit < 0.5 * bound, (deficit, bound)
    mid = np.all(np.abs(verts[:, 1:] - L / 2) < 0.25 * L, axis=1)   # the x faces, away from the edges
    assert np.abs(verts[mid, 0].max() - L) < 0.01 * dx and np.abs(verts[mid, 0].min()) < 0.01 * dx


def test_2d_colour_field_and_level_set_of_a_block():
    # 2-D: the colour field of an n^2 block is 1/2 on the block's sides (partition of unity), and
    # level_set's phi has its zero there with |grad phi| ~ 1 (a distance) across the side.
    dx, n = 0.02, 12
    L = n * dx
    field, lo, cell = surface.colour_field(_block(n, dx, 2), dx)
    phi = surface.level_set(field, cell)
    j = int(round((L / 2 - lo[1]) / cell))                           # the row through the middle
    xs = lo[0] + np.arange(field.shape[0]) * cell
    crossing = np.interp(0.0, phi[xs > L / 2, j], xs[xs > L / 2])   # phi rises through 0 at x = L
    assert abs(crossing - L) < 0.01 * dx
    slope = np.gradient(phi[:, j], cell)[np.argmin(np.abs(xs - L))]
    assert 0.7 < slope < 1.3
    with pytest.raises(ValueError, match="x must"):
        surface.colour_field(np.zeros((3, 4)), dx)
