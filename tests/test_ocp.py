"""nhgait.ocp: problem validation, transcriptions, solver outcomes, solution files.

Reference objectives are those of the hand-written CasADi reference
(experiments/reference_casadi_ocp.py, RK4 with 4 sub-steps, piecewise-constant controls).
Our state uses momenta instead of velocities; for the unicycle the two are linearly related
(identical RK4 iterates), for the snakeboard the RK4 discretisation differs by O(h⁴), measured
≤ 1e-6 relative at N = 25 — so 1e-4 relative is the stated target tolerance.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from nhgait.ocp import (Collocation, InitialGuess, OCPSolver, OptimalControlProblem, ProblemError,
                        SolverOptions, solve)

REF_25 = {"P1": 1.543703, "P2": 0.110252, "P3": 2.162582}


@pytest.fixture(scope="module")
def unicycle(models):
    from nhgait.gaits.planner import specialise
    return specialise(models["unicycle"]["reduced"])


@pytest.fixture(scope="module")
def snakeboard(models):
    from nhgait.gaits.planner import specialise
    return specialise(models["snakeboard"]["reduced"])


def p1(model, N=25, **kw):
    return OptimalControlProblem(model, 4.0, N, initial={n: 0.0 for n in model.state_names},
                                 final={"x": 0.0, "y": 0.5, "theta": 0.0, "p": 0.0, "pt_theta": 0.0},
                                 control_bounds=5.0, **kw)


def p1_guess(problem):
    from nhgait.gaits.guesses import FAMILIES, guess_from_shape
    return guess_from_shape(problem, FAMILIES["unicycle-park"][0])


def test_ocp_does_not_import_sympy():
    code = ("import sys, nhgait.ocp.problem, nhgait.ocp.transcription, nhgait.ocp.solver, "
            "nhgait.ocp.solution; print('sympy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_bad_statements_list_every_problem(unicycle):
    with pytest.raises(ProblemError, match=r"(?s)horizon T = -1.*intervals N = 0.*unknown quantity 'zz'"
                                           r".*contradictory bounds lo = 2 > hi = 1.*unknown input 'tau_q'"):
        OptimalControlProblem(unicycle, -1.0, 0, initial={"zz": 0.0}, state_bounds={"phi": (2.0, 1.0)},
                              control_bounds={"tau_q": (-1, 1)})
    with pytest.raises(ValueError, match="lies outside state_bounds"):
        OptimalControlProblem(unicycle, 1.0, 10, initial={"phi": 3.0}, state_bounds={"phi": (-1, 1)})
    with pytest.raises(ValueError, match="periodic 'theta'.*cannot be equal"):
        OptimalControlProblem(unicycle, 1.0, 10, initial={"theta": 0.0}, final={"theta": 1.0}, periodic=["theta"])
    with pytest.raises(ValueError, match="unknown transcription"):
        OCPSolver(p1(unicycle), "shooting-stars")


def test_p1_multiple_shooting_matches_reference(unicycle):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem))
    assert sol.success, sol.message
    assert sol.objective == pytest.approx(REF_25["P1"], rel=1e-4)
    # exact piecewise-constant objective: Σ h |u_k|²
    assert sol.objective == pytest.approx(problem.horizon / 25 * np.sum(sol.controls ** 2), rel=1e-12)
    v = sol.verify()
    assert v.success and v.max_error < 1e-6   # RK4 (h = 0.04) vs DOP853 at rtol 1e-10
    assert sol.state("y")[-1] == pytest.approx(0.5, abs=1e-9)


def test_collocation_agrees_with_shooting(unicycle):
    problem = p1(unicycle)
    ms = solve(problem, p1_guess(problem))
    col = solve(problem, p1_guess(problem), transcription=Collocation(degree=3))
    assert col.success, col.message
    # both converge to the continuous optimum 1.5338 with O(h^4)-size transcription differences
    assert col.objective == pytest.approx(ms.objective, rel=2e-2)


def test_failure_is_a_solution_not_an_exception(unicycle):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem), max_iter=2)
    assert not sol.success and sol.status == "Maximum_Iterations_Exceeded"
    # infeasible statement: reach y = 50 with |tau| <= 1e-3
    bad = OptimalControlProblem(unicycle, 1.0, 10, initial={n: 0.0 for n in unicycle.state_names},
                                final={"y": 50.0}, control_bounds=1e-3)
    sol = solve(bad, p1_guess(p1(unicycle, N=10)), max_iter=50)
    assert sol.success is False and sol.status


def test_solution_json_keys(unicycle, tmp_path):
    problem = p1(unicycle)
    sol = solve(problem, p1_guess(problem)).verified()
    data = json.loads(sol.to_json(tmp_path / "s.json").read_text())
    for key in ("success", "status", "objective", "iterations", "solve_time_s", "setup_time_s",
                "verification_error", "settings", "trajectory"):
        assert key in data
    assert data["verification_error"] == pytest.approx(sol.verification_error)
    assert len(data["trajectory"]["t"]) == 26 and set(data["trajectory"]["controls"]) == {"tau_theta", "tau_phi"}


def test_free_horizon_and_jit_cache(unicycle, tmp_path):
    problem = p1(unicycle, N=10)
    guess = p1_guess(problem)
    s1 = OCPSolver(problem, options=SolverOptions(jit=True))
    s2 = OCPSolver(problem, options=SolverOptions(jit=True))
    assert s1.jit_cached is False and s2.jit_cached is True
    a, b = s1.solve(guess), solve(problem, guess)
    assert a.success and a.objective == pytest.approx(b.objective, rel=1e-8)
    free = problem.replace(free_horizon=(2.0, 8.0), time_weight=0.1)
    sol = solve(free, guess)
    assert sol.success and 2.0 <= sol.horizon <= 8.0 and sol.horizon != pytest.approx(4.0)
