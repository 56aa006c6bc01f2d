"""The [sph.NAME] scene table (inertia.fluids.sph.scene): builds a fluid; bad input names the key."""

import pytest

import inertia as ia
from inertia.fluids.sph import scene

BASE = {"spacing": 0.02, "domain": [[0, 0], [1, 1]], "fluid": [{"box": [[0, 0], [0.2, 0.4]]}]}


def test_table_builds_the_fluid():
    table = dict(BASE, viscosity=1e-3, boundaries=["tank"], emitters=[{"center": [0.5, 0.8], "velocity": [0, -1],
                                                                       "width": 0.1}],
                 outflows=[{"lo": [0.9, 0], "hi": [1, 1]}], capacity=1000)
    tank = ia.colliders.Container(center=(0.5, 0.5), half_extents=(0.5, 0.5))
    fluid = scene.build(table, colliders={"tank": tank}, name="water")
    assert fluid.particle_count == 10 * 20 and fluid.capacity == 1000
    assert fluid.viscosity == 1e-3
    fluid.step()
    assert fluid.boundary_x.shape[0] > 0


@pytest.mark.parametrize("change,match", [
    ({"spacing": 2.0}, r"sph.water.*(domain|spacing)"),
    ({"smoothing_length": 0.2}, r"sph.water.*smoothing_length"),
    ({"rest_density": -1.0}, r"sph.water.*rest_density"),
    ({"method": "sph"}, r"sph.water.method"),
    ({"dt": 0.5}, r"sph.water.*dt = 0.5"),
    ({"viscositty": 1.0}, r"sph.water.viscositty.*allowed keys"),
    ({"fluid": [{"box": [[0, 0], [2, 0.4]]}]}, r"sph.water.fluid\[0\].box.*inside the domain"),
    ({"emitters": [{"center": [3, 3], "velocity": [1, 0], "width": 0.1}]}, r"sph.water.emitters\[0\].*center"),
    ({"boundaries": ["nope"]}, r"sph.water.boundaries\[0\].*unknown collider"),
])
def test_bad_input_names_the_key(change, match):
    with pytest.raises(ValueError, match=match):
        scene.build(dict(BASE, **change), colliders={}, name="water")
