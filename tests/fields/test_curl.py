"""Curl-noise (src/inertia/fields/curl.py): incompressibility, boundaries, tracers, determinism.

Reference equations (Bridson, Hourihan & Nordenstam 2007):
    2-D  v = (d psi/dy, -d psi/dx)           3-D  v = curl psi
    div v = 0 exactly, since div curl = 0 and d/dx d/dy psi = d/dy d/dx psi.
    Boundaries: psi' = ramp(d/d0) psi + (1 - ramp) n (n . psi) [3-D] (+ (1 - ramp) psi_R, the
    potential of the collider's rigid motion u_R), so at the surface v . n = u_R . n.
"""

import numba
import numpy as np
import pytest

import inertia as ia
from inertia.fields import CurlNoise


def _grid(n, lo, hi, dim):
    """Nodes of an n^dim grid over [lo, hi]^dim, flattened (i, j, k order), and the spacing."""
    axis = np.linspace(lo, hi, n)
    pts = np.stack(np.meshgrid(*([axis] * dim), indexing="ij"), axis=-1).reshape(-1, dim)
    return pts, axis[1] - axis[0]


def _central_divergence(v, n, dim, h):
    """div v = sum_a (v_a(x + h e_a) - v_a(x - h e_a)) / 2h at the interior nodes."""
    V = v.reshape(*([n] * dim), dim)
    div = 0.0
    for a in range(dim):
        plus = [slice(1, -1)] * dim
        minus = [slice(1, -1)] * dim
        plus[a], minus[a] = slice(2, None), slice(0, -2)
        div = div + (V[tuple(plus) + (a,)] - V[tuple(minus) + (a,)]) / (2 * h)
    return div


def _interior(mask, dim):
    return mask.reshape(*([round(mask.size ** (1 / dim))] * dim))[(slice(1, -1),) * dim]


def _curl_of_potential(field, pts, t, h=1e-5):
    """Central-difference curl of field.potential: an independent check of the analytic v."""
    dim = field.dim
    eye = np.eye(dim)
    d = [(field.potential(pts + h * eye[k], t) - field.potential(pts - h * eye[k], t)) / (2 * h)
         for k in range(dim)]
    if dim == 2:
        return np.stack([d[1], -d[0]], axis=1)
    J = np.stack(d, axis=2)  # J[:, c, k] = d psi_c / d x_k
    return np.stack([J[:, 2, 1] - J[:, 1, 2], J[:, 0, 2] - J[:, 2, 0], J[:, 1, 0] - J[:, 0, 1]], axis=1)


class AnalyticSphere:
    """Test double of the collider interface that also gives the distance Hessian.

    d = |x - c| - r, n = (x - c) / |x - c|, grad n = (I - n n^T) / |x - c|.
    """

    dim = 3

    def __init__(self, center, radius):
        self.center, self.radius = np.asarray(center, float), float(radius)

    def signed_distance(self, p, t=0.0):
        return np.linalg.norm(p - self.center, axis=1) - self.radius

    def normal(self, p, t=0.0):
        d = p - self.center
        return d / np.linalg.norm(d, axis=1)[:, None]

    def velocity(self, p, t=0.0):
        return np.zeros_like(p)

    def distance_hessian(self, p, t=0.0):
        d = p - self.center
        r = np.linalg.norm(d, axis=1)
        n = d / r[:, None]
        return (np.eye(3)[None] - n[:, :, None] * n[:, None, :]) / r[:, None, None]


# ---------------------------------------------------------------------------------------------
# Incompressibility
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["simplex", "perlin"])
def test_divergence_free_central_differences_64_cubed(kind):
    # Central differences of an exactly divergence-free field leave only truncation error,
    #   div_h v = div v + h^2/6 sum_a d^3 v_a / dx_a^3 + O(h^4) = O(h^2),
    # so max|div_h v| h / max|v| ~ (h k)^3 / 6 for features of wavenumber k. On 64^3 nodes over
    # [-0.5, 0.5]^3 (h = 1/63, ~40 nodes per lattice cell of the finest octave, 25 across the
    # boundary ramp) it is <= 1e-3; only nodes whose stencil lies in the fluid count.
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.25)

    def ratio(field, n):
        pts, h = _grid(n, -0.5, 0.5, 3)
        fluid = sphere.signed_distance(pts) > h
        v = field(pts, 0.3)
        div = _central_divergence(v, n, 3, h)[_interior(fluid, 3)]
        return np.abs(div).max() * h / np.abs(v[fluid]).max()

    for boundaries in ([], [sphere]):
        field = CurlNoise(dim=3, seed=1, kind=kind, frequency=0.8, octaves=2, time_frequency=0.5,
                          boundaries=boundaries, boundary_width=0.4)
        fine = ratio(field, 64)
        assert fine <= 1e-3
        # The residual is truncation error: halving h divides it by ~8 (at least 4 here, as
        # the C^2 ramp makes the error first order in a thin shell at d = d0).
        assert fine < ratio(field, 32) / 4


