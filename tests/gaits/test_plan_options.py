"""PlanOptions: the plan's options written once, checked once (issue 44 item 1)."""
from __future__ import annotations

import math

import pytest

from nhgait.gaits.planning.options import PlanOptions
from nhgait.ocp import ProblemError


def test_defaults_are_the_planners_documented_ones():
    o = PlanOptions()
    assert (o.intervals, o.solver, o.transcription, o.jit, o.workers, o.max_iter, o.hessian,
            o.max_guesses, o.verify, o.time_limit) == (None, "auto", None, None, 1, 500, "auto", 12,
                                                       True, None)
    assert o.summary() == "defaults"


def test_values_fold_over_an_options_value_or_a_mapping_and_the_original_is_unchanged():
    base = PlanOptions.of(intervals=40, solver="ipopt")
    later = PlanOptions.of(base, verify=False)
    assert (later.intervals, later.solver, later.verify) == (40, "ipopt", False)
    assert base.verify is True
    assert PlanOptions.of({"max_iter": 30}).max_iter == 30
    assert later.changed() == {"intervals": 40, "solver": "ipopt", "verify": False}
    assert later.summary() == "intervals=40, solver='ipopt', verify=False"


def test_every_problem_is_named_in_one_error():
    with pytest.raises(ProblemError) as caught:
        PlanOptions.of(intervals=3.5, solver="snopt", workers="many", max_iter=0, jit="yes",
                       time_limit=-1.0, hessian="bfgs")
    text = str(caught.value)
    for fragment in ("intervals = 3.5 must be a whole number", "solver = 'snopt': use one of",
                     "workers = 'many' must be a whole number ≥ 1 or 'auto'", "max_iter = 0 must be",
                     "jit = 'yes' must be True or False or None", "hessian = 'bfgs'", "time_limit"):
        assert fragment in text, fragment
    assert text.count("\n  - ") == 7


def test_an_unknown_name_gets_its_close_match_and_a_bool_is_not_a_count():
    with pytest.raises(ProblemError, match=r"unknown option 'max_iters': did you mean 'max_iter'"):
        PlanOptions.of(max_iters=10)
    with pytest.raises(ProblemError, match="max_guesses = True must be a whole number"):
        PlanOptions.of(max_guesses=True)
    with pytest.raises(ProblemError, match="no limited-memory Hessian"):
        PlanOptions.of(solver="fatrop", hessian="limited-memory")


def test_unlimited_time_and_automatic_workers_are_accepted():
    o = PlanOptions.of(time_limit=math.inf, workers="auto", jit=False)
    assert o.problems() == []
