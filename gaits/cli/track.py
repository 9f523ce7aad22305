"""``nhgait track <scene> [--gait G] [--set ...] --mismatch params.NAME=FACTOR ... --samples K --out DIR``.

Plans the scene's ``[task]`` (or reads ``--plan DIR/solution.json``), then re-simulates the plan
on the general model with the parameters changed and with initial-state and input noise, open
loop and with the plan's feedback (the time-varying LQR stored with every plan), K samples —
in this process, or on the sweep back ends when K is large or ``--scheduler``/``--workers`` is
given — and writes tracking.json, tracking_paths.png and tracking_errors.png
(:mod:`nhgait.gaits.tracking.study`). Like ``plan``: ``--out`` is checked and locked before any
work, the files are written whole or not at all, and the study runs within a time budget
(``--time-limit``, shared by the plan and the samples; one that runs out is a clean failure,
exit 1). Registered by :mod:`nhgait.gaits.cli.main`.
"""
from __future__ import annotations

import argparse
import time

__all__ = ["add_track_parser", "run"]


def add_track_parser(subparsers) -> argparse.ArgumentParser:
    from ..tracking.runs import Noise
    from ..tracking.study import SERIAL_SAMPLES
    p = subparsers.add_parser(
        "track",
        help="track a planned gait with its feedback on a robot whose parameters differ from the model's",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Re-simulate a plan on the general model with changed parameters and noise, "
                    "open loop and "
                    "with the plan's time-varying LQR, and report the final position errors, the "
                    "tracking error of every state and the time the inputs sit at their bounds.\n\n"
                    "  nhgait track snakeboard --gait forward --mismatch params.m=1.1 --mismatch "
                    "params.J_r=0.9 \\\n"
                    "      --samples 20 --out out/track\n"
                    "  nhgait track examples/tiago_park.toml --mismatch params.m_base=1.1 --out "
                    "out/tiago-track\n"
                    "  nhgait track snakeboard --gait forward --plan out/demo/solution.json --mismatch "
                    "params.m=1.1 --out out/t2")
    p.add_argument("system", help="scene file (.toml) or built-in scene name")
    p.add_argument("--gait", default=None,
                   help="a built-in gait of a built-in scene (default: the scene's [task])")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a task value before planning, e.g. final.x=2.0 (repeatable)")
    p.add_argument("--plan", default=None, metavar="SOLUTION_JSON",
                   help="track this solution.json (with its feedback) instead of planning")
    p.add_argument("--mismatch", action="append", default=[], metavar="params.NAME=FACTOR",
                   help="the robot's parameter NAME is FACTOR times the model's (repeatable, "
                        "each parameter once)")
    p.add_argument("--samples", type=int, default=20, help="noisy samples K (default 20)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise, an integer ≥ 0 (default 0)")
    p.add_argument("--state-noise", type=float, default=Noise.state,
                   help=f"std of each initial state, fraction of its scale (default {Noise.state:g})")
    p.add_argument("--input-noise", type=float, default=Noise.input,
                   help=f"std of each input per plan interval, fraction of the plan's peak input "
                        f"(default {Noise.input:g})")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the samples on Dask: local:N (a local cluster of N workers) or tcp://host:8786")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (0: this process; default: this process up to "
                        f"{SERIAL_SAMPLES} samples, else one per core)")
    p.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                   help="seconds the whole study (the plan and the samples) may take (default: the task's "
                        "time_limit, else 120 s + 30 s per coordinate); a study that runs out fails "
                        "cleanly (exit 1) with the samples done in tracking.json ('inf': unlimited;"
                        " a huge number of seconds is in effect the same)")
    talk = p.add_mutually_exclusive_group()
    talk.add_argument("--quiet", action="store_true", help="no progress on stderr")
    talk.add_argument("--verbose", action="store_true", help="the solver's own iteration log as well")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """The study with ``--out`` checked and locked first (:mod:`nhgait.gaits.files.outputs`); exit 1
    when the plan or a run failed, the time ran out or the files could not all be written."""
    from nhgait.dynamics.progress import Progress

    from ..files.outputs import output_directory, output_lock
    from ..tracking.runs import Noise
    from ..tracking.study import summary_lines, track
    started = time.perf_counter()
    progress = Progress.silent() if args.quiet else Progress.to_stderr(verbose=args.verbose)
    out = output_directory(args.out)
    with output_lock(out, f"nhgait track {args.system}"):
        result = track(args.system, args.gait, overrides=args.overrides, mismatch=args.mismatch,
                       samples=args.samples, seed=args.seed, noise=Noise(args.state_noise, args.input_noise),
                       plan_file=args.plan, scheduler=args.scheduler, workers=args.workers, out_dir=out,
                       progress=progress, time_limit=args.time_limit)
    print("\n".join(summary_lines(result)))
    print(f"  wall time          {time.perf_counter() - started:.1f} s")
    return 0 if result.success and not result.unwritten else 1
