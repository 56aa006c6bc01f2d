"""The sweep table: rows in a journal, Parquet + CSV written atomically, and the summary plot.

Files in a sweep's output folder:

- ``sweep.json``     what was asked (scene hash, parameters, design, seed, metrics); a resume
                     must ask the same;
- ``journal.jsonl``  one JSON row per finished variant, appended (and flushed) as results
                     arrive; the source of truth for resuming (a torn last line is ignored,
                     a variant seen twice keeps its last row);
- ``results.parquet``, ``results.csv``  the table, one row per variant sorted by ``variant``,
                     rewritten atomically (temporary file + rename) every few seconds and at
                     the end;
- ``summary.png``    every metric against every parameter.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

__all__ = ["Journal", "rows_to_frame", "write_table", "plot_summary", "SPEC_NAME", "JOURNAL_NAME",
           "PARQUET_NAME", "CSV_NAME", "PLOT_NAME"]

SPEC_NAME = "sweep.json"
JOURNAL_NAME = "journal.jsonl"
PARQUET_NAME = "results.parquet"
CSV_NAME = "results.csv"
PLOT_NAME = "summary.png"

FIRST = ("variant", "seed")
LAST = ("status", "error", "wall_time", "cpu_time", "pid")


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return {"__float__": repr(value)}
    if hasattr(value, "item"):
        return _json_safe(value.item())
    return value


def _from_json(value):
    if isinstance(value, dict) and "__float__" in value:
        return float(value["__float__"])
    return value


class Journal:
    """Append-only rows of finished variants (``journal.jsonl``)."""

    def __init__(self, path):
        self.path = Path(path)

    def read(self) -> dict[int, dict]:
        rows: dict[int, dict] = {}
        if not self.path.exists():
            return rows
        with open(self.path, encoding="utf-8") as handle:
            for line in handle:
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:
                    continue            # a line torn by a kill mid-write
                if isinstance(row, dict) and "variant" in row:
                    rows[int(row["variant"])] = {k: _from_json(v) for k, v in row.items()}
        return rows

    def append(self, rows: list[dict]) -> None:
        if not rows:
            return
        with open(self.path, "a", encoding="utf-8") as handle:
            for row in rows:
                handle.write(json.dumps({k: _json_safe(v) for k, v in row.items()}, allow_nan=False) + "\n")
            handle.flush()


def rows_to_frame(rows: dict[int, dict], param_keys: list[str], metric_names: list[str]):
    """The table as a pandas DataFrame: variant, seed, parameters, metrics, status, error, wall_time."""
    import pandas as pd

    columns = [*FIRST, *param_keys, *metric_names, *LAST]
    ordered = [rows[i] for i in sorted(rows)]
    frame = pd.DataFrame([{c: r.get(c) for c in columns} for r in ordered], columns=columns)
    for name in metric_names + ["wall_time", "cpu_time"]:
        frame[name] = pd.to_numeric(frame[name], errors="coerce").astype(float)
    frame["variant"] = frame["variant"].astype("int64")
    frame["seed"] = frame["seed"].astype("int64")
    frame["error"] = frame["error"].fillna("").astype(str)
    frame["status"] = frame["status"].astype(str)
    return frame


def write_table(frame, out_dir) -> tuple[Path, Path]:
    """Write results.parquet (pyarrow) and results.csv atomically."""
    from ..io import atomic_path

    out = Path(out_dir)
    parquet, csv = out / PARQUET_NAME, out / CSV_NAME
    table = frame.copy()
    for column in table.columns:
        # mixed-type parameter columns (numbers and words) are stored as text
        if table[column].dtype == object and table[column].map(type).nunique() > 1:
            table[column] = table[column].astype(str)
    with atomic_path(parquet) as temp:
        table.to_parquet(temp, engine="pyarrow", index=False)
    with atomic_path(csv) as temp:
        table.to_csv(temp, index=False)
    return parquet, csv


def plot_summary(frame, params, metric_names: list[str], path) -> Path | None:
    """Every metric (rows) against every parameter (columns), completed variants only (PNG)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import numpy as np

    from ..io import atomic_path

    done = frame[frame["status"] == "completed"]
    if not metric_names or not params:
        return None
    fig, axes = plt.subplots(len(metric_names), len(params), squeeze=False,
                             figsize=(3.6 * len(params) + 0.8, 2.6 * len(metric_names) + 0.6))
    for j, p in enumerate(params):
        column = done[p.key] if p.key in done else []
        numeric = len(column) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in column)
        if numeric:
            xs = np.asarray(column, dtype=float)
            labels = None
        else:
            labels = list(dict.fromkeys(str(v) for v in (p.values if p.values is not None else column)))
            xs = np.asarray([labels.index(str(v)) if str(v) in labels else -1 for v in column], dtype=float)
        for i, name in enumerate(metric_names):
            ax = axes[i][j]
            ys = done[name].to_numpy(dtype=float)
            ax.scatter(xs, ys, s=12, alpha=0.8)
            if not np.isfinite(ys).any():
                ax.text(0.5, 0.5, "no finite values (NaN)", transform=ax.transAxes, ha="center", va="center",
                        fontsize=8, color="0.4")
            if labels is not None:
                ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=7)
            elif p.scale == "log10":
                ax.set_xscale("log")
            if i == len(metric_names) - 1:
                ax.set_xlabel(p.key, fontsize=8)
            if j == 0:
                ax.set_ylabel(name, fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    failed = int((frame["status"] != "completed").sum())
    fig.suptitle(f"{len(done)} completed variants" + (f", {failed} failed (not drawn)" if failed else ""), fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)
