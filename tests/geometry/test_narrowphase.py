"""Narrow-phase manifolds against closed-form separations, normals and contact points."""

import math

import numpy as np
import pytest

from inertia.dynamics.contacts import Contacts
from inertia.geometry.broadphase import shape_world_bounds, sort_and_sweep
from inertia.geometry.narrowphase import compact_active, narrow_phase
from inertia.model import ModelBuilder


def _manifolds(builder, dt=1.0 / 60.0):
    """Run broad and narrow phase once on the builder's scene; returns the Contacts and the model."""
    m = builder.finalize()
    st = m.state()
    ns = m.shape_count
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shapes = m.shapes()
    shape_world_bounds(shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    pairs, keys = np.zeros((64, 2), np.int32), np.zeros(64, np.int64)
    n = sort_and_sweep(aabb, shapes, m.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    c = Contacts(64)
    narrow_phase(pairs, keys, n, shapes, pose, st.body_qd, m.body_bound_radius, dt, c.arrays())
    c.count = n
    c.active_count = compact_active(c.arrays(), n)
    return c, m


def _only(c):
    act = c.manifolds()
    assert len(act) == 1
    i = act[0]
    k = c.contact_point_count[i]
    return c.contact_normal[i], c.contact_point[i, :k], c.contact_separation[i, :k], c.contact_feature[i, :k]


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return (math.cos(angle / 2), *(axis * math.sin(angle / 2)))


def test_sphere_sphere_gap_normal_and_midpoint():
    b = ModelBuilder(default_margin=0.5)
    b.add_sphere(b.add_body(position=(0, 0, 0)), 0.3)
    b.add_sphere(b.add_body(position=(1.0, 0.0, 0.0)), 0.5)
    n, p, s, _ = _only(_manifolds(b)[0])
    # gap = |c_b - c_a| - r_a - r_b; normal from A to B; point midway between the surfaces
    assert s[0] == pytest.approx(0.2, abs=1e-12)
    assert n == pytest.approx([1, 0, 0], abs=1e-12)
    assert p[0] == pytest.approx([0.4, 0, 0], abs=1e-12)


def test_box_resting_on_a_plane_gives_its_four_corners():
    b = ModelBuilder()
    b.add_plane()
    b.add_box(b.add_body(position=(0.3, -0.2, 0.099)), (0.2, 0.1, 0.1))
    n, p, s, f = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, -1], abs=1e-12)          # box (A) -> plane (B)
    assert s == pytest.approx([-0.001] * 4, abs=1e-12)
    corners = sorted((round(x, 9), round(y, 9)) for x, y in p[:, :2])
    assert corners == sorted([(0.1, -0.3), (0.5, -0.3), (0.1, -0.1), (0.5, -0.1)])
    assert len(set(f.tolist())) == 4


def test_tilted_box_on_plane_touches_with_its_lowest_edge():
    b = ModelBuilder(default_margin=0.001)
    b.add_plane()
    # rotated 30 deg about x: the lowest edge is at z = c_z - (hy sin 30 + hz cos 30)
    h = 0.1
    low = h * math.sin(math.radians(30)) + h * math.cos(math.radians(30))
    b.add_box(b.add_body(position=(0, 0, low - 0.002), orientation=_rot((1, 0, 0), math.radians(30))), (h, h, h))
    n, p, s, _ = _only(_manifolds(b)[0])
    assert len(s) == 2
    assert s == pytest.approx([-0.002, -0.002], abs=1e-12)


def test_box_on_box_face_clipping_gives_the_overlap_square():
    b = ModelBuilder()
    b.add_box(b.add_body(position=(0, 0, 0)), (0.5, 0.5, 0.5))
    # a smaller box on top, rotated 45 deg about z, 1 mm into the lower one: its four bottom corners
    # lie inside the big face, so the manifold is those corners at separation -1 mm
    b.add_box(b.add_body(position=(0, 0, 0.5 + 0.2 - 0.001), orientation=_rot((0, 0, 1), math.pi / 4)),
              (0.2, 0.2, 0.2))
    n, p, s, f = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, 1], abs=1e-12)
    assert s == pytest.approx([-0.001] * 4, abs=1e-12)
    radii = np.hypot(p[:, 0], p[:, 1])
    assert radii == pytest.approx([0.2 * math.sqrt(2)] * 4, abs=1e-12)
    assert p[:, 2] == pytest.approx([0.5 - 0.0005] * 4, abs=1e-12)