def test_divergence_free_central_differences_2d():
    disc = ia.colliders.Sphere(center=(0.1, -0.05), radius=0.2)
    field = CurlNoise(dim=2, seed=4, frequency=1.0, octaves=2, time_frequency=0.5,
                      boundaries=[disc], boundary_width=0.25)
    pts, h = _grid(256, -0.5, 0.5, 2)
    v = field(pts, 1.7)
    div = _central_divergence(v, 256, 2, h)
    fluid = _interior(disc.signed_distance(pts) > h, 2)
    assert np.abs(div[fluid]).max() * h / np.abs(v).max() <= 1e-4


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("kind", ["simplex", "perlin"])
@pytest.mark.parametrize("time_frequency", [0.0, 0.5])
def test_divergence_from_analytic_jacobian_is_roundoff(dim, kind, time_frequency):
    # trace(dv/dx) = eps_ijk d_i d_j psi_k: each Hessian is symmetric, so the trace cancels to
    # rounding (~1e-15 relative); the Jacobian itself matches central differences of v.
    field = CurlNoise(dim=dim, seed=2, kind=kind, frequency=2.0, octaves=3,
                      time_frequency=time_frequency)
    # 64^3 nodes (32^3 for Perlin in 3-D, whose general Hessian kernel visits 2^D corners).
    n = 256 if dim == 2 else (64 if kind == "simplex" else 32)
    pts, h = _grid(n, -1.0, 1.0, dim)
    jac = field.jacobian(pts, 0.4)
    v = field(pts, 0.4)
    div = np.trace(jac, axis1=1, axis2=2)
    assert np.abs(div).max() * h / np.abs(v).max() <= 1e-12
    np.testing.assert_allclose(field.divergence(pts[:100], 0.4), div[:100])
    # Jacobian vs central differences of the velocity (h = 1e-6: error ~1e-8 relative).
    sample = pts[:: max(1, len(pts) // 2000)]
    eye = np.eye(dim)
    jac_fd = np.stack([(field(sample + 1e-6 * eye[k], 0.4) - field(sample - 1e-6 * eye[k], 0.4)) / 2e-6
                       for k in range(dim)], axis=2)
    scale = np.abs(jac).max()
    assert np.abs(field.jacobian(sample, 0.4) - jac_fd).max() <= 1e-6 * scale


@pytest.mark.parametrize("kind", ["simplex", "perlin"])
@pytest.mark.parametrize("time_frequency", [0.0, 0.5])
def test_batched_lattice_walk_equals_three_separate_noises(kind, time_frequency):
    # 3-D curl-noise walks each octave's lattice once for the three potentials. Reference: the
    # same three noises evaluated one at a time by the scalar fractal kernel (gradient table
    # c, the shared octave offsets), v = curl psi = (d1 psi2 - d2 psi1, d2 psi0 - d0 psi2,
    # d0 psi1 - d1 psi0). Same arithmetic in another order (with FMA contraction): equal to
    # rounding, ~1e-13 of max|v| (derivatives sum up to 15 corner terms each, and the curl
    # subtracts derivatives larger than v); a wrong gradient or weight gives O(1).
    from inertia.fields import kernels as K
    field = CurlNoise(dim=3, seed=4, kind=kind, frequency=1.3, octaves=3, time_frequency=time_frequency)
    pts = np.random.default_rng(6).uniform(-3, 3, (5000, 3))
    p = field.params
    J = np.empty((3, len(pts), 3))
    for c in range(3):
        K.fractal_noise(pts, field._offsets[0], field._perm, field._grads[c], np.empty(len(pts)),
                        J[c], np.empty((0, 3, 3)), 0.7, p.kind_code, 1, p.frequency, p.lacunarity,
                        p.gain, p.octaves, p.time_frequency, field._scale)
    curl = np.stack([J[2, :, 1] - J[1, :, 2], J[0, :, 2] - J[2, :, 0], J[1, :, 0] - J[0, :, 1]], axis=1)
    v = field(pts, 0.7)
    assert np.abs(v - curl).max() <= 1e-12 * np.abs(v).max()


def test_three_potentials_are_uncorrelated():
    # The potentials share the lattice points but not the gradients: like three independent
    # noises, their sample correlation over many lattice cells is ~0 (N = 2e5 points over
    # ~5e4 cells: sampling error ~ 1 / sqrt(cells) ~ 0.005; bound 0.03), while each has the
    # same spread.
    field = CurlNoise(dim=3, seed=2, frequency=1.0, octaves=1)
    psi = field.potential(np.random.default_rng(3).uniform(-18, 18, (200_000, 3)))
    corr = np.corrcoef(psi.T)
    assert np.abs(corr[np.triu_indices(3, 1)]).max() < 0.03
    std = psi.std(axis=0)
    assert std.max() < 1.15 * std.min()


def test_wall_lists_match_a_brute_force_search():
    # The compiled wall lists (collider order, then plane order; planes' distances computed in
    # the kernel) against a NumPy search: the same rows, distances, normals and colliders.
    room = ia.colliders.Container(center=(0.1, 0.0, -0.1), half_extents=(0.9, 0.8, 0.7),
                                  rotation=(0.2, -0.1, 0.3))
    sphere = ia.colliders.Sphere(center=(0.1, 0.2, 0.0), radius=0.3)
    field = CurlNoise(dim=3, seed=1, boundaries=[sphere, room], boundary_width=0.3)
    pts = np.random.default_rng(2).uniform(-1, 1, (4000, 3))
    slot, count, dist, normal, _, coll, *_ = field.boundaries.prepare(pts, 0.0)
    from inertia.fields.curl import _planes
    plane_p, plane_n = _planes(room, 0.0, 3)
    for i in range(0, len(pts), 7):
        walls = [(sphere.signed_distance(pts[i:i + 1])[0], sphere.normal(pts[i:i + 1])[0], 0)]
        walls += [((pts[i] - p0) @ n0, n0, 1) for p0, n0 in zip(plane_p, plane_n)]
        near = [w for w in walls if w[0] < 0.3]
        assert count[i] == len(near)
        assert (slot[i] < 0) == (len(near) == 0)
        for j, (d, n, k) in enumerate(near):
            row = slot[i] + j
            assert abs(dist[row] - d) < 1e-14 and coll[row] == k
            np.testing.assert_allclose(normal[row], n, atol=1e-14)


def test_sphere_hessian_is_the_derivative_of_its_normal():
    # The closed form grad n = (I - n n^T) / |x - c| that the boundaries use for a Sphere (in
    # place of central differences of its normals) against central differences of the
    # collider's own normal, step 1e-5: O(h^2) ~ 1e-10 / |x - c|^3 agreement.
    sphere = ia.colliders.Sphere(center=(0.2, -0.1, 0.05), radius=0.3)
    field = CurlNoise(dim=3, seed=1, boundaries=[sphere], boundary_width=0.3)
    pts = np.random.default_rng(5).uniform(-0.6, 0.6, (3000, 3))
    slot, count, _, normal, hessian, *_ = field.boundaries.prepare(pts, 0.0)
    near = np.flatnonzero(slot >= 0)
    r = np.linalg.norm(pts[near] - sphere.center, axis=1)
    near = near[r > 0.05]
    assert near.size > 300
    rows = slot[near]
    h = 1e-5
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        fd = (sphere.normal(pts[near] + e) - sphere.normal(pts[near] - e)) / (2 * h)
        np.testing.assert_allclose(hessian[rows, a, :], fd, atol=1e-7)
    np.testing.assert_allclose(normal[rows], sphere.normal(pts[near]), atol=1e-14)


def test_reused_boundary_buffers_give_the_same_velocity():
    # prepare() keeps its arrays between calls (no allocation per step): sampling a large, a
    # small and again the large batch gives, bit for bit, what a fresh field gives.
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3)
    pts = np.random.default_rng(6).uniform(-0.99, 0.99, (3000, 3))
    used = CurlNoise(dim=3, seed=2, boundaries=[sphere, room])
    used(pts[:50], 0.1)
    big = used(pts, 0.3)
    small = used(pts[:700], 0.2)
    np.testing.assert_array_equal(used(pts, 0.3), big)
    fresh = CurlNoise(dim=3, seed=2, boundaries=[sphere, room])
    np.testing.assert_array_equal(fresh(pts, 0.3), big)
    np.testing.assert_array_equal(CurlNoise(dim=3, seed=2, boundaries=[sphere, room])(pts[:700], 0.2), small)


def test_jacobian_not_offered_with_boundaries():
    field = CurlNoise(dim=3, boundaries=[ia.colliders.Sphere(radius=0.2)])
    with pytest.raises(NotImplementedError, match="boundaries"):
        field.jacobian(np.zeros((1, 3)) + 1.0)


# ---------------------------------------------------------------------------------------------
# Velocity = curl of the (boundary-modified) potential, analytic vs. finite differences
# ---------------------------------------------------------------------------------------------

def _scenes():
    sphere = ia.colliders.Sphere(center=(0.1, 0.2, 0.0), radius=0.3)
    plane = ia.colliders.Plane(point=(0.0, 0.0, -0.4), normal=(0.3, 0.1, 1.0))
    moving = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.3, motion=ia.colliders.Motion(
        position=lambda t: (0.4 * t, -0.2 * t, 0.1),
        rotation=lambda t: (0.5 * t, -1.0 * t, 0.8 * t)))
    disc = ia.colliders.Sphere(center=(0.1, 0.2), radius=0.3)
    spinning_box = ia.colliders.Box(center=(0.0, 0.0), half_extents=(0.3, 0.2), motion=ia.colliders.Motion(
        position=lambda t: (0.3 * t, 0.1), rotation=lambda t: 1.5 * t))
    wind3, wind2 = {"mean_velocity": (0.3, -0.2, 1.0)}, {"mean_velocity": (1.0, 0.4)}
    room = ia.colliders.Container(center=(0.1, 0.0, -0.1), half_extents=(0.9, 0.8, 0.7),
                                  rotation=(0.2, -0.1, 0.3))
    moving_room = ia.colliders.Container(center=(0.0, 0.0, 0.0), half_extents=(0.9, 0.8, 0.7),
                                         motion=ia.colliders.Motion(position=lambda t: (0.1 * t, 0.0, 0.0),
                                                                    rotation=lambda t: (0.0, 0.0, 0.3 * t)))
    return {
        "3d-free": (3, [], 1e-7, {}),
        "3d-sphere": (3, [sphere], 1e-5, {}),            # FD Hessian of the distance: ~1e-6
        "3d-analytic-sphere": (3, [AnalyticSphere((0.1, 0.2, 0.0), 0.3)], 1e-7, {}),
        "3d-sphere-plane": (3, [sphere, plane], 1e-5, {}),
        "3d-container": (3, [room], 1e-7, {}),               # planes: no FD Hessian
        "3d-moving-container-sphere": (3, [moving_room, sphere], 1e-5, {}),
        "3d-moving-sphere": (3, [moving], 1e-5, {}),
        "3d-sphere-wind": (3, [sphere], 1e-5, wind3),
        "3d-free-wind": (3, [], 1e-7, wind3),
        "2d-disc": (2, [disc], 1e-7, {}),
        "2d-moving-box": (2, [spinning_box], 1e-7, {}),
        "2d-disc-wind": (2, [disc], 1e-7, wind2),
    }


