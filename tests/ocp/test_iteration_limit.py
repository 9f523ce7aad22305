"""``SolverOptions.iteration_limit`` (issue 25): a solve stopped after that many iterations by
Ipopt's iteration callback, below the ``max_iter`` the solver was made with (the planner's
exploration shares such an allowance among its guesses: ``tests/gaits/test_exploration.py``)."""
from __future__ import annotations

import pytest

from nhgait.gaits.planner import prepare
from nhgait.gaits.planning.guesses import candidates
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import OCPSolver, SolverOptions
from nhgait.ocp.problem import ProblemError


@pytest.fixture(scope="module")
def parking():
    """The unicycle's parallel park at N = 10, interpreted (no compiler needed), and its guesses."""
    problem = prepare(resolve("unicycle", "parallel-park", overrides=["intervals=10"])).problem
    return OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False)), candidates(problem)


def test_a_solve_stops_after_its_iteration_limit_and_says_so(parking):
    ocp, guesses = parking
    full = ocp.solve(guesses[0])
    assert full.success
    assert full.iterations > 3
    capped = ocp.with_iteration_limit(3).solve(guesses[0])
    assert capped.status == "Maximum_Iterations_Exceeded"
    assert capped.iterations == 3
    assert not capped.success
    again = ocp.with_iteration_limit(None).solve(guesses[0])    # the limit belongs to the copy only
    assert again.success
    assert again.iterations == full.iterations
    assert again.objective == pytest.approx(full.objective, rel=1e-10)


@pytest.mark.parametrize("bad", [0, -3, 2.5, "10", True])
def test_an_iteration_limit_must_be_a_whole_number(bad):
    with pytest.raises(ProblemError, match="iteration_limit"):
        SolverOptions(iteration_limit=bad)
