"""``[task.robust]`` (gaits/tasks/robust.py): the copies are the grid of the listed factors
without the nominal (2 × 2 factors: 3 copies, by hand), or K seeded draws uniform in each list's
[min, max] (numpy's generator with the same seed is the reference); the table reads back to
itself; every problem is named."""
from __future__ import annotations

import numpy as np

from nhgait.gaits.tasks.robust import MAX_COPIES, RobustTask, parse_robust


def test_the_grid_of_factors_without_the_nominal():
    spec = parse_robust({"robust": {"parameters": {"m": [1.0, 1.1], "J_r": [0.9, 1.0]}}}, "[task]", [])
    assert spec.factors() == [{"m": 1.0, "J_r": 0.9}, {"m": 1.1, "J_r": 0.9}, {"m": 1.1, "J_r": 1.0}]


def test_seeded_draws_in_the_ranges():
    problems = []
    spec = parse_robust({"robust": {"parameters": {"m": [0.8, 1.2], "J": [1.1, 0.9]}, "samples": 5, "seed": 3,
                                    "aggregate": "worst", "weight": 2.0, "terminal": ["x", "y"]}},
                        "[task]", problems)
    assert not problems and spec.aggregate == "worst" and spec.weight == 2.0 and spec.terminal == ("x", "y")
    draws = np.random.default_rng(3).uniform([0.8, 0.9], [1.2, 1.1], size=(5, 2))
    got = np.array([[f["m"], f["J"]] for f in spec.factors()])
    np.testing.assert_array_equal(got, draws)
    assert parse_robust({"robust": spec.to_dict()}, "[task]", problems) == spec and not problems


def test_every_problem_named():
    problems = []
    parse_robust({"robust": {"parameters": {"m": [0.9, 1.1]}, "samples": 0, "aggregate": "median",
                             "wieght": 1}}, "[task]", problems)
    said = "\n".join(problems)
    assert "unknown key(s) ['wieght']" in said and "did you mean 'weight'" in said
    assert "samples" in said and "median" in said
    assert parse_robust({"robust": 3}, "[task]", problems) is None and "must be a table" in problems[-1]
    many = {f"p{i}": [0.9, 1.1] for i in range(7)}                 # 2⁷ = 128 combinations
    parse_robust({"robust": {"parameters": many}}, "[task]", problems)
    assert f"more than {MAX_COPIES} copies" in problems[-1]
    assert parse_robust({}, "[task]", problems) is None and RobustTask().factors() == []
