#!/usr/bin/env python3
"""The designer's loop (issue 40): how long one turn of plan/derive takes, against its floors.

Every ratio is measured in one run, the commands of one round taking turns (floor, plan, plan,
derive, floor, …) so that a shared machine's load falls on all alike; each time is the median
of ``--repeats`` runs.

* **whole process, warm** — ``nhgait plan unicycle --gait parallel-park --quiet``,
  ``nhgait plan snakeboard --gait forward --quiet`` and ``nhgait derive snakeboard`` as a user
  runs them (a fresh process each; the cache already holding the derivation and the optimised
  library), against the floor of any such tool: a bare ``python -c "import casadi, sympy,
  numpy"``. Targets: plan ≤ 2×, derive ≤ 1.5× the floor.
  Each plan also runs with ``NHGAIT_WARM_OPTIMA=0``: without the last verified optimum of
  its task from the cache, as every warm run did before it (issue 40).
* **in process, warm** — ``plan("snakeboard", "forward", intervals=100, verify=False)`` (P2) in
  a long-lived process, against the hand-written jit CasADi multiple-shooting reference's solve
  of the same problem (``experiments/reference_casadi_ocp.py``, Ipopt, gcc -O1; its NLP built
  once; J = 0.109703). Target: ≤ 3×; the objectives are printed side by side. A third row is
  the same plan without the process's memo (``memo=False``), as every in-process plan ran before
  the memo (issue 40): each call prepares the model, builds the NLP and the solver, builds and
  screens the guesses and explores after the first success.

The cache is a private folder (``--cache``; default: a new temporary one, warmed first by one
run of each command, the optimised library's background build waited for). Writes
``--out`` (JSON) and prints the table.

Each row also gives the CPU seconds of the whole process tree (``getrusage``, every process
waited for), which a loaded machine inflates far less than the wall time, and their ratio.

Usage: python experiments/bench_loop.py [--repeats 5] [--sections process,inprocess]
       [--commands plan-unicycle,plan-snakeboard,derive] [--cache DIR] [--out out/bench_loop.json]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import plan_process  # experiments/plan_process.py: nhgait as a user runs it
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

FLOOR = "import casadi, sympy, numpy"
#: key (``--commands``) → (label, nhgait arguments, target ratio to the floor)
ALL_COMMANDS = {
    "plan-unicycle": ("plan unicycle parallel-park",
                      ["plan", "unicycle", "--gait", "parallel-park", "--quiet"], 2.0),
    "plan-snakeboard": ("plan snakeboard forward",
                        ["plan", "snakeboard", "--gait", "forward", "--quiet"], 2.0),
    "derive": ("derive snakeboard", ["derive", "snakeboard"], 1.5)}
P2 = dict(system="snakeboard", gait="forward", intervals=100)
P2_OBJECTIVE = 0.109703
TIMEOUT_S = 600.0


def _env(cache: Path, background: bool) -> dict:
    """The runs' environment: the private cache; ``background``: the optimised library built in
    the background (the warm-up waits for it); else (``--no-background``) none is started and
    the warm runs use the fast compiler's library — a quick run on a busy machine, where gcc -O2
    of the snakeboard's NLP took over 10 min."""
    return {**os.environ, "NHGAIT_CACHE_DIR": str(cache),
            "NHGAIT_BACKGROUND_BUILDS": "1" if background else "0"}


def _cpu(who) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def _timed(cmd: list, env: dict) -> tuple:
    """(wall seconds, CPU seconds) of ``cmd`` (its output discarded) — the CPU time of its
    whole process tree (every process it waited for), which a loaded machine does not inflate
    as it does the wall time; an error when it fails."""
    c0, t0 = _cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
    proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          timeout=TIMEOUT_S, check=False)
    seconds, cpu = time.perf_counter() - t0, _cpu(resource.RUSAGE_CHILDREN) - c0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr[-2000:]}")
    return seconds, cpu


def _command(args: list, out: Path) -> list:
    extra = ["--out", str(out)] if args[0] == "plan" else []
    return [*plan_process.nhgait_command(), *args, *extra]


