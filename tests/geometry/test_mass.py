"""Tests for inertia.geometry.mass: closed forms against independent slice integration (scipy quad),
exact polyhedral integration against the unit cube, Tonon's (2005) published tetrahedron and exact rational
arithmetic, regular polyhedra (Satterly 1958) and Archimedean solids (Perrier 2015), parallel axis, compounds and
principal frames; the common solids (hemisphere, torus, thin rod, tubes, shells, cone) against the textbook
table (Hibbeler, Engineering Mechanics: Dynamics), slices and fine revolved polyhedra."""

import math
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.spatial.transform import Rotation

from inertia import math as im
from inertia.geometry import mass as gm
from inertia.geometry.convex import build_convex_hull

RNG = np.random.default_rng(9)


def rel(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b))


# ----------------------------------------------------------------------------------------- closed forms
def revolution_integrals(radius_sq, z0, z1, rho, breaks=()):
    """Mass, z-centroid and inertia (about the centroid) of a solid of revolution about z, by integrating
    thin discs of squared radius s2(z): dm = rho pi s2 dz, dI_zz = dm s2 / 2, dI_xx = dm (s2 / 4 + z^2).
    (s2 is a polynomial on each piece for all our shapes, so Gauss-Kronrod quadrature is exact to rounding.)"""
    def q(f, epsabs=0.0):
        return quad(f, z0, z1, points=breaks or None, epsabs=epsabs, epsrel=1e-12, limit=200)[0]
    m = q(lambda z: rho * math.pi * radius_sq(z))
    zc = q(lambda z: rho * math.pi * radius_sq(z) * z, epsabs=1e-13 * m * (z1 - z0)) / m
    izz = q(lambda z: rho * math.pi * radius_sq(z) ** 2 / 2)
    ixx = q(lambda z: rho * math.pi * radius_sq(z) * (radius_sq(z) / 4 + (z - zc) ** 2))
    return m, zc, ixx, izz


def check_revolution(props, m, zc, ixx, izz):
    assert props.mass == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(props.com, [0, 0, 0], atol=1e-12)
    assert zc == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(np.diag(props.inertia), [ixx, ixx, izz], rtol=1e-12)
    np.testing.assert_array_equal(props.inertia - np.diag(np.diag(props.inertia)), 0.0)


def test_solid_sphere_and_thick_shell_against_slices():
    r, rho = 0.7, 1300.0
    check_revolution(gm.sphere_mass_properties(r, rho),
                     *revolution_integrals(lambda z: r * r - z * z, -r, r, rho))
    # thick shell = sphere(r) - sphere(ri): the difference of the two slice integrals
    ri = 0.5
    outer = revolution_integrals(lambda z: r * r - z * z, -r, r, rho)
    inner = revolution_integrals(lambda z: ri * ri - z * z, -ri, ri, rho)
    shell = gm.sphere_mass_properties(r, rho, inner_radius=ri)
    assert shell.mass == pytest.approx(outer[0] - inner[0], rel=1e-12)
    assert shell.inertia[0, 0] == pytest.approx(outer[2] - inner[2], rel=1e-12)


def test_thin_shell_is_the_limit_of_thick_shells():
    # I = 2/5 m (r^5 - ri^5)/(r^3 - ri^3) -> 2/3 m r^2 as ri -> r, with error O(t) for thickness t
    r = 1.3
    thin = gm.thin_spherical_shell_mass_properties(r, 2.0)
    assert thin.mass == pytest.approx(4 * math.pi * r * r * 2.0, rel=1e-15)
    errors = []
    for t in (1e-2, 5e-3):
        thick = gm.sphere_mass_properties(r, 1.0, inner_radius=r - t)
        errors.append(abs(thick.inertia[0, 0] / thick.mass - thin.inertia[0, 0] / thin.mass))
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.02)  # first order in t


def test_cylinder_capsule_cone_against_slices():
    r, h, rho = 0.3, 0.8, 700.0
    check_revolution(gm.cylinder_mass_properties(r, h, rho), *revolution_integrals(lambda z: r * r, -h, h, rho))

    def capsule_radius_sq(z):
        if abs(z) <= h:
            return r * r
        return r * r - (abs(z) - h) ** 2
    check_revolution(gm.capsule_mass_properties(r, h, rho),
                     *revolution_integrals(capsule_radius_sq, -h - r, h + r, rho, breaks=(-h, h)))
    # a capsule of zero segment is a sphere
    np.testing.assert_allclose(gm.capsule_mass_properties(r, 0.0, rho).inertia,
                               gm.sphere_mass_properties(r, rho).inertia, rtol=1e-15)

    height = 1.7
    # base at z = -H/4, apex at 3H/4: radius shrinks linearly to 0
    check_revolution(gm.cone_mass_properties(r, height, rho),
                     *revolution_integrals(lambda z: (r * (0.75 * height - z) / height) ** 2, -0.25 * height,
                                           0.75 * height, rho))


