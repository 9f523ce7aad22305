"""No module installs a signal handler when it is imported (issue 40, item 4): a test run that
imports the library and the experiments' scripts must stay stoppable by SIGTERM and Ctrl-C. A
script that needs a handler installs it in ``main()`` and puts the previous one back when
``main`` returns (the smoke tests call ``main`` in-process)."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import experiment_scripts
import pytest

ROOT = Path(__file__).resolve().parents[2]

_IMPORT_EVERYTHING = """
import importlib, signal, sys
from pathlib import Path
SIGNALS = ("SIGTERM", "SIGINT", "SIGHUP", "SIGALRM", "SIGCHLD", "SIGUSR1")
before = {name: signal.getsignal(getattr(signal, name)) for name in SIGNALS}
experiments = Path(sys.argv[1])
sys.path.insert(0, str(experiments))
import sibling
for name in sys.argv[2:]:
    if name.startswith("nhgait"):
        importlib.import_module(name)
    else:
        sibling.load(name)
    after = {s: signal.getsignal(getattr(signal, s)) for s in SIGNALS}
    changed = [s for s in SIGNALS if after[s] != before[s]]
    if changed:
        print(name, *changed)
        sys.exit(1)
print("none")
"""


def _library_modules() -> list:
    folders = {"api": "nhgait", "dynamics": "nhgait.dynamics", "ocp": "nhgait.ocp", "gaits": "nhgait.gaits"}
    names = []
    for folder, package in folders.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            name = ".".join([package, *parts]).removesuffix(".__init__")
            if not name.endswith("__main__"):
                names.append(name)
    return sorted(names)


def test_no_module_or_experiment_script_installs_a_signal_handler_at_import():
    """Every library module and every script of experiments/, imported one after the other in a
    fresh process: after each, the handlers of SIGTERM, SIGINT, SIGHUP, SIGALRM, SIGCHLD and
    SIGUSR1 are the interpreter's own (the first module that changes one is named)."""
    scripts = sorted(p.stem for p in (ROOT / "experiments").glob("*.py"))
    out = subprocess.run([sys.executable, "-c", _IMPORT_EVERYTHING, str(ROOT / "experiments"),
                          *_library_modules(), *scripts], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.split()[-1:] == ["none"], (out.stdout, out.stderr[-3000:])


@pytest.mark.skipif(not hasattr(signal, "SIGTERM"), reason="POSIX signals")
def test_the_any_robot_benchmark_puts_the_previous_sigterm_handler_back():
    """``bench_any_robot.main`` turns SIGTERM into SystemExit while it runs (its plans run in
    sessions of their own) and restores the handler it found, on every way out — here a
    command-line error."""
    bench = experiment_scripts.load("bench_any_robot")

    def mine(signum, frame):
        raise AssertionError("not expected")

    previous = signal.signal(signal.SIGTERM, mine)
    try:
        with pytest.raises(SystemExit):
            bench.main(["--no-such-option"])
        assert signal.getsignal(signal.SIGTERM) is mine
    finally:
        signal.signal(signal.SIGTERM, previous)