def warm_up(cache: Path, folder: Path, commands: tuple, background: bool = True) -> None:
    """One run of each plan (its background build of the optimised library waited for) and of
    derive: the cache then holds what a warm run uses."""
    for label, args, _ in commands:
        if args[0] == "plan":
            out = folder / f"warm-{label.replace(' ', '-')}"
            row = _warm_plan(args[1:], out, cache, background)
            plan_process.background_build(row.get("later"), cache, TIMEOUT_S)
        else:
            _timed(_command(args, folder), _env(cache, background))


def _row(what: str, runs: list, floor: tuple | None, target, **extra) -> dict:
    """A row: the medians of wall and CPU seconds of ``runs`` [(wall, cpu)], their ratios to
    ``floor`` (medians; None: this is the floor)."""
    wall, cpu = (statistics.median(r[i] for r in runs) for i in (0, 1))
    base = floor or (wall, cpu)
    return {"what": what, "median_s": wall, "cpu_s": cpu, "ratio": wall / base[0], "cpu_ratio": cpu / base[1],
            "target": target, "runs": runs, **extra}


def _warm_plan(args: list, out: Path, cache: Path, background: bool) -> dict:
    """One plan (:func:`plan_process.run_plan`, its background build started unless
    ``background`` is false)."""
    if background:
        return plan_process.run_plan(args, out, cache, TIMEOUT_S)
    cmd = _command(["plan", *args], out)
    subprocess.run(cmd, env=_env(cache, False), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   timeout=TIMEOUT_S, check=False)
    return {}


def measure_processes(cache: Path, folder: Path, repeats: int, commands: tuple,
                      background: bool = True, cold_guesses: bool = True) -> list:
    """Rows of the whole-process runs against the floor, each command's runs taking turns;
    ``cold_guesses``: each plan also with ``NHGAIT_WARM_OPTIMA=0`` (no last verified optimum
    from the cache: the planner's guesses built, the exploration run — every warm run before
    :mod:`nhgait.gaits.planning.plan_memo`)."""
    env = _env(cache, background)
    cold_env = {**env, "NHGAIT_WARM_OPTIMA": "0"}
    plans = [(label, args) for label, args, _ in commands if args[0] == "plan"] if cold_guesses else []
    times = {"floor": []} | {label: [] for label, _, _ in commands}
    times |= {f"{label} cold": [] for label, _ in plans}
    for _ in range(repeats):
        times["floor"].append(_timed([sys.executable, "-c", FLOOR], env))
        for label, args, _ in commands:
            times[label].append(_timed(_command(args, folder / "runs"), env))
        for label, args in plans:
            times[f"{label} cold"].append(_timed(_command(args, folder / "runs"), cold_env))
    floor = _row(f'python -c "{FLOOR}" (the floor)', times["floor"], None, None)
    base = (floor["median_s"], floor["cpu_s"])
    rows = [floor] + [_row(f"nhgait {label}, warm", times[label], base, target)
                      for label, _, target in commands]
    return rows + [_row(f"nhgait {label}, warm, NHGAIT_WARM_OPTIMA=0 (guesses built, exploration run)",
                        times[f"{label} cold"], base, None) for label, _ in plans]


def _both() -> tuple:
    return time.perf_counter(), _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN)


def _since(start: tuple) -> tuple:
    now = _both()
    return now[0] - start[0], now[1] - start[1]


