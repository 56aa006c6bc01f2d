"""Dynamics: the shared contact buffer, constraint graph colouring, islands and sleeping, the
soft-step contact and joint solver (see docs/architecture.md)."""
