#!/usr/bin/env python3
"""Is FATROP as robust as Ipopt on every planning task? (the condition for making it the default)

For each task (the four built-ins and the three example scenes), each N and each of the first
``--candidates`` initial guesses of the planner, solve with Ipopt (multiple shooting) and with
FATROP (stage-ordered shooting), both interpreted (robustness does not depend on compiling),
500 iterations each; count successes, and whether both reach the same objective (1e-6
relative). Writes ``out/robustness_fatrop.json``.

Usage: python experiments/robustness_fatrop.py [--N 25,50,100] [--candidates 4]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TASKS = [("unicycle", "parallel-park"), ("snakeboard", "forward"), ("snakeboard", "rotate"),
         ("snakeboard", "lateral"), (str(ROOT / "examples" / "car.toml"), None),
         (str(ROOT / "examples" / "cart_trailer.toml"), None),
         (str(ROOT / "examples" / "rotor_sleigh.toml"), None)]


def main(argv=None) -> int:
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.ocp import OCPSolver, SolverOptions

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", default="25,50,100")
    ap.add_argument("--candidates", type=int, default=4)
    ap.add_argument("--out", default="out/robustness_fatrop.json")
    args = ap.parse_args(argv)
    rows = []
    print(f"{'task':32s} {'N':>4s} {'guess':42s} {'ipopt':>22s} {'fatrop':>22s} same")
    for scene, gait in TASKS:
        for N in [int(n) for n in args.N.split(",")]:
            to_plan = resolve(scene, gait, overrides=[f"intervals={N}"])
            problem = prepare(to_plan).problem
            solvers = {s: OCPSolver(problem, None, SolverOptions(jit=False, solver=s, max_iter=500))
                       for s in ("ipopt", "fatrop")}
            for guess in candidates(problem)[:args.candidates]:
                res = {s: S.solve(guess) for s, S in solvers.items()}
                i, f = res["ipopt"], res["fatrop"]
                same = i.success and f.success and abs(i.objective - f.objective) <= 1e-6 * abs(i.objective)
                rows.append({"task": to_plan.label, "N": N, "guess": guess.label,
                             **{s: {"success": r.success, "iterations": r.iterations,
                                    "objective": r.objective, "status": r.status} for s, r in res.items()},
                             "same_optimum": same})
                print(f"{to_plan.label:32s} {N:4d} {guess.label[:42]:42s} "
                      f"{str(i.success):>5s} {i.iterations:4d} {i.objective:11.6f} "
                      f"{str(f.success):>5s} {f.iterations:4d} {f.objective:11.6f} {same}", flush=True)
    summary = {s: sum(r[s]["success"] for r in rows) for s in ("ipopt", "fatrop")}
    only = {"ipopt_only": sum(r["ipopt"]["success"] and not r["fatrop"]["success"] for r in rows),
            "fatrop_only": sum(r["fatrop"]["success"] and not r["ipopt"]["success"] for r in rows),
            "same_optimum": sum(r["same_optimum"] for r in rows), "solves": len(rows)}
    print(f"successes of {len(rows)}: {summary}; {only}")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "successes": summary, **only}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