def test_ellipsoid_against_elliptic_slices():
    a, b, c, rho = 0.4, 0.9, 1.3, 250.0
    # slice at z: ellipse with semi-axes a s, b s, s = sqrt(1 - z^2/c^2); area pi a b s^2,
    # integral x^2 dA = pi a^3 b s^4 / 4, integral y^2 dA = pi a b^3 s^4 / 4
    def q(f):
        return quad(f, -c, c, epsabs=0, epsrel=1e-12)[0]
    s2 = lambda z: 1 - z * z / (c * c)  # noqa: E731
    m = q(lambda z: rho * math.pi * a * b * s2(z))
    xx = q(lambda z: rho * math.pi * a ** 3 * b * s2(z) ** 2 / 4)
    yy = q(lambda z: rho * math.pi * a * b ** 3 * s2(z) ** 2 / 4)
    zz = q(lambda z: rho * math.pi * a * b * s2(z) * z * z)
    props = gm.ellipsoid_mass_properties([a, b, c], rho)
    assert props.mass == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(np.diag(props.inertia), [yy + zz, xx + zz, xx + yy], rtol=1e-12)


def box_mesh(half_extents, centre=(0.0, 0.0, 0.0)):
    """The 8 corners and 12 outward-wound triangles of a box."""
    hx, hy, hz = half_extents
    v = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    hull = build_convex_hull(v + np.asarray(centre))
    return hull.vertices, hull.triangles


def test_box_closed_form_equals_polyhedral_integration():
    half = (0.3, 0.5, 1.1)
    closed = gm.box_mass_properties(half, 2.5)
    v, t = box_mesh(half)
    poly = gm.mesh_mass_properties(v, t, 2.5)
    assert poly.mass == pytest.approx(closed.mass, rel=1e-12)
    assert rel(poly.inertia, closed.inertia) < 1e-12
    np.testing.assert_allclose(poly.com, 0.0, atol=1e-15)


# ------------------------------------------------------------------------------------------- polyhedra
def test_unit_cube_about_centre_and_corner():
    # unit cube, unit density: I_centre = 1/6 E; about a corner (parallel axis, d = (1/2, 1/2, 1/2)):
    # I = [[2/3, -1/4, -1/4], [-1/4, 2/3, -1/4], [-1/4, -1/4, 2/3]]
    v, t = box_mesh((0.5, 0.5, 0.5), centre=(0.5, 0.5, 0.5))
    cube = gm.mesh_mass_properties(v, t, 1.0)
    assert cube.mass == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(cube.com, [0.5, 0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(cube.inertia, np.eye(3) / 6, atol=1e-12)
    corner = gm.parallel_axis(cube.inertia, cube.mass, -cube.com)
    expected = np.full((3, 3), -0.25) + np.eye(3) * (2 / 3 + 0.25)
    np.testing.assert_allclose(corner, expected, atol=1e-12)


TONON_VERTICES = [("8.33220", "-11.86875", "0.93355"), ("0.75523", "5.00000", "16.37072"),
                  ("52.61236", "5.00000", "-5.38580"), ("2.00000", "5.00000", "3.00000")]


def tonon_exact():
    """Tonon (2005) eq. 7-9 in exact rational arithmetic for the printed vertices: the centroid and the
    inertia entries a, b, c (moments about axes through the centroid) and a', b', c' (the products
    integral y z, x z, x y about the centroid), for unit density."""
    p = [[Fraction(x) for x in row] for row in TONON_VERTICES]
    c = [sum(row[k] for row in p) / 4 for k in range(3)]
    q = [[row[k] - c[k] for k in range(3)] for row in p]
    (x1, y1, z1), (x2, y2, z2), (x3, y3, z3), (x4, y4, z4) = q
    det = ((x2 - x1) * ((y3 - y1) * (z4 - z1) - (z3 - z1) * (y4 - y1))
           - (y2 - y1) * ((x3 - x1) * (z4 - z1) - (z3 - z1) * (x4 - x1))
           + (z2 - z1) * ((x3 - x1) * (y4 - y1) - (y3 - y1) * (x4 - x1)))
    det = abs(det)

    def sq(u):  # u1^2 + ... + u1 u2 + ...  (Tonon's symmetric quadratic)
        return sum(u[i] * u[j] for i in range(4) for j in range(i, 4))

    def mixed(u, w):  # 2 u1 w1 + ... + u1 w2 + u2 w1 + ...
        return sum((2 if i == j else 1) * u[i] * w[j] for i in range(4) for j in range(4) if i <= j) + \
            sum(u[j] * w[i] for i in range(4) for j in range(4) if i < j)
    xs, ys, zs = [r[0] for r in q], [r[1] for r in q], [r[2] for r in q]
    a = det * (sq(ys) + sq(zs)) / 60
    b = det * (sq(xs) + sq(zs)) / 60
    cc = det * (sq(xs) + sq(ys)) / 60
    a_p = det * mixed(ys, zs) / 120
    b_p = det * mixed(xs, zs) / 120
    c_p = det * mixed(xs, ys) / 120
    return det / 6, c, (a, b, cc, a_p, b_p, c_p)


def tonon_mesh():
    v = np.array([[float(Fraction(x)) for x in row] for row in TONON_VERTICES])
    return v, np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 2, 3]])


