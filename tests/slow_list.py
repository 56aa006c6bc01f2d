"""Regenerate ``tests/slow.txt``, the tests that ``pytest -m "not slow"`` leaves out.

Run the full suite with per-test durations on the 2-core reference machine, then this script:

    python -m pytest -q -n 2 --dist loadfile --durations=0 > durations.log
    python tests/slow_list.py durations.log

A test is slow when its setup, call and teardown together took more than ``THRESHOLD`` seconds
(Numba compilation included, so the first test of a file to use a kernel family is often the slow
one). The cheapest test of every file stays in the fast set, so ``-m "not slow"`` still imports and
exercises every test module. Tests marked ``@pytest.mark.slow`` in their file stay slow either way.
"""
import collections
import re
import sys
from pathlib import Path

THRESHOLD = 2.5   # seconds per test


def slow_tests(log_lines):
    seconds = collections.defaultdict(float)
    for line in log_lines:
        m = re.match(r"\s*([\d.]+)s (?:call|setup|teardown)\s+(\S+)", line)
        if m:
            seconds[m.group(2)] += float(m.group(1))
    by_file = collections.defaultdict(list)
    for node, t in seconds.items():
        by_file[node.split("::")[0]].append((t, node))
    slow = []
    for tests in by_file.values():
        tests.sort()
        slow += [node for t, node in tests[1:] if t > THRESHOLD]
    return sorted(slow)


if __name__ == "__main__":
    nodes = slow_tests(Path(sys.argv[1]).read_text().splitlines())
    out = Path(__file__).with_name("slow.txt")
    out.write_text("# Written by tests/slow_list.py from measured durations: the tests -m \"not slow\" leaves out.\n"
                   + "\n".join(nodes) + "\n")
    print(f"{len(nodes)} slow tests -> {out}")
