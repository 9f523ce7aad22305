"""Benchmark: the Whipple bicycle built from bodies against the published benchmark, and what it
costs (issue 27).

Prints and writes (``--out DIR``: bicycle.json, eigenvalues.png):

* accuracy: the largest |λ − published| over Meijaard et al.'s Table 2 (0–10 m/s), the weave
  and capsize speeds found by the stability chart against theirs, the largest error of the
  nonlinear accelerations against Basu-Mandal et al.'s Table 1 (experiments/whipple_published.py);
* cost, measured in this run: the scene built and the reduced ODE derived with an empty cache
  (cold, in a fresh process), loaded from the cache (warm), one linearisation (median of
  ``--repeats``), the chart over ``--speeds``, ``nhgait linearize whipple_bicycle --speed 5``
  warm (median of 3 processes) and ``nhgait plan whipple_bicycle`` cold (an empty cache) and
  warm, wall time of the whole command (unless ``--no-commands``);
* the figure of the eigenvalues against speed with the published values as crosses (the
  README's docs/img/bicycle_eigenvalues.png).

Usage: python experiments/bench_bicycle.py [--out out/bicycle] [--speeds 0:10:101]
       [--repeats 5] [--no-commands] [--no-cold]
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

import numpy as np
import sibling

PUBLISHED = sibling.load("whipple_published")
NHGAIT = [sys.executable, "-m", "nhgait.gaits.cli.main"]


def _in_fresh_process(code: str, cache: str) -> dict:
    """Run ``code`` (which prints one JSON line last) in a new interpreter with ``cache``."""
    env = {**os.environ, "NHGAIT_CACHE_DIR": cache}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


COLD = """
import json, time
t0 = time.perf_counter()
from nhgait.dynamics import derive, load_scene
t1 = time.perf_counter(); system = load_scene("whipple_bicycle").system
t2 = time.perf_counter(); derive(system)
t3 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "scene_s": t2 - t1, "derive_s": t3 - t2}))
"""


def _command_time(args: list, cache: str) -> float:
    env = {**os.environ, "NHGAIT_CACHE_DIR": cache}
    t0 = time.perf_counter()
    subprocess.run(NHGAIT + args, env=env, capture_output=True, text=True)
    return time.perf_counter() - t0


def accuracy(model, speeds) -> dict:
    """Errors against the published values and the chart (module docstring)."""
    from nhgait.dynamics.linearisation import linearise, stability_chart
    worst = 0.0
    for v, published in PUBLISHED.TABLE2.items():
        ours = sorted(linearise(model, speed=float(v)).eigenvalues, key=lambda x: (round(x.real, 6), x.imag))
        theirs = sorted(np.asarray(published, complex), key=lambda x: (round(x.real, 6), x.imag))
        worst = max(worst, max(abs(a - b) for a, b in zip(ours, theirs, strict=True)))
    t0 = time.perf_counter()
    chart = stability_chart(model, speeds)
    chart_s = time.perf_counter() - t0
    weave, capsize = (c.speed for c in chart.changes[:2])
    basu = PUBLISHED.basu_mandal_accelerations(model)
    return {"table2_max_abs_error": worst, "weave_speed": weave, "weave_error": abs(weave - PUBLISHED.WEAVE),
            "capsize_speed": capsize, "capsize_error": abs(capsize - PUBLISHED.CAPSIZE),
            "basu_mandal_max_abs_error": max(abs(basu[k] - v) for k, v in PUBLISHED.BASU_OUTPUT.items()),
            "chart_s": chart_s, "chart_speeds": len(speeds)}, chart


def costs(model, repeats: int, cold: bool, commands: bool) -> dict:
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.linearisation import linearise
    out = {}
    if cold:
        with tempfile.TemporaryDirectory() as cache:
            out["cold"] = _in_fresh_process(COLD, cache)
    t0 = time.perf_counter()
    system = load_scene("whipple_bicycle").system
    t1 = time.perf_counter()
    derive(system)
    out["warm"] = {"scene_s": t1 - t0, "derive_s": time.perf_counter() - t1}
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        linearise(model, speed=5.0)
        times.append(time.perf_counter() - t0)
    out["linearise_median_s"] = statistics.median(times)
    if not commands:
        return out
    cache = os.environ.get("NHGAIT_CACHE_DIR") or str(Path.home() / ".cache" / "nhgait")
    out["cli_linearize_warm_median_s"] = statistics.median(
        _command_time(["linearize", "whipple_bicycle", "--speed", "5", "--quiet"], cache) for _ in range(3))
    with tempfile.TemporaryDirectory() as fresh, tempfile.TemporaryDirectory() as dest:
        out["plan_cold_s"] = _command_time(["plan", "whipple_bicycle", "--quiet", "--out", dest], fresh)
        out["plan_warm_s"] = _command_time(["plan", "whipple_bicycle", "--quiet", "--out", dest], fresh)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/bicycle")
    parser.add_argument("--speeds", default="0:10:101")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-commands", action="store_true",
                        help="skip the timed nhgait commands (linearize warm, plan cold and warm)")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold derivation in a fresh process")
    args = parser.parse_args(argv)
    from nhgait.dynamics import derive, load_scene
    from nhgait.dynamics.linearisation.chart import parse_speeds
    from nhgait.gaits.figures.stability import write_eigenvalue_figure
    model = derive(load_scene("whipple_bicycle").system)
    found, chart = accuracy(model, parse_speeds(args.speeds))
    found.update(costs(model, args.repeats, not args.no_cold, not args.no_commands))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bicycle.json").write_text(json.dumps(found, indent=1))
    figure = write_eigenvalue_figure(
        chart, out, title="Whipple bicycle built from bodies: eigenvalues of upright straight motion",
        reference=PUBLISHED.TABLE2, reference_label="Meijaard et al. 2007, Table 2")
    for key, value in found.items():
        print(f"{key:32} {value}")
    print(f"wrote {out / 'bicycle.json'} and {figure}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
