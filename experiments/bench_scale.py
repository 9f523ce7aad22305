#!/usr/bin/env python3
"""Gait planning for robots of 5–10 coordinates against a hand-written reference (issue 19).

For every member of ``experiments/scale_tasks.py`` (wheeled snakes with 3–8 links, carts with
1–6 trailers, the two-steering snakeboard; forward tasks written as users write them):

* **cold** — ``nhgait plan <scene> --no-gif`` in a fresh process with an empty cache:
  derive + specialise + build + compile + solve + verify; its wall time, the longest time
  between two progress lines on stderr ("no phase silent for more than 10 s"), the peak
  resident memory of the whole process tree (nhgait and the C compiler), the generated C,
  the compile flags and seconds, the verdict;
* **warm** — in this process, the cache filled by the cold run: the planner's NLP solved again
  from its winning guess (median of ``--repeats``), interleaved with the reference NLP of
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
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import sibling  # experiments/sibling.py: the other scripts, loaded by file path

#: prints the peak RSS (kB) of every process the command started (RUSAGE_CHILDREN)
_WRAPPER = ("import resource, subprocess, sys; rc = subprocess.call(sys.argv[1:]); "
            "print('PEAK_RSS_KB', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
            "sys.exit(rc)")


def _nhgait() -> list:
    exe = Path(sys.executable).with_name("nhgait")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "nhgait.gaits.cli.main"]


def cold(member: str, folder: Path, cache: Path, timeout: float, extra: tuple = ()) -> dict:
    """``nhgait plan`` in a fresh process with the empty cache ``cache`` (module docstring);
    ``extra``: more command-line options (``--intervals``, ``--no-jit``)."""
    scene = folder / f"{member}.toml"
    scene.write_text(sibling.load("scale_tasks").scene_with_task(member))
    out = folder / f"{member}_out"
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-c", _WRAPPER, *_nhgait(), "plan", str(scene), "--no-gif", "--out", str(out), *extra]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stamps, lines, peak = [t0], [], 0
    try:
        for line in proc.stderr:
            stamps.append(time.monotonic())
            lines.append(line.rstrip())
            m = re.match(r"PEAK_RSS_KB (\d+)", line)
            if m:
                peak = int(m.group(1))
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        return {"member": member, "status": f"cold run not finished in {timeout:.0f} s"}
    wall = time.monotonic() - t0
    stamps.append(time.monotonic())
    row = {"member": member, "exit": proc.returncode, "cold_s": wall, "peak_mb": peak / 1024.0,
           "max_silent_s": max(b - a for a, b in zip(stamps, stamps[1:])), "stderr_tail": lines[-5:]}
    path = out / "solution.json"
    if path.exists():
        data = json.loads(path.read_text())
        st = data["settings"]
        comp = st.get("compile") or {}
        row.update({"success": data["success"], "status": data["status"], "objective": data["objective"],
                    "iterations": data["iterations"], "guess": data["guess"]["won"],
                    "solver": st.get("solver"), "hessian": st.get("hessian"), "stage": st.get("stage"),
                    "ode_operations": st.get("ode_operations"), "c_bytes": comp.get("c_bytes", 0),
                    "flags": comp.get("flags"), "compile_s": comp.get("compile_s", 0.0),
                    "verification_error": (data.get("verification") or {}).get("max_error"),
                    "condition_error": (data.get("verification") or {}).get("max_condition_error"),
                    "velocities": st.get("velocities"), "phases": {k: st[k] for k in st if k.endswith("_s")}})
    return row


@dataclasses.dataclass(frozen=True)
class Settings:
    """How the planner's NLP is solved: ``solver`` and ``hessian`` (SolverOptions), ``intervals``
    (None: the task's) and ``jit`` (None: the solver's default)."""

    solver: str = "ipopt"
    hessian: str = "exact"
    intervals: int | None = None
    jit: bool | None = None


class Ours:
    """The planner's NLP of a member, built from the warm cache; :meth:`run` solves it from the
    guess the cold run won with."""

    def __init__(self, member, guess_label, settings: Settings, reference=None):
        from nhgait.dynamics.derivation.scene import scene_from_text
        from nhgait.gaits.guesses import candidates
        from nhgait.gaits.planner import prepare
        from nhgait.gaits.task_library import resolve
        from nhgait.ocp import OCPSolver, SolverOptions
        scene = scene_from_text(sibling.load("scale_tasks").scene_with_task(member), member)
        overrides = [f"intervals={settings.intervals}"] if settings.intervals else []
        problem = prepare(resolve(scene, overrides=overrides)).problem
        self.solver = OCPSolver(problem, None, SolverOptions(solver=settings.solver, hessian=settings.hessian,
                                                             max_iter=500, jit=settings.jit))
        guesses = candidates(problem)
        self.guess = next((g for g in guesses if g.label == guess_label), guesses[0])
        if reference is not None:                 # the reference's own guess, when the states agree
            self.guess = _reference_guess(reference.ref, problem)
        self.runs = []

    def run(self):
        self.runs.append(self.solver.solve(self.guess))

    def result(self) -> dict:
        last = self.runs[-1]
        return {"solve_ms": statistics.median(r.solve_time_s for r in self.runs) * 1e3,
                "function_ms": statistics.median(r.function_time_s for r in self.runs) * 1e3,
                "iterations": last.iterations, "objective": last.objective, "success": last.success,
                "status": last.status, "setup_s": self.solver.setup_time_s, "compiled": self.solver.compiled}


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
    cold = Settings(row.get("solver") or "ipopt", row.get("hessian") or "exact", intervals, None if jit else False)
    runners = {"ours": Ours(member, row.get("guess"), cold)}
    if reference:
        runners["reference"] = Reference(member, intervals, jit)
        try:
            runners["ours, reference's guess"] = Ours(member, None, cold, reference=runners["reference"])
        except ValueError as exc:
            print(f"# {member}: no same-guess run ({exc})", file=sys.stderr)
    if hessians:
        for solver, hessian in (("ipopt", "exact"), ("ipopt", "gauss-newton"), ("ipopt", "limited-memory"),
                                ("fatrop", "exact"), ("fatrop", "gauss-newton")):
            runners[f"{solver}/{hessian}"] = Ours(member, row.get("guess"),
                                                  dataclasses.replace(cold, solver=solver, hessian=hessian))
    results = dict(zip(runners, interleaved(list(runners.values()), repeats)))
    out = {"warm": results["ours"]}
    if reference:
        r = results["reference"]
        out.update(reference=r, ratio=results["ours"]["solve_ms"] / r["solve_ms"],
                   rel_objective=(row.get("objective", float("nan")) - r["objective"]) / abs(r["objective"]))
        same = results.get("ours, reference's guess")
        if same is not None:
            out.update(same_guess=same, same_guess_ratio=same["solve_ms"] / r["solve_ms"])
    if hessians:
        out["hessians"] = {k: v for k, v in results.items() if "/" in k}
    return out


def _line(r: dict) -> str:
    if "objective" not in r:
        return f"{r['member']:24s} {r.get('status', 'failed')}"
    w, ref = r.get("warm", {}), r.get("reference", {})
    return (f"{r['member']:24s} {r['cold_s']:6.1f} {r['max_silent_s']:6.1f} {r['peak_mb']:6.0f} "
            f"{r['c_bytes'] / 1e6:5.2f} {ref.get('c_bytes', 0) / 1e6:5.2f} {r['compile_s']:6.1f} "
            f"{ref.get('setup_s', float('nan')):6.1f} {w.get('solve_ms', float('nan')):8.1f} "
            f"{ref.get('solve_ms', float('nan')):8.1f} {r.get('ratio', float('nan')):5.2f} "
            f"{r.get('same_guess', {}).get('iterations', -1):4d} {r.get('same_guess_ratio', float('nan')):5.2f} "
            f"{w.get('iterations', -1):4d} {ref.get('iterations', -1):4d} {r['objective']:10.6f} "
            f"{r.get('rel_objective', float('nan')):9.1e} {r.get('verification_error') or float('nan'):8.1e} "
            f"{r['solver']}/{r['hessian']} {r['status']}")


HEADER = (f"{'member':24s} {'cold s':>6s} {'silent':>6s} {'RSS MB':>6s} {'C MB':>5s} {'ref C':>5s} "
          f"{'cc s':>6s} {'ref su':>6s} {'warm ms':>8s} {'ref ms':>8s} {'ratio':>5s} {'sg it':>4s} {'sg r':>5s} "
          f"{'it':>4s} {'r it':>4s} "
          f"{'objective':>10s} {'rel J':>9s} {'verify':>8s} solver/hessian status")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", default=",".join(sibling.load("scale_tasks").MEMBERS))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds for one cold run")
    ap.add_argument("--hessians", action="store_true", help="also every Hessian and solver, warm")
    ap.add_argument("--no-reference", action="store_true", help="skip the hand-written reference")
    ap.add_argument("--intervals", type=int, default=None, help="N for every member (default: the task's)")
    ap.add_argument("--no-jit", action="store_true", help="interpreted NLPs, ours and the reference (smoke test)")
    ap.add_argument("--out", default="out/bench_scale.json")
    args = ap.parse_args(argv)
    extra = ((f"--intervals={args.intervals}",) if args.intervals else ()) + (("--no-jit",) if args.no_jit else ())
    rows = []
    print(HEADER, flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-scale-") as tmp:
        for member in [m.strip() for m in args.members.split(",") if m.strip()]:
            cache = Path(tmp) / f"cache-{member}"
            print(f"# {member}: cold nhgait plan …", file=sys.stderr, flush=True)
            row = cold(member, Path(tmp), cache, args.timeout, extra)
            if "objective" in row:
                os.environ["NHGAIT_CACHE_DIR"] = str(cache)
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
