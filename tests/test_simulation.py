"""Simulation loop: checkpoints continue bit for bit; results are identical at 1 and 2 threads."""

import hashlib
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import inertia as ia


def cloth(n=12, seed=0):
    """A small hanging spring grid with structural and shear springs, two corners pinned."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x = np.stack([i.ravel() * 0.1, np.zeros(n * n), -j.ravel() * 0.1], axis=1)
    idx = (i * n + j)
    pairs = np.concatenate([
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], 1),
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], 1),
        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()], 1),
        np.stack([idx[1:, :-1].ravel(), idx[:-1, 1:].ravel()], 1)])
    rng = np.random.default_rng(seed)
    ps = ia.ParticleSystem(x, rng.normal(0, 0.1, x.shape), masses=0.01, pinned=[0, (n - 1) * n])
    ps.add_force(ia.forces.Gravity())
    ps.add_force(ia.forces.Springs(pairs, stiffness=50.0, damping=0.05))
    ps.add_force(ia.forces.Drag(0.001))
    return ps


def with_emitter(seed=3):
    ps = ia.ParticleSystem.pool(300)
    ps.add_force(ia.forces.Gravity())
    ps.add_force(ia.forces.QuadraticDrag(0.01))
    ps.add_emitter(ia.Emitter(rate=300.0, position=ia.SphereSource((0, 0, 0), 0.2),
                              velocity=ia.Cone((0, 0, 1), 3.0, spread=0.5), lifetime=(0.2, 0.5), seed=seed))
    return ps


@pytest.mark.parametrize("name", ia.integrators.available())
def test_restore_continues_bit_for_bit(name):
    """save at step 50, run 50 more -> A; restore, run 50 -> B: A == B exactly (integrator history,
    emitter random state and pool included)."""
    dt = 2e-3 if name not in ("euler",) else 5e-4
    for make in (cloth, with_emitter):
        ps = make()
        sim = ia.Simulation(ps, integrator=name, dt=dt)
        for _ in range(50):
            sim.step()
        saved = sim.save_state()
        for _ in range(50):
            sim.step()
        a, t_a = ps.state.copy(), sim.t
        sim.restore_state(saved)
        for _ in range(50):
            sim.step()
        np.testing.assert_array_equal(ps.state, a)
        assert sim.t == t_a


SCRIPT = textwrap.dedent("""
    import hashlib, sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    from test_simulation import cloth, with_emitter
    import inertia as ia
    digest = hashlib.sha256()
    for name in ["implicit_euler", "rk4", "semi_implicit_euler", "velocity_verlet"]:
        for make in (cloth, with_emitter):
            ps = make()
            ia.Simulation(ps, integrator=name, dt=2e-3).run(0.2)
            digest.update(ps.state.tobytes())
    print(digest.hexdigest())
