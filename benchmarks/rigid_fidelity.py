"""Rigid-body fidelity figures: bounce apex ratios and torque-free rotation.

1. Bounce apexes. A sphere (r 0.05 m) dropped from h0 = 1 m onto a plane, both of restitution e, rises to
   h_n = e^(2n) h0 after the n-th bounce (each bounce keeps e^2 of the impact energy). Printed: the ratio
   h_n / (e^(2n) h0) of the first three apexes for e in 0.3, 0.5, 0.8, 1.0 at the default step (dt 1/60 s,
   8 substeps) and at dt = 1/600 s, with ``restitution_threshold`` 0.1 m/s (the default 1 m/s stops the
   e = 0.3 ball after its second bounce). The apex is that of the parabola the ball leaves a bounce step
   on: the stepper's positions lie on the parabola whose velocity at a state is the stored one minus g h / 2
   (symplectic Euler stores the velocity half a substep back), so h = z - r + (v - g h / 2)^2 / (2 g).
2. Torque-free rotation, 60 s at the default step, no gravity: the relative drift of the kinetic energy
   and of |L| of a tumbling body (principal moments 0.5, 1.3, 1.6 kg m^2, body-frame w = (1, -2, 0.7)
   rad/s), and the intermediate-axis flip period of the top (1, 2, 3) kg m^2 spun at w = (2e-3, 2, 2e-3)
   rad/s against Landau and Lifshitz's elliptic-function period 27.5308 s (tests/rigid/test_free_body.py).
3. The price of the implicit gyroscopic step: CPU time of one ``integrate_velocities`` call (serial) over
   1000 tumbling bodies (min of 7 x 2000 calls, thread time), to compare between two trees.

Run:  PYTHONPATH=src python benchmarks/rigid_fidelity.py [--bounce] [--rotation] [--integrate-cost]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from inertia import math as im
from inertia.model import ModelBuilder
from inertia.rigid.world import RigidWorld

G = 9.81


def bounce_apexes(e, dt, *, substeps=8, h0=1.0, r=0.05, bounces=3, threshold=0.1, seconds=4.0):
    b = ModelBuilder(gravity=(0.0, 0.0, -G))
    b.add_plane(restitution=e)
    body = b.add_body(position=(0.0, 0.0, h0 + r))
    b.add_sphere(body, r, restitution=e)
    world = RigidWorld(b.finalize(), dt=dt, substeps=substeps, restitution_threshold=threshold,
                       enable_sleep=False)
    h = dt / substeps
    apexes, prev = [], None
    for _ in range(int(round(seconds / dt))):
        world.step()
        z, vz = world.state.body_q[0, 2], world.state.body_qd[0, 5]
        if prev is not None and vz > prev:          # a bounce in this step: gravity alone lowers vz
            vc = vz - 0.5 * G * h
            apexes.append(z - r + vc * vc / (2.0 * G))
            if len(apexes) == bounces:
                break
        prev = vz
    return np.array(apexes) / (e ** (2.0 * np.arange(1, len(apexes) + 1)) * h0)


def free_rotation(inertia, omega_body, *, seconds=60.0, dt=1.0 / 60.0, substeps=8):
    """Body-frame angular momentum per step and the relative drift of E and |L| after ``seconds``."""
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    q0 = im.quat_from_axis_angle(np.array([0.3, -1.0, 0.4]), 1.1)
    w0 = im.quat_rotate(q0, np.asarray(omega_body, float))
    b.add_body(orientation=q0, angular_velocity=w0, mass=1.0, inertia=inertia)
    world = RigidWorld(b.finalize(), dt=dt, substeps=substeps, enable_sleep=False)
    ib = np.asarray(inertia, float)

    def body_momentum():
        q = world.state.body_q[0, 3:]
        return ib * im.quat_rotate_inv(q, world.state.body_qd[0, :3])

    steps = int(round(seconds / dt))
    lb = np.empty((steps + 1, 3))
    lb[0] = body_momentum()
    for n in range(steps):
        world.step()
        lb[n + 1] = body_momentum()
    energy = 0.5 * np.sum(lb * lb / ib, axis=1)
    norm = np.linalg.norm(lb, axis=1)
    return lb, energy[-1] / energy[0] - 1.0, norm[-1] / norm[0] - 1.0


def flip_period(lb, dt):
    l2 = lb[:, 1]
    idx = np.flatnonzero(np.sign(l2[1:]) != np.sign(l2[:-1]))
    crossings = (idx + l2[idx] / (l2[idx] - l2[idx + 1])) * dt
    return crossings[2] - crossings[0] if len(crossings) >= 3 else float("nan")


def integrate_cost(bodies=1000, calls=2000, repeats=7):
    """Microseconds of CPU per serial integrate_velocities call over ``bodies`` tumbling bodies."""
    import time

    from inertia.dynamics import solver as sv
    integrate = sv.serial_versions()["integrate_velocities"]
    rng = np.random.default_rng(0)
    inertia = rng.uniform(0.5, 2.0, (bodies, 3))
    q = rng.normal(size=(bodies, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    args = (np.zeros(bodies, np.int32), np.ones(bodies, np.bool_), np.ones(bodies), inertia, 1.0 / inertia,
            np.zeros(bodies), np.zeros(bodies), np.zeros((bodies, 3)), np.zeros((bodies, 3)),
            np.array([0.0, 0.0, -G]), np.hstack([np.zeros((bodies, 3)), q]), rng.normal(size=(bodies, 6)) * 1e-3,
            1.0 / 480.0)
    integrate(*args)
    best = math.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        for _ in range(calls):
            integrate(*args)
        best = min(best, (time.thread_time() - t0) / calls * 1e6)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bounce", action="store_true")
    ap.add_argument("--rotation", action="store_true")
    ap.add_argument("--integrate-cost", action="store_true")
    args = ap.parse_args()
    both = not (args.bounce or args.rotation or args.integrate_cost)
    if args.bounce or both:
        for dt, label in ((1.0 / 60.0, "dt 1/60 (default)"), (1.0 / 600.0, "dt 1/600")):
            for e in (0.3, 0.5, 0.8, 1.0):
                ratios = bounce_apexes(e, dt)
                print(f"apex / e^(2n) h0  {label:18s} e {e:.1f}: " + ", ".join(f"{x:.5f}" for x in ratios))
    if args.rotation or both:
        _, de, dl = free_rotation([0.5, 1.3, 1.6], [1.0, -2.0, 0.7])
        print(f"tumbling body, 60 s at dt 1/60 (8 substeps): energy {de:+.3e}, |L| {dl:+.3e}")
        lb, de, dl = free_rotation([1.0, 2.0, 3.0], [2e-3, 2.0, 2e-3])
        print(f"flip body: period {flip_period(lb, 1.0 / 60.0):.4f} s (elliptic 27.5308 s), "
              f"energy {de:+.3e}, |L| {dl:+.3e}")
    if args.integrate_cost:
        print(f"integrate_velocities, 1000 bodies, serial: {integrate_cost():.1f} us per call")


if __name__ == "__main__":
    main()
