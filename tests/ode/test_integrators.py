"""Verification of every integrator against closed forms (order of accuracy, energy, stability)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import inertia as ia

ALL = ia.integrators.available()
SECOND_ORDER_ONLY = ["semi_implicit_euler", "verlet", "velocity_verlet", "leapfrog", "implicit_euler"]
ORDER = {"euler": 1, "midpoint": 2, "rk4": 4, "rk45": 5, "semi_implicit_euler": 1, "verlet": 2,
         "velocity_verlet": 2, "leapfrog": 2, "implicit_euler": 1}
# Time steps per order: large enough to stay well above rounding, small enough for the asymptotic regime.
DTS = {1: [0.01, 0.005, 0.0025, 0.00125], 2: [0.04, 0.02, 0.01, 0.005],
       4: [0.2, 0.1, 0.05, 0.025], 5: [0.4, 0.2, 0.1, 0.05]}
# rk45 with a huge tolerance accepts every step, so its internal step is exactly dt: that measures
# the order of the 5th-order Dormand-Prince formula itself.
OPTIONS = {"rk45": {"rtol": 1e6, "atol": 1e6}}


def measured_order(errors, dts):
    slope, _ = np.polyfit(np.log(dts), np.log(errors), 1)
    return slope


def oscillator(k=4.0, m=1.0, x0=(1.0, 0.0), v0=(0.0, 0.5)):
    ps = ia.ParticleSystem(np.array([x0]), np.array([v0]), masses=m)
    ps.add_force(ia.forces.AnchorSprings([0], [[0.0, 0.0]], stiffness=k, damping=0.0, rest_length=0.0))
    return ps


def oscillator_exact(t, k=4.0, m=1.0, x0=(1.0, 0.0), v0=(0.0, 0.5)):
    # x(t) = x0 cos(w t) + v0 / w sin(w t),  w = sqrt(k / m)
    w = np.sqrt(k / m)
    return np.asarray(x0) * np.cos(w * t) + np.asarray(v0) / w * np.sin(w * t)


def run_to(system, name, dt, duration):
    sim = ia.Simulation(system, integrator=name, dt=dt, **OPTIONS.get(name, {}))
    steps = int(round(duration / dt))
    for _ in range(steps):
        sim.step()
    return sim


@pytest.mark.parametrize("name", ALL)
def test_order_harmonic_oscillator(name):
    """Global error at T = 2 s against x(t) = x0 cos wt + v0/w sin wt; slope within 0.2 of the order."""
    p = ORDER[name]
    dts = DTS[p]
    errors = []
    for dt in dts:
        ps = oscillator()
        run_to(ps, name, dt, 2.0)
        errors.append(np.linalg.norm(ps.x[0] - oscillator_exact(2.0)))
    order = measured_order(errors, dts)
    assert abs(order - p) < 0.2, f"{name}: measured order {order:.3f}, expected {p} (errors {errors})"


@pytest.mark.parametrize("name", ALL)
def test_order_projectile_with_linear_drag(name):
    """m dv/dt = m g - k v:  v(t) = v_inf + (v0 - v_inf) e^{-kt/m},  v_inf = m g / k,
    x(t) = x0 + v_inf t + (v0 - v_inf) (m/k) (1 - e^{-kt/m})."""
    m, k = 2.0, 0.8
    g = np.array([0.0, 0.0, -9.81])
    x0, v0 = np.array([0.0, 0.0, 1.0]), np.array([3.0, 1.0, 8.0])
    T = 1.6  # a whole number of steps for every dt in DTS
    v_inf = m * g / k
    decay = np.exp(-k * T / m)
    x_exact = x0 + v_inf * T + (v0 - v_inf) * (m / k) * (1.0 - decay)
    v_exact = v_inf + (v0 - v_inf) * decay
    p = ORDER[name]
    dts = DTS[p]
    errors = []
    for dt in dts:
        ps = ia.ParticleSystem([x0], [v0], masses=m)
        ps.add_force(ia.forces.Gravity(g))
        ps.add_force(ia.forces.Drag(k))
        run_to(ps, name, dt, T)
        errors.append(np.linalg.norm(ps.x[0] - x_exact) + np.linalg.norm(ps.v[0] - v_exact))
    order = measured_order(errors, dts)
    assert abs(order - p) < 0.2, f"{name}: measured order {order:.3f}, expected {p} (errors {errors})"


@pytest.mark.parametrize("name", ["semi_implicit_euler", "verlet", "velocity_verlet", "leapfrog", "rk4"])
def test_order_generic_force_path(name):
    """The same projectile through a ForceField (no fused fast path) has the same order."""
    m, k = 1.0, 0.5
    g = np.array([0.0, -9.81])
    x0, v0 = np.array([0.0, 0.0]), np.array([2.0, 5.0])
    T = 1.0
    v_inf = m * g / k
    x_exact = x0 + v_inf * T + (v0 - v_inf) * (m / k) * (1.0 - np.exp(-k * T / m))
    p = ORDER[name]
    errors = []
    for dt in DTS[p]:
        ps = ia.ParticleSystem([x0], [v0], masses=m)
        ps.add_force(ia.forces.ForceField(lambda x, v, t: m * g - k * v))
        run_to(ps, name, dt, T)
        errors.append(np.linalg.norm(ps.x[0] - x_exact))
    order = measured_order(errors, DTS[p])
    assert abs(order - p) < 0.2, f"{name}: measured order {order:.3f}, expected {p}"


STEPS = 10_000


def energy_history(name, dt, k=4.0, m=1.0):
    ps = oscillator(k, m)
    sim = ia.Simulation(ps, integrator=name, dt=dt)
    energy = np.empty(STEPS + 1)
    energy[0] = ps.total_energy()
    for n in range(STEPS):
        sim.step()
        energy[n + 1] = ps.total_energy()
    return energy


def test_explicit_euler_energy_grows_by_one_plus_w2dt2():
    """Explicit Euler on x'' = -w^2 x: E_{n+1} = (1 + w^2 dt^2) E_n exactly."""
    k, dt = 4.0, 1e-3
    w2 = k
    energy = energy_history("euler", dt, k)
    ratios = energy[1:] / energy[:-1]
    np.testing.assert_allclose(ratios, 1.0 + w2 * dt * dt, rtol=1e-12)
    np.testing.assert_allclose(energy[-1] / energy[0], (1.0 + w2 * dt * dt) ** STEPS, rtol=1e-9)


def test_implicit_euler_energy_decays_by_one_plus_w2dt2():
    """Backward Euler on a linear oscillator: E_{n+1} = E_n / (1 + w^2 dt^2)."""
    k, dt = 4.0, 1e-3
    energy = energy_history("implicit_euler", dt, k)
    np.testing.assert_allclose(energy[1:] / energy[:-1], 1.0 / (1.0 + k * dt * dt), rtol=1e-9)


@pytest.mark.parametrize("name,order", [("semi_implicit_euler", 1), ("verlet", 2),
                                        ("velocity_verlet", 2), ("leapfrog", 2)])
def test_symplectic_energy_bounded(name, order):
    """Symplectic methods conserve a shadow energy: |E - E0| / E0 stays O((w dt)^p) for 10^4 steps
    (about 13 periods), with no secular drift."""
    k, dt = 4.0, 5e-3
    w = np.sqrt(k)
    energy = energy_history(name, dt, k)
    deviation = np.abs(energy - energy[0]) / energy[0]
    assert deviation.max() < 2.0 * (w * dt) ** order, f"{name}: max deviation {deviation.max():.3e}"
    # no drift: the energy averaged over the first and the last period agree far below the oscillation
    period = int(round(2 * np.pi / w / dt))
    drift = abs(energy[:period].mean() - energy[-period:].mean()) / energy[0]
    assert drift < 0.05 * (w * dt) ** order + 1e-12, f"{name}: drift {drift:.3e}"


def rotational_flow(omega):
    return lambda p, t: omega * np.stack([-p[:, 1], p[:, 0]], axis=1)


@pytest.mark.parametrize("name,amplification", [
    # radius gain per step of the linear test equation z' = i w z, with z = w dt:
    ("euler", lambda z: np.sqrt(1 + z**2)),                                    # |1 + iz|
    ("midpoint", lambda z: np.sqrt(1 + z**4 / 4)),                             # |1 + iz - z^2/2|
    ("rk4", lambda z: abs(1 + 1j * z - z**2 / 2 - 1j * z**3 / 6 + z**4 / 24)),  # 4-term Taylor
])
def test_particle_in_rotational_flow(name, amplification):
    """dx/dt = w (-y, x): the exact path is a circle. Euler spirals out by sqrt(1 + w^2 dt^2) per step;
    midpoint and RK4 stay on the circle to their order."""
    omega, dt, steps = 2.0, 0.01, 3142   # ~10 revolutions
    tracers = ia.Tracers(np.array([[1.0, 0.0], [0.0, 2.0]]), rotational_flow(omega))
    run_to(tracers, name, dt, steps * dt)
    radius = np.linalg.norm(tracers.x, axis=1)
    expected = np.array([1.0, 2.0]) * amplification(omega * dt) ** steps
    np.testing.assert_allclose(radius, expected, rtol=1e-10)
    drift = radius[0] - 1.0
    if name == "euler":
        assert drift > 0.8   # spirals far out: (1 + 4e-4)^(3142/2) ~ 1.87
    else:
        assert abs(drift) < 1e-3


def chain(k, m, count=20, spacing=0.1):
    x = np.zeros((count, 3))
    x[:, 2] = -spacing * np.arange(count)
    ps = ia.ParticleSystem(x, masses=m, pinned=[0])
    pairs = np.stack([np.arange(count - 1), np.arange(1, count)], axis=1)
    ps.add_force(ia.forces.Springs(pairs, stiffness=k, damping=0.0))
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
    return ps, pairs


def chain_max_frequency(k, m, count):
    # Longitudinal modes of a chain fixed at the top and free at the bottom: stiffness matrix of the
    # free particles, w_max^2 = largest eigenvalue of K / m.
    n = count - 1
    K = np.zeros((n, n))
    for s in range(count - 1):          # spring s joins s and s+1; particle 0 is pinned
        a, b = s - 1, s
        K[b, b] += k
        if a >= 0:
            K[a, a] += k
            K[a, b] -= k
            K[b, a] -= k
    return np.sqrt(np.linalg.eigvalsh(K / m).max())


def test_stiff_chain_implicit_stable_far_beyond_explicit_limit():
    """Stiff hanging chain: explicit methods are stable only below dt ~ 2.8 / w_max (RK4's limit on the
    imaginary axis, the largest of them); implicit Euler at 100x that stays bounded and settles to the
    static equilibrium (spring s carries the weight below it: stretch = (count - 1 - s) m g / k)."""
    k, m, count = 1e5, 0.01, 20
    w_max = chain_max_frequency(k, m, count)
    explicit_limit = 2.83 / w_max
    dt = 100 * explicit_limit
    for name in ["euler", "midpoint", "rk4", "semi_implicit_euler", "verlet", "velocity_verlet", "leapfrog"]:
        ps, _ = chain(k, m, count)
        ps.v[1:, 2] = 1e-3  # a small disturbance to excite the stiff modes
        sim = ia.Simulation(ps, integrator=name, dt=dt)
        with pytest.raises(ia.SimulationDiverged):
            for _ in range(200):
                sim.step()
                if not np.all(np.abs(ps.x) < 1e6):
                    raise ia.SimulationDiverged("exploded", step=sim.step_count, time=sim.t, indices=[])
    ps, pairs = chain(k, m, count)
    ps.v[1:, 2] = 1e-3
    sim = ia.Simulation(ps, integrator="implicit_euler", dt=dt)
    for _ in range(200):
        sim.step()
    lengths = np.linalg.norm(ps.x[pairs[:, 0]] - ps.x[pairs[:, 1]], axis=1)
    expected = 0.1 + (count - 1 - np.arange(count - 1)) * m * 9.81 / k
    np.testing.assert_allclose(lengths, expected, rtol=1e-6)
    # and below the limit an explicit method is fine, so the limit above is real
    ps, _ = chain(k, m, count)
    sim = ia.Simulation(ps, integrator="rk4", dt=0.5 * explicit_limit)
    sim.run(200 * 0.5 * explicit_limit)
    assert np.all(np.abs(ps.x) < 10)


def test_rk45_meets_tolerance_against_solve_ivp():
    """An eccentric orbit around a softened attractor: rk45 at rtol=1e-8 against solve_ivp (DOP853 at
    1e-13); the global error stays within a small multiple of the tolerance."""
    x0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.1])
    strength, eps = 1.0, 0.05
    ps = ia.ParticleSystem([x0], [v0])
    ps.add_force(ia.forces.Attractor((0.0, 0.0, 0.0), strength=strength, softening=eps))
    rtol, atol = 1e-8, 1e-10
    sim = ia.Simulation(ps, integrator="rk45", dt=0.1, rtol=rtol, atol=atol)
    T = 5.0
    sim.run(T)

    def rhs(t, y):
        r = -y[:3]
        return np.concatenate([y[3:], strength * r / (r @ r + eps * eps) ** 1.5])

    ref = solve_ivp(rhs, (0, T), np.concatenate([x0, v0]), method="DOP853", rtol=1e-13, atol=1e-13)
    error = np.abs(ps.state - ref.y[:, -1])
    scale = atol + rtol * np.abs(ref.y[:, -1])
    assert np.max(error / scale) < 200, f"error / tolerance = {np.max(error / scale):.1f}"
    assert sim.integrator.accepted_steps > 50
    assert sim.integrator.rejected_steps >= 1  # the pericentre pass forces step rejections
    # tighter tolerance gives a smaller error (the controller really controls)
    ps2 = ia.ParticleSystem([x0], [v0])
    ps2.add_force(ia.forces.Attractor((0.0, 0.0, 0.0), strength=strength, softening=eps))
    ia.Simulation(ps2, integrator="rk45", dt=0.1, rtol=1e-11, atol=1e-13).run(T)
    assert np.max(np.abs(ps2.state - ref.y[:, -1])) < np.max(error)


@pytest.mark.parametrize("name", SECOND_ORDER_ONLY)
def test_first_order_system_rejects_second_order_integrators(name):
    tracers = ia.Tracers(np.zeros((2, 2)), rotational_flow(1.0))
    with pytest.raises(ValueError, match="second-order system"):
        ia.Simulation(tracers, integrator=name, dt=0.01)


def test_available_lists_all_nine():
    assert ALL == ["euler", "midpoint", "rk4", "rk45", "semi_implicit_euler", "verlet",
                   "velocity_verlet", "leapfrog", "implicit_euler"]