def test_tonon_tetrahedron_exact_and_published():
    v, t = tonon_mesh()
    props = gm.mesh_mass_properties(v, t, 1.0)
    vol, centroid, (a, b, c, a_p, b_p, c_p) = tonon_exact()
    # inertia tensor [[a, -c', -b'], [-c', b, -a'], [-b', -a', c]] (a' = int yz, b' = int xz, c' = int xy)
    exact = np.array([[a, -c_p, -b_p], [-c_p, b, -a_p], [-b_p, -a_p, c]], dtype=float)
    assert props.mass == pytest.approx(float(vol), rel=1e-13)
    np.testing.assert_allclose(props.com, [float(x) for x in centroid], rtol=1e-13)
    assert rel(props.inertia, exact) < 1e-12
    # Tonon's published values (Journal of Mathematics and Statistics 1(1), 2005, p. 10), unit density:
    # a = 43520.33257, b = 194711.28938, c = 191168.76173, a' = 4417.66150, b' = -46343.16662,
    # c' = 11996.20119, centroid (15.92492, 0.78281, 3.72962).  The paper's printed vertices are rounded to
    # 5 decimals (its centroid x differs from the mean of the printed vertices, 15.9249475, by 2.8e-5), so
    # the published tensor is only consistent with them to ~2e-8 relative; we check to 5e-8.
    published = np.array([[43520.33257, -11996.20119, 46343.16662],
                          [-11996.20119, 194711.28938, -4417.66150],
                          [46343.16662, -4417.66150, 191168.76173]])
    assert rel(props.inertia, published) < 5e-8
    np.testing.assert_allclose(props.com, [15.92492, 0.78281, 3.72962], atol=3e-5)


def regular_tetrahedron(edge):
    v = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float) * edge / (2 * math.sqrt(2))
    return v


def test_regular_polyhedra_closed_forms():
    # regular tetrahedron of edge L: V = L^3 / (6 sqrt 2), I = m L^2 / 20 about any centroidal axis;
    # regular octahedron of edge L: V = sqrt(2) L^3 / 3, I = m L^2 / 10
    L = 1.7
    tet = gm.convex_hull_mass_properties(regular_tetrahedron(L), 3.0)
    assert tet.mass == pytest.approx(3.0 * L ** 3 / (6 * math.sqrt(2)), rel=1e-13)
    np.testing.assert_allclose(tet.inertia, np.eye(3) * tet.mass * L * L / 20, rtol=0,
                               atol=1e-12 * tet.inertia[0, 0])
    a = L / math.sqrt(2)
    octa = np.array([[a, 0, 0], [-a, 0, 0], [0, a, 0], [0, -a, 0], [0, 0, a], [0, 0, -a]])
    oct_props = gm.convex_hull_mass_properties(octa, 1.0)
    assert oct_props.mass == pytest.approx(math.sqrt(2) * L ** 3 / 3, rel=1e-13)
    np.testing.assert_allclose(oct_props.inertia, np.eye(3) * oct_props.mass * L * L / 10, rtol=0,
                               atol=1e-12 * oct_props.inertia[0, 0])


def _signed_permutations(base, cyclic):
    """Every sign choice of `base` under its cyclic (or all) coordinate permutations, without repeats."""
    import itertools
    perms = ([(0, 1, 2), (1, 2, 0), (2, 0, 1)] if cyclic else list(itertools.permutations(range(3))))
    out = set()
    for perm in perms:
        for signs in itertools.product((1.0, -1.0), repeat=3):
            out.add(tuple(round(s * base[k], 15) + 0.0 for s, k in zip(signs, perm)))
    return np.array(sorted(out))


