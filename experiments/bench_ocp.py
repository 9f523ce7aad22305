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

* ``cold``: the whole ``nhgait plan`` process with an empty cache, then the same plan warm
  (``experiments/plan_process.py``), beside the reference's own set-up (build + gcc -O1).

Usage: python experiments/bench_ocp.py [--quick] [--N 25,50] [--problems P1,P2]
       [--sections default,fatrop,collocation,cold] [--repeats 5]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import re
import statistics
import sys
import time
from pathlib import Path

import plan_process  # experiments/plan_process.py: nhgait plan cold and warm, measured from outside
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

PROBLEMS = {"P1": ("unicycle", "parallel-park"), "P2": ("snakeboard", "forward"),
            "P3": ("snakeboard", "rotate")}


def _reference():
    return sibling.load("reference_casadi_ocp")


class Ours:
    """The planner's NLP built once (its own winning guess, or ``guess_label``); :meth:`run`
    solves it once more from that guess."""

    def __init__(self, key, N, *, solver=None, transcription=None, jit=None, guess_label=None):
        from nhgait.gaits.planner import prepare
        from nhgait.gaits.planning.guesses import candidates
        from nhgait.gaits.planning.options import solver_order
        from nhgait.gaits.planning.search import solve_from_guesses
        from nhgait.gaits.tasks.sources import resolve
        from nhgait.ocp import OCPSolver, SolverOptions
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


@dataclasses.dataclass(frozen=True)
class Section:
    """One comparison of the benchmark: its heading, its printed columns ((title, format) pairs)
    and ``measure(ref, key, N, repeats)`` → (JSON row, passed, the columns' values) for one
    problem and N."""

    heading: str
    columns: tuple
    measure: object

    def header(self) -> str:
        return " ".join(f"{title:>{_width(spec)}s}" for title, spec in self.columns)

    def line(self, values) -> str:
        return " ".join(format(value, spec) for (_, spec), value in zip(self.columns, values, strict=True))


def _width(spec: str) -> int:
    digits = re.match(r"\d*", spec).group()
    return int(digits) if digits else 0


def _default_row(ref, key, N, repeats):
    default = Ours(key, N)
    o, i, r = interleaved([default, Ours(key, N, solver="ipopt", guess_label=default.guess.label),
                           Reference(ref, key, N)], repeats)
    rel = abs(o["objective"] - ref.REFERENCE[key][N]) / ref.REFERENCE[key][N] if N in ref.REFERENCE[key] \
        else abs(o["objective"] - r["objective"]) / abs(r["objective"])
    ratio = o["solve_time_s"] / r["solve_time_s"]
    ratio_i = i["solve_time_s"] / r["solve_time_s"]
    row = {"section": "default", "problem": key, "N": N, "ours": o, "ours_ipopt": i,
           "reference": r, "rel_error": rel, "time_ratio": ratio, "ipopt_time_ratio": ratio_i}
    values = [key, N, o["objective"], rel, o["iterations"], r["iterations"], o["solve_time_s"] * 1e3,
              r["solve_time_s"] * 1e3, ratio, i["solve_time_s"] * 1e3, ratio_i, o["setup_time_s"] * 1e3,
              r["setup_time_s"] * 1e3, o["verification_error"], " " + o["guess"]]
    return row, o["success"] and rel < 1e-4, values


def _fatrop_row(ref, key, N, repeats):
    ipopt = Ours(key, N, solver="ipopt")
    fatrop = Ours(key, N, solver="fatrop", guess_label=ipopt.guess.label)
    i, f, r = interleaved([ipopt, fatrop, Reference(ref, key, N)], repeats)
    rel = abs(f["objective"] - i["objective"]) / abs(i["objective"])
    row = {"section": "fatrop", "problem": key, "N": N, "fatrop": f, "ipopt": i, "reference": r,
           "rel_diff": rel, "speedup_vs_reference": r["solve_time_s"] / f["solve_time_s"],
           "speedup_vs_ipopt": i["solve_time_s"] / f["solve_time_s"]}
    values = [key, N, f["objective"], rel, f["iterations"], i["iterations"]]
    values += [x[name] * 1e3 for x in (f, i) for name in ("solve_time_s", "function_time_s", "solver_time_s")]
    values += [r["solve_time_s"] * 1e3, r["solve_time_s"] / f["solve_time_s"],
               i["solve_time_s"] / f["solve_time_s"]]
    return row, f["success"] and rel < 1e-6, values


def _collocation_row(ref, key, N, repeats):
    shooting = Ours(key, N, solver="ipopt")
    colloc = Ours(key, N, solver="ipopt", transcription="collocation", guess_label=shooting.guess.label)
    m, c = interleaved([shooting, colloc], repeats)
    ratio = c["solve_time_s"] / m["solve_time_s"]
    row = {"section": "collocation", "problem": key, "N": N, "shooting": m, "collocation": c,
           "time_ratio": ratio}
    values = [key, N, m["objective"], c["objective"], m["iterations"], c["iterations"],
              m["solve_time_s"] * 1e3, c["solve_time_s"] * 1e3, ratio, c["setup_time_s"] * 1e3]
    return row, c["success"], values


