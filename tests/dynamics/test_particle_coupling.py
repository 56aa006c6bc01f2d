"""Two-way particle/body coupling (inertia.dynamics.particle_coupling) in the World step."""

import numpy as np
import pytest

import inertia as ia
from inertia.dynamics.particle_coupling import apply_body_impulses
from inertia.math import quat_to_mat3
from inertia.model import ModelBuilder
from inertia.world import World


def _momenta(world, system, body):
    """Total linear momentum and angular momentum about the origin of particles + the body."""
    st, m = world.rigid.state, world.model
    mass = system.mass[:, None]
    p = (mass * system.v).sum(axis=0)
    L = (mass * np.cross(system.x, system.v)).sum(axis=0)
    q, qd = st.body_q[body], st.body_qd[body]
    M = m.body_mass[body]
    r = quat_to_mat3(np.ascontiguousarray(q[3:]))
    inertia_world = r @ np.diag(m.body_inertia[body]) @ r.T
    p = p + M * qd[3:]
    L = L + M * np.cross(q[:3], qd[3:]) + inertia_world @ qd[:3]
    return p, L


def test_stream_on_free_box_conserves_linear_and_angular_momentum():
    # gravity off: a stream of particles hits a free cube off-centre (it spins and drifts). Every
    # momentum change the collision pass gives the particles goes into the body, so the totals are
    # constant to rounding (Newton's third law); reference: the initial totals. A cube's inertia is
    # isotropic, so its free rotation conserves L exactly (no gyroscopic term).
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    box = b.add_body(position=(0.0, 0.0, 0.0))
    b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=100.0, restitution=0.5, friction=0.3)
    world = World(dt=1 / 240, model=b.finalize(), rigid_options={"substeps": 2, "enable_sleep": False})
    n = 12
    x = np.column_stack([-0.3 - 0.05 * np.arange(n), np.full(n, 0.06), 0.02 * np.sin(np.arange(n))])
    v = np.tile([3.0, 0.0, 0.0], (n, 1))
    ps = ia.ParticleSystem(x, v, masses=0.05, radius=0.01)
    world.add("stream", ps)
    p0, L0 = _momenta(world, ps, box)
    for _ in range(96):
        world.step()
        p, L = _momenta(world, ps, box)
        assert np.linalg.norm(p - p0) <= 1e-9 * np.linalg.norm(p0)
        assert np.linalg.norm(L - L0) <= 1e-9 * max(np.linalg.norm(L0), np.linalg.norm(p0) * 0.1)
    qd = world.rigid.state.body_qd[box]
    assert qd[3] > 0.05                      # the box was pushed along +x ...
    assert abs(qd[2]) > 1e-3                 # ... and spun about z by the off-centre hits
    assert np.all(ps.x[:, 0] < world.rigid.state.body_q[box, 0] + 0.1)   # nothing passed through


def test_particles_resting_on_a_box_load_the_ground_with_the_total_weight():
    # a box on the ground plane carrying 9 resting particles: averaged over a second, the plane's
    # normal impulse per second equals the total weight (M + n m) g (static equilibrium); without
    # the coupling it would be M g.
    g = 9.81
    b = ModelBuilder(gravity=(0.0, 0.0, -g))
    b.add_plane()
    box = b.add_body(position=(0.0, 0.0, 0.1))
    b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=500.0, friction=0.8)
    world = World(dt=1 / 240, model=b.finalize(), rigid_options={"substeps": 4})
    gx, gy = np.meshgrid([-0.05, 0.0, 0.05], [-0.05, 0.0, 0.05])
    x = np.column_stack([gx.ravel(), gy.ravel(), np.full(9, 0.2 + 0.01)])
    m = 0.2
    ps = ia.ParticleSystem(x, masses=m, radius=0.01)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -g)))
    world.add("load", ps)
    for _ in range(120):
        world.step()
    c = world.rigid.contacts
    support = 0.0
    steps = 240
    for _ in range(steps):
        world.step()
        a = c.manifolds()
        support += float(c.contact_total_normal_impulse[a].sum())
    weight = (world.model.body_mass[box] + 9 * m) * g
    assert support / (steps * world.dt) == pytest.approx(weight, rel=5e-3)
    assert np.all(np.abs(ps.x[:, 2] - 0.21) < 2e-3)      # they rest on the top face


