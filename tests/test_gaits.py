"""nhgait.gaits: each gait task at N = 25 against the reference objectives, verification of
the optimal controls by re-simulation (DOP853, rtol 1e-10), the CLI end to end.

Reference objectives at N = 25 from experiments/reference_casadi_ocp.py (same transcription:
RK4, 4 sub-steps, piecewise-constant controls); 1e-4 relative as in the issue's target (our
momentum coordinates change the snakeboard's RK4 iterates by ~1e-6 relative at N = 25).
Verification bound: the RK4 global error at h = T/(4N) — measured 4e-8 (P2) and 8e-6 (P3)
at N = 25 — so 1e-4 at N = 25 (the ≤ 1e-6 target holds at N ≥ 100, see the benchmark).
"""
from __future__ import annotations

import argparse
import json
import math

import pytest

from nhgait.gaits.planner import solve_task, specialise
from nhgait.gaits.tasks import TASKS, get_task

CASES = [("unicycle", "parallel-park", 1.543703), ("snakeboard", "forward", 0.110252),
         ("snakeboard", "rotate", 2.162582), ("snakeboard", "lateral", None)]


@pytest.mark.parametrize("system, gait, reference", CASES)
def test_gait_task_small_N(models, system, gait, reference):
    task = get_task(system, gait)
    problem = task.problem(specialise(models[system]["reduced"]), intervals=25)
    sol, attempts, _ = solve_task(problem, task.guess_family)
    assert sol.success, attempts
    if reference is not None:
        assert sol.objective == pytest.approx(reference, rel=1e-4)
    v = sol.verify()
    assert v.success and v.max_error < 1e-4
    if gait == "lateral":  # P4: net sideways shift, back to x = 0 and θ = 0
        assert sol.state("y")[-1] == pytest.approx(0.5, abs=1e-8)
        assert abs(sol.state("x")[-1]) < 1e-8 and abs(sol.state("theta")[-1]) < 1e-8


def test_specialised_model_agrees_with_general(models):
    import numpy as np
    model = models["snakeboard"]["reduced"]
    fast = specialise(model)
    assert fast.simplified
    rng = np.random.default_rng(1)
    P = model.numeric.params()
    for _ in range(20):
        z, u = rng.uniform(-1, 1, 8), rng.normal(size=2)
        a = np.asarray(fast.numeric["rhs"](0, z, u, P)).ravel()
        b = np.asarray(model.numeric["rhs"](0, z, u, P)).ravel()
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12)


def test_unknown_gait_lists_known():
    with pytest.raises(ValueError, match="unknown gait 'moonwalk'.*snakeboard forward"):
        get_task("snakeboard", "moonwalk")
    assert {("snakeboard", "forward"), ("snakeboard", "rotate"), ("snakeboard", "lateral"),
            ("unicycle", "parallel-park")} <= set(TASKS)


def test_cli_plan_end_to_end(tmp_path, capsys, _temporary_cache):
    from nhgait.gaits.cli_plan import add_plan_parser
    ap = argparse.ArgumentParser(prog="nhgait")
    add_plan_parser(ap.add_subparsers())
    out = tmp_path / "demo"
    args = ap.parse_args(["plan", "snakeboard", "--gait", "forward", "--intervals", "25",
                          "--distance", "0.8", "--out", str(out)])
    assert args.func(args) == 0
    text = capsys.readouterr().out
    assert "objective" in text and "verification error" in text
    data = json.loads((out / "solution.json").read_text())
    for key in ("success", "status", "objective", "iterations", "solve_time_s", "setup_time_s",
                "verification_error", "settings", "trajectory"):
        assert key in data
    assert data["success"] and data["verification_error"] < 1e-4
    assert math.isclose(data["trajectory"]["states"]["x"][-1], 0.8, abs_tol=1e-8)
    for name in ("path.png", "shape.png", "histories.png", "momentum.png", "motion.gif"):
        assert (out / name).stat().st_size > 0
