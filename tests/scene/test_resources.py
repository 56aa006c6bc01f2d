"""Resource estimates (issue 8): a scene too big for the machine or too long to finish is refused
before anything is allocated, naming the key, the estimate and what the machine has."""

import tracemalloc

import pytest

from inertia.scene import SceneError, build, parse_scene
from inertia.scene.resources import SECONDS_PER_SPH_PARTICLE_STEP, estimate_resources

HUGE_CHAIN = """
format_version = 1
[[particles]]
chain = { start = [0, 0, 1], end = [1, 0, 1], count = 1_000_000_000 }
"""


def test_a_billion_particles_are_refused_before_allocating():
    scene = parse_scene(HUGE_CHAIN, source="huge.toml")
    tracemalloc.start()
    try:
        with pytest.raises(SceneError) as info:
            build(scene)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(info.value)
    assert "particles[0].chain.count" in message and "1,000,000,000 particles" in message
    assert "TB of memory" in message and "available" in message
    assert peak < 20e6, f"the refusal itself allocated {peak / 1e6:.0f} MB"


@pytest.mark.parametrize("layout, key, particles, springs", [
    ("lattice = { origin = [0, 0, 0], counts = [10, 20, 30], spacing = 0.1 }", "particles[0].lattice.counts", 6000, 0),
    ("random = { count = 500, center = [0, 0, 0], radius = 1.0, shape = 'ball' }", "particles[0].random.count", 500, 0),
    ("chain = { start = [0, 0, 0], end = [1, 0, 0], count = 50 }", "particles[0].chain.count", 50, 49),
    ("cloth = { corner = [0, 0, 0], edge_u = [1, 0, 0], edge_v = [0, 1, 0], counts = [4, 3] }",
     "particles[0].cloth.counts", 12, 17 + 12 + 10),
])
def test_counts_match_what_the_builder_makes(layout, key, particles, springs):
    text = f"format_version = 1\n[[particles]]\n{layout}\n"
    estimate = estimate_resources(parse_scene(text).model)
    assert estimate.particles == particles and estimate.springs == springs
    assert estimate.largest_key == key
    world = build(parse_scene(text))
    assert world.particle_count == particles
    built_springs = sum(len(f.pairs) for g in world.groups for f in g.system.forces if hasattr(f, "pairs"))
    assert built_springs == springs


def test_emitter_pools_are_counted():
    text = """
format_version = 1
[simulation]
duration = 2.0
[[particles]]
[[particles.emitters]]
rate = 1e12
position = [0, 0, 0]
velocity = [0, 0, 1]
lifetime = 1.0
"""
    with pytest.raises(SceneError, match=r"particles\[0\].emitters\[0\].rate"):
        build(parse_scene(text))


def test_run_time_estimate_names_duration_and_substeps():
    text = """
format_version = 1
[simulation]
duration = 1e12
substeps = 1000
[[particles]]
positions = [[0, 0, 1]]
"""
    estimate = estimate_resources(parse_scene(text).model)
    assert estimate.steps == pytest.approx(1e12 * 600 * 1000, rel=1e-6)
    assert estimate.seconds > 3.15e7 * 100         # centuries, at any speed this machine has
    problem = estimate.run_time_problem()
    assert "simulation.duration" in problem and "substeps" in problem and "years" in problem and "--force" in problem
    short = estimate_resources(parse_scene(text.replace("1e12", "1.0").replace("1000", "1")).model)
    assert short.run_time_problem() is None


# ---- every part counted (issue 22) ---------------------------------------------------------------
BOXES = """
format_version = 1
[bodies.box]
shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }
array = { count = [100, 100, 10], spacing = [0.3, 0.3, 0.3] }
"""


def test_bodies_cost_the_measured_memory_each():
    from inertia.scene.resources import BYTES_PER_BODY

    est = estimate_resources(parse_scene(BOXES).model)
    # 100k boxes peaked at about 3.1 GB in a run: the estimate must not be far below it
    assert est.memory >= 100_000 * BYTES_PER_BODY >= 3.0e9
    assert est.largest_key == "bodies.box.array.count"


def test_a_huge_hull_is_listed_as_a_limit_naming_its_key():
    points = ", ".join(f"[{i % 7 * 0.01}, {i % 11 * 0.01}, {i % 13 * 0.01}]" for i in range(10_001))
    text = BOXES.replace('shape = { type = "box", half_extents = [0.1, 0.1, 0.1] }',
                         f'shape = {{ type = "hull", points = [{points}] }}').replace("[100, 100, 10]", "[1, 1, 1]")
    key, message = estimate_resources(parse_scene(text).model).size_problem()
    assert key == "bodies.box.shape.points" and "10,001 points" in message and "--force" in message


def test_sph_particles_come_from_the_spacing_and_the_boxes_and_cost_run_time():
    text = """
format_version = 1
[simulation]
dim = 2
dt = 0.005
duration = 2.0
[sph.water]
spacing = 1e-4
domain = [[0, 0], [0.8, 0.6]]
fluid = [{ box = [[0, 0], [0.2, 0.4]] }]
"""
    est = estimate_resources(parse_scene(text).model)
    assert abs(est.particles - 2000 * 4000) <= 6000      # (0.2 / 1e-4) x (0.4 / 1e-4) lattice points
    assert est.memory > 8e6 * 1000 and est.largest_key == "sph.water.spacing"
    # the fluid's own steps: a CFL step of cfl spacings at the speed the 0.4 m column reaches falling its
    # height, sqrt(2 g H) = 2.80 m/s: dt = 0.4 x 1e-4 / 2.80 = 1.43e-5 s, 350 fluid steps per 5 ms world step
    fluid_steps = 400 * 0.005 / (0.4 * 1e-4 / (2 * 9.81 * 0.4) ** 0.5)
    assert est.seconds == pytest.approx(fluid_steps * 8e6 * SECONDS_PER_SPH_PARTICLE_STEP, rel=0.01)
    assert est.run_time_problem() is not None                       # days: refused without --force
    coarser = estimate_resources(parse_scene(text.replace("1e-4", "2e-4")).model)
    assert est.seconds / coarser.seconds == pytest.approx(8.0, rel=0.01)    # 4x the particles, 2x the steps


def test_grid_cells_cost_memory_and_run_time_and_negative_sizes_are_refused():
    text = """
format_version = 1
[simulation]
dim = 2
dt = 0.01
duration = 1.0
[fluids.box]
shape = [1000, 1000]
cell_size = 0.001
"""
    est = estimate_resources(parse_scene(text).model)
    assert est.cells == 1_000_000 and est.seconds >= 100 * 1e6 * 1e-8
    with pytest.raises(SceneError, match=r"fluids\.box\.shape\[0\]"):
        parse_scene(text.replace("[1000, 1000]", "[-1000, 1000]"))


def test_an_absurd_step_count_does_not_overflow_the_estimate():
    text = "format_version = 1\n[simulation]\ndt = 1e-300\nduration = 1e15\n[[particles]]\npositions = [[0, 0, 0]]\n"
    est = estimate_resources(parse_scene(text).model)
    assert est.steps > 1e300 and est.run_time_problem() is not None
