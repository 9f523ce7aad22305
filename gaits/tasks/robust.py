"""``[task.robust]``: plan one input sequence against several parameter samples at once.

::

    [task.robust]
    parameters = {m = [0.9, 1.1], J_r = [0.9, 1.1]}   # factors of each parameter's value
    samples = 8                  # optional: K seeded draws, each factor uniform in [min, max] of
    seed = 0                     #   its list (default: every combination of the listed factors)
    aggregate = "mean"           # or "worst": the copies' terminal deviations averaged / the largest
    weight = 1.0                 # W = weight × the nominal plan's objective (see below)
    terminal = ["x", "y", "theta"]   # states compared at the end (default: the states the task's
                                     # `final` names and the planar frame's position)

The copies are the parameter vectors θ_s = θ_0 · factors (the combination of all ones, the
nominal, is not a copy). The scenario problem (:mod:`nhgait.ocp.scenarios`) keeps the task's
conditions hard on the nominal copy and adds W · A_s Σ_i ((y_i(c^s_N) − y_i(z_N)) / (ε s_i))²
to the objective, with s_i the feedback's scale of each terminal state
(:func:`nhgait.ocp.feedback.state_scales`: bound width, else the nominal plan's range, flat
states raised to the largest of their kind) and ε = 0.02 the end fraction of the feedback's
weights: a copy that ends 2 % of a state's scale away costs ``weight`` times the nominal plan's
objective. Every problem of the table is listed in the task's one ProblemError.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from nhgait.dynamics.suggestions import known_names
from nhgait.ocp.scenarios import AGGREGATES
from nhgait.ocp.statement import FrozenMap

from .values import number

__all__ = ["RobustTask", "parse_robust", "robust_table", "ROBUST_KEYS", "MAX_COPIES", "robust_name_problems"]

ROBUST_KEYS = ("parameters", "samples", "seed", "aggregate", "weight", "terminal")
#: the most copies a scenario problem may have (its NLP grows with them)
MAX_COPIES = 64


@dataclass(frozen=True)
class RobustTask:
    """A parsed ``[task.robust]`` table (module docstring): ``parameters`` name → factors,
    ``samples`` (None: the grid of the factors), ``seed``, ``aggregate``, ``weight``,
    ``terminal`` (empty: the default names)."""

    parameters: Mapping = field(default_factory=dict)
    samples: int | None = None
    seed: int = 0
    aggregate: str = "mean"
    weight: float = 1.0
    terminal: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "parameters", FrozenMap({k: tuple(v) for k, v in self.parameters.items()}))
        object.__setattr__(self, "terminal", tuple(self.terminal))

    def factors(self) -> list:
        """One {name: factor} per copy: the grid of the listed factors without the nominal, or
        ``samples`` draws from ``numpy.random.default_rng(seed)``, each factor uniform in
        [min, max] of its list."""
        names = list(self.parameters)
        if self.samples is None:
            grid = itertools.product(*(self.parameters[n] for n in names))
            return [dict(zip(names, combo, strict=True)) for combo in grid if any(f != 1.0 for f in combo)]
        rng = np.random.default_rng(int(self.seed))
        lo = np.array([min(self.parameters[n]) for n in names])
        hi = np.array([max(self.parameters[n]) for n in names])
        return [dict(zip(names, map(float, rng.uniform(lo, hi)), strict=True))
                for _ in range(int(self.samples))]

    def to_dict(self) -> dict:
        out = {"parameters": {k: list(v) for k, v in self.parameters.items()}, "seed": self.seed,
               "aggregate": self.aggregate, "weight": self.weight, "terminal": list(self.terminal)}
        if self.samples is not None:
            out["samples"] = self.samples
        return out


def robust_table(task) -> dict | None:
    """The ``robust`` entry of a task's table (None without one)."""
    return None if task.robust is None else task.robust.to_dict()