@pytest.mark.parametrize("scene", list(_scenes()))
def test_velocity_is_curl_of_potential(scene):
    # v from the analytic formula vs. central differences of potential(): checks every term
    # (ramp, normal blend with grad n, rigid motion, mean flow) at once.
    dim, boundaries, tol, extra = _scenes()[scene]
    field = CurlNoise(dim=dim, seed=3, frequency=1.5, octaves=2, time_frequency=0.5,
                      boundaries=boundaries, **extra)
    pts = np.random.default_rng(0).uniform(-1, 1, (3000, dim))
    if boundaries:  # the fluid region (including where the closest wall or collider changes)
        dist = np.stack([b.signed_distance(pts, 0.6) for b in boundaries])
        pts = pts[dist.min(axis=0) > 0.01]
    v = field(pts, 0.6)
    v_fd = _curl_of_potential(field, pts, 0.6)
    assert np.abs(v - v_fd).max() <= tol * np.abs(v).max()


# ---------------------------------------------------------------------------------------------
# Boundaries: tangential flow, moving colliders, tracers never enter
# ---------------------------------------------------------------------------------------------

def _sphere_surface(center, radius, count, seed=0):
    dirs = np.random.default_rng(seed).normal(size=(count, len(center)))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    return np.asarray(center) + radius * dirs, dirs


