"""Dynamics: the shared contact buffer, constraint graph colouring, islands and sleeping, the
soft-step contact and joint solver (see docs/architecture.md and docs/rigid.md).

Modules: ``contacts`` (`Contacts`), ``solver`` (soft step, colouring), ``islands`` (sleep, wake).
"""

from .contacts import Contacts

__all__ = ["Contacts"]
