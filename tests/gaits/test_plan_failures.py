"""A plan succeeds only when it is verified; a failure says why (issue 19, item 6).

References: the verification is an independent re-simulation (scipy DOP853, rtol 1e-10); the
coarse grid below (4 intervals over 4 s, RK4 steps of 0.25 s) cannot be accurate to 1e-6 for
the parallel-park's manoeuvre, but is to 1e-2 — which the task's ``verify_tolerance`` decides.
The infeasible task asks the unicycle to move 0.5 m sideways with torques of at most 0.01 N·m:
the wheel's inertia (J_phi + m r² = 0.205 kg·m²) allows at most 0.01/0.205 · T²/4 · r ≈ 0.002 m
of rolling in T = 4 s, far from the 0.5 m asked.
"""
from __future__ import annotations

import json

import pytest

from nhgait.gaits.cli.main import main
from nhgait.gaits.planner import plan

P1 = {"horizon": 4.0, "intervals": 4, "control_bounds": 5.0,
      "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0}, "final": {"x": 0.0, "y": 0.5, "theta": 0.0},
      "rest": ["initial", "final"]}


def test_a_converged_plan_that_misses_the_task_is_refined_or_a_failure():
    """4 intervals of 1 s: with 4 RK4 sub-steps the optimum misses its re-simulation; the planner
    solves it again with more sub-steps (gaits.verification.refinement) and verifies that. A tolerance no
    refinement reaches (below the re-simulation's own rtol) leaves a converged, unverified
    plan: a failure that says so; a loose one accepts the first optimum as it is."""
    result = plan("unicycle", P1, jit=False, solver="ipopt")
    first = result.attempts[0]
    assert first.success
    assert "refined to" in result.attempts[-1].label
    assert result.success
    assert result.solution.verification.max_error <= 1e-6
    assert result.solution.settings["rk4_steps"] > 4
    tight = plan("unicycle", {**P1, "verify_tolerance": 1e-13}, jit=False, solver="ipopt")
    s = tight.solution
    assert s.stats["solver_status"] == "Solve_Succeeded"           # the solver converged …
    assert not tight.success  # … but it is not a gait
    assert s.status == "Verification_Failed"
    v = s.verification
    assert not v.passed
    assert v.max_error > 1e-13
    text = "\n".join(tight.diagnosis)
    assert "does not meet the task to 1e-13" in text
    assert "increase intervals (now 4" in text
    assert "even refined to" in text
    loose = plan("unicycle", {**P1, "verify_tolerance": 1e-2}, jit=False, solver="ipopt")
    assert loose.success
    assert loose.solution.verification.max_error <= 1e-2
    assert not any("refined" in a.label for a in loose.attempts)           # nothing solved again
    # the first optimum, accepted
    assert loose.solution.objective == pytest.approx(first.objective, rel=1e-9)


TASK_TOML = """
[task]
horizon = 4.0
intervals = 4
initial = {x = 0.0, y = 0.0, theta = 0.0, phi = 0.0}
final = {x = 0.0, y = 0.5, theta = 0.0}
rest = ["initial", "final"]
control_bounds = 5.0
verify_tolerance = 1e-13
"""


def _scene(tmp_path, task_text):
    from importlib import resources
    text = resources.files("nhgait.dynamics.derivation").joinpath("scenes", "unicycle.toml").read_text()
    path = tmp_path / "unicycle_task.toml"
    path.write_text(text + task_text)
    return path


