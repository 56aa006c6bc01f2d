"""``inertia sweep``: run many variants of a scene on dask.distributed and tabulate their metrics.

    inertia sweep SCENE --param KEY=VALUES ... [--metric NAME[=EXPR] ...] [--samples N --seed S]
                  [--design grid|random|lhs] [--scheduler ADDRESS] [--workers N] [--out DIR] [--resume]
                  [--outputs scene,states,plot,mp4,gif] [--max-variants N]

Registered on the `inertia` app by `register` (called from `inertia.cli.main`); the engine is
`inertia.sweep`. Exit codes as ``inertia run``: 0 done (failed variants are rows, not failures
of the sweep), 2 bad input (unknown key path, wrong value type, empty range, too many variants,
unreachable scheduler, missing ``sweep`` extra), 130 interrupted (``--resume`` continues).
"""

# no `from __future__ import annotations`: typer reads the annotations of the nested command
from pathlib import Path
from typing import Annotated, Optional

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add the ``sweep`` command to the `inertia` typer app."""
    from rich.progress import BarColumn, Progress, ProgressColumn, TextColumn
    from rich.table import Table
    from rich.text import Text

    from .main import EXIT_INTERRUPTED, DebugOption, InputError, console, handle_errors, out_console, resolve_scene

    class _Counts(ProgressColumn):
        def render(self, task):
            f = task.fields
            eta = f.get("eta")
            eta_text = "--:--" if eta is None else f"{int(eta // 60):d}:{int(eta % 60):02d}"
            return Text(f"{int(task.completed)}/{int(task.total)} done  {f.get('running', 0)} running  "
                        f"{f.get('failed', 0)} failed  ETA {eta_text}")

    @app.command("sweep")
    @handle_errors
    def sweep_command(
        scene: Annotated[str, typer.Argument(help="Scene file (.toml/.json) or a bundled example name.")],
        param: Annotated[Optional[list[str]], typer.Option(
            "--param", "-p", metavar="KEY=VALUES",
            help="A swept scene key and its values: a,b,c | lo:hi:N | lo:hi:N:log10 | lo:hi[:log10] (with --samples) "
                 "| a JSON list. Repeat for more keys.")] = None,
        metric: Annotated[Optional[list[str]], typer.Option(
            "--metric", "-m", metavar="NAME[=EXPR]",
            help="A built-in metric (final_energy, time_to_rest, max_penetration, max_speed, max_height, "
                 "energy_change, final_kinetic_energy) or NAME=EXPR, e.g. 'zmax=peak(max(z))'. Repeat for more.")] = None,
        samples: Annotated[Optional[int], typer.Option(help="Variants of a random or Latin-hypercube design.")] = None,
        design: Annotated[Optional[str], typer.Option(help="grid (default), random or lhs (default with --samples).")] = None,
        seed: Annotated[Optional[int], typer.Option(help="Sweep seed: design draws and per-variant seeds (default: the scene's).")] = None,
        scheduler: Annotated[Optional[str], typer.Option(help="Address of a running dask scheduler (default: a local cluster).")] = None,
        workers: Annotated[Optional[int], typer.Option(help="Local worker processes (default: one per core).")] = None,
        connect_timeout: Annotated[float, typer.Option(help="Seconds to reach --scheduler.")] = 10.0,
        out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Output folder (default: out/NAME-sweep).")] = None,
        resume: Annotated[bool, typer.Option("--resume", help="Continue the sweep in --out, skipping finished variants.")] = False,
        overwrite: Annotated[bool, typer.Option("--overwrite", "-f", help="Replace a sweep already in --out.")] = False,
        outputs: Annotated[str, typer.Option(help="Per-variant heavy outputs, comma separated: scene, states, plot, mp4, gif "
                                                  "(into OUT/variants/NNNNN/).")] = "",
        max_variants: Annotated[int, typer.Option(help="Refuse designs with more variants than this.")] = 10_000,
        dashboard: Annotated[bool, typer.Option("--dashboard/--no-dashboard", help="Serve the dask dashboard (local cluster).")] = True,
        quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
        debug: DebugOption = False,
        stop_after: Annotated[Optional[int], typer.Option(hidden=True, help="Stop after N variants (tests).")] = None,
    ):
        """Run variants of a scene over a grid, random or Latin-hypercube design; tabulate their metrics."""
        from inertia.sweep import SweepInputError, SweepInterrupted, sweep

        from .main import _resolve_out_dir

        # (the sweep checks its dependencies itself, once the design's size is known: a design
        # refused for its size needs none of them)
        path = resolve_scene(scene)
        if out is None:
            from inertia.scene import read_scene
            out = Path("out") / f"{read_scene(path).name}-sweep"
        out = _resolve_out_dir(out, from_scene=False)
        kinds = [k.strip() for k in outputs.split(",") if k.strip()]
        shown = {"link": False}
        bar = Progress(TextColumn("[bold]sweep"), BarColumn(), _Counts(), console=console, disable=quiet)

        def report(p):
            if p.dashboard and not shown["link"] and not quiet:
                console.print(f"dask dashboard: {p.dashboard}")
                shown["link"] = True
            if not shown.get("task"):
                shown["task"] = bar.add_task("sweep", total=p.total)
            bar.update(shown["task"], completed=p.completed, total=p.total, running=p.running, failed=p.failed, eta=p.eta)

        try:
            with bar:
                frame = sweep(path, param or [], metric or None, samples=samples, design=design, seed=seed,
                              scheduler=scheduler, workers=workers, connect_timeout=connect_timeout, out=out,
                              resume=resume, overwrite=overwrite, outputs=kinds, max_variants=max_variants,
                              dashboard=dashboard and not quiet, progress=report, stop_after=stop_after)
        except SweepInputError as exc:
            raise InputError(str(exc)) from None
        except SweepInterrupted as exc:
            console.print(f"[yellow]stopped[/]: {exc}")
            raise typer.Exit(EXIT_INTERRUPTED) from None
        failed = frame[frame["status"] != "completed"]
        if not quiet:
            table = Table(title=f"{len(frame)} variants ({frame.attrs['computed']} run now, "
                                f"{frame.attrs['skipped']} from before) in {frame.attrs['seconds']:.1f} s",
                          header_style="bold")
            table.add_column("output")
            table.add_column("path")
            for kind, name in (("table", "results.parquet"), ("csv", "results.csv"), ("plot", "summary.png"),
                               ("journal", "journal.jsonl")):
                if (out / name).exists():
                    table.add_row(kind, str(out / name))
            console.print(table)
        for _, row in failed.head(5).iterrows():
            console.print(f"[yellow]variant {row['variant']} {row['status']}[/]: {row['error'].splitlines()[0] if row['error'] else ''}")
        if len(failed):
            console.print(f"[yellow]{len(failed)} of {len(frame)} variants did not complete[/] (status and error in the table)")
        out_console.print(str(out / "results.parquet"))
