"""How a plan is solved, as one value: :class:`PlanOptions`.

The task says *what* a gait must do; these options say *how* the planner looks for it — the grid,
the solver and its transcription, compiled or interpreted functions, how many guesses and
workers, whether the optimum is verified, how long the whole plan may take. They are written
once here (as :class:`~nhgait.dynamics.simulation.options.SimulationOptions` is for a
simulation, after scipy's ``solve_ivp(**options)`` and rockit's ``ocp.solver(name, options)``),
checked once (:meth:`PlanOptions.problems`: every problem in one list) and printed once
(:meth:`PlanOptions.summary`). :func:`~nhgait.gaits.planner.plan`, ``nhgait plan``, ``nhgait
sweep`` and ``nhgait track`` take the same value; ``plan(..., intervals=40, verify=False)``
still works (the keywords are folded in by :meth:`PlanOptions.of`).

Examples
--------
>>> from nhgait.gaits.planning.options import PlanOptions
>>> options = PlanOptions.of(intervals=40, solver="ipopt")
>>> options.intervals, options.solver, options.verify
(40, 'ipopt', True)
>>> PlanOptions.of(options, verify=False).verify          # a new value; ``options`` is unchanged
False
>>> PlanOptions.of(intervls=40)    # doctest: +ELLIPSIS
Traceback (most recent call last):
...
nhgait.ocp.statement.ProblemError: invalid plan options: 1 problem(s)
  - unknown option 'intervls': did you mean 'intervals'? (options: intervals, solver, ...)
"""
from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple

__all__ = ["PlanOptions", "OptionValues", "Collected", "whole_number", "solver_order"]


def whole_number(value) -> bool:
    """Whether ``value`` is an integer (Python's or numpy's), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


class Collected(NamedTuple):
    """What an options value's ``collect`` returns (:class:`PlanOptions`, and the sweep's and
    the tracking study's options)."""

    options: Any                   #: the options; None when a name is unknown
    problems: list                 #: every problem of the values, in words


class OptionValues:
    """What every options value of nhgait shares (:class:`PlanOptions`,
    :class:`~nhgait.gaits.sweeps.options.SweepOptions`,
    :class:`~nhgait.gaits.tracking.request.TrackingOptions`, all frozen dataclasses): its names,
    and :meth:`of` — its ``collect`` with the problems raised as one
    :class:`~nhgait.ocp.ProblemError` titled :attr:`TITLE`."""

    TITLE = "invalid options"

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The option names, in the order of the docstring."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def of(cls, options=None, **values):
        """``options`` with ``values`` on top, checked: every problem in one
        :class:`~nhgait.ocp.ProblemError` (with the close matches of an unknown name)."""
        from nhgait.ocp import ProblemError
        made, problems = cls.collect(options, **values)
        if problems:
            raise ProblemError(problems, title=cls.TITLE)
        return made

    @classmethod
    def made(cls, given: dict) -> Collected:
        """The options of ``given`` (name → value), their own problems listed; None and every
        unknown name (with its close matches) when one is unknown."""
        from nhgait.dynamics.suggestions import known_names
        unknown = [f"unknown option {name!r}" + known_names(str(name), cls.names(), label="options")
                   for name in given if name not in cls.names()]
        if unknown:
            return Collected(None, unknown)
        options = cls(**given)
        return Collected(options, options.problems())


