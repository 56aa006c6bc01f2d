"""Force objects for particle systems; see `inertia.particles.forces` for the protocol."""

from .particles.forces import (AnchorSprings, Attractor, Drag, Force, ForceField, Gravity,
                               GridForceField, QuadraticDrag, Springs, Wind)

__all__ = ["Force", "Gravity", "Drag", "QuadraticDrag", "Springs", "AnchorSprings", "ForceField",
           "GridForceField", "Wind", "Attractor"]
