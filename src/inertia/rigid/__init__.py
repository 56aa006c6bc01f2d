"""Rigid bodies: the rigid step, free-body motion, scene queries, vehicles (see docs/rigid.md).

Public: `RigidWorld` (the rigid step, standalone until it merges with ``inertia.world.World``),
`FreeBodies` (free bodies under the nine-integrator phase-space interface), `WorldQueries` (ray cast,
shape cast, overlap, closest points, AABB query), `RaycastVehicle` and `Wheel`.
The Model / State / Control / builder live in `inertia.model`.
"""

from .free_body import FreeBodies
from .queries import ClosestPoints, RayHit, ShapeHit, WorldQueries
from .vehicle import RaycastVehicle, Wheel
from .world import RigidWorld

__all__ = ["RigidWorld", "FreeBodies", "WorldQueries", "RayHit", "ShapeHit", "ClosestPoints", "RaycastVehicle",
           "Wheel"]
