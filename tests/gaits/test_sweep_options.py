"""One options value per job (issue 44): a sweep's :class:`SweepOptions` and a tracking study's
:class:`TrackingOptions` gather the keywords once, take the planner's shared
:class:`PlanOptions`, and list every problem in one error before any derivation. No planning
here: the checks and the folding are what is tested (the sweep and the study themselves are
tests/gaits/test_sweep*.py and test_tracking.py)."""
from __future__ import annotations

import doctest

import pytest

from nhgait.gaits.planning.options import PlanOptions
from nhgait.gaits.sweeps.options import PLAN_OPTIONS, SweepOptions
from nhgait.gaits.tracking.request import TrackingOptions
from nhgait.gaits.tracking.runs import Noise
from nhgait.ocp import ProblemError


def test_the_module_examples_run():
    import nhgait.gaits.sweeps.options as module
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in doctest.DocTestFinder().find(module):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.attempted >= 3 and result.failed == 0


def test_keywords_fold_into_the_options_and_override_a_given_value():
    base = SweepOptions(workers=2, resume=True, overrides=("intervals=30",))
    made = SweepOptions.of(base, workers=0)
    assert (made.workers, made.resume, made.overrides) == (0, True, ("intervals=30",))
    assert base.workers == 2                                  # a new value; the given one is unchanged


def test_a_mapping_given_as_options_is_the_planner_options_as_before():
    """``sweep(..., options={"jit": False})`` (the form before SweepOptions) still means the
    planner options of every point; a PlanOptions there means the same."""
    assert SweepOptions.of({"jit": False, "time_limit": 30}).planner() == {"jit": False, "time_limit": 30}
    assert SweepOptions.of(PlanOptions(jit=False, time_limit=30.0)).planner() == {"jit": False,
                                                                                  "time_limit": 30.0}
    assert SweepOptions.of().planner() == {}


def test_a_plan_option_a_point_does_not_take_is_named_with_the_others():
    _, problems = SweepOptions.collect(plan=PlanOptions(intervals=40, max_guesses=3, solver="auto"),
                                       workers=-1, chain=0, resume="yes")
    text = "\n".join(problems)
    assert "options: intervals = 40: a sweep point is one solve" in text
    assert "options: max_guesses = 3: a sweep point is one solve" in text
    assert "--workers must be ≥ 0" in text
    assert "chain must be a whole number ≥ 1" in text
    assert "resume = 'yes' must be True or False" in text
    assert len(problems) == 5
    assert all(name in text for name in PLAN_OPTIONS)          # what a point takes, said


def test_an_unknown_sweep_option_suggests_the_close_name():
    with pytest.raises(ProblemError, match="unknown option 'warmstart': did you mean 'warm_start'"):
        SweepOptions.of(warmstart=False)


def test_a_bad_sweep_request_is_refused_before_the_derivation_and_the_folder(tmp_path, monkeypatch):
    from nhgait.gaits.sweeps import point
    from nhgait.gaits.sweeps.driver import sweep

    def described(*args, **kwargs):
        raise AssertionError("derived before the request was checked")
    monkeypatch.setattr(point, "describe_case", described)
    how = SweepOptions(plan=PlanOptions(jit="no", solver="fatrop"), workers=0)
    with pytest.raises(ProblemError) as bad:
        sweep("unicycle", "parallel-park", ["final.y=0.3:0.5:2"], out=tmp_path / "s", options=how)
    assert "invalid sweep: 1 problem(s)" in str(bad.value)
    assert "options: jit = 'no' must be True or False or None" in str(bad.value)
    assert not (tmp_path / "s").exists()


def test_a_tracking_study_takes_the_plan_options_and_the_former_time_limit_keyword():
    """``track(time_limit=60)`` (the keyword before TrackingOptions) goes into the shared
    PlanOptions, as does any plan option by its name; ``workers`` stays the samples'."""
    made, problems = TrackingOptions.collect(time_limit=60, intervals=40, workers=3, samples=5)
    assert problems == []
    assert (made.plan.time_limit, made.plan.intervals, made.plan.workers) == (60, 40, 1)
    assert (made.workers, made.samples) == (3, 5)
    again, _ = TrackingOptions.collect(made, plan={"solver": "ipopt"}, seed=4)
    assert (again.plan.solver, again.plan.time_limit, again.seed, again.samples) == ("ipopt", None, 4, 5)


def test_an_unknown_tracking_option_names_the_close_match():
    made, problems = TrackingOptions.collect(sample=5)
    assert made is None
    assert problems == [problems[0]] and "did you mean 'samples'" in problems[0]


def test_a_bad_time_limit_of_a_study_is_said_once_with_every_other_problem():
    from nhgait.gaits.tracking.study import track
    with pytest.raises(ProblemError) as bad:
        track("unicycle", "parallel-park", time_limit=-1.0, samples=0, noise=Noise(-0.1, 0.05),
              mismatch=["params.m=2"])
    text = str(bad.value)
    assert text.count("time_limit") + text.count("--time-limit") >= 1
    assert "3 problem(s)" in text          # the time limit once, the samples, the noise
    assert "--samples must be an integer ≥ 1, got 0" in text
    assert "--state-noise must be a finite number ≥ 0, got -0.1" in text
