"""Time integrators, selectable by name: ``inertia.integrators.available()``."""

from .ode.integrators import Integrator, available, create, register

__all__ = ["Integrator", "available", "create", "register"]
