"""The minimum-violation (elastic) solve and the stall of a search (gaits/planning/infeasibility.py, issue 41)
on a task whose least move is known in closed form.

The robot: tests/scenes/unstable_line.toml with k = 0, a double integrator x'' = F beside a free
cart. The task: from rest, x = 3 m in T = 2 s with |ẋ| ≤ 1 m/s at the nodes (N = 20, h = 0.1 s)
and |F| ≤ 1000 N. Inputs are held on each interval, so ẋ is linear between nodes and the fastest
motion reaches ẋ = v in the first interval and keeps it: x(T) = v (T − h/2) = 1.95 v. Each move
is measured relative to the value stated: moving the target by a costs a/3 (1/3 per metre
gained), widening the speed bound by b costs b (1/1.95 per metre gained) — the least total move
is a = 3 − 1.95 = 1.05 m, b = 0, the start (at rest, as stated) untouched; the speed bound alone
must widen by 3/1.95 − 1 = 0.538461…
"""
from __future__ import annotations

from pathlib import Path

import pytest

from nhgait.gaits.figures.convergence import plot_convergence, write_convergence_figure
from nhgait.gaits.planner import plan, prepare
from nhgait.gaits.planning.infeasibility import Elastic, elastic_solve, stalled
from nhgait.gaits.planning.search import Attempt
from nhgait.gaits.tasks.sources import resolve

SCENE = str(Path(__file__).resolve().parents[1] / "scenes" / "unstable_line.toml")
T, N, TARGET = 2.0, 20, 3.0
TASK = {"horizon": T, "intervals": N, "initial": {"s": 0.0, "s_dot": 0.0, "x": 0.0, "x_dot": 0.0},
        "final": {"x": TARGET}, "bounds": {"x_dot": [-1.0, 1.0]}, "control_bounds": 1000.0,
        "objective": "effort"}
REACH = T - T / N / 2                            # 1.95 m at |ẋ| ≤ 1
LEAST = TARGET - REACH                           # 1.05 m: the target moves
ALONE = TARGET / REACH - 1.0                     # 0.538461…: the speed bound alone


def test_the_elastic_solve_moves_the_cheapest_condition_by_the_closed_form_amount():
    prepared = prepare(resolve(SCENE, TASK), params={"k": 0.0})
    elastic = elastic_solve(prepared.stated, tolerance=1e-6)
    assert isinstance(elastic, Elastic) and elastic.converged and not elastic.feasible
    moved = {m.label: m for m in elastic.moved}
    assert set(moved) == {"final.x"}
    assert moved["final.x"].by == pytest.approx(LEAST, abs=1e-6)
    assert moved["final.x"].reached == pytest.approx(REACH, abs=1e-6)
    assert elastic.total == pytest.approx(LEAST, abs=1e-6) and not elastic.start_moved
    alone = dict(elastic.alone)
    assert alone["final.x"].by == pytest.approx(LEAST, abs=1e-6)
    assert alone["bounds.x_dot"].by == pytest.approx(ALONE, abs=1e-6)
    assert elastic.lines()[0].startswith("possibly infeasible")


def test_a_feasible_task_needs_no_move():
    task = {**TASK, "final": {"x": 1.5}}
    prepared = prepare(resolve(SCENE, task), params={"k": 0.0})
    elastic = elastic_solve(prepared.stated, tolerance=1e-6)
    assert elastic.feasible and elastic.total <= 1e-6
    assert "a gait exists" in elastic.lines()[0]


@pytest.fixture(scope="module")
def stalling():
    return plan(SCENE, TASK, jit=False, params={"k": 0.0})


def test_a_plan_that_stalls_stops_and_says_what_must_move(stalling):
    result = stalling
    assert not result.success
    ipopt = [a for a in result.attempts if a.solver == "ipopt"]
    assert len(ipopt) == 3 and stalled(ipopt)                 # stopped at the third, not twelve
    text = "\n".join(result.diagnosis)
    assert "possibly infeasible" in text and "final.x = 3: move by 1.05" in text
    assert "bounds.x_dot in [-1, 1]: widen by 0.5385" in text
    assert "initial." not in text                             # the start as the user gave it
    data = result.solution.to_dict()["settings"]["elastic"]
    assert data["moves"][0]["condition"] == "final.x"
    assert data["moves"][0]["by"] == pytest.approx(LEAST, abs=1e-6)


def _attempt(status, violation, success=False):
    return Attempt(label="g", status=status, success=success, iterations=10, objective=1.0, solver="ipopt",
                   constraint_violation=violation)


def test_stalled_needs_the_same_infeasible_point_three_times():
    same = [_attempt("Infeasible_Problem_Detected", v) for v in (0.0564, 0.0569, 0.0549)]
    assert stalled(same)
    assert not stalled(same[:2])                                          # too few
    assert not stalled(same[:2] + [_attempt("Infeasible_Problem_Detected", 0.08)])   # another point
    assert not stalled(same[:2] + [_attempt("Maximum_Iterations_Exceeded", 0.056)])  # not infeasible
    assert not stalled(same[:2] + [_attempt("Solve_Succeeded", 0.0, True)])


def test_stalled_sees_two_kinds_of_guesses_stop_at_two_points():
    """Shape loops and roll-outs interleaved, each kind at its own infeasible point (a snakeboard
    under tight torque bounds): the third at one point within the last five stops the search,
    an attempt that is not infeasible among them does not."""
    loop, rollout = "Infeasible_Problem_Detected", "Infeasible_Problem_Detected"
    mixed = [_attempt(loop, 0.100), _attempt(rollout, 0.180), _attempt(loop, 0.110), _attempt(rollout, 0.182)]
    assert not stalled(mixed)                                            # two at each point
    assert stalled(mixed + [_attempt(rollout, 0.179)])                   # the third at 0.18
    assert not stalled(mixed + [_attempt("Maximum_Iterations_Exceeded", 0.179)])
    assert not stalled([_attempt("Solve_Succeeded", 0.0, True)] + mixed[1:] + [_attempt(rollout, 0.2)])


def test_the_convergence_figure_draws_each_attempt(stalling, tmp_path):
    attempts = stalling.attempts
    top, bottom = plot_convergence(attempts)
    assert len(bottom.get_lines()) == len(attempts) == len(top.get_lines())
    for a, line in zip(attempts, bottom.get_lines(), strict=True):
        if a.solver == "ipopt":        # every iterate (restoration's too); an infeasible one levels off
            assert len(line.get_ydata()) > a.iterations
            assert line.get_ydata()[-1] > 1e-3
        else:                          # FATROP keeps no history: its final point
            assert len(line.get_ydata()) == 1
    path = write_convergence_figure(attempts, tmp_path / "convergence.png", title="unstable_line")
    assert path.stat().st_size > 10_000
