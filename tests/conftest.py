import os

# Tests must not depend on a display.
os.environ.setdefault("MPLBACKEND", "Agg")

# The suite runs in one worker process per core (pytest-xdist, the README's test command), and each
# worker's parallel kernels start their own OpenMP threads: waiting threads sleep instead of spinning,
# so two workers on two cores do not take turns burning each other's time. Read when Numba first
# loads its OpenMP pool, which happens after this file.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
