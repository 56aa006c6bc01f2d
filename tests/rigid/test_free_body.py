"""Tests for inertia.rigid.free_body: torque-free conservation, the Dzhanibekov flip period against Landau
and Lifshitz's elliptic-function solution, stability about the extreme axes, orders of accuracy of every
first-order integrator against an independent solution of Euler's equations, and exact ballistic flight."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import ellipk

from inertia import math as im
from inertia.rigid.free_body import FreeBodies
from inertia.simulation import Simulation

DT = 1e-3
DURATION = 60.0
# bodies of the shared 60 s run (one system, one Python loop of 60 000 rk4 steps)
INTERMEDIATE, MIN_AXIS, MAX_AXIS, TUMBLING, BALLISTIC = range(5)
TOP = np.array([1.0, 2.0, 3.0])  # principal moments of the asymmetric top, kg m^2
EPS = 2e-3


def landau_period(inertia, omega):
    """Period of the body-frame angular velocity of a torque-free asymmetric top (Landau and Lifshitz,
    Mechanics, section 37): with I1 < I2 < I3, M^2 = |L|^2, 2E = omega . I omega, and M^2 > 2 E I2,
    T = 4 K(k) sqrt(I1 I2 I3 / ((I3 - I2)(M^2 - 2 E I1))), k^2 = (I2 - I1)(2 E I3 - M^2) / ((I3 - I2)(M^2 - 2 E I1));
    for M^2 < 2 E I2 exchange the indices 1 and 3."""
    i1, i2, i3 = inertia
    m2 = np.sum((inertia * omega) ** 2)
    e2 = np.sum(inertia * omega * omega)
    if m2 < e2 * i2:
        i1, i3 = i3, i1
    k2 = (i2 - i1) * (e2 * i3 - m2) / ((i3 - i2) * (m2 - e2 * i1))
    return 4.0 * ellipk(k2) * np.sqrt(i1 * i2 * i3 / ((i3 - i2) * (m2 - e2 * i1)))


@pytest.fixture(scope="module")
def long_run():
    inertia = np.array([TOP, TOP, TOP, [0.5, 1.3, 1.6], [1.0, 1.0, 1.0]])
    q_tumble = im.quat_from_axis_angle(np.array([0.3, -1.0, 0.4]), 1.1)
    orient = np.tile([1.0, 0, 0, 0], (5, 1))
    orient[TUMBLING] = q_tumble
    omega = np.array([[EPS, 2.0, EPS], [2.0, EPS, EPS], [EPS, EPS, 2.0], [1.0, -2.0, 0.7], [0.0, 0.0, 0.0]])
    # world angular velocity of the tumbling body from its body-frame value
    omega[TUMBLING] = im.quat_rotate(q_tumble, omega[TUMBLING])
    bodies = FreeBodies([1.0, 1.0, 1.0, 2.0, 3.0], inertia, orientations=orient, angular_velocities=omega,
                        positions=np.zeros((5, 3)), velocities=[[0, 0, 0]] * 4 + [[1.0, 2.0, 8.0]])
    bodies.body_force[BALLISTIC] = 3.0 * np.array([0.0, 0.0, -9.81])
    sim = Simulation(bodies, "rk4", dt=DT)
    steps = int(round(DURATION / DT))
    poses = np.empty((steps + 1, 5, 7))
    momenta = np.empty((steps + 1, 5, 6))
    poses[0], momenta[0] = bodies.body_pose, bodies.body_momentum
    energy0 = bodies.kinetic_energy()
    for n in range(1, steps + 1):
        sim.step()
        poses[n] = bodies.body_pose
        momenta[n] = bodies.body_momentum
    return dict(bodies=bodies, poses=poses, momenta=momenta, energy0=energy0, omega0=omega, steps=steps)


def body_frame_momentum(poses, momenta, b):
    """R^T L for body b at every recorded step."""
    out = np.empty((poses.shape[0], 3))
    for n in range(poses.shape[0]):
        out[n] = im.quat_rotate_inv(poses[n, b, 3:], momenta[n, b, :3])
    return out


def test_torque_free_energy_and_momentum_conserved(long_run):
    bodies = long_run["bodies"]
    # kinetic energy 1/2 L . omega depends on the integrated orientation: conserved to 1e-6 over 60 s
    drift = np.abs(bodies.kinetic_energy()[:4] / long_run["energy0"][:4] - 1.0)
    assert drift.max() < 1e-6, drift
    # dL/dt = 0 with no torque: the world angular momentum is constant bit for bit (Witkin-Baraff state)
    np.testing.assert_array_equal(long_run["momenta"][-1, :4, :3], long_run["momenta"][0, :4, :3])
    # and |L| seen from the body (R^T L) stays |L| (the orientation stays a rotation)
    lb = body_frame_momentum(long_run["poses"], long_run["momenta"], TUMBLING)
    norms = np.linalg.norm(lb, axis=1)
    assert np.abs(norms / norms[0] - 1).max() < 1e-12
    # and the body-frame momentum stays on the energy ellipsoid sum L_i^2 / I_i = 2E (both integrals at once)
    e2 = np.sum(lb ** 2 / np.array([0.5, 1.3, 1.6]), axis=1)
    assert np.abs(e2 / e2[0] - 1).max() < 1e-6


def test_dzhanibekov_flip_period_matches_elliptic_solution(long_run):
    lb = body_frame_momentum(long_run["poses"], long_run["momenta"], INTERMEDIATE)
    l2 = lb[:, 1]
    # the intermediate component flips sign twice per period; zero crossings by linear interpolation
    idx = np.flatnonzero(np.sign(l2[1:]) != np.sign(l2[:-1]))
    crossings = (idx + l2[idx] / (l2[idx] - l2[idx + 1])) * DT
    assert len(crossings) >= 3
    measured = crossings[2] - crossings[0]
    expected = landau_period(TOP, long_run["omega0"][INTERMEDIATE])
    assert expected == pytest.approx(27.5308405533, rel=1e-9)  # K(k) for omega0 = (2e-3, 2, 2e-3)
    assert measured == pytest.approx(expected, rel=1e-2)  # the brief's tolerance; measured: ~3e-11
    assert measured == pytest.approx(expected, rel=1e-6)  # rk4 at dt = 1e-3 does far better
    # it really flips: the intermediate component reaches -|L| (a full turn over)
    assert l2.min() < -0.99 * np.abs(l2).max()


def test_rotation_about_min_and_max_axes_is_stable(long_run):
    for body, axis in ((MIN_AXIS, 0), (MAX_AXIS, 2)):
        lb = body_frame_momentum(long_run["poses"], long_run["momenta"], body)
        tilt = np.linalg.norm(np.delete(lb, axis, axis=1), axis=1) / np.linalg.norm(lb, axis=1)
        # the initial tilt ~ EPS / 2 * I_other / I_axis stays bounded (linear stability: an ellipse in the
        # body frame); the intermediate axis under the same perturbation tips over completely
        assert tilt.max() < 5 * tilt[0], (body, tilt[0], tilt.max())
    lb = body_frame_momentum(long_run["poses"], long_run["momenta"], INTERMEDIATE)
    tilt = np.linalg.norm(lb[:, [0, 2]], axis=1) / np.linalg.norm(lb, axis=1)
    assert tilt.max() > 0.99


def test_ballistic_body_follows_the_parabola(long_run):
    # x(t) = x0 + v0 t + g t^2 / 2: rk4 integrates a quadratic exactly (up to rounding over 60 000 steps)
    t = np.arange(long_run["steps"] + 1) * DT
    v0, g = np.array([1.0, 2.0, 8.0]), np.array([0.0, 0.0, -9.81])
    expected = v0[None, :] * t[:, None] + 0.5 * g[None, :] * t[:, None] ** 2
    err = np.abs(long_run["poses"][:, BALLISTIC, :3] - expected).max()
    assert err < 1e-9 * np.abs(expected).max()
    np.testing.assert_array_equal(long_run["poses"][:, BALLISTIC, 3:], [[1.0, 0, 0, 0]] * len(t))


@pytest.mark.parametrize("integrator", ["euler", "midpoint", "rk4", "rk45"])
def test_gravity_parabola_for_each_integrator(integrator):
    # midpoint, rk4 and rk45 are exact for quadratic motion; explicit Euler lags by its own closed form:
    # x_n = x0 + v0 t_n + g t_n (t_n - dt) / 2
    g = np.array([0.5, -9.81, 0.0])
    bodies = FreeBodies([2.0], [1.0, 1.0, 1.0], velocities=[[3.0, 4.0, -1.0]], gravity=g)
    dt, steps = 0.01, 200
    sim = Simulation(bodies, integrator, dt=dt)
    sim.run(steps * dt)
    t = steps * dt
    lag = dt if integrator == "euler" else 0.0
    expected = np.array([3.0, 4.0, -1.0]) * t + 0.5 * g * t * (t - lag)
    np.testing.assert_allclose(bodies.body_position[0], expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(bodies.body_velocity[0], np.array([3.0, 4.0, -1.0]) + g * t, atol=1e-12)


def euler_equations_reference(inertia, q0, omega_body0, torque_world, t_end):
    """Independent reference: Euler's equations I dw/dt = R^T tau - w x I w with the gyroscopic term
    explicit, and dq/dt = 1/2 q (0, w_body), by DOP853 at rtol 1e-13."""
    def rhs(_, y):
        q, w = y[:4], y[4:]
        tau = im.quat_rotate_inv(q / np.linalg.norm(q), torque_world)
        dw = (tau - np.cross(w, inertia * w)) / inertia
        dq = 0.5 * im.quat_mul(q, np.array([0.0, *w]))
        return np.concatenate([dq, dw])
    sol = solve_ivp(rhs, (0, t_end), np.concatenate([q0, omega_body0]), method="DOP853", rtol=1e-13,
                    atol=1e-14)
    q = sol.y[:4, -1]
    return q / np.linalg.norm(q), sol.y[4:, -1]


@pytest.mark.parametrize("integrator,order,dts", [("euler", 1, (4e-3, 2e-3)), ("midpoint", 2, (2e-2, 1e-2)),
                                                  ("rk4", 4, (5e-2, 2.5e-2))])
def test_order_of_accuracy_against_euler_equations(integrator, order, dts):
    inertia = np.array([0.6, 1.1, 1.4])
    q0 = im.quat_from_axis_angle(np.array([1.0, 2.0, 3.0]), 0.4)
    w_body0 = np.array([1.5, -1.0, 2.0])
    torque = np.array([0.2, -0.1, 0.3])
    t_end = 1.0
    q_ref, w_ref = euler_equations_reference(inertia, q0, w_body0, torque, t_end)
    errors = []
    for dt in dts:
        bodies = FreeBodies([1.0], inertia, orientations=[q0], angular_velocities=[im.quat_rotate(q0, w_body0)])
        bodies.body_torque[0] = torque
        Simulation(bodies, integrator, dt=dt).run(t_end)
        q = bodies.body_orientation[0]
        w_body = im.quat_rotate_inv(q, bodies.body_angular_velocity[0])
        errors.append(max(np.abs(w_body - w_ref).max(), 1 - abs(q @ q_ref)))
    ratio = errors[0] / errors[1]
    assert 2 ** order * 0.8 < ratio < 2 ** order * 1.25, (errors, ratio)


def test_rk45_matches_euler_equations():
    inertia = np.array([0.6, 1.1, 1.4])
    q0 = im.quat_from_axis_angle(np.array([1.0, -2.0, 0.5]), 1.3)
    w_body0 = np.array([-0.5, 2.0, 1.0])
    q_ref, w_ref = euler_equations_reference(inertia, q0, w_body0, np.zeros(3), 2.0)
    bodies = FreeBodies([1.0], inertia, orientations=[q0], angular_velocities=[im.quat_rotate(q0, w_body0)])
    Simulation(bodies, "rk45", dt=0.1, rtol=1e-10, atol=1e-12).run(2.0)
    q = bodies.body_orientation[0]
    np.testing.assert_allclose(im.quat_rotate_inv(q, bodies.body_angular_velocity[0]), w_ref, atol=1e-8)
    assert 1 - abs(q @ q_ref) < 1e-12


def test_checkpoint_restores_bit_identically():
    bodies = FreeBodies([1.0, 2.0], [[1.0, 2.0, 3.0], [2.0, 2.0, 3.0]],
                        angular_velocities=[[0.1, 2.0, 0.3], [1.0, 0.0, 0.5]], gravity=(0, 0, -9.81))
    sim = Simulation(bodies, "rk45", dt=0.05)
    sim.run(0.5)
    saved = sim.save_state()
    sim.run(0.5)
    first = bodies.state.copy()
    sim.restore_state(saved)
    sim.run(0.5)
    np.testing.assert_array_equal(bodies.state, first)


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="masses"):
        FreeBodies([0.0], [1, 1, 1])
    with pytest.raises(ValueError, match="inertia_diag"):
        FreeBodies([1.0], [1, -1, 1])
    with pytest.raises(ValueError, match="triangle inequality"):
        FreeBodies([1.0], [1, 1, 3])
    with pytest.raises(ValueError, match="orientations"):
        FreeBodies([1.0], [1, 1, 1], orientations=[[0, 0, 0, 0]])
    with pytest.raises(ValueError, match="gravity"):
        FreeBodies([1.0], [1, 1, 1], gravity=(0, 1))
    with pytest.raises(ValueError, match="second-order"):
        Simulation(FreeBodies([1.0], [1, 1, 1]), "velocity_verlet", dt=0.01)


DETERMINISM_SCRIPT = """
import hashlib
import numpy as np
from inertia.rigid.free_body import FreeBodies
from inertia.simulation import Simulation
rng = np.random.default_rng(5)
n = 400  # 5200 state entries: above the serial-twin threshold, so the parallel kernels run
inertia = np.sort(rng.uniform(0.5, 1.0, size=(n, 3)), axis=1)
q = rng.normal(size=(n, 4))
bodies = FreeBodies(rng.uniform(1, 2, n), inertia, positions=rng.normal(size=(n, 3)), orientations=q,
                    velocities=rng.normal(size=(n, 3)), angular_velocities=rng.normal(size=(n, 3)) * 3,
                    gravity=(0, 0, -9.81))
bodies.body_torque[:] = rng.normal(size=(n, 3)) * 0.1
Simulation(bodies, "rk4", dt=1e-3).run(0.1)
print(hashlib.sha256(bodies.state.tobytes()).hexdigest())
"""
# No BLAS on the hashed path (the momentum set-up rotates by quaternions in plain arithmetic): the
# hash is the same under every OpenBLAS kernel (checked with OPENBLAS_CORETYPE Haswell, SkylakeX, Prescott).
GOLDEN_HASH = "64013ea3997f0f6ebd2f6ded2c00657be09b09a3e05e185356430271f210b0b7"


def run_with_threads(threads):
    import os
    import subprocess
    import sys
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    out = subprocess.run([sys.executable, "-c", DETERMINISM_SCRIPT], env=env, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip().splitlines()[-1]


def test_bit_identical_at_one_and_two_threads_against_golden_hash():
    one, two = run_with_threads(1), run_with_threads(2)
    assert one == two
    assert one == GOLDEN_HASH
