"""A solution.json read as data (gaits/files/solution_file.py): a well-formed trajectory comes back
state-first (the file is time-first, as nhgait plan writes it: K+1 rows of n columns); every
problem of its form is one sentence of one ProblemError; a file that is not a plan's is a
ModelError naming it; another robot's plan is named as such."""
from __future__ import annotations

import json

import numpy as np
import pytest

from nhgait.dynamics.errors import ModelError
from nhgait.gaits.files.solution_file import previous_trajectory, read_solution, robot_problems
from nhgait.ocp import ProblemError


def _data(K=4):
    t = np.linspace(0.0, 2.0, K + 1)
    return {"system": "unicycle/parallel-park",
            "trajectory": {"t": t.tolist(), "q": np.column_stack([t, 2 * t]).tolist(),
                           "qdot": np.column_stack([np.ones(K + 1), 2 * np.ones(K + 1)]).tolist(),
                           "u": np.zeros((K, 1)).tolist(), "coordinates": ["x", "y"], "inputs": ["F"]}}


def test_a_trajectory_comes_back_state_first(tmp_path):
    path = tmp_path / "solution.json"
    path.write_text(json.dumps(_data()))
    previous = previous_trajectory(read_solution(path), "solution.json")
    assert previous.q.shape == (2, 5) and previous.u.shape == (1, 4)
    np.testing.assert_array_equal(previous.q[1], 2 * np.linspace(0.0, 2.0, 5))
    assert previous.coordinates == ("x", "y") and previous.system == "unicycle/parallel-park"
    assert robot_problems(previous, ("x", "y"), ("F",), "unicycle", "solution.json") == []
    other = robot_problems(previous, ("x", "y", "theta"), ("F",), "car", "solution.json")
    assert len(other) == 1 and "'unicycle/parallel-park'" in other[0] and "(x, y) are not" in other[0]


def test_every_problem_of_the_form_in_one_error():
    data = _data()
    tr = data["trajectory"]
    tr["t"][2] = tr["t"][1]                       # times not increasing
    tr["qdot"][0][0] = float("nan")               # not finite
    tr["u"] = tr["u"][:2]                         # u has K−2 rows
    with pytest.raises(ProblemError, match="invalid guess") as caught:
        previous_trajectory(data, "old.json")
    assert len(caught.value.problems) >= 3 and all("old.json" in p for p in caught.value.problems)
    with pytest.raises(ProblemError, match="no 'trajectory'"):
        previous_trajectory({}, "old.json")


def test_a_file_that_is_not_a_plans(tmp_path):
    (tmp_path / "a.json").write_text("{not json")
    (tmp_path / "b.json").write_text("[1, 2]")
    with pytest.raises(ModelError, match="is not JSON"):
        read_solution(tmp_path / "a.json")
    with pytest.raises(ModelError, match="holds a JSON list"):
        read_solution(tmp_path / "b.json")
