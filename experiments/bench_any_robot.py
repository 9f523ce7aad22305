#!/usr/bin/env python3
"""Robots nobody tuned the planner for, as a benchmark (issue 24, item 3).

For ``--pairs`` robot-and-task pairs of ``experiments/robot_generator.py`` (seed ``--seed``):

* **plan cold**: ``nhgait plan <scene> --no-gif`` — the whole process, in its own session, with a
  fresh empty ``NHGAIT_CACHE_DIR`` — under a wall-clock budget (``--budget`` s). When the planner
  has ``--time-limit`` it is passed the budget and given ``--grace`` s more to stop by itself
  (``--budget default``: the planner's own default budget for the robot's size, 120 s + 30 s per
  coordinate as issue 24 asks — not passed, the same grace);
  either way the process group is sent SIGTERM at the end of that time, and SIGKILL 2 s later
  (the row says whether SIGTERM was enough and whether anything of the group outlived it).
  The outcome: ``verified`` (exit 0, the re-simulation meets the task), ``failed`` with the
  planner's stated cause (its status and the first line of its message), ``infeasible`` (a
  solver proved it), ``budget`` (stopped by this script, or the planner's own time limit),
  ``rejected`` (exit 2: the planner called the scene bad input) or ``crash`` (any other exit);
  the time to the answer and where it went (the plan's own "wall time … in all" split: model, NLP
  set-up, guesses and solves, verification, figures, start-up), iterations, objective, the
  re-simulation error;
* **reference** (``experiments/reference_dae_ocp.py``: the Lagrange DAE in (q, q̇, λ), same N and
  horizon, Ipopt): from the planner's best point (its ``solution.json``: q, q̇, u) and from the
  reference's own guess, for every pair the planner does not verify (``--reference all``: every
  pair, which gives the "within 1 % of the reference" column for the verified ones too); its
  best converged answer is re-simulated independently (DOP853, rtol 1e-10) and counts as solved
  when that re-simulation meets the nodes and the task's conditions to ``--reference-tolerance``
  (default 1e-4 relative to the state's scale: a gait exists, to the accuracy RK4 has at this N;
  the planner's own verification asks 1e-6, so a pair whose dynamics N resolves only to 1e-5 is
  solvable here and a ``Verification_Failed`` there, with that cause) — the reference's verdict
  decides whether a pair is solvable.

Writes ``table.csv``, ``table.md`` and ``results.json`` into ``--out`` (each pair's scene, the
planner's log and its ``solution.json`` under ``pairs/<name>/``); the summary gives the success
rate over the pairs the reference solves, the pairs within 1 % of the reference objective, the
failures by cause and the distribution of the time to answer. ``--reference-only`` runs the
reference on the plans of an earlier run (``--plans``, default ``--out``) and writes the whole
table again. Progress goes to stderr (``--quiet``: none).

Usage: python experiments/bench_any_robot.py [--seed 24] [--pairs 40] [--intervals 40]
       [--budget 120|default] [--out out/any_robot] [--reference {failed,all,none}] [--quiet]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import sibling  # experiments/sibling.py: the other scripts, loaded by file path

OUTCOMES = ("verified", "failed", "infeasible", "budget", "rejected", "crash")
_INFEASIBLE = ("Infeasible_Problem_Detected", "Local_Infeasibility", "infeasible")


def _nhgait() -> list:
    exe = Path(sys.executable).with_name("nhgait")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "nhgait.gaits.cli.main"]


def has_time_limit() -> bool:
    """Whether this ``nhgait plan`` takes ``--time-limit`` (issue 24, item 2)."""
    out = subprocess.run([*_nhgait(), "plan", "--help"], capture_output=True, text=True, timeout=120)
    return "--time-limit" in out.stdout


def _say(quiet: bool, text: str) -> None:
    if not quiet:
        print(text, file=sys.stderr, flush=True)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
        return True
    except ProcessLookupError:
        return False
    except PermissionError:      # pragma: no cover - a recycled id of someone else's group
        return False


def _stop_group(proc: subprocess.Popen) -> dict:
    """SIGTERM to the plan's process group, SIGKILL 2 s later if anything of it is left."""
    pgid = proc.pid
    t0 = time.monotonic()
    try:
        os.killpg(pgid, signal.SIGTERM)
    except ProcessLookupError:
        pass
    try:
        proc.wait(timeout=2.0)
    except subprocess.TimeoutExpired:
        pass
    while _group_alive(pgid) and time.monotonic() - t0 < 2.0:
        time.sleep(0.05)
    killed = _group_alive(pgid)
    if killed:
        os.killpg(pgid, signal.SIGKILL)
        proc.wait()
    return {"sigterm_enough": not killed, "stop_s": time.monotonic() - t0}