@pytest.mark.parametrize("time_frequency", [0.0, 0.7])
def test_tangential_at_sphere_and_plane_surfaces(time_frequency):
    # At the surface: |v . n| / max|v| <= 1e-3 (the construction gives ~1e-16).
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.2)
    plane = ia.colliders.Plane(point=(0.0, 0.0, -0.6), normal=(0.0, 0.0, 1.0))
    field = CurlNoise(dim=3, seed=1, frequency=2.0, octaves=2, time_frequency=time_frequency,
                      boundaries=[sphere, plane])
    on_sphere, n_sphere = _sphere_surface((0.0, 0.0, 0.0), 0.2, 4000)
    rng = np.random.default_rng(1)
    on_plane = np.c_[rng.uniform(-2, 2, (4000, 2)), np.full(4000, -0.6)]
    vmax = np.abs(field(_grid(24, -1.0, 1.0, 3)[0], 0.8)).max()
    for pts, normal in ((on_sphere, n_sphere), (on_plane, np.array([0.0, 0.0, 1.0]))):
        v = field(pts, 0.8)
        assert np.abs(np.sum(v * normal, axis=1)).max() / vmax <= 1e-3
        assert np.abs(np.sum(v * normal, axis=1)).max() / vmax <= 1e-12
        # ... while the flow does move along the surface.
        assert np.linalg.norm(v, axis=1).max() > 0.1 * vmax


