"""A plan's time budget (gaits/planning/time_limits.py), by the rules of docs/gait-planning.md "Time
limits": the seconds given win over the task's, the task's over the default 120 s + 30 s per
coordinate (written out here as the page states it), scaled by the machine's contention factor;
``inf`` is unlimited; anything but a positive number is one ProblemError naming the value."""
from __future__ import annotations

import math

import pytest

from nhgait.gaits.planning.time_limits import GIVEN, budget_for, time_limit_problem
from nhgait.ocp import ProblemError


def test_given_then_task_then_the_default_rule(monkeypatch):
    import nhgait.gaits.planning.time_limits as time_limits
    monkeypatch.setattr(time_limits, "contention", lambda: (1.0, 0.5, 2))        # a quiet machine
    b = budget_for(5, given=60, task_limit=300)
    assert (b.seconds, b.source) == (60.0, GIVEN)
    b = budget_for(5, task_limit="300")
    assert (b.seconds, b.source) == (300.0, "[task] time_limit")
    b = budget_for(5)
    assert b.seconds == pytest.approx(120.0 + 30.0 * 5) and "per coordinate" in b.source
    monkeypatch.setattr(time_limits, "contention", lambda: (4.0, 8.0, 2))        # a busy one: × 4
    b = budget_for(5)
    assert b.seconds == pytest.approx(4 * (120.0 + 30.0 * 5))
    assert "busy machine (load average 8.0" in b.source
    assert budget_for(5, given=math.inf).seconds is None and not budget_for(5, given="inf").limited
    assert budget_for(3, given=10, started=100.0).started == 100.0


@pytest.mark.parametrize("bad", [0, -1, "soon", True, None, math.nan])
def test_a_time_that_is_not_a_positive_number_is_refused(bad):
    assert "must be a positive number of seconds" in time_limit_problem(bad)
    if bad is not None:
        with pytest.raises(ProblemError, match="invalid time limit"):
            budget_for(4, given=bad)
    assert time_limit_problem(1e300) == ""