def parse_robust(data, where: str, problems: list) -> RobustTask | None:
    """The :class:`RobustTask` of ``data["robust"]`` (None when absent); problems appended."""
    if "robust" not in data:
        return None
    table, here = data["robust"], f"{where}.robust"
    if not isinstance(table, Mapping):
        problems.append(f"{here} must be a table such as {{parameters = {{m = [0.9, 1.1]}}}}")
        return None
    unknown = sorted(set(table) - set(ROBUST_KEYS))
    if unknown:
        problems.append(f"{here}: unknown key(s) "
                        f"{unknown}{known_names(unknown[0], ROBUST_KEYS, label='allowed')}")
    spec = RobustTask(_parameters(table, here, problems),
                      _count(table, "samples", here, problems, 1, MAX_COPIES),
                      _count(table, "seed", here, problems, 0, 2 ** 32 - 1) or 0,
                      _aggregate(table, here, problems), _weight(table, here, problems),
                      _terminal(table, here, problems))
    copies = math.prod(len(v) for v in spec.parameters.values()) if spec.parameters else 0
    if spec.samples is None and copies > MAX_COPIES + 1:
        problems.append(f"{here}: the grid of the listed factors has {copies} combinations, more than "
                        f"{MAX_COPIES} copies: list fewer factors or draw samples = K")
    return spec


def _parameters(table, here, problems) -> dict:
    value = table.get("parameters")
    if not isinstance(value, Mapping) or not value:
        problems.append(f"{here}.parameters must be a table of factor lists, e.g. {{m = [0.9, 1.1]}}")
        return {}
    out = {}
    for name, factors in value.items():
        factors = factors if isinstance(factors, (list, tuple)) else [factors]
        parsed = [number(f, f"{here}.parameters.{name}", problems) for f in factors]
        if any(math.isnan(p) for p in parsed):          # said by number()
            continue
        if not factors or not all(math.isfinite(p) and p > 0 for p in parsed):
            problems.append(f"{here}.parameters.{name}: factors must be positive numbers, got "
                            f"{list(factors)!r}")
            continue
        out[str(name)] = tuple(parsed)
    return out


def _count(table, key, here, problems, low, high) -> int | None:
    if key not in table:
        return None
    value = table[key]
    if isinstance(value, str) and value.strip().isdigit():      # from --set robust.samples=8
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        problems.append(f"{here}.{key} = {value!r} must be an integer from {low} to {high}")
        return None
    return int(value)


def _aggregate(table, here, problems) -> str:
    value = table.get("aggregate", "mean")
    if value not in AGGREGATES:
        problems.append(f"{here}.aggregate = {value!r}: use {' or '.join(map(repr, AGGREGATES))}")
        return "mean"
    return value


def _weight(table, here, problems) -> float:
    value = number(table.get("weight", 1.0), f"{here}.weight", problems)
    if not (math.isfinite(value) and value >= 0):
        problems.append(f"{here}.weight = {table.get('weight')!r} must be a finite number ≥ 0")
        return 1.0
    return value


def _terminal(table, here, problems) -> tuple:
    value = table.get("terminal", [])
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        problems.append(f"{here}.terminal must be a list of state names, got {value!r}")
        return ()
    return tuple(value)


def robust_name_problems(spec: RobustTask | None, system, known, where: str = "[task]") -> list:
    """Unknown parameters and unknown terminal names of ``spec`` on ``system`` (the names a
    task may use, ``known``; whether a terminal name is a state of the plan is checked when the
    velocity states are chosen)."""
    if spec is None:
        return []
    params = tuple(system.parameters)
    out = [f"{where}.robust.parameters: unknown parameter {n!r}{known_names(n, params, label='parameters')}"
           for n in spec.parameters if n not in params]
    out += [f"{where}.robust.terminal: unknown name {n!r}{known_names(n, tuple(known))}"
            for n in spec.terminal if n not in known]
    return out
