#!/usr/bin/env python3
"""Benchmark of issue 28: do planned gaits survive the real robot? One run, numbers printed.

1. Snakeboard forward gait (P2: 1 m in one period, N = 100), the robot's m +10 % and J_r −10 %,
   20 noisy samples (``nhgait track`` defaults: initial state 1 % of each state's scale, input
   5 % of the plan's peak input per interval): the closed loop's worst final position error
   against the open loop's median (target ≤ 0.1).
2. TIAGo's parallel park (examples/tiago_park.toml; its URDF comes with ``nhgait[pinocchio]``), the base
   link's mass +10 % (``params.m_base``), 20 samples: the same ratio (target ≤ 0.1).
3. 100 tracked samples of a 6-coordinate robot — the snakeboard with independently steered
   wheels (experiments/scaling_systems.py, its forward task of experiments/scale_tasks.py,
   m +10 %) — on 2 worker processes (``workers``): the wall time of the samples (the compiled
   closed loop; workers start, load the model from the cache and run; target ≤ 60 s) and of
   the whole study.
4. Floquet multipliers of the snakeboard's periodic forward gait: the closed loop's and the
   open loop's monodromy (the variational equation, CVODES) against central differences of
   DOP853 flows at rtol 1e-13 (``finite_difference_monodromy``): largest entry and multiplier
   differences (target ≤ 1e-6).
5. Robust planning (``[task.robust]``): the snakeboard's forward gait planned against the
   grid m ×{0.9, 1.1}, J_r ×{0.9, 1.1} (4 copies, mean terminal deviation, weight 1) and the
   nominal plan, both tracked as in part 1 (m +10 %, J_r −10 %, the same 20 noisy samples and
   seed): open-loop final position error median / max and the noise-free run, closed loop too,
   the objectives and the robust plan's time.

Writes ``out/bench_tracking.json``. The machine's cores may be shared: quote one run.

Usage: python experiments/bench_tracking.py [--quick] [--workers 2]
       [--sections snakeboard,tiago,six,floquet,robust] [--out out/bench_tracking.json]
(``--quick``: N = 30 plans (part 3's too), 4 samples, 8 samples of part 3 — a smoke run, not the targets.)
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

ROOT = Path(__file__).resolve().parents[1]


def _ratio(report) -> dict:
    f = {loop: report[loop]["final_position_error"] for loop in ("open_loop", "closed_loop")}
    return {"open_median": f["open_loop"]["median"], "open_max": f["open_loop"]["max"],
            "closed_median": f["closed_loop"]["median"], "closed_max": f["closed_loop"]["max"],
            "ratio": report["closed_max_over_open_median"], "unit": f["open_loop"]["unit"],
            "saturation_s_closed_median": report["closed_loop"]["saturation_time_s"]["median"],
            "saturation_s_open_median": report["open_loop"]["saturation_time_s"]["median"]}


def snakeboard(samples: int, overrides) -> dict:
    from nhgait.gaits.tracking.study import track
    t0 = time.perf_counter()
    result = track("snakeboard", "forward", overrides=overrides, mismatch=["params.m=1.1", "params.J_r=0.9"],
                   samples=samples, seed=0)
    return {**_ratio(result.report), "wall_s": time.perf_counter() - t0, "samples": samples}


def tiago(samples: int, overrides) -> dict:
    from importlib import metadata
    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return {"skipped": "needs pip install 'nhgait[pinocchio]' (TIAGo's URDF is in example-robot-data)"}
    from nhgait.gaits.tracking.study import track
    t0 = time.perf_counter()
    result = track(str(ROOT / "examples" / "tiago_park.toml"), overrides=overrides,
                   mismatch=["params.m_base=1.1"], samples=samples, seed=0)
    return {**_ratio(result.report), "wall_s": time.perf_counter() - t0, "samples": samples}


def six_coordinates(samples: int, workers: int, folder: Path, overrides=()) -> dict:
    from nhgait.gaits.tracking.study import track
    scene = folder / "snakeboard_two_steering.toml"
    scene.write_text(sibling.load("scale_tasks").scene_with_task("snakeboard_two_steering"))
    t0 = time.perf_counter()
    result = track(str(scene), overrides=list(overrides), mismatch=["params.m=1.1"], samples=samples, seed=0,
                   workers=workers)
    wall = time.perf_counter() - t0
    return {**_ratio(result.report), "samples": samples, "workers": workers, "n": 6,
            "samples_s": result.timings["samples_s"], "plan_s": result.timings["plan_s"], "wall_s": wall,
            "per_sample_ms": 1e3 * result.timings["samples_s"] / samples}


def floquet(overrides) -> dict:
    from nhgait.gaits.planner import plan, prepare
    from nhgait.ocp.floquet import Loop, finite_difference_monodromy
    from nhgait.ocp.transcription import ode_function
    result = plan("snakeboard", "forward", overrides=overrides)
    st, fb = result.solution.stability, result.solution.feedback
    ode = ode_function(prepare(result.plan).problem)
    out = {}
    t0 = time.perf_counter()
    for loop, gains, analytic, mu in (("closed_loop", fb.gains, st.closed_loop, st.closed_multipliers),
                                      ("open_loop", None, st.open_loop, None)):
        fd = finite_difference_monodromy(Loop(ode, fb.t, fb.states, fb.controls, fb.rates, gains))
        row = {"max_entry_difference": float(np.max(np.abs(fd - analytic))),
               "max_abs_multiplier": float(np.max(np.abs(np.linalg.eigvals(analytic))))}
        if mu is not None:
            fd_mu = np.linalg.eigvals(fd)
            fd_mu = fd_mu[np.argsort(-np.abs(fd_mu), kind="stable")]
            row["max_multiplier_difference"] = float(np.max(np.abs(fd_mu - mu)))
            row["multipliers"] = [[float(m.real), float(m.imag)] for m in mu]
        out[loop] = row
    out["finite_differences_s"] = time.perf_counter() - t0
    out["summary"] = st.summary()
    return out


#: the copies of part 5: every combination of these factors (the nominal one left out)
ROBUST = {"parameters": {"m": [0.9, 1.1], "J_r": [0.9, 1.1]}}


def robust(samples: int, overrides) -> dict:
    """Part 5: the nominal and the robust plan of the forward gait, tracked under one mismatch."""
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.gaits.tracking.study import track
    task = resolve("snakeboard", "forward", overrides=overrides).task.to_dict()
    out = {}
    for label, extra in (("nominal", {}), ("robust", {"robust": ROBUST})):
        t0 = time.perf_counter()
        result = track("snakeboard", {**task, **extra}, mismatch=["params.m=1.1", "params.J_r=0.9"],
                       samples=samples, seed=0)
        wall, report, solution = time.perf_counter() - t0, result.report, result.plan.solution
        out[label] = {**_ratio(report),
                      "noise_free_open": report["open_loop"]["noise_free_final_position_error"],
                      "objective": solution.objective, "plan_s": result.timings["plan_s"], "wall_s": wall,
                      "robust": solution.settings.get("robust")}
    out["copies"] = ROBUST
    return out


def _print_robust(r: dict) -> None:
    for label in ("nominal", "robust"):
        x = r[label]
        effort = x["objective"] if x["robust"] is None else x["robust"]["task_objective"]
        print(f"  {label:8s} plan: J = {x['objective']:.4g} (the task's {effort:.4g}), planned in "
              f"{x['plan_s']:.1f} s; open loop final position "
              f"error median {x['open_median']:.4g} {x['unit']}, max {x['open_max']:.4g} (noise-free "
              f"{x['noise_free_open']:.4g}); closed loop median {x['closed_median']:.4g}, max "
              f"{x['closed_max']:.4g}")
    n, b = r["nominal"], r["robust"]
    dev = b["robust"]
    print(f"  robust / nominal open loop: median {b['open_median'] / n['open_median']:.3f}, max "
          f"{b['open_max'] / n['open_max']:.3f}, noise-free "
          f"{b['noise_free_open'] / n['noise_free_open']:.3f}; "
          f"copies' mean terminal deviation {dev['nominal_plan']['mean']:.3g} → "
          f"{dev['robust_plan']['mean']:.3g} (units of (0.02 s_i)²)")


def _print(results: dict) -> None:
    if "robust" in results:
        print("robust planning (snakeboard forward, copies m ×{0.9, 1.1}, J_r ×{0.9, 1.1}; tracked "
              "with m +10 %, J_r −10 %):")
        _print_robust(results["robust"])
    for name in ("snakeboard", "tiago"):
        if name not in results:
            continue
        r = results[name]
        if "skipped" in r:
            print(f"{name}: skipped ({r['skipped']})")
            continue
        print(f"{name}: {r['samples']} samples; final position error open median {r['open_median']:.4g} "
              f"{r['unit']} (max {r['open_max']:.4g}), closed median {r['closed_median']:.4g}, max "
              f"{r['closed_max']:.4g}; closed max / open median = {r['ratio']:.4f} (target ≤ 0.1); "
              f"inputs at a bound {r['saturation_s_open_median']:.3g} s open, "
              f"{r['saturation_s_closed_median']:.3g} s closed (medians); {r['wall_s']:.1f} s")
    if "six_coordinates" not in results or "floquet" not in results:
        return
    r = results["six_coordinates"]
    print(f"two-steering snakeboard (n = 6): {r['samples']} samples on {r['workers']} workers in "
          f"{r['samples_s']:.1f} s ({r['per_sample_ms']:.0f} ms per sample, open + closed loop; "
          "target ≤ 60 s), "
          f"plan {r['plan_s']:.1f} s, whole study {r['wall_s']:.1f} s; closed max / open median = "
          f"{r['ratio']:.4f}")
    f = results["floquet"]
    print(f"Floquet (snakeboard forward gait): closed loop multipliers agree with finite differences to "
          f"{f['closed_loop']['max_multiplier_difference']:.2e}, monodromy entries to "
          f"{f['closed_loop']['max_entry_difference']:.2e} (open loop "
          f"{f['open_loop']['max_entry_difference']:.2e}); target ≤ 1e-6")
    for line in f["summary"]:
        print(f"  {line}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a smoke run (small N and few samples)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes of part 3 (default 2)")
    ap.add_argument("--sections", default="snakeboard,tiago,six,floquet,robust",
                    help="parts to run, comma-separated (default: all)")
    ap.add_argument("--out", default="out/bench_tracking.json")
    args = ap.parse_args(argv)
    sections = set(args.sections.split(","))
    overrides = ["intervals=30"] if args.quick else []
    samples, many = (4, 8) if args.quick else (20, 100)
    results = {"quick": args.quick}
    with tempfile.TemporaryDirectory() as folder:
        if "snakeboard" in sections:
            results["snakeboard"] = snakeboard(samples, overrides)
        if "tiago" in sections:
            results["tiago"] = tiago(samples, overrides)
        if "six" in sections:
            results["six_coordinates"] = six_coordinates(many, args.workers, Path(folder), overrides)
    if "floquet" in sections:
        results["floquet"] = floquet(overrides)
    if "robust" in sections:
        results["robust"] = robust(samples, ["intervals=50"] if args.quick else [])
    _print(results)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=1))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
