"""Regenerate the shipped JSON Schema: ``python -m inertia.scene.schema [PATH]``."""

import sys

from . import SCHEMA_PATH, write_schema

if __name__ == "__main__":
    print(write_schema(sys.argv[1] if len(sys.argv) > 1 else SCHEMA_PATH))
