"""`inertia warmup`: compile the Numba kernels ahead of time by running tiny scenes.

Every kernel is ``@njit(cache=True)``, so compiling once fills the on-disk cache (beside the
sources, or under ``NUMBA_CACHE_DIR``) and later runs start warm. First every bundled example
runs for two frames and renders one (what `inertia run NAME` compiles, render kernels
included); then the scenes below touch every integrator, force, emitter, tracer field and
collider type for a few steps, in 2-D and 3-D, and the collision kernels of every collider kind
set (``particle_kernels.kernels_for``), fused into rk4 and separate; last the render kernels of
meshes, lines and every collider primitive (``inertia.render.warm_kernels``).

Limitations: kernels have a serial and a parallel build (``inertia._jit``); tiny scenes compile
the serial builds only, so the first run of a scene above ``inertia._jit.SERIAL_BELOW``
elements (or a frame above 600,000 pixels) still compiles the parallel ones.
"""

from __future__ import annotations

import contextlib
import tempfile
from typing import Callable


__all__ = ["warm_all", "WARM_SCENES", "compile_notice", "COMPILING"]

#: What the progress bars say while Numba compiles (a cold on-disk cache).
COMPILING = "compiling kernels (first run only)"


@contextlib.contextmanager
def compile_notice(on_start: Callable[[], None], on_end: Callable[[], None] | None = None):
    """Call ``on_start()`` when Numba starts compiling and ``on_end()`` when it is done.

    Listens to Numba's ``numba:compile`` event, which fires only on a cache miss (a kernel
    loaded from the on-disk cache raises none), so a warm run says nothing. Nested compiles
    (a kernel compiling the functions it calls) count once.
    """
    from numba.core import event

    depth = 0

    class _Listener(event.Listener):
        def on_start(self, ev):
            nonlocal depth
            depth += 1
            if depth == 1:
                on_start()

        def on_end(self, ev):
            nonlocal depth
            depth -= 1
            if depth == 0 and on_end is not None:
                on_end()

    with event.install_listener("numba:compile", _Listener()):
        yield


def _base(dim: int, integrator: str, **extra) -> dict:
    sim = {"dim": dim, "dt": 0.001, "duration": 0.004, "fps": 500.0, "integrator": integrator}
    sim.update(extra)
    return {"format_version": 1, "simulation": sim}


def _springy(dim: int, integrator: str) -> dict:
    scene = _base(dim, integrator)
    zero = [0.0] * dim
    origin = [0.0] * (dim - 1) + [1.0]
    scene["particles"] = [
        {"name": "chain", "mass": 0.1, "radius": 0.01,
         "chain": {"start": origin, "end": [0.5] + origin[1:], "count": 4, "stiffness": 50.0, "damping": 0.1}},
        {"name": "free", "lattice": {"origin": zero, "counts": [2] * dim, "spacing": 0.1}},
    ]
    scene["forces"] = [
        {"type": "gravity"}, {"type": "drag", "coefficient": 0.01}, {"type": "quadratic_drag", "coefficient": 0.01},
        {"type": "attractor", "center": origin, "strength": 0.1, "groups": ["chain"]},
        {"type": "wind", "velocity": [1.0] + zero[1:], "coefficient": 0.01, "gust_amplitude": 0.5, "groups": ["chain"]},
        {"type": "anchor_springs", "indices": [1], "anchors": origin, "stiffness": 1.0, "groups": ["chain"]},
    ]
    return scene


def _affine(dim: int, integrator: str) -> dict:
    scene = _base(dim, integrator)
    scene["particles"] = [{"random": {"count": 8, "center": [0.0] * dim, "half_extents": [1.0] * dim}}]
    scene["forces"] = [{"type": "gravity"}, {"type": "drag", "coefficient": 0.1}]
    return scene


def _emitter(dim: int) -> dict:
    scene = _base(dim, "semi_implicit_euler")
    up = [0.0] * (dim - 1) + [1.0]
    scene["particles"] = [{"emitters": [{"rate": 2000.0, "source": {"type": "sphere", "center": [0.0] * dim, "radius": 0.1},
                                         "cone": {"direction": up, "speed": 1.0, "spread": 0.3}, "lifetime": [0.001, 0.003]}]}]
    scene["forces"] = [{"type": "gravity"}]
    return scene


