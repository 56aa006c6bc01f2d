"""The particle collision kernels' far test (``particle_kernels._far_from_slots``).

The fused step (``step_and_collide``) integrates each chunk of particles in a loop that only
asks "can this path reach any collider?" with ``_far_from_slots`` (over the rows
``far_slots`` makes of the packed colliders) and leaves the exact mask
(``_near_mask``) and the response to the few particles it sets aside. The results stay the
bits of the separate pass (test_particle_stage.py) only if the cheap test never calls a particle
far that the exact mask calls near; it must also send most far particles straight through, or
the split buys nothing.
"""

import numpy as np

import inertia as ia
from inertia.collision import particle_kernels as pk

C = ia.colliders


def test_far_test_implies_the_exact_mask_is_empty():
    ps = ia.ParticleSystem(np.zeros((1, 3)), radius=0.0)
    ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    ps.add_collider(C.Sphere(center=(0.3, 0, 0.4), radius=0.4))
    ps.add_collider(C.Container(center=(0, 0, 1), half_extents=(1.2, 1.2, 1.2)))
    ps.add_collider(C.Box(center=(-0.5, 0.5, 0.2), half_extents=(0.2, 0.1, 0.2), rotation=(0, 0, 0.5)))
    d = ps._collision
    rng = np.random.default_rng(5)
    m = 6000
    ends = rng.uniform([-1.3, -1.3, -0.1], [1.3, 1.3, 2.3], (m, 3))
    steps = rng.normal(0.0, 0.02, (m, 3)) * rng.uniform(0, 1, (m, 1)) ** 3  # a range of speeds
    radii = rng.uniform(0.0, 0.05, m)
    tol = d.distance_tolerance
    far_count = 0
    for cnear in (d.cnear, d.cnear[:2], d.cnear[1:2]):  # all kinds; plane + sphere; sphere alone
        planes, balls = pk.far_slots(cnear, d.cf)
        for i in range(m):
            e, s, r = ends[i], steps[i], radii[i]
            far = pk._far_from_slots(planes, balls, r, tol, e[0], e[1], e[2], s[0], s[1], s[2])
            mask = pk._near_mask(cnear, d.cf, -1, r, tol, e[0], e[1], e[2], s[0], s[1], s[2])
            assert not (far and mask != 0), (i, e, s, r, mask)
            far_count += far
    # not vacuous: most of the exact test's far particles pass the cheap test too
    exact_far = sum(pk._near_mask(c, d.cf, -1, radii[i], tol, *ends[i], *steps[i]) == 0
                    for c in (d.cnear, d.cnear[:2], d.cnear[1:2]) for i in range(m))
    assert far_count >= 0.9 * exact_far > 0


def test_a_scene_whose_force_filter_runs_does_not_compile_the_fused_resting_motion():
    # quadratic drag is not affine: semi-implicit Euler runs the force filter in every evaluation,
    # so collide_particles gets the ``unfiltered`` token None and prunes ``_resting_motion`` (a
    # compile-time token, like ``motion``); the particle still comes to rest on the plane
    import inertia as ia
    from inertia.collision import particle_kernels as pk

    ps = ia.ParticleSystem(np.array([[0.0, 0.0, 0.3]]), np.zeros((1, 3)), radius=0.05)
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    ps.add_force(ia.forces.QuadraticDrag(1e-4))
    ps.add_collider(ia.colliders.Plane(point=(0, 0, 0), normal=(0, 0, 1)), restitution=0.0, friction=0.2)
    ia.Simulation(ps, integrator="semi_implicit_euler", dt=1 / 240).run(0.5)
    bundle = pk.kernels_for(ps._collision.cint)
    assert bundle.kinds == pk.PLANE_KINDS
    sigs = bundle.collide_particles.dispatched.serial.signatures
    assert any(str(sig[-4]) == "none" for sig in sigs)  # the unfiltered token None was compiled for it
    assert ps._collision.resting_count == 1 and abs(ps.x[0, 2] - 0.05) < 1e-6


