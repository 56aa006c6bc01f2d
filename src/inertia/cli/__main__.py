"""``python -m inertia.cli`` runs the `inertia` command."""

from .main import app

app(prog_name="inertia")
