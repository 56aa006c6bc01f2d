"""Phase-space systems and their time integrators."""
