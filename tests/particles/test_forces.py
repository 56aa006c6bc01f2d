"""Force objects: conservation laws, Jacobians against finite differences, energies, bad input."""

import numpy as np
import pytest

import inertia as ia


def spring_network(n=60, seed=3, dim=3):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, dim))
    v = rng.normal(0, 1, (n, dim))
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)
                      if np.linalg.norm(x[i] - x[j]) < 0.6], dtype=np.int64)
    ps = ia.ParticleSystem(x, v, masses=rng.uniform(0.5, 2.0, n))
    rest = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) * rng.uniform(0.7, 1.3, len(pairs))
    springs = ps.add_force(ia.forces.Springs(pairs, stiffness=rng.uniform(50, 150, len(pairs)),
                                             damping=0.5, rest_lengths=rest))
    return ps, springs


def test_spring_forces_sum_to_zero_and_match_pairwise_formula():
    """f_i = -[k (l - L) + c (v_i - v_j).n] n with f_j = -f_i: the total internal force vanishes."""
    ps, springs = spring_network()
    f = np.zeros_like(ps.x)
    springs.accumulate(ps.x, ps.v, 0.0, f)
    assert np.abs(f.sum(axis=0)).max() < 1e-12 * np.abs(f).sum()
    # reference: direct loop over springs
    ref = np.zeros_like(f)
    for s, (i, j) in enumerate(springs.pairs):
        d = ps.x[i] - ps.x[j]
        length = np.linalg.norm(d)
        n = d / length
        mag = springs.stiffness[s] * (length - springs.rest_lengths[s]) + springs.damping[s] * (ps.v[i] - ps.v[j]) @ n
        ref[i] -= mag * n
        ref[j] += mag * n
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", ["rk4", "semi_implicit_euler", "velocity_verlet", "implicit_euler"])
def test_springs_conserve_linear_momentum(name):
    """Internal forces only: d/dt sum m v = 0, so momentum is constant to rounding for 1000 steps."""
    ps, _ = spring_network()
    p0 = ps.momentum()
    sim = ia.Simulation(ps, integrator=name, dt=1e-3)
    sim.run(1.0)
    scale = np.sum(ps.mass[:, None] * np.abs(ps.v))
    assert np.abs(ps.momentum() - p0).max() < 1e-12 * scale * 1000 ** 0.5


def test_spring_energy_conserved_without_damping():
    """Undamped springs are conservative: RK4 at small dt keeps T + U to O(dt^4)."""
    rng = np.random.default_rng(1)
    ps, springs = spring_network()
    springs.damping[:] = 0.0
    e0 = ps.total_energy()
    ia.Simulation(ps, integrator="rk4", dt=1e-3).run(0.5)
    assert abs(ps.total_energy() - e0) < 1e-8 * abs(e0) + 1e-9


def finite_difference_jacobians(ps, h=1e-6):
    n = ps.position_size
    f0 = np.zeros(n)
    x, v = ps.x.reshape(-1).copy(), ps.v.reshape(-1).copy()

    def force(xf, vf):
        out = np.zeros((ps.particle_count, ps.dim))
        ps.accumulate_forces(xf.reshape(-1, ps.dim), vf.reshape(-1, ps.dim), 0.0, out)
        return out.reshape(-1)

    Jx, Jv = np.zeros((n, n)), np.zeros((n, n))
    for k in range(n):
        e = np.zeros(n)
        e[k] = h
        Jx[:, k] = (force(x + e, v) - force(x - e, v)) / (2 * h)
        Jv[:, k] = (force(x, v + e) - force(x, v - e)) / (2 * h)
    return Jx, Jv


def dense(pattern, blocks, n, d):
    out = np.zeros((n * d, n * d))
    for i in range(n):
        for s in range(pattern.row_start[i], pattern.row_start[i + 1]):
            j = pattern.columns[s]
            out[i * d:(i + 1) * d, j * d:(j + 1) * d] = blocks[s]
    return out


def test_jacobians_match_finite_differences():
    """df/dx and df/dv assembled from Springs (stretched, undamped position part), AnchorSprings, Drag and
    QuadraticDrag equal central differences of the force (O(h^2) accurate)."""
    rng = np.random.default_rng(0)
    n, d = 6, 3
    x = rng.uniform(-1, 1, (n, d))
    ps = ia.ParticleSystem(x, rng.normal(0, 1, (n, d)))
    pairs = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [0, 5], [1, 4]])
    rest = 0.5 * np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)   # all stretched
    ps.add_force(ia.forces.Springs(pairs, stiffness=30.0, damping=0.0, rest_lengths=rest))
    ps.add_force(ia.forces.AnchorSprings([0, 3], [[0, 0, 2.0], [1.0, 1.0, 1.0]], stiffness=20.0, rest_length=0.1))
    ps.add_force(ia.forces.Drag(0.7))
    ps.add_force(ia.forces.QuadraticDrag(0.3))
    ps.add_force(ia.forces.Gravity())
    p = ps.jacobian_pattern
    f = np.zeros(n * d)
    dfdx, dfdv = np.zeros((p.nnz, d, d)), np.zeros((p.nnz, d, d))
    ps.evaluate_with_jacobians(ps.x.reshape(-1), ps.v.reshape(-1), 0.0, f, dfdx, dfdv)
    Jx, Jv = finite_difference_jacobians(ps)
    np.testing.assert_allclose(dense(p, dfdx, n, d), Jx, atol=1e-6)
    np.testing.assert_allclose(dense(p, dfdv, n, d), Jv, atol=1e-6)