def test_tangential_in_2d_and_for_other_colliders():
    box = ia.colliders.Box(center=(0.0, 0.0, 0.0), half_extents=(0.3, 0.2, 0.25),
                           rotation=(0.3, -0.2, 0.5))
    capsule = ia.colliders.Capsule(a=(1.0, 0.0, -0.3), b=(1.0, 0.2, 0.3), radius=0.15)
    field = CurlNoise(dim=3, seed=5, frequency=1.0, boundaries=[box, capsule], boundary_width=0.3)
    rng = np.random.default_rng(2)
    # Project random points onto each surface: x - d n.
    for col in (box, capsule):
        pts = rng.uniform(-1.5, 1.5, (20000, 3))
        pts = pts[np.abs(col.signed_distance(pts)) < 0.1]
        pts = pts - col.signed_distance(pts)[:, None] * col.normal(pts)
        pts = pts[np.abs(col.signed_distance(pts)) < 1e-12]
        assert len(pts) > 50
        v = field(pts)
        assert np.abs(np.sum(v * col.normal(pts), axis=1)).max() <= 1e-12 * np.abs(v).max()
    # Flow inside a Container (free space inside, walls facing in): tangent to every wall,
    # finite near the edges where the distance field has kinks (one-sided differences there).
    room = ia.colliders.Container(center=(0.0, 0.0, 0.0), half_extents=(1.0, 0.8, 0.6))
    inside = CurlNoise(dim=3, seed=6, frequency=1.5, octaves=2, boundaries=[room], boundary_width=0.3)
    wall = np.c_[rng.uniform(-1.0, 1.0, 3000), rng.uniform(-0.8, 0.8, 3000), np.full(3000, 0.6)]
    v = inside(wall)
    assert np.abs(v[:, 2]).max() <= 1e-12 * np.abs(v).max()
    bulk = inside(rng.uniform(-1.0, 1.0, (50_000, 3)) * [1.0, 0.8, 0.6])
    assert np.all(np.isfinite(bulk)) and np.abs(bulk).max() < 3.0 * np.abs(v).max()
    disc = ia.colliders.Sphere(center=(0.2, 0.1), radius=0.25)
    line = ia.colliders.Plane(point=(0.0, -0.5), normal=(0.0, 1.0))
    field2 = CurlNoise(dim=2, seed=5, frequency=2.0, octaves=2, boundaries=[disc, line])
    on_disc, n_disc = _sphere_surface((0.2, 0.1), 0.25, 2000)
    on_line = np.c_[rng.uniform(-2, 2, 2000), np.full(2000, -0.5)]
    for pts, normal in ((on_disc, n_disc), (on_line, np.array([0.0, 1.0]))):
        v = field2(pts, 0.0)
        assert np.abs(np.sum(v * normal, axis=1)).max() <= 1e-12 * np.abs(v).max()


