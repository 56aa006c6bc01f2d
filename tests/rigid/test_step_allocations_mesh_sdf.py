"""No allocation per step in the mesh, heightfield and SDF narrow phases (issue 9: "no allocation per step").

Bodies of every convex kind (boxes, spheres, capsules, cylinders, a convex hull) resting on three static
floors side by side: a triangle mesh (BVH over its triangles), a heightfield, and a baked SDF
(`inertia.geometry.sdf_collide`), in a `inertia.rigid.world.RigidWorld` after warm-up. The two counters
of tests/conftest.py (explained in tests/fluids/grid/test_step_allocations.py and
tests/rigid/test_step_allocations.py):

* Numba's NRT allocation counter per kernel, less the wrapping of each array argument: what the kernels
  allocate inside. Before the mesh bank (``narrowphase.MeshScratch``) a warm step of the 18-body scene
  made 170 such allocations in ``narrow_phase_mesh`` (per mesh or heightfield pair: the candidate list,
  the BVH stack, the query box, a polytope's vertex and point rows, a sphere's crease rows) and 64 in
  ``narrow_phase_sdf`` (four sample rows per run of pairs), measured by running this test against main's
  tree before the change (its kernel counter assertion fails naming both kernels). Now none.
* tracemalloc's peak over 3 steps above their start, at 18 and at 3136 bodies: below BOUND_BYTES =
  24.5 KB, the size of one (3136,) float64 array, so a per-body (or per-pair, per-contact) array made per
  step at 3136 bodies fails it, while the fixed Python overhead per step (bundles rebuilt per call,
  profile floats; 11-17 KB measured at both sizes, load 6) passes. The per-pair scratch the first counter
  caught was freed pair by pair, so it raised the peak by a few hundred bytes only: the counters see
  different faults.

The large scene starts 5-7 cm above the floors, so its pair and contact counts stay within the buffers made
at build (a growth, doubling, is an allocation by design and would show as a peak of megabytes).
"""

import numpy as np
import pytest

from inertia.colliders import SDF
from inertia.geometry import shapes as S
from inertia.model import ModelBuilder, with_colliders
from inertia.rigid.world import RigidWorld

SPACING = 0.2                        # m between neighbouring bodies (no body-body pairs in one layer)


def _floors_and_bodies(side, layers):
    """``side`` x ``side`` columns of ``layers`` bodies over three flat floors at z = 0 along x: a triangle
    mesh (x < -L/6), a heightfield (around x = 0) and a baked SDF (x > L/6), L = side * SPACING, overlapping
    a little; the lowest layer starts 5-7 cm above them."""
    rng = np.random.default_rng(2)
    half = 0.5 * side * SPACING
    third = 2.0 * half / 3.0
    b = ModelBuilder(gravity=(0.0, 0.0, -9.81))
    # mesh floor: a grid of squares of SPACING / 2, two triangles each, over [-half - 0.2, -third / 2]
    xs = np.linspace(-half - 0.2, -0.5 * third, max(3, int(np.ceil((half - 0.5 * third) / (0.5 * SPACING)))))
    ys = np.linspace(-half - 0.2, half + 0.2, max(3, int(np.ceil(2.0 * half / (0.5 * SPACING)))))
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    nx, ny = X.shape
    a = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    tris = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)])
    b.add_triangle_mesh(np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1), tris)
    # heightfield floor over |x| < third / 2 (its cells SPACING / 2 wide)
    hx = max(3, int(np.ceil((third + 0.4) / (0.5 * SPACING))) + 1)
    hy = max(3, int(np.ceil((2.0 * half + 0.4) / (0.5 * SPACING))) + 1)
    b.add_heightfield(np.zeros((hx, hy)), (0.5 * SPACING, 0.5 * SPACING))
    hull = rng.normal(size=(10, 3)) * 0.03
    for k in range(side * side * layers):
        i, j, lay = k % side, (k // side) % side, k // (side * side)
        x, y = SPACING * (i - (side - 1) / 2), SPACING * (j - (side - 1) / 2)
        q = rng.normal(size=4)
        q /= np.sqrt(np.sum(q * q))
        body = b.add_body(position=(x, y, 0.1 + 0.2 * lay), orientation=q)
        # every kind in turn, one hull; in a large scene spheres, every 16th body of another kind (the
        # others' mass properties take ~1 ms each to build, a hull's ~10 ms)
        kind = (4 if k == 4 else k % 4) if side * side * layers < 64 else (k // 16 % 5 if k % 16 == 4 else 1)
        (lambda: b.add_box(body, (0.05, 0.04, 0.03)), lambda: b.add_sphere(body, 0.05),
         lambda: b.add_capsule(body, 0.03, 0.04), lambda: b.add_cylinder(body, 0.04, 0.03),
         lambda: b.add_convex_hull(body, hull))[kind]()
    floor = SDF(lambda p: p[:, 2], bake={"bounds": ((0.5 * third, -half - 0.2, -0.2), (half + 0.2, half + 0.2, 0.2)),
                                         "resolution": 16})
    return RigidWorld(with_colliders(b.finalize(), [floor]), enable_sleep=False)


BOUND_BYTES = 3136 * 8               # one (3136,) float64 array


@pytest.mark.isolated
def test_warm_step_on_mesh_heightfield_and_sdf_allocates_nothing_that_grows(alloc):
    small = _floors_and_bodies(3, 2)          # 18 bodies of every kind in two layers: stacked contacts
    for _ in range(30):
        small.step()
    c = small.contacts
    floors = small.model.shape_type[c.contact_shape[c.active[:c.active_count], 1]]
    assert {S.TRIANGLE_MESH, S.HEIGHTFIELD, S.SDF} <= {int(t) for t in floors}      # every floor is touched
    assert alloc.kernel_allocations(small.step, 5) == {}   # no kernel of the step allocates, narrow phases too
    peaks = [alloc.peak_bytes(small.step, 3, BOUND_BYTES)]
    big = _floors_and_bodies(56, 1)           # 3136 bodies in one layer on the floors
    for _ in range(3):
        big.step()
    assert alloc.kernel_allocations(big.step, 3) == {}
    peaks.append(alloc.peak_bytes(big.step, 3, BOUND_BYTES))
    # one (3136,) float64 array is 24.5 KB: no per-body array made per step at 3136 bodies fits under it;
    # the fixed Python overhead per step does, at 18 and at 3136 bodies
    assert max(peaks) < BOUND_BYTES, peaks
    assert big.contacts.active_count >= 3136
