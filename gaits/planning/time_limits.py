"""How much time a plan, a sweep point and a solver attempt get (the rules of docs/gait-planning.md,
"Time limits"); the budget itself and its defaults are :mod:`nhgait.ocp.budget`'s.

* :func:`budget_for` — a plan's or a sweep point's :class:`~nhgait.ocp.budget.Budget`: the
  seconds given (``--time-limit``, ``plan(time_limit=)``), else the task's ``time_limit``, else
  :func:`~nhgait.ocp.budget.default_plan_seconds` of the robot's coordinates, scaled by the
  machine's measured contention (:func:`contention`: a loaded machine gives each process a
  share of its cores, and the default must hold there too — issue 40); ``inf``: unlimited. A
  time given by the caller or the task is kept as given.
* :func:`attempt_limited` — a built solver with its default limit per attempt, from one measured
  evaluation of its NLP functions (:func:`~nhgait.ocp.budget.default_attempt_seconds`).
"""
from __future__ import annotations

import math
import os

__all__ = ["budget_for", "time_limit_problem", "attempt_limited", "contention", "GIVEN", "CONTENTION_CAP"]

#: how a budget given by the caller is named in the progress output and in failures
GIVEN = "--time-limit / plan(time_limit=...)"


def budget_for(n_coordinates: int, given=None, task_limit=None, *, given_as: str = GIVEN, started=None):
    """The budget (module docstring); :class:`~nhgait.ocp.ProblemError` for a time that is not
    a positive number of seconds."""
    from nhgait.ocp import ProblemError
    from nhgait.ocp.budget import PLAN_BASE_S, PLAN_PER_COORDINATE_S, Budget, default_plan_seconds
    if given is not None:
        seconds, source = given, given_as
    elif task_limit is not None:
        seconds, source = task_limit, "[task] time_limit"
    else:
        factor, load, cores = contention()
        seconds = default_plan_seconds(n_coordinates) * factor
        source = (f"default: {PLAN_BASE_S:g} s + {PLAN_PER_COORDINATE_S:g} s per coordinate, n = "
                  f"{n_coordinates}" + (f"; × {factor:.2g} for a busy machine (load average {load:.1f} "
                                        f"on {cores} cores)" if factor > 1 else ""))
    problem = time_limit_problem(seconds)
    if problem:
        raise ProblemError([problem], title="invalid time limit")
    seconds = float(seconds)
    return Budget(None if math.isinf(seconds) else seconds, source,
                  **({} if started is None else {"started": started}))


#: the default budget grows with the machine's contention up to this factor
CONTENTION_CAP = 4.0


def contention() -> tuple:
    """(factor, load, cores): how much longer work takes here than on idle cores, measured as
    the 1-minute load average over the cores (each runnable process gets about cores/load of
    one), at least 1 and at most :data:`CONTENTION_CAP`; 1 where the load average is unknown."""
    cores = os.cpu_count() or 1
    try:
        load = float(os.getloadavg()[0])
    except (OSError, AttributeError):            # not measured on this platform
        return 1.0, math.nan, cores
    return min(CONTENTION_CAP, max(1.0, load / cores)), load, cores


def time_limit_problem(seconds) -> str:
    """What keeps ``seconds`` from being a time limit ('' when nothing): a positive number
    (or a string of one, as TOML's ``"inf"``), not a bool; any size (``1e300``: in effect
    unlimited, :data:`~nhgait.ocp.budget.MAX_ALARM_S`)."""
    try:
        value = math.nan if isinstance(seconds, bool) else float(seconds)
    except (TypeError, ValueError):
        value = math.nan
    if value > 0:
        return ""
    return f"time_limit = {seconds!r} must be a positive number of seconds (inf: unlimited)"


def attempt_limited(ocp, guess=None, progress=None):
    """``ocp`` with its default time limit per attempt (:func:`~nhgait.ocp.budget.default_attempt_seconds`
    from one measured evaluation of its NLP functions at ``guess``, None: zero within the
    bounds), said on ``progress``."""
    from nhgait.ocp.budget import (
        ATTEMPT_CAP_S,
        ATTEMPT_FLOOR_S,
        EVALUATIONS_PER_ITERATION,
        default_attempt_seconds,
    )
    evaluation = ocp.evaluation_seconds(guess)
    limit = default_attempt_seconds(evaluation, ocp.options.max_iter)
    if progress is not None:
        progress.note(f"  each attempt at most {limit:.0f} s ({ocp.options.max_iter} iterations × "
                      f"{EVALUATIONS_PER_ITERATION:g} evaluations of the NLP functions, "
                      f"{evaluation * 1e3:.1f} ms each; "
                      f"between {ATTEMPT_FLOOR_S:g} and {ATTEMPT_CAP_S:g} s)")
    return ocp.with_time_limit(limit)
