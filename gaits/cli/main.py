"""The ``nhgait`` command line: one module per subcommand, registered here.

    nhgait derive <scene.toml | built-in> ...      (gaits/cli_derive.py)
    nhgait simulate <scene.toml | built-in> ...    (gaits/cli_simulate.py)
    nhgait reproduce [--out DIR] ...               (gaits/cli_reproduce.py)
    nhgait plan <system> ... --out DIR             (gaits/cli_plan.py)
    nhgait track <system> --mismatch ... --out DIR (gaits/cli/track.py)

Exit status: 0 success; 1 the job ran but did not succeed (an integration that stopped early,
an optimisation that did not converge or was not verified); 2 bad input — one message listing
every problem, no traceback; 3 an internal error (a bug: one line naming it; ``NHGAIT_DEBUG=1``
shows the traceback); 130 interrupted (Ctrl-C), 143 terminated (SIGTERM, e.g. ``timeout``).

Interrupts clean up: SIGTERM is turned into an exception like Ctrl-C, so that a running C
compiler is killed and its temporary files removed (:mod:`nhgait.dynamics.numerics.compiler`), worker
processes are stopped and no half-written cache entry is left.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

#: (module, function adding the subcommand), in the order of ``nhgait --help``
SUBCOMMANDS = (
    ("nhgait.gaits.cli.derive", "add_derive_parser"),
    ("nhgait.gaits.cli.simulate", "add_simulate_parser"),
    ("nhgait.gaits.bench.command", "add_bench_parser"),
    ("nhgait.gaits.cli.reproduce", "add_reproduce_parser"),
    ("nhgait.gaits.cli.plan", "add_plan_parser"),
    ("nhgait.gaits.cli.sweep", "add_sweep_parser"),
    ("nhgait.gaits.cli.track", "add_track_parser"),
)


def build_parser() -> argparse.ArgumentParser:
    from nhgait import __version__
    parser = argparse.ArgumentParser(prog="nhgait", description="Dynamics and gait planning of nonholonomic robots.")
    parser.add_argument("--version", action="version", version=f"nhgait {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for module, adder in SUBCOMMANDS:
        getattr(importlib.import_module(module), adder)(sub)
    return parser


class Terminated(BaseException):
    """SIGTERM received: unwinds like KeyboardInterrupt (cleanup runs), exit status 143."""


def _terminate(signum, frame):
    raise Terminated()


def main(argv=None) -> int:
    import signal
    from nhgait.dynamics.errors import ModelError
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = signal.signal(signal.SIGTERM, _terminate) if _main_thread() else None
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("nhgait: interrupted", file=sys.stderr)
        return 130
    except Terminated:
        print("nhgait: terminated", file=sys.stderr)
        return 143
    except ModelError as exc:            # bad input (ProblemError and BridgeError included)
        print(f"nhgait: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - a bug: one line, the traceback on request
        if os.environ.get("NHGAIT_DEBUG"):
            raise
        print(f"nhgait: internal error ({type(exc).__name__}: {exc}); this is a bug in nhgait — "
              "rerun with NHGAIT_DEBUG=1 for the traceback and please report it", file=sys.stderr)
        return 3
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _main_thread() -> bool:
    import threading
    return threading.current_thread() is threading.main_thread()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
