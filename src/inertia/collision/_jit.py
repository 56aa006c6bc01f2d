"""Re-export of the shared serial-twin helpers (see `inertia._jit`)."""

from .._jit import SERIAL_BELOW, pick, serial_twin  # noqa: F401
