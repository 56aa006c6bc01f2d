"""Rigid bodies: builders, free-body motion, materials (see docs/architecture.md)."""
