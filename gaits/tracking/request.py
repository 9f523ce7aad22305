"""What a tracking study's request must be, checked before any work (:func:`~.study.track`).

* :func:`request_problems` — the values that need no scene: ``samples`` (an integer ≥ 1),
  ``seed`` (an integer ≥ 0: numpy's generators take no negative seed), the :class:`~.runs.Noise`
  (finite, ≥ 0), and ``plan_file`` given with a task or overrides (the plan file holds its task);
* :func:`parse_mismatch` — ``["params.m=1.1", ...]`` or a mapping → {name: factor}: each name a
  parameter of the scene, each factor a positive number, each parameter named once.

Each returns or raises every problem it finds; :func:`~.study.track` joins them with the time
budget's and the back end's into one :class:`~nhgait.ocp.ProblemError` before planning.

The request itself is one value, :class:`TrackingOptions` (gathered by
:meth:`TrackingOptions.collect` from ``track``'s keywords, as
:class:`~nhgait.gaits.planning.options.PlanOptions` are from ``plan``'s); how the plan is
solved is the shared :class:`~nhgait.gaits.planning.options.PlanOptions` (``plan``), its
``time_limit`` the whole study's.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..planning.options import Collected, OptionValues, PlanOptions, whole_number
from .runs import Noise

__all__ = ["request_problems", "parse_mismatch", "TrackingOptions"]


@dataclass(frozen=True, kw_only=True)
class TrackingOptions(OptionValues):
    """What a tracking study does besides planning (:func:`~.study.track`).

    Attributes
    ----------
    overrides : ``--set`` strings of the task
    mismatch : ``params.NAME=FACTOR`` strings or a mapping name → factor (:func:`parse_mismatch`)
    samples : K noisy samples; seed : of the noise (an integer ≥ 0); noise : a :class:`~.runs.Noise`
    plan_file : a ``solution.json`` (with its feedback) to track instead of planning
    scheduler, workers : the sweep back ends the samples run on
        (:func:`~nhgait.gaits.sweeps.backends.make_backend`); both None and K ≤
        :data:`~.study.SERIAL_SAMPLES`: in this process
    plan : how the plan is solved, a :class:`~nhgait.gaits.planning.options.PlanOptions`; its
        ``time_limit`` is the seconds the whole study may take (the plan and the samples)
    """

    overrides: Any = ()
    mismatch: Any = ()
    samples: int = 20
    seed: int = 0
    noise: Noise = Noise()
    plan_file: Any = None
    scheduler: str | None = None
    workers: int | None = None
    plan: PlanOptions = PlanOptions()

    TITLE = "invalid tracking study"

    @classmethod
    def collect(cls, options=None, **values) -> Collected:
        """(the options, the problems of the plan's options): ``options`` (a TrackingOptions or
        None) with ``values`` on top — its fields, or a plan option's name (``time_limit``,
        ``intervals``, …; ``workers`` is the samples') that goes into ``plan``; ``plan`` may be
        a PlanOptions, a mapping of its names or None. An unknown name is listed with the close
        matches; the other values are :func:`request_problems`' to check (with the task)."""
        from nhgait.dynamics.suggestions import known_names
        if options is not None and not isinstance(options, TrackingOptions):
            return Collected(None, [f"options = {options!r} must be TrackingOptions or None"])
        given = {} if options is None else {name: getattr(options, name) for name in cls.names()}
        planned = {k: values.pop(k) for k in list(values)
                   if k not in cls.names() and k in PlanOptions.names()}
        given.update(values)
        unknown = [f"unknown option {name!r}"
                   + known_names(str(name), cls.names() + PlanOptions.names(), label="options")
                   for name in given if name not in cls.names()]
        if unknown:
            return Collected(None, unknown)
        plan, problems = PlanOptions.collect(given.get("plan"), **planned)
        if plan is None:
            return Collected(None, problems)
        return Collected(cls(**{**given, "plan": plan}), problems)


def request_problems(samples, seed, noise, *, plan_file=None, task=None, overrides=()) -> list:
    """The problems of the scene-independent values of a request (module docstring)."""
    problems = []
    if not whole_number(samples) or samples < 1:
        problems.append(f"--samples must be an integer ≥ 1, got {samples!r}")
    if not whole_number(seed) or seed < 0:
        problems.append(f"--seed must be an integer ≥ 0, got {seed!r}")
    problems += _noise_problems(noise)
    if plan_file is not None and (overrides or task is not None):
        problems.append("--plan tracks the task stored in that solution.json: give no --gait or "
                        "--set with it")
    return problems


def _noise_problems(noise) -> list:
    """Each standard deviation of ``noise`` must be a finite number ≥ 0."""
    from .runs import Noise
    if not isinstance(noise, Noise):
        return [f"noise must be a Noise(state, input), got {noise!r}"]
    problems = []
    for name, value in (("state-noise", noise.state), ("input-noise", noise.input)):
        number = isinstance(value, numbers.Real) and not isinstance(value, bool)
        if not (number and math.isfinite(value) and value >= 0):
            problems.append(f"--{name} must be a finite number ≥ 0, got {value!r}")
    return problems


def parse_mismatch(items, parameters: dict) -> dict:
    """``["params.m=1.1", ...]`` (or a mapping {"m": 1.1}) → {"m": 1.1}: each named parameter
    multiplied by its factor on the simulated robot. One :class:`~nhgait.ocp.ProblemError`
    lists every problem (a parameter named twice among them: which factor was meant is not
    guessed)."""
    from nhgait.ocp import ProblemError
    if isinstance(items, str):
        items = [items]
    pairs = ([(f"params.{name}={value}", name, value) for name, value in items.items()]
             if isinstance(items, Mapping) else [_split(item) for item in items])
    out, given, problems = {}, {}, []
    for item, name, text in pairs:
        problem = _factor_problem(item, name, text, parameters)
        if problem:
            problems.append(problem)
            continue
        given.setdefault(name, []).append(item)
        out[name] = float(text)
    problems += [f"--mismatch params.{name} given {len(items)} times ({', '.join(map(repr, items))}): "
                 "give each parameter once" for name, items in given.items() if len(items) > 1]
    if problems:
        raise ProblemError(problems, title="invalid mismatch")
    return out


def _split(item) -> tuple:
    """``"params.m=1.1"`` → ("params.m=1.1", "m", "1.1"); a malformed item → (item, None, None)."""
    key, sep, text = str(item).partition("=")
    prefix, _, name = key.strip().partition(".")
    if not sep or prefix != "params" or not name:
        return item, None, None
    return item, name, text


def _factor_problem(item, name, text, parameters: dict) -> str:
    """What is wrong with one mismatch ``item`` (its parameter ``name`` and factor ``text``), or ''."""
    from nhgait.dynamics.suggestions import known_names
    if name is None:
        return f"--mismatch {item!r}: write params.NAME=FACTOR (e.g. params.m=1.1)"
    if name not in parameters:
        return (f"--mismatch {item!r}: unknown parameter {name!r}"
                + known_names(name, tuple(parameters), label="parameters"))
    try:
        factor = math.nan if isinstance(text, bool) else float(text)
    except (TypeError, ValueError):
        factor = math.nan
    if not (math.isfinite(factor) and factor > 0):
        return f"--mismatch {item!r}: the factor must be a positive number, got {text!r}"
    return ""