""")


def run_with_threads(threads):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    script = SCRIPT.format(tests=os.path.dirname(__file__))
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip().splitlines()[-1]


def test_bit_identical_at_one_and_two_threads_and_run_to_run():
    """Same scene and seed: the same state hash at NUMBA_NUM_THREADS=1 and 2, and twice at 2."""
    one, two, again = run_with_threads(1), run_with_threads(2), run_with_threads(2)
    assert one == two == again


def test_implicit_euler_cloth_is_stable_and_hangs():
    ps = cloth()
    sim = ia.Simulation(ps, integrator="implicit_euler", dt=0.02)
    sim.run(2.0)
    assert np.all(np.isfinite(ps.state))
    assert ps.x[:, 2].min() < -1.0 and ps.kinetic_energy() < 1.0
    assert sim.integrator.last_cg_iterations < sim.integrator.cg_max_iterations


def test_profile_and_callback():
    seen = []
    ps = cloth(4)
    sim = ia.Simulation(ps, integrator="rk4", dt=1e-3, callback=lambda s: seen.append(s.step_count))
    sim.run(0.01)
    assert seen == list(range(1, 11))
    assert sim.t == pytest.approx(0.01, abs=1e-15)
    assert set(sim.profile) == {"begin", "integrate", "end", "check"} and sim.profile["integrate"] > 0


def test_tracers_with_rk45():
    omega = 1.5
    tracers = ia.Tracers([[1.0, 0.0]], lambda p, t: omega * np.stack([-p[:, 1], p[:, 0]], 1))
    period = 2 * np.pi / omega
    ia.Simulation(tracers, integrator="rk45", dt=period / 8, rtol=1e-10, atol=1e-12).run(period)
    np.testing.assert_allclose(tracers.x[0], [1.0, 0.0], atol=1e-8)


@pytest.mark.parametrize("name", ia.integrators.available())
def test_restore_into_a_fresh_simulation_continues_bit_for_bit(name):
    """A checkpoint restored into a newly built system and simulation (as `--resume` does) continues
    exactly: integrator history (implicit Euler's CG guess included) is not reset by the first step."""
    ps = cloth()
    sim = ia.Simulation(ps, integrator=name, dt=2e-3)
    sim.run(0.1)
    saved = sim.save_state()
    sim.run(0.1)
    fresh = cloth()
    sim2 = ia.Simulation(fresh, integrator=name, dt=2e-3)
    sim2.restore_state(saved)
    sim2.run(0.1)
    np.testing.assert_array_equal(fresh.state, ps.state)


# --- the divergence check folded into the fused kernels (issue 8) ------------------------------

def _rain(n=200, colliders=False, seed=1):
    rng = np.random.default_rng(seed)
    ps = ia.ParticleSystem(rng.uniform([-1, -1, 0], [1, 1, 1], (n, 3)), rng.normal(0, 1, (n, 3)))
    ps.add_force(ia.forces.Gravity())
    ps.add_force(ia.forces.Drag(0.01))
    if colliders:
        ps.add_collider(ia.colliders.Plane(), restitution=0.5, friction=0.2)
        ps.add_collider(ia.colliders.Sphere(center=(0, 0, -0.3), radius=0.5), restitution=0.3)
    return ps


def _fountain():
    ps = ia.ParticleSystem.pool(300)
    ps.add_force(ia.forces.Gravity())
    ps.add_force(ia.forces.Drag(0.01))
    ps.add_emitter(ia.Emitter(rate=3000.0, position=ia.SphereSource((0, 0, 0), 0.2),
                              velocity=ia.Cone((0, 0, 1), 3.0, spread=0.5), lifetime=(0.2, 0.5), seed=3))
    ps.add_collider(ia.colliders.Plane(point=(0, 0, -0.1)), restitution=0.5)
    return ps


@pytest.mark.parametrize("make, integrator, separate_checks", [
    (_rain, "semi_implicit_euler", 0), (_rain, "rk4", 0),
    (lambda: _rain(colliders=True), "semi_implicit_euler", 0), (lambda: _rain(colliders=True), "rk4", 0),
    (lambda: _fountain(), "rk4", 0),  # spawned values are finite: the witness carries over
    # no fused kernel: the state is read again after the step
    (_rain, "velocity_verlet", 20), (lambda: cloth(4), "rk4", 20)])
def test_fused_steps_check_the_state_in_their_own_pass(monkeypatch, make, integrator, separate_checks):
    import inertia.simulation as simulation
    calls = []
    check = simulation.all_finite
    monkeypatch.setattr(simulation, "all_finite", lambda y: calls.append(1) or check(y))
    sim = ia.Simulation(make(), integrator=integrator, dt=1e-3)
    for _ in range(20):
        sim.step()
    assert len(calls) == separate_checks


@pytest.mark.parametrize("integrator", ["semi_implicit_euler", "rk4"])
@pytest.mark.parametrize("colliders", [False, True])
def test_fused_divergence_is_reported_at_the_step_it_happens(integrator, colliders):
    # linear drag k / m = 1500 1/s at dt = 0.01: |1 - h k / m| = 14 (semi-implicit Euler) and
    # |R(-15)| ~ 1000 (rk4) per step; the velocities overflow within a few hundred steps
    def make():
        ps = _rain(50, colliders)
        ps.add_force(ia.forces.Drag(1500.0))
        return ps

    reference = ia.Simulation(make(), integrator=integrator, dt=0.01, check_finite=False)
    first_bad = None
    for step in range(2000):
        reference.step()
        bad = np.flatnonzero(~np.all(np.isfinite(reference.system.x) & np.isfinite(reference.system.v), axis=1))
        if bad.size:
            first_bad = step
            break
    assert first_bad is not None
    sim = ia.Simulation(make(), integrator=integrator, dt=0.01)
    with pytest.raises(ia.SimulationDiverged) as info:
        sim.run(30.0)
    err = info.value
    assert err.step == first_bad and err.time == pytest.approx(first_bad * 0.01)
    np.testing.assert_array_equal(err.indices, bad)
    assert f"step {first_bad}" in str(err) and "particles [" in str(err) and integrator in str(err)


def test_a_state_made_non_finite_between_steps_is_caught_by_the_fused_step():
    ps = _rain(colliders=True)
    sim = ia.Simulation(ps, integrator="rk4", dt=1e-3)
    sim.run(0.01)
    ps.v[7, 1] = np.inf  # pinned-or-not, anything in the state counts
    with pytest.raises(ia.SimulationDiverged) as info:
        sim.step()
    assert 7 in info.value.indices.tolist()
