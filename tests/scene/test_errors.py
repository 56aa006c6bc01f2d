"""Validation messages: each broken scene gives one clear message naming the key path."""

import pytest

from inertia.scene import SceneError, load_scene, read_scene

GOOD = """
format_version = 1
[simulation]
dt = 0.01
duration = 0.1
[[particles]]
name = "p"
positions = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]
[[particles.forces]]
type = "springs"
pairs = [[0, 1]]
stiffness = 10.0
"""


def problems(write_scene, text, name="scene.toml"):
    path = write_scene(text, name)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert str(path) in message          # the file is named
    return info.value, message


def test_good_scene_loads(write_scene):
    world = load_scene(write_scene(GOOD))
    assert world["p"].particle_count == 2


def test_unknown_key_suggests_the_right_one(write_scene):
    err, message = problems(write_scene, GOOD.replace("stiffness = 10.0", "stifness = 10.0"))
    assert "particles[0].forces[0].stifness: unknown key 'stifness'; did you mean 'stiffness'?" in message
    assert "allowed:" in message


def test_unknown_top_level_and_section_keys(write_scene):
    err, message = problems(write_scene, GOOD.replace("[simulation]", "partcles = 1\n[simulation]\nfsp = 3"))
    paths = [i.path for i in err.issues]
    assert "partcles" in paths and "simulation.fsp" in paths
    assert "did you mean 'particles'?" in message and "did you mean 'fps'?" in message


def test_wrong_type(write_scene):
    _, message = problems(write_scene, GOOD.replace("dt = 0.01", 'dt = "fast"'))
    assert "simulation.dt: must be a number (got 'fast')" in message


def test_out_of_range(write_scene):
    _, message = problems(write_scene, GOOD.replace("stiffness = 10.0", "stiffness = -5.0"))
    assert "particles[0].forces[0].stiffness: must be >= 0 (got -5.0)" in message


def test_unknown_type_and_literal_suggest(write_scene):
    text = GOOD.replace('type = "springs"', 'type = "sprngs"').replace("duration = 0.1", 'duration = 0.1\nintegrator = "rk5"')
    err, message = problems(write_scene, text)
    assert "particles[0].forces[0]: unknown type 'sprngs'; did you mean 'springs'?" in message
    assert "simulation.integrator: must be one of" in message and "'implicit_euler'" in message


def test_missing_format_version(write_scene):
    _, message = problems(write_scene, GOOD.replace("format_version = 1", ""))
    assert "format_version" in message and "format_version = 1" in message


def test_newer_format_version(write_scene):
    _, message = problems(write_scene, GOOD.replace("format_version = 1", "format_version = 7"))
    assert "newer than this inertia reads" in message


def test_vector_length_is_checked_against_dim(write_scene):
    _, message = problems(write_scene, GOOD.replace("[1.0, 0.0, 1.0]]", "[1.0, 0.0]]"))
    assert "particles[0].positions[1]: must have 3 components in a 3-D scene" in message


def test_spring_index_out_of_range(write_scene):
    _, message = problems(write_scene, GOOD.replace("pairs = [[0, 1]]", "pairs = [[0, 5]]"))
    assert "particles[0].forces[0].pairs[0]: index out of range" in message


def test_missing_mesh_file(write_scene):
    text = GOOD + """
[[colliders]]
type = "mesh"
file = "bunny.obj"
"""
    _, message = problems(write_scene, text)
    assert "colliders[0].file: file not found:" in message and "bunny.obj" in message


def test_unknown_field_and_group_names(write_scene):
    text = GOOD + """
[[forces]]
type = "gravity"
groups = ["q"]
"""
    _, message = problems(write_scene, text)
    assert "forces[0].groups[0]: no particle group named 'q'" in message
    text = GOOD + """
[fields.swirl]
type = "rotation"
center = [0.0, 0.0, 0.0]
[[tracers]]
field = "swril"
positions = [[1.0, 0.0, 0.0]]
"""
    _, message = problems(write_scene, text)
    assert "tracers[0].field: no field named 'swril' in [fields]; did you mean 'swirl'?" in message


def test_layout_choice_and_fps_faster_than_steps(write_scene):
    text = GOOD.replace('name = "p"', 'name = "p"\nlattice = { origin = [0, 0, 0], counts = [2, 2, 2], spacing = 0.1 }')
    _, message = problems(write_scene, text)
    assert "particles[0]: give at most one layout" in message
    _, message = problems(write_scene, GOOD.replace("duration = 0.1", "duration = 0.1\nfps = 500"))
    assert "simulation: fps = 500 asks for frames every 0.002 s" in message