def test_far_slots_rows_walls_and_the_too_many_colliders_case():
    # a container's walls become plane rows (min over walls > bound <=> every wall > bound);
    # with more than 62 colliders the exact mask marks every particle near, so the cheap test
    # must pass none: every row is then the always-near plane
    ps = ia.ParticleSystem(np.zeros((1, 3)), radius=0.0)
    ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    ps.add_collider(C.Sphere(center=(0.3, 0, 0.4), radius=0.4))
    ps.add_collider(C.Container(center=(0, 0, 1), half_extents=(1.2, 1.2, 1.2)))
    planes, balls = pk.far_slots(ps._collision.cnear, ps._collision.cf)
    assert planes.shape == (1 + 6, 4) and balls.shape == (1, 4)
    tol = ps._collision.distance_tolerance
    assert pk._far_from_slots(planes, balls, 0.0, tol, 0.0, 0.0, 1.0, 0.0, 0.0, 1e-3)  # mid-room
    assert not pk._far_from_slots(planes, balls, 0.0, tol, 0.0, 0.0, 1e-4, 0.0, 0.0, -1e-3)  # floor
    many = ia.ParticleSystem(np.zeros((1, 3)), radius=0.0)
    for k in range(63):
        many.add_collider(C.Sphere(center=(10.0 * k, 0, 0), radius=0.1))
    planes, balls = pk.far_slots(many._collision.cnear, many._collision.cf)
    assert balls.shape[0] == 0 and (planes == pk.ALWAYS_NEAR_PLANE).all()
    assert not pk._far_from_slots(planes, balls, 0.0, tol, 5.0, 5.0, 5.0, 0.0, 0.0, 0.0)


def test_never_near_rows_only_narrow_the_far_test():
    # step_and_collide tests a ground alone or an obstacle alone as one plane row and one ball row,
    # the missing row being NEVER_NEAR_*: that pair must call far only what the exact mask calls
    # far (so the results keep their bits), pass nearly every particle the scene's row passes (or
    # the vectorised loop buys nothing), and call a NaN path near
    ps = ia.ParticleSystem(np.zeros((1, 3)), radius=0.0)
    ps.add_collider(C.Plane(point=(0, 0, 0.1), normal=(0, 0.6, 0.8)))
    ps.add_collider(C.Sphere(center=(0.3, 0, 0.4), radius=0.4))
    d = ps._collision
    tol = d.distance_tolerance
    rng = np.random.default_rng(8)
    m = 4000
    ends = rng.uniform([-1.3, -1.3, -0.1], [1.3, 1.3, 2.3], (m, 3))
    steps = rng.normal(0.0, 0.02, (m, 3)) * rng.uniform(0, 1, (m, 1)) ** 3
    radii = rng.uniform(0.0, 0.05, m)
    for cnear, pad in ((d.cnear[:1], "ball"), (d.cnear[1:2], "plane")):
        planes, balls = pk.far_slots(cnear, d.cf)
        p = planes[0] if pad == "ball" else pk.NEVER_NEAR_PLANE
        b = balls[0] if pad == "plane" else pk.NEVER_NEAR_BALL
        agree = 0
        for i in range(m):
            e, s, r = ends[i], steps[i], radii[i]
            far = pk._far_from_one_each(*p, *b, r, tol, *e, *s)
            mask = pk._near_mask(cnear, d.cf, -1, r, tol, *e, *s)
            assert not (far and mask != 0), (pad, i)
            agree += far == pk._far_from_slots(planes, balls, r, tol, *e, *s)
        assert agree == m, pad  # finite paths: the padding row never changes the answer
        assert not pk._far_from_one_each(*p, *b, 0.0, tol, np.nan, 1.0, 1.0, 0.0, 0.0, 0.0)


def _fused_inputs(dim, n, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform([-1.0, -1.0, 0.0][:dim], [1.0, 1.0, 1.0][:dim], (n, dim))
    v = rng.normal(0.0, 2.0, (n, dim))
    pinned = np.zeros(n, bool)
    pinned[::11] = True
    ps = ia.ParticleSystem(x, v, radius=rng.uniform(0.0, 0.02, n), pinned=pinned)
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)[:dim] if dim == 3 else (0, -9.81)))
    normal = (0, 0, 1) if dim == 3 else (0, 1)
    ps.add_collider(C.Plane(point=(0,) * dim, normal=normal), restitution=0.5, friction=0.3)
    if dim == 3:
        ps.add_collider(C.Sphere(center=(0.3, 0, 0.4), radius=0.4), restitution=0.7, friction=0.1)
    ps.active[::13] = False
    ps.refresh_masses()
    sim = ia.Simulation(ps, integrator="rk4", dt=1 / 120)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # particles start inside the sphere
        sim.run(0.25)  # some particles come to rest on the plane (rest_k >= 0)
    assert ps._collision.fused_step == "rk4" and (ps._collision.rest_k >= 0).sum() > 10
    return ps


