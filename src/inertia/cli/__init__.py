"""The `inertia` command line (typer + rich): see `inertia.cli.main`."""

from .main import app

__all__ = ["app"]
