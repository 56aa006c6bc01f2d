"""The bundled fluid examples validate, build and run; a scene with a fluid resumes bit for bit
from a checkpoint file (inertia.world.save_checkpoint / load_checkpoint)."""

from pathlib import Path

import numpy as np

import inertia as ia
from inertia.scene import load_scene, read_scene
from inertia.world import load_checkpoint, save_checkpoint

EXAMPLES = Path(ia.__file__).parent / "examples"


def test_sph_dam_break_example_collapses():
    scene = read_scene(EXAMPLES / "sph_dam_break.toml")
    assert scene.model.description and "water" in scene.model.sph
    world = load_scene(EXAMPLES / "sph_dam_break.toml")
    fluid = world.fluids["water"]
    x0 = fluid.frame_arrays()["x"].copy()
    for _ in range(20):                     # 0.1 s
        world.step()
    x = fluid.frame_arrays()["x"]
    assert np.all(np.isfinite(x)) and fluid.particle_count == x0.shape[0]    # no particle lost
    # Under gravity the column falls and spreads: the top sinks, the front advances (0.1 s after
    # release the free-fall scale is g t^2 / 2 = 4.9 cm; we only ask for a tenth of it).
    assert x[:, 1].max() < x0[:, 1].max() - 0.005
    assert x[:, 0].max() > x0[:, 0].max() + 0.005
    assert np.all(x >= -1e-9) and np.all(x[:, 0] <= 0.8) and np.all(x[:, 1] <= 0.6)  # the tank holds it


def test_lid_cavity_example_is_driven_by_the_lid():
    world = load_scene(EXAMPLES / "lid_cavity.toml")
    fluid = world.fluids["cavity"]
    for _ in range(5):
        world.step()
    speed = fluid.frame_arrays()["speed"]
    assert speed.shape == (32, 32) and np.all(np.isfinite(speed))
    # Momentum enters by viscous diffusion from the sliding top wall (and the pressure it builds):
    # after 0.05 s the diffusion length sqrt(nu t) is 2.2 cm, so the top row moves and the bottom
    # row, 1 m away, barely does.
    assert speed[:, -1].mean() > 0.1
    assert speed[:, 0].mean() < 0.1 * speed[:, -1].mean()


def test_resume_of_a_scene_with_a_fluid_is_bit_for_bit(tmp_path):
    path = EXAMPLES / "sph_dam_break.toml"
    straight = load_scene(path)
    for _ in range(6):
        straight.step()
    save_checkpoint(tmp_path / "c.npz", straight.save_state(), {"fingerprint": "x"})
    for _ in range(6):
        straight.step()
    resumed = load_scene(path)
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed.restore_state(state)
    for _ in range(6):
        resumed.step()
    a, b = straight.fluids["water"].save_state(), resumed.fluids["water"].save_state()
    assert sorted(a) == sorted(b)
    for key in a:
        assert np.array_equal(np.asarray(a[key]), np.asarray(b[key])), key


def test_an_interrupted_run_resumes_to_the_same_fluid_frames(tmp_path):
    # The user's path (`inertia run`, Ctrl-C, `inertia run --resume`): the state file records the
    # fluid's frames as fields fluid/water/<key>, and the resumed run's equal the straight run's.
    from inertia.io.states import load_states
    from inertia.world import Run

    path = EXAMPLES / "sph_dam_break.toml"

    def run(out, **kw):
        world = load_scene(path, duration=0.1, fps=50)
        return Run(world, out, duration=0.1, fps=50, fingerprint="dam", handle_sigint=False,
                   checkpoint_interval=0.0, **kw).execute()

    run(tmp_path / "straight")
    run(tmp_path / "cut", stop_after_frames=3)
    run(tmp_path / "cut", resume=True)
    a, b = load_states(tmp_path / "straight" / "states"), load_states(tmp_path / "cut" / "states")
    assert a.fields["fluid/water/x"].shape == (6, 200, 2)
    for key in ("x", "v", "active"):
        assert np.array_equal(a.fields[f"fluid/water/{key}"], b.fields[f"fluid/water/{key}"]), key
    assert not np.array_equal(a.fields["fluid/water/x"][0], a.fields["fluid/water/x"][-1])
