"""distance / toi: the kind-set dispatch (``sdf_in``, ``lower_bound_in``, ``segment_toi_in``)
gives the generic dispatch's bits for the kinds it holds and leaves the others out; the
particle stage runs the kernels of its scene's kind set (``particle_kernels.kernels_for``)."""

import numpy as np
from numba import njit

import inertia as ia
from inertia.collision import distance as D
from inertia.collision import particle_kernels as pk
from inertia.collision import toi

C = ia.colliders


@njit
def _sample(kinds, kind, cf, ci, pts, ends, out):
    for i in range(pts.shape[0]):
        x, y, z = pts[i, 0], pts[i, 1], pts[i, 2]
        d, gx, gy, gz = D.sdf_in(kinds, kind, cf, 0, ci, 0, x, y, z)
        lb = D.lower_bound_in(kinds, kind, cf, 0, ci, 0, x, y, z)
        hit, sig, nx, ny, nz = toi.segment_toi_in(kinds, kind, cf, 0, ci, 0, x, y, z, ends[i, 0], ends[i, 1],
                                                  ends[i, 2], 0.01, 1e-9, 32)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = d, gx, gy, gz, lb
        out[i, 5], out[i, 6], out[i, 7], out[i, 8], out[i, 9] = hit, sig, nx, ny, nz


def _run(kinds, shape, pts, ends):
    out = np.empty((len(pts), 10))
    _sample(D.kinds_token(kinds), shape.kind, shape._cf, shape._ci, pts, ends, out)
    return out


def test_kind_set_dispatch_gives_the_generic_bits_and_drops_absent_kinds():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.5, 1.5, (64, 3))
    ends = pts + rng.normal(0.0, 0.5, (64, 3))
    every = set(range(D.GRID + 1))  # the generic dispatch (``sdf`` is ``sdf_in(ALL_KINDS, ...)``)
    shapes = [C.Plane(point=(0, 0, 0.1), normal=(0, 0.6, 0.8)), C.Sphere(center=(0.2, 0, 0), radius=0.5),
              C.Box(center=(0, 0.1, 0), half_extents=(0.3, 0.4, 0.5)),
              C.Container(center=(0, 0, 0), half_extents=(1.0, 1.2, 0.9))]
    hits = 0
    for shape in shapes:
        want = _run(every, shape, pts, ends)
        assert np.isfinite(want).all()
        hits += int(want[:, 5].sum())
        np.testing.assert_array_equal(_run({shape.kind}, shape, pts, ends), want)
    assert hits > 20  # the segments do meet the shapes
    # a kind outside the set is not compiled in: it reads as "no shape" (like CALLABLE)
    got = _run({D.PLANE}, shapes[2], pts, ends)
    assert np.all(got[:, 0] == D.BIG) and not got[:, 5].any()


def test_stage_runs_the_kernels_of_its_kind_set():
    ps = ia.ParticleSystem(np.array([[0.0, 0.0, 0.5]]), np.zeros((1, 3)), radius=0.05)
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)), restitution=0.5)
    bundle = pk.kernels_for(ps._collision.cint)
    assert bundle is pk.kernels_for([D.PLANE], moving=False) and bundle.kinds == pk.PLANE_KINDS
    assert not bundle.moving  # static colliders only: the moving-collider code is not compiled in
    assert repr(bundle) == "ParticleKernels(plane)"
    assert pk.kernels_for([D.PLANE, D.CONTAINER]).kinds == pk.LIGHT_KINDS
    assert pk.kernels_for([D.PLANE, D.BOX]).kinds == pk.ALL_KINDS
    ia.Simulation(ps, integrator="rk4", dt=1 / 240).run(0.5)
    # the planes-only token: only the plane entry is compiled in
    sigs = bundle.step_and_collide.dispatched.serial.signatures
    tokens = [[str(t) for t in sig[-2].types] for sig in sigs]
    assert ["bool", "none", "none", "none", "none", "none", "none"] in tokens
    assert all(str(sig[-1]) == "none" for sig in sigs)  # motion token: no moving collider
    assert ps.x[0, 2] >= 0.05 - 1e-6
    # a moving collider compiles the moving-collider code in (rest frames, surface velocities)
    ps.add_collider(C.Sphere(center=(2, 0, 0), radius=0.5, motion=lambda t: (2.0 + t, 0.0, 0.0)))
    assert pk.kernels_for(ps._collision.cint).moving


def test_query_points_compiles_the_collider_kind_only_with_the_same_bits_serial_and_parallel():
    # Collider.query passes kinds_token((kind,)): its results must equal the generic dispatch's
    # (ALL_KINDS: every branch, what query_points computed before it took a token) and the
    # parallel build's bit for bit (each point is written by one iteration).
    rng = np.random.default_rng(5)
    pts = rng.uniform(-1.2, 1.2, (200, 3))
    shapes = [C.Sphere(center=(0.2, 0, 0), radius=0.5, motion=lambda t: (0.2 + t, 0.1 * t, 0.0)),
              C.Box(center=(0, 0.1, 0), half_extents=(0.3, 0.4, 0.5)),
              C.Plane(point=(0, 0, 0.1), normal=(0, 0.6, 0.8))]
    t = 0.3
    for shape in shapes:
        got = shape._query_new(pts, t)  # 600 elements: the serial twin
        m = len(pts)
        args = (shape.kind, shape._cf, shape._ci, shape._packed_pose(t), shape._ref, shape.moving,
                *shape._rigid_velocity(t))
        for kernel, kinds in ((D.query_points.serial, D.ALL_KINDS),
                              (D.query_points.parallel, D.kinds_token((shape.kind,)))):
            want = np.empty(m), np.empty((m, 3)), np.empty((m, 3))
            kernel(pts, kinds, *args, *want)
            for a, b in zip(got, want):
                np.testing.assert_array_equal(a, b)
        assert np.isfinite(got[0]).all() and (got[0] < 0).any() and (got[0] > 0).any()
    assert np.any(shapes[0].velocity(pts, t) != 0.0)  # the moving sphere carries its velocity
    # the serial twin was typed with one-kind tokens only (no box code in the sphere's build)
    tokens = {tuple(str(x) for x in sig[1].types) for sig in D.query_points.serial.signatures}
    assert ("none", "bool", "none", "none", "none", "none", "none") in tokens