def test_fused_step_same_bits_through_the_vectorised_and_the_general_first_loop():
    # the vectorised first loop (one plane row and one ball row, 3-D, rk4 or semi-implicit) is a
    # reordering of the general one's arithmetic: a duplicated plane row sends the same step
    # through the general loop (a loop over rows), which must give the same bits, the same near
    # list and the same counts; 2-D (a plane only) goes through the general loop with dim 2
    for dim in (3, 2):
        ps = _fused_inputs(dim, 2500, 3 + dim)  # three chunks, the last one partial
        d = ps._collision
        ps.x[7] = np.nan  # a diverged particle: reported as not finite by both
        kern = pk.kernels_for(d.cint).step_and_collide
        g, force, damping = ps._affine_terms()
        planes, balls = d.far_planes, d.far_balls
        for rk4 in (True, False):
            out = []
            for rows in ((planes, balls), (np.vstack([planes, planes]), balls)):
                x, v, rest_k = ps.x.copy(), ps.v.copy(), d.rest_k.copy()
                near_list = np.empty(len(x), np.int64)
                res = kern(x, v, ps.radius, ps.inv_mass, ps.active, g, force, damping, rk4, d.cint, d.cnear,
                           d.cmat, d.cf, d.ci, rows[0], rows[1],
                           d.pose1, d.ref, rest_k, d.rest_n.copy(), d.rest_u.copy(), d.load.copy(),
                           d.static_ok.copy(), near_list, d.chunk_counts.copy(), *d.pass_record(), 1 / 120,
                           d.distance_tolerance, d.rest_speed, True, d.max_substeps, d.max_iterations)
                out.append((x, v, rest_k, res))
            (x1, v1, k1, r1), (x2, v2, k2, r2) = out
            assert r1 == r2 and r1[2] is False and r1[0] > 0, (dim, rk4, r1, r2)
            assert x1.tobytes() == x2.tobytes() and v1.tobytes() == v2.tobytes(), (dim, rk4)
            assert (k1 == k2).all()
            assert not np.array_equal(x1[~np.isnan(x1)], ps.x[~np.isnan(ps.x)])  # the step moved them


def test_near_list_from_blocks_of_flags_is_the_flag_by_flag_list():
    # ``_list_near`` passes over all-zero blocks of NEAR_BLOCK flags; the list must be what the
    # flag-by-flag compaction gives: the flagged indices in order from slot lo, then -1 if shorter.
    # Sparse and dense flags, a flag at each end of a block, chunks that end inside a block.
    rng = np.random.default_rng(11)
    b = pk.NEAR_BLOCK
    for lo, hi, density in ((0, 1024, 0.007), (1024, 2048, 0.5), (0, 1000, 0.02), (3, 40, 1.0), (5, 5 + b, 0.0),
                            (0, 7, 0.3)):
        flags = (rng.random(hi + 8) < density).astype(np.int64)
        if hi - lo > 2 * b:
            flags[lo + b - 1] = flags[lo + b] = 1  # the last slot of a block and the first of the next
        near = flags.copy()
        end = pk._list_near(near, lo, hi)
        expect = lo + np.flatnonzero(flags[lo:hi])
        assert end == lo + len(expect)
        assert (near[lo:end] == expect).all()
        if end < hi:
            assert near[end] == -1
        assert (near[:lo] == flags[:lo]).all() and (near[hi:] == flags[hi:]).all()  # nothing else written


def test_near_pass_helpers_do_not_count_references():
    # the per-particle helpers of the response are compiled without Numba's reference counting
    # (``_unrefcounted``): with it, each call made atomic increments and decrements on every array
    # argument, 30 % of the near pass's time (see the decorator's comment)
    import re

    from numba import njit

    from inertia.collision import distance as _d

    helpers = (pk._collide_near, pk._full_path, pk._resting_collider, pk._eval, pk._surface_velocity,
               pk._body_velocity, pk._clear_of_planes_and_spheres)
    assert all(fn.targetoptions.get("_nrt") is False for fn in helpers)
    # and the effect: ``_resting_collider`` compiled afresh (the kernels' copies come from the cache,
    # without IR) with the same options holds no NRT_incref / NRT_decref in its own code, and
    # compiled with Numba's defaults it does (else this check could not fail)
    ps = ia.ParticleSystem(np.zeros((1, 3)), radius=0.0)
    ps.add_collider(C.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    d = ps._collision
    opts = {k: v for k, v in pk._resting_collider.targetoptions.items() if k not in ("cache", "nopython")}
    for options in (opts, {}):
        fresh = njit(**options)(pk._resting_collider.py_func)
        k = fresh(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, d.cint, d.cf, d.ci, d.pose1, d.pose0, d.pose1, d.ref,
                  1.0, 1e-6, 1e-6, -1, -1, np.zeros((1, 3)), np.zeros((1, 3)), _d.kinds_token(pk.LIGHT_KINDS), None)
        assert k == 0  # on the plane, at rest
        ir = fresh.inspect_llvm(fresh.signatures[0])
        own = r'[^\n@]*@"?_ZN7inertia9collision16particle_kernels\d+_resting_collider'  # not the wrapper
        bodies = [m.split("\n}\n")[0] for m in re.split(r"^define ", ir, flags=re.M) if re.match(own, m)]
        counted = sum(b.count("@NRT_incref") + b.count("@NRT_decref") for b in bodies)
        assert bodies and (counted == 0) == (options is opts), (options, counted)
