"""The particle collision stage: entry points, bad input, warnings, checkpoints."""

import numpy as np
import pytest

import inertia as ia

from .conftest import particles, state_hash

C = ia.colliders


@pytest.mark.parametrize("kwargs, match", [
    ({"restitution": 1.5}, r"restitution must be in \[0, 1\]"),
    ({"restitution": -0.1}, r"restitution must be in \[0, 1\]"),
    ({"restitution": "a"}, "restitution must be a number"),
    ({"friction": -0.2}, "friction must be a finite number >= 0"),
    ({"friction": np.inf}, "friction must be a finite number >= 0"),
])
def test_bad_contact_parameters(kwargs, match):
    ps = particles([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match=match):
        ps.add_collider(C.Plane(), **kwargs)


def test_bad_collider_mode_and_flags():
    ps = particles([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="collider must be one of inertia.colliders"):
        ps.add_collider("plane")
    with pytest.raises(ValueError, match="collider is 2-D but the particle system is 3-D"):
        ps.add_collider(C.Plane(point=(0, 0), normal=(0, 1)))
    with pytest.raises(ValueError, match=r"collision_mode must be one of \('a_priori', 'a_posteriori'\)"):
        ps.collision_mode = "continuous"
    with pytest.raises(ValueError, match="self_collisions must be True or False"):
        ps.self_collisions = "yes"
    with pytest.raises(ValueError, match="iterations must be an integer >= 1"):
        C.configure_contacts(ps, iterations=0)
    with pytest.raises(ValueError, match="distance_tolerance must be"):
        C.configure_contacts(ps, distance_tolerance=-1.0)
    assert ps.collision_mode == "a_priori" and ps.self_collisions is False
    ps.collision_mode = "a_posteriori"
    assert ps.collision_mode == "a_posteriori"


def test_self_collisions_without_radius_warns():
    ps = particles([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]])
    with pytest.warns(UserWarning, match="radius 0"):
        ps.self_collisions = True


def test_particles_starting_inside_are_pushed_out_with_a_warning():
    pos = np.array([[0.0, 0.0, -0.2], [0.1, 0.0, -0.5], [0.0, 0.0, 1.0], [3.0, 0.0, 0.1]])
    ps = particles(pos, radius=0.0)
    ps.add_collider(C.Plane(), restitution=0.0)
    ps.add_collider(C.Sphere(center=(3, 0, 0), radius=0.5), restitution=0.0)
    sim = ia.Simulation(ps, dt=1e-3)
    with pytest.warns(UserWarning, match=r"3 particles start inside colliders \(Plane #0: 2, Sphere #1: 1\)"):
        sim.step()
    assert ps.x[0, 2] >= -1e-9 and ps.x[1, 2] >= -1e-9
    assert np.linalg.norm(ps.x[3] - [3, 0, 0]) >= 0.5 - 1e-9


def test_collider_queries_fill_preallocated_outputs():
    col = C.Sphere(center=(0, 0, 0), radius=1.0, motion=lambda t: (t, 0.0, 0.0))
    p = np.array([[2.0, 0.0, 0.0], [1.0, 1.0, 0.0]])
    d, n, v = np.empty(2), np.empty((2, 3)), np.empty((2, 3))
    col.query(p, 1.0, d, n, v)
    np.testing.assert_allclose(d, [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(n, [[1, 0, 0], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(v, [[1, 0, 0], [1, 0, 0]], atol=1e-6)


def _scene():
    rng = np.random.default_rng(11)
    pos = rng.uniform([-1, -1, 0.2], [1, 1, 1.5], size=(300, 3))
    ps = particles(pos, rng.normal(0, 1, size=(300, 3)), radius=0.03)
    ps.add_collider(C.Container(center=(0, 0, 1), half_extents=(1.2, 1.2, 1.0)), restitution=0.4, friction=0.3)
    ps.add_collider(C.Sphere(center=(0, 0, 0.3), radius=0.3, motion=lambda t: (0.2 * np.sin(t), 0.0, 0.3)),
                    restitution=0.6, friction=0.1)
    ps.add_collider(C.Box(center=(0.5, 0.5, 0.2), half_extents=(0.2, 0.1, 0.2), rotation=(0, 0, 0.5)))
    return ps


@pytest.mark.filterwarnings("ignore:.*start inside colliders")  # random particles, some inside
@pytest.mark.parametrize("self_collisions", [False, True])
def test_checkpoint_restore_continues_bit_identically(self_collisions):
    ps = _scene()
    ps.self_collisions = self_collisions
    sim = ia.Simulation(ps, dt=2e-3)
    sim.run(0.2)
    saved = sim.save_state()
    sim.run(0.2)
    first = state_hash(ps)
    sim.restore_state(saved)
    sim.run(0.2)
    assert state_hash(ps) == first


@pytest.mark.filterwarnings("ignore:.*start inside colliders")  # random particles, some inside
def test_2d_particles_rest_in_a_2d_container_with_a_circle():
    rng = np.random.default_rng(5)
    ps = particles(rng.uniform([-0.8, 0.2], [0.8, 1.5], size=(50, 2)), radius=0.0)
    ps.add_collider(C.Container(center=(0, 1), half_extents=(1, 1)), restitution=0.3, friction=0.5)
    ps.add_collider(C.Sphere(center=(0, 0.3), radius=0.25), restitution=0.3, friction=0.5)
    ps.add_collider(C.Capsule(a=(-0.7, 0.6), b=(-0.2, 0.8), radius=0.05), restitution=0.3, friction=0.5)
    ps.add_collider(C.Box(center=(0.5, 0.5), half_extents=(0.2, 0.05), rotation=0.3), restitution=0.3)
    sim = ia.Simulation(ps, dt=1e-3)
    sim.run(3.0)
    cont = ps._collision.colliders[0]
    assert np.all(cont.signed_distance(ps.x) >= -1e-6)
    for col in ps._collision.colliders[1:]:
        assert np.all(col.signed_distance(ps.x) >= -1e-6)
    assert np.abs(ps.v).max() < 0.5  # settling (particles on the round top may still slide)


def test_profile_counts_steps():
    ps = particles([[0.0, 0.0, 1.0]])
    ps.add_collider(C.Plane())
    sim = ia.Simulation(ps, dt=1e-3)
    sim.run(0.01)
    prof = ps._collision.profile
    assert prof["steps"] == 10 and prof["collide"] > 0


def _static_scene(dim, mode, n=300):
    # static colliders of four kinds, particles with and without radius, drag (affine forces)
    rng = np.random.default_rng(3)
    lo, hi = ([-1, -1, 0.0], [1, 1, 1.5]) if dim == 3 else ([-1, 0.0], [1, 1.5])
    ps = particles(rng.uniform(lo, hi, (n, dim)), rng.normal(0, 2, (n, dim)), radius=rng.uniform(0, 0.02, n))
    ps.add_force(ia.forces.Drag(0.05))
    up = (0, 0, 1) if dim == 3 else (0, 1)
    ps.add_collider(C.Plane(point=(0,) * dim, normal=up), restitution=0.3, friction=0.4)
    ps.add_collider(C.Sphere(center=(0.3, 0, 0.4)[:dim], radius=0.4), restitution=0.6, friction=0.1)
    ps.add_collider(C.Container(center=(0, 0, 1)[:dim], half_extents=(1.2,) * dim), restitution=0.8,
                    friction=0.2)
    ps.add_collider(C.Box(center=(-0.5, 0.5, 0.2)[:dim], half_extents=(0.2, 0.1, 0.2)[:dim],
                          rotation=(0, 0, 0.5) if dim == 3 else 0.5), restitution=0.5)
    ps.collision_mode = mode
    return ps


@pytest.mark.filterwarnings("ignore:.*start inside colliders")  # random particles, some inside
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("mode", ["a_priori", "a_posteriori"])
@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_fused_collision_pass_gives_the_bits_of_the_separate_pass(integrator, mode, dim):
    # static colliders with the fused integrators: the collision pass runs inside the integrator's
    # kernel (particle_kernels.step_and_collide); it must reproduce the integrator's kernel
    # followed by collide_particles bit for bit (resting contact, impacts, friction, radius)
    def make(fuse):
        ps = _static_scene(dim, mode)
        if not fuse:
            ps._collision.can_fuse = lambda: False
        sim = ia.Simulation(ps, integrator=integrator, dt=1 / 240)
        sim.run(0.75)
        return ps

    fused, separate = make(True), make(False)
    assert fused._collision.fused_step is not None and separate._collision.fused_step is None
    assert fused._collision.resting_count == separate._collision.resting_count > 0
    assert state_hash(fused) == state_hash(separate)


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_a_world_whose_bodies_are_all_static_takes_the_fused_path_with_the_same_bits(integrator):
    # a World with a static body (a box) and a ground plane on body -1: no body moves, so the
    # particle group fuses its collision pass into the integrator's kernel although the world
    # couples it to the (static) table; the state equals the separate pass's bit for bit
    from inertia.model import ModelBuilder
    from inertia.world import World

    def make(fuse):
        b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
        b.add_plane(friction=0.4, restitution=0.3)
        wall = b.add_body(body_type="static", position=(0.3, 0.0, 0.2))
        b.add_box(wall, (0.1, 0.3, 0.2), friction=0.2, restitution=0.6)
        world = World(dt=1 / 240, model=b.finalize())
        rng = np.random.default_rng(5)
        ps = ia.ParticleSystem(rng.uniform([-0.5, -0.3, 0.05], [0.5, 0.3, 0.6], (200, 3)),
                               rng.normal(0.0, 1.0, (200, 3)), masses=0.001, radius=0.01)
        ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
        world.add("p", ps, integrator=integrator)
        d = ps._collision
        assert d.coupling is not None and not d.any_moving  # coupled to the table, nothing moves
        if not fuse:
            d.can_fuse = lambda: False
        for _ in range(120):
            world.step()
        return ps

    with pytest.warns(UserWarning, match="start inside"):  # random particles, some in the box
        fused = make(True)
    with pytest.warns(UserWarning, match="start inside"):
        separate = make(False)
    assert fused._collision.fused_step is not None and separate._collision.fused_step is None
    assert fused._collision.resting_count == separate._collision.resting_count > 0
    assert state_hash(fused) == state_hash(separate)


# sha256 of the state of _static_scene(3, "a_priori", 2000) after 0.5 s of rk4 at dt = 1/240
FUSED_GOLDEN = "d24935d6ce9721f397c864a45d742ae8de74805295a2eaac6456c445b543dbfe"


@pytest.mark.filterwarnings("ignore:.*start inside colliders")  # random particles, some inside
def test_fused_collision_pass_is_deterministic_at_1_and_2_threads(monkeypatch):
    import numba

    from inertia import _jit
    monkeypatch.setattr(_jit, "SERIAL_BELOW", 0)  # the parallel kernels
    before = numba.get_num_threads()
    hashes = []
    try:
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            ps = _static_scene(3, "a_priori", 2000)
            ia.Simulation(ps, integrator="rk4", dt=1 / 240).run(0.5)
            assert ps._collision.fused_step == "rk4"
            hashes.append(state_hash(ps))
    finally:
        numba.set_num_threads(before)
    assert set(hashes) == {FUSED_GOLDEN}


# --- issue 8: the NumPy path of unbaked SDF colliders matches the compiled kernels ---------------
# Closed forms (gravity g, restitution e, drop height h0): apex after bounce n: e^(2n) h0; time to
# rest: sqrt(2 h0 / g) (1 + e) / (1 - e). Before the fix the unbaked path used the straight path,
# kept the velocity gained inside (a posteriori) and never rested for e = 0.9.
from .conftest import G, particles  # noqa: E402


def _floor_sdf(points):
    return points[:, 2]


def _floor_gradient(points):
    return np.tile([0.0, 0.0, 1.0], (points.shape[0], 1))


def _sdf_drop(h0, e, dt, mode, integrator="rk4", vz=0.0, compiled=False):
    ps = particles([[0.0, 0.0, h0]], [[0.0, 0.0, vz]])
    floor = C.Plane() if compiled else C.SDF(_floor_sdf, gradient=_floor_gradient)
    ps.add_collider(floor, restitution=e)
    ps.collision_mode = mode
    return ps, ia.Simulation(ps, integrator=integrator, dt=dt)


def _last_moving(ps, sim, t_end):
    last = 0.0
    while sim.t < t_end:
        z_before = ps.x[0, 2]
        sim.step()
        if abs(ps.x[0, 2] - z_before) > 1e-12 or ps.v[0, 2] != 0.0:
            last = sim.t
    return last


@pytest.mark.parametrize("mode", ["a_priori", "a_posteriori"])
@pytest.mark.parametrize("e", [0.5, 0.6, 0.7, 0.8, 0.9])
def test_unbaked_sdf_ball_rests_at_the_geometric_series_time(one_thread, e, mode):
    h0, dt = 1.0, 1 / 600
    t_rest = np.sqrt(2 * h0 / G) * (1 + e) / (1 - e)
    ps, sim = _sdf_drop(h0, e, dt, mode)
    assert _last_moving(ps, sim, 1.25 * t_rest) == pytest.approx(t_rest, rel=0.05)
    assert ps.v[0, 2] == 0.0 and abs(ps.x[0, 2]) <= 1e-6


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_unbaked_sdf_apex_heights(one_thread, integrator):
    # the velocity lag of symplectic Euler is handed on as in the kernels, so both methods give
    # the exact apexes up to sampling at steps (<= g dt^2 / 8 = 3.4e-6 m, 2e-5 of the 8th apex);
    # the issue asks 2 %, we hold 0.1 %. Before the fix: +4 % (rk4) and -4 % (symplectic Euler)
    # by the 8th apex
    h0, e, dt = 1.0, 0.9, 1 / 600
    ps, sim = _sdf_drop(h0, e, dt, "a_priori", integrator)
    apexes, z_prev, rising = [], ps.x[0, 2], False
    for _ in range(12 * 600):
        sim.step()
        z = ps.x[0, 2]
        if rising and z < z_prev:
            apexes.append(z_prev)
            if len(apexes) == 8:
                break
        rising, z_prev = z > z_prev, z
    np.testing.assert_allclose(apexes, h0 * e ** (2 * np.arange(1, 9)), rtol=1e-3)


def test_unbaked_sdf_bounce_keeps_gravity_and_matches_the_compiled_plane():
    # issue 8 reproducer: in 0.0346 m/s (above the resting threshold 2 g dt), out e times that
    # (below it); the exact step: impact at t*, then e v_in up for dt - t* under gravity
    z0, v0, e, dt = 2.3076e-5, -0.027334, 0.9, 1 / 600
    t_star = (v0 + np.sqrt(v0 * v0 + 2 * G * z0)) / G
    v_in, rem = -v0 + G * t_star, dt - t_star
    energy0 = 0.5 * v0 * v0 + G * z0
    finals = []
    for compiled in (False, True):
        ps, sim = _sdf_drop(z0, e, dt, "a_priori", vz=v0, compiled=compiled)
        sim.step()
        assert ps.v[0, 2] == pytest.approx(e * v_in - G * rem, rel=1e-9)  # 0.02213
        energy1 = 0.5 * ps.v[0, 2] ** 2 + G * ps.x[0, 2]
        assert energy1 == pytest.approx(0.5 * (e * v_in) ** 2, rel=1e-9) and energy1 < energy0
        finals.append(ps.state.copy())
    np.testing.assert_allclose(finals[0], finals[1], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("mode", ["a_priori", "a_posteriori"])
def test_unbaked_sdf_trajectory_agrees_with_the_compiled_plane(one_thread, mode):
    h0, e, dt = 1.0, 0.8, 1 / 600
    runs = [_sdf_drop(h0, e, dt, mode, compiled=c) for c in (False, True)]
    for _ in range(1200):
        for ps, sim in runs:
            sim.step()
        np.testing.assert_allclose(runs[0][0].x[0, 2], runs[1][0].x[0, 2], atol=1e-9)
    np.testing.assert_allclose(runs[0][0].v, runs[1][0].v, atol=1e-7)