PHI = (1 + math.sqrt(5)) / 2


@pytest.mark.parametrize("name, points, edge, volume, inertia_over_m_a2", [
    # Satterly (1958), The Moments of Inertia of Some Polyhedra, Math. Gazette 42: I = c m a^2 about any
    # centroidal axis, icosahedron c = (3 + sqrt 5) / 20, dodecahedron c = (95 + 39 sqrt 5) / 300;
    # volumes 5 (3 + sqrt 5) a^3 / 12 and (15 + 7 sqrt 5) a^3 / 4.
    ("icosahedron", _signed_permutations((0.0, 1.0, PHI), cyclic=True), 2.0,
     5 * (3 + math.sqrt(5)) / 12 * 8.0, (3 + math.sqrt(5)) / 20),
    ("dodecahedron", np.vstack([_signed_permutations((1.0, 1.0, 1.0), cyclic=True),
                                _signed_permutations((0.0, 1 / PHI, PHI), cyclic=True)]), 2 / PHI,
     (15 + 7 * math.sqrt(5)) / 4 * (2 / PHI) ** 3, (95 + 39 * math.sqrt(5)) / 300),
    # Perrier (2015), Moments of inertia of Archimedean solids: cuboctahedron c = 7/25 (V = 5 sqrt 2 a^3 / 3),
    # truncated octahedron c = 19/24 (V = 8 sqrt 2 a^3).
    ("cuboctahedron", _signed_permutations((1.0, 1.0, 0.0), cyclic=False), math.sqrt(2),
     5 * math.sqrt(2) / 3 * 2 * math.sqrt(2), 7 / 25),
    ("truncated octahedron", _signed_permutations((0.0, 1.0, 2.0), cyclic=False), math.sqrt(2),
     8 * math.sqrt(2) * 2 * math.sqrt(2), 19 / 24),
])
def test_platonic_and_archimedean_solids_match_published_values(name, points, edge, volume,
                                                                 inertia_over_m_a2):
    # the divergence-theorem integration is exact, so only rounding separates it from the closed forms
    props = gm.convex_hull_mass_properties(points, 2.5)
    assert props.mass == pytest.approx(2.5 * volume, rel=1e-12), name
    np.testing.assert_allclose(props.com, 0.0, atol=1e-12)
    expected = inertia_over_m_a2 * props.mass * edge ** 2
    np.testing.assert_allclose(props.inertia, np.eye(3) * expected, rtol=0, atol=1e-11 * expected)


def test_polyhedral_integration_is_frame_covariant():
    # a rigid motion of the vertices moves the com and rotates the tensor: I' = R I R^T
    pts = RNG.normal(size=(40, 3))
    base = gm.convex_hull_mass_properties(pts, 1.0)
    r = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
    shift = np.array([10.0, -3.0, 7.0])
    moved = gm.convex_hull_mass_properties(pts @ r.T + shift, 1.0)
    assert moved.mass == pytest.approx(base.mass, rel=1e-12)
    np.testing.assert_allclose(moved.com, r @ base.com + shift, atol=1e-12)
    assert rel(moved.inertia, r @ base.inertia @ r.T) < 1e-11


def test_bad_meshes_and_arguments_raise():
    v, t = tonon_mesh()
    with pytest.raises(ValueError, match="inside out"):
        gm.mesh_mass_properties(v, t[:, ::-1], 1.0)
    with pytest.raises(ValueError, match="not closed"):
        gm.mesh_mass_properties(np.vstack([v, [[0, 0, 0]]]),
                                np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 2, 4]]), 1.0)
    with pytest.raises(ValueError, match="consistently wound"):
        gm.mesh_mass_properties(v, np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 3, 2]]), 1.0)
    with pytest.raises(ValueError, match="at least 4 points"):
        gm.convex_hull_mass_properties(v[:3], 1.0)
    with pytest.raises(ValueError, match="coplanar"):
        gm.convex_hull_mass_properties(np.c_[RNG.normal(size=(10, 2)), np.zeros(10)], 1.0)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="density"):
            gm.box_mass_properties((1, 1, 1), bad)
    with pytest.raises(ValueError, match="mass"):
        gm.box_mass_properties((1, 1, 1), 1.0).scaled_to_mass(0.0)
    with pytest.raises(ValueError, match="half_extents"):
        gm.box_mass_properties((1, -1, 1), 1.0)
    with pytest.raises(ValueError, match="radius"):
        gm.sphere_mass_properties(-1.0, 1.0)
    with pytest.raises(ValueError, match="inner_radius"):
        gm.sphere_mass_properties(1.0, 1.0, inner_radius=1.0)
    with pytest.raises(ValueError, match="static"):
        gm.shape_mass_properties(6, [0, 0, 0, 0], 1.0)


