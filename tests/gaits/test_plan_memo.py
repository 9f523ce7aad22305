"""The planner's memo in a long-lived process (:mod:`nhgait.gaits.planning.plan_memo`, issue 40).

Behaviour, not time: a second plan of one structure builds no solver (counted by the memo); a
repeated plan starts from the last optimum and reaches the cold plan's optimum; a plan with a
changed final value reuses the solver and still reaches the new end state (checked against the
task's own value). The unicycle's parallel park (a small robot) keeps the tests fast.
"""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.gaits.planner import plan
from nhgait.gaits.planning.plan_memo import LAST_OPTIMUM, PlanMemo, structure_key, task_key

pytestmark = pytest.mark.usefixtures("_temporary_cache")

TASK = dict(system="unicycle", task="parallel-park")
OPTIONS = dict(intervals=30, verify=False, workers=1)
#: the solver's tolerance (tol 1e-8 on a scaled objective) allows this much between two optima
OBJECTIVE_TOLERANCE = 1e-6


def _plan(memo, **extra):
    return plan(TASK["system"], TASK["task"], memo=memo, **OPTIONS, **extra)


@pytest.fixture(scope="module")
def cold():
    return _plan(False)


def test_second_plan_reuses_the_solver_and_the_optimum(cold):
    memo = PlanMemo()
    first = _plan(memo)
    assert (memo.builds, memo.reuses) == (1, 0)
    second = _plan(memo)
    assert (memo.builds, memo.reuses) == (1, 1)           # no solver built the second time
    assert second.guess == LAST_OPTIMUM and len(second.attempts) == 1    # no exploration again
    for result in (first, second):
        assert result.solution.success
        assert abs(result.solution.objective - cold.solution.objective) <= OBJECTIVE_TOLERANCE * max(
            1.0, abs(cold.solution.objective))
    np.testing.assert_allclose(second.solution.z[-1], cold.solution.z[-1], atol=1e-6)
    # every repetition starts at the same optimum: the same solution, bit for bit, whose
    # feedback is then not computed again
    third = _plan(memo)
    np.testing.assert_array_equal(third.solution.z, second.solution.z)
    assert third.solution.feedback is second.solution.feedback


def test_changed_final_value_reuses_the_solver_and_reaches_it():
    memo = PlanMemo()
    _plan(memo)
    moved = _plan(memo, overrides=["final.y=0.6"])
    assert (memo.builds, memo.reuses) == (1, 1)
    assert moved.solution.success
    y = moved.solution.state_names.index("y")
    assert moved.solution.z[-1, y] == pytest.approx(0.6, abs=1e-6)     # the task's new end value
    assert moved.guess != LAST_OPTIMUM                  # another task: no other task's optimum


def test_no_memo_builds_every_time():
    memo = PlanMemo()
    _plan(False)
    assert memo.builds == 0 and len(memo.solvers) == 0


def test_memo_is_bounded_and_clearable():
    memo = PlanMemo(solvers=1, optima=1)
    memo.solver("a", lambda: "A")
    memo.solver("b", lambda: "B")
    assert len(memo.solvers) == 1 and memo.builds == 2
    memo.clear()
    assert len(memo.solvers) == 0 and memo.builds == 0


def test_keys_without_a_cached_model_are_none():
    assert task_key(None, object()) is None

    class Bare:
        provenance = None
    prepared = type("P", (), {"model": Bare(), "specialised": None})()
    assert structure_key(prepared, None, None, None, "") is None


def test_a_new_process_starts_from_the_last_verified_optimum(cold, monkeypatch, tmp_path):
    monkeypatch.setenv("NHGAIT_WARM_OPTIMA", "1")
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path))     # its own cache: nothing stored before
    options = {**OPTIONS, "verify": True}
    first = plan(TASK["system"], TASK["task"], memo=PlanMemo(), **options)     # a process
    again = plan(TASK["system"], TASK["task"], memo=PlanMemo(), **options)     # the next one
    assert first.success and again.success
    assert first.guess != LAST_OPTIMUM and again.guess == LAST_OPTIMUM
    assert len(again.attempts) == 1
    assert again.solution.objective == pytest.approx(cold.solution.objective, rel=OBJECTIVE_TOLERANCE)


