"""``python -m inertia`` runs the `inertia` command (the same as the console script)."""

from inertia.cli.main import app

app(prog_name="inertia")
