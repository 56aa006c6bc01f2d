"""Impact rows of the fused particle step (issue 9: one contact buffer with the impulses applied).

In a World whose bodies are all static the particle groups run their collision pass inside the
integrator's kernel (``particle_kernels.step_and_collide``); its near loop writes the coupling's
contact slots itself, so the Contacts buffer lists impacts with their impulses exactly as after
the separate pass (``particle_coupling.gather_pass_impulses``).
"""

import hashlib

import numpy as np
import pytest

import inertia as ia
from inertia.model import ModelBuilder
from inertia.world import World

G = 9.81
ROW_FIELDS = ("contact_shape", "contact_body", "contact_particle", "contact_point_count", "contact_normal",
              "contact_point", "contact_separation", "contact_tangent", "contact_normal_impulse",
              "contact_total_normal_impulse", "contact_tangent_impulse", "contact_is_sensor")


def _static_world(x, v, *, integrator="rk4", restitution=0.5, friction=0.2, fuse=True, mass=0.002, substeps=1):
    """A ground plane (table row 0, body -1) and a static box (row 1) under gravity, particles of
    radius 1 cm. ``fuse=False`` forces the separate collision pass."""
    b = ModelBuilder(gravity=(0.0, 0.0, -G))
    b.add_plane(restitution=restitution, friction=friction)
    wall = b.add_body(body_type="static", position=(0.3, 0.0, 0.15))
    b.add_box(wall, (0.1, 0.3, 0.15), restitution=0.6, friction=0.3)
    world = World(dt=1 / 240, substeps=substeps, model=b.finalize())
    ps = ia.ParticleSystem(np.asarray(x, float), np.asarray(v, float), masses=mass, radius=0.01)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -G)))
    world.add("p", ps, integrator=integrator)
    d = ps._collision
    assert d.coupling is not None and not d.any_moving   # rows recorded, nothing moves
    if not fuse:
        d.can_fuse = lambda: False
    return world, ps


def _rain(n=60, seed=3):
    # particles above the plane and clear of the box, thrown at it and at the ground
    rng = np.random.default_rng(seed)
    x = rng.uniform([-0.3, -0.2, 0.03], [0.1, 0.2, 0.4], (n, 3))
    v = rng.normal(0.0, 1.0, (n, 3)) + [1.0, 0.0, 0.0]
    return x, v


def _rows(world):
    c = world.rigid.contacts
    r = c.particle_rows()
    return {name: getattr(c, name)[r].copy() for name in ROW_FIELDS}


def _step_both_with_equal_rows(first, second):
    """Step two worlds once; their particle Contacts rows must be equal, field by field, bit for bit.
    Returns both rows."""
    first.step()
    second.step()
    a, b = _rows(first), _rows(second)
    for name in ROW_FIELDS:
        assert np.array_equal(a[name], b[name]), name
    return a, b


def _row_impulses(rows):
    """(R, 3) impulse each row's shape gave its particle, rebuilt from the normal and tangent parts."""
    return (rows["contact_normal_impulse"][:, 0, None] * rows["contact_normal"]
            + np.einsum("rk,rkc->rc", rows["contact_tangent_impulse"][:, 0], rows["contact_tangent"]))


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_fused_and_separate_paths_give_the_same_contact_rows_step_by_step(integrator):
    # impacts on the plane and the box, bounces, resting contacts (restitution and friction): each
    # step the fused path's particle rows equal the separate path's, same order, same impulses, bit
    # for bit (the fused step runs the separate pass's arithmetic, and its near loop credits each
    # particle's change over the pass to the same row, particle_kernels.pass_row). The fused path
    # used to list resting rows only, with zero impulse.
    x, v = _rain()
    fused, pf = _static_world(x, v, integrator=integrator)
    separate, pse = _static_world(x, v, integrator=integrator, fuse=False)
    weight_step = 0.002 * G / 240
    impacts = resting = 0
    shapes = set()
    for _ in range(90):
        a, b = _step_both_with_equal_rows(fused, separate)
        jn = a["contact_total_normal_impulse"][:, 0]
        impacts += int((jn > 3.0 * weight_step).sum())
        resting += int((np.abs(jn - weight_step) <= 1e-9 * weight_step).sum())
        shapes |= set(a["contact_shape"][:, 0].tolist())
    assert pf._collision.fused_step is not None and pse._collision.fused_step is None
    assert np.array_equal(pf.state, pse.state)
    assert impacts >= 60 and resting >= 60                # both kinds of row were compared ...
    assert shapes == {0, 1}                               # ... on the plane and on the box


def test_an_impact_on_a_static_plane_begins_with_the_impulse_m_1_plus_e_vn():
    # a particle dropped from rest, its surface h = 0.1 m above a static plane (restitution e,
    # friction mu), sliding at u = 1 m/s: it meets the plane at v_n = sqrt(2 g h) within a step
    # (rk4 follows the parabola exactly under gravity). Newton's impact law (Witkin & Baraff 2001,
    # v' = v_T - e v_N) gives the normal impulse m (1 + e) v_n; Coulomb friction at the impact
    # (Bridson et al. 2002, friction bounded by the normal impulse) the tangential impulse
    # mu m (1 + e) v_n against the sliding while that is below m u. The event is a begin on
    # (group 0, particle 0, row 0), on the fused path; to rounding (1e-9 relative: the impact time
    # on the step's parabola is a quadratic root).
    m, e, mu, h, u = 0.002, 0.5, 0.2, 0.1, 1.0
    world, ps = _static_world([[-0.5, 0.0, 0.01 + h]], [[u, 0.0, 0.0]], restitution=e, friction=mu, mass=m)
    for _ in range(60):
        world.step()
        ev = world.contact_events()
        if len(ev["particle_begin"]):
            break
    assert ps._collision.fused_step == "rk4"
    assert ev["particle_begin"].tolist() == [[0, 0, 0]]
    vn = np.sqrt(2.0 * G * h)
    assert ev["particle_begin_impulse"][0] == pytest.approx(m * (1.0 + e) * vn, rel=1e-9)
    j = _row_impulses(_rows(world))[0]
    np.testing.assert_allclose(j, [-mu * m * (1.0 + e) * vn, 0.0, m * (1.0 + e) * vn], rtol=1e-9,
                               atol=1e-12 * m * vn)
    # the bounce: it leaves at e v_n (the rest of the step under gravity)
    assert ps.v[0, 2] > 0.0