def run_plan(scene: Path, out: Path, budget: float, time_limit: bool, grace: float, extra=(),
             default: bool = False) -> dict:
    """One cold ``nhgait plan`` (module docstring); returns its row's planner fields. With
    ``default`` the planner keeps its own default budget (``budget`` is that value) and is not
    given ``--time-limit``."""
    log = out.parent / "plan.log"
    with tempfile.TemporaryDirectory(prefix="nhgait-cold-") as cache, open(log, "w") as log_file:
        cmd = [*_nhgait(), "plan", str(scene), "--no-gif", "--out", str(out), *extra]
        if time_limit and not default:
            cmd += ["--time-limit", f"{budget:g}"]
        env = {**os.environ, "NHGAIT_CACHE_DIR": cache}
        t0 = time.monotonic()
        proc = subprocess.Popen(cmd, env=env, stdout=log_file, stderr=subprocess.STDOUT,
                                start_new_session=True)
        stopped = None
        try:
            proc.wait(timeout=budget + (grace if time_limit else 0.0))
        except subprocess.TimeoutExpired:
            stopped = _stop_group(proc)
        except BaseException:                         # this script stopped: its plan (a new session) too
            _stop_group(proc)
            raise
        wall = time.monotonic() - t0
        leftover = _group_alive(proc.pid)
        if leftover:                                  # children that outlived the plan
            os.killpg(proc.pid, signal.SIGKILL)
    row = {"exit": proc.returncode, "time_s": round(wall, 2), "stopped_by_bench": stopped is not None,
           "left_processes": leftover, "log": str(log),
           "phases": sibling.load("bench_loop_ranking").phases(log.read_text(errors="replace"))}
    if stopped:
        row.update(stopped)
    return row


def _first_line(text) -> str:
    return str(text or "").strip().splitlines()[0][:200] if str(text or "").strip() else ""


def _log_cause(log: Path) -> str:
    """The last error-looking line of a plan's log (for exits without a solution.json)."""
    lines = [ln.strip() for ln in Path(log).read_text(errors="replace").splitlines() if ln.strip()]
    for ln in reversed(lines):
        if any(w in ln for w in ("Error", "error", "failed", "Traceback", "FAILED")):
            return ln[:200]
    return lines[-1][:200] if lines else "(no output)"


def classify(row: dict, solution: dict | None) -> dict:
    """outcome and cause of a plan (module docstring)."""
    if row["stopped_by_bench"]:
        sigterm = "enough" if row.get("sigterm_enough") else "ignored"
        return {"outcome": "budget", "cause": f"no answer within the budget ({row['time_s']:.0f} s); "
                                              f"SIGTERM {sigterm}"}
    code = row["exit"]
    if code == 0 and solution and solution.get("success"):
        return {"outcome": "verified", "cause": ""}
    if code == 1 and solution is not None:
        status = str(solution.get("status", ""))
        cause = f"{status}: {_first_line(solution.get('message'))}"
        if "time limit" in cause.lower() or "budget" in cause.lower():
            return {"outcome": "budget", "cause": cause}
        if any(s in status for s in _INFEASIBLE):
            return {"outcome": "infeasible", "cause": cause}
        return {"outcome": "failed", "cause": cause}
    if code == 1:
        return {"outcome": "failed", "cause": _log_cause(row["log"])}
    if code == 2:
        return {"outcome": "rejected", "cause": _log_cause(row["log"])}
    return {"outcome": "crash", "cause": f"exit {code}: {_log_cause(row['log'])}"}