def _tracers(dim: int, integrator: str) -> dict:
    scene = _base(dim, integrator)
    scene["fields"] = {"spin": {"type": "rotation", "center": [0.0] * dim},
                       "noise": {"type": "curl_noise", "frequency": 1.0}}
    scene["tracers"] = [{"field": "spin", "positions": [[1.0] + [0.0] * (dim - 1)]},
                        {"field": "noise", "positions": [[0.5] * dim]}]
    return scene


def _colliders(dim: int, mode: str, moving: bool = True) -> dict:
    scene = _base(dim, "semi_implicit_euler")
    zero = [0.0] * dim
    up = [0.0] * (dim - 1) + [1.0]
    scene["particles"] = [{"radius": 0.05, "self_collisions": True, "collision_mode": mode, "restitution": 0.5,
                           "lattice": {"origin": [0.0] * (dim - 1) + [0.2], "counts": [2] * dim, "spacing": 0.12},
                           "velocity": [0.0] * (dim - 1) + [-50.0]}]
    scene["forces"] = [{"type": "gravity"}]
    colliders = [{"type": "plane", "point": zero, "normal": up},
                 {"type": "sphere", "center": [2.0] + zero[1:], "radius": 0.3},
                 {"type": "box", "center": [-2.0] + zero[1:], "half_extents": [0.3] * dim,
                  **({"motion": {"velocity": [0.1] + zero[1:]}} if moving else {})},
                 {"type": "capsule", "a": [0.0, 2.0] + zero[2:], "b": [0.5, 2.0] + zero[2:], "radius": 0.1},
                 {"type": "container", "center": zero, "half_extents": [5.0] * dim}]
    if dim == 3:
        colliders.append({"type": "cylinder", "center": [0.0, -2.0, 0.0], "radius": 0.2, "half_height": 0.3})
    scene["colliders"] = colliders
    return scene


def _fused_colliders(kinds: str) -> dict:
    """Static colliders with affine forces under rk4: the collision pass fused into the
    integrator's kernel (``particle_kernels.step_and_collide``), for each kind set
    (``particle_kernels.kernels_for``): "planes" (a ground only), "light" (planes, spheres,
    containers) or "all" (every kind); some particles start inside the sphere (the first
    step's push-out)."""
    scene = _base(3, "rk4")
    scene["particles"] = [{"radius": 0.05, "restitution": 0.5,
                           "lattice": {"origin": [-0.3, -0.3, 0.1], "counts": [3, 3, 3], "spacing": 0.3},
                           "velocity": [0.0, 0.0, -50.0]}]
    scene["forces"] = [{"type": "gravity"}]
    colliders = [{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}]
    if kinds != "planes":
        colliders.append({"type": "sphere", "center": [0.0, 0.0, 0.4], "radius": 0.2})
    if kinds == "light":
        colliders.append({"type": "container", "center": [0.0, 0.0, 0.0], "half_extents": [5.0, 5.0, 5.0]})
    elif kinds == "all":
        colliders.append({"type": "box", "center": [2.0, 0.0, 0.0], "half_extents": [0.3, 0.3, 0.3]})
    scene["colliders"] = colliders
    return scene


def _scenes():
    from inertia.ode.integrators import available

    scenes = []
    for dim in (3, 2):
        for name in available():
            scenes.append((f"{dim}-D springs, {name}", _springy(dim, name)))
        for name in ("semi_implicit_euler", "rk4", "verlet"):
            scenes.append((f"{dim}-D fast path, {name}", _affine(dim, name)))
        scenes.append((f"{dim}-D emitter", _emitter(dim)))
        for name in ("euler", "midpoint", "rk4", "rk45"):
            scenes.append((f"{dim}-D tracers, {name}", _tracers(dim, name)))
        for mode in ("a_priori", "a_posteriori"):
            scenes.append((f"{dim}-D colliders, {mode}", _colliders(dim, mode)))
            scenes.append((f"{dim}-D static colliders, {mode}", _colliders(dim, mode, moving=False)))
    # the fused collision kernels of every kind set (the same compiled code in 2-D and 3-D)
    scenes.append(("3-D fused colliders, planes", _fused_colliders("planes")))
    scenes.append(("3-D fused colliders, planes/spheres/containers", _fused_colliders("light")))
    scenes.append(("3-D fused colliders, every kind", _fused_colliders("all")))
    return scenes


