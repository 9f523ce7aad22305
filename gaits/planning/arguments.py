""":func:`~nhgait.gaits.planner.plan`'s own arguments, checked before any work.

The command line's types (``--intervals`` an int, ``--workers`` a number ≥ 1 or ``auto`` …) hold
for it; a Python caller gets the same checks here, every problem in one
:class:`~nhgait.ocp.ProblemError` — with the output folder's and the scene's and task's
(:func:`~nhgait.gaits.tasks.sources.resolve`) — instead of a value silently truncated
(``intervals=3.5``), taken for a number (``intervals=True``), or an error deep inside
(``workers="many"``, ``max_iter=-1`` in Ipopt's option dump).

* :func:`checked_request` — (the resolved plan, the output folder, the options) or one ProblemError;
* :func:`argument_problems` — the problems of the arguments alone (the options' are
  :class:`~.plan_options.PlanOptions`'s own);
* :func:`override_list` — ``overrides`` as a list: a single string is one override;
* :func:`check_params` — the parameter values themselves (names, numbers, a positive definite
  kinetic metric), once the scene is known.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

from .options import PlanOptions, whole_number

__all__ = ["checked_request", "argument_problems", "override_list", "check_params", "PlanRequest"]

#: ``plan``'s own arguments; the other keywords are its options (:class:`~.plan_options.PlanOptions`)
OWN = ("overrides", "params", "out_dir", "animate", "progress", "options", "values")


class PlanRequest(NamedTuple):
    """What :func:`checked_request` returns."""

    plan: Any                       #: the :class:`~nhgait.gaits.tasks.sources.Plan`
    out_dir: Any                    #: the output folder (a Path) or None
    options: PlanOptions            #: how the plan is solved


def checked_request(system, task, arguments: dict) -> PlanRequest:
    """The plan, the output folder and the options of ``plan``'s keyword ``arguments``
    (:func:`argument_problems`' names); one ProblemError listing every problem of the arguments,
    the options, the output folder, the scene and the task."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.ocp import ProblemError

    from ..files.outputs import output_directory
    from ..tasks.sources import resolve
    values = {**(arguments.get("values") or {}), **{k: v for k, v in arguments.items() if k not in OWN}}
    problems = argument_problems(**{k: v for k, v in arguments.items() if k in OWN and k != "values"},
                                 **values)
    options = PlanOptions.collect(arguments.get("options"), **values).options
    out_dir, to_plan, caught = arguments.get("out_dir"), None, []
    try:
        if out_dir is not None:            # before any derivation (a bad location: exit 2)
            out_dir = output_directory(out_dir, "out_dir")
    except ModelError as exc:
        caught.append(exc)
    intervals = options.intervals if options is not None else None
    overrides = override_list(arguments.get("overrides", ()), intervals)
    try:
        if overrides is not None:          # else their type is among the problems
            to_plan = resolve(system, task, overrides=overrides)
    except ModelError as exc:
        caught.append(exc)
    if caught and not problems and len(caught) == 1:
        raise caught[0]
    problems += [p for exc in caught for p in exc.problems]
    if problems:
        raise ProblemError(problems, title="invalid plan request")
    return PlanRequest(to_plan, out_dir, options)


def override_list(overrides, intervals=None) -> list | None:
    """``overrides`` as a list of ``key=value`` strings (a single string is one override, None
    none), ``intervals=N`` appended when ``intervals`` is a whole number; None when
    ``overrides`` is not a string or a sequence of strings."""
    if overrides is None:
        overrides = []
    elif isinstance(overrides, str):
        overrides = [overrides]
    elif isinstance(overrides, (list, tuple)) and all(isinstance(o, str) for o in overrides):
        overrides = list(overrides)
    else:
        return None
    if whole_number(intervals):
        overrides.append(f"intervals={int(intervals)}")
    return overrides


def argument_problems(*, overrides=(), params=None, out_dir=None, animate=False, progress=None,
                      options=None, **values) -> list:
    """What is wrong with ``plan``'s arguments (the names and meanings of
    :func:`~nhgait.gaits.planner.plan`): its own, and its options — ``options`` (a
    :class:`~.plan_options.PlanOptions`, a mapping or None) with ``values`` (option names as
    keywords) on top (:meth:`~.plan_options.PlanOptions.collect`)."""
    problems = list(PlanOptions.collect(options, **values).problems)
    problems += _switch_problems(animate=animate)
    if override_list(overrides) is None:
        problems.append(f"overrides = {overrides!r}: give 'key=value' strings, a list of them or one "
                        "(e.g. ['final.y=0.3'])")
    if params is not None and not isinstance(params, Mapping):
        problems.append(f"params = {params!r} must be a mapping of parameter names to values")
    if animate is True and out_dir is None:
        problems.append("animate=True writes motion.gif into out_dir: give out_dir (or leave animate False)")
    return problems + _progress_problems(progress)


def _switch_problems(**switches) -> list:
    """Each of ``switches`` (``animate``): a bool."""
    return [f"{name} = {value!r} must be True or False" for name, value in switches.items()
            if not isinstance(value, bool)]


def _progress_problems(progress) -> list:
    from nhgait.dynamics.progress import Progress
    if progress is None or isinstance(progress, Progress):
        return []
    return [f"progress = {progress!r} must be a nhgait.dynamics.progress.Progress "
            "(Progress.to_stderr(), Progress.silent()) or None"]


def check_params(system, params) -> None:
    """Parameter values overriding the scene's (``params``, a mapping or a vector) checked before
    any derivation: names, numbers, a positive definite kinetic metric and independent
    constraints at sampled configurations (:meth:`~nhgait.dynamics.System.parameter_problems`),
    all problems in one ProblemError."""
    from nhgait.ocp import ProblemError
    if params is None:
        return
    named = ", ".join(f"{k} = {v}" for k, v in params.items()) if isinstance(params, Mapping) else ""
    problems = system.parameter_problems(params, label=f"the given params ({named})" if named else "params")
    if problems:
        raise ProblemError(problems, title="invalid parameters")
