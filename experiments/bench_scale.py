#!/usr/bin/env python3
"""Gait planning for robots of 5–10 coordinates against a hand-written reference (issue 19).

For every member of ``experiments/scale_tasks.py`` (wheeled snakes with 3–8 links, carts with
1–6 trailers, the two-steering snakeboard; forward tasks written as users write them):

* **cold** — ``nhgait plan <scene> --no-gif`` in a fresh process with an empty cache:
  derive + specialise + build + the code that is ready at once (the fast compiler's library) +
  solve + verify; its wall time, the longest time between two progress lines on stderr ("no
  phase silent for more than 10 s"), the peak resident memory of the process tree, the
  generated C, which code solved, the verdict; then **the background build** it started (gcc
  -O1/-O0, waited for: its seconds and the compiler's peak memory) and **the same plan warm**
  (the whole process again, the cache full): ``cold/warm`` (issue 25: ≤ 2) and cold against the
  reference's own set-up (build + gcc; issue 25: ≤ 0.25 for n ≥ 6) — the whole plan
  (``c/rsu``) and its set-up alone (``cs/rs``: derivation, specialisation, the NLP's build and
  the code ready at once, in the plan's process, beside the reference's build and compile)
  (``experiments/plan_process.py``);
* **warm solve** — in this process, the cache filled by the cold run: the planner's NLP solved again
  from its winning guess (median of ``--repeats``) on the threads a plan's solver child gets
  (``openmp.share(1)``: the stage maps' OpenMP loops) and on one thread, interleaved with the
  reference NLP of
  ``experiments/reference_scale_ocp.py`` (independent model, Ipopt, exact Hessian, gcc -O1,
  its own guess); ratio of the medians, iterations, objectives (relative difference);
* ``--hessians`` — the warm solve with each Hessian (exact, gauss-newton, limited-memory) and
  each solver, same guess: the measurement behind ``hessian="auto"``.

Writes ``out/bench_scale.json``; prints one table. Ratios are measured in one run on one
machine; compare ratios, not absolute times.

Usage: python experiments/bench_scale.py [--members snake_3,cart_trailers_1] [--repeats 5]
       [--hessians] [--no-reference] [--timeout 600] [--intervals N] [--no-jit]
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
import plan_process  # experiments/plan_process.py: nhgait plan cold and warm, measured from outside
import sibling  # experiments/sibling.py: the other scripts, loaded by file path


def cold(member: str, folder: Path, cache: Path, timeout: float, extra: tuple = ()) -> dict:
    """``nhgait plan`` of ``member`` in a fresh process with the empty cache ``cache``, its
    background build, then the same command warm (:func:`plan_process.cold_and_warm`);
    ``extra``: more command-line options (``--intervals``, ``--no-jit``)."""
    scene = folder / f"{member}.toml"
    scene.write_text(sibling.load("scale_tasks").scene_with_task(member))
    (folder / member).mkdir(exist_ok=True)
    return {"member": member, **plan_process.cold_and_warm([scene, *extra], folder / member, cache, timeout)}


@dataclasses.dataclass(frozen=True)
class Settings:
    """How the planner's NLP is solved: ``solver`` and ``hessian`` (SolverOptions), ``intervals``
    (None: the task's), ``jit`` ("optimised": the optimised library, built now if the cold run's
    background build did not finish; False: interpreted) and ``coarse`` (the coarse grid first:
    as the cold plan solved its winning guess, :mod:`nhgait.ocp.coarse`)."""

    solver: str = "ipopt"
    hessian: str = "exact"
    intervals: int | None = None
    jit: bool | str | None = "optimised"
    coarse: bool = False


class Ours:
    """The planner's NLP of a member, built from the warm cache; :meth:`run` solves it from the
    guess the cold run won with."""

    def __init__(self, member, guess_label, settings: Settings, reference=None, threads: int = 1):
        from nhgait.dynamics.derivation.input.scene import scene_from_text
        from nhgait.gaits.planner import prepare
        from nhgait.gaits.planning.guesses import candidates
        from nhgait.gaits.tasks.sources import resolve
        from nhgait.ocp import OCPSolver, SolverOptions
        scene = scene_from_text(sibling.load("scale_tasks").scene_with_task(member), member)
        overrides = [f"intervals={settings.intervals}"] if settings.intervals else []
        problem = prepare(resolve(scene, overrides=overrides)).problem
        self.solver = OCPSolver(problem, None, SolverOptions(solver=settings.solver, hessian=settings.hessian,
                                                             max_iter=500, jit=settings.jit,
                                                             coarse=settings.coarse))
        guesses = candidates(problem)
        self.guess = next((g for g in guesses if g.label == guess_label), guesses[0])
        if reference is not None:                 # the reference's own guess, when the states agree
            self.guess = _reference_guess(reference.ref, problem)
        self.runs, self.threads = [], threads

    def run(self):
        if self.threads == 1:
            self.runs.append(self.solver.solve(self.guess))
            return
        # as the planner: in a solver child, on its share of the cores
        from nhgait.gaits.planning.search import solve_attempts
        self.runs.append(solve_attempts(self.solver, [self.guess])[0])

    def result(self) -> dict:
        last = self.runs[-1]
        return {"solve_ms": statistics.median(r.solve_time_s for r in self.runs) * 1e3,
                "function_ms": statistics.median(r.function_time_s for r in self.runs) * 1e3,
                "iterations": last.iterations, "coarse_iterations": last.stats.get("coarse_iterations"),
                "coarse_intervals": last.stats.get("coarse_intervals"),
                "objective": last.objective, "success": last.success,
                "status": last.status, "setup_s": self.solver.setup_time_s, "compiled": self.solver.compiled,
                "threads": self.threads}


def _reference_guess(ref, problem):
    """The hand-written reference's initial guess as an InitialGuess of ``problem``: the same
    states when the planner chose the same velocity states (q, u_ind), else ValueError."""
    from nhgait.ocp.solver import InitialGuess
    names = list(ref.ode.coordinates) + [f"{s}_dot" for s in ref.ode.independent]   # u_s = ṡ
    if names != list(problem.state_names):
        raise ValueError(f"states differ: reference {names}, planner {list(problem.state_names)}")
    Z, U = ref._unpack(ref.w0)
    return InitialGuess(np.asarray(Z, float), np.asarray(U, float), label="reference's guess")


class Reference:
    def __init__(self, member, intervals=None, jit=True):
        self.ref = sibling.load("reference_scale_ocp").build(member, N=intervals, jit=jit)
        self.runs = []

    def run(self):
        self.runs.append(self.ref.solve())

    def result(self) -> dict:
        last = self.runs[-1]
        return {"solve_ms": statistics.median(r["solve_s"] for r in self.runs) * 1e3,
                "iterations": last["iterations"], "objective": last["objective"], "success": last["success"],
                "setup_s": self.ref.setup_s, "compile_s": self.ref.compile_s, "c_bytes": self.ref.c_bytes,
                "n_states": self.ref.n_states}


def interleaved(runners, repeats) -> list:
    for _ in range(repeats):
        for r in runners:
            r.run()
    return [r.result() for r in runners]


def warm(row: dict, repeats: int, reference: bool, hessians: bool, intervals=None, jit=True) -> dict:
    """The warm-cache solves of one member (module docstring)."""
    member = row["member"]
    cold = Settings(row.get("solver") or "ipopt", row.get("hessian") or "exact", intervals,
                    "optimised" if jit else False, bool(row.get("coarse", False)))
    from nhgait.dynamics.numerics import openmp
    threads = openmp.share(1)               # a plan's solver child's (its stage maps' OpenMP)
    runners = {"ours": Ours(member, row.get("guess"), cold, threads=threads),
               "ours, one thread": Ours(member, row.get("guess"), cold)}
    if reference:
        runners["reference"] = Reference(member, intervals, jit)
        try:
            runners["ours, reference's guess"] = Ours(member, None, cold, reference=runners["reference"],
                                                      threads=threads)
        except ValueError as exc:
            print(f"# {member}: no same-guess run ({exc})", file=sys.stderr)
    if hessians:
        for solver, hessian in (("ipopt", "exact"), ("ipopt", "gauss-newton"), ("ipopt", "limited-memory"),
                                ("fatrop", "exact"), ("fatrop", "gauss-newton")):
            runners[f"{solver}/{hessian}"] = Ours(member, row.get("guess"),
                                                  dataclasses.replace(cold, solver=solver, hessian=hessian))
    results = dict(zip(runners, interleaved(list(runners.values()), repeats), strict=True))
    out = {"warm_solve": results["ours"], "warm_solve_one_thread": results["ours, one thread"]}
    if reference:
        r = results["reference"]
        out.update(reference=r, ratio=results["ours"]["solve_ms"] / r["solve_ms"],
                   ratio_one_thread=results["ours, one thread"]["solve_ms"] / r["solve_ms"],
                   rel_objective=(row.get("objective", float("nan")) - r["objective"]) / abs(r["objective"]),
                   cold_over_reference_setup=row["cold_s"] / r["setup_s"],
                   cold_setup_over_reference_setup=cold_setup_s(row) / r["setup_s"])
        same = results.get("ours, reference's guess")
        if same is not None:
            out.update(same_guess=same, same_guess_ratio=same["solve_ms"] / r["solve_ms"])
    if hessians:
        out["hessians"] = {k: v for k, v in results.items() if "/" in k}
    return out


def cold_setup_s(row: dict) -> float:
    """The cold plan's own set-up, in its process: derivation and specialisation (``prepare_s``)
    and the NLP's build and the code that is ready at once (``setup_s``) — what the reference's
    ``setup_s`` (its NLP built and compiled) is beside; NaN when the plan did not report them."""
    phases = row.get("phases") or {}
    return float(phases.get("prepare_s", float("nan"))) + float(phases.get("setup_s", float("nan")))


def _line(r: dict) -> str:
    if "objective" not in r:
        return f"{r['member']:24s} {r.get('status', 'failed')}"
    ref, bg = r.get("reference", {}), r.get("background", {})
    nan = float("nan")
    return (f"{r['member']:24s} {r['cold_s']:6.1f} {r.get('warm_s', nan):6.1f} "
            f"{r.get('cold_over_warm', nan):5.2f} "
            f"{ref.get('setup_s', nan):6.1f} {r.get('cold_over_reference_setup', nan):5.2f} "
            f"{cold_setup_s(r):5.2f} {r.get('cold_setup_over_reference_setup', nan):5.3f} "
            f"{r['max_silent_s']:6.1f} {r['peak_mb']:6.0f} {r['code']:>11s} {r['compile_s']:5.2f} "
            f"{' '.join(bg.get('flags') or ['-']):>4s} {bg.get('compile_s') or nan:6.1f} "
            f"{bg.get('peak_mb') or nan:6.0f} "
            f"{r['c_bytes'] / 1e6:5.2f} {ref.get('c_bytes', 0) / 1e6:5.2f} "
            f"{r.get('warm_solve', {}).get('solve_ms', nan):8.1f} {ref.get('solve_ms', nan):8.1f} "
            f"{r.get('ratio', nan):5.2f} {r.get('ratio_one_thread', nan):5.2f} "
            f"{r.get('warm_solve', {}).get('iterations', -1):4d} "
            f"{ref.get('iterations', -1):4d} {r.get('same_guess', {}).get('iterations', -1):4d} "
            f"{r.get('same_guess_ratio', nan):5.2f} {r['objective']:10.6f} "
            f"{r.get('rel_objective', nan):9.1e} "
            f"{r.get('verification_error') or nan:8.1e} {r['solver']}/{r['hessian']} {r['status']}")


HEADER = (f"{'member':24s} {'cold s':>6s} {'warm s':>6s} {'c/w':>5s} {'ref su':>6s} {'c/rsu':>5s} "
          f"{'c su':>5s} {'cs/rs':>5s} "
          f"{'silent':>6s} {'RSS MB':>6s} {'code':>11s} {'now s':>5s} {'bg':>4s} {'bg s':>6s} {'bg MB':>6s} "
          f"{'C MB':>5s} {'ref C':>5s} {'warm ms':>8s} {'ref ms':>8s} {'ratio':>5s} {'1 thr':>5s} {'it':>4s} "
          f"{'r it':>4s} "
          f"{'sg it':>4s} {'sg r':>5s} {'objective':>10s} {'rel J':>9s} {'verify':>8s} solver/hessian status")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", default=",".join(sibling.load("scale_tasks").MEMBERS))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds for one cold run")
    ap.add_argument("--hessians", action="store_true", help="also every Hessian and solver, warm")
    ap.add_argument("--no-reference", action="store_true", help="skip the hand-written reference")
    ap.add_argument("--intervals", type=int, default=None, help="N for every member (default: the task's)")
    ap.add_argument("--no-jit", action="store_true",
                    help="interpreted NLPs, ours and the reference (smoke test)")
    ap.add_argument("--out", default="out/bench_scale.json")
    args = ap.parse_args(argv)
    extra = ((f"--intervals={args.intervals}",) if args.intervals else ()) + (("--no-jit",)
                                                                              if args.no_jit else ())
    rows = []
    print(HEADER, flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-scale-") as tmp:
        for member in [m.strip() for m in args.members.split(",") if m.strip()]:
            cache = Path(tmp) / f"cache-{member}"
            print(f"# {member}: cold nhgait plan …", file=sys.stderr, flush=True)
            row = cold(member, Path(tmp), cache, args.timeout, extra)
            if "objective" in row:
                os.environ["NHGAIT_CACHE_DIR"] = str(cache)
                os.environ["NHGAIT_BACKGROUND_BUILDS"] = "0"       # this process leaves no builder
                if row.get("background", {}).get("state") not in ("built", "none", "unavailable"):
                    print(f"# {member}: the optimised build is {row['background']}: the warm solve is not "
                          "on the optimised library", file=sys.stderr, flush=True)
                print(f"# {member}: warm solves{'' if args.no_reference else ' and the reference'} …",
                      file=sys.stderr, flush=True)
                row.update(warm(row, args.repeats, not args.no_reference, args.hessians, args.intervals,
                                not args.no_jit))
            rows.append(row)
            print(_line(row), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "repeats": args.repeats}, indent=1, default=str))
    print(f"wrote {out}")
    return 0 if all(r.get("success") for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