def test_damping_jacobian_along_spring():
    """d f_i / d v_i = -c n n^T for a damped spring."""
    ps = ia.ParticleSystem([[0, 0, 0], [1.0, 2.0, 2.0]], [[0, 0, 0], [0.3, -0.2, 0.1]])
    ps.add_force(ia.forces.Springs([[0, 1]], stiffness=0.0, damping=4.0))
    p = ps.jacobian_pattern
    f = np.zeros(6)
    dfdx, dfdv = np.zeros((p.nnz, 3, 3)), np.zeros((p.nnz, 3, 3))
    ps.evaluate_with_jacobians(ps.x.reshape(-1), ps.v.reshape(-1), 0.0, f, dfdx, dfdv)
    n = np.array([1.0, 2.0, 2.0]) / 3.0
    np.testing.assert_allclose(dfdv[p.diag_slot[0]], -4.0 * np.outer(n, n), atol=1e-14)


def test_gravity_and_potential():
    """U = -sum m g.x; pinned particles feel no gravity and carry no energy."""
    ps = ia.ParticleSystem([[0, 0, 1.0], [0, 0, 2.0]], masses=[2.0, np.inf])
    ps.add_force(ia.forces.Gravity((0, 0, -10.0)))
    assert ps.potential_energy() == pytest.approx(2.0 * 10.0 * 1.0)
    ia.Simulation(ps, integrator="rk4", dt=0.01).run(1.0)
    # z(t) = 1 - g t^2 / 2, exact for RK4 (polynomial of degree 2)
    assert ps.x[0, 2] == pytest.approx(1.0 - 5.0, abs=1e-12)
    assert ps.x[1, 2] == 2.0 and ps.v[1, 2] == 0.0


def test_attractor_orbit_energy_and_angular_momentum():
    """A circular orbit in the softened potential: v^2 = s r^2 / (r^2 + eps^2)^(3/2); radius and
    energy are kept by RK4 at dt = T/1000 to 1e-8."""
    s, eps, r = 2.0, 0.1, 1.0
    speed = np.sqrt(s * r * r / (r * r + eps * eps) ** 1.5)
    ps = ia.ParticleSystem([[r, 0.0]], [[0.0, speed]])
    ps.add_force(ia.forces.Attractor((0.0, 0.0), strength=s, softening=eps))
    e0 = ps.total_energy()
    period = 2 * np.pi * r / speed
    ia.Simulation(ps, integrator="rk4", dt=period / 1000).run(period)
    assert np.linalg.norm(ps.x[0]) == pytest.approx(r, rel=1e-8)
    assert ps.total_energy() == pytest.approx(e0, rel=1e-8)
    np.testing.assert_allclose(ps.x[0], [r, 0.0], atol=1e-6)


def test_repeller_pushes_away():
    ps = ia.ParticleSystem([[1.0, 0.0]])
    ps.add_force(ia.forces.Attractor((0.0, 0.0), strength=-1.0))
    ia.Simulation(ps, dt=0.01).run(0.1)
    assert ps.x[0, 0] > 1.0 and ps.v[0, 0] > 0


def test_wind_terminal_velocity_and_gusts():
    """m dv/dt = k (w - v): v(t) = w + (v0 - w) e^{-kt/m}. Gusts are deterministic per seed."""
    ps = ia.ParticleSystem([[0.0, 0.0, 0.0]], masses=2.0)
    ps.add_force(ia.forces.Wind((3.0, 0.0, 0.0), coefficient=0.5))
    ia.Simulation(ps, integrator="rk4", dt=0.01).run(2.0)
    assert ps.v[0, 0] == pytest.approx(3.0 * (1 - np.exp(-0.5 * 2.0 / 2.0)), rel=1e-9)
    a = ia.forces.Wind((3.0, 0, 0), gust_amplitude=1.0, seed=4)
    b = ia.forces.Wind((3.0, 0, 0), gust_amplitude=1.0, seed=4)
    c = ia.forces.Wind((3.0, 0, 0), gust_amplitude=1.0, seed=5)
    times = np.linspace(0, 10, 50)
    wa = [a.wind_at(t)[0] for t in times]
    assert wa == [b.wind_at(t)[0] for t in times]
    assert wa != [c.wind_at(t)[0] for t in times]
    assert 2.0 - 1e-12 <= min(wa) and max(wa) <= 4.0 + 1e-12