def _examples():
    """The bundled examples, cut to their first 2 s recorded as two frames: the kernels
    `inertia run NAME` compiles (2 s, so that falling particles reach the ground and the
    contact kernels that only run then are compiled too)."""
    import tomllib

    from .main import bundled_examples

    scenes = []
    for name, path in bundled_examples().items():
        data = tomllib.loads(path.read_text())
        sim = data.setdefault("simulation", {})
        sim["duration"] = min(float(sim.get("duration", 2.0)), 2.0)
        sim["fps"] = 2.0 / sim["duration"]
        data.pop("output", None)
        scenes.append((f"example {name}", data))
    return scenes


WARM_SCENES = _scenes


def _run_scene(data: dict, render: bool) -> None:
    """Run a scene for its (short) duration; render its last frame small and plot its energy.

    The frame goes through the same renderer path as `inertia run` (``render_frames``) with the
    scene's own [render] table, so colour modes and collider primitives match; a small frame
    runs the same (serial) builds as the default 960 x 540 video.
    """
    from inertia.io import load_states
    from inertia.scene import build, parse_scene
    from inertia.world import Run

    import json

    scene = parse_scene(json.dumps(data), format="json", source="<warmup>")
    world = build(scene)
    with tempfile.TemporaryDirectory(prefix="inertia-warmup-") as tmp:
        result = Run(world, tmp, duration=world.duration, fps=world.fps, handle_sigint=False).execute()
        if render:
            from .outputs import plot_energy, render_frames

            states = load_states(result.states_path)
            table = {**data.get("render", {}), "width": 64, "height": 48}
            for _ in render_frames(states, table, world.colliders, frames=[states.frame_count - 1]):
                pass
            plot_energy(states, f"{tmp}/energy.png")


def warm_all(report: Callable[[str], None] | None = None, *, only: str | None = None) -> list[str]:
    """Run every warm-up scene (or those whose name contains `only`); returns their names.

    Raises RuntimeError listing the failures after trying all.
    """
    done, failures = [], []
    for i, (name, data) in enumerate(_examples() + _scenes()):
        if only is not None and only not in name:
            continue
        if report is not None:
            report(name)
        try:
            _run_scene(data, render=name.startswith("example") or name.endswith(("a_priori", "rk4")) or i == 0)
            done.append(name)
        except Exception as exc:  # noqa: BLE001 - keep compiling the rest, then report
            failures.append(f"{name}: {type(exc).__name__}: {exc}")
    if only is None or only in "render":
        # Meshes (bodies, cloth surfaces), lines and every collider primitive: what a scene with
        # rigid bodies draws, which the particle examples above do not reach.
        if report is not None:
            report("render")
        try:
            from ..render import warm_kernels

            warm_kernels()
            done.append("render")
        except Exception as exc:  # noqa: BLE001
            failures.append(f"render: {type(exc).__name__}: {exc}")
    if failures:
        raise RuntimeError("warm-up scenes failed:\n  " + "\n  ".join(failures))
    return done


def compile_notice_on(bar, task, label: str):
    """`compile_notice` for a rich progress bar: while Numba compiles, the task's description
    reads ``COMPILING`` (and the line is printed once, so logs show it too); then ``label``."""
    said = []

    def start():
        bar.update(task, description=COMPILING)
        if not said and not getattr(bar, "disable", False):
            said.append(True)
            bar.console.print(f"[dim]{COMPILING}...[/]")

    return compile_notice(start, lambda: bar.update(task, description=label))
