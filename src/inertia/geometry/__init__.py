"""Geometry: the shape table, support functions, mass properties, broad and narrow phase, scene
queries (see docs/architecture.md)."""