def _solution_fields(solution: dict | None) -> dict:
    if not solution:
        return {}
    ver = solution.get("verification") or {}
    st = solution.get("settings") or {}
    return {"status": solution.get("status"), "objective": solution.get("objective"),
            "iterations": solution.get("iterations"), "verification_error": ver.get("max_error"),
            "guess": (solution.get("guess") or {}).get("won"), "solver": st.get("solver"),
            "velocities": st.get("velocities")}


def pair_budget(p, budget) -> float:
    """The seconds a pair may take: ``budget`` (``--budget``), or with "default" the planner's
    own default for the robot's size (:func:`nhgait.ocp.budget.default_plan_seconds`)."""
    if budget == "default":
        from nhgait.ocp.budget import default_plan_seconds
        return default_plan_seconds(p.robot.n)
    return float(budget)


def plan_pair(p, folder: Path, args, time_limit: bool) -> dict:
    """Write the pair's scene, plan it cold, classify (one table row)."""
    folder.mkdir(parents=True, exist_ok=True)
    scene = folder / "scene.toml"
    scene.write_text(p.scene)
    extra = ("--no-jit",) if args.no_jit else ()
    row = {"pair": p.name, "robot": p.robot.name, "family": p.family, "n": p.robot.n, "k": p.robot.k,
           "m": len(p.robot.inputs), "task": p.task_label, "N": p.task["intervals"],
           "horizon": p.task["horizon"]}
    row["budget_s"] = pair_budget(p, args.budget)
    row.update(run_plan(scene, folder / "plan", row["budget_s"], time_limit, args.grace, extra,
                        default=args.budget == "default"))
    path = folder / "plan" / "solution.json"
    solution = json.loads(path.read_text()) if path.exists() else None
    row.update(classify(row, solution))
    row.update(_solution_fields(solution))
    row["solution"] = str(path) if solution else None
    return row


def reference_pair(p, row: dict, args) -> dict:
    """The independent transcription of ``p``, built once: from the planner's point (when it
    wrote one) and from its own guess; the best converged and re-simulated answer."""
    ref = sibling.load("reference_dae_ocp")
    if p.robot.n > args.reference_max_n:
        return {"reference": {}, "ref_solved": None, "ref_objective": None}
    runs = {}
    try:
        ocp = ref.ReferenceOCP(p, jit=not args.no_jit)
        for start in (["planner"] if row.get("solution") else []) + ["own"]:
            guess = row["solution"] if start == "planner" else None
            runs[start] = ocp.solve(guess, max_wall_s=args.reference_budget,
                                    tolerance=args.reference_tolerance).summary()
        runs["compile_s"] = round(ocp.compile_s, 1)
    except Exception as exc:   # the reference is this benchmark's tool: its failure is a row, not an abort
        runs["error"] = f"{type(exc).__name__}: {exc}"[:300]
    solved = [r for r in runs.values() if isinstance(r, dict) and r.get("solved")]
    best = min(solved, key=lambda r: r["objective"]) if solved else None
    return {"reference": runs, "ref_solved": best is not None,
            "ref_objective": best["objective"] if best else None}


def _within(row, rel=0.01) -> bool:
    J, R = row.get("objective"), row.get("ref_objective")
    return row["outcome"] == "verified" and J is not None and R is not None and J <= R + rel * abs(R) + 1e-9


