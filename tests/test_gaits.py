"""nhgait.gaits: each gait task at N = 25 against the reference objectives, verification of
the optimal controls by re-simulation (DOP853, rtol 1e-10), the CLI end to end.

Reference objectives at N = 25 from experiments/reference_casadi_ocp.py (same transcription:
RK4, 4 sub-steps, piecewise-constant controls); 1e-4 relative as in the issue's target. The
planner transcribes in the reference's velocity coordinates (``GaitTask.velocities``), so the
NLP is the reference's up to round-off and so are the Ipopt iteration counts.
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

# (system, gait, reference objective, reference Ipopt iterations) at N = 25
CASES = [("unicycle", "parallel-park", 1.543703, 13), ("snakeboard", "forward", 0.110252, 9),
         ("snakeboard", "rotate", 2.162582, 13), ("snakeboard", "lateral", None, None)]


@pytest.mark.parametrize("system, gait, reference, reference_iterations", CASES)
def test_gait_task_small_N(models, system, gait, reference, reference_iterations):
    task = get_task(system, gait)
    model = specialise(models[system]["reduced"], velocities=task.velocities)
    assert model.state_names[-len(task.velocities):] == task.velocities
    problem = task.problem(model, intervals=25)
    sol, attempts, _ = solve_task(problem, task.guess_family)
    assert sol.success, attempts
    if reference is not None:
        assert sol.objective == pytest.approx(reference, rel=1e-4)
        # the reference's coordinates, bounds and guess: its iteration count (+2 for platform noise)
        assert sol.iterations <= reference_iterations + 2
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


def test_velocity_model_has_the_momentum_flow(models):
    """Same controls, same initial condition mapped by state(q, q̇): the configurations agree."""
    import numpy as np
    from nhgait.ocp.solution import simulate_piecewise_constant
    model = models["snakeboard"]["reduced"]
    fast = specialise(model, velocities=("forward_velocity", "psi_dot", "phi_dot"))
    P = model.numeric.params()
    q0, qd0 = np.array([0.1, -0.2, 0.3, 0.1, 0.2]), np.array([0.0, 0.0, 0.0, 0.4, -0.3])
    qd0[:3] = np.asarray(model.numeric["qdot"](model.numeric["state"](q0, qd0, P), P)).ravel()[:3]
    t = np.linspace(0.0, 2.0, 9)
    controls = np.random.default_rng(2).normal(size=(2, 8))
    zv, ok_v = simulate_piecewise_constant(fast, P, t, np.asarray(fast.numeric["state"](q0, qd0, P)).ravel(), controls)
    zp, ok_p = simulate_piecewise_constant(model, P, t, np.asarray(model.numeric["state"](q0, qd0, P)).ravel(), controls)
    assert ok_v and ok_p
    assert np.max(np.abs(zv[:5] - zp[:5])) < 1e-8          # DOP853 at rtol 1e-10 over 2 s
    mapped = np.column_stack([np.asarray(fast.numeric["momentum_state"](zv[:, k], P)).ravel() for k in range(9)])
    assert np.max(np.abs(mapped - zp)) < 1e-8
    # the forward body velocity is the state: ẋ cos θ + ẏ sin θ
    qd = np.asarray(fast.numeric["qdot"](zv[:, -1], P)).ravel()
    assert qd[0] * np.cos(zv[2, -1]) + qd[1] * np.sin(zv[2, -1]) == pytest.approx(zv[5, -1], abs=1e-12)


def test_statement_is_coordinate_free(models):
    """The rotate task on the momentum model reaches the same optimum as in velocity coordinates."""
    task = get_task("snakeboard", "rotate")
    problem = task.problem(specialise(models["snakeboard"]["reduced"]), intervals=25)
    sol, attempts, _ = solve_task(problem, task.guess_family)
    assert sol.success, attempts
    assert sol.objective == pytest.approx(2.162582, rel=1e-4)


def test_bad_velocity_coordinates_are_listed(models):
    with pytest.raises(ValueError, match=r"(?s)'omega' is not a velocity quantity.*repeated names"):
        specialise(models["snakeboard"]["reduced"], velocities=("omega", "psi_dot", "psi_dot"))
    with pytest.raises(ValueError, match="Y X is singular"):
        specialise(models["snakeboard"]["reduced"], velocities=("lateral_velocity", "psi_dot", "phi_dot"))


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