def test_box_on_box_clipped_polygon_is_reduced_to_four_points():
    b = ModelBuilder()
    b.add_box(b.add_body(position=(0, 0, 0)), (0.3, 0.3, 0.3))
    # same-size box rotated 45 deg about z: the overlap of the two squares is an octagon (8 points),
    # reduced to 4 that keep the deepest point and a large area
    b.add_box(b.add_body(position=(0, 0, 0.6 - 0.001), orientation=_rot((0, 0, 1), math.pi / 4)),
              (0.3, 0.3, 0.3))
    n, p, s, f = _only(_manifolds(b)[0])
    assert len(s) == 4
    assert s == pytest.approx([-0.001] * 4, abs=1e-12)
    # the kept quad spans the octagon: its area is at least half the octagon's
    octagon = 2 * (1 + math.sqrt(2)) * (0.6 * (math.sqrt(2) - 1)) ** 2
    xy = p[:, :2]
    c = xy.mean(axis=0)
    order = np.argsort(np.arctan2(xy[:, 1] - c[1], xy[:, 0] - c[0]))
    x, y = xy[order, 0], xy[order, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
    assert area > 0.5 * octagon


def test_box_box_edge_edge_contact():
    b = ModelBuilder(default_margin=0.01)
    h = 0.1
    # two cubes each standing on an edge: A's top edge along x, B's bottom edge along y
    qa = _rot((1, 0, 0), math.pi / 4)
    qb = _rot((0, 1, 0), math.pi / 4)
    d = h * math.sqrt(2)
    b.add_box(b.add_body(position=(0, 0, 0), orientation=qa), (h, h, h))
    b.add_box(b.add_body(position=(0, 0, 2 * d + 0.003), orientation=qb), (h, h, h))
    n, p, s, f = _only(_manifolds(b)[0])
    assert len(s) == 1
    assert s[0] == pytest.approx(0.003, abs=1e-9)
    assert n == pytest.approx([0, 0, 1], abs=1e-9)
    assert p[0] == pytest.approx([0, 0, d + 0.0015], abs=1e-9)


def test_sphere_inside_box_leaves_through_nearest_face():
    b = ModelBuilder()
    b.add_sphere(b.add_body(position=(0.25, 0, 0)), 0.1)
    b.add_box(b.add_body(position=(0, 0, 0)), (0.3, 0.5, 0.5))
    n, p, s, _ = _only(_manifolds(b)[0])
    # centre 0.05 inside the +x face: depth = 0.05 + r
    assert s[0] == pytest.approx(-0.15, abs=1e-12)
    assert n == pytest.approx([-1, 0, 0], abs=1e-12)     # sphere (A) -> box (B)


def test_parallel_capsules_get_two_points():
    b = ModelBuilder()
    r, hl = 0.05, 0.3
    b.add_capsule(b.add_body(position=(0, 0, 0)), r, hl)
    b.add_capsule(b.add_body(position=(0.099, 0, 0.1)), r, hl)   # overlap of the segments 0.5 long
    n, p, s, _ = _only(_manifolds(b)[0])
    assert len(s) == 2
    assert s == pytest.approx([-0.001, -0.001], abs=1e-12)
    assert sorted(p[:, 2]) == pytest.approx([-0.2, 0.3], abs=1e-12)


def test_capsule_lying_on_a_plane_and_on_a_box():
    b = ModelBuilder()
    b.add_plane()
    q = _rot((0, 1, 0), math.pi / 2)                       # segment along x
    b.add_capsule(b.add_body(position=(0, 0, 0.049), orientation=q), 0.05, 0.2)
    n, p, s, _ = _only(_manifolds(b)[0])
    assert s == pytest.approx([-0.001, -0.001], abs=1e-12)
    b = ModelBuilder()
    b.add_box(b.add_body(position=(0, 0, 0)), (0.5, 0.5, 0.1))
    b.add_capsule(b.add_body(position=(0, 0, 0.149), orientation=q), 0.05, 0.2)
    n, p, s, _ = _only(_manifolds(b)[0])
    assert n == pytest.approx([0, 0, 1], abs=1e-12)        # box (A) -> capsule (B)
    assert s == pytest.approx([-0.001, -0.001], abs=1e-12)


def test_cylinder_on_its_side_and_standing():
    b = ModelBuilder()
    b.add_plane()
    q = _rot((1, 0, 0), math.pi / 2)
    b.add_cylinder(b.add_body(position=(0, 0, 0.099), orientation=q), 0.1, 0.2)
    n, p, s, _ = _only(_manifolds(b)[0])
    assert s == pytest.approx([-0.001, -0.001], abs=1e-12)       # the two rim points of the caps
    b = ModelBuilder()
    b.add_plane()
    b.add_cylinder(b.add_body(position=(0, 0, 0.199)), 0.1, 0.2)
    n, p, s, _ = _only(_manifolds(b)[0])
    assert len(s) == 4 and s == pytest.approx([-0.001] * 4, abs=1e-12)


def test_hull_vertices_against_plane():
    b = ModelBuilder()
    b.add_plane()
    tet = np.array([[0, 0, 0.3], [0.2, 0, -0.1], [-0.1, 0.17, -0.1], [-0.1, -0.17, -0.1]])
    body = b.add_body(position=(0, 0, 0.098), mass=1.0, inertia=(0.01, 0.01, 0.01))
    b.add_convex_hull(body, tet)
    n, p, s, _ = _only(_manifolds(b)[0])
    assert s == pytest.approx([-0.002] * 3, abs=1e-12)


def test_speculative_distance_grows_with_speed():
    # a sphere 0.5 m above the ground: no contact at rest, a speculative one when it falls at 60 m/s
    for v, expect in ((0.0, 0), (60.0, 1)):
        b = ModelBuilder()
        b.add_plane()
        b.add_sphere(b.add_body(position=(0, 0, 0.6), linear_velocity=(0, 0, -v)), 0.1)
        c, _ = _manifolds(b)
        assert len(c.manifolds()) == expect


def test_pair_families_route_each_pair_to_one_kernel_and_a_scene_compiles_only_its_own():
    """Each canonical type pair belongs to exactly one family (closed form, general convex, mesh, SDF, none),
    matching the routes of the module docstring; ``scene_families`` of a box + sphere + plane scene asks
    for neither the GJK/EPA kernel nor the mesh kernel (their compile is skipped), a box + capsule scene
    needs GJK/EPA (box-capsule is general), a heightfield scene the mesh kernel."""
    from inertia.geometry import shapes as S
    from inertia.geometry.narrowphase import (FAMILY_CLOSED, FAMILY_GENERAL, FAMILY_MESH, FAMILY_NONE,
                                              FAMILY_SDF, pair_family, scene_families)
    fam = pair_family.py_func
    closed = {(S.SPHERE, S.SPHERE), (S.SPHERE, S.BOX), (S.SPHERE, S.CAPSULE), (S.SPHERE, S.PLANE),
              (S.BOX, S.BOX), (S.BOX, S.PLANE), (S.CAPSULE, S.CAPSULE), (S.CAPSULE, S.PLANE),
              (S.CYLINDER, S.PLANE), (S.CONVEX_HULL, S.PLANE)}
    for ta in range(9):
        for tb in range(ta, 9):
            f = fam(ta, tb)
            if tb in (S.TRIANGLE_MESH, S.HEIGHTFIELD):
                assert f == FAMILY_MESH
            elif tb == S.SDF and ta <= S.CONVEX_HULL:
                assert f == FAMILY_SDF
            elif (ta, tb) in closed:
                assert f == FAMILY_CLOSED
            elif tb <= S.CONVEX_HULL:
                assert f == FAMILY_GENERAL
            else:
                assert f == FAMILY_NONE
    assert scene_families([S.PLANE, S.BOX, S.SPHERE, S.BOX]) == (False, False, False)
    assert scene_families([S.PLANE, S.BOX, S.CAPSULE]) == (True, False, False)
    assert scene_families([S.HEIGHTFIELD, S.SPHERE]) == (False, True, False)
    assert scene_families([S.SDF, S.SPHERE]) == (False, False, True)
    assert scene_families([S.SDF, S.PLANE, S.HEIGHTFIELD]) == (False, True, False)


def test_closed_token_compiles_the_pairs_of_the_smallest_nested_type_set():
    """``closed_token``: a scene compiles the closed-form pairs among the smallest of three nested shape-type
    sets holding its types (sphere + plane; sphere + box + plane; every closed-form type), so a box pile
    never compiles the capsule, cylinder or hull routines; types without closed forms (meshes, SDFs) do
    not widen the set."""
    from inertia.geometry import shapes as S
    from inertia.geometry.narrowphase import CLOSED_PAIRS, closed_token

    def kinds(types):
        return {pair for pair, on in zip(CLOSED_PAIRS, closed_token(types)) if on}

    spheres = {(S.SPHERE, S.SPHERE), (S.SPHERE, S.PLANE)}
    boxes = spheres | {(S.SPHERE, S.BOX), (S.BOX, S.BOX), (S.BOX, S.PLANE)}
    assert kinds([S.SPHERE, S.PLANE]) == kinds([S.SPHERE, S.TRIANGLE_MESH, S.PLANE]) == spheres
    assert kinds([S.BOX, S.PLANE]) == kinds([S.BOX, S.HEIGHTFIELD]) == kinds([S.BOX, S.SPHERE]) == boxes
    assert kinds([S.BOX, S.CAPSULE]) == kinds([S.CYLINDER]) == set(CLOSED_PAIRS)
    assert closed_token([S.TRIANGLE_MESH, S.SDF]) == closed_token([S.SPHERE])   # no closed form: the smallest


def test_closed_kernel_of_a_smaller_type_set_gives_the_same_bits_as_the_full_one():
    """A box-sphere-plane scene's manifolds through its own closed kernel (``closed_token``: the capsule,
    cylinder and hull routines pruned before compiling) equal those of the kernel with every closed form,
    bit for bit."""
    from inertia.geometry import narrowphase as N

    b = ModelBuilder()
    b.add_plane()
    b.add_box(b.add_body(position=(0.0, 0.0, 0.099), orientation=_rot((1, 1, 0), 0.05)), (0.2, 0.1, 0.1))
    b.add_box(b.add_body(position=(0.05, 0.02, 0.29)), (0.1, 0.1, 0.1))
    b.add_sphere(b.add_body(position=(0.6, 0.0, 0.09)), 0.1)
    b.add_sphere(b.add_body(position=(0.6, 0.0, 0.28)), 0.1)
    c, m = _manifolds(b)
    assert N.closed_token(m.shape_type) != N.ALL_CLOSED
    assert len(c.manifolds()) == 4          # box-plane, box-box, sphere-plane, sphere-sphere
    st = m.state()
    ns, dt = m.shape_count, 1.0 / 60.0
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shapes = m.shapes()
    shape_world_bounds(shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    pairs, keys = np.zeros((64, 2), np.int32), np.zeros(64, np.int64)
    n = sort_and_sweep(aabb, shapes, m.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    full = Contacts(64)
    N.narrow_phase_closed(pairs, keys, n, shapes, pose, st.body_qd, m.body_bound_radius, dt, full.arrays(),
                          N.new_narrow_work(False).scratch, N.ALL_CLOSED)
    for name in ("contact_point_count", "contact_normal", "contact_point", "contact_separation",
                 "contact_feature", "contact_tangent"):
        np.testing.assert_array_equal(getattr(full, name)[:n], getattr(c, name)[:n], err_msg=name)


_BOX_BOX_SIGNATURES = r"""
import numpy as np
from inertia.geometry import narrowphase as N
bank = N.new_scratch_bank(1)
scr = N.NarrowScratch(*(a[0] for a in bank))
out = N.ManifoldOut(np.zeros((1, 3)), np.zeros((1, 4, 3)), np.zeros((1, 4)), np.zeros((1, 4), np.int64))
q, h = (1.0, 0.0, 0.0, 0.0), (0.1, 0.1, 0.1)
count = N._box_box(out, 0, (0.0, 0.0, 0.0), q, h, (0.05, 0.02, 0.19), q, h, 0.01, scr)
print(count, [len(k.signatures) for k in (N._box_face_manifold, N._reduce_and_emit, N._emit)])
"""


def test_box_box_compiles_each_helper_once_from_an_empty_cache(tmp_path):
    """Compile time: from an empty Numba cache, a box-box manifold (face on face: four points) compiles the
    clipper, the point reduction and the point writer once each. A counter or feature code starting as
    the literal 0 is typed Literal[int](0) before Numba widens it, and each helper the call reaches then
    compiled a second time for the literal (they start as ``np.int64(0)``)."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    env["PYTHONPATH"] = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "src"))
    out = subprocess.run([sys.executable, "-c", _BOX_BOX_SIGNATURES], capture_output=True, text=True, env=env,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["4", "[1,", "1,", "1]"]


def test_general_and_mesh_kernels_fill_their_pairs_after_the_closed_form_kernel():
    """A scene with every family: the split kernels give each pair the manifold of its routine (a box on
    a box and a sphere on a plane by closed forms, a capsule across a box by GJK/EPA with its two
    clipped points, a sphere on a triangle mesh) and zero points to separated pairs."""
    b = ModelBuilder()
    b.add_plane()
    b.add_box(b.add_body(position=(0, 0, 0.1)), (0.1, 0.1, 0.1))
    b.add_box(b.add_body(position=(0, 0, 0.299)), (0.1, 0.1, 0.1))
    b.add_capsule(b.add_body(position=(0, 0, 0.448), orientation=_rot((0, 1, 0), math.pi / 2)), 0.05, 0.05)
    b.add_sphere(b.add_body(position=(3, 0, 0.099)), 0.1)
    b.add_triangle_mesh([(5.5, -0.5, 1.0), (6.5, -0.5, 1.0), (6.5, 0.5, 1.0), (5.5, 0.5, 1.0)], [(0, 1, 2), (0, 2, 3)])
    b.add_sphere(b.add_body(position=(6, 0, 1.099)), 0.1)
    c, m = _manifolds(b)
    act = c.manifolds()
    seps = {tuple(sorted(c.contact_shape[i])): c.contact_separation[i, :c.contact_point_count[i]] for i in act}
    assert set(seps) == {(0, 1), (1, 2), (2, 3), (0, 4), (5, 6)}
    assert seps[(1, 2)] == pytest.approx([-0.001] * 4, abs=1e-9)          # box on box (closed form)
    assert seps[(2, 3)] == pytest.approx([-0.001] * 2, abs=1e-6)          # capsule across the box (GJK/EPA)
    assert seps[(0, 4)] == pytest.approx([-0.001], abs=1e-12)             # sphere on the plane
    assert seps[(5, 6)] == pytest.approx([-0.001], abs=1e-9)              # sphere on the mesh
    assert seps[(0, 1)] == pytest.approx([-0.0] * 4, abs=1e-12)           # lower box resting on the plane


def _general_pairs_scene(npairs):
    """``npairs`` separate general-family contacts (a tetrahedral hull tilted on a box, a capsule lying
    across a box, alternately), with the arguments of one ``_narrow_range_general`` run over all pairs."""
    from inertia.geometry.narrowphase import FAMILY_GENERAL, pair_family
    b = ModelBuilder()
    tet = np.array([[0, 0, 0.3], [0.2, 0, -0.1], [-0.1, 0.17, -0.1], [-0.1, -0.17, -0.1]])
    for k in range(npairs):
        x = 2.0 * k
        b.add_box(b.add_body(position=(x, 0, 0)), (0.2, 0.2, 0.2))
        if k % 2 == 0:
            b.add_convex_hull(b.add_body(position=(x, 0.01, 0.29), orientation=_rot((1, 0, 0), 0.4)), tet)
        else:
            b.add_capsule(b.add_body(position=(x, 0, 0.248), orientation=_rot((0, 1, 0), math.pi / 2)), 0.05, 0.1)
    m = b.finalize()
    st = m.state()
    ns, dt = m.shape_count, 1.0 / 60.0
    pose, aabb = np.zeros((ns, 7)), np.zeros((ns, 6))
    shapes = m.shapes()
    shape_world_bounds(shapes, m.body_type, m.body_bound_radius, st.body_q, st.body_qd, dt, pose, aabb)
    cap = 2 * npairs + 8
    pairs, keys = np.zeros((cap, 2), np.int32), np.zeros(cap, np.int64)
    n = sort_and_sweep(aabb, shapes, m.body_type, st.body_awake, np.zeros(ns, np.int64), keys, pairs)
    families = [pair_family(*sorted(m.shape_type[pairs[i]])) for i in range(n)]
    assert n == npairs and families == [FAMILY_GENERAL] * n
    c = Contacts(cap)
    return c, (0, n, pairs, shapes, pose, st.body_qd, m.body_bound_radius, dt, c.arrays())


def test_general_pairs_reuse_one_gjk_epa_scratch_per_run():
    """GJK/EPA work in the run's scratch (issue 9): Numba's NRT allocation counter
    (``rtsys.get_allocation_stats``) over one run of 50 hull/capsule-box pairs equals that over 5 pairs, so
    nothing is allocated per pair (before the change: ~210 allocations per pair). The scratch is the
    caller's (a world keeps a bank of them, ``new_narrow_work``); the count left is the wrapping of the
    array arguments at the call from Python."""
    from numba.core.runtime import _nrt_python, rtsys
    from inertia.geometry.narrowphase import _narrow_range_general, new_narrow_work
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    try:
        counts = {}
        for npairs in (5, 50):
            c, args = _general_pairs_scene(npairs)
            work = new_narrow_work()
            args = args + (work.scratch, work.gjk, 0)
            _narrow_range_general(*args)                        # compile / warm
            a0 = rtsys.get_allocation_stats().alloc
            _narrow_range_general(*args)
            counts[npairs] = rtsys.get_allocation_stats().alloc - a0
            assert (c.contact_point_count[:npairs] > 0).all()
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    assert counts[5] > 0                                        # the counter works (the arguments)
    assert counts[50] == counts[5], counts
