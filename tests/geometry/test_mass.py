"""Tests for inertia.geometry.mass: closed forms against independent slice integration (scipy quad),
exact polyhedral integration against the unit cube, Tonon's (2005) published tetrahedron and exact rational
arithmetic, regular polyhedra (Satterly 1958) and Archimedean solids (Perrier 2015), parallel axis, compounds and principal frames."""

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