def test_apply_body_impulses_changes_only_dynamic_bodies():
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    dyn = b.add_body(position=(0.0, 0.0, 0.0))
    b.add_sphere(dyn, 0.5, density=1000.0)
    kin = b.add_body(position=(2.0, 0.0, 0.0), body_type="kinematic")
    b.add_sphere(kin, 0.5)
    model = b.finalize()
    state = model.state()
    J = np.array([[1.0, 2.0, 3.0], [5.0, 5.0, 5.0]])
    A = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
    apply_body_impulses(model, state, J, A)
    m, i = model.body_mass[dyn], model.body_inertia[dyn]
    # sphere: v = J / m, w = A / (2/5 m r^2)
    np.testing.assert_allclose(state.body_qd[dyn, 3:], J[0] / m, rtol=1e-12)
    np.testing.assert_allclose(state.body_qd[dyn, :3], A[0] / (0.4 * m * 0.25), rtol=1e-12)
    np.testing.assert_allclose(i, 0.4 * m * 0.25, rtol=1e-12)
    assert np.all(state.body_qd[kin] == 0.0)


def test_a_collider_added_after_the_world_keeps_the_coupling_consistent():
    # rows are packed in the order they come; a collider attached after world.add goes after the body
    # rows and must not be mistaken for a body (its impulses go to the ground, the body's to the body)
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    box = b.add_body(position=(0.0, 0.0, 0.0))
    b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=100.0, restitution=1.0)
    world = World(dt=1 / 240, model=b.finalize(), rigid_options={"enable_sleep": False})
    x = np.array([[-0.3, 0.0, 0.0], [0.0, 0.0, 0.5]])
    v = np.array([[2.0, 0.0, 0.0], [0.0, 0.0, 2.0]])
    ps = ia.ParticleSystem(x, v, masses=0.1, radius=0.01)
    world.add("p", ps)
    ps.add_collider(ia.colliders.Plane(point=(0.0, 0.0, 0.7), normal=(0.0, 0.0, -1.0)), restitution=1.0)
    for _ in range(120):
        world.step()
    # the first particle bounced off the box (elastic): the box carries its momentum change, 0.1 * 4
    # less what the particle kept; the second bounced off the ceiling plane (the box is untouched by it)
    qd = world.rigid.state.body_qd[box]
    p_particle_x = 0.1 * ps.v[0, 0]
    assert qd[3] * world.model.body_mass[box] + p_particle_x == pytest.approx(0.2, rel=1e-9)
    assert ps.v[1, 2] < 0.0 and qd[5] == 0.0


@pytest.mark.parametrize("rest_speed", [1e-6, 0.05])
def test_a_free_box_pushed_by_its_load_accelerates_at_the_total_force_over_the_total_mass(rest_speed):
    # no gravity on the body, a downward force on the 9 particles resting on its top face only: box
    # and load accelerate together at a = 9 m g / (M + 9 m) (Newton's second law for the pair). With
    # the default rest_speed the load acts through the collision pass; with rest_speed = 5 cm/s and a
    # (force-free) spring between two particles, which makes the integrator evaluate the forces through
    # the resting-contact filter, the particles act through the filter's cancelled force.
    g = 9.81
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    box = b.add_body(position=(0.0, 0.0, 0.0))
    b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=500.0, friction=0.8)
    world = World(dt=1 / 240, model=b.finalize(), rigid_options={"substeps": 2, "enable_sleep": False})
    gx, gy = np.meshgrid([-0.05, 0.0, 0.05], [-0.05, 0.0, 0.05])
    m = 0.2
    ps = ia.ParticleSystem(np.column_stack([gx.ravel(), gy.ravel(), np.full(9, 0.11)]), masses=m, radius=0.01)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -g)))
    ia.colliders.configure_contacts(ps, rest_speed=rest_speed)
    if rest_speed > 1e-3:
        ps.add_force(ia.forces.Springs([[0, 8]], stiffness=1.0))      # at rest length: no force
    world.add("load", ps)
    steps = 120
    for _ in range(steps):
        world.step()
    M = world.model.body_mass[box]
    a = 9 * m * g / (M + 9 * m)
    t = steps * world.dt
    # the load's momentum enters the box one step late (explicit coupling): v(t) = a (t - dt) to O(dt)
    vz = world.rigid.state.body_qd[box, 5]
    assert -vz == pytest.approx(a * t, rel=2 * world.dt / t)
    assert np.all(np.abs(ps.v[:, 2] - vz) < 0.05 * a * t)        # the load moves with the box
    # momentum theorem: particles + box carry exactly the external impulse -9 m g t (to rounding)
    total = M * vz + m * ps.v[:, 2].sum()
    assert total == pytest.approx(-9 * m * g * t, rel=1e-12)
    counts = world["load"]._collision.coupling.counts
    assert counts["resting" if rest_speed > 1e-3 else "pass"] > 0