@dataclass(frozen=True, kw_only=True)
class PlanOptions(OptionValues):
    """How :func:`~nhgait.gaits.planner.plan` searches (module docstring).

    Attributes
    ----------
    intervals : N control intervals, overriding the task's (None: the task's)
    solver : "auto" (FATROP then Ipopt for small ODEs, Ipopt then FATROP for larger ones:
        :func:`solver_order`), "fatrop" or "ipopt"
    transcription : None (multiple shooting; stage-ordered for FATROP), "collocation", or a
        transcription object (one with ``build``)
    jit : compile the NLP functions (None: when a C compiler is found, within the compile budget)
    workers : candidates tried at once (separate processes); "auto": up to 2 per machine
    max_iter : iteration limit of each candidate's solve
    hessian : "auto", "exact", "gauss-newton" or "limited-memory" (Ipopt only)
    max_guesses : guesses tried per solver before the continuation
    verify : re-simulate the optimum by an independent integrator (the plan's checks)
    time_limit : seconds the whole plan may take (None: the task's ``time_limit``, else the
        default for the robot's size; ``inf``: unlimited)
    """

    intervals: int | None = None
    solver: str = "auto"
    transcription: Any = None
    jit: bool | None = None
    workers: int | str = 1
    max_iter: int = 500
    hessian: str = "auto"
    max_guesses: int = 12
    verify: bool = True
    time_limit: float | None = None

    TITLE = "invalid plan options"

    @classmethod
    def collect(cls, options=None, **values) -> Collected:
        """(the options, their problems) — as :meth:`of`, with the problems listed instead of
        raised (a caller that checks more than the options lists them all in one error); the
        options are None when a name is unknown or ``options`` is not one of its kinds."""
        if isinstance(options, PlanOptions):
            given = asdict(options)
        elif options is None:
            given = {}
        elif isinstance(options, Mapping):
            given = dict(options)
        else:
            return Collected(None, [f"options = {options!r} must be a PlanOptions, a mapping of option "
                                    "names or None"])
        return cls.made({**given, **values})

    @classmethod
    def values_of(cls, args) -> dict:
        """The option values a parsed command line holds: its attributes named as the options (the
        ones it has not stay the defaults), unchecked — :func:`~nhgait.gaits.planner.plan` checks
        them with the rest of the request, every problem in one error."""
        return {name: getattr(args, name) for name in cls.names() if hasattr(args, name)}

    def problems(self) -> list[str]:
        """What is wrong with these values (the command line's types hold for a Python caller
        too: no ``intervals=3.5`` silently truncated, no ``workers="many"`` deep inside)."""
        from .time_limits import time_limit_problem
        problems = [*self._count_problems(), *self._choice_problems()]
        problems += [f"{name} = {value!r} must be True or False" + (" or None" if name == "jit" else "")
                     for name, value in (("jit", self.jit), ("verify", self.verify))
                     if not (isinstance(value, bool) or (name == "jit" and value is None))]
        if not (self.workers in (None, "auto") or (whole_number(self.workers) and self.workers >= 1)):
            problems.append(f"workers = {self.workers!r} must be a whole number ≥ 1 or 'auto'")
        if self.time_limit is not None and time_limit_problem(self.time_limit):
            problems.append(time_limit_problem(self.time_limit))
        return problems

    def _count_problems(self) -> list[str]:
        """``max_iter``, ``max_guesses``: whole numbers ≥ 1; ``intervals``: None or a whole
        number (its range, 1 to 5000, is the task's check)."""
        problems = [f"{name} = {value!r} must be a whole number ≥ 1"
                    for name, value in (("max_iter", self.max_iter), ("max_guesses", self.max_guesses))
                    if not (whole_number(value) and value >= 1)]
        if self.intervals is not None and not whole_number(self.intervals):
            problems.insert(0, f"intervals = {self.intervals!r} must be a whole number (N control "
                               "intervals) or None")
        return problems

    def _choice_problems(self) -> list[str]:
        from nhgait.ocp.backends import BACKENDS
        from nhgait.ocp.derivatives import HESSIANS
        from nhgait.ocp.transcription import TRANSCRIPTIONS
        problems = [f"{name} = {value!r}: use one of {', '.join(map(repr, choices))}"
                    for name, value, choices in (("solver", self.solver, ("auto", *sorted(BACKENDS))),
                                                 ("hessian", self.hessian, ("auto", *HESSIANS)))
                    if not (isinstance(value, str) and value in choices)]
        if self.solver == "fatrop" and self.hessian == "limited-memory":
            problems.append("solver = 'fatrop' has no limited-memory Hessian (Ipopt's L-BFGS): use "
                            "hessian 'exact' or 'gauss-newton', or solver 'ipopt' or 'auto'")
        t = self.transcription
        known = isinstance(t, str) and t in TRANSCRIPTIONS
        if not (t is None or known or (not isinstance(t, str) and callable(getattr(t, "build", None)))):
            problems.append(f"transcription = {t!r}: use None or one of "
                            f"{', '.join(map(repr, TRANSCRIPTIONS))}")
        return problems

    def changed(self) -> dict:
        """The options that differ from the defaults, by name."""
        default = PlanOptions()
        return {f.name: getattr(self, f.name) for f in fields(self)
                if getattr(self, f.name) != getattr(default, f.name)}

    def summary(self) -> str:
        """One line: the options that differ from the defaults (``defaults`` when none do)."""
        changed = self.changed()
        return ", ".join(f"{k}={v!r}" for k, v in changed.items()) if changed else "defaults"


def solver_order(solver: str, transcription=None, problem=None, hessian: str = "exact") -> tuple:
    """The solvers ``plan`` tries, the next one when the previous finds no solution.

    "auto": Ipopt alone for collocation (FATROP does not take it) and for the limited-memory
    Hessian (Ipopt's L-BFGS; FATROP has none); for shooting, FATROP first
    when the stage function is written inline (small ODEs: FATROP is the faster there), Ipopt
    first when it is structured (robots of 5–10 coordinates: Ipopt is the faster there; the
    measurements are in docs/gait-planning.md and docs/benchmarks.md)."""
    from nhgait.ocp import ProblemError
    from nhgait.ocp.solver import SOLVERS
    if solver == "auto":
        if transcription == "collocation" or hessian == "limited-memory":
            return ("ipopt",)
        return (("ipopt", "fatrop") if problem is not None and _structured_stage(problem)
                else ("fatrop", "ipopt"))
    if solver not in SOLVERS:
        raise ProblemError([f"unknown solver {solver!r} (auto, {', '.join(SOLVERS)})"])
    return (solver,)


def _structured_stage(problem) -> bool:
    from nhgait.ocp.stage import stage_mode
    from nhgait.ocp.transcription import ode_function
    return stage_mode(ode_function(problem), free_horizon=problem.free_horizon is not None) == "structured"
