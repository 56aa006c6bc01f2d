"""ParticleSystem: construction, views, pinning, bad input, divergence reporting."""

import numpy as np
import pytest

import inertia as ia


def test_state_is_one_array_and_x_v_are_views():
    ps = ia.ParticleSystem(np.ones((4, 3)), np.full((4, 3), 2.0))
    assert ps.state.shape == (24,) and ps.state.dtype == np.float64
    assert np.shares_memory(ps.x, ps.state) and np.shares_memory(ps.v, ps.state)
    ps.state[0] = 7.0
    assert ps.x[0, 0] == 7.0
    np.testing.assert_array_equal(ps.state[12:], 2.0)


def test_derivative_three_phase_matches_fused_path():
    """dy/dt = [v, f/m]: the generic three-phase evaluation and the fused affine kernel agree."""
    rng = np.random.default_rng(0)
    x, v, m = rng.normal(size=(10, 3)), rng.normal(size=(10, 3)), rng.uniform(1, 2, 10)
    fused = ia.ParticleSystem(x, v, masses=m)
    fused.add_force(ia.forces.Gravity())
    fused.add_force(ia.forces.Drag(0.3))
    generic = ia.ParticleSystem(x, v, masses=m)
    generic.add_force(ia.forces.Gravity())
    generic.add_force(ia.forces.Drag(0.3))
    generic.force_filters.append(type("Noop", (), {"apply": lambda self, x, v, t, f: None})())
    a, b = np.zeros(60), np.zeros(60)
    fused.derivative(fused.state, 0.0, a)
    generic.derivative(generic.state, 0.0, b)
    np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(a[:30], v.reshape(-1))
    np.testing.assert_allclose(a[30:].reshape(10, 3), np.array([0, 0, -9.81]) - 0.3 * v / m[:, None])


def test_pinned_particles_do_not_move():
    x = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    ps = ia.ParticleSystem(x, pinned=[0])
    ps.add_force(ia.forces.Gravity((0, -9.81)))
    ps.add_force(ia.forces.Springs([[0, 1], [1, 2]], stiffness=100.0, damping=1.0))
    for name in ia.integrators.available():
        if name == "rk45":
            continue
        p = ia.ParticleSystem(x, pinned=np.array([True, False, False]))
        p.add_force(ia.forces.Gravity((0, -9.81)))
        p.add_force(ia.forces.Springs([[0, 1], [1, 2]], stiffness=100.0, damping=1.0))
        ia.Simulation(p, integrator=name, dt=1e-3).run(0.2)
        np.testing.assert_array_equal(p.x[0], [0.0, 0.0])
        assert p.x[2, 1] < -0.01
    assert np.isinf(ps.mass[0]) and ps.inv_mass[0] == 0.0


@pytest.mark.parametrize("kwargs,match", [
    (dict(positions=np.zeros((3, 4))), "2 or 3 columns"),
    (dict(positions=np.zeros(3)), "2-D array of shape"),
    (dict(positions=[[0, np.nan, 0]]), "positions must be finite"),
    (dict(positions=np.zeros((2, 3)), velocities=np.zeros((3, 3))), "velocities must have 2 rows"),
    (dict(positions=np.zeros((2, 3)), velocities=[[0, 0, np.inf], [0, 0, 0]]), "velocities must be finite"),
    (dict(positions=np.zeros((2, 3)), masses=0.0), "masses must be > 0"),
    (dict(positions=np.zeros((2, 3)), masses=[1.0, -2.0]), "masses must be > 0"),
    (dict(positions=np.zeros((2, 3)), masses=[1.0, 2.0, 3.0]), r"masses must be a scalar or an array of shape \(2,\)"),
    (dict(positions=np.zeros((2, 3)), radius=-0.1), "radius must be >= 0"),
    (dict(positions=np.zeros((2, 3)), pinned=[4]), r"pinned indices must lie in \[0, 1\]"),
])
def test_bad_input_names_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ia.ParticleSystem(**kwargs)


@pytest.mark.parametrize("kwargs,match", [
    (dict(dt=0.0), "dt must be a finite number > 0"),
    (dict(dt=-1e-3), "dt must be a finite number > 0"),
    (dict(dt=float("nan")), "dt must be a finite number > 0"),
    (dict(integrator="rk5"), r"integrator must be one of \['euler', 'midpoint', 'rk4'"),
    (dict(integrator="rk45", rtol=-1.0), "rk45 needs rtol > 0"),
    (dict(integrator="rk4", rtol=1e-3), "takes no options named"),
])
def test_bad_simulation_input(kwargs, match):
    ps = ia.ParticleSystem(np.zeros((1, 3)))
    with pytest.raises(ValueError, match=match):
        ia.Simulation(ps, **kwargs)


def test_divergence_names_step_time_particles_and_cause():
    """Explicit Euler on a stiff spring at dt far beyond 2/w blows up; the error says where and why."""
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    ps = ia.ParticleSystem(x, pinned=[0])
    ps.add_force(ia.forces.Springs([[0, 1], [1, 2]], stiffness=1e6, rest_lengths=0.9))
    sim = ia.Simulation(ps, integrator="euler", dt=0.01)
    with pytest.raises(ia.SimulationDiverged) as info:
        sim.run(10.0)
    err = info.value
    message = str(err)
    assert f"step {err.step}" in message and "t = " in message
    assert err.step > 0 and err.time == pytest.approx(err.step * 0.01)
    assert set(err.indices.tolist()) <= {1, 2} and len(err.indices) > 0
    assert "particles [" in message
    assert "Springs with stiffness 1e+06" in message
    assert "smaller dt" in message and "implicit_euler" in message


def test_energy_and_momentum_observables():
    ps = ia.ParticleSystem([[0, 0, 1.0], [0, 0, 3.0]], [[1.0, 0, 0], [0, 2.0, 0]], masses=[2.0, 3.0])
    ps.add_force(ia.forces.Gravity((0, 0, -10.0)))
    assert ps.kinetic_energy() == pytest.approx(0.5 * 2 * 1 + 0.5 * 3 * 4)
    assert ps.potential_energy() == pytest.approx(2 * 10 * 1 + 3 * 10 * 3)
    np.testing.assert_allclose(ps.momentum(), [2.0, 6.0, 0.0])
