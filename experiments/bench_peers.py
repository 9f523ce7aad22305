#!/usr/bin/env python3
"""Side by side with opty on its own gallery examples (issue 30).

opty (direct collocation from sympy with Ipopt) has three nonholonomic wheeled-vehicle
examples in its gallery: a bicycle-model car parallel parking, a three-body car parking in a
garage and the same car driving around two pylons. nhgait states them as scenes
(``examples/opty_parallel_park.toml``, ``opty_garage.toml``, ``opty_pylons.toml``: the examples'
equations — equal to their KanesMethod models, tests/dynamics/test_peer_examples.py — parameters, bounds
and objectives). For each task, in one run on this machine:

* **opty as its authors wrote it**: the example file executed unchanged in opty's own
  environment (``--opty-python``, a virtual environment with ``pip install opty matplotlib``;
  ``--examples``: the folder of opty's gallery files) by ``experiments/peer_opty_run.py``: the
  whole run (interpreter start to the end of the example's code, plots included), its solves'
  seconds and iterations, its objective;
* **nhgait plan cold**: ``nhgait plan <scene> --no-gif --quiet`` as a new process with an empty
  private ``NHGAIT_CACHE_DIR`` (derivation, code generation and compilation included), then
  **warm** (the same command again, the cache filled); the wall time of each process, the
  winning solve's seconds and iterations, the guesses tried;
* **true accuracy** of both answers, judged the same way: the answer's inputs re-simulated on the
  example's own KanesMethod equations in opty's environment (DOP853, rtol 1e-10, atol 1e-12,
  ``peer_opty_run.py``), from the answer's first node — opty's inputs held as its backward-Euler
  transcription reads them, nhgait's piecewise constant as planned; the largest distance of the
  car's reference point from where the answer says it is (m).

``--refine TASKS`` also runs each tool at 2× and 4× the nodes on those tasks, each from its
previous answer (opty through ``peer_opty_run.py --guess``, nhgait with ``--intervals`` and
``--guess``), and extrapolates the objective (Richardson, the observed order).

Writes ``results.json``, ``table.csv`` and ``table.md`` into ``--out``; each run's log and
answer under ``runs/<task>/<tool>/``. Progress on stderr.

Usage: python experiments/bench_peers.py --opty-python /path/opty-venv/bin/python
       --examples /path/opty/examples-gallery [--tasks parallel_park,garage,pylons] [--out out/peers]
       [--refine parallel_park,garage] [--skip-opty] [--opty-results DIR]
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RUNNER = ROOT / "experiments" / "peer_opty_run.py"

#: task → (opty's gallery file, nhgait's scene, opty's num_nodes, kind of vehicle)
TASKS = {
    "parallel_park": ("plot_parallel_park.py", "examples/opty_parallel_park.toml", 501, "bicycle"),
    "garage": ("plot_car_in_garage.py", "examples/opty_garage.toml", 301, "car3"),
    "pylons": ("plot_car_around_pylons.py", "examples/opty_pylons.toml", 401, "car3"),
}


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- opty
def run_opty(python: str, example: Path, out: Path, num_nodes=None, guess=None) -> dict:
    """One run of an opty example in a fresh folder (no stored solution short-cuts it)."""
    out.mkdir(parents=True, exist_ok=True)
    args = [python, str(RUNNER), "run", str(example), str(out / "opty.json")]
    args += ["--num-nodes", str(num_nodes)] if num_nodes else []
    args += ["--guess", str(guess)] if guess else []
    with tempfile.TemporaryDirectory() as work, open(out / "log.txt", "w") as log:
        t0 = time.perf_counter()
        code = subprocess.call(args, cwd=work, stdout=log, stderr=subprocess.STDOUT)
        wall = time.perf_counter() - t0
    if code != 0 or not (out / "opty.json").exists():
        return {"ok": False, "exit": code, "process_s": wall}
    data = json.loads((out / "opty.json").read_text())
    return {"ok": True, "process_s": wall, **{k: data[k] for k in (
        "whole_s", "construct_s", "solve_s", "iterations", "status_msg", "converged", "objective", "horizon",
        "num_nodes", "accuracy")}, "solves": len(data["solves"])}


def resimulate_in_opty(python: str, example: Path, trajectory: dict, out: Path) -> dict:
    """An answer's inputs re-simulated on the example's own equations (``peer_opty_run.py``)."""
    path = out / "trajectory.json"
    path.write_text(json.dumps(trajectory))
    with tempfile.TemporaryDirectory() as work, open(out / "resimulate_log.txt", "w") as log:
        subprocess.call([python, str(RUNNER), "resimulate", str(example), str(path),
                         str(out / "accuracy.json")],
                        cwd=work, stdout=log, stderr=subprocess.STDOUT)
    if not (out / "accuracy.json").exists():
        return {}
    return json.loads((out / "accuracy.json").read_text())["accuracy"]


# ----------------------------------------------------------------------------- nhgait
def run_nhgait(scene: Path, out: Path, cache: Path, intervals=None, guess=None) -> dict:
    """``nhgait plan`` as a new process with the cache ``cache``: its wall time and answer."""
    out.mkdir(parents=True, exist_ok=True)
    args = [sys.executable, "-m", "nhgait.gaits.cli.main", "plan", str(scene), "--out", str(out / "plan"),
            "--no-gif", "--quiet"] + (["--intervals", str(intervals)] if intervals else [])
    args += ["--guess", str(guess)] if guess else []
    env = {**os.environ, "NHGAIT_CACHE_DIR": str(cache)}
    with open(out / "log.txt", "w") as log:
        t0 = time.perf_counter()
        code = subprocess.call(args, env=env, stdout=log, stderr=subprocess.STDOUT)
        wall = time.perf_counter() - t0
    path = out / "plan" / "solution.json"
    if not path.exists():
        return {"ok": False, "exit": code, "whole_s": wall}
    data = json.loads(path.read_text())
    verification = data.get("verification") or {}
    return {"ok": code == 0, "exit": code, "whole_s": wall, "solve_s": data["solve_time_s"],
            "iterations": data["iterations"], "objective": data["objective"], "status_msg": data["status"],
            "horizon": data["trajectory"]["horizon"], "tried": len(data["guess"]["tried"]),
            "verified": verification.get("passed"), "solution": str(path)}


def opty_trajectory(solution_path: str, kind: str) -> dict:
    """nhgait's answer in the example's state order (opty's names), inputs N × m."""
    tr = json.loads(Path(solution_path).read_text())["trajectory"]
    q, qd = np.asarray(tr["q"], float).T, np.asarray(tr["qdot"], float).T        # n × (N + 1)
    u = np.asarray(tr["u"], float)                                                 # N × m
    states = {name: np.asarray(row, float) for name, row in tr["states"].items()}
    if kind == "bicycle":        # (x, y, θ, δ, v_x, v_y, ω, β): body velocities of the mass centre
        th = q[2]
        rows = [q[0], q[1], q[2], q[3], np.cos(th) * qd[0] + np.sin(th) * qd[1],
                -np.sin(th) * qd[0] + np.cos(th) * qd[1], qd[2], qd[3]]
        inputs = {"F": "F(t)", "T": "T(t)"}
    else:                        # (x, y, q0, qf, u_x, u_y, u_0, u_f [, punkt1, punkt2]): u_f absolute
        rows = [q[0], q[1], q[2], q[3], qd[0], qd[1], qd[2], qd[2] + qd[3]]
        rows += [states[n] for n in ("near1", "near2") if n in states]
        inputs = {"Fb": "F_b(t)", "Tf": "T_f(t)"}
    return {"t": list(map(float, tr["t"])), "states": np.vstack(rows).tolist(),
            "input_names": [inputs[c] for c in tr["control_names"]], "inputs": u.tolist()}


# ----------------------------------------------------------------------------- one task
def bench_task(task: str, args, out: Path) -> dict:
    example_name, scene, nodes, kind = TASKS[task]
    example = Path(args.examples) / example_name
    scene = ROOT / scene
    row = {"task": task}
    if args.opty_results:
        row["opty"] = json.loads((Path(args.opty_results) / task / "opty" / "summary.json").read_text())
    elif not args.skip_opty:
        _say(f"[{task}] opty as written …")
        row["opty"] = run_opty(args.opty_python, example, out / task / "opty")
        (out / task / "opty" / "summary.json").write_text(json.dumps(row["opty"]))
        _say(f"[{task}]   {_line(row['opty'])}")
    with tempfile.TemporaryDirectory() as cache:
        for label in ("cold", "warm"):
            _say(f"[{task}] nhgait plan {label} …")
            row[label] = run_nhgait(scene, out / task / f"nhgait_{label}", Path(cache))
            _say(f"[{task}]   {_line(row[label])}")
    if row["warm"].get("solution") and args.opty_python:
        row["warm"]["accuracy"] = resimulate_in_opty(args.opty_python, example,
                                                     opty_trajectory(row["warm"]["solution"], kind),
                                                     out / task / "nhgait_warm")
    if task in args.refine.split(","):
        row["refine"] = refine(task, args, out, example, scene, nodes, row)
    return row


def refine(task, args, out, example, scene, nodes, row) -> dict:
    """Objectives at 1×, 2×, 4× the nodes (both tools) and their Richardson extrapolations."""
    result = {"nhgait": [], "opty": []}
    N = nodes - 1
    with tempfile.TemporaryDirectory() as cache:
        previous = row["warm"]
        result["nhgait"].append((N, previous.get("objective"), previous.get("ok")))
        for factor in (2, 4):       # each from the previous answer, as opty's refinement below
            previous = run_nhgait(scene, out / task / f"nhgait_{factor}x", Path(cache), intervals=N * factor,
                                  guess=previous.get("solution"))
            result["nhgait"].append((N * factor, previous.get("objective"), previous.get("ok")))
    if not args.skip_opty and not args.opty_results:
        guess = out / task / "opty" / "opty.json"
        for factor in (2, 4):
            r = run_opty(args.opty_python, example, out / task / f"opty_{factor}x", num_nodes=N * factor + 1,
                         guess=guess if guess.exists() else None)
            result["opty"].append((N * factor, r.get("objective"), r.get("converged")))
            guess = out / task / f"opty_{factor}x" / "opty.json"
        first = row.get("opty", {})
        result["opty"].insert(0, (N, first.get("objective"), first.get("converged")))
    for tool in ("nhgait", "opty"):
        result[f"{tool}_extrapolated"] = _richardson([j for _, j, _ in result[tool]])
    return result


def _richardson(values) -> float | None:
    """J∞ from J(N), J(2N), J(4N): observed order p from the ratio of the differences."""
    if len(values) < 3 or any(v is None for v in values):
        return None
    d1, d2 = values[1] - values[0], values[2] - values[1]
    if d1 == 0 or d2 == 0 or d2 / d1 <= 0:
        return values[2]
    ratio = d1 / d2                           # 2^p
    return values[2] + d2 / (ratio - 1)


def _line(r: dict) -> str:
    if not r.get("ok", True) and "objective" not in r:
        return f"failed (exit {r.get('exit')})"
    return (f"whole {r.get('whole_s', float('nan')):.1f} s, solve {r.get('solve_s', float('nan')):.2f} s, "
            f"{r.get('iterations')} iterations, J = {r.get('objective', float('nan')):.6g}, "
            f"{r.get('status_msg')}")


# ----------------------------------------------------------------------------- tables
COLUMNS = ("task", "tool", "whole_s", "solve_s", "iterations", "objective", "horizon", "converged",
           "position_error_m")


def table_rows(results: list) -> list:
    rows = []
    for row in results:
        opty = row.get("opty")
        if opty:
            rows.append([row["task"], "opty", opty.get("whole_s"), opty.get("solve_s"),
                         opty.get("iterations"), opty.get("objective"), opty.get("horizon"),
                         opty.get("converged"), (opty.get("accuracy") or {}).get("max_position_error_m")])
        for label in ("cold", "warm"):
            r = row[label]
            rows.append([row["task"], f"nhgait {label}", r.get("whole_s"), r.get("solve_s"),
                         r.get("iterations"), r.get("objective"), r.get("horizon"), r.get("verified"),
                         (r.get("accuracy") or {}).get("max_position_error_m")])
    return rows


def _cell(v) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else (f"{v:.3g}" if abs(v) < 1e-2 else f"{v:.6g}" if abs(v) > 1e3
                                         else f"{v:.4g}")
    return "" if v is None else str(v)


def write_tables(results: list, out: Path) -> None:
    rows = table_rows(results)
    with open(out / "table.csv", "w", newline="") as fh:
        csv.writer(fh).writerows([COLUMNS] + rows)
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_cell(v) for v in r) + " |" for r in rows]
    for row in results:
        opty, cold, warm = row.get("opty") or {}, row["cold"], row["warm"]
        if opty.get("whole_s") and cold.get("whole_s"):
            lines.append(f"\n{row['task']}: nhgait cold / opty {cold['whole_s'] / opty['whole_s']:.2f}×, "
                         f"warm / opty {warm['whole_s'] / opty['whole_s']:.2f}×")
        if "refine" in row:
            ref = row["refine"]
            lines.append(f"{row['task']} refined: nhgait {ref['nhgait']} → {ref['nhgait_extrapolated']}; "
                         f"opty {ref['opty']} → {ref['opty_extrapolated']}")
    (out / "table.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--opty-python", default="", help="python of opty's own virtual environment")
    parser.add_argument("--examples", default="", help="the folder holding opty's gallery example files")
    parser.add_argument("--tasks", default=",".join(TASKS))
    parser.add_argument("--out", default="out/peers")
    parser.add_argument("--refine", default="",
                        help="tasks also run at 2× and 4× the nodes (comma-separated)")
    parser.add_argument("--skip-opty", action="store_true", help="nhgait only")
    parser.add_argument("--opty-results", default="", help="reuse the opty runs of an earlier --out")
    args = parser.parse_args(argv)
    tasks = [t.strip() for t in args.tasks.split(",") if t.strip()]
    bad = [t for t in tasks if t not in TASKS]
    if bad or (not args.skip_opty and not args.opty_results and not (args.opty_python and args.examples)):
        parser.error(f"unknown task(s) {bad}" if bad
                     else "give --opty-python and --examples (or --skip-opty)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = [bench_task(task, args, out) for task in tasks]
    (out / "results.json").write_text(json.dumps(results, indent=1, default=str))
    write_tables(results, out)
    _say((out / "table.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