def test_wind_from_field_callable():
    field = lambda p, t: np.tile([0.0, 2.0], (len(p), 1))
    ps = ia.ParticleSystem(np.zeros((3, 2)))
    ps.add_force(ia.forces.Wind(field, coefficient=1.0))
    ia.Simulation(ps, dt=0.01).run(5.0)
    np.testing.assert_allclose(ps.v[:, 1], 2.0 * (1 - np.exp(-5.0)), rtol=1e-8)


def test_grid_force_field_is_trilinear():
    """A grid sampled from a linear field f = A x + b reproduces it exactly (trilinear is exact on linear)."""
    A = np.array([[0.1, 0.2, -0.3], [0.0, 0.5, 0.1], [-0.2, 0.0, 0.3]])
    b = np.array([1.0, -2.0, 0.5])
    axes = [np.linspace(-1, 1, 5), np.linspace(-1, 1, 7), np.linspace(-1, 1, 4)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    values = X @ A.T + b
    ps = ia.ParticleSystem(np.random.default_rng(0).uniform(-0.99, 0.99, (50, 3)))
    field = ps.add_force(ia.forces.GridForceField(values, origin=(-1, -1, -1), spacing=(0.5, 1 / 3, 2 / 3)))
    f = np.zeros_like(ps.x)
    field.accumulate(ps.x, ps.v, 0.0, f)
    np.testing.assert_allclose(f, ps.x @ A.T + b, atol=1e-12)
    # 2D version
    g = np.stack(np.meshgrid(np.linspace(0, 1, 3), np.linspace(0, 2, 5), indexing="ij"), axis=-1)
    ps2 = ia.ParticleSystem([[0.3, 1.1], [5.0, -1.0]])
    field2 = ps2.add_force(ia.forces.GridForceField(g, origin=(0, 0), spacing=(0.5, 0.5)))
    f2 = np.zeros_like(ps2.x)
    field2.accumulate(ps2.x, ps2.v, 0.0, f2)
    np.testing.assert_allclose(f2, [[0.3, 1.1], [1.0, 0.0]], atol=1e-12)  # second one clamped to the border


def test_user_force_in_numpy_and_numba():
    """The two ways the docs show to write a force give the same motion."""
    from numba import njit

    class NumpyBuoyancy(ia.forces.Force):
        def accumulate(self, x, v, t, f):
            f[:, 2] += 5.0 * np.clip(-x[:, 2], 0.0, None)

    @njit(cache=True)
    def _buoyancy(x, f):
        for i in range(x.shape[0]):
            if x[i, 2] < 0.0:
                f[i, 2] += 5.0 * -x[i, 2]

    class NumbaBuoyancy(ia.forces.Force):
        def accumulate(self, x, v, t, f):
            _buoyancy(x, f)

    results = []
    for force in (NumpyBuoyancy(), NumbaBuoyancy()):
        ps = ia.ParticleSystem([[0.0, 0.0, 1.0]])
        ps.add_force(ia.forces.Gravity())
        ps.add_force(force)
        ps.add_force(ia.forces.Drag(2.0))
        ia.Simulation(ps, dt=0.01).run(20.0)
        results.append(ps.x.copy())
    np.testing.assert_array_equal(results[0], results[1])
    # settles where buoyancy balances weight: 5 (-z) = m g  =>  z = -9.81 / 5
    assert results[0][0, 2] == pytest.approx(-9.81 / 5, abs=1e-4)


@pytest.mark.parametrize("make,match", [
    (lambda: ia.forces.Springs([[0, 7]]), r"Springs pairs indices must lie in \[0, 2\]"),
    (lambda: ia.forces.Springs([[0, 0]]), "join a particle to itself"),
    (lambda: ia.forces.Springs([[0, 1]], stiffness=-1.0), "Springs stiffness must be >= 0"),
    (lambda: ia.forces.Springs([[0.5, 1]]), "integer particle indices"),
    (lambda: ia.forces.Springs([0, 1, 2]), r"shape \(M, 2\)"),
    (lambda: ia.forces.Gravity((0, -9.81)), "system is 3-D"),
    (lambda: ia.forces.AnchorSprings([5], [[0, 0, 0]]), "AnchorSprings indices"),
    (lambda: ia.forces.Drag(-0.1), "Drag coefficient must be a finite number >= 0"),
    (lambda: ia.forces.Attractor((0, 0, 0), softening=0.0), "Attractor softening must be a finite number > 0"),
])
def test_bad_force_input_names_the_argument(make, match):
    ps = ia.ParticleSystem(np.zeros((3, 3)))
    with pytest.raises(ValueError, match=match):
        ps.add_force(make())


def test_force_cannot_join_two_systems():
    g = ia.forces.Gravity()
    ia.ParticleSystem(np.zeros((1, 3))).add_force(g)
    with pytest.raises(ValueError, match="already added to another system"):
        ia.ParticleSystem(np.zeros((1, 3))).add_force(g)
