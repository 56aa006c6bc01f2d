"""Fluids: MAC-grid Navier-Stokes (`inertia.fluids.grid`) and smoothed particle hydrodynamics
(`inertia.fluids.sph`). Each solver owns its grids or particle arrays; solid shapes enter as
boundary conditions (see docs/architecture.md)."""