def test_toml_syntax_error(write_scene):
    _, message = problems(write_scene, GOOD.replace("dt = 0.01", "dt = = 0.01"))
    assert "invalid TOML" in message and "line" in message


def test_json_scene_is_accepted(write_scene):
    import json
    import tomllib

    data = tomllib.loads(GOOD)
    world = load_scene(write_scene(json.dumps(data), "scene.json"))
    assert world["p"].particle_count == 2
    path = write_scene('{"format_version": 1, "particles": [{"positions": [[0, 0, 0]], "mas": 2}]}', "bad.json")
    with pytest.raises(SceneError, match=r"particles\[0\]\.mas: unknown key 'mas'; did you mean 'mass'\?"):
        read_scene(path)


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(SceneError, match="file not found"):
        read_scene(tmp_path / "nope.toml")
    with pytest.raises(SceneError, match="is a directory"):
        read_scene(tmp_path)


def test_all_problems_are_listed_at_once(write_scene):
    text = GOOD.replace("dt = 0.01", "dt = -1").replace("stiffness = 10.0", "stiffness = -1\nfoo = 2")
    err, message = problems(write_scene, text)
    assert len(err.issues) == 3 and message.splitlines()[0].endswith("3 problems")


# ---- issue 8: strict types, finite numbers, paths that stay inside the output directory --------
@pytest.mark.parametrize("value, expected", [
    ("true", "particles[0].mass: must be a number or a list (got True)"),
    ('"0.01"', "particles[0].mass: must be a number or a list (got '0.01')"),
])
def test_numbers_are_numbers(write_scene, value, expected):
    _, message = problems(write_scene, GOOD.replace('name = "p"', f'name = "p"\nmass = {value}'))
    assert expected in message


def test_strict_types_elsewhere(write_scene):
    # booleans are booleans, integers are integers, strings are strings
    for old, new, message in [
        ("stiffness = 10.0", "stiffness = false", "particles[0].forces[0].stiffness: must be"),
        ('[simulation]', '[simulation]\nsubsteps = 2.5', "simulation.substeps: must be an integer (got 2.5)"),
        ('[simulation]', '[simulation]\nseed = true', "simulation.seed: must be an integer (got True)"),
        ('name = "p"', 'name = "p"\ncollide = 1', "particles[0].collide: must be true or false (got 1)"),
        ('name = "p"', 'name = 5', "particles[0].name: must be a string (got 5)"),
    ]:
        _, got = problems(write_scene, GOOD.replace(old, new))
        assert message in got, got


@pytest.mark.parametrize("key, value", [("duration", "inf"), ("dt", "inf"), ("fps", "nan"), ("duration", "1e400")])
def test_infinite_and_nan_numbers_are_refused(write_scene, key, value):
    text = GOOD.replace("[simulation]", f"[simulation]\n{key} = {value}").replace("dt = 0.01\nduration = 0.1", "")
    _, message = problems(write_scene, text)
    assert f"simulation.{key}: must be a finite number" in message
    assert "lower fps" not in message


def test_deeply_nested_json_is_a_clear_error(write_scene):
    text = '{"format_version": 1, "x": ' + "[" * 100_000 + "]" * 100_000 + "}"
    _, message = problems(write_scene, text, "deep.json")
    assert "nested" in message and "deep.json" in message


@pytest.mark.parametrize("key, value", [
    ("name", '"/tmp/elsewhere"'), ("name", '"../../elsewhere"'), ("name", '"a/b"'), ("name", '".."'),
])
def test_a_scene_name_is_a_name_not_a_path(write_scene, key, value):
    _, message = problems(write_scene, GOOD.replace("format_version = 1", f"format_version = 1\n{key} = {value}"))
    assert "name: must be a plain name" in message


@pytest.mark.parametrize("value", ['"/tmp/elsewhere"', '"../../elsewhere"', '"out/../../x"', '"~/x"', '"C:/x"', '"\\\\\\\\server\\\\x"'])
def test_output_directory_stays_inside(write_scene, value):
    _, message = problems(write_scene, GOOD + f"\n[output]\ndirectory = {value}\n")
    assert "output.directory: must be a relative path inside the working directory" in message


def test_relative_output_directory_and_plain_names_are_fine(write_scene):
    world = load_scene(write_scene(GOOD.replace("format_version = 1", 'format_version = 1\nname = "my scene-2.v1"')
                                   + '\n[output]\ndirectory = "runs/mine"\n'))
    assert world.name == "my scene-2.v1"
