"""The collision layer: shapes, signed distance, time of impact, broad phase, response.

Modules
-------
``shapes``            collider classes (public through ``inertia.colliders``)
``motion``            rigid poses and kinematic motion (``Motion``)
``distance``          signed distance kernels of every shape (Numba)
``mesh``              triangle meshes: loading, baked signed distance field, triangle grid
``toi``               time of impact along a step's straight path (continuous detection)
``response``          restitution / Coulomb friction responses, pair impulses
``broadphase``        uniform grid in a spatial hash, pair lists, colouring
``particle_kernels``  the particle stage's kernels
``particle_stage``    the particle collision stage, resting-contact force filter, entry points

Shared by the later layers (cloth, fluids, rigid bodies): a collider is queried through
``signed_distance`` / ``normal`` / ``velocity`` / ``query`` (docs/contracts.md), and its packed form
(``kind``, ``_cf``, ``_ci``, pose) feeds the compiled kernels.

References and limitations are in each module's docstring.
"""

from __future__ import annotations
