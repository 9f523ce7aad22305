"""The coarse grid first (:mod:`nhgait.ocp.coarse`, issue 25): the task solved on ⌊N/3⌋ intervals,
then on its own grid from that answer — the same optimum as the direct solve, a fallback to the
direct solve when the coarse one fails, and no coarse grid where one does not apply."""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.gaits.planner import prepare
from nhgait.gaits.planning.guesses import candidates
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import OCPSolver, SolverOptions
from nhgait.ocp.coarse import coarse_intervals, resampled
from nhgait.ocp.solver import InitialGuess


def _parking(intervals: int):
    return prepare(resolve("unicycle", "parallel-park", overrides=[f"intervals={intervals}"])).problem


@pytest.fixture(scope="module")
def parking():
    problem = _parking(45)
    return problem, candidates(problem)[0]


def test_a_guess_resampled_keeps_lines_and_holds_inputs(parking):
    """States linear in t come back exactly; each target interval takes the input of the source
    interval that holds its midpoint."""
    fine, _ = parking
    coarse = fine.replace(intervals=15)
    tc, tf = coarse.grid(), fine.grid()
    nz, nu = fine.n_states, fine.n_controls
    states = np.vstack([a + b * tc for a, b in zip(range(nz), np.linspace(-1, 1, nz), strict=True)])
    controls = np.tile(np.arange(15.0), (nu, 1))
    out = resampled(InitialGuess(states, controls), coarse, fine)
    expect = np.vstack([a + b * tf for a, b in zip(range(nz), np.linspace(-1, 1, nz), strict=True)])
    np.testing.assert_allclose(out.states, expect, atol=1e-12)
    mids = (tf[:-1] + tf[1:]) / 2
    np.testing.assert_array_equal(out.controls[0], np.floor(mids / (tc[1] - tc[0])))


def test_coarse_first_reaches_the_direct_solves_optimum(parking):
    problem, guess = parking
    direct = OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False)).solve(guess)
    two = OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False, coarse=True)).solve(guess)
    assert direct.success
    assert two.success
    assert two.stats["coarse_intervals"] == 15
    assert two.stats["coarse_status"] == "Solve_Succeeded"
    assert two.stats["coarse_iterations"] > 0
    assert two.settings["coarse_intervals"] == 15
    assert two.objective == pytest.approx(direct.objective, rel=1e-6)
    np.testing.assert_allclose(two.z, direct.z, atol=1e-4)
    assert two.constraint_violation < 1e-8


def test_a_failed_coarse_solve_falls_back_to_the_direct_one(parking, monkeypatch):
    problem, guess = parking
    solver = OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False, coarse=True))
    n, sub, warm = solver.coarse
    monkeypatch.setattr(sub, "solve", lambda g: sub.unsolved(g, "Solver_Died", "on purpose"))
    fallback = solver.solve(guess)
    direct = OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False)).solve(guess)
    assert fallback.stats["coarse_status"] == "Solver_Died"
    assert fallback.success
    assert fallback.iterations == direct.iterations
    assert fallback.objective == pytest.approx(direct.objective, rel=1e-10)


@pytest.mark.parametrize("intervals, solver, expected",
                         [(45, "ipopt", 15), (60, "ipopt", 20), (44, "ipopt", None), (45, "fatrop", None)])
def test_where_a_coarse_grid_applies(intervals, solver, expected):
    assert coarse_intervals(_parking(intervals), solver) == expected


def test_no_coarse_grid_with_waypoints():
    problem = _parking(45)
    from nhgait.ocp.statement import Waypoint
    with_waypoint = problem.replace(waypoints=(Waypoint(problem.horizon / 3, {"x": 0.0}),))
    assert coarse_intervals(with_waypoint, "ipopt") is None
