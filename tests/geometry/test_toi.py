"""Time of impact by conservative advancement against closed-form contact times (bullets at 300 m/s)."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from inertia.geometry.toi import time_of_impact, time_of_impact_batch

DT = 1.0 / 60.0
SPEED = 300.0
ID = (1.0, 0.0, 0.0, 0.0)
SPHERE = ("sphere", (0.005,))                 # 1 cm sphere
WALL = ("box", (0.005, 0.5, 0.5))             # 1 cm thick wall
PLATE = ("box", (0.005, 0.05, 0.05))          # thin (1 cm) box bullet


def _pose(x, q=ID):
    return (x, 0.0, 0.0, *q)


def _qx(angle):
    return (math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0)


@pytest.mark.parametrize("bullet, reach", [(SPHERE, 0.005), (PLATE, 0.005)])
def test_bullet_at_300_m_s_hits_a_1_cm_wall_at_the_closed_form_time(bullet, reach):
    """Start 2 m before the wall (surface at x = -0.005), moving +x at 300 m/s for dt = 1/60 (5 m): contact
    when the front reaches the wall, t = (2 - 0.005 - reach) / 300 s (closed form), within 1e-6 s."""
    x0 = -2.0
    toi, n, p = time_of_impact(bullet, _pose(x0), _pose(x0 + SPEED * DT), WALL, _pose(0.0), _pose(0.0))
    t_exact = (-x0 - 0.005 - reach) / SPEED
    assert abs(toi * DT - t_exact) < 1e-6
    assert n == pytest.approx([1, 0, 0], abs=1e-9)
    assert p[0] == pytest.approx(-0.005, abs=1e-6)


def test_spinning_thin_box_hits_the_wall_at_the_closed_form_time():
    """Spinning about the direction of flight (10 turns in the step) leaves the box's x extent unchanged,
    so the closed form is the same; the rotation bound only makes advancement take more steps."""
    x0 = -2.0
    q1 = _qx(2 * math.pi * 10 + 0.3)
    toi, n, p = time_of_impact(PLATE, _pose(x0), _pose(x0 + SPEED * DT, q1), WALL, _pose(0.0), _pose(0.0))
    assert abs(toi * DT - (2.0 - 0.01) / SPEED) < 1e-6


def test_sphere_and_thin_box_flying_at_each_other():
    """Sphere +300 m/s from x = -1, thin box -300 m/s from x = +1: the gap 2 - 0.005 - 0.005 closes at 600 m/s."""
    toi, n, p = time_of_impact(SPHERE, _pose(-1.0), _pose(-1.0 + SPEED * DT), PLATE, _pose(1.0),
                               _pose(1.0 - SPEED * DT))
    assert abs(toi * DT - (2.0 - 0.01) / (2 * SPEED)) < 1e-6
    assert n == pytest.approx([1, 0, 0], abs=1e-9)
    assert p[0] == pytest.approx(0.0, abs=1e-6)


def test_misses_and_starting_overlap():
    # passing 0.1 m beside the wall's edge: no contact in the step
    toi, n, p = time_of_impact(SPHERE, (-2.0, 0.6, 0.0, *ID), (3.0, 0.6, 0.0, *ID), WALL, _pose(0.0), _pose(0.0))
    assert toi == 1.0 and not n.any()
    # moving away
    toi, _, _ = time_of_impact(SPHERE, _pose(-0.1), _pose(-5.0), WALL, _pose(0.0), _pose(0.0))
    assert toi == 1.0
    # already touching at the start
    toi, _, _ = time_of_impact(SPHERE, _pose(-0.008), _pose(3.0), WALL, _pose(0.0), _pose(0.0))
    assert toi == 0.0


def test_oblique_sphere_against_a_tilted_box():
    """Sphere moving along (1, 1, 0)/sqrt(2) towards a box rotated 30 deg about z: the contact time solves
    n . (c0 + v t) + r = -h for the box's -x face (normal -n, half extent h; closed form)."""
    ang = math.radians(30)
    qz = (math.cos(ang / 2), 0.0, 0.0, math.sin(ang / 2))
    n = np.array([math.cos(ang), math.sin(ang), 0.0])          # the box's +x face normal
    v = SPEED * np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    c0 = np.array([-1.0, -1.2, 0.0])
    # box centre 0, half extent along its x 0.05: the sphere (on the -n side) meets the face n.x = -0.05
    t_exact = (-0.05 - 0.005 - c0 @ n) / (v @ n)
    box = ("box", (0.05, 0.4, 0.4))
    toi, nn, p = time_of_impact(SPHERE, (*c0, *ID), (*(c0 + v * DT), *ID), box, (0, 0, 0, *qz), (0, 0, 0, *qz))
    assert abs(toi * DT - t_exact) < 1e-6
    assert nn == pytest.approx(n, abs=1e-9)


def test_batch_matches_the_scalar_call():
    shape_type = np.array([0, 1, 1], np.int32)
    shape_params = np.array([[0.005, 0, 0, 0], [0.005, 0.5, 0.5, 0], [0.005, 0.05, 0.05, 0]])
    pose0 = np.array([[-2.0, 0, 0, *ID], [0.0, 0, 0, *ID], [1.0, 0.3, 0, *ID]])
    pose1 = pose0.copy()
    pose1[0, 0] += SPEED * DT
    pose1[2, 0] -= SPEED * DT
    pairs = np.array([[0, 1], [0, 2], [1, 2]], np.int32)
    toi, nrm, pt = np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    time_of_impact_batch(pairs, 3, shape_type, shape_params, np.zeros(3, np.int32), np.zeros(3, np.int32),
                         np.zeros((1, 3)), pose0, pose1, 0.0, 1e-9, toi, nrm, pt)
    for k, (a, b) in enumerate(pairs):
        name = {0: "sphere", 1: "box"}
        ref = time_of_impact((name[shape_type[a]], shape_params[a]), pose0[a], pose1[a],
                             (name[shape_type[b]], shape_params[b]), pose0[b], pose1[b])
        assert toi[k] == ref[0]
        assert nrm[k] == pytest.approx(ref[1], abs=0)
    assert abs(toi[0] * DT - 1.99 / SPEED) < 1e-6


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="shape_a"):
        time_of_impact(("plane", ()), _pose(0), _pose(1), WALL, _pose(0), _pose(0))
    with pytest.raises(ValueError, match="pose_b1"):
        time_of_impact(SPHERE, _pose(0), _pose(1), WALL, _pose(0), (0, 0, 0, 2.0, 0, 0, 0))