def test_cli_exits_1_and_writes_a_failed_solution(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["plan", str(_scene(tmp_path, TASK_TOML)), "--no-jit", "--solver", "ipopt", "--quiet",
                 "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 1
    assert "FAILED (Verification_Failed)" in printed
    assert "why:" in printed
    data = json.loads((out / "solution.json").read_text())
    assert data["success"] is False
    assert data["verification"]["passed"] is False
    assert data["diagnosis"]
    assert (out / "path.png").exists()  # marked FAILED, no animation
    assert not (out / "motion.gif").exists()


def test_an_infeasible_task_names_what_is_violated(tmp_path):
    # |τ| ≤ 0.012: the energy bound allows 0.55 m sideways in 4 s (0.01 allowed only 0.46 m and
    # is refused before any solve, test_numeric_extremes.py); the solver finds it infeasible
    task = {**P1, "intervals": 20, "control_bounds": 0.012}
    result = plan("unicycle", task, jit=False, solver="ipopt", max_guesses=2)
    assert not result.success
    assert result.solution.status != "Solve_Succeeded"
    text = "\n".join(result.diagnosis)
    assert text.startswith("no guess converged:")
    assert "at the closest point found" in text
    assert "violated by" in text
    # the minimum-violation solve says what must move (issue 41): no gait within these bounds
    assert "possibly infeasible" in text and "each alone, the others as stated:" in text
    # the closest point cannot meet the sideways target: final.y (or the dynamics) is named
    assert "final.y" in text or "shooting gaps" in text
    statuses = {a.status for a in result.attempts}
    assert not any(s.startswith("fatrop_return_flag") or s.startswith("FATROP return flag") for s in statuses)


def test_a_budget_spent_after_a_guess_converged_does_not_say_none_did():
    """``--time-limit 2`` on the snakeboard: guess 1 converged, the budget ran out in the
    exploration; the diagnosis said "no guess converged: 2 attempts (1 Solve_Succeeded, …)" and
    "the solver stopped before reporting a point" (a user's trial, 2026-11-29). It names the
    converged guess instead; without one it lists the attempts as before."""
    from types import SimpleNamespace

    from nhgait.gaits.planning.search import Attempt
    from nhgait.gaits.verification.diagnosis import _out_of_time
    overrun = SimpleNamespace(lines=lambda: ["the time budget of 2 s ran out during verification"])
    tried = [Attempt(label="psi:phi 1:1", status="Solve_Succeeded", success=True, iterations=9,
                     objective=0.109703, solver="fatrop"),
             Attempt(label="fitted roll-out", status="Line_Search_Failed", success=False, iterations=3,
                     objective=4.2, solver="fatrop", constraint_violation=0.16)]
    result = SimpleNamespace(overrun=overrun, attempts=tried, solution=None, screening=())
    lines = _out_of_time(result)
    assert lines[1] == ("a guess had converged ('psi:phi 1:1', Solve_Succeeded, J = 0.109703): "
                        "solution.json holds it, not verified")
    assert not any("no guess converged" in line for line in lines)
    lines = _out_of_time(SimpleNamespace(overrun=overrun, attempts=tried[1:], solution=None, screening=()))
    assert lines[1] == "no guess converged: 1 attempts (1 Line_Search_Failed)"


def test_a_failed_continuation_step_short_of_the_task_is_not_its_closest_point(monkeypatch):
    """The continuation's first step solves an easier task (a quarter of the way to the final
    values): its failed point was reported as the plan's closest one — J and trajectory of a
    task with y(T) = 0.125 instead of 0.5 (a user's trial, 2026-11-29). Only the last step,
    the task itself, may be."""
    from types import SimpleNamespace

    from nhgait.gaits.planning import search

    class Task:
        initial, final = {"y": 0.0}, {"y": 0.5}

        def bounds(self, mapping, name):
            return mapping[name], mapping[name]

        def replace(self, final):
            easier = Task()
            easier.final = final
            return easier

    class Solver:
        options, problem = SimpleNamespace(solver="ipopt"), Task()

        def with_problem(self, problem):
            asked.append(problem.final["y"])
            return self

    asked = []
    failed = SimpleNamespace(success=False, status="Maximum_Iterations_Exceeded", iterations=500,
                             objective=0.22, constraint_violation=1e-7, solve_time_s=0.1)
    monkeypatch.setattr(search, "solve_attempts", lambda solver, guesses, **kw: [failed])
    found = search.continuation(Solver(), SimpleNamespace(label="fitted roll-out"))
    assert asked == [0.125] and found.closest is None and len(found.attempts) == 1
    found = search.continuation(Solver(), SimpleNamespace(label="fitted roll-out"), steps=(1.0,))
    assert asked[-1] == 0.5 and found.closest is failed


def test_too_few_intervals_for_the_task_is_refused_before_any_solve():
    """The parallel park on N = 2: 12 equality rows (six states' dynamics twice) on 11 free
    unknowns once the ends are fixed — no point meets them in general; CasADi said "NLP is
    overconstrained" at each of 26 attempts, with --quiet too, before the plan failed. N = 3
    has as many unknowns as rows and is planned."""
    from nhgait.ocp import OCPSolver, ProblemError, SolverOptions
    said = r"(?s)overdetermined problem.*N = 2 intervals: 12 equality conditions .* on 11 free unknowns"
    with pytest.raises(ProblemError, match=said + " — give the task more intervals"):
        plan("unicycle", "parallel-park", intervals=2, jit=False)
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.tasks.sources import resolve
    problem = prepare(resolve("unicycle", "parallel-park", overrides=["intervals=3"])).problem
    assert OCPSolver(problem, None, SolverOptions(jit=False)).nlp.n_w > 0
