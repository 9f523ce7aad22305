""":func:`~nhgait.gaits.planner.plan`'s own arguments, checked before any work.

The command line's types (``--intervals`` an int, ``--workers`` a number ≥ 1 or ``auto`` …) hold
for it; a Python caller gets the same checks here, every problem in one
:class:`~nhgait.ocp.ProblemError` — with the output folder's and the scene's and task's
(:func:`~nhgait.gaits.task_library.resolve`) — instead of a value silently truncated
(``intervals=3.5``), taken for a number (``intervals=True``), or an error deep inside
(``workers="many"``, ``max_iter=-1`` in Ipopt's option dump).

* :func:`checked_request` — (the resolved plan, the output folder) or one ProblemError;
* :func:`argument_problems` — the problems of the arguments alone;
* :func:`override_list` — ``overrides`` as a list: a single string is one override;
* :func:`whole_number` — an integer (Python's or numpy's), not a bool (also for track and sweep);
* :func:`check_params` — the parameter values themselves (names, numbers, a positive definite
  kinetic metric), once the scene is known.
"""
from __future__ import annotations

import numbers
from collections.abc import Mapping

__all__ = ["checked_request", "argument_problems", "override_list", "check_params", "whole_number"]

def checked_request(system, task, arguments: dict) -> tuple:
    """(the :class:`~nhgait.gaits.task_library.Plan`, the output folder or None) for ``plan``'s
    keyword ``arguments``; one ProblemError listing every problem of the arguments, the output
    folder, the scene and the task."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.ocp import ProblemError

    from .outputs import output_directory
    from .task_library import resolve
    problems = argument_problems(**arguments)
    out_dir, to_plan, caught = arguments["out_dir"], None, []
    try:
        if out_dir is not None:            # before any derivation (a bad location: exit 2)
            out_dir = output_directory(out_dir, "out_dir")
    except ModelError as exc:
        caught.append(exc)
    overrides = override_list(arguments["overrides"], arguments["intervals"])
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
    return to_plan, out_dir


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


def argument_problems(*, overrides=(), intervals=None, solver="auto", transcription=None, jit=None,
                      workers=1, params=None, max_iter=500, out_dir=None, animate=False, verify=True,
                      hessian="auto", max_guesses=12, progress=None, time_limit=None) -> list:
    """What is wrong with ``plan``'s arguments (the names and meanings of
    :func:`~nhgait.gaits.planner.plan`; the values a command-line option can give pass)."""
    from .time_limits import time_limit_problem
    problems = [*_count_problems(intervals, max_iter, max_guesses),
                *_choice_problems(solver, hessian, transcription),
                *_switch_problems(jit=jit, animate=animate, verify=verify)]
    if override_list(overrides) is None:
        problems.append(f"overrides = {overrides!r}: give 'key=value' strings, a list of them or one "
                        "(e.g. ['final.y=0.3'])")
    if not (workers in (None, "auto") or (whole_number(workers) and workers >= 1)):
        problems.append(f"workers = {workers!r} must be a whole number ≥ 1 or 'auto'")
    if params is not None and not isinstance(params, Mapping):
        problems.append(f"params = {params!r} must be a mapping of parameter names to values")
    if animate is True and out_dir is None:
        problems.append("animate=True writes motion.gif into out_dir: give out_dir (or leave animate False)")
    problems += _progress_problems(progress)
    if time_limit is not None and time_limit_problem(time_limit):
        problems.append(time_limit_problem(time_limit))
    return problems


def whole_number(value) -> bool:
    """Whether ``value`` is an integer (Python's or numpy's), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _count_problems(intervals, max_iter, max_guesses) -> list:
    """``max_iter`` and ``max_guesses``: whole numbers ≥ 1; ``intervals``: None or a whole number
    (its range, 1 to 5000, is the task's check: ``--intervals 0`` says it)."""
    problems = [f"{name} = {value!r} must be a whole number ≥ 1"
                for name, value in (("max_iter", max_iter), ("max_guesses", max_guesses))
                if not (whole_number(value) and value >= 1)]
    if intervals is not None and not whole_number(intervals):
        problems.insert(0, f"intervals = {intervals!r} must be a whole number (N control intervals) or None")
    return problems


def _switch_problems(**switches) -> list:
    """Each of ``jit`` (or None: when a C compiler is found), ``animate`` and ``verify``: a bool."""
    return [f"{name} = {value!r} must be True or False" + (" or None" if name == "jit" else "")
            for name, value in switches.items()
            if not (isinstance(value, bool) or (name == "jit" and value is None))]


def _choice_problems(solver, hessian, transcription) -> list:
    """``solver`` and ``hessian`` among their choices; ``transcription`` None, a known name or a
    transcription object (one with ``build``)."""
    from nhgait.ocp.backends import BACKENDS
    from nhgait.ocp.derivatives import HESSIANS
    from nhgait.ocp.transcription import TRANSCRIPTIONS
    problems = [f"{name} = {value!r}: use one of {', '.join(map(repr, choices))}"
                for name, value, choices in (("solver", solver, ("auto", *sorted(BACKENDS))),
                                             ("hessian", hessian, ("auto", *HESSIANS)))
                if not (isinstance(value, str) and value in choices)]
    if solver == "fatrop" and hessian == "limited-memory":
        problems.append("solver = 'fatrop' has no limited-memory Hessian (Ipopt's L-BFGS): use "
                        "hessian 'exact' or 'gauss-newton', or solver 'ipopt' or 'auto'")
    known = isinstance(transcription, str) and transcription in TRANSCRIPTIONS
    if not (transcription is None or known or (not isinstance(transcription, str)
                                               and callable(getattr(transcription, "build", None)))):
        problems.append(f"transcription = {transcription!r}: use None or one of "
                        f"{', '.join(map(repr, TRANSCRIPTIONS))}")
    return problems


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
