"""Emitters: rate, lifetime, pool, distributions, determinism."""

import numpy as np
import pytest

import inertia as ia


def fountain(seed=0, capacity=500, rate=200.0, lifetime=1.0):
    ps = ia.ParticleSystem.pool(capacity, dim=3)
    ps.add_force(ia.forces.Gravity())
    emitter = ps.add_emitter(ia.Emitter(rate=rate, position=ia.DiskSource((0, 0, 0), 0.1),
                                        velocity=ia.Cone((0, 0, 1), speed=5.0, spread=0.3, speed_jitter=0.1),
                                        lifetime=lifetime, seed=seed))
    return ps, emitter


def test_rate_and_lifetime():
    """After time t < lifetime, floor(rate t) particles are alive; after that the count stays at
    rate * lifetime (each one retires exactly when its age reaches the lifetime)."""
    ps, _ = fountain(rate=200.0, lifetime=1.0)
    sim = ia.Simulation(ps, integrator="semi_implicit_euler", dt=0.01)
    sim.run(0.5)
    assert ps.active.sum() == 100
    sim.run(1.5)
    assert ps.active.sum() == 200
    assert np.all(ps.particle_age[ps.active] < 1.0 + 1e-9)
    # retired particles are inactive, motionless and excluded from energy
    dead = ~ps.active
    assert np.all(ps.v[dead] == 0) and np.all(ps.inv_mass[dead] == 0)


def test_spawned_particles_follow_the_forces():
    """A particle emitted at speed v0 up the z axis with no spread follows z = v0 t - g t^2 / 2."""
    ps = ia.ParticleSystem.pool(10)
    ps.add_force(ia.forces.Gravity((0, 0, -10.0)))
    # rate * window = 100 * 0.01 = exactly one particle, spawned at the end of the first step
    ps.add_emitter(ia.Emitter(rate=100.0, position=(0, 0, 0), velocity=(0, 0, 5.0), stop=0.01))
    sim = ia.Simulation(ps, integrator="rk4", dt=0.01)
    sim.run(0.02)   # then one more step of 0.01 s
    i = np.flatnonzero(ps.active)
    assert len(i) == 1
    assert ps.x[i[0], 2] == pytest.approx(5.0 * 0.01 - 5.0 * 0.01 ** 2, abs=1e-12)


def test_distributions_stay_in_their_shapes():
    rng = np.random.default_rng(0)
    out = np.zeros((2000, 3))
    ia.DiskSource((1, 2, 3), 0.5, normal=(0, 1, 0)).draw(rng, out)
    assert np.all(np.linalg.norm(out - [1, 2, 3], axis=1) <= 0.5 + 1e-12)
    np.testing.assert_allclose(out[:, 1], 2.0)
    ia.SphereSource((0, 0, 0), 2.0).draw(rng, out)
    r = np.linalg.norm(out, axis=1)
    assert r.max() <= 2.0 and np.mean(r ** 3) == pytest.approx(8.0 / 2, rel=0.1)  # uniform in volume
    ia.BoxSource((0, 0, 0), (1, 2, 3)).draw(rng, out)
    assert np.all(np.abs(out) <= [1, 2, 3])
    cone = ia.Cone((0, 0, 1), speed=4.0, spread=0.2, speed_jitter=0.25)
    cone.draw(rng, out)
    speed = np.linalg.norm(out, axis=1)
    assert speed.min() >= 3.0 - 1e-12 and speed.max() <= 5.0 + 1e-12
    assert np.all(out[:, 2] / speed >= np.cos(0.2) - 1e-12)


def test_same_seed_same_particles_and_full_pool_drops():
    a, _ = fountain(seed=7)
    b, _ = fountain(seed=7)
    c, _ = fountain(seed=8)
    for ps in (a, b, c):
        ia.Simulation(ps, integrator="rk4", dt=0.01).run(0.3)
    np.testing.assert_array_equal(a.state, b.state)
    assert not np.array_equal(a.state, c.state)
    small, emitter = fountain(capacity=20, rate=100.0, lifetime=5.0)
    ia.Simulation(small, dt=0.01).run(0.5)
    assert small.active.sum() == 20 and emitter.dropped == 30


@pytest.mark.parametrize("kwargs,match", [
    (dict(rate=0.0), "Emitter rate must be a finite number > 0"),
    (dict(lifetime=-1.0), "Emitter lifetime must be > 0"),
    (dict(lifetime=(2.0, 1.0)), "min <= max"),
    (dict(start=2.0, stop=1.0), "stop must be after start"),
    (dict(velocity="fast"), "Emitter velocity must be finite"),
])
def test_bad_emitter_input(kwargs, match):
    if kwargs.get("velocity") == "fast":
        kwargs["velocity"] = (0, 0, np.nan)
    args = dict(rate=10.0, position=(0, 0, 0), velocity=(0, 0, 1.0))
    with pytest.raises(ValueError, match=match):
        args.update(kwargs)
        ia.Emitter(**args)


def test_bad_cone():
    with pytest.raises(ValueError, match="Cone direction must be non-zero"):
        ia.Cone((0, 0, 0), 1.0)
