#!/usr/bin/env python3
"""Benchmark of the nhgait gait planner against the hand-written CasADi reference.

Sections (all in one process, so every ratio is measured in one run on the same machine):

* ``default``: the default ``nhgait plan`` path (velocity-coordinate model, ``--solver auto``
  = FATROP on the stage-ordered multiple shooting, compiled NLP functions from the
  content-hash cache, the planner's own winning guess) against
  ``experiments/reference_casadi_ocp.py`` compiled (``--jit``: CasADi's jit, gcc -O1, Ipopt),
  which uses its own hand-made guess; and, in the same rows, our Ipopt path (compiled);
* ``fatrop``: the same problem solved by FATROP on the stage-ordered transcription (compiled),
  against our Ipopt and the reference's compiled Ipopt; same optimum (relative difference of
  the objectives) and the time split into function evaluations and solver;
* ``collocation``: Legendre collocation (degree 3) against multiple shooting, both ours
  compiled.

P1 (unicycle parallel-park), P2 (snakeboard forward), P3 (snakeboard rotate) at
N = 25, 50, 100, 200; each time is the median of ``--repeats`` solves of the built NLP (set-up
reported apart), the solvers of one row taking turns (a, b, a, b, …) so that a shared
machine's load falls on all alike. Writes ``out/bench_ocp.json``. Compare ratios, not
absolute times.

Usage: python experiments/bench_ocp.py [--quick] [--N 25,50] [--problems P1,P2]
       [--sections default,fatrop,collocation] [--repeats 5]
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
SECTIONS = ("default", "fatrop", "collocation")


def _reference():
    spec = importlib.util.spec_from_file_location("reference_casadi_ocp", HERE / "reference_casadi_ocp.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


class Ours:
    """The planner's NLP built once (its own winning guess, or ``guess_label``); :meth:`run`
    solves it once more from that guess."""

    def __init__(self, key, N, *, solver=None, transcription=None, jit=None, guess_label=None):
        from nhgait.gaits.guesses import candidates
        from nhgait.gaits.planner import prepare
        from nhgait.gaits.search import solve_from_guesses
        from nhgait.gaits.task_library import resolve
        from nhgait.ocp import OCPSolver, SolverOptions

        from nhgait.gaits.planner import solver_order
        solver = solver or solver_order("auto", transcription)[0]
        system, gait = PROBLEMS[key]
        t0 = time.perf_counter()
        problem = prepare(resolve(system, gait, overrides=[f"intervals={N}"])).problem
        self.model_time = time.perf_counter() - t0
        self.solver = OCPSolver(problem, transcription, SolverOptions(jit=jit, solver=solver, max_iter=500))
        guesses = candidates(problem)
        if guess_label is None:
            guess_label = solve_from_guesses(self.solver, guesses).won
        self.guess = next(g for g in guesses if g.label == guess_label)
        self.runs = []

    def run(self):
        self.runs.append(self.solver.solve(self.guess))

    def result(self) -> dict:
        runs, S = self.runs, self.solver
        sol = runs[-1].verified()
        return {"objective": sol.objective, "iterations": sol.iterations, "success": sol.success,
                "solve_time_s": statistics.median(r.solve_time_s for r in runs),
                "function_time_s": statistics.median(r.function_time_s for r in runs),
                "solver_time_s": statistics.median(r.solver_time_s for r in runs),
                "setup_time_s": S.setup_time_s, "model_time_s": self.model_time, "compiled": S.compiled,
                "jit_cached": S.jit_cached, "verification_error": sol.verification_error,
                "guess": self.guess.label}


class Reference:
    """The hand-written reference (compiled): built once by its own cache, one solve per :meth:`run`."""

    def __init__(self, ref, key, N, *, jit=True):
        self.ref, self.key, self.N, self.jit = ref, key, N, jit
        self.runs = []

    def run(self):
        self.runs.append(self.ref.solve(self.key, self.N, jit=self.jit))

    def result(self) -> dict:
        runs = self.runs
        r = runs[-1]
        return {"objective": r["objective"], "iterations": r["iterations"], "success": r["success"],
                "solve_time_s": statistics.median(x["solve_time_s"] for x in runs),
                "solver_time_s": statistics.median(x["ipopt_time_s"] for x in runs),
                "setup_time_s": r["setup_time_s"]}


def interleaved(runners, repeats) -> list:
    """Solve each runner ``repeats`` times in turn (a, b, c, a, b, c, …) so that the load of a
    shared machine falls on all of them alike; returns their results."""
    for _ in range(repeats):
        for r in runners:
            r.run()
    return [r.result() for r in runners]


def _ms(x):
    return f"{x * 1e3:8.1f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="P1,P2,P3")
    ap.add_argument("--N", default="25,50,100,200")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sections", default=",".join(SECTIONS))
    ap.add_argument("--quick", action="store_true", help="smoke run: N = 25, 2 repeats")
    ap.add_argument("--out", default="out/bench_ocp.json")
    args = ap.parse_args(argv)
    if args.quick:
        args.N, args.repeats = "25", 2
    ref = _reference()
    keys = [p.strip() for p in args.problems.split(",") if p.strip()]
    Ns = [int(n) for n in args.N.split(",") if n.strip()]
    sections = [s.strip() for s in args.sections.split(",") if s.strip()]
    rows, ok = [], True
    if "default" in sections:
        print("\n# default nhgait plan (auto = FATROP, compiled, own guess) and our Ipopt path (compiled) vs the "
              "hand-written reference (Ipopt, compiled, its guess)")
        print(f"{'prob':4s} {'N':>4s} {'objective':>10s} {'rel err':>8s} {'it':>3s} {'ref it':>6s} {'ours ms':>8s} "
              f"{'ref ms':>8s} {'ratio':>5s} {'ipopt ms':>8s} {'ratio':>5s} {'setup ms':>8s} {'ref setup':>9s} "
              f"{'verify':>8s}  guess")
        for key in keys:
            for N in Ns:
                default = Ours(key, N)
                o, i, r = interleaved([default, Ours(key, N, solver="ipopt", guess_label=default.guess.label),
                                       Reference(ref, key, N)], args.repeats)
                rel = abs(o["objective"] - ref.REFERENCE[key][N]) / ref.REFERENCE[key][N] if N in ref.REFERENCE[key] \
                    else abs(o["objective"] - r["objective"]) / abs(r["objective"])
                ratio = o["solve_time_s"] / r["solve_time_s"]
                ok &= o["success"] and rel < 1e-4
                ratio_i = i["solve_time_s"] / r["solve_time_s"]
                rows.append({"section": "default", "problem": key, "N": N, "ours": o, "ours_ipopt": i,
                             "reference": r, "rel_error": rel, "time_ratio": ratio, "ipopt_time_ratio": ratio_i})
                print(f"{key:4s} {N:4d} {o['objective']:10.6f} {rel:8.1e} {o['iterations']:3d} {r['iterations']:6d} "
                      f"{_ms(o['solve_time_s'])} {_ms(r['solve_time_s'])} {ratio:5.2f} {_ms(i['solve_time_s'])} "
                      f"{ratio_i:5.2f} {_ms(o['setup_time_s'])} {r['setup_time_s'] * 1e3:9.1f} "
                      f"{o['verification_error']:8.1e}  {o['guess']}", flush=True)
    if "fatrop" in sections:
        print("\n# FATROP (stage-ordered, compiled) vs our Ipopt (compiled) vs the reference's Ipopt (compiled); same guess")
        print(f"{'prob':4s} {'N':>4s} {'J fatrop':>10s} {'rel diff':>8s} {'it F':>4s} {'it I':>4s} {'fatrop ms':>9s} "
              f"{'(fun':>6s} {'solver)':>7s} {'ipopt ms':>8s} {'(fun':>6s} {'solver)':>7s} {'ref ms':>8s} "
              f"{'ref/F':>5s} {'ipopt/F':>7s}")
        for key in keys:
            for N in Ns:
                ipopt = Ours(key, N, solver="ipopt")
                fatrop = Ours(key, N, solver="fatrop", guess_label=ipopt.guess.label)
                i, f, r = interleaved([ipopt, fatrop, Reference(ref, key, N)], args.repeats)
                rel = abs(f["objective"] - i["objective"]) / abs(i["objective"])
                ok &= f["success"] and rel < 1e-6
                rows.append({"section": "fatrop", "problem": key, "N": N, "fatrop": f, "ipopt": i, "reference": r,
                             "rel_diff": rel, "speedup_vs_reference": r["solve_time_s"] / f["solve_time_s"],
                             "speedup_vs_ipopt": i["solve_time_s"] / f["solve_time_s"]})
                print(f"{key:4s} {N:4d} {f['objective']:10.6f} {rel:8.1e} {f['iterations']:4d} {i['iterations']:4d} "
                      f"{f['solve_time_s'] * 1e3:9.1f} {f['function_time_s'] * 1e3:6.1f} {f['solver_time_s'] * 1e3:7.1f} "
                      f"{_ms(i['solve_time_s'])} {i['function_time_s'] * 1e3:6.1f} {i['solver_time_s'] * 1e3:7.1f} "
                      f"{_ms(r['solve_time_s'])} {r['solve_time_s'] / f['solve_time_s']:5.2f} "
                      f"{i['solve_time_s'] / f['solve_time_s']:7.2f}", flush=True)
    if "collocation" in sections:
        print("\n# collocation (Legendre, degree 3) vs multiple shooting, both ours compiled, same guess")
        print(f"{'prob':4s} {'N':>4s} {'J shooting':>10s} {'J colloc':>10s} {'it MS':>5s} {'it C':>4s} "
              f"{'MS ms':>8s} {'coll ms':>8s} {'ratio':>5s} {'coll setup ms':>13s}")
        for key in keys:
            for N in Ns:
                shooting = Ours(key, N, solver="ipopt")
                colloc = Ours(key, N, solver="ipopt", transcription="collocation", guess_label=shooting.guess.label)
                m, c = interleaved([shooting, colloc], args.repeats)
                ratio = c["solve_time_s"] / m["solve_time_s"]
                ok &= c["success"]
                rows.append({"section": "collocation", "problem": key, "N": N, "shooting": m, "collocation": c,
                             "time_ratio": ratio})
                print(f"{key:4s} {N:4d} {m['objective']:10.6f} {c['objective']:10.6f} {m['iterations']:5d} "
                      f"{c['iterations']:4d} {_ms(m['solve_time_s'])} {_ms(c['solve_time_s'])} {ratio:5.2f} "
                      f"{c['setup_time_s'] * 1e3:13.1f}", flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "repeats": args.repeats}, indent=1, default=float))
    print(f"wrote {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
