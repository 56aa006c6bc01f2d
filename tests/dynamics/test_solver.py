"""Soft-constraint coefficients and constraint colouring."""

import numpy as np
import pytest

from inertia.dynamics import solver as sv


@pytest.mark.parametrize("hertz, zeta, h", [(30.0, 10.0, 1 / 240), (60.0, 1.0, 1 / 480), (5.0, 0.3, 0.01)])
def test_soft_step_is_implicit_euler_of_a_spring_damper(hertz, zeta, h):
    # Catto's soft constraint: one impulse -m * mass_scale * (v + bias_rate * x) equals the implicit
    # Euler update of m x'' = -k x - c x' with k = m w^2, c = 2 m zeta w, evaluated at x + h v':
    # v' - v = -(h k x + (h c + h^2 k) v) / (m + h c + h^2 k)
    m, x, v = 2.5, -0.01, -0.3
    w = 2 * np.pi * hertz
    k, c = m * w * w, 2 * m * zeta * w
    bias_rate, mass_scale, impulse_scale = sv.soft_coefficients(hertz, zeta, h)
    dv_soft = -mass_scale * (v + bias_rate * x)
    dv_implicit = -(h * k * x + (h * c + h * h * k) * v) / (m + h * c + h * h * k)
    assert dv_soft == pytest.approx(dv_implicit, rel=1e-12)
    assert impulse_scale == pytest.approx(1 - mass_scale, rel=1e-12)


def test_colouring_is_write_disjoint_stable_and_complete():
    rng = np.random.default_rng(0)
    nb, nc = 200, 1500
    contact_body = rng.integers(-1, nb, size=(nc, 2)).astype(np.int32)
    contact_body[contact_body[:, 0] == contact_body[:, 1], 1] = -1   # a contact joins two bodies
    inv_mass = np.where(rng.random(nb) < 0.9, 1.0, 0.0)          # some static/kinematic bodies
    cons = np.arange(nc, dtype=np.int32)
    colour_of = np.zeros(nc, np.int64)
    start = np.zeros(sv.MAX_COLOURS + 2, np.int64)
    items = np.zeros(nc, np.int64)
    sv.colour_constraints(cons, nc, contact_body, inv_mass, np.zeros(nb, np.uint64), colour_of, start, items)
    assert sorted(items.tolist()) == list(range(nc))
    for col in range(sv.MAX_COLOURS):                           # the overflow colour is serial
        seen = set()
        batch = items[start[col]:start[col + 1]]
        assert np.all(np.diff(batch) > 0)                       # constraint order kept in a colour
        for c in batch:
            for b in contact_body[c]:
                if b >= 0 and inv_mass[b] > 0:
                    assert b not in seen
                    seen.add(b)
