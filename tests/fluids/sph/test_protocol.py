"""The World protocol of SPHFluid: advance, save_state/restore_state (bit for bit), frame_arrays,
static_arrays."""

import numpy as np
import pytest

from inertia.fluids.sph import SPHFluid, sample_block
from inertia.model import ModelBuilder
from inertia.rigid.world import RigidWorld


def _scene():
    # thin 3-D slab with an emitter, an outflow and a free rigid box: every piece of state is used
    dx = 0.025
    x = sample_block((0.0, 0.0, 0.0), (0.3, 0.15, 0.15), dx)
    fluid = SPHFluid(x, spacing=dx, domain=((0, 0, 0), (0.6, 0.15, 0.4)), periodic=(False, True, False),
                     viscosity=1e-3, xsph=0.02, capacity=x.shape[0] + 400)
    fluid.add_emitter(center=(0.1, 0.075, 0.3), velocity=(0.5, 0.0, 0.0), width=0.05)
    fluid.add_outflow((0.55, 0.0, 0.0), (0.6, 0.15, 0.4))
    b = ModelBuilder(gravity=(0, 0, -9.81))
    b.add_plane((0, 0, 1), 0.0)
    b.add_plane((1, 0, 0), 0.0)
    b.add_plane((-1, 0, 0), -0.6)
    body = b.add_body(position=(0.45, 0.075, 0.1))
    b.add_box(body, half_extents=(0.05, 0.075, 0.05), density=600.0)
    rigid = RigidWorld(b.finalize(), dt=1 / 200, substeps=2)
    return fluid, rigid


def _run(fluid, rigid, steps):
    for _ in range(steps):
        rigid.step()
        fluid.advance(rigid.dt, rigid)


def _digest(fluid, rigid):
    return (fluid.x.tobytes(), fluid.v.tobytes(), fluid.particle_id.tobytes(), rigid.state.body_q.tobytes(),
            fluid.time)


def test_save_restore_continues_bit_for_bit():
    fluid, rigid = _scene()
    _run(fluid, rigid, 10)
    saved, rigid_saved = fluid.save_state(), rigid.save()
    _run(fluid, rigid, 10)
    reference = _digest(fluid, rigid)
    fresh, fresh_rigid = _scene()
    fresh_rigid.restore(rigid_saved)
    fresh.restore_state(saved)
    _run(fresh, fresh_rigid, 10)
    assert _digest(fresh, fresh_rigid) == reference
    assert fresh.particle_count > 0 and fluid.stats.get("emitter_dropped", 0) == 0


def test_restore_names_the_bad_key():
    fluid, _ = _scene()
    state = fluid.save_state()
    del state["fluid_x"]
    with pytest.raises(ValueError, match="fluid_x"):
        fluid.restore_state(state)
    state = fluid.save_state()
    state["fluid_v"] = state["fluid_v"][:5]
    with pytest.raises(ValueError, match="fluid_v"):
        fluid.restore_state(state)


def test_frame_and_static_arrays_have_fixed_shapes():
    fluid, rigid = _scene()
    shapes = None
    for _ in range(3):
        _run(fluid, rigid, 5)
        frame = fluid.frame_arrays()
        now = {k: (v.shape, v.dtype) for k, v in frame.items()}
        assert shapes is None or now == shapes
        shapes = now
        assert frame["active"].sum() == fluid.particle_count
        assert np.array_equal(frame["x"][frame["active"]], fluid.x.astype(np.float32))
    static = fluid.static_arrays()
    assert static["domain"].shape == (2, 3) and static["boundary_x"].shape[1] == 3
    assert frame["x"].shape == (fluid.capacity, 3)


def test_advance_covers_the_world_step_exactly():
    # advance(dt) splits dt into equal fluid steps no longer than the fluid's own limit (here the
    # fixed dt_max 2 ms): 0.005 s -> 3 steps of 1.667 ms; the clock ends at the frame time.
    fluid = SPHFluid(sample_block((0.0, 0.0), (0.2, 0.2), 0.02), spacing=0.02, domain=((0, 0), (1, 1)), dt_max=0.002)
    assert fluid.advance(0.005) == 3
    assert abs(fluid.time - 0.005) < 1e-15 and abs(fluid.last_dt - 0.005 / 3) < 1e-15
    with pytest.raises(ValueError, match="dt"):
        fluid.advance(-1.0)


def test_2d_fluid_with_rigid_bodies_is_refused_when_added_to_a_world():
    # Rigid bodies are 3-D; a 2-D fluid cannot couple with them through the World. The
    # combination is refused by World.add_fluid (at construction, not in the first step), naming
    # the 3-D slab alternative; a 2-D fluid in a world without bodies is accepted.
    from inertia.world import World
    x = sample_block((0.0, 0.0), (0.1, 0.1), 0.02)
    fluid = SPHFluid(x, spacing=0.02, domain=((0, 0), (0.4, 0.4)))
    b = ModelBuilder(gravity=(0, 0, -9.81))
    b.add_plane((0, 0, 1), 0.0)
    body = b.add_body(position=(0.0, 0.0, 0.5))
    b.add_box(body, half_extents=(0.05, 0.05, 0.05), density=600.0)
    world = World(dt=1 / 100, model=b.finalize())
    with pytest.raises(ValueError, match="2-D SPH fluid cannot join a World with rigid bodies.*3-D slab"):
        world.add_fluid("water", fluid)
    assert "water" not in world.fluids
    with pytest.raises(ValueError, match="2-D SPH fluid"):   # the direct protocol call says the same
        fluid.advance(0.01, world.rigid)
    World(dt=1 / 100).add_fluid("water", fluid)