def test_container_velocity_continuous_across_medial_planes():
    # Inside a box the closest wall changes across the medial planes (x = y, ...); with every
    # wall's ramp multiplied in, the velocity is continuous there (the old closest-wall blend
    # jumped by O(speed)). Pairs of points 2e-6 apart straddling x = y near the (+x, +y) edge:
    # |v(a) - v(b)| <= |grad v| * 2e-6 ~ 1e-4 for speed 1 and d0 = 0.5.
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    field = CurlNoise(dim=3, seed=7, boundaries=[room])
    rng = np.random.default_rng(3)
    s = rng.uniform(0.55, 0.999, 2000)
    z = rng.uniform(-0.999, 0.999, 2000)
    eps = 1e-6
    a = np.c_[s + eps, s - eps, z]
    b = np.c_[s - eps, s + eps, z]
    assert np.abs(field(a) - field(b)).max() < 1e-4


def test_container_tracer_from_the_issue_stays_inside(one_thread):
    # Issue 8's reproducer: this tracer, near the (-x, +z) edge of a unit box, went from
    # d = +3.4e-3 to -2.2e-3 within 0.05 s under RK4 at dt = 0.005 and 0.001.
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    field = CurlNoise(dim=3, seed=7, boundaries=[room])
    for dt in (0.005, 0.001):
        least, _ = _advect_and_check(field, [room], np.array([[-0.99656, 0.86976, 0.99649]]), dt,
                                     round(0.05 / dt))
        assert least[0] > 0.0, (dt, least)


def test_no_tracer_leaves_a_3d_container_in_10_s(one_thread):
    # Zero of N tracers leave a box over 10 s of RK4 at dt = 0.01 (a step moves a tracer about
    # 2 % of d0 at the RMS speed). Before the continuous wall blend, 53 of 3000 tracers spread
    # uniformly left within 10 s. Here 400 tracers start where leaks happened, within 0.1 of
    # an edge (two walls within d0); `benchmarks/bench_curl_noise.py --leak` runs the full
    # 3000, spread uniformly.
    room = ia.colliders.Container(half_extents=(1.0, 1.0, 1.0))
    field = CurlNoise(dim=3, seed=7, boundaries=[room])
    rng = np.random.default_rng(5)
    x0 = rng.uniform(-0.999, 0.999, (400, 3))
    axis = rng.integers(0, 3, 400)
    for k in range(2):  # push two of the three coordinates to within 0.1 of a wall
        a = (axis + 1 + k) % 3
        x0[np.arange(400), a] = np.sign(x0[np.arange(400), a]) * rng.uniform(0.9, 0.999, 400)
    least, tracers = _advect_and_check(field, [room], x0, 0.01, 1000)
    assert least[0] > 0.0, least
    assert np.median(np.linalg.norm(tracers.x - x0, axis=1)) > 0.5  # they did travel


def test_moving_collider_no_flow_through_surface():
    # Kinematic sphere translating and spinning: at its surface the fluid's normal velocity
    # equals the surface's, (v - u_R) . n = 0.
    motion = ia.colliders.Motion(position=lambda t: (0.5 * t, 0.2 * np.sin(t), 0.0),
                                 rotation=lambda t: (0.0, 0.0, 2.0 * t))
    ball = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.25, motion=motion)
    field = CurlNoise(dim=3, seed=2, frequency=2.0, octaves=2, time_frequency=0.3, boundaries=[ball])
    for t in (0.0, 0.7, 1.9):
        center = ball.pose(t)[0]
        pts, normal = _sphere_surface(center, 0.25, 3000, seed=int(10 * t))
        v = field(pts, t)
        u = ball.velocity(pts, t)
        assert np.abs(np.sum((v - u) * normal, axis=1)).max() <= 1e-9 * np.abs(v).max()
        # The fluid is pushed: ahead of the sphere it moves with the sphere's normal speed.
        assert np.abs(np.sum(v * normal, axis=1)).max() > 0.1


@pytest.fixture
def one_thread():
    """Run on one thread: these tests advect a few hundred tracers for thousands of steps, where
    starting threads for every small collider query (on a loaded 2-core machine, up to ms per
    call) would dominate. Results do not depend on the thread count."""
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(threads)


