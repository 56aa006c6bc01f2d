"""Inertia: physically based simulation for games and computer graphics.

The user's loop::

    import numpy as np
    import inertia as ia

    ps = ia.ParticleSystem(positions=np.zeros((100, 3)))
    ps.add_force(ia.forces.Gravity((0, 0, -9.81)))
    sim = ia.Simulation(ps, integrator="rk4", dt=1e-3)
    sim.run(2.0)
    ps.x, ps.v   # (N, D) views of the state
"""

from __future__ import annotations

__version__ = "0.2.0"

from . import forces, integrators
from .errors import SimulationDiverged
from .particles.emitters import BoxSource, Cone, DiskSource, Emitter, PointSource, SphereSource
from .particles.system import ParticleSystem
from .particles.tracers import Tracers
from .simulation import Simulation, SimulationState

__all__ = [
    "ParticleSystem", "Tracers", "Simulation", "SimulationState", "SimulationDiverged",
    "Emitter", "PointSource", "BoxSource", "SphereSource", "DiskSource", "Cone",
    "forces", "integrators", "sweep", "colliders", "fields", "load_scene", "load_states", "World",
    "__version__",
]


def load_scene(path, **overrides):
    """Read, validate and build a scene file (TOML or JSON) into a `World` (see `inertia.scene`)."""
    from .scene import load_scene as _load_scene
    return _load_scene(path, **overrides)


def load_states(path, **options):
    """Read a state file written by a run (see `inertia.io`)."""
    from .io import load_states as _load_states
    return _load_states(path, **options)


def __getattr__(name):
    # Layers built on the core are imported on first use, so `import inertia` stays light.
    if name == "World":
        from .world import World
        return World
    if name in ("ModelBuilder", "Model", "State", "Control"):
        from . import model
        return getattr(model, name)
    if name in ("RigidWorld", "FreeBodies", "WorldQueries", "RaycastVehicle"):
        from . import rigid
        return getattr(rigid, name)
    if name in ("colliders", "fields", "render", "io", "viewer", "scene", "world", "sweep", "math", "geometry",
                "dynamics", "rigid", "model", "fluids"):
        import importlib
        module = importlib.import_module(f".{name}", __name__)
        globals()[name] = module
        return module
    raise AttributeError(f"module 'inertia' has no attribute {name!r}")