def _cold_row(ref, key, N, repeats):
    """``nhgait plan`` of the problem in a fresh process with an empty cache, its background
    build, the same plan warm (:func:`plan_process.cold_and_warm`) and the reference's own
    set-up (build + gcc -O1) of the same problem (issue 25: cold ≤ 2× warm)."""
    import tempfile
    system, gait = PROBLEMS[key]
    with tempfile.TemporaryDirectory(prefix="bench-ocp-cold-") as tmp:
        row = plan_process.cold_and_warm([system, "--gait", gait, "--intervals", N], Path(tmp),
                                         Path(tmp) / "cache", timeout=900.0)
    setup = ref.solve(key, N, jit=True)["setup_time_s"]
    nan, bg = float("nan"), row.get("background", {})
    row.update(section="cold", problem=key, N=N, reference_setup_s=setup,
               cold_over_reference_setup=row.get("cold_s", nan) / setup)
    values = [key, N, row.get("cold_s", nan), row.get("warm_s", nan), row.get("cold_over_warm", nan),
              " " + str(row.get("code")), row.get("compile_s") or 0.0,
              " " + " ".join(bg.get("flags") or ["-"]),
              bg.get("compile_s") or nan, bg.get("peak_mb") or nan, row.get("peak_mb", nan), setup,
              row["cold_over_reference_setup"], " " + str(row.get("status"))]
    return row, bool(row.get("success")) and (row.get("warm") or {}).get("success", False), values


_PROBLEM = (("prob", "4s"), ("N", "4d"))
_MS = "8.1f"
SECTIONS = {
    "default": Section(
        "default nhgait plan (auto = FATROP, compiled, own guess) and our Ipopt path (compiled) vs the "
        "hand-written reference (Ipopt, compiled, its guess)",
        _PROBLEM + (("objective", "10.6f"), ("rel err", "8.1e"), ("it", "3d"), ("ref it", "6d"),
                    ("ours ms", _MS),
                    ("ref ms", _MS), ("ratio", "5.2f"), ("ipopt ms", _MS), ("ratio", "5.2f"),
                    ("setup ms", _MS), ("ref setup", "9.1f"), ("verify", "8.1e"), (" guess", "")),
        _default_row),
    "fatrop": Section(
        "FATROP (stage-ordered, compiled) vs our Ipopt (compiled) vs the reference's Ipopt "
        "(compiled); same guess",
        _PROBLEM + (("J fatrop", "10.6f"), ("rel diff", "8.1e"), ("it F", "4d"), ("it I", "4d"),
                    ("fatrop ms", "9.1f"),
                    ("(fun", "6.1f"), ("solver)", "7.1f"), ("ipopt ms", _MS), ("(fun", "6.1f"),
                    ("solver)", "7.1f"), ("ref ms", _MS), ("ref/F", "5.2f"), ("ipopt/F", "7.2f")),
        _fatrop_row),
    "collocation": Section(
        "collocation (Legendre, degree 3) vs multiple shooting, both ours compiled, same guess",
        _PROBLEM + (("J shooting", "10.6f"), ("J colloc", "10.6f"), ("it MS", "5d"), ("it C", "4d"),
                    ("MS ms", _MS), ("coll ms", _MS), ("ratio", "5.2f"), ("coll setup ms", "13.1f")),
        _collocation_row),
    "cold": Section(
        "cold nhgait plan (empty cache, whole process) vs the same plan warm, and vs the reference's set-up "
        "(build + gcc -O1); the code that solved cold and the background build it started",
        _PROBLEM + (("cold s", "7.1f"), ("warm s", "7.1f"), ("c/w", "5.2f"), (" code", "12s"),
                    ("now s", "6.2f"),
                    (" bg", "5s"), ("bg s", "6.1f"), ("bg MB", "6.0f"), ("RSS MB", "7.0f"),
                    ("ref setup s", "11.1f"), ("c/rsu", "6.2f"), (" status", "")),
        _cold_row),
}


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
    chosen = [s.strip() for s in args.sections.split(",") if s.strip()]
    rows, ok = [], True
    for name in SECTIONS:                   # the sections in their own order, as before
        if name not in chosen:
            continue
        section = SECTIONS[name]
        print(f"\n# {section.heading}")
        print(section.header())
        for key in keys:
            for N in Ns:
                row, passed, values = section.measure(ref, key, N, args.repeats)
                rows.append(row)
                ok &= passed
                print(section.line(values), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "repeats": args.repeats}, indent=1, default=float))
    print(f"wrote {out}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