def test_a_warm_start_solved_in_this_process_is_the_supervised_solve(monkeypatch):
    """A warm start whose iterations are cheap runs in this process (no supervised attempt:
    counted) and gives the supervised solve's answer; a costly one stays supervised."""
    import nhgait.gaits.planning.search as search
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.planning.guesses import candidates
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.ocp import InitialGuess, OCPSolver, SolverOptions
    problem = prepare(resolve("unicycle", "parallel-park", overrides=["intervals=10"])).problem
    ocp = OCPSolver(problem, options=SolverOptions(max_iter=500, jit=True, solver="ipopt"))
    if not ocp.compiled:
        pytest.skip(f"no compiled NLP functions here ({ocp.jit_fallback})")
    optimum = search.solve_from_guesses(ocp, candidates(problem), limit=3).solution
    assert optimum.success
    start = InitialGuess(optimum.z.T, optimum.u.T, optimum.horizon, LAST_OPTIMUM)
    supervised = search.solve_from_guesses(ocp, [start]).solution
    calls = []
    real = search.solve_attempts
    monkeypatch.setattr(search, "solve_attempts", lambda *a, **k: calls.append(1) or real(*a, **k))
    here = search.solve_from_guesses(ocp, [start], in_process=1e-6).solution
    assert calls == [] and here.success
    np.testing.assert_array_equal(here.z, supervised.z)
    assert here.iterations == supervised.iterations
    costly = search.solve_from_guesses(ocp, [start], in_process=1.0).solution     # 50 × 1 s: not here
    assert calls == [1] and costly.success


def test_a_memo_serves_one_thread():
    import threading
    memo = PlanMemo()
    assert memo.serves_this_thread()
    seen = []
    worker = threading.Thread(target=lambda: seen.append(memo.serves_this_thread()))
    worker.start()
    worker.join()
    assert seen == [False] and memo.serves_this_thread()


def test_a_kept_solver_talks_on_each_plans_own_stream():
    """A solver built under one plan's progress says nothing there during a later quiet plan;
    the later plan's own stream says what was reused."""
    import io

    from nhgait.dynamics.progress import Progress
    memo, first, later = PlanMemo(), io.StringIO(), io.StringIO()
    options = {**OPTIONS, "solver": "ipopt"}            # Ipopt: the iteration callback talks too
    plan(TASK["system"], TASK["task"], memo=memo, progress=Progress(first, interval=0.0), **options)
    said = first.getvalue()
    plan(TASK["system"], TASK["task"], memo=memo, **options)
    assert first.getvalue() == said
    plan(TASK["system"], TASK["task"], memo=memo, progress=Progress(later), **options)
    assert "built before in this process: reused" in later.getvalue()
    assert "explored before: no exploration" in later.getvalue()


def test_a_last_optimum_that_fails_gives_way_to_the_planners_guesses(cold):
    """An optimum kept for the task that no longer converges (here: not finite, refused before
    any solve) is followed by the planner's own guesses and exploration: the cold optimum."""
    import io

    from nhgait.dynamics.progress import Progress
    from nhgait.gaits.planning.plan_memo import Optimum
    from nhgait.ocp import InitialGuess
    memo = PlanMemo()
    _plan(memo)
    (key,) = list(memo.optima._entries)         # the one task planned
    good = memo.optimum(key)
    broken = InitialGuess(np.full_like(good.guess.states, np.nan), good.guess.controls, good.guess.horizon,
                          LAST_OPTIMUM)
    memo.remember(key, Optimum(broken, good.objective, True))
    said = io.StringIO()
    again = _plan(memo, progress=Progress(said))
    assert "did not converge again: the planner's own guesses" in said.getvalue()
    assert again.success and again.guess != LAST_OPTIMUM
    assert again.attempts[0].label == LAST_OPTIMUM and not again.attempts[0].success
    assert again.solution.objective == pytest.approx(cold.solution.objective, rel=OBJECTIVE_TOLERANCE)


def test_memo_hands_out_named_kept_values_and_says_when_reused():
    memo = PlanMemo()
    first, again = memo.solver("a", lambda: "A"), memo.solver("a", lambda: "not built")
    assert (first.value, first.reused, again.value, again.reused) == ("A", False, "A", True)
    assert (memo.builds, memo.reuses) == (1, 1)
    assert memo.prepare(None, lambda: 1).reused is False and memo.prepare(None, lambda: 2).value == 2
    assert memo.of_solution("s", lambda: 3).reused is False and memo.of_solution("s", lambda: 4) == (3, True)
