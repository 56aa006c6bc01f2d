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
