"""Particle systems, force objects, tracers and emitters."""
