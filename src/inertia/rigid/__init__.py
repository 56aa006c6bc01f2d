"""Rigid bodies: builders, free-body motion, materials (see docs/architecture.md and docs/rigid.md).

Public: `RigidWorld` (the rigid step, standalone until it merges with ``inertia.world.World``).
The Model / State / Control / builder live in `inertia.model`.
"""

from .world import RigidWorld

__all__ = ["RigidWorld"]