@pytest.mark.parametrize("fuse", [True, False])
def test_row_impulses_sum_to_the_particles_momentum_change_minus_gravity(fuse):
    # momentum bookkeeping, every step: the particles' momentum changes by gravity's impulse
    # M g dt plus what the shapes gave them, and every contact the pass makes is credited to a
    # row, so sum(row impulses) = P(t + dt) - P(t) - M g dt (to rounding: 1e-12 of the momentum
    # scale), on the fused and the separate path alike
    x, v = _rain(40, seed=8)
    world, ps = _static_world(x, v, fuse=fuse)
    gravity_step = ps.mass.sum() * np.array([0.0, 0.0, -G]) / 240
    scale = (ps.mass[:, None] * np.abs(ps.v)).sum()
    hits = 0
    for _ in range(90):
        p0 = (ps.mass[:, None] * ps.v).sum(axis=0)
        world.step()
        p1 = (ps.mass[:, None] * ps.v).sum(axis=0)
        rows = _rows(world)
        j = _row_impulses(rows).sum(axis=0)
        assert np.linalg.norm(p1 - p0 - gravity_step - j) <= 1e-12 * scale
        hits += rows["contact_shape"].shape[0]
    assert (ps._collision.fused_step is not None) == fuse
    assert hits > 100


def test_fused_contact_rows_are_the_same_bits_at_1_and_2_threads(monkeypatch, thread_counts):
    # the parallel build of the fused step: each particle's slots are written by its own chunk, so
    # the rows do not depend on the thread count
    from inertia import _jit
    monkeypatch.setattr(_jit, "SERIAL_BELOW", 0)
    digests = []
    for _ in thread_counts():
        x, v = _rain(3000, seed=1)
        world, ps = _static_world(x, v)
        h = hashlib.sha256()
        for _ in range(40):
            world.step()
            for arr in _rows(world).values():
                h.update(arr.tobytes())
        assert ps._collision.fused_step == "rk4" and world.rigid.contacts.particle_count > 0
        digests.append(h.hexdigest())
    assert len(set(digests)) == 1


def _listed(ps):
    t = ps._collision.coupling.touched
    return t.index[:t.state[0]]


@pytest.mark.parametrize("fuse, substeps", [(True, 1), (True, 2), (False, 2)])
def test_rows_are_cleared_and_filled_for_the_particles_in_contact_only(fuse, substeps):
    # the world clears the contact slots and fills the Contacts rows of the particles its coupling
    # listed (TouchedParticles), not of every particle: 4000 particles 50 m up, far from every
    # shape, added to the rain change no row and list nothing, so the clear and the fill do the
    # same work with and without them. Every particle that can have a row (a slot taken, or
    # resting on a table row: the rows the full scan would write) is listed, and the rows come
    # out in particle order also when a second substep lists lower indices (sorted before the fill)
    x, v = _rain(200, seed=5)
    far = np.column_stack([np.linspace(-1.0, 1.0, 4000), np.zeros(4000), np.full(4000, 50.0)])
    small, ps_small = _static_world(x, v, fuse=fuse, substeps=substeps)
    big, ps_big = _static_world(np.vstack([x, far]), np.vstack([v, np.zeros_like(far)]), fuse=fuse,
                                substeps=substeps)
    coupling = ps_big._collision.coupling
    unsorted = []
    row_order = coupling.row_order

    def spy(every):     # was the list out of order before the fill sorted it?
        unsorted.append(int(coupling.touched.state[1] == 0))
        return row_order(every)

    coupling.row_order = spy
    listed_max = 0
    for _ in range(90):
        a, b = _step_both_with_equal_rows(small, big)
        assert np.all(np.diff(b["contact_particle"][:, 1]) >= 0)          # particle order
        c = coupling
        rest_k = ps_big._collision.rest_k
        can_have_rows = (c.slot_entry[:, 0] >= 0) | ((rest_k >= 0) & (c.entry_shape[np.maximum(rest_k, 0)] >= 0))
        assert set(_listed(ps_big).tolist()) == set(np.flatnonzero(can_have_rows).tolist())
        assert np.array_equal(_listed(ps_big), _listed(ps_small))       # none of the far particles
        listed_max = max(listed_max, _listed(ps_big).size)
    assert (ps_big._collision.fused_step is not None) == fuse
    assert listed_max >= 25 and big.rigid.contacts.particle_count > 0
    assert (sum(unsorted) > 0) == (substeps > 1)        # the sort was needed with two substeps
    # the next step's clear empties every slot (no particle outside the list held one)
    coupling.clear_slots()
    assert (coupling.slot_entry == -1).all() and (coupling.slot_impulse == 0.0).all()
    assert not coupling.touched.listed.any() and coupling.touched.state[0] == 0
