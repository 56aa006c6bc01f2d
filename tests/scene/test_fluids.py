"""[sph.NAME] tables in scene files (inertia.scene.fluids): validated by the SPH package's table
model, built into the World as a fluid, bad keys reported at their path, memory estimated."""

import tracemalloc

import numpy as np
import pytest

from inertia.scene import SceneError, build, parse_scene
from inertia.scene.resources import estimate_resources

DAM = """
format_version = 1
[simulation]
dim = 2
dt = 0.005
duration = 0.02
fps = 100

[[colliders]]
type = "container"
name = "tank"
center = [0.4, 0.3]
half_extents = [0.4, 0.3]

[sph.water]
spacing = 0.02
domain = [[0, 0], [0.8, 0.6]]
fluid = [{ box = [[0, 0], [0.2, 0.4]] }]
boundaries = ["tank"]
"""


def test_sph_table_becomes_a_fluid_of_the_world():
    world = build(parse_scene(DAM, source="dam.toml"))
    fluid = world.fluids["water"]
    assert fluid.particle_count == 10 * 20          # 0.2 / 0.02 by 0.4 / 0.02 lattice points
    assert np.allclose(fluid.gravity, [0.0, -9.81])  # 2-D scenes are y-up
    world.step()
    assert fluid.boundary_x.shape[0] > 0            # the tank's walls were sampled
    x = fluid.frame_arrays()["x"]
    assert x.shape == (200, 2) and np.all(np.isfinite(x))


@pytest.mark.parametrize("old,new,path", [
    ("spacing = 0.02", "spacing = -0.02", "sph.water.spacing"),
    ("spacing = 0.02", "spacing = 0.02\nviscositty = 1.0", "sph.water.viscositty"),
    ('boundaries = ["tank"]', 'boundaries = ["tnak"]', "sph.water.boundaries[0]"),
    ("fluid = [{ box = [[0, 0], [0.2, 0.4]] }]", "fluid = [{ box = [[0, 0], [2, 0.4]] }]", "sph.water.fluid[0].box"),
    ("domain = [[0, 0], [0.8, 0.6]]", "domain = [[0, 0, 0], [0.8, 0.6, 0.6]]", "sph.water.domain"),
])
def test_bad_sph_keys_are_named(old, new, path):
    with pytest.raises(SceneError) as info:
        build(parse_scene(DAM.replace(old, new), source="dam.toml"))
    assert f"dam.toml: {path}" in str(info.value)


def test_a_scene_with_only_a_fluid_is_valid_and_one_without_anything_is_not():
    parse_scene(DAM)
    with pytest.raises(SceneError, match="at least one"):
        parse_scene("format_version = 1\n")


def test_memory_estimate_counts_the_fluid_and_bounds_what_it_allocates():
    # 40 x 40 particles: the estimate's particle count is the built fluid's, and its bytes cover what
    # building and one step allocate (neighbour lists included) without overshooting 4x.
    text = DAM.replace("[[0, 0], [0.2, 0.4]]", "[[0, 0], [0.4, 0.4]]").replace("0.02", "0.01")
    scene = parse_scene(text)
    est = estimate_resources(scene.model)
    key = "sph.water.spacing"
    assert est.particles == 1600 and key in est.items
    build(scene).step()  # compile and warm everything outside the measurement
    tracemalloc.start()
    try:
        world = build(scene)
        world.step()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert world.fluids["water"].particle_count == 1600
    assert peak <= est.items[key][0] <= 4 * peak, (peak, est.items[key][0])