# ------------------------------------------------------------------------------- frames and compounds
def test_two_boxes_make_one_box():
    # boxes 1 x 1 x 1 at x = -0.5 and x = +0.5 (half extents 0.5) equal one box with half extents (1, .5, .5)
    half = gm.box_mass_properties((0.5, 0.5, 0.5), 3.0)
    poses = [np.array([-0.5, 0, 0, 1, 0, 0, 0.0]), np.array([0.5, 0, 0, 1, 0, 0, 0.0])]
    both = gm.compound_mass_properties([half, half], poses)
    whole = gm.box_mass_properties((1.0, 0.5, 0.5), 3.0)
    assert both.mass == pytest.approx(whole.mass, rel=1e-15)
    np.testing.assert_allclose(both.com, 0.0, atol=1e-15)
    assert rel(both.inertia, whole.inertia) < 1e-14


def test_rotated_compound_and_principal_frame():
    # a box rotated by R and shifted: its principal frame recovers the box's moments and R (up to the
    # symmetry of a box: columns match R's up to sign and order)
    half = np.array([0.2, 0.5, 0.9])
    box = gm.box_mass_properties(half, 1.0)
    q = im.quat_from_axis_angle(np.array([1.0, 2.0, -0.5]), 0.9)
    pose = np.concatenate([[1.0, 2.0, 3.0], q])
    moved = gm.compound_mass_properties([box], [pose])
    frame = gm.principal_frame(moved)
    np.testing.assert_allclose(frame.com, [1, 2, 3], atol=1e-14)
    np.testing.assert_allclose(frame.inertia_diag, np.sort(np.diag(box.inertia)), rtol=1e-12)
    r_body = im.quat_to_mat3(frame.rotation)
    np.testing.assert_allclose(r_body.T @ moved.inertia @ r_body, np.diag(frame.inertia_diag),
                               atol=1e-12 * frame.inertia_diag.max())
    assert np.linalg.det(r_body) == pytest.approx(1.0, abs=1e-12)
    # box moments ascending <=> half extents descending along the rotated axes: |R^T R_body| = permutation
    perm = np.abs(im.quat_to_mat3(q).T @ r_body)
    np.testing.assert_allclose(np.sort(perm, axis=0)[-1], 1.0, atol=1e-12)


def test_parallel_axis_matches_direct_integration():
    # the tensor of a mesh about an arbitrary point equals the parallel-axis shift of the centroidal one
    pts = RNG.normal(size=(30, 3))
    props = gm.convex_hull_mass_properties(pts, 2.0)
    point = np.array([0.3, -2.0, 1.5])
    moved = gm.convex_hull_mass_properties(pts - point, 2.0)  # same solid, origin at `point`
    about_origin = gm.parallel_axis(moved.inertia, moved.mass, moved.com)
    np.testing.assert_allclose(gm.parallel_axis(props.inertia, props.mass, props.com - point), about_origin,
                               rtol=1e-12)
    # and directly: integral (|x|^2 E - x x^T) dm about the new origin, from the raw moments
    hull = build_convex_hull(pts - point)
    _, first, second, ref = gm._polyhedron_integrals(hull.vertices, hull.triangles.astype(np.int64))
    vol = moved.mass / 2.0
    cov0 = 2.0 * (second + np.outer(ref, first) + np.outer(first, ref) + vol * np.outer(ref, ref))
    np.testing.assert_allclose(about_origin, np.trace(cov0) * np.eye(3) - cov0, rtol=1e-11)


def test_shape_table_dispatch():
    np.testing.assert_array_equal(gm.shape_mass_properties(1, [0.1, 0.2, 0.3, 0], 5.0).inertia,
                                  gm.box_mass_properties((0.1, 0.2, 0.3), 5.0).inertia)
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    hull_props = gm.shape_mass_properties(4, [0, 0, 0, 0], 1.0, vertices=cube)
    np.testing.assert_allclose(hull_props.inertia, np.eye(3) / 6, atol=1e-12)


