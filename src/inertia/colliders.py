"""Colliders for particles (and, later, cloth, fluids and rigid bodies).

    import inertia as ia
    ps.add_collider(ia.colliders.Plane(point=(0, 0, 0), normal=(0, 0, 1)), restitution=0.5, friction=0.3)
    ps.add_collider(ia.colliders.Sphere(center=(0, 0, 1), radius=0.5))
    ps.collision_mode = "a_priori"        # or "a_posteriori"
    ps.self_collisions = True             # particles with a radius collide with each other

Shapes: ``Plane``, ``Sphere``, ``Box``, ``Capsule``, ``Cylinder`` (3-D), ``Container`` (particles
inside), ``Mesh`` (3-D, OBJ/STL/PLY via ``pip install inertia[mesh]``, or vertex/face arrays),
``SDF`` (a user signed distance function). Each answers ``signed_distance``, ``normal``,
``velocity`` and ``query`` for many points at once. ``Motion`` makes a collider kinematic.
``configure_contacts(system, ...)`` sets contact tolerances and the particle-particle options.
See ``inertia.collision`` for the algorithms, references and limitations.
"""

from __future__ import annotations

from .collision.mesh import Mesh
from .collision.motion import Motion, as_rotation
from .collision.particle_stage import COLLISION_MODES, configure_contacts
from .collision.shapes import SDF, Box, Capsule, Collider, Container, Cylinder, Plane, Sphere

__all__ = ["Collider", "Plane", "Sphere", "Box", "Capsule", "Cylinder", "Container", "Mesh", "SDF",
           "Motion", "as_rotation", "configure_contacts", "COLLISION_MODES"]
