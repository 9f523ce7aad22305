"""Benchmark: building systems from URDF files and planning TIAGo's parallel park.

For each robot: n, k, the size of the generated Lagrangian, the time to build the System from
the URDF (median of ``--repeats``, sympy's cache cleared before each) and to derive its reduced
equations without the disk cache; then ``nhgait plan examples/tiago_park.toml`` twice in fresh
processes, cold (an empty cache directory) and warm (the same directory), wall time of the whole
command and the planner's own numbers.

Usage: python experiments/bench_urdf.py [--repeats 3] [--robots snakeboard,tiago_base]
       [--no-plan] [--json out/bench_urdf.json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
TIAGO = "example-robot-data:tiago_description/robots/tiago.urdf"
WHEELS = ["wheel_left_joint", "wheel_right_joint"]
#: tiago_3 is the 8-coordinate TIAGo of tests/dynamics/test_urdf_pinocchio.py
ROBOTS = {
    "snakeboard": {"urdf": "snakeboard.urdf", "joints": ["psi", "phi"],
                   "skates": ["back_wheels", "front_wheels"]},
    "roller_racer": {"urdf": "roller_racer.urdf", "joints": ["phi"], "skates": ["front_axle", "rear_axle"]},
    "tiago_base": {"urdf": TIAGO, "joints": WHEELS, "rolling": WHEELS},
    "tiago_shoulder": {"urdf": TIAGO, "joints": WHEELS + ["arm_1_joint"], "rolling": WHEELS},
    "tiago_3": {"urdf": TIAGO, "joints": WHEELS + ["arm_2_joint", "torso_lift_joint", "arm_4_joint"],
                "rolling": WHEELS, "locked": {"arm_1_joint": 0.2, "head_2_joint": -0.3, "arm_6_joint": 0.7}},
    "tiago_5": {"urdf": TIAGO, "joints": WHEELS + ["arm_1_joint", "arm_2_joint", "arm_3_joint", "arm_4_joint",
                                                   "torso_lift_joint"], "rolling": WHEELS},
}


def _build(table):
    from sympy.core.cache import clear_cache

    from nhgait.dynamics.derivation.urdf import urdf_system
    clear_cache()
    t0 = time.perf_counter()
    system = urdf_system(table, EXAMPLES).system
    return system, time.perf_counter() - t0


def bench_robot(name, repeats):
    """n, k, size of L, median build time and one reduced derivation time of one robot."""
    from nhgait.dynamics import derive
    times, system = [], None
    for _ in range(repeats):
        system, dt = _build(ROBOTS[name])
        times.append(dt)
    t0 = time.perf_counter()
    model = derive(system, "reduced", use_cache=False)
    return {"robot": name, "n": system.n, "k": system.k, "L_chars": len(str(system.L)),
            "build_s": statistics.median(times), "derive_reduced_s": time.perf_counter() - t0,
            "form": model.form}


def _plan_once(cache_dir, out_dir):
    env = dict(os.environ, NHGAIT_CACHE_DIR=str(cache_dir))
    command = [sys.executable, "-m", "nhgait.gaits.cli", "plan", str(EXAMPLES / "tiago_park.toml"),
               "--no-gif", "--quiet", "--out", str(out_dir)]
    t0 = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        return {"wall_s": wall, "error": done.stdout[-2000:] + done.stderr[-2000:]}
    data = json.loads((Path(out_dir) / "solution.json").read_text())
    return {"wall_s": wall, "objective": data["objective"], "iterations": data["iterations"],
            "solve_s": data["solve_time_s"], "setup_s": data["setup_time_s"],
            "verification_error": data["verification_error"]}


def bench_plan():
    """Cold and warm ``nhgait plan examples/tiago_park.toml --no-gif``."""
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp) / "cache"
        return {"cold": _plan_once(cache, Path(tmp) / "cold"), "warm": _plan_once(cache, Path(tmp) / "warm")}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--no-plan", action="store_true")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    rows = [bench_robot(name, args.repeats) for name in args.robots.split(",")]
    print("| robot | n | k | L (chars) | build (median) | derive reduced | form |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['robot']} | {r['n']} | {r['k']} | {r['L_chars']} | {r['build_s']:.2f} s | "
              f"{r['derive_reduced_s']:.2f} s | {r['form']} |")
    result = {"robots": rows}
    if not args.no_plan:
        result["plan"] = bench_plan()
        for kind, numbers in result["plan"].items():
            print(f"plan tiago_park ({kind}): " + ", ".join(f"{k} = {v:.6g}" if isinstance(v, float)
                                                            else f"{k} = {v}"
                                                          for k, v in numbers.items()))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
