import os

# Tests must not depend on a display.
os.environ.setdefault("MPLBACKEND", "Agg")
