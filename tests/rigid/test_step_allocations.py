"""No allocation per step in the rigid step (issue 9: "no allocation per step"), with a particle group.

A small mixed pile (boxes, spheres, capsules, convex hulls on a plane) with one coupled particle group
in an `inertia.world.World` (the rigid stage, the particle stage against the body rows, the impulses
back onto the bodies), after warm-up. Two counters (the counters of tests/conftest.py,
explained in tests/fluids/grid/test_step_allocations.py):

* Numba's NRT allocation counter per kernel, minus the wrapping of each array argument at the call
  from Python: what the kernels allocate inside (``np.empty`` and friends, lists, array copies). Before
  issue 9's change a warm step of this scene made ~960 such allocations on the rigid path (the narrow
  phase's scratch per run of pairs: 160 + 768; four per shape in ``shape_world_bounds``; seven in
  ``sort_and_sweep``; one in ``colour_constraints``; two in ``_first_bad_bodies``; two 3x3 per pushed
  body in ``particle_coupling._apply``). Now every rigid-path kernel allocates nothing.
* tracemalloc's peak over 3 steps above their start (every Python object and NumPy buffer). What is
  left is the fixed Python overhead per step (frames, the bundles ``Contacts.arrays()`` and
  ``SolverContext`` rebuilt per step, profile floats): it does not grow with the scene. The test runs
  the coupled pile at 8 bodies (two layers, stacked) and the rigid stage of a 4096-body pile (one
  layer on the plane) and asserts the peaks are below BOUND_BYTES = 32 KB, the size of one (4096,)
  float64 array: a per-body float array (or any per-pair, per-contact or per-shape one, larger still)
  made per step at 4096 bodies fails it, while the overhead, 10-22 KB measured at both sizes, passes.
  The whole coupled step at 4096 bodies is held to the same bound: it used to peak at ~54 KB, the
  particle stage looking its kernels up with ``kinds[:, 0].tolist()`` per call (32 KB at 4096
  collider rows); the collision data now keeps its bundle from the last change of the table
  (``ParticleCollisionData.kernels``), and the step peaks at 18-22 KB (measured). The large pile
  starts at rest on the plane so its pair and contact counts stay within the buffers made at build: a growth (doubling,
  amortised) is an allocation by design and would show as a peak of megabytes.
"""

import numpy as np
import pytest

import inertia as ia
from inertia.model import ModelBuilder
from inertia.world import World

BOUND_BYTES = 4096 * 8             # one (4096,) float64 array


def _pile(side, layers):
    """side x side columns of ``layers`` bodies (boxes, spheres, capsules, one hull) above a plane, 0.2 m
    apart, and 16 particles (a coupled group) above them; one layer rests on the plane from the start, so
    its pair and contact counts stay within the buffers made at build (no amortised growth)."""
    rng = np.random.default_rng(1)
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    b.add_plane()
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * 0.05
    for k in range(side * side * layers):
        i, j, lay = k % side, (k // side) % side, k // (side * side)
        q = rng.normal(size=4)
        q /= np.sqrt(np.sum(q * q))
        body = b.add_body(position=(0.2 * (i - (side - 1) / 2), 0.2 * (j - (side - 1) / 2), 0.1 + 0.2 * lay),
                          orientation=q)
        if k == 3:                      # one hull (the particles see it as a distance grid: costly to build)
            b.add_convex_hull(body, cube)
        else:
            (lambda: b.add_box(body, (0.05, 0.04, 0.03)), lambda: b.add_sphere(body, 0.05),
             lambda: b.add_capsule(body, 0.03, 0.04))[k % 3]()
    world = World(dt=1 / 60, model=b.finalize(), rigid_options={"substeps": 4, "enable_sleep": False})
    x = np.column_stack([rng.uniform(-0.2, 0.2, 16), rng.uniform(-0.2, 0.2, 16),
                         rng.uniform(0.1, 0.2, 16) + 0.2 * layers])   # above the pile
    ps = ia.ParticleSystem(x, masses=0.01, radius=0.01)
    ps.add_force(ia.forces.Gravity((0.0, 0.0, -9.81)))
    world.add("drops", ps)
    return world


@pytest.mark.isolated
def test_warm_coupled_pile_step_allocates_nothing_that_grows_with_the_scene(alloc):
    small = _pile(2, 2)                      # 8 bodies in two layers: stacked contacts, GJK pairs
    for _ in range(30):                      # the upper layer lands, particles land on the bodies
        small.step()
    assert alloc.kernel_allocations(small.step, 5) == {}     # no kernel the coupled step calls allocates
    rigid = small.rigid
    assert rigid.contacts.active_count >= 8              # the pile is in contact (the plane, each other)
    assert (small.rigid.contacts.contact_point_count[:rigid.contacts.count] > 0).any()
    peaks = [alloc.peak_bytes(small.step, 3, BOUND_BYTES)]
    big = _pile(64, 1)                       # 4096 bodies in one layer on the plane
    for _ in range(3):
        big.step()
    assert alloc.kernel_allocations(big.step, 5) == {}
    # the rigid stage at 4096 bodies, and the whole coupled step (the particle stage against 4096 body
    # rows: no list per collider row, see the module docstring)
    peaks.append(alloc.peak_bytes(big.rigid.step, 3, BOUND_BYTES))
    peaks.append(alloc.peak_bytes(big.step, 3, BOUND_BYTES))
    # one (4096,) float64 array is 32 KB: the bound, which no per-body float array made per step at 4096
    # bodies fits under; the peaks (Python's fixed overhead per step, ~10-22 KB measured at load 10)
    # are below it at 8 and at 4096 bodies, rigid stage and coupled step
    assert max(peaks) < BOUND_BYTES, peaks
    assert big.rigid.contacts.active_count >= 4096