# --------------------------------------------------------- common solids: closed forms, slices, polyhedra
def revolve(profile, n_theta):
    """Closed outward-wound triangle mesh of the solid swept by the closed polygon ``profile`` [(rho, z), ...]
    of the half plane rho >= 0 about z (n_theta segments; profile points on the axis become one pole vertex)."""
    prof = np.asarray(profile, float)
    theta = 2 * np.pi * np.arange(n_theta) / n_theta
    verts, index = [], []
    for rho, z in prof:
        if rho == 0.0:
            index.append([len(verts)] * n_theta)
            verts.append([0.0, 0.0, z])
        else:
            index.append(list(range(len(verts), len(verts) + n_theta)))
            verts.extend([rho * math.cos(t), rho * math.sin(t), z] for t in theta)
    tris = []
    for k in range(len(prof)):
        a_row, b_row = index[k], index[(k + 1) % len(prof)]
        for j in range(n_theta):
            j1 = (j + 1) % n_theta
            for tri in ((a_row[j], b_row[j], b_row[j1]), (a_row[j], b_row[j1], a_row[j1])):
                if len(set(tri)) == 3:
                    tris.append(tri)
    verts, tris = np.array(verts), np.array(tris, np.int64)
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    if np.einsum("ij,ij->i", a, np.cross(b, c)).sum() < 0:      # profile given clockwise: turn the faces
        tris = tris[:, ::-1].copy()
    return verts, tris


def arc(cx, cz, radius, a0, a1, n):
    t = np.linspace(a0, a1, n + 1)
    return np.stack([cx + radius * np.cos(t), cz + radius * np.sin(t)], axis=1)


def polyhedral_error(props, profile_of_n, rho):
    """Relative error of ``props`` against the revolved polyhedron at two resolutions; it must fall about
    fourfold when the tessellation doubles (second-order convergence of inscribed polygons)."""
    errs = []
    for n in (48, 96):
        poly = gm.mesh_mass_properties(*revolve(profile_of_n(n), 2 * n), rho)
        scale = np.abs(props.inertia).max()
        length = math.sqrt(scale / props.mass)
        errs.append(max(abs(poly.mass / props.mass - 1), np.abs(poly.com - props.com).max() / length,
                        np.abs(poly.inertia - props.inertia).max() / scale))
    return errs


def assert_converges(errs, tol):
    assert errs[1] < tol, errs
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=0.15), errs


def test_hemisphere_closed_form_slices_and_polyhedron():
    # textbook (Hibbeler, Dynamics, inside back cover): centroid 3r/8 from the flat face, I_zz = 2/5 m r^2,
    # I_perp = 83/320 m r^2 about the centroid
    r, rho = 0.6, 900.0
    p = gm.hemisphere_mass_properties(r, rho)
    assert p.mass == pytest.approx(2 / 3 * math.pi * r ** 3 * rho, rel=1e-15)
    np.testing.assert_allclose(p.com, [0, 0, 3 * r / 8], rtol=1e-15)
    np.testing.assert_allclose(np.diag(p.inertia), [83 / 320 * p.mass * r * r] * 2 + [0.4 * p.mass * r * r],
                               rtol=1e-14)
    np.testing.assert_allclose(p.inertia_about(), np.eye(3) * 0.4 * p.mass * r * r, rtol=1e-14)
    m, zc, ixx, izz = revolution_integrals(lambda z: r * r - z * z, 0.0, r, rho)
    assert (p.mass, p.com[2]) == (pytest.approx(m, rel=1e-12), pytest.approx(zc, rel=1e-12))
    np.testing.assert_allclose(np.diag(p.inertia), [ixx, ixx, izz], rtol=1e-12)
    assert_converges(polyhedral_error(p, lambda n: np.vstack([[0, 0], arc(0, 0, r, 0, np.pi / 2, n)]), rho), 2e-3)
    # a bowl (thick hemispherical shell) is the difference of two hemispheres
    ri = 0.45
    bowl = gm.hemisphere_mass_properties(r, rho, inner_radius=ri)
    inner = gm.hemisphere_mass_properties(ri, rho)
    assert bowl.mass == pytest.approx(p.mass - inner.mass, rel=1e-14)
    assert bowl.mass * bowl.com[2] == pytest.approx(p.mass * p.com[2] - inner.mass * inner.com[2], rel=1e-14)
    np.testing.assert_allclose(bowl.inertia_about(), p.inertia_about() - inner.inertia_about(), rtol=1e-13)
    bowl_profile = lambda n: np.vstack([arc(0, 0, r, 0, np.pi / 2, n), arc(0, 0, ri, np.pi / 2, 0, n)])  # noqa: E731
    assert_converges(polyhedral_error(bowl, bowl_profile, rho), 2e-3)


