"""Raycast vehicle (inertia.rigid.vehicle) on a heightfield against closed forms."""

import math

import numpy as np
import pytest

from inertia.model import ModelBuilder
from inertia.rigid.vehicle import RaycastVehicle, Wheel
from inertia.rigid.world import RigidWorld

G = 9.81
M = 1000.0
K = 30000.0
HALF_BASE, HALF_TRACK = 1.3, 0.8


def build(mu=0.8, heights=None):
    b = ModelBuilder(gravity=(0, 0, -G))
    h = np.zeros((41, 41)) if heights is None else heights
    b.add_heightfield(h, (1.0, 1.0))
    sag = M * G / (4 * K)
    chassis = b.add_body(position=(0.0, 0.0, 0.2 + 0.65 - sag + 0.01), mass=M,
                         inertia=(M * (1.8 ** 2 + 0.5 ** 2) / 12, M * (4.0 ** 2 + 0.5 ** 2) / 12,
                                  M * (4.0 ** 2 + 1.8 ** 2) / 12))
    b.add_box(chassis, (2.0, 0.9, 0.25))
    world = RigidWorld(b.finalize(), enable_sleep=False)
    wheels = [Wheel((sx * HALF_BASE, sy * HALF_TRACK, -0.2), rest_length=0.3, radius=0.35, stiffness=K,
                    damping=3000.0, friction=mu, steered=sx > 0, driven=sx < 0)
              for sx in (1, -1) for sy in (1, -1)]
    return world, RaycastVehicle(world, chassis, wheels), chassis


def drive(world, car, steps):
    for _ in range(steps):
        car.update()
        world.step()


def test_static_sag_is_mg_over_4k():
    world, car, chassis = build()
    drive(world, car, 240)
    sag = M * G / (4 * K)
    assert car.wheel_in_contact.all()
    np.testing.assert_allclose(car.wheel_compression, sag, rtol=0.02)
    assert np.linalg.norm(world.state.body_qd[chassis]) < 1e-3
    assert car.wheel_suspension_force.sum() == pytest.approx(M * G, rel=1e-3)


def test_braking_distance_is_v0_squared_over_2_mu_g():
    mu, v0 = 0.8, 10.0
    world, car, chassis = build(mu=mu)
    drive(world, car, 180)
    st = world.state
    st.body_qd[chassis, 3:] = (v0, 0.0, 0.0)
    car.wheel_omega[:] = v0 / 0.35
    x0 = st.body_q[chassis, 0]
    car.brake_torque = 1e4
    for _ in range(600):
        drive(world, car, 1)
        if st.body_qd[chassis, 3] < 1e-3:
            break
    dist = st.body_q[chassis, 0] - x0
    assert dist == pytest.approx(v0 ** 2 / (2 * mu * G), rel=0.02)          # brief: 5 %; measured 0.1 %
    assert np.all(car.wheel_omega == 0.0)                             # locked


def test_steady_turn_follows_the_kinematic_bicycle_model():
    # low speed, rigid tyres, Ackermann steering: the rear axle centre turns on R = L / tan(delta)
    # (kinematic bicycle model, Rajamani 2012, 2.2)
    delta, v0 = 0.15, 3.0
    world, car, chassis = build()
    drive(world, car, 180)
    st = world.state
    st.body_qd[chassis, 3:] = (v0, 0.0, 0.0)
    car.wheel_omega[:] = v0 / 0.35
    car.steering = delta
    pts = []
    for _ in range(480):
        drive(world, car, 1)
        q = st.body_q[chassis]
        w, x, y, z = q[3:]
        fwd = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z)])
        pts.append(q[:2] - HALF_BASE * fwd)
    P = np.array(pts[60:])
    # algebraic circle fit: x^2 + y^2 = 2 a x + 2 b y + c
    A = np.column_stack([2 * P[:, 0], 2 * P[:, 1], np.ones(len(P))])
    a, b_, c = np.linalg.lstsq(A, (P ** 2).sum(1), rcond=None)[0]
    radius = math.sqrt(c + a * a + b_ * b_)
    expect = 2 * HALF_BASE / math.tan(delta)
    assert radius == pytest.approx(expect, rel=0.03)                 # brief: 10 %; measured 0.8 %
    assert b_ > 0                                                     # positive steering turns left


def test_engine_accelerates_and_bad_input():
    world, car, chassis = build()
    drive(world, car, 120)
    car.engine_torque = 400.0                                          # 2 driven wheels, no slip
    drive(world, car, 60)
    # rigid tyres, no slip: a = 2 T / r / (M + 4 I_w / r^2)
    a = 2 * 400.0 / 0.35 / (M + 4 * 1.2 / 0.35 ** 2)
    assert world.state.body_qd[chassis, 3] == pytest.approx(a * 1.0, rel=0.03)
    with pytest.raises(ValueError, match="chassis"):
        RaycastVehicle(world, 5, [Wheel((0, 0, 0))])
    with pytest.raises(ValueError, match=r"wheels\[0\].radius"):
        RaycastVehicle(world, chassis, [Wheel((0, 0, 0), radius=-1.0)])


def test_resumed_vehicle_run_equals_an_uninterrupted_one_bit_for_bit():
    # accelerating and turning: the wheels spin up under the engine torque (wheel_omega is integrated
    # state), so a checkpoint without it would resume with the wrong spin and tyre forces
    world, car, chassis = build()
    drive(world, car, 60)
    car.engine_torque, car.steering = 600.0, 0.1
    drive(world, car, 30)
    cp = world.save()                                   # carries the vehicle (world.checkpoint_parts)
    omega_at_cp = car.wheel_omega.copy()
    drive(world, car, 20)
    car.brake_torque = 800.0                            # inputs change after the checkpoint
    drive(world, car, 20)
    first = world.state.body_q.tobytes() + world.state.body_qd.tobytes() + car.wheel_omega.tobytes()
    assert not np.array_equal(car.wheel_omega, omega_at_cp)
    world.restore(cp)
    assert car.brake_torque == 0.0 and np.array_equal(car.wheel_omega, omega_at_cp)
    drive(world, car, 20)
    car.brake_torque = 800.0
    drive(world, car, 20)
    second = world.state.body_q.tobytes() + world.state.body_qd.tobytes() + car.wheel_omega.tobytes()
    assert first == second
    # a world with another number of vehicles cannot take this checkpoint
    other, _, _ = build()
    other.checkpoint_parts.clear()
    with pytest.raises(ValueError, match="attached parts"):
        other.restore(cp)
