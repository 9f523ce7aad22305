"""What each test file costs, for the order in which ``make test`` hands files to its workers.

``make test`` runs ``pytest -n 2 --dist loadfile``: a file is one unit of work (its module-scoped
fixtures — a plan, the docs build — are made once), and a worker takes the next file when it has
almost finished its own. xdist's default order (most tests first) leaves the files of one or two
heavy tests — benchmark smoke runs, a cold plan, the docs build — to the end, where one worker runs
them while the other is idle. Handing the costliest files out first (the longest-processing-time
rule) lets both workers end together; ``tests/conftest.py`` sorts the collection by
:data:`COSTS_FILE` and the Makefile turns xdist's own reordering off (``--no-loadscope-reorder``).

The costs are seconds measured on one run (the sum of setup, call and teardown of a file's tests);
they only order the work, they are asserted nowhere. A file not listed (a new one) counts as the
median file.
Refresh them after a run with a JUnit report::

    .venv/bin/python -m pytest -n 2 --dist loadfile --junitxml=/tmp/suite.xml
    .venv/bin/python tests/file_costs.py /tmp/suite.xml
"""
from __future__ import annotations

import json
import statistics
import sys
import xml.etree.ElementTree as ET
from functools import lru_cache
from pathlib import Path

COSTS_FILE = Path(__file__).with_name("file_costs.json")
ROOT = Path(__file__).resolve().parents[1]


@lru_cache(maxsize=1)
def costs() -> dict:
    """Seconds per test file, by path relative to the repository (``tests/…/test_x.py``)."""
    try:
        return json.loads(COSTS_FILE.read_text())["seconds"]
    except (OSError, ValueError, KeyError):
        return {}


@lru_cache(maxsize=1)
def _median() -> float:
    return statistics.median(costs().values()) if costs() else 0.0


def cost(path: str) -> float:
    """The measured seconds of the test file ``path`` (the median file's if not measured)."""
    return costs().get(path, _median())


def _file_of(classname: str) -> str:
    """The file of a JUnit ``classname`` (``tests.gaits.test_x`` or ``tests.gaits.test_x.Class``)."""
    parts = classname.split(".")
    for end in range(len(parts), 0, -1):
        path = "/".join(parts[:end]) + ".py"
        if (ROOT / path).is_file():
            return path
    return "/".join(parts) + ".py"


def from_junit(report: Path) -> dict:
    """Seconds per file summed over the test cases of a JUnit XML report, rounded to 0.1 s."""
    seconds: dict = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        path = _file_of(case.get("classname", ""))
        seconds[path] = seconds.get(path, 0.0) + float(case.get("time", 0.0))
    return {path: round(s, 1) for path, s in sorted(seconds.items(), key=lambda kv: -kv[1])}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python tests/file_costs.py REPORT.xml  (writes tests/file_costs.json)", file=sys.stderr)
        return 2
    seconds = from_junit(Path(argv[0]))
    COSTS_FILE.write_text(json.dumps({"unit": "s (setup + call + teardown, one run)",
                                      "seconds": seconds}, indent=1) + "\n")
    print(f"{len(seconds)} files, {sum(seconds.values()):.0f} s in all -> {COSTS_FILE}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