def test_torus_closed_form_pappus_and_polyhedron():
    # I_zz = m (R^2 + 3a^2/4), I_perp = m (R^2/2 + 5a^2/8); volume 2 pi R x pi a^2 (Pappus)
    big, a, rho = 0.5, 0.15, 1200.0
    p = gm.torus_mass_properties(big, a, rho)
    assert p.mass == pytest.approx(2 * math.pi * big * math.pi * a * a * rho, rel=1e-15)
    np.testing.assert_allclose(np.diag(p.inertia), [p.mass * (big ** 2 / 2 + 5 * a * a / 8)] * 2
                               + [p.mass * (big ** 2 + 0.75 * a * a)], rtol=1e-15)
    assert_converges(polyhedral_error(p, lambda n: arc(big, 0, a, 0, 2 * np.pi, n)[:-1], rho), 2e-3)
    # independently by slices in z: the section at height z is the annulus R -+ sqrt(a^2 - z^2)
    def ring(f):
        return quad(lambda z: f(big + math.sqrt(a * a - z * z), big - math.sqrt(a * a - z * z), z), -a, a,
                    epsabs=0, epsrel=1e-12)[0]
    izz = ring(lambda o, i, z: rho * math.pi * (o ** 4 - i ** 4) / 2)
    ixx = ring(lambda o, i, z: rho * math.pi * ((o ** 4 - i ** 4) / 4 + (o * o - i * i) * z * z))
    np.testing.assert_allclose(np.diag(p.inertia), [ixx, ixx, izz], rtol=1e-9)


def test_thin_rod_about_centre_and_end_is_the_limit_of_thin_cylinders():
    length, lam = 1.2, 3.0
    rod = gm.thin_rod_mass_properties(length, lam)
    m = lam * length
    np.testing.assert_allclose(np.diag(rod.inertia), [m * length ** 2 / 12] * 2 + [0.0], rtol=1e-15)
    end = gm.thin_rod_mass_properties(length, lam, origin="end")
    np.testing.assert_allclose(end.com, [0, 0, length / 2])
    np.testing.assert_allclose(np.diag(end.inertia_about()), [m * length ** 2 / 3] * 2 + [0.0], rtol=1e-15)
    # a solid cylinder of radius eps and the same mass per length: I_perp - m L^2/12 = m eps^2 / 4
    for eps in (1e-2, 1e-3):
        cyl = gm.cylinder_mass_properties(eps, length / 2, lam / (math.pi * eps * eps))
        assert cyl.inertia[0, 0] - rod.inertia[0, 0] == pytest.approx(m * eps * eps / 4, rel=1e-9)


def test_hollow_cylinder_open_and_closed():
    ro, ri, h, rho = 0.4, 0.3, 0.5, 800.0
    tube = gm.hollow_cylinder_mass_properties(ro, ri, h, rho)
    m = 2 * math.pi * (ro * ro - ri * ri) * h * rho
    assert tube.mass == pytest.approx(m, rel=1e-14)
    np.testing.assert_allclose(np.diag(tube.inertia), [m * ((ro * ro + ri * ri) / 4 + h * h / 3)] * 2
                               + [m * (ro * ro + ri * ri) / 2], rtol=1e-14)
    check_revolution(tube, *(np.subtract(revolution_integrals(lambda z: ro * ro, -h, h, rho),
                                         revolution_integrals(lambda z: ri * ri, -h, h, rho)) * [1, 0, 1, 1]))
    assert_converges(polyhedral_error(tube, lambda n: [(ri, -h), (ro, -h), (ro, h), (ri, h)], rho), 2e-3)
    # closed can, caps as thick as the wall: the solid cylinder minus its cavity, and as a revolved polyhedron
    can = gm.hollow_cylinder_mass_properties(ro, ri, h, rho, closed=True)
    t = ro - ri
    solid, cavity = gm.cylinder_mass_properties(ro, h, rho), gm.cylinder_mass_properties(ri, h - t, rho)
    assert can.mass == pytest.approx(solid.mass - cavity.mass, rel=1e-14)
    np.testing.assert_allclose(can.inertia, solid.inertia - cavity.inertia, rtol=1e-14)
    can_profile = lambda n: [(0, -h), (ro, -h), (ro, h), (0, h), (0, h - t), (ri, h - t), (ri, -h + t),  # noqa: E731
                             (0, -h + t)]
    assert_converges(polyhedral_error(can, can_profile, rho), 2e-3)
    thin_caps = gm.hollow_cylinder_mass_properties(ro, ri, h, rho, closed=True, cap_thickness=0.01)
    assert tube.mass < thin_caps.mass < can.mass