def test_mean_flow_goes_around_boundaries():
    # speed = 0: only the mean flow U, carried in the potential. Far away v = U exactly; at the
    # surface v . n = 0; in between the flow is deflected (as potential flow past a body is).
    U = np.array([0.0, 0.0, 1.5])
    sphere = ia.colliders.Sphere(center=(0.5, 0.0, 0.0), radius=0.3)
    field = CurlNoise(dim=3, speed=0.0, mean_velocity=U, boundaries=[sphere], boundary_width=0.4)
    far = np.random.default_rng(0).uniform(2.0, 3.0, (100, 3))
    np.testing.assert_allclose(field(far), np.broadcast_to(U, far.shape), atol=1e-15)
    on, normal = _sphere_surface((0.5, 0.0, 0.0), 0.3, 2000)
    v = field(on)
    assert np.abs(np.sum(v * normal, axis=1)).max() <= 1e-12 * 1.5
    # Flow speeds up beside the body (|v| > |U| within d0 of the equator), as it must to carry
    # the flux the body blocks.
    beside = np.c_[0.5 + np.linspace(0.31, 0.7, 40), np.zeros(40), np.zeros(40)]
    assert np.linalg.norm(field(beside), axis=1).max() > 1.2 * 1.5
    with pytest.raises(ValueError, match="mean_velocity"):
        CurlNoise(dim=2, mean_velocity=(1.0, 0.0, 0.0))


def _advect_and_check(field, colliders, x0, dt, steps):
    """Advect tracers with ia.Tracers + ia.Simulation (RK4); return the least signed distance
    to each collider seen over all steps."""
    tracers = ia.Tracers(x0, field)
    sim = ia.Simulation(tracers, integrator="rk4", dt=dt)
    least = np.full(len(colliders), np.inf)
    for _ in range(steps):
        sim.step()
        for k, c in enumerate(colliders):
            least[k] = min(least[k], c.signed_distance(tracers.x, sim.t).min())
    return least, tracers


def test_tracers_never_enter_sphere_or_plane_over_10k_steps(one_thread):
    # Tracers start within 0.05 of the surfaces, where the flow runs along them; RK4 at a step
    # that moves a tracer ~0.6 % of the boundary width keeps them out for 10^4 steps.
    sphere = ia.colliders.Sphere(center=(0.0, 0.0, 0.0), radius=0.2)
    plane = ia.colliders.Plane(point=(0.0, 0.0, -0.6), normal=(0.0, 0.0, 1.0))
    field = ia.fields.CurlNoise(dim=3, seed=1, frequency=2.0, octaves=2, time_frequency=0.5,
                                boundaries=[sphere, plane])
    rng = np.random.default_rng(0)
    _, dirs = _sphere_surface((0.0, 0.0, 0.0), 1.0, 100)
    near_sphere = dirs * (0.2 + rng.uniform(0.001, 0.05, (100, 1)))
    near_plane = np.c_[rng.uniform(-0.5, 0.5, (60, 2)), rng.uniform(-0.599, -0.55, 60)]
    x0 = np.vstack([near_sphere, near_plane])
    least, tracers = _advect_and_check(field, [sphere, plane], x0, 1e-3, 10_000)
    assert np.all(least > 0.0), least
    # They did travel (10 s at ~1 m/s RMS).
    assert np.median(np.linalg.norm(tracers.x - x0, axis=1)) > 0.5


def test_tracers_never_enter_moving_collider_2d(one_thread):
    # A disc sweeping through 2-D curl-noise: tracers ahead of it are pushed aside, not run over.
    motion = ia.colliders.Motion(position=lambda t: (-0.8 + 0.4 * t, 0.1 * np.sin(3 * t)))
    disc = ia.colliders.Sphere(center=(-0.8, 0.0), radius=0.2, motion=motion)
    field = CurlNoise(dim=2, seed=3, frequency=2.0, octaves=2, speed=0.5, boundaries=[disc],
                      boundary_width=0.2)
    rng = np.random.default_rng(4)
    x0 = rng.uniform(-0.5, 1.0, (4000, 2))
    x0 = x0[disc.signed_distance(x0, 0.0) > 0.01][:200]
    least, _ = _advect_and_check(field, [disc], x0, 1e-3, 4000)
    assert least[0] > 0.0


# ---------------------------------------------------------------------------------------------
# Determinism, scaling, integration with forces, validation
# ---------------------------------------------------------------------------------------------

