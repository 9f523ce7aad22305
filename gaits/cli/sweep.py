"""``nhgait sweep SCENE --grid NAME=lo:hi:n ... --out DIR`` (registered by :mod:`nhgait.gaits.cli.main`).

Writes ``DIR/sweep.sqlite`` (one row per point, as each finishes), ``DIR/solutions/<id>.json``
and, at the end, ``landscape.png`` (cost over the first two axes with more than one value),
``feasibility.png`` and ``loops.png`` (shape loops along the first axis). Prints a progress
line while it runs and a summary table at the end. Exit status 0 when every point was solved
and verified, 1 when some failed, 2 for bad input, 130 when interrupted (Ctrl-C; the stored
points are kept: ``--resume``).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .vocabulary import renamed

__all__ = ["add_sweep_parser", "run"]


def add_sweep_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "sweep", help="solve a gait task over a grid of task values and parameters",
        description="One optimal control problem per grid point, warm-started from solved neighbours and "
                    "verified by re-simulation; every point stored as it finishes (resumable); heat maps "
                    "of cost and feasibility. Back ends: a local process pool, or Dask distributed.")
    p.add_argument("scene", help="scene file (.toml) or built-in scene name (unicycle, snakeboard)")
    p.add_argument("--gait", default=None,
                   help="built-in gait task (e.g. parallel-park), as in nhgait plan and track; default: "
                        "the scene's [task]")
    renamed(p, "--task", "--gait")
    p.add_argument("--grid", action="append", required=True, metavar="NAME=lo:hi:n",
                   help="a grid axis: horizon, intervals, control_bounds, initial.<name>, final.<name>, "
                        "objective.<weight> or params.<name>; values lo:hi:n, a,b,c or one value "
                        "(repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="change the base task, e.g. --set intervals=50 (repeatable)")
    p.add_argument("--out", required=True, help="sweep directory (store, solutions, plots)")
    p.add_argument("--resume", action="store_true",
                   help="continue the sweep stored in --out: solve only missing points")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on Dask distributed: a scheduler address (tcp://host:8786) or local:N for a "
                        "LocalCluster of N workers on 127.0.0.1 (needs pip install 'nhgait[dask]')")
    p.add_argument("--workers", type=int, default=None,
                   help="local pool size (default: one per core; 0: in this process)")
    p.add_argument("--chain", type=int, default=None, metavar="N",
                   help="grid points per back-end task, solved in a row down the continuation tree "
                        "(default: 1 for the local pool, 4 for Dask, whose fixed cost per task they share)")
    p.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                   help="seconds each grid point may take (default: the task's time_limit, else "
                        "the planner's "
                        "default for the robot's size); a point that runs out is a failed point "
                        "naming the budget ('inf': unlimited; a huge number of seconds is in effect "
                        "the same)")
    p.add_argument("--cold", action="store_true",
                   help="no continuation: start every point from the planner's guesses")
    p.add_argument("--plot", default=None, metavar="X,Y",
                   help="axes of the heat map (default: the first two)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG files")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=run)
    return p


class _ProgressPrinter:
    """One progress line: redrawn in place on a terminal, at most every 5 s in a log."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.last = 0.0

    def __call__(self, progress) -> None:
        now = time.monotonic()
        final = progress.finished == progress.total
        if self.tty:
            self.stream.write("\r" + progress.line().ljust(100) + ("\n" if final else ""))
            self.stream.flush()
        elif final or now - self.last >= 5.0:
            self.stream.write(progress.line() + "\n")
            self.stream.flush()
            self.last = now


def _plot_axes(result, requested):
    from nhgait.ocp import ProblemError
    names = [a.name for a in result.grid.axes if len(a) > 1] or list(result.grid.names)
    if requested:
        chosen = [s.strip() for s in requested.split(",")]
        if len(chosen) != 2:
            raise ProblemError([f"--plot {requested!r}: give two axes X,Y"], title="invalid --plot")
        result.grid.axis(chosen[0]), result.grid.axis(chosen[1])
        return chosen
    return names[:2]


def _check_plot(requested, grid) -> None:
    """``--plot X,Y`` checked against the ``--grid`` axes before any point is solved."""
    from nhgait.ocp import ProblemError
    if not requested or not grid:
        return
    chosen = [s.strip() for s in requested.split(",")]
    names = [str(spec).partition("=")[0].strip() for spec in grid]
    problems = ([f"--plot {requested!r}: give two axes X,Y"] if len(chosen) != 2 else []) + [
        f"--plot: no grid axis {name!r} (axes: {', '.join(names)})" for name in chosen if name not in names]
    if problems:
        raise ProblemError(problems, title="invalid --plot")


def write_plots(result, out: Path, requested=None) -> list:
    """landscape.png, feasibility.png (two axes) and loops.png (first axis); returns the paths."""
    from ..sweeps import plots as sp
    axes = _plot_axes(result, requested)
    files = []
    if len(axes) == 2:
        for name, fn in (("landscape.png", sp.plot_landscape), ("feasibility.png", sp.plot_feasibility)):
            ax = fn(result, axes[0], axes[1])
            ax.figure.savefig(out / name, dpi=110, bbox_inches="tight")
            files.append(out / name)
    if len(result.case.get("shape") or ()) >= 2:
        loops = sp.plot_shape_loops(result, axes[0])
        loops[0].figure.savefig(out / "loops.png", dpi=110, bbox_inches="tight")
        files.append(out / "loops.png")
    return files


def run(args) -> int:
    from ..files.outputs import write_failure
    from ..sweeps.driver import load_sweep, sweep
    from ..sweeps.store import StoreWriteError
    out = Path(args.out)
    if not args.no_plots:
        _check_plot(args.plot, args.grid)
    try:
        result = sweep(args.scene, args.gait, args.grid, out=args.out, scheduler=args.scheduler,
                       workers=args.workers,
                       resume=args.resume, warm_start=not args.cold, overrides=args.overrides,
                       chain=args.chain, progress=None if args.quiet else _ProgressPrinter(),
                       options=None if args.time_limit is None else {"time_limit": args.time_limit})
    except KeyboardInterrupt:
        stored = len(load_sweep(out).records) if (out / "sweep.sqlite").exists() else 0
        print(f"\nnhgait sweep: interrupted; {stored} points are stored in {out} — continue with --resume",
              file=sys.stderr)
        return 130
    except StoreWriteError as exc:
        print(f"nhgait sweep: stopped: {exc}", file=sys.stderr)
        return 1
    for line in result.summary_lines():
        print(line)
    if not args.no_plots:
        try:
            files = write_plots(result, out, args.plot)
        except OSError as exc:                 # the points are stored; only the pictures are missing
            print(f"  plots NOT WRITTEN: {write_failure(exc, out)} (the points are stored in "
                  f"{out / 'sweep.sqlite'})")
            return 1
        print("  files:  " + "  ".join(str(f) for f in [out / "sweep.sqlite", *files]))
    return 0 if all(r.success for r in result.records) and result.complete else 1
