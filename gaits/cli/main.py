"""The ``nhgait`` command line: one module per subcommand, registered here.

    nhgait derive <scene.toml | built-in> ...      (gaits/cli/derive.py)
    nhgait simulate <scene.toml | built-in> ...    (gaits/cli/simulate.py)
    nhgait reproduce [--out DIR] ...               (gaits/cli/reproduce.py)
    nhgait plan <system> ... --out DIR             (gaits/cli/plan.py)
    nhgait track <system> --mismatch ... --out DIR (gaits/cli/track.py)
    nhgait analyse <scene.toml | built-in> ...     (gaits/cli/analyse.py)
    nhgait cache [list | clean | stop]             (gaits/cli/cache.py)

Exit status: 0 success; 1 the job ran but did not succeed (an integration that stopped early,
an optimisation that did not converge or was not verified); 2 bad input — one message listing
every problem, no traceback; 3 an internal error (a bug: one line naming it; ``NHGAIT_DEBUG=1``
shows the traceback); 130 interrupted (Ctrl-C), 143 terminated (SIGTERM, e.g. ``timeout``), 129
hung up (SIGHUP: the terminal closed).

Interrupts clean up, at once: SIGTERM is turned into an exception like Ctrl-C, so that a running
C compiler is killed and its temporary files removed (:mod:`nhgait.dynamics.numerics.compiler`),
supervised solver processes are killed (:mod:`nhgait.ocp.supervision`) and no half-written cache
entry or output file is left; a watchdog ends the process when the main thread is inside C code
that does not return (:mod:`.stopping`).
"""
from __future__ import annotations

import importlib
import os
import sys
import warnings

from nhgait.dynamics.errors import Terminated  # noqa: F401 - nhgait.gaits.cli.main.Terminated, kept

from .vocabulary import CommandParser

#: (name, module, function adding the subcommand), in the order of ``nhgait --help``
SUBCOMMANDS = (
    ("derive", "nhgait.gaits.cli.derive", "add_derive_parser"),
    ("simulate", "nhgait.gaits.cli.simulate", "add_simulate_parser"),
    ("bench", "nhgait.gaits.bench.command", "add_bench_parser"),
    ("reproduce", "nhgait.gaits.cli.reproduce", "add_reproduce_parser"),
    ("plan", "nhgait.gaits.cli.plan", "add_plan_parser"),
    ("sweep", "nhgait.gaits.cli.sweep", "add_sweep_parser"),
    ("linearize", "nhgait.gaits.cli.linearize", "add_linearize_parser"),
    ("analyse", "nhgait.gaits.cli.analyse", "add_analyse_parser"),
    ("track", "nhgait.gaits.cli.track", "add_track_parser"),
    ("cache", "nhgait.gaits.cli.cache", "add_cache_parser"),
)


def build_parser(argv=None) -> CommandParser:
    """The ``nhgait`` parser: every subcommand's parser a :class:`~.vocabulary.CommandParser`
    (an unknown option answered with "did you mean …?"). With ``argv`` naming a subcommand
    (its first word that is not an option), only that one's module is imported and its parser
    built in full, the others named only: a command imports what it uses (issue 40)."""
    from nhgait import __version__
    parser = CommandParser(prog="nhgait", description="Dynamics and gait planning of nonholonomic robots.")
    parser.add_argument("--version", action="version", version=f"nhgait {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    words = [tok for tok in (argv or ()) if not tok.startswith("-")]
    chosen = words[0] if words and words[0] in {name for name, _, _ in SUBCOMMANDS} else None
    for name, module, adder in SUBCOMMANDS:
        if chosen is None or name == chosen:
            getattr(importlib.import_module(module), adder)(sub)
        else:
            sub.add_parser(name)
    return parser


def main(argv=None) -> int:
    """Run one subcommand; its exit status (the module docstring's table). Run as the program
    (``argv`` None: the ``nhgait`` command), a stop by SIGINT/SIGTERM ends the process as soon
    as its cleanup is done (:func:`~.stopping.exit_now`), and so does a command that ends by
    itself (:func:`~.stopping.end_process`: its threads joined, ``atexit`` run, the streams
    flushed, the interpreter's teardown of CasADi, SciPy and matplotlib — 0.3–1 s — skipped);
    called with ``argv`` it returns."""
    status = _main(argv)
    if argv is None:
        from .stopping import end_process
        end_process(status)
    return status


def _main(argv) -> int:
    from nhgait.dynamics.errors import ModelError

    from .stopping import cancel_background_builds, exit_now, stop_signals
    parser = build_parser(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    stopped = (lambda status: status) if argv is not None else exit_now
    formatter, warnings.formatwarning = warnings.formatwarning, _format_warning
    try:
        with stop_signals() as stop:
            try:
                status = int(args.func(args) or 0)
            except Exception:
                if stop.signal is None:
                    raise
                raise stop.exception() from None    # the stop, whatever it became on its way up
            if stop.signal is not None:             # its exception was dropped on the way (a __del__)
                raise stop.exception()
            return status
    except KeyboardInterrupt:
        cancel_background_builds()
        print("nhgait: interrupted", file=sys.stderr)
        return stopped(130)
    except Terminated:
        cancel_background_builds()
        status, message = stop.ending()             # SIGTERM's or SIGHUP's
        print(message, file=sys.stderr)
        return stopped(status)
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
        warnings.formatwarning = formatter


def _format_warning(message, category, filename, lineno, line=None) -> str:
    """A warning as the command prints it: one line, no source location."""
    return f"nhgait: warning: {message}\n"


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