def test_same_seed_same_flow_any_thread_count():
    pts = np.random.default_rng(0).uniform(-1, 1, (50_000, 3))
    sphere = ia.colliders.Sphere(radius=0.3)
    a = CurlNoise(dim=3, seed=9, octaves=3, time_frequency=0.4, boundaries=[sphere])
    b = CurlNoise(dim=3, seed=9, octaves=3, time_frequency=0.4, boundaries=[sphere])
    c = CurlNoise(dim=3, seed=10, octaves=3, time_frequency=0.4, boundaries=[sphere])
    va = a(pts, 1.0)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        vb = b(pts, 1.0)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(va, vb)
    # Small batches take the serial kernel (chosen by batch size, never by thread count, so a scene's
    # result does not depend on the threads): a separately compiled function whose rounding may differ
    # by an ulp (seen twice under cache churn), so this check is to rounding, not bits.
    np.testing.assert_allclose(a(pts[:100], 1.0), va[:100], rtol=1e-12, atol=1e-12 * np.abs(va).max())
    assert np.abs(va - c(pts, 1.0)).max() > 0.1


def test_speed_is_the_rms_speed():
    for dim in (2, 3):
        for kind in ("simplex", "perlin"):
            field = CurlNoise(dim=dim, kind=kind, frequency=3.0, octaves=2, speed=2.5)
            v = field(np.random.default_rng(1).uniform(-20, 20, (100_000, dim)))
            rms = np.sqrt(np.mean(np.sum(v * v, axis=1)))
            assert abs(rms - 2.5) < 0.05 * 2.5
    assert np.all(CurlNoise(dim=3, speed=0.0)(np.ones((3, 3))) == 0.0)


def test_time_varying():
    pts = np.random.default_rng(0).uniform(-1, 1, (2000, 3))
    steady = CurlNoise(dim=3, seed=1)
    np.testing.assert_array_equal(steady(pts, 0.0), steady(pts, 3.0))
    evolving = CurlNoise(dim=3, seed=1, time_frequency=0.5)
    assert np.abs(evolving(pts, 0.0) - evolving(pts, 3.0)).max() > 0.5
    assert np.abs(evolving(pts, 1.0) - evolving(pts, 1.0 + 1e-7)).max() < 1e-5


def test_issue_example_and_wind_force():
    # The API example of the issue, used as wind on particles with mass: with drag
    # f = k (w - v) and k/m large, the particles follow the air, v -> w(x).
    field = ia.fields.CurlNoise(dim=3, seed=1, frequency=2.0, octaves=2,
                                boundaries=[ia.colliders.Sphere(center=(0, 0, 0), radius=0.2)])
    x0 = np.random.default_rng(0).uniform(-1, 1, (200, 3))
    x0 = x0[np.linalg.norm(x0, axis=1) > 0.3]
    ps = ia.ParticleSystem(positions=x0, masses=0.01)
    ps.add_force(ia.forces.Wind(field, coefficient=1.0))
    sim = ia.Simulation(ps, integrator="rk4", dt=1e-3)
    sim.run(0.3)
    # Relaxation time m/k = 0.01 s; after 30 of them the lag is ~ (m/k) |dw/dt| ~ 0.01 * 10.
    assert np.abs(ps.v - field(ps.x, sim.t)).max() < 0.2 * np.abs(field(ps.x)).max()
    # As a ForceField: a field of accelerations, f = m a(x, t).
    ps2 = ia.ParticleSystem(positions=x0, masses=2.0)
    ps2.add_force(ia.forces.ForceField(lambda x, v, t: field(x, t), per_mass=True))
    accel = np.empty_like(ps2.x)
    ps2.acceleration(ps2.x.ravel(), ps2.v.ravel(), 0.0, accel.ravel())
    np.testing.assert_allclose(accel, field(x0, 0.0), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kwargs,name", [
    (dict(dim=4), "dim"),
    (dict(dim=3, kind="worley"), "kind"),
    (dict(dim=3, seed=-3), "seed"),
    (dict(dim=3, octaves=20), "octaves"),
    (dict(dim=3, frequency=-1.0), "frequency"),
    (dict(dim=3, speed=-1.0), "speed"),
    (dict(dim=3, boundary_width=0.0), "boundary_width"),
    (dict(dim=3, boundaries=[object()]), "boundaries"),
    (dict(dim=2, boundaries=[ia.colliders.Sphere(center=(0, 0, 0), radius=0.2)]), "boundaries"),
])
def test_validation_names_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        CurlNoise(**kwargs)


def test_sample_checks_shapes():
    field = CurlNoise(dim=3)
    with pytest.raises(ValueError, match="out"):
        field.sample(np.zeros((4, 3)), 0.0, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="points"):
        field(np.zeros((4, 2)))