def summary(rows: list) -> dict:
    """Success rate over the pairs the reference solves, within 1 %, failures by cause, times."""
    # a verified gait is a solution: solvable = verified by the planner or solved by the reference
    solvable = [r for r in rows if r.get("ref_solved") or r["outcome"] == "verified"]
    causes = {}
    for r in rows:
        if r["outcome"] != "verified":
            key = r["outcome"] + (": " + r["cause"].split(":")[0] if r["outcome"] == "failed" else "")
            causes[key] = causes.get(key, 0) + 1
    times = sorted(r["time_s"] for r in rows)
    q = (lambda f: times[min(len(times) - 1, int(f * len(times)))]) if times else (lambda f: None)
    return {"pairs": len(rows), "outcomes": {o: sum(r["outcome"] == o for r in rows) for o in OUTCOMES},
            "answered_within_budget": sum(not r.get("stopped_by_bench") and not r.get("left_processes")
                                          for r in rows),
            "reference_checked": sum("reference" in r for r in rows),
            "reference_solved": len(solvable),
            "verified_of_solvable": sum(r["outcome"] == "verified" for r in solvable),
            "success_rate_over_solvable": (sum(r["outcome"] == "verified" for r in solvable) / len(solvable)
                                           if solvable else None),
            "within_1pct_of_reference": sum(_within(r) for r in solvable),
            "verified_with_reference": sum(r["outcome"] == "verified" and r.get("ref_solved") is not None
                                           for r in rows),
            "planner_defects": [r["pair"] for r in solvable if r["outcome"] != "verified"],
            "failures_by_cause": dict(sorted(causes.items(), key=lambda kv: -kv[1])),
            "time_s": {"median": statistics.median(times) if times else None, "p90": q(0.9),
                       "max": times[-1] if times else None},
            "median_phase_s": _phase_medians(rows),
            "worst_times": sorted(((r["time_s"], r["pair"], r["outcome"]) for r in rows), reverse=True)[:5]}


def _phase_medians(rows: list) -> dict:
    """Where the time to answer went: the median seconds of each phase of the plans' own "wall
    time … in all" split (model, NLP set-up, guesses and solves, verification, figures, …)."""
    split = [r["phases"] for r in rows if r.get("phases")]
    names = sorted({k for p in split for k in p})
    return {k: statistics.median(p.get(k, 0.0) for p in split) for k in names}


COLUMNS = ("pair", "family", "n", "k", "task", "outcome", "cause", "time_s", "budget_s", "iterations",
           "objective", "ref_objective", "verification_error", "guess")


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v).replace("|", "/")


def write_tables(rows: list, summ: dict, out: Path, meta: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "table.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([r.get(c) for c in COLUMNS])
    md = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    md += ["| " + " | ".join(_fmt(r.get(c)) for c in COLUMNS) + " |" for r in rows]
    s = summ
    rate = s["success_rate_over_solvable"]
    md += ["", f"Pairs: {s['pairs']}; outcomes: " + ", ".join(f"{k} {v}" for k, v in s["outcomes"].items()),
           f"Solvable (verified by the planner, or solved by the reference: {s['reference_solved']} of the "
           f"{s['reference_checked']} pairs it was run on): "
           f"{len(s['planner_defects']) + s['verified_of_solvable']}; "
           f"the planner verified {s['verified_of_solvable']} of those"
           + (f" ({100 * rate:.0f} %)" if rate is not None else "")
           + f", {s['within_1pct_of_reference']} within 1 % of the reference objective.",
           "Failures by cause: " + "; ".join(f"{k}: {v}" for k, v in s["failures_by_cause"].items()),
           f"Answered by the planner itself within the budget (not stopped by this script, nothing left "
           f"running): {s['answered_within_budget']} of {s['pairs']}.",
           f"Time to answer: median {_fmt(s['time_s']['median'])} s, 90 % {_fmt(s['time_s']['p90'])} s, "
           f"max {_fmt(s['time_s']['max'])} s.",
           "Where it went (medians of the plans' own split): "
           + ", ".join(f"{k} {v:.3g} s" for k, v in s.get("median_phase_s", {}).items())]
    (out / "table.md").write_text("\n".join(md) + "\n")
    (out / "results.json").write_text(json.dumps({"meta": meta, "summary": summ, "rows": rows}, indent=1,
                                                 default=str))


def _budget(text: str):
    return "default" if text == "default" else float(text)


def _args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=24)
    ap.add_argument("--pairs", type=int, default=40)
    ap.add_argument("--first", type=int, default=0, help="index of the first pair")
    ap.add_argument("--families", default=",".join(sibling.load("robot_generator").FAMILIES))
    ap.add_argument("--intervals", type=int, default=40, help="N of every task")
    ap.add_argument("--budget", type=_budget, default=120.0,
                    help="wall-clock seconds per plan, or 'default': the planner's default for the "
                         "robot's size (120 s + 30 s per coordinate), not passed as --time-limit")
    ap.add_argument("--grace", type=float, default=5.0,
                    help="seconds past --time-limit before this script stops the plan")
    ap.add_argument("--reference", choices=("failed", "all", "none"), default="failed",
                    help="which pairs the reference checks (the verified ones are solvable anyway)")
    ap.add_argument("--reference-budget", type=float, default=300.0, help="seconds per reference solve")
    ap.add_argument("--reference-tolerance", type=float, default=1e-4,
                    help="re-simulation and condition errors (relative) a reference answer must "
                         "meet to count as solved: a gait exists to the transcription's accuracy at this N")
    ap.add_argument("--reference-max-n", type=int, default=99,
                    help="no reference for robots with more coordinates")
    ap.add_argument("--indices", default=None,
                    help="comma-separated pair indices (instead of --first/--pairs)")
    ap.add_argument("--reference-only", action="store_true",
                    help="reuse the plans in --plans (default --out)")
    ap.add_argument("--plans", default=None,
                    help="with --reference-only: the benchmark output whose plans to check")
    ap.add_argument("--no-jit", action="store_true", help="plan with interpreted NLP functions")
    ap.add_argument("--out", default="out/any_robot")
    ap.add_argument("--quiet", action="store_true")
    return ap.parse_args(argv)


