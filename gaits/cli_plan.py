"""``nhgait plan <system> --gait <name> ... --out DIR`` (registered by :mod:`nhgait.gaits.cli`)."""
from __future__ import annotations

import argparse
import math

__all__ = ["add_plan_parser", "run"]


def add_plan_parser(subparsers) -> argparse.ArgumentParser:
    from .tasks import TASKS
    gaits = sorted({n for _, n in TASKS})
    p = subparsers.add_parser("plan", help="plan an optimal periodic gait and verify it",
                              description="Plan an optimal gait (CasADi + Ipopt), verify it by an independent "
                                          "simulation and write solution.json, PNG plots and a GIF.")
    p.add_argument("system", help="built-in system (unicycle, snakeboard)")
    p.add_argument("--gait", required=True, help=f"gait task ({', '.join(gaits)})")
    p.add_argument("--distance", type=float, default=None, help="task distance (gait default if omitted)")
    p.add_argument("--angle", type=float, default=None, help="task angle in rad (gait default if omitted)")
    p.add_argument("--period", type=float, default=None, help="period T in s (gait default if omitted)")
    p.add_argument("--intervals", type=int, default=None, help="control intervals N (default 100)")
    p.add_argument("--transcription", choices=["multiple-shooting", "collocation"], default="multiple-shooting")
    p.add_argument("--jit", action="store_true", help="compile the NLP functions (cached on disk)")
    p.add_argument("--no-gif", action="store_true", help="skip the animation")
    p.add_argument("--out", required=True, help="output directory")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from .planner import plan
    res = plan(args.system, args.gait, distance=args.distance, angle=args.angle, period=args.period,
               intervals=args.intervals, transcription=args.transcription, jit=args.jit,
               out_dir=args.out, animate=not getattr(args, "no_gif", False))
    s = res.solution
    v = s.verification_error
    print(f"nhgait plan {res.system} --gait {res.gait}: {'SUCCESS' if s.success else 'FAILED'} ({s.status})")
    print(f"  objective          J = {s.objective:.6f}  (∫|u|² dt)")
    print(f"  iterations         {s.iterations}  (guesses tried: {', '.join(a for a, _ in res.attempts)})")
    print(f"  solve time         {s.solve_time_s * 1e3:.1f} ms  (functions {s.function_time_s * 1e3:.1f} ms, "
          f"solver {s.solver_time_s * 1e3:.1f} ms); set-up {s.setup_time_s * 1e3:.1f} ms; "
          f"derivation/cache {res.derive_time_s * 1e3:.1f} ms")
    print(f"  verification error {v:.2e}" if not math.isnan(v) else "  verification       not run")
    print(f"  N = {s.settings.get('intervals')}, T = {s.horizon:.4f}, {s.settings.get('transcription')}, "
          f"jit = {s.settings.get('jit')}" + (f" (cached: {res.timings.get('jit_cached')})" if s.settings.get('jit') else ""))
    print("  files:")
    for f in res.files:
        print(f"    {f}")
    return 0 if s.success else 1
