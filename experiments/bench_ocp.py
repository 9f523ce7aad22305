#!/usr/bin/env python3
"""Benchmark of the nhgait gait planner against the hand-written CasADi reference.

P1 (unicycle parallel-park), P2 (snakeboard forward), P3 (snakeboard rotate) at
N = 25, 50, 100, 200: median solve time of ``--repeats`` solves (same built NLP, the planner's
own first working guess), Ipopt iterations, set-up time, objective and its relative error vs
the reference objective, verification error; the reference (``experiments/
reference_casadi_ocp.py``, imported by path) is run in the same process and the ratio
ours/reference printed. ``--jit`` compares jit against jit. The planner's model is the task's
velocity-coordinate model (``specialise(..., velocities=task.velocities)``), as in ``plan``.
Writes ``out/bench_ocp.json``.

Usage: python experiments/bench_ocp.py [--quick] [--jit] [--N 25,50] [--problems P1,P2]
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PROBLEMS = {"P1": ("unicycle", "parallel-park"), "P2": ("snakeboard", "forward"), "P3": ("snakeboard", "rotate")}


def _reference():
    spec = importlib.util.spec_from_file_location("reference_casadi_ocp", HERE / "reference_casadi_ocp.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def bench_case(ref, key, N, *, jit, repeats):
    from nhgait.dynamics import builtin, derive
    from nhgait.gaits.guesses import candidates
    from nhgait.gaits.planner import solve_task, specialise
    from nhgait.gaits.tasks import get_task
    from nhgait.ocp import SolverOptions

    system, gait = PROBLEMS[key]
    task = get_task(system, gait)
    t0 = time.perf_counter()
    model = specialise(derive(builtin(system), "reduced"), velocities=task.velocities)
    model_time = time.perf_counter() - t0
    problem = task.problem(model, intervals=N)
    sol, attempts, solver = solve_task(problem, task.guess_family, options=SolverOptions(jit=jit))
    guess = next(g for g in candidates(problem, task.guess_family) if g.label == attempts[-1][0])
    runs = [sol] + [solver.solve(guess) for _ in range(repeats - 1)]
    sol = runs[-1].verified()
    ours = {"objective": sol.objective, "iterations": sol.iterations, "success": sol.success,
            "solve_time_s": statistics.median(r.solve_time_s for r in runs),
            "function_time_s": statistics.median(r.function_time_s for r in runs),
            "setup_time_s": solver.setup_time_s, "model_time_s": model_time,
            "verification_error": sol.verification_error, "guess": attempts[-1][0],
            "guesses_tried": len(attempts), "jit_cached": solver.jit_cached}
    rruns = [ref.solve(key, N, jit=jit) for _ in range(repeats)]
    r = rruns[-1]
    refd = {"objective": r["objective"], "iterations": r["iterations"], "success": r["success"],
            "solve_time_s": statistics.median(x["solve_time_s"] for x in rruns), "setup_time_s": r["setup_time_s"]}
    ref_obj = ref.REFERENCE[key][N] if N in ref.REFERENCE[key] else r["objective"]
    return {"problem": key, "N": N, "jit": jit, "ours": ours, "reference": refd,
            "reference_objective": ref_obj,
            "rel_error": abs(ours["objective"] - ref_obj) / abs(ref_obj),
            "time_ratio": ours["solve_time_s"] / refd["solve_time_s"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="P1,P2,P3")
    ap.add_argument("--N", default="25,50,100,200")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--jit", action="store_true", help="jit on both sides (compiled artefacts cached)")
    ap.add_argument("--quick", action="store_true", help="smoke run: N = 25, 2 repeats")
    ap.add_argument("--out", default="out/bench_ocp.json")
    args = ap.parse_args(argv)
    if args.quick:
        args.N, args.repeats = "25", 2
    ref = _reference()
    rows = []
    hdr = (f"{'prob':4s} {'N':>4s} {'jit':>3s} {'objective':>10s} {'rel err':>8s} {'it':>3s} {'ref it':>6s} "
           f"{'ours ms':>8s} {'ref ms':>8s} {'ratio':>5s} {'setup ms':>8s} {'ref setup':>9s} {'verify':>8s}")
    print(hdr)
    print("-" * len(hdr))
    ok = True
    for key in [p.strip() for p in args.problems.split(",") if p.strip()]:
        for N in [int(n) for n in args.N.split(",") if n.strip()]:
            row = bench_case(ref, key, N, jit=args.jit, repeats=max(1, args.repeats))
            rows.append(row)
            o, r = row["ours"], row["reference"]
            ok &= o["success"] and row["rel_error"] < 1e-4
            print(f"{key:4s} {N:4d} {'y' if args.jit else 'n':>3s} {o['objective']:10.6f} {row['rel_error']:8.1e} "
                  f"{o['iterations']:3d} {r['iterations']:6d} {o['solve_time_s'] * 1e3:8.1f} "
                  f"{r['solve_time_s'] * 1e3:8.1f} {row['time_ratio']:5.2f} {o['setup_time_s'] * 1e3:8.1f} "
                  f"{r['setup_time_s'] * 1e3:9.1f} {o['verification_error']:8.1e}", flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "jit": args.jit, "repeats": args.repeats}, indent=1))
    print(f"wrote {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
