"""Shared helpers for the collision tests: tiny scenes built inline."""

import numba
import numpy as np
import pytest

import inertia as ia

G = 9.81


@pytest.fixture
def one_thread():
    """Run a long test of a tiny scene on one Numba thread.

    Launching a 2-thread parallel region costs up to a millisecond on a loaded 2-core machine;
    the core's kernels run in parallel at any size, so 10^5 steps of one particle would be
    dominated by launch latency. The physics is the same at any thread count (see
    test_broadphase.py::test_deterministic_at_1_and_2_threads).
    """
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(before)


def particles(positions, velocities=None, *, radius=0.0, gravity=True, masses=1.0):
    ps = ia.ParticleSystem(np.atleast_2d(np.asarray(positions, float)),
                           None if velocities is None else np.atleast_2d(np.asarray(velocities, float)),
                           masses=masses, radius=radius)
    if gravity:
        dim = ps.x.shape[1]
        ps.add_force(ia.forces.Gravity((0.0, -G) if dim == 2 else (0.0, 0.0, -G)))
    return ps


def state_hash(system) -> str:
    import hashlib
    return hashlib.sha256(system.state.tobytes()).hexdigest()
