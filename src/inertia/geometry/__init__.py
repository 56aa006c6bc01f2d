"""Geometry: the shape table, support functions, mass properties, broad and narrow phase, scene
queries (see docs/architecture.md and docs/rigid.md).

Modules: ``shapes`` (type codes), ``broadphase`` (swept AABBs, sort-and-sweep), ``narrowphase``
(closed-form manifolds, warm-start matching).
"""
