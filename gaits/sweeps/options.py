"""How a sweep runs, as one value: :class:`SweepOptions`.

:func:`~nhgait.gaits.sweeps.driver.sweep` states *what* is swept (the scene, the task, the
grid, the store folder); these options say everything else — the base task's changes
(``overrides``, ``params``), the planner's options of every point (``plan``: the shared
:class:`~nhgait.gaits.planning.options.PlanOptions`, of which a point takes ``transcription``,
``solver``, ``jit`` and ``time_limit``), where the points run (``scheduler``, ``workers``, an
open ``backend``), and how (``resume``, ``warm_start``, ``chain``, ``progress``). They are
gathered and checked once (:meth:`SweepOptions.collect`: every problem in one list), as
:class:`~nhgait.gaits.planning.options.PlanOptions` are for a plan; ``sweep(..., workers=0,
resume=True)`` still works (the keywords are folded in).

Examples
--------
>>> from nhgait.gaits.sweeps.options import SweepOptions
>>> options = SweepOptions.of(workers=0, plan={"jit": False})
>>> options.workers, options.planner()
(0, {'jit': False})
>>> SweepOptions.of(wokers=2)          # doctest: +ELLIPSIS
Traceback (most recent call last):
...
nhgait.ocp.statement.ProblemError: invalid sweep: 1 problem(s)
  - unknown option 'wokers': did you mean 'workers'? (options: ...)
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any

from ..planning.options import Collected, OptionValues, PlanOptions
from .point import OPTIONS, option_problems

__all__ = ["SweepOptions", "PLAN_OPTIONS"]

#: the planner options a sweep point takes (the others are a plan's search: one solve per point)
PLAN_OPTIONS = OPTIONS


@dataclass(frozen=True, kw_only=True)
class SweepOptions(OptionValues):
    """How :func:`~nhgait.gaits.sweeps.driver.sweep` runs (module docstring).

    Attributes
    ----------
    overrides : ``key.sub=value`` changes of the base task (``--set``)
    params : parameter values overriding the scene's (a mapping), None: the scene's
    plan : the planner options of every point: a :class:`~nhgait.gaits.planning.options.PlanOptions`
        or a mapping of its names, of which :data:`PLAN_OPTIONS` may differ from the defaults
        (``time_limit``: seconds per point); None: the defaults (``jit`` False in a point)
    scheduler : Dask scheduler address or ``local:N`` (None: the local process pool)
    workers : local pool size (None: one per core; 0: in this process)
    backend : an open back end to use instead (not closed by the sweep)
    resume : continue the sweep stored in the folder (solve only its missing points)
    warm_start : continue from solved neighbours (False: every point cold, for comparison)
    chain : points per back-end task down the continuation tree (None: the back end's choice;
        1 for the local pool, 4 for Dask)
    progress : callback receiving a :class:`~nhgait.gaits.sweeps.driver.Progress` after each point
    """

    overrides: Any = ()
    params: Mapping | None = None
    plan: Any = None
    scheduler: str | None = None
    workers: int | None = None
    backend: Any = None
    resume: bool = False
    warm_start: bool = True
    chain: int | None = None
    progress: Callable | None = None

    TITLE = "invalid sweep"

    @classmethod
    def collect(cls, options=None, **values) -> Collected:
        """(the options, their problems): ``options`` — a SweepOptions, None, or (as before
        these options existed) a mapping of planner options, which becomes ``plan`` — with
        ``values`` (the fields as keywords) on top; an unknown name or a wrong value is listed
        with every other problem."""
        if isinstance(options, SweepOptions):
            given = {f.name: getattr(options, f.name) for f in fields(cls)}
        elif options is None:
            given = {}
        elif isinstance(options, (Mapping, PlanOptions)):
            given = {"plan": options}
        else:
            return Collected(None, [f"options = {options!r} must be SweepOptions, a mapping of planner "
                                     f"options ({', '.join(PLAN_OPTIONS)}) or None"])
        return cls.made({**given, **values})

    def planner(self) -> dict:
        """The planner options of a point, as the names that differ from the defaults (what a
        point's :class:`~nhgait.gaits.sweeps.point.SweepCase` stores)."""
        if isinstance(self.plan, PlanOptions):
            return self.plan.changed()
        return dict(self.plan or {})

    def problems(self) -> list[str]:
        """What is wrong with these values: the planner options (:func:`_plan_problems`), the
        back end's (:func:`~.backends.backend_problems`, unless an open ``backend`` is given),
        the switches and ``chain``."""
        from ..planning.options import whole_number
        from .backends import backend_problems
        problems = _plan_problems(self.plan)
        if self.backend is None:
            problems += backend_problems(self.scheduler, self.workers)
        problems += [f"{name} = {value!r} must be True or False"
                     for name, value in (("resume", self.resume), ("warm_start", self.warm_start))
                     if not isinstance(value, bool)]
        if self.chain is not None and not (whole_number(self.chain) and self.chain >= 1):
            problems.append(f"chain must be a whole number ≥ 1 of points per task, got {self.chain!r}")
        if self.progress is not None and not callable(self.progress):
            problems.append(f"progress = {self.progress!r} must be a callable or None")
        return problems


def _plan_problems(plan) -> list:
    """What is wrong with a sweep's planner options: a mapping as
    :func:`~.point.option_problems` says (an unknown name, the values as a plan's, a solver a
    point can run); a PlanOptions by its own checks and an option other than
    :data:`PLAN_OPTIONS` changed (a point is one solve)."""
    if not isinstance(plan, PlanOptions):
        return option_problems(plan)
    changed = plan.changed()
    return [*(f"options: {name} = {value!r}: a sweep point is one solve; it takes only "
              f"{', '.join(PLAN_OPTIONS)}" for name, value in changed.items() if name not in PLAN_OPTIONS),
            *option_problems({k: v for k, v in changed.items() if k in PLAN_OPTIONS})]