def measure_in_process(cache: Path, repeats: int, with_bare: bool = True, background: bool = True) -> list:
    """Rows of the in-process warm P2 plan against the reference's solve, taking turns (CPU:
    this process and the attempts' children); ``with_bare``: also the same plan without the
    process's memo (``plan(..., memo=False)``, :mod:`nhgait.gaits.planning.plan_memo`), as every
    plan ran before it."""
    os.environ["NHGAIT_CACHE_DIR"] = str(cache)
    os.environ["NHGAIT_BACKGROUND_BUILDS"] = "1" if background else "0"   # --no-background: none here either
    from nhgait.gaits.planner import plan
    ref = sibling.load("reference_casadi_ocp")
    run_ours = lambda: plan(P2["system"], P2["gait"], intervals=P2["intervals"], verify=False)  # noqa: E731
    run_bare = lambda: plan(P2["system"], P2["gait"], intervals=P2["intervals"], verify=False,  # noqa: E731
                            memo=False)
    ours = run_ours()                                     # warm-up: the process's first plan
    theirs = ref.solve("P2", P2["intervals"], jit=True)   # builds (and compiles) the reference once
    ours_runs, theirs_runs, bare_runs = [], [], []
    for _ in range(repeats):
        start = _both()
        ours = run_ours()
        ours_runs.append(_since(start))
        start = _both()
        theirs = ref.solve("P2", P2["intervals"], jit=True)
        theirs_runs.append((theirs["solve_time_s"], _since(start)[1]))
        if with_bare:
            start = _both()
            bare = run_bare()
            bare_runs.append(_since(start))
    reference = _row("reference jit CasADi solve of P2 (N = 100; NLP built once)", theirs_runs, None, None,
                     objective=theirs["objective"])
    base = (reference["median_s"], reference["cpu_s"])
    rows = [reference,
            _row('plan("snakeboard", "forward", intervals=100, verify=False), in process, warm', ours_runs,
                 base, 3.0, objective=ours.solution.objective if ours.solution is not None else None,
                 success=ours.success)]
    if with_bare:
        rows.append(_row('the same plan without the memo (memo=False: each call prepares, builds, explores)',
                         bare_runs, base, None, objective=bare.solution.objective if bare.solution else None,
                         success=bare.success))
    return rows


def table(rows: list) -> str:
    """The Markdown table of ``rows``."""
    lines = ["| what | wall, median | ratio | CPU, median | CPU ratio | target | objective |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        target = "" if r["target"] is None else f"≤ {r['target']:g}×"
        objective = "" if r.get("objective") is None else f"{r['objective']:.6f}"
        lines.append(f"| {r['what']} | {r['median_s']:.3f} s | {r['ratio']:.2f}× | {r['cpu_s']:.3f} s | "
                     f"{r['cpu_ratio']:.2f}× | {target} | {objective} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sections", default="process,inprocess")
    ap.add_argument("--commands", default=",".join(ALL_COMMANDS),
                    help=f"the whole-process commands ({', '.join(ALL_COMMANDS)})")
    ap.add_argument("--cache", default=None, help="cache folder (default: a new temporary one, warmed first)")
    ap.add_argument("--out", default="out/bench_loop.json")
    ap.add_argument("--no-bare", action="store_true",
                    help="no rows without the memo (in process) or without the cache's optima (processes)")
    ap.add_argument("--no-background", action="store_true",
                    help="no optimised background build: the warm runs use the fast compiler's library")
    args = ap.parse_args(argv)
    background = not args.no_background
    sections = {s.strip() for s in args.sections.split(",") if s.strip()}
    commands = tuple(ALL_COMMANDS[c.strip()] for c in args.commands.split(",") if c.strip())
    if "inprocess" in sections and not any(a[0] == "plan" and "snakeboard" in a for _, a, _ in commands):
        commands += (ALL_COMMANDS["plan-snakeboard"],)     # its warm-up: the cache P2 plans from
    with tempfile.TemporaryDirectory(prefix="nhgait-bench-loop-") as tmp:
        folder = Path(tmp)
        cache = Path(args.cache) if args.cache else folder / "cache"
        print(f"warming the cache {cache} ...", file=sys.stderr, flush=True)
        warm_up(cache, folder, commands, background)
        rows = []
        if "process" in sections:
            rows += measure_processes(cache, folder, args.repeats, commands, background,
                                      cold_guesses=not args.no_bare)
        if "inprocess" in sections:
            rows += measure_in_process(cache, args.repeats, with_bare=not args.no_bare, background=background)
    print(f"# the designer's loop: medians of {args.repeats} runs, ratios in this run "
          f"(load average {os.getloadavg()[0]:.1f})")
    print(table(rows))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "repeats": args.repeats}, indent=1, default=float))
    ok = all(r.get("success", True) for r in rows)
    inproc = [r for r in rows if r.get("objective") is not None]     # ours, without the memo, the reference
    ok &= all(abs(r["objective"] - P2_OBJECTIVE) < 1e-5 for r in inproc)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
