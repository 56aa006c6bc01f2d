"""Tests for inertia.geometry.convex: hull building, support functions, GJK distance and EPA penetration
against closed forms and against brute force on the Minkowski difference (Qhull of all a_i - b_j)."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from inertia import math as im
from inertia.geometry import convex as C

RNG = np.random.default_rng(2026)
NO_VERTS = np.zeros((1, 3))
SPHERE, BOX, CAPSULE, CYLINDER, HULL = 0, 1, 2, 3, 4


def params(*values):
    out = np.zeros(4)
    out[:len(values)] = values
    return out


def pose(p=(0.0, 0.0, 0.0), q=(1.0, 0.0, 0.0, 0.0)):
    return np.array([*p, *q], dtype=np.float64)


def random_quat(rng=RNG):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def distance(ta, pa_, posa, tb, pb_, posb, verts=NO_VERTS, sa=0, ca=0, sb=0, cb=0):
    return C.shape_distance(ta, pa_, posa, sa, ca, tb, pb_, posb, sb, cb, verts)


# --------------------------------------------------------------------------------------------- hulls
def test_hull_faces_are_outward_and_merged():
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    interior = RNG.uniform(-0.5, 0.5, size=(20, 3))
    hull = C.build_convex_hull(np.vstack([cube, interior]))
    assert hull.vertices.shape == (8, 3)
    assert hull.triangles.shape == (12, 3)
    assert hull.face_planes.shape == (6, 4)  # coplanar triangle pairs merged into squares
    np.testing.assert_array_equal(hull.face_vert_count, 4)
    np.testing.assert_allclose(hull.face_planes[:, 3], 1.0, atol=1e-12)
    for f in range(6):
        loop = hull.vertices[hull.face_verts[hull.face_vert_start[f]:][:4]]
        n = hull.face_planes[f, :3]
        # counter-clockwise seen from outside: consecutive edge cross products point along n
        for k in range(4):
            e1, e2 = loop[(k + 1) % 4] - loop[k], loop[(k + 2) % 4] - loop[(k + 1) % 4]
            assert np.cross(e1, e2) @ n > 0
    a, b, c = (hull.vertices[hull.triangles[:, k]] for k in range(3))
    centroid_dir = (a + b + c) / 3
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), centroid_dir) > 0)


# ------------------------------------------------------------------------------------------ supports
def test_support_functions_maximise_the_dot_product():
    # the support point is on the shape and no sampled surface point goes farther along the direction
    shapes = [(SPHERE, params(0.7)), (BOX, params(0.3, 0.5, 0.8)), (CAPSULE, params(0.4, 0.9)),
              (CYLINDER, params(0.6, 0.5))]
    dirs = RNG.normal(size=(50, 3))
    for st, par in shapes:
        for d in dirs:
            s = C.support_local(st, par, NO_VERTS, 0, 0, d)
            # closed-form support values h(d) = max_x d.x
            dn = d / np.linalg.norm(d)
            if st == SPHERE:
                h = par[0]
            elif st == BOX:
                h = np.abs(dn) @ par[:3]
            elif st == CAPSULE:
                h = abs(dn[2]) * par[1] + par[0]
            else:
                h = np.hypot(dn[0], dn[1]) * par[0] + abs(dn[2]) * par[1]
            assert s @ dn == pytest.approx(h, abs=1e-14)
    pts = RNG.normal(size=(30, 3))
    for d in dirs:
        s = C.support_local(HULL, params(), pts, 0, 30, d)
        assert s @ d == pytest.approx((pts @ d).max(), abs=1e-14)


# ------------------------------------------------------------------------------------------ closed forms
def test_sphere_sphere_distance_and_penetration():
    for gap in (1.5, 1e-6, -1e-6, -0.4, -1.2):
        q_a = random_quat()
        direction = RNG.normal(size=3)
        direction /= np.linalg.norm(direction)
        ra, rb = 1.0, 0.5
        ca = RNG.normal(size=3)
        cb = ca + (ra + rb + gap) * direction
        d, wa, wb, n = distance(SPHERE, params(ra), pose(ca, q_a), SPHERE, params(rb), pose(cb, random_quat()))
        # |ca - cb| - ra - rb, witnesses on the line of centres, normal from A to B
        assert d == pytest.approx(gap, abs=1e-12)
        np.testing.assert_allclose(n, direction, atol=1e-12)
        np.testing.assert_allclose(wa, ca + ra * direction, atol=1e-12)
        np.testing.assert_allclose(wb, cb - rb * direction, atol=1e-12)


def test_box_box_separated_by_known_gap():
    # B sits beyond A's +x face (in A's frame) by `gap`, turned about that face's normal: face-face contact
    half_a, half_b = np.array([0.5, 0.7, 0.9]), np.array([0.3, 0.2, 0.25])
    for gap in (0.37, 1e-5, 2.0):
        q_a = random_quat()
        x_axis = im.quat_rotate(q_a, np.array([1.0, 0, 0]))
        q_b = im.quat_mul(im.quat_from_axis_angle(x_axis, 0.3), q_a)
        ca = RNG.normal(size=3)
        cb = ca + (half_a[0] + half_b[0] + gap) * x_axis
        d, wa, wb, n = distance(BOX, params(*half_a), pose(ca, q_a), BOX, params(*half_b), pose(cb, q_b))
        assert d == pytest.approx(gap, rel=1e-10, abs=1e-12)
        np.testing.assert_allclose(n, x_axis, atol=1e-9)
        assert np.linalg.norm(wb - wa) == pytest.approx(gap, rel=1e-10, abs=1e-12)


def test_box_box_penetration_depth():
    # axis-aligned overlap along x by 0.1 (smallest axis of overlap): depth 0.1, normal +x
    d, wa, wb, n = distance(BOX, params(1, 1, 1), pose(), BOX, params(0.5, 0.5, 0.5), pose((1.4, 0.2, -0.1)))
    assert d == pytest.approx(-0.1, abs=1e-10)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-9)
    assert wa[0] == pytest.approx(1.0, abs=1e-10) and wb[0] == pytest.approx(0.9, abs=1e-10)


def test_capsule_capsule_and_sphere_cylinder_closed_forms():
    # perpendicular skew capsules: segments along z (at origin) and along x (at height... offset in y)
    q_x = im.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), np.pi / 2)
    d, wa, wb, n = distance(CAPSULE, params(0.2, 1.0), pose(), CAPSULE, params(0.3, 1.0), pose((0, 1.5, 0.4), q_x))
    # segment distance 1.5 (along y), minus the radii
    assert d == pytest.approx(1.5 - 0.5, abs=1e-12)
    np.testing.assert_allclose(n, [0, 1, 0], atol=1e-12)
    # sphere above a cylinder's cap rim: distance from the centre to the rim circle minus the radius
    c = np.array([1.3, 0.0, 0.9])
    d, wa, wb, n = distance(CYLINDER, params(1.0, 0.5), pose(), SPHERE, params(0.1), pose(c))
    assert d == pytest.approx(np.hypot(0.3, 0.4) - 0.1, rel=1e-9)


# ----------------------------------------------------------------------------------- brute force pairs
def closest_on_triangle_bruteforce(a, b, c):
    """Closest point to the origin on a triangle: the plane projection if inside, else the best edge point."""
    n = np.cross(b - a, c - a)
    p = (a @ n) / (n @ n) * n
    bary = [np.cross(c - b, p - b) @ n, np.cross(a - c, p - c) @ n, np.cross(b - a, p - a) @ n]
    if min(bary) >= 0:
        return np.linalg.norm(p)
    best = np.inf
    for u, v in ((a, b), (b, c), (c, a)):
        t = np.clip(-(u @ (v - u)) / ((v - u) @ (v - u)), 0, 1)
        best = min(best, np.linalg.norm(u + t * (v - u)))
    return best


def minkowski_reference(pts_a, pts_b):
    """Signed distance of two convex polytopes from the hull of A - B: if the origin is outside, the
    distance to the nearest hull triangle; inside, minus the distance to the nearest facet plane."""
    diff = (pts_a[:, None, :] - pts_b[None, :, :]).reshape(-1, 3)
    hull = ConvexHull(diff)
    offsets = hull.equations[:, 3]  # n . x + offset <= 0 inside; the origin gives offset
    if np.all(offsets < 0):
        return offsets.max()  # -min distance to a facet plane
    return min(closest_on_triangle_bruteforce(*diff[s]) for s in hull.simplices)


@pytest.mark.parametrize("seed", range(40))
def test_random_hull_pairs_against_minkowski_brute_force(seed):
    # half the pairs overlap (EPA), half are apart (GJK)
    rng = np.random.default_rng(seed)
    spread = 0.8 if seed % 2 else 2.5
    local_a = rng.normal(size=(12, 3)) * [1.0, 0.6, 0.8]
    local_b = rng.normal(size=(9, 3)) * 0.7
    verts = np.vstack([local_a, local_b])
    pa = pose(rng.normal(size=3) * 0.2, random_quat(rng))
    pb = pose(rng.normal(size=3) * spread, random_quat(rng))
    world_a = np.array([im.transform_point(pa, v) for v in local_a])
    world_b = np.array([im.transform_point(pb, v) for v in local_b])
    d, wa, wb, n = C.shape_distance(HULL, params(), pa, 0, 12, HULL, params(), pb, 12, 9, verts)
    ref = minkowski_reference(world_a, world_b)
    assert d == pytest.approx(ref, abs=1e-8)
    # witnesses: wb - wa = d n, and each witness is a support point of its shape along the normal
    np.testing.assert_allclose(wb - wa, d * n, atol=1e-8)
    assert wa @ n == pytest.approx((world_a @ n).max(), abs=1e-8)
    assert wb @ n == pytest.approx((world_b @ n).min(), abs=1e-8)


def test_hull_against_rounded_shapes_brute_force():
    # hull vs sphere: the Minkowski reference on the hull and the sphere's centre, minus the radius
    pts = RNG.normal(size=(15, 3))
    for _ in range(5):
        c = RNG.normal(size=3) * 2.5
        d, wa, wb, n = C.shape_distance(HULL, params(), pose(), 0, 15, SPHERE, params(0.3), pose(c), 0, 0, pts)
        assert d == pytest.approx(minkowski_reference(pts, c[None, :]) - 0.3, abs=1e-8)


def test_deep_overlap_of_rounded_shapes_uses_epa():
    # concentric spheres: the cores coincide, EPA on the curved supports; depth ra + rb (any direction)
    d, wa, wb, n = distance(SPHERE, params(1.0), pose((0.3, 0.2, 0.1)), SPHERE, params(0.5), pose((0.3, 0.2, 0.1)))
    assert d == pytest.approx(-1.5, rel=1e-15)
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-12)
    # crossing capsules (segments along z and x through nearby points): the cores' Minkowski difference is
    # flat, the way out is across both segments (+-y) with depth ra + rb - |offset along y|... here 0 offset
    q_x = im.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), np.pi / 2)
    d, wa, wb, n = distance(CAPSULE, params(0.2, 1.0), pose(), CAPSULE, params(0.3, 1.0), pose((0.1, 0.0, 0.2), q_x))
    assert d == pytest.approx(-0.5, rel=1e-14)
    assert abs(n[1]) == pytest.approx(1.0, abs=1e-14)
    # cylinder (core = itself) against a box overlapping its side by 0.1: EPA on cores
    d, wa, wb, n = distance(CYLINDER, params(1.0, 1.0), pose(), BOX, params(0.5, 0.5, 0.5), pose((1.4, 0.0, 0.0)))
    assert d == pytest.approx(-0.1, abs=1e-6)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-4)
    # a sphere centred inside a box, nearer the +z face: depth = distance to that face + radius
    d, wa, wb, n = distance(BOX, params(1.0, 1.0, 1.0), pose(), SPHERE, params(0.2), pose((0.1, -0.2, 0.7)))
    assert d == pytest.approx(-(0.3 + 0.2), rel=1e-9)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-9)
    # two unit boxes turned 45 degrees about z, centres 1.2 apart along x (the GJK simplex ends as a segment
    # through the origin): the way out is along a face normal (+-1, +-1, 0)/sqrt 2, where the centre offset
    # projects to 1.2/sqrt 2 against a summed half width of 1: depth 1 - 1.2/sqrt 2
    q45 = im.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.pi / 4)
    d, wa, wb, n = distance(BOX, params(0.5, 0.5, 0.5), pose((0, 0, 0), q45), BOX, params(0.5, 0.5, 0.5),
                            pose((1.2, 0, 0), q45))
    assert d == pytest.approx(-(1 - 1.2 / np.sqrt(2)), abs=1e-9)
    np.testing.assert_allclose(np.abs(n), [2 ** -0.5, 2 ** -0.5, 0], atol=1e-9)
    assert n[0] > 0


CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


@pytest.mark.parametrize("seed", range(30))
def test_degenerate_box_pairs_against_minkowski_brute_force(seed):
    # equal or axis-aligned orientations and offsets on a quarter grid: many coplanar Minkowski faces and
    # contacts whose GJK simplex ends as a segment or triangle through the origin (EPA's hard cases)
    rng = np.random.default_rng(1000 + seed)
    ha, hb = rng.uniform(0.2, 1, 3), rng.uniform(0.2, 1, 3)
    qa = random_quat(rng) if seed % 3 == 0 else np.array([1.0, 0, 0, 0])
    qb = qa if seed % 3 != 2 else random_quat(rng)
    pa = pose(np.round(rng.normal(size=3) * 2) / 4, qa)
    pb = pose(np.round(rng.normal(size=3) * 2) / 4, qb)
    world_a = np.array([im.transform_point(pa, v) for v in CORNERS * ha])
    world_b = np.array([im.transform_point(pb, v) for v in CORNERS * hb])
    d, wa, wb, n = distance(BOX, params(*ha), pa, BOX, params(*hb), pb)
    assert d == pytest.approx(minkowski_reference(world_a, world_b), abs=1e-8)
    np.testing.assert_allclose(wb - wa, d * n, atol=1e-8)


def test_a_reused_scratch_gives_the_bits_of_a_fresh_one():
    """One `GjkScratch` reused across pairs (as the narrow phase does) leaves nothing behind: every call
    through the shared scratch returns exactly (bit for bit) what the public functions, which make a fresh
    scratch per call, return; penetrating, separated and deep pairs interleaved."""
    rng = np.random.default_rng(9)
    scr = C.new_gjk_scratch()
    shapes = [(BOX, params(0.3, 0.2, 0.25)), (CAPSULE, params(0.1, 0.3)), (CYLINDER, params(0.2, 0.15)),
              (SPHERE, params(0.2))]
    for trial in range(24):
        ta, pa_ = shapes[trial % 4]
        tb, pb_ = shapes[(trial // 4) % 4]
        posa = pose(rng.uniform(-0.1, 0.1, 3), random_quat(rng))
        posb = pose(rng.uniform(-0.5, 0.5, 3), random_quat(rng))
        d, wa, wb, n, sep = C.gjk_distance(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS)
        d2, sep2 = C.gjk_distance_scratch(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS, scr)
        assert (d2, sep2) == (d, sep)
        assert np.array_equal(scr.vec[6:9], np.array([wa, wb, n]))
        if not sep:
            depth, wa, wb, n, ok = C.epa_penetration(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS)
            depth2, ok2 = C._epa(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS, True, scr)
            assert (depth2, ok2) == (depth, ok)
            assert np.array_equal(scr.vec[6:9], np.array([wa, wb, n]))


def _touching_pairs():
    """Pairs whose GJK ends with fewer than four simplex points (touching faces, edges and corners,
    coincident boxes, a sphere's or capsule's core on a box face): EPA must grow the simplex itself."""
    box = params(0.1, 0.1, 0.1)
    at = [(0, 0, 0.2), (0.2, 0.2, 0.2), (0.2, 0, 0.2), (0, 0, 0)]
    pairs = [(BOX, box, pose((0, 0, 0), (1, 0, 0, 0)), BOX, box, pose(p, (1, 0, 0, 0))) for p in at]
    pairs.append((SPHERE, params(0.05), pose((0, 0, 0.1), (1, 0, 0, 0)), BOX, box, pose((0, 0, 0), (1, 0, 0, 0))))
    pairs.append((CAPSULE, params(0.05, 0.1), pose((0, 0, 0.2), (1, 0, 0, 0)), BOX, box,
                  pose((0, 0, 0), (1, 0, 0, 0))))
    return pairs


def test_epa_seeds_a_short_gjk_simplex_in_the_scratch_without_allocating():
    """EPA's rare path (GJK stops with 1, 2 or 3 simplex points: touching or coincident shapes) grows the
    simplex into a tetrahedron in the `GjkScratch` too: Numba's NRT allocation counter over 40 calls on one
    scratch equals that over 2 calls (before: support points, differences and cross products as new arrays,
    ~20 allocations per call), for every pair whose GJK simplex is short; the results are the public
    function's (fresh scratch) bit for bit."""
    from numba import njit
    from numba.core.runtime import _nrt_python, rtsys

    @njit
    def repeat(k, ta, pa_, posa, tb, pb_, posb, verts, with_radius, scr):
        depth, ok = 0.0, False
        for _ in range(k):
            depth, ok = C._epa(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, verts, with_radius, scr)
        return depth, ok

    @njit
    def simplex_size(ta, pa_, posa, tb, pb_, posb, verts, with_radius, scr):
        return C._gjk(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, verts, with_radius, scr.pw, scr.pa, scr.pb, scr)[1]

    scr = C.new_gjk_scratch()
    sizes = set()
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        for ta, pa_, posa, tb, pb_, posb in _touching_pairs():
            for with_radius in (False, True):
                n = simplex_size(ta, pa_, posa, tb, pb_, posb, NO_VERTS, with_radius, scr)
                if n == 4:
                    continue
                sizes.add(n)
                repeat(1, ta, pa_, posa, tb, pb_, posb, NO_VERTS, with_radius, scr)       # compile / warm
                counts = []
                for k in (2, 40):
                    a0 = rtsys.get_allocation_stats().alloc
                    repeat(k, ta, pa_, posa, tb, pb_, posb, NO_VERTS, with_radius, scr)
                    counts.append(rtsys.get_allocation_stats().alloc - a0)
                assert counts[0] == counts[1], (ta, tb, n, counts)
                if with_radius:
                    depth, ok = C._epa(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS, True, scr)
                    ref = C.epa_penetration(ta, pa_, posa, 0, 0, tb, pb_, posb, 0, 0, NO_VERTS)
                    assert (depth, ok) == (ref[0], ref[4])
                    assert np.array_equal(scr.vec[6:9], np.array(ref[1:4]))
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert sizes == {1, 2, 3}                     # every branch of the seeding was exercised
