"""The planner's exploration after its first success (``gaits/planning/search.py``, issues 24 and 25): an
allowance of iterations shared in order — the same guesses on slow code and on fast — and a
first success kept beside the winner (the planner's fallback when the winner fails its check)."""
from __future__ import annotations

import pytest

import nhgait.gaits.planning.search as search
from nhgait.gaits.planner import prepare
from nhgait.gaits.planning.guesses import candidates
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import OCPSolver, SolverOptions


@pytest.fixture(scope="module")
def parking():
    """The unicycle's parallel park at N = 10, interpreted (no compiler needed), and its guesses."""
    problem = prepare(resolve("unicycle", "parallel-park", overrides=["intervals=10"])).problem
    return OCPSolver(problem, options=SolverOptions(max_iter=500, jit=False)), candidates(problem)


def test_the_exploration_shares_an_iteration_allowance_in_order(parking, monkeypatch):
    """With an allowance of half the first success's iterations the next guess is stopped at
    exactly that many, and nothing after it runs: the window is spent."""
    ocp, guesses = parking
    first = ocp.solve(guesses[0])
    monkeypatch.setattr(search, "EXPLORE_MIN_ITERATIONS", 1)
    monkeypatch.setattr(search, "EXPLORE_ITERATION_RATIO", 0.5)
    allowance = -(-first.iterations // 2)
    found = search.solve_from_guesses(ocp, guesses, limit=4, explore=True)
    assert found.won == guesses[0].label
    explored = found.attempts[1:]
    assert [(a.status, a.iterations) for a in explored] == [("Maximum_Iterations_Exceeded", allowance)]


def test_the_exploration_keeps_the_first_success_beside_the_winner(parking, monkeypatch):
    """Every later success counts as lower here (EXPLORE_GAIN < 0): the last one explored wins,
    and the first converged solution stays in the search (``first``) — the planner falls back to
    it when the winner fails its verification."""
    ocp, guesses = parking
    monkeypatch.setattr(search, "EXPLORE_GAIN", -1.0)
    found = search.solve_from_guesses(ocp, guesses, limit=4, explore=True)
    successes = [a.label for a in found.attempts if a.success]
    assert len(successes) >= 2
    assert found.won == successes[-1]
    assert found.first_won == successes[0] == guesses[0].label
    assert found.first.objective == pytest.approx(found.attempts[0].objective, rel=1e-12)
    alone = search.solve_from_guesses(ocp, guesses, limit=4, explore=False)
    assert alone.first is None
