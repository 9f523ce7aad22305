"""``nhgait plan <scene> [--gait NAME] [--set key=value ...] --out DIR``.

Plans the scene file's ``[task]`` (or a built-in gait of a built-in scene), verifies the
optimum by an independent simulation and writes solution.json and PNG plots; ``--gif`` also
writes the animation motion.gif (60 frames in a frame fitted to the motion, made on request; its
time is reported apart). The plan runs within a time budget
(``--time-limit``; a budget that runs out is a clean failure, exit 1). Registered by
:mod:`nhgait.gaits.cli.main`.
"""
from __future__ import annotations

import argparse
import time

__all__ = ["add_plan_parser", "run"]


def add_plan_parser(subparsers) -> argparse.ArgumentParser:
    from ..tasks.sources import describe_library
    from .arguments import positive_int, workers
    p = subparsers.add_parser(
        "plan", help="plan an optimal gait of a scene's [task] (or a built-in gait) and verify it",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Plan an optimal gait (CasADi + FATROP or Ipopt), verify it by an independent "
                    "simulation and write solution.json and PNG plots (--gif: also an animation).\n\n"
                    "  nhgait plan my_robot.toml --out out/robot          # the scene's [task]\n"
                    "  nhgait plan my_robot.toml --set final.x=2.0 --out out/robot2\n"
                    "  nhgait plan snakeboard --gait forward --out out/demo\n\n"
                    "Built-in gaits:\n" + describe_library())
    p.add_argument("system", help="scene file (.toml) or built-in scene name")
    p.add_argument("--gait", default=None,
                   help="a built-in gait of a built-in scene (default: the scene's [task])")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a task value, e.g. final.x=2.0, horizon=6.0, bounds.phi=-1,1 (repeatable)")
    p.add_argument("--intervals", type=int, default=None, help="control intervals N (default: the task's)")
    p.add_argument("--solver", choices=["auto", "fatrop", "ipopt"], default="auto",
                   help="NLP solver: auto (default) = FATROP (stage-ordered) then Ipopt for small ODEs, "
                        "Ipopt then FATROP for larger ones, the second when the first finds no solution; "
                        "or one of them alone")
    p.add_argument("--transcription", choices=["multiple-shooting", "collocation"], default=None)
    jit = p.add_mutually_exclusive_group()
    jit.add_argument("--jit", dest="jit", action="store_true", default=None,
                     help="compile the NLP functions (default: when a C compiler is found; cached)")
    jit.add_argument("--no-jit", dest="jit", action="store_false", help="interpreted NLP functions")
    p.add_argument("--workers", default="1", type=workers, help="initial guesses tried at once, in separate "
                                                                 "processes (a number or 'auto'; default 1)")
    p.add_argument("--hessian", choices=["auto", "exact", "gauss-newton", "limited-memory"], default="auto",
                   help="Lagrangian Hessian: exact (auto), Gauss-Newton (the stage curvature dropped) or "
                        "limited-memory (Ipopt's L-BFGS: with --solver auto, Ipopt alone)")
    p.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                   help="seconds the whole plan may take (default: the task's time_limit, else 120 "
                        "s + 30 s per "
                        "coordinate); each solver attempt is also limited, from its measured cost; "
                        "a plan that runs out fails cleanly (exit 1) naming the phase ('inf': "
                        "unlimited; a huge number of seconds is in effect the same)")
    p.add_argument("--guess", default=None, metavar="SOLUTION_JSON",
                   help="start from a previous plan's solution.json of the same robot (resampled "
                        "onto this task's grid) before the planner's own guesses: a refinement with "
                        "--intervals")
    p.add_argument("--max-guesses", type=positive_int, default=12,
                   help="initial guesses tried per solver before the continuation (default 12)")
    gif = p.add_mutually_exclusive_group()
    gif.add_argument("--gif", action="store_true",
                     help="also write motion.gif (60 frames, the body moving along its path)")
    gif.add_argument("--no-gif", action="store_true", help="no animation (the default; kept for old scripts)")
    talk = p.add_mutually_exclusive_group()
    talk.add_argument("--quiet", action="store_true", help="no progress on stderr")
    talk.add_argument("--verbose", action="store_true", help="the solver's own iteration log as well")
    p.add_argument("--no-background-build", action="store_true",
                   help="ask for no optimised build in the background for the next run (as "
                        "NHGAIT_BACKGROUND_BUILDS=0; `nhgait cache` lists the builds pending)")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Plan with ``--out`` checked and locked first (:mod:`nhgait.gaits.files.outputs`); the result
    first — solution.json and trajectory.csv written, the summary printed (``plan``'s
    ``on_result``) — then the figures, drawn while the gait was verified and moved into place
    now (and ``--gif``'s animation). Exit 1 when the plan failed or its files could not all be
    written (the summary says where the solution went)."""
    from nhgait.dynamics.numerics.background import builds_off
    from nhgait.dynamics.progress import Progress

    from ..files.outputs import output_directory, output_lock
    from ..plan_summary import summary_lines
    from ..planner import plan
    from ..planning.options import PlanOptions
    started = time.perf_counter()
    progress = Progress.silent() if args.quiet else Progress.to_stderr(verbose=args.verbose)
    out = output_directory(args.out)
    announced = []

    def announce(result):
        """The result, before anything optional."""
        announced.append(result)
        lines = [line for line in summary_lines(result)      # the animation comes with the figures
                 if not (args.gif and line.startswith("  animation "))]
        print("\n".join(lines), flush=True)
    with output_lock(out, f"nhgait plan {args.system}"), builds_off(args.no_background_build):
        drawn = plan(args.system, args.gait, overrides=args.overrides, out_dir=out, animate=args.gif,
                     progress=progress, guess=args.guess, on_result=announce,
                     options=PlanOptions.values_of(args))
    print("\n".join(_figure_lines(announced[0], drawn)))
    print(f"  wall time          {_wall_text(time.perf_counter() - started, drawn.timings)}")
    return 0 if drawn.success and not drawn.unwritten else 1


def _figure_lines(before, after) -> list:
    """The figures written after the result (or why they were not)."""
    if after.unwritten and not before.unwritten:
        return [f"  figures            NOT WRITTEN: {after.unwritten} (the result is written)"]
    added = after.files[len(before.files):]
    return ["  figures:", *(f"    {f}" for f in added)] if added else []


def _wall_text(wall: float, timings: dict) -> str:
    """"4.3 s in all: model 1.1 s, NLP set-up and compilation 0.3 s, …" (the rest: files)."""
    parts = [("model", "prepare_s"), ("NLP set-up and compilation", "setup_s"),
             ("guesses and solves", "solve_s"),
             ("the robust plan", "robust_s"), ("verification", "verify_s"), ("feedback", "feedback_s"),
             ("figures", "figures_s")]
    shown = [(label, float(timings[key])) for label, key in parts if key in timings]
    rest = wall - sum(seconds for _, seconds in shown)
    items = [f"{label} {seconds:.1f} s" for label, seconds in shown] + [f"files and start-up {rest:.1f} s"]
    return f"{wall:.1f} s in all: " + ", ".join(items)
