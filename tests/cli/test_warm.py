"""`inertia warmup` helpers (src/inertia/cli/warm.py): the compile notice and the scene list."""

import numpy as np
from numba import njit

from inertia.cli import warm


def test_compile_notice_fires_once_per_compile_and_not_when_compiled():
    events = []

    def add_one(x):
        return x + 1.0

    def twice(x):
        return 2.0 * inner(x)

    inner = njit(add_one)
    kernel = njit(twice)  # compiling it compiles `inner` inside: one notice, not two
    with warm.compile_notice(lambda: events.append("start"), lambda: events.append("end")):
        assert kernel(np.float64(1.0)) == 4.0
        assert events == ["start", "end"]
        kernel(np.float64(2.0))  # compiled: no event
    assert events == ["start", "end"]
    kernel(np.int64(3))  # a new signature outside the context: not reported
    assert events == ["start", "end"]


def test_warmup_covers_every_bundled_example_and_renders_it():
    from inertia.cli.main import bundled_examples

    names = [name for name, _ in warm._examples()]
    assert names == [f"example {n}" for n in bundled_examples()]
    for _, data in warm._examples():
        sim = data["simulation"]
        assert abs(sim["duration"] * sim["fps"] - 2.0) < 1e-9  # two frames each
        assert sim["duration"] == 2.0  # long enough for falling particles to land


def test_warmup_covers_the_fused_collision_kernels_of_every_kind_set():
    # `inertia run` compiles the collision kernels per collider kind set
    # (particle_kernels.kernels_for): the warm-up scenes fuse the collision pass into rk4 for both
    import json

    from inertia.collision import particle_kernels as pk
    from inertia.scene import build, parse_scene

    kinds = set()
    for name, data in warm._scenes():
        if "fused colliders" not in name:
            continue
        world = build(parse_scene(json.dumps(data), format="json", source=name))
        for group in world.groups:
            d = group.system._collision
            assert group.integrator == "rk4" and d.can_fuse() and group.system._affine_terms() is not None
            kinds.add(pk.kernels_for(d.cint).kinds)
    assert kinds == {pk.PLANE_KINDS, pk.LIGHT_KINDS, pk.ALL_KINDS}


def test_warmup_covers_the_closed_form_narrow_phase_of_every_shape_type_set():
    # A rigid world compiles the closed-form pair routines of its shape types only
    # (narrowphase.closed_token, three nested sets): the bundled examples meet all three, so
    # `inertia warmup` leaves no closed-form narrow phase to compile on a later first run.
    import json

    from inertia.geometry.narrowphase import CLOSED_TYPE_SETS, closed_token
    from inertia.scene import build, parse_scene

    tokens = set()
    for name, data in warm._examples():
        if "bodies" not in data:
            continue
        world = build(parse_scene(json.dumps(data), format="json", source=name))
        tokens.add(world.rigid._closed)
    assert tokens == {closed_token(sorted(types)) for types in CLOSED_TYPE_SETS}


def test_warmup_ends_with_the_render_kernels_of_meshes_and_lines(monkeypatch):
    # bodies, cloth surfaces and spring lines are drawn by kernels the particle examples never
    # reach: warm_all calls inertia.render.warm_kernels once (here replaced by a recorder)
    import inertia.render

    calls = []
    monkeypatch.setattr(inertia.render, "warm_kernels", lambda: calls.append(1) or 0.0)
    assert warm.warm_all(only="render") == ["render"]
    assert calls == [1]
