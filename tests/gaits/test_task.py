"""A task is data: the [task] table, its validation (every problem in one error), --set
overrides parsed as data, the built-in library in the same format. No solving here."""
from __future__ import annotations

import math

import pytest

from nhgait.gaits.tasks.sources import get_task, library_task_names, resolve
from nhgait.gaits.tasks.statement import Task, apply_overrides, parse_task
from nhgait.ocp import ProblemError

P2 = {"horizon": "2*pi", "intervals": 50,
      "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "psi": 0.0, "forward_velocity": 0.0},
      "final": {"x": 1.0, "theta": 0.0, "forward_velocity": 0.0},
      "periodic": ["psi", "phi", "psi_dot", "phi_dot"], "bounds": {"phi": [-1.0, 1.0]},
      "control_bounds": 10.0, "objective": "effort"}


def test_builtin_tasks_are_library_data():
    assert {("snakeboard", "forward"), ("snakeboard", "rotate"), ("snakeboard", "lateral"),
            ("unicycle", "parallel-park")} <= set(library_task_names())
    rotate = get_task("snakeboard", "rotate")
    assert rotate.final["theta"] == pytest.approx(math.pi / 2, abs=1e-15)    # "pi/2" parsed as data
    assert rotate.horizon == pytest.approx(2 * math.pi, abs=1e-15)
    assert rotate.periodic == ("psi", "phi", "psi_dot", "phi_dot")
    assert rotate.control_bounds == 10.0
    assert rotate.bounds["phi"] == (-1.0, 1.0)
    with pytest.raises(ProblemError, match=r"unknown gait 'moonwalk'.*snakeboard forward"):
        get_task("snakeboard", "moonwalk")


def test_task_table_round_trip():
    import pickle
    task = parse_task(P2)
    again = parse_task(task.to_dict())
    assert again == task
    assert pickle.loads(pickle.dumps(task)) == task          # tasks travel to worker processes
    with pytest.raises((TypeError, AttributeError)):
        task.final["x"] = 2.0
    free = parse_task({**P2, "horizon": [2.0, 8.0], "objective": {"effort": 1.0, "time": 0.1}})
    assert free.horizon_bounds == (2.0, 8.0)
    assert free.horizon == 5.0
    assert parse_task(free.to_dict()) == free


def test_every_problem_is_listed_at_once():
    bad = {"horizon": -1.0, "intervals": 0, "initial": {"phi": 3.0}, "final": {"theta": "pi/0"},
           "bounds": {"phi": [1.0, -1.0], "psi": 2.0}, "periodic": "psi", "objective": "fast",
           "colour": "red"}
    with pytest.raises(ProblemError) as info:
        parse_task(bad)
    text = str(info.value)
    for fragment in ("unknown key(s) ['colour']", "horizon = -1.0 must be positive", "intervals = 0",
                     "final.theta", "contradictory range, lower bound 1 > upper bound -1",
                     "bounds.psi: a path bound is a range", "periodic must be a list of names",
                     "objective = 'fast'"):
        assert fragment in text, fragment
    assert len(info.value.problems) >= 8


def test_a_bound_that_is_not_a_range_is_one_problem():
    """``--set bounds.theta=1``: the bound is refused once; it was also taken as [1, 1] and every
    end value of theta reported outside it (a user's trial, 2026-11-29)."""
    with pytest.raises(ProblemError) as info:
        parse_task({**P2, "bounds": {"theta": 1.0}})           # theta(0) = theta(T) = 0
    assert list(info.value.problems) == ["[task].bounds.theta: a path bound is a range [lo, hi], got 1.0"]


def test_contradictions_and_time_objective():
    with pytest.raises(ProblemError, match=r"initial.phi = 3.0 lies outside bounds.phi"):
        parse_task({**P2, "initial": {**P2["initial"], "phi": 3.0}})
    with pytest.raises(ProblemError, match=r"psi is periodic but initial 0.0 and final 1.0 cannot be equal"):
        parse_task({**P2, "final": {**P2["final"], "psi": 1.0}})
    with pytest.raises(ProblemError, match=r"time objective needs a free horizon"):
        parse_task({**P2, "objective": "time"})


def test_values_are_data_never_code():
    with pytest.raises(ProblemError, match=r"final.x"):
        parse_task(apply_overrides(P2, ["final.x=__import__('os').getcwd()"]))
    with pytest.raises(ProblemError, match=r"final.x"):
        parse_task({**P2, "final": {"x": "x_dot + 1"}})       # a name, not a number


def test_set_overrides():
    data = apply_overrides(P2, ["final.x=2.0", "horizon=pi", "bounds.phi=-0.5,0.5", "periodic=psi,phi",
                                "intervals=30", "objective=effort"])
    task = parse_task(data)
    assert task.final["x"] == 2.0
    assert task.horizon == pytest.approx(math.pi)
    assert task.bounds["phi"] == (-0.5, 0.5)
    assert task.periodic == ("psi", "phi")
    assert task.intervals == 30
    assert P2["final"]["x"] == 1.0                          # the original table is untouched
    with pytest.raises(ProblemError, match=r"(?s)expected key=value.*unknown key 'colour'"):
        apply_overrides(P2, ["final.x", "colour=red"])


def test_resolve_names_the_missing_task(tmp_path):
    scene = tmp_path / "robot.toml"
    scene.write_text('[system]\ncoordinates = ["x"]\nlagrangian = "m*x_dot**2/2"\ninputs = ["F"]\n'
                     '[system.forces]\nx = "F"\n[system.parameters]\nm = 1.0\n')
    with pytest.raises(ProblemError, match=r"robot.toml has no \[task\] table"):
        resolve(str(scene))
    to_plan = resolve(str(scene), {"horizon": 1.0, "final": {"x": 1.0}})
    assert isinstance(to_plan.task, Task)
    assert to_plan.label == "robot/task"


def test_a_task_is_the_problem_statement_in_the_tables_words():
    """The task parses into the ocp statement (no model yet); one validator speaks to both readers."""
    from dataclasses import replace

    from nhgait.gaits.tasks.statement import TASK_WORDS
    from nhgait.ocp import ProblemStatement
    task = parse_task(P2)
    assert isinstance(task.statement, ProblemStatement)
    assert task.statement.model is None
    assert task.bounds == {"phi": (-1.0, 1.0)}
    assert task.statement.state_bounds == task.bounds
    assert task.statement.time_weight == 0.0
    assert task.horizon_bounds is None
    assert task.replace(intervals=30, bounds={"phi": (-0.5, 0.5)}).to_dict() == {
        **task.to_dict(), "intervals": 30, "bounds": {"phi": [-0.5, 0.5]}}
    bad = replace(task.statement, state_bounds={"phi": (1.0, -1.0)})
    assert bad.problems() == ["state_bounds['phi']: contradictory bounds lo = 1 > hi = -1"]
    assert bad.problems(TASK_WORDS) == ["[task].bounds.phi: contradictory range, lower bound 1 > "
                                        "upper bound -1"]
