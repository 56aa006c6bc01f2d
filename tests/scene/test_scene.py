"""Scene loading: same simulation as the Python API, seeds, layouts, schema, every example builds."""

import json
from pathlib import Path

import numpy as np
import pytest

import inertia as ia
from inertia.scene import SCHEMA_PATH, load_scene, read_scene, scene_schema
from inertia.scene.builder import derive_seed

EXAMPLES = sorted((Path(ia.__file__).parent / "examples").glob("*.toml"))


def test_examples_are_bundled():
    names = {p.stem for p in EXAMPLES}
    assert {"fountain", "vortex", "chain", "cloth", "bouncing_balls", "wind", "paddle", "spheres_in_box"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_every_example_builds(path):
    world = load_scene(path)
    assert (world.particle_count > 0 or world.rigid_scene is not None or world.fluids) and world.duration > 0
    assert read_scene(path).model.description


def test_shipped_schema_is_current():
    shipped = json.loads(SCHEMA_PATH.read_text())
    assert shipped == json.loads(json.dumps(scene_schema())), "run: python -m inertia.scene.schema"
    assert shipped["properties"]["format_version"]["const"] == 1
    assert shipped["additionalProperties"] is False


def test_chain_scene_equals_python_api(write_scene):
    """The scene builds the same system as the API: identical trajectories, bit for bit."""
    path = write_scene("""
        format_version = 1
        [simulation]
        dt = 0.001
        integrator = "rk4"
        [[particles]]
        name = "chain"
        mass = 0.05
        [particles.chain]
        start = [0.0, 0.0, 1.0]
        end = [1.0, 0.0, 1.0]
        count = 5
        stiffness = 200.0
        damping = 0.1
        [[forces]]
        type = "gravity"
        [[forces]]
        type = "drag"
        coefficient = 0.01
    """)
    world = load_scene(path)
    world.run(0.05)
    x = np.stack([np.linspace(0, 1, 5), np.zeros(5), np.ones(5)], axis=1)
    ps = ia.ParticleSystem(x, masses=0.05, pinned=[0])
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    ps.add_force(ia.forces.Drag(0.01))
    ps.add_force(ia.forces.Springs([[0, 1], [1, 2], [2, 3], [3, 4]], stiffness=200.0, damping=0.1))
    sim = ia.Simulation(ps, integrator="rk4", dt=0.001)
    sim.run(0.05)
    assert world.step_count == sim.step_count == 50
    np.testing.assert_array_equal(world["chain"].state, ps.state)


def test_cloth_layout_springs_and_pins(write_scene):
    world = load_scene(write_scene("""
        format_version = 1
        [[particles]]
        name = "cloth"
        [particles.cloth]
        corner = [0.0, 0.0, 1.0]
        edge_u = [1.0, 0.0, 0.0]
        edge_v = [0.0, 1.0, 0.0]
        counts = [4, 3]
        pin = "corners"
    """))
    ps = world["cloth"]
    assert ps.particle_count == 12
    springs = [f for f in ps.forces if isinstance(f, ia.forces.Springs)][0]
    # structural 3*3 + 4*2 = 17, shear 2 * 3 * 2 = 12, bend 2*3 + 4*1 = 10
    assert springs.spring_count == 39
    assert np.isinf(ps.mass[[0, 3]]).all() and np.isfinite(ps.mass[1:3]).all()
    np.testing.assert_allclose(ps.x[11], [1.0, 1.0, 1.0])


def test_seeds(write_scene):
    text = """
        format_version = 1
        [simulation]
        seed = {seed}
        [[particles]]
        random = {{ count = 10, center = [0, 0, 0], half_extents = [1, 1, 1] {extra} }}
    """
    a = load_scene(write_scene(text.format(seed=1, extra=""))).groups[0].system.x.copy()
    b = load_scene(write_scene(text.format(seed=1, extra=""))).groups[0].system.x.copy()
    c = load_scene(write_scene(text.format(seed=2, extra=""))).groups[0].system.x.copy()
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    # an explicit seed is used as is, whatever the scene seed
    d = load_scene(write_scene(text.format(seed=1, extra=", seed = 5"))).groups[0].system.x.copy()
    e = load_scene(write_scene(text.format(seed=2, extra=", seed = 5"))).groups[0].system.x.copy()
    np.testing.assert_array_equal(d, e)
    # and the override reaches every random choice
    f = load_scene(write_scene(text.format(seed=1, extra="")), seed=2).groups[0].system.x
    np.testing.assert_array_equal(f, c)
    assert derive_seed(1, "particles[0].random") != derive_seed(1, "particles[1].random")


def test_groups_have_their_own_integrators_and_tracers(write_scene):
    world = load_scene(write_scene("""
        format_version = 1
        [simulation]
        dim = 2
        dt = 0.1
        fps = 10
        [fields.spin]
        type = "rotation"
        center = [0.0, 0.0]
        [[tracers]]
        name = "euler"
        field = "spin"
        integrator = "euler"
        positions = [[1.0, 0.0]]
        [[tracers]]
        name = "rk4"
        field = "spin"
        integrator = "rk4"
        positions = [[1.0, 0.0]]
    """))
    assert [g.integrator for g in world] == ["euler", "rk4"]
    world.run(2 * np.pi)
    r_euler = np.linalg.norm(world["euler"].x[0])
    r_rk4 = np.linalg.norm(world["rk4"].x[0])
    # explicit Euler: |x| grows by sqrt(1 + h^2) per step; RK4 stays on the circle
    steps = world.step_count
    assert r_euler == pytest.approx((1 + 0.01) ** (steps / 2), rel=1e-9)
    assert abs(r_rk4 - 1.0) < 1e-5


def test_fields_forces_and_colliders_build(write_scene, tmp_path):
    np.save(tmp_path / "grid.npy", np.zeros((3, 3, 3, 3)))
    world = load_scene(write_scene("""
        format_version = 1
        [fields.noise]
        type = "curl_noise"
        [fields.v]
        type = "vortex"
        center = [0, 0, 0]
        [fields.mix]
        type = "sum"
        fields = ["noise", "v"]
        weights = [0.5, 1.0]
        [[colliders]]
        name = "ball"
        type = "sphere"
        center = [0, 0, -1]
        radius = 0.5
        [[colliders]]
        type = "box"
        center = [2, 0, 0]
        half_extents = [0.2, 0.2, 0.2]
        rotation = [0.0, 0.0, 0.5]
        motion = { times = [0.0, 1.0], positions = [[2, 0, 0], [3, 0, 0]] }
        [[particles]]
        lattice = { origin = [0, 0, 0], counts = [2, 2, 2], spacing = 0.2 }
        radius = 0.01
        [[particles.forces]]
        type = "wind"
        field = "mix"
        [[particles.forces]]
        type = "field_force"
        field = "v"
        [[particles.forces]]
        type = "grid_force"
        file = "grid.npy"
        origin = [0, 0, 0]
        spacing = 0.5
        [[particles.forces]]
        type = "anchor_springs"
        indices = [0, 1]
        anchors = [0, 0, 1]
        [[particles.emitters]]
        rate = 100
        position = [0, 0, 0]
        cone = { direction = [0, 0, 1], speed = 1.0, spread = 0.2 }
        lifetime = 0.5
        [[tracers]]
        field = "mix"
        random = { count = 4, shape = "ball", center = [0, 0, 0], radius = 1 }
    """))
    assert len(world.colliders) == 2 and len(world.groups[0].colliders) == 2
    world.run(0.02)
    assert np.all(np.isfinite(world.positions()))
