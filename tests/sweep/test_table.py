"""Journal, table files and summary plot (src/inertia/sweep/table.py)."""

import math

import pytest

pd = pytest.importorskip("pandas")

from inertia.sweep.params import Param
from inertia.sweep.table import Journal, plot_summary, rows_to_frame, write_table


def row(i, e, status="completed", value=1.0):
    return {"variant": i, "seed": 100 + i, "k": e, "m": value, "status": status, "error": "", "wall_time": 0.1,
            "cpu_time": 0.05, "pid": 1}


def test_journal_keeps_the_last_row_per_variant_and_skips_a_torn_line(tmp_path):
    journal = Journal(tmp_path / "journal.jsonl")
    journal.append([row(0, 0.1), row(1, 0.2, "lost", math.nan)])
    journal.append([row(1, 0.2, "completed", 2.0)])
    with open(tmp_path / "journal.jsonl", "a") as handle:
        handle.write('{"variant": 2, "seed": 1')          # a kill in the middle of a write
    rows = journal.read()
    assert sorted(rows) == [0, 1] and rows[1]["status"] == "completed" and rows[1]["m"] == 2.0


def test_table_files_and_plot(tmp_path):
    rows = {0: row(0, "rk4", value=math.nan), 1: row(1, 0.5), 2: row(2, 0.9, "diverged", math.nan)}
    frame = rows_to_frame(rows, ["k"], ["m"])
    assert list(frame.columns) == ["variant", "seed", "k", "m", "status", "error", "wall_time", "cpu_time", "pid"]
    parquet, csv = write_table(frame, tmp_path)
    back = pd.read_parquet(parquet)
    assert list(back["variant"]) == [0, 1, 2] and list(back["k"]) == ["rk4", "0.5", "0.9"]   # mixed column as text
    assert math.isnan(back["m"][0]) and back["m"][1] == 1.0
    assert len(pd.read_csv(csv)) == 3
    assert not list(tmp_path.glob("*.tmp*")) and not list(tmp_path.glob(".*"))             # nothing half-written left
    path = plot_summary(frame, [Param("k", values=("rk4", 0.5, 0.9))], ["m"], tmp_path / "summary.png")
    assert path.stat().st_size > 1000