def test_particle_rows_of_the_contacts_buffer_carry_the_impulses_the_body_received():
    # gravity off, a stream hits a free cube off-centre while other particles slide on the static
    # ground plane. Newton's third law per contact row: the impulses of the particle rows on the cube
    # (shape 1) sum to minus the linear impulse the coupling gave the cube, and to its momentum change
    # over the step (the rigid stage moves a free, untouched cube at constant momentum) -- 1e-12
    # relative. Rows on the static plane (shape 0) are recorded too and push no body.
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    b.add_plane(offset=-0.5)
    box = b.add_body(position=(0.0, 0.0, 0.0))
    b.add_box(box, half_extents=(0.1, 0.1, 0.1), density=100.0, restitution=0.5, friction=0.3)
    world = World(dt=1 / 240, model=b.finalize(), rigid_options={"substeps": 2, "enable_sleep": False})
    n = 8
    x = np.column_stack([-0.3 - 0.05 * np.arange(n), np.full(n, 0.06), 0.02 * np.sin(np.arange(n))])
    x = np.vstack([x, [[0.3, 0.0, -0.49], [0.4, 0.0, -0.49]]])            # two on the plane
    v = np.vstack([np.tile([3.0, 0.0, 0.0], (n, 1)), [[0.0, 0.5, -0.2], [0.0, -0.5, -0.2]]])
    ps = ia.ParticleSystem(x, v, masses=0.05, radius=0.01)
    world.add("stream", ps)
    mass = world.model.body_mass[box]
    box_rows_seen = plane_rows_seen = 0
    for _ in range(60):
        p_before = mass * world.rigid.state.body_qd[box, 3:].copy()
        world.step()
        c = world.rigid.contacts
        rows = c.particle_rows()
        assert c.particle_start == c.count
        on_box = rows[c.contact_shape[rows, 0] == 1]
        on_plane = rows[c.contact_shape[rows, 0] == 0]
        box_rows_seen += on_box.size
        plane_rows_seen += on_plane.size
        assert np.all(c.contact_body[on_box, 0] == box) and np.all(c.contact_body[on_plane, 0] == -1)
        assert np.all(c.contact_particle[rows, 0] == 0) and np.all(np.diff(c.contact_particle[rows, 1]) >= 0)
        # the particle's impulse rebuilt from the row: normal and the two tangents
        j = (c.contact_normal_impulse[on_box, 0, None] * c.contact_normal[on_box]
             + np.einsum("rk,rkc->rc", c.contact_tangent_impulse[on_box, 0], c.contact_tangent[on_box]))
        received = world._impulse_linear[box]
        scale = max(np.linalg.norm(received), 1e-30)
        assert np.linalg.norm(j.sum(axis=0) + received) <= 1e-12 * scale + 1e-300
        dp = mass * world.rigid.state.body_qd[box, 3:] - p_before
        assert np.linalg.norm(dp + j.sum(axis=0)) <= 1e-12 * max(np.linalg.norm(p_before), scale)
    assert box_rows_seen >= n and plane_rows_seen >= 2 * 60 - 2   # every hit recorded; the sliders stay
