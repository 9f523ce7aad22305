#!/usr/bin/env python3
"""Shape loops ranked by the connection's prediction, before and after (issue 42, item 4).

For each scene — ``--pairs`` robot-and-task pairs of ``experiments/robot_generator.py`` (seed
``--seed``) and the user scenes given with ``--scene`` — two cold ``nhgait plan SCENE --no-gif``
processes, each with a fresh empty ``NHGAIT_CACHE_DIR`` and ``--time-limit`` ``--budget`` s:
``before`` with :func:`nhgait.gaits.planning.loop_ranking.rank_loops` replaced by the identity (the
candidates in their generated order) and without the one-shape-coordinate reach check
(:func:`nhgait.gaits.tasks.reachability.shape_reach`) and with the stall rule of before (three
infeasible attempts in a row, :data:`nhgait.gaits.planning.infeasibility.STALL_WINDOW` = 3),
``after`` as shipped. The arms alternate
per scene. A row per (scene, arm): the exit code (0: a verified gait), the time to the answer, whether the
ranking changed the order (the plan's log says "shape loops ranked"), the winning guess, the
attempts made and the plan's own "wall time … in all" split (model, NLP set-up, guesses and
solves, verification, figures, …).
Prints the verified counts, the median times to answer of both arms and their ratio, the median
of the per-scene ratios, the median seconds per phase and attempts per plan, and
writes ``results.json`` into ``--out``. Progress on stderr (``--quiet``: none).

Usage: python experiments/bench_loop_ranking.py [--seed 24] [--pairs 6] [--scene FILE ...]
       [--budget 90] [--repeat 1] [--out out/loop_ranking] [--quiet]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import sibling  # experiments/sibling.py

BEFORE = ("import sys\nimport nhgait.gaits.planning.guesses as g\n"
          "from nhgait.gaits.planning.loop_ranking import RankedLoops\n"
          "g.rank_loops = lambda problem, guesses, progress=None: RankedLoops(tuple(guesses))\n"
          "import nhgait.gaits.tasks.reachability as r\nr.shape_reach = lambda problem: None\n"
          "import nhgait.gaits.planning.infeasibility as f\nf.STALL_WINDOW = f.STALL_ATTEMPTS\n"
          "from nhgait.gaits.cli.main import main\nsys.exit(main(sys.argv[1:]))\n")
AFTER = "import sys\nfrom nhgait.gaits.cli.main import main\nsys.exit(main(sys.argv[1:]))\n"


def run(scene: Path, out: Path, arm: str, budget: float) -> dict:
    """One cold plan of ``scene`` in the arm ``arm``: its row."""
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="nhgait-rank-") as cache:
        env = {**os.environ, "NHGAIT_CACHE_DIR": cache, "NHGAIT_BACKGROUND_BUILDS": "0"}
        cmd = [sys.executable, "-c", BEFORE if arm == "before" else AFTER, "plan", str(scene), "--no-gif",
               "--out", str(out), "--time-limit", f"{budget:g}"]
        t0 = time.monotonic()
        with open(out / "plan.log", "w") as log_file:
            proc = subprocess.Popen(cmd, env=env, stdout=log_file, stderr=subprocess.STDOUT,
                                    start_new_session=True)
            try:
                proc.wait(timeout=budget + 120)
            except BaseException:          # past its time, or this script stopped: the plan's group
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                if not isinstance(sys.exc_info()[1], subprocess.TimeoutExpired):
                    raise
        wall = time.monotonic() - t0
    log = (out / "plan.log").read_text(errors="replace")
    solution = out / "solution.json"
    won = json.loads(solution.read_text()).get("guess", {}).get("won") if solution.exists() else None
    return {"scene": str(scene), "arm": arm, "exit": proc.returncode, "verified": proc.returncode == 0,
            "time_s": round(wall, 2), "ranked": "shape loops ranked" in log, "won": won,
            "attempts": len(re.findall(r"^\[[ 0-9.]+ s\]   guess \d+/\d+ ", log, flags=re.M)),
            "phases": phases(log)}


def phases(log: str) -> dict:
    """The plan's own "wall time … in all: model 1.4 s, …" line as {phase: seconds}."""
    found = re.search(r"wall time\s+([0-9.]+) s in all: (.*)", log)
    if not found:
        return {}
    out = {"all": float(found.group(1))}
    for part in found.group(2).split(", "):
        m = re.match(r"(.+?) ([0-9.]+) s$", part.strip())
        if m:
            out[m.group(1)] = float(m.group(2))
    return out


def _terminated(signum, frame):
    """SIGTERM as an exception, so the plan running in its own session is stopped with this script."""
    raise SystemExit(128 + signum)


def main(argv=None) -> int:
    previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        return _run(argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(argv) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=24)
    ap.add_argument("--pairs", type=int, default=6)
    ap.add_argument("--scene", nargs="*", default=[])
    ap.add_argument("--budget", type=float, default=90.0)
    ap.add_argument("--out", default="out/loop_ranking")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each arm per scene")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    scenes = [Path(s) for s in args.scene]
    gen = sibling.load("robot_generator")
    for p in gen.pairs(args.seed, args.pairs):
        folder = out / "scenes"
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{p.name}.toml"
        path.write_text(p.scene)
        scenes.append(path)
    rows = []
    runs = [(scene, k) for scene in scenes for k in range(args.repeat)]
    for i, (scene, k) in enumerate(runs):
        for arm in (("before", "after") if i % 2 == 0 else ("after", "before")):
            row = run(scene, out / "runs" / scene.stem / f"{arm}{k}", arm, args.budget)
            rows.append(row)
            if not args.quiet:
                print(f"{scene.stem:32s} {arm:6s} exit {row['exit']} {row['time_s']:7.1f} s "
                      f"ranked={row['ranked']} won={row['won']}", file=sys.stderr, flush=True)
    summary = {}
    for arm in ("before", "after"):
        mine = [r for r in rows if r["arm"] == arm]
        summary[arm] = {"verified": sum(r["verified"] for r in mine), "of": len(mine),
                        "median_time_s": statistics.median(r["time_s"] for r in mine)}
    before, after = summary["before"]["median_time_s"], summary["after"]["median_time_s"]
    summary["median_ratio_after_before"] = after / before
    for arm in ("before", "after"):                        # where the time went: medians per phase
        mine = [r["phases"] for r in rows if r["arm"] == arm and r["phases"]]
        names = sorted({k for p in mine for k in p})
        summary[arm]["median_phase_s"] = {k: statistics.median(p.get(k, 0.0) for p in mine) for k in names}
        summary[arm]["median_attempts"] = statistics.median(r["attempts"] for r in rows if r["arm"] == arm)
    pairs = {}
    for r in rows:
        pairs.setdefault(r["scene"], {}).setdefault(r["arm"], []).append(r["time_s"])
    ratios = [statistics.median(v["after"]) / statistics.median(v["before"]) for v in pairs.values()
              if v.get("before") and v.get("after")]
    summary["median_paired_ratio"] = statistics.median(ratios) if ratios else None
    ranked = {r["scene"] for r in rows if r["ranked"]}
    summary["scenes_reordered"] = len(ranked)
    changed = [r for r in rows if r["scene"] in ranked]
    for arm in ("before", "after"):
        mine = [r for r in changed if r["arm"] == arm]
        if mine:
            summary[f"reordered_{arm}"] = {"verified": sum(r["verified"] for r in mine),
                                           "median_time_s": statistics.median(r["time_s"] for r in mine)}
    (out / "results.json").write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