def _terminated(signum, frame):
    """SIGTERM as an exception, so the plan running in its own session is stopped with this script."""
    raise SystemExit(128 + signum)


def main(argv=None) -> int:
    """The benchmark; SIGTERM ends it through ``_terminated`` while it runs (the previous handler
    is restored on return, so a test calling ``main`` in-process stays stoppable)."""
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        return _run(_args(argv))
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(args) -> int:
    gen = sibling.load("robot_generator")
    families = tuple(f.strip() for f in args.families.split(",") if f.strip())
    indices = ([int(i) for i in args.indices.split(",")] if args.indices
               else range(args.first, args.first + args.pairs))
    todo = [gen.pair(args.seed, i, families[i % len(families)], args.intervals) for i in indices]
    out = Path(args.out)
    old = {}
    if args.reference_only:
        old = {r["pair"]: r
               for r in json.loads((Path(args.plans or out) / "results.json").read_text())["rows"]}
    time_limit = False if args.reference_only else has_time_limit()
    meta = {"seed": args.seed, "indices": [p.index for p in todo], "intervals": args.intervals,
            "budget_s": args.budget, "planner_time_limit": time_limit, "no_jit": args.no_jit}
    rows = []
    for i, p in enumerate(todo, 1):
        if args.reference_only:
            row = old[p.name]
        else:
            _say(args.quiet,
                 f"[{i}/{len(todo)}] {p.name} (n = {p.robot.n}, k = {p.robot.k}, {p.task_label}): "
                             f"nhgait plan, budget {pair_budget(p, args.budget):g} s …")
            row = plan_pair(p, out / "pairs" / p.name, args, time_limit)
            _say(args.quiet, f"    {row['outcome']} in {row['time_s']:.1f} s {row['cause']}")
        if args.reference == "all" or (args.reference == "failed" and row["outcome"] != "verified"):
            _say(args.quiet, "    reference (Lagrange DAE, Ipopt) …")
            row.update(reference_pair(p, row, args))
            _say(args.quiet, f"    reference: {'solved' if row['ref_solved'] else 'not solved'}"
                             + (f", J = {row['ref_objective']:.6g}" if row["ref_solved"] else ""))
        rows.append(row)
        write_tables(rows, summary(rows), out, meta)        # after every pair: a partial table survives
    if args.reference_only:                                 # the plans not re-checked keep their rows
        done = {r["pair"] for r in rows}
        rows += [r for name, r in old.items() if name not in done]
        rows.sort(key=lambda r: int(r["pair"].rsplit("-", 1)[1]))
    summ = summary(rows)
    write_tables(rows, summ, out, meta)
    if not args.quiet:
        print((out / "table.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
