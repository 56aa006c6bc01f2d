"""Every fenced ``python`` block of README.md and docs/*.md runs, as a reader would run it.

The blocks of one page run in order in one fresh Python process (a later block may use what an
earlier one defined, as on the page), as the main script (so an ``if __name__ == "__main__":``
guard works, as dask's spawned workers need), in a temporary working directory. A block opts out
only with a first line ``# docs-test: skip: <reason>`` (a cluster the test machine does not have);
the reason is required. ``bash`` and ``toml`` blocks are not run.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SKIP = re.compile(r"^#\s*docs-test:\s*skip\b:?\s*(?P<reason>.*)$")
FENCE = re.compile(r"^```python\s*$(?P<body>.*?)^```\s*$", re.MULTILINE | re.DOTALL)


def python_blocks(path: Path) -> list[tuple[int, str]]:
    """(first line number, code) of each fenced python block of a Markdown page."""
    text = path.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start("body")) + 1, m.group("body")) for m in FENCE.finditer(text)]


def _runner(path: Path, blocks: list[tuple[int, str]]) -> str:
    """A script that executes the blocks in order, each compiled under '<page>:<line>' so a traceback
    names the block."""
    lines = ["import sys", "if __name__ == '__main__':", "    _g = globals()"]
    for line, code in blocks:
        name = f"{path.relative_to(ROOT)}:{line}"
        lines.append(f"    print({name!r}, flush=True)")
        lines.append(f"    exec(compile({code!r}, {name!r}, 'exec'), _g)")
    return "\n".join(lines) + "\n"


PAGES_WITH_CODE = [p for p in PAGES if python_blocks(p)]


def test_opt_outs_give_a_reason():
    for page in PAGES:
        for line, code in python_blocks(page):
            first = code.strip().splitlines()[0] if code.strip() else ""
            m = SKIP.match(first)
            assert m is None or len(m.group("reason").strip()) > 10, f"{page.name}:{line}: skip without a reason"


@pytest.mark.parametrize("page", PAGES_WITH_CODE, ids=[p.name for p in PAGES_WITH_CODE])
def test_page_snippets_run(page, tmp_path):
    blocks = [(line, code) for line, code in python_blocks(page)
              if not SKIP.match(code.strip().splitlines()[0] if code.strip() else "")]
    if not blocks:
        pytest.skip("every block opts out")
    script = tmp_path / "snippets.py"
    script.write_text(_runner(page, blocks))
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": os.pathsep.join(
        [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, (f"{page.name}: a snippet failed (last block started: "
                                  f"{(done.stdout.strip().splitlines() or ['none'])[-1]})\n"
                                  + textwrap.indent(done.stderr[-4000:], "  "))