def test_cone_against_revolved_polyhedron():
    r, height, rho = 0.3, 1.1, 500.0
    cone = gm.cone_mass_properties(r, height, rho)
    def profile(n):   # base centre, the slanted side from the rim to the apex
        side = np.stack([np.linspace(r, 0, n + 1), np.linspace(-height / 4, 3 * height / 4, n + 1)], 1)
        return np.vstack([[0, -height / 4], side])
    assert_converges(polyhedral_error(cone, profile, rho), 2e-3)


def test_thick_spherical_shell_against_revolved_polyhedron():
    r, ri, rho = 0.5, 0.4, 300.0
    shell = gm.sphere_mass_properties(r, rho, inner_radius=ri)
    def profile(n):   # the outer half circle up, the inner one down
        return np.vstack([arc(0, 0, r, -np.pi / 2, np.pi / 2, n), arc(0, 0, ri, np.pi / 2, -np.pi / 2, n)])
    assert_converges(polyhedral_error(shell, profile, rho), 2e-3)


def test_cylindrical_shell_is_the_limit_of_thin_tubes():
    # open: I_zz = m r^2, I_perp = m (r^2/2 + h^2/3); a tube of wall t and density sigma / t tends to it at O(t^2)
    r, h, sigma = 0.25, 0.4, 2.0
    shell = gm.cylindrical_shell_mass_properties(r, h, sigma)
    m = 4 * math.pi * r * h * sigma
    np.testing.assert_allclose(np.diag(shell.inertia), [m * (r * r / 2 + h * h / 3)] * 2 + [m * r * r],
                               rtol=1e-15)
    errors = []
    for t in (1e-2, 5e-3):
        tube = gm.hollow_cylinder_mass_properties(r + t / 2, r - t / 2, h, sigma / t)
        assert tube.mass == pytest.approx(shell.mass, rel=1e-12)
        errors.append(np.abs(tube.inertia - shell.inertia).max() / shell.inertia.max())
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.02)
    # closed: plus two end discs; the limit of closed cans with caps of the same thickness
    closed = gm.cylindrical_shell_mass_properties(r, h, sigma, closed=True)
    assert closed.mass == pytest.approx(m + 2 * math.pi * r * r * sigma, rel=1e-15)
    errors = []
    for t in (1e-3, 5e-4):
        can = gm.hollow_cylinder_mass_properties(r + t / 2, r - t / 2, h + t / 2, sigma / t, closed=True,
                                                 cap_thickness=t)
        errors.append(np.abs(can.inertia - closed.inertia).max() / closed.inertia.max())
    assert errors[1] < 1e-3 and errors[1] < errors[0], errors


def test_common_solids_reject_bad_arguments():
    with pytest.raises(ValueError, match="inner_radius"):
        gm.hemisphere_mass_properties(1.0, 1.0, inner_radius=1.0)
    with pytest.raises(ValueError, match="minor_radius"):
        gm.torus_mass_properties(0.2, 0.3, 1.0)
    with pytest.raises(ValueError, match="origin"):
        gm.thin_rod_mass_properties(1.0, 1.0, origin="middle")
    with pytest.raises(ValueError, match="inner_radius"):
        gm.hollow_cylinder_mass_properties(0.3, 0.4, 1.0, 1.0)
    with pytest.raises(ValueError, match="cap_thickness"):
        gm.hollow_cylinder_mass_properties(0.4, 0.3, 0.05, 1.0, closed=True)
    with pytest.raises(ValueError, match="cap_thickness"):
        gm.hollow_cylinder_mass_properties(0.4, 0.3, 1.0, 1.0, cap_thickness=0.1)
    with pytest.raises(TypeError, match="closed"):
        gm.cylindrical_shell_mass_properties(0.4, 1.0, 1.0, closed=1)
    with pytest.raises(TypeError, match="inner_radius"):
        gm.hemisphere_mass_properties(1.0, 1.0, inner_radius=True)
    with pytest.raises(ValueError, match="point"):
        gm.torus_mass_properties(0.5, 0.1, 1.0).inertia_about([0.0, 1.0])


def test_a_body_takes_a_solid_s_mass_properties():
    # a body built from a hemisphere's mass properties: its user frame at the centroid, principal moments
    from inertia.model import ModelBuilder
    p = gm.hemisphere_mass_properties(0.2, 1000.0)
    b = ModelBuilder()
    b.add_body(position=p.com, mass=p.mass, inertia=p.inertia)
    model = b.finalize()
    assert model.body_mass[0] == pytest.approx(p.mass, rel=1e-15)
    np.testing.assert_allclose(np.sort(model.body_inertia[0]), np.sort(np.diag(p.inertia)), rtol=1e-14)
    np.testing.assert_allclose(model.state().body_q[0, :3], p.com)
