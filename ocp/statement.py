"""The statement of a problem before a model is chosen: its fields and their validators, once.

:class:`ProblemStatement` holds what an optimal control problem says that needs no model —
horizon, grid, boundary and periodicity conditions, path and control bounds, weights.
:class:`~nhgait.ocp.problem.OptimalControlProblem` is a statement bound to a model (it adds
the model's own checks: names, parameters, quantities); a gait task
(:class:`nhgait.gaits.task.Task`) is a statement parsed from a ``[task]`` table, with what
only a task says (objective words, ends at rest, velocity states, the verification
tolerance). Each field is checked by one small validator below; the two speak to their
readers in their own words (:class:`Wording`: :data:`OCP_WORDS` here, the ``[task]`` table's
in :mod:`nhgait.gaits.task`). A validator appends to one list, so every problem found is
listed in one :class:`ProblemError`.

Values of conditions and bounds are a number (equality) or a ``(lo, hi)`` pair (``None`` for
unbounded); :func:`interval` reads both.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.suggestions import known_names

__all__ = ["ProblemStatement", "ProblemError", "Wording", "OCP_WORDS", "FrozenMap", "interval", "STATEMENT_FIELDS",
           "MAX_INTERVALS"]

#: the statement's fields after ``model``, in order (an OptimalControlProblem's too)
STATEMENT_FIELDS = ("horizon", "intervals", "initial", "final", "periodic", "state_bounds", "control_bounds",
                    "control_weights", "state_weights", "time_weight", "free_horizon")


class ProblemError(ModelError):
    """An optimal control problem that cannot be transcribed (all problems listed)."""

    def __init__(self, problems, *, title: str = "invalid optimal control problem"):
        super().__init__(problems, title=title)


class FrozenMap(Mapping):
    """A read-only mapping that pickles (tasks travel to worker processes) and compares equal
    to any mapping with the same items."""

    __slots__ = ("_data",)

    def __init__(self, data=()):
        object.__setattr__(self, "_data", dict(data or {}))

    def __getitem__(self, key):
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __setattr__(self, name, value):
        raise AttributeError("FrozenMap is read-only")

    def __reduce__(self):
        return (FrozenMap, (self._data,))

    def __repr__(self) -> str:
        return f"FrozenMap({self._data!r})"

    def __hash__(self):
        return hash(tuple(sorted(self._data.items(), key=lambda kv: str(kv[0]))))


@dataclass(frozen=True)
class Wording:
    """The message templates of the validators, in one reader's words (``str.format`` fields
    named in each). A template that is None is a check this reader does not state on its own
    (another of its messages covers it)."""

    place: str               # {field}, {name}: where one entry of a table is
    field_names: Mapping     # a statement field → the reader's name for it
    horizon: str             # {value}
    horizon_not_number: str | None
    free_horizon_guess: str | None   # {value}: the initial T of a free horizon is not positive
    intervals: str           # {value}
    free_horizon_lower: str  # {lo}, {hi}
    free_horizon_any: str | None     # {lo}, {hi}: one line for any problem of the free horizon's bounds
    time_without_free_horizon: str
    not_a_bound: str | None  # {place}, {value}
    nan_bound: str | None    # {place}, {value}
    contradictory: str       # {place}, {lo}, {hi}
    outside_bounds: str      # {place}, {name}, {value}, {lo}, {hi}
    periodic_unequal: str    # {name}, {initial}, {final}
    repeated: str            # {field}, {names} (a tuple), {names_list}
    unknown_quantity: str    # {field}, {name}, {hint}
    unknown_input: str       # {field}, {name}, {hint}

    def field(self, name: str) -> str:
        return self.field_names.get(name, name)

    def at(self, field_name: str, name) -> str:
        return self.place.format(field=self.field(field_name), name=name)


#: the words of :class:`~nhgait.ocp.problem.OptimalControlProblem` (its keyword arguments)
OCP_WORDS = Wording(
    place="{field}[{name!r}]", field_names={},
    horizon="horizon T = {value!r} must be positive and finite",
    horizon_not_number="horizon T = {value!r} is not a number",
    free_horizon_guess="horizon T = {value!r} must be positive and finite",
    intervals="intervals N = {value!r} must be an integer from 1 to {max}",
    free_horizon_lower="free_horizon: lower bound {lo:g} must be positive",
    free_horizon_any=None,
    time_without_free_horizon="time_weight is only meaningful with free_horizon",
    not_a_bound="{place}: expected a number or a (lo, hi) pair, got {value!r}",
    nan_bound="{place}: NaN bound {value!r}",
    contradictory="{place}: contradictory bounds lo = {lo:g} > hi = {hi:g}",
    outside_bounds="{place} = {value!r} lies outside state_bounds [{lo:g}, {hi:g}]",
    periodic_unequal="periodic {name!r}: initial {initial!r} and final {final!r} cannot be equal",
    repeated="{field}: repeated names in {names}",
    unknown_quantity="{field}: unknown quantity {name!r}{hint}",
    unknown_input="{field}: unknown input {name!r}{hint}",
)


def interval(value, where: str = "", problems: list | None = None, words: Wording = OCP_WORDS) -> tuple:
    """(lo, hi) of a bound given as a number (equality) or a (lo, hi) pair with None for
    unbounded; a malformed, NaN or contradictory one is appended to ``problems``."""
    problems = [] if problems is None else problems
    try:
        if isinstance(value, (tuple, list)):
            if len(value) != 2:
                raise TypeError
            lo = -math.inf if value[0] is None else float(value[0])
            hi = math.inf if value[1] is None else float(value[1])
        else:
            lo = hi = float(value)
    except (TypeError, ValueError):
        _say(problems, words.not_a_bound, place=where, value=value)
        return -math.inf, math.inf
    if math.isnan(lo) or math.isnan(hi):
        _say(problems, words.nan_bound, place=where, value=value)
    elif lo > hi:
        problems.append(words.contradictory.format(place=where, lo=lo, hi=hi))
    return lo, hi


def _say(problems: list, template: str | None, **values) -> None:
    """``template`` filled in, appended unless the reader does not state it (None) or already
    has the same line."""
    if template is not None:
        line = template.format(**values)
        if line not in problems:
            problems.append(line)


# ----------------------------------------------------------------------------- validators
def horizon_problems(statement: "ProblemStatement", words: Wording) -> list:
    """T > 0 and finite (for a free horizon, its initial value)."""
    problems: list = []
    guess = words.horizon if statement.free_horizon is None else words.free_horizon_guess
    try:
        T = float(statement.horizon)
        if not (T > 0 and math.isfinite(T)):
            _say(problems, guess, value=statement.horizon)
    except (TypeError, ValueError):
        _say(problems, words.horizon_not_number, value=statement.horizon)
    return problems


def free_horizon_problems(statement: "ProblemStatement", words: Wording) -> list:
    """A free horizon 0 < T_min ≤ T_max; a time weight only with a free horizon."""
    if statement.free_horizon is None:
        return [words.time_without_free_horizon] if statement.time_weight else []
    problems: list = []
    lo, hi = interval(statement.free_horizon, words.field("free_horizon"), problems, words)
    if lo <= 0:
        _say(problems, words.free_horizon_lower, lo=lo, hi=hi)
    if problems and words.free_horizon_any is not None:
        return [words.free_horizon_any.format(lo=lo, hi=hi)]
    return problems


#: the largest number of control intervals accepted: N = 5000 already builds 31 MB of C in about a
#: minute and solves in minutes; N = 100000 spent more than 2 min and 1.4 GB inside nlpsol alone
MAX_INTERVALS = 5000


def intervals_problems(statement: "ProblemStatement", words: Wording) -> list:
    """N an integer from 1 to :data:`MAX_INTERVALS`."""
    N = statement.intervals
    if isinstance(N, bool) or not isinstance(N, numbers.Integral) or not 1 <= N <= MAX_INTERVALS:
        return [words.intervals.format(value=N, max=MAX_INTERVALS)]
    return []


def _ends(statement: "ProblemStatement") -> tuple:
    return (("initial", statement.initial), ("final", statement.final))


def table_problems(statement: "ProblemStatement", words: Wording, known=None, inputs=None) -> list:
    """Each condition and bound a number or a (lo, hi) pair with lo ≤ hi, no periodic name
    twice and, given ``known`` (quantity names) and ``inputs`` (input names), every name known."""
    problems: list = []
    for where, mapping in (*_ends(statement), ("state_bounds", statement.state_bounds)):
        for name, value in mapping.items():
            problems += _unknown(name, known, words.unknown_quantity, words.field(where))
            interval(value, words.at(where, name), problems, words)
    for name in statement.periodic:
        problems += _unknown(name, known, words.unknown_quantity, words.field("periodic"))
    if len(set(statement.periodic)) != len(statement.periodic):
        problems.append(words.repeated.format(field=words.field("periodic"), names=statement.periodic,
                                              names_list=list(statement.periodic)))
    if isinstance(statement.control_bounds, Mapping):
        for name, value in statement.control_bounds.items():
            problems += _unknown(name, inputs, words.unknown_input, words.field("control_bounds"), label="inputs")
            interval(value, words.at("control_bounds", name), problems, words)
    return problems


def _unknown(name, known, template: str, where: str, label: str = "known") -> list:
    if known is None or name in known:
        return []
    return [template.format(field=where, name=name, hint=known_names(name, known, label=label))]


def consistency_problems(statement: "ProblemStatement", words: Wording, known=None) -> list:
    """End values outside their path bound; periodic quantities whose end values cannot be
    equal. A name outside ``known`` and a contradictory bound are reported once, elsewhere."""
    problems: list = []
    for where, mapping in _ends(statement):
        for name, value in mapping.items():
            if name not in statement.state_bounds or (known is not None and name not in known):
                continue
            lo, hi = interval(value)
            bound_lo, bound_hi = interval(statement.state_bounds[name])
            if bound_lo <= bound_hi and (hi < bound_lo or lo > bound_hi):
                problems.append(words.outside_bounds.format(place=words.at(where, name), name=name, value=value,
                                                            lo=bound_lo, hi=bound_hi))
    for name in statement.periodic:
        if name in statement.initial and name in statement.final:
            a, b = interval(statement.initial[name]), interval(statement.final[name])
            if max(a[0], b[0]) > min(a[1], b[1]):
                problems.append(words.periodic_unequal.format(name=name, initial=statement.initial[name],
                                                              final=statement.final[name]))
    return problems


# ----------------------------------------------------------------------------- the statement
@dataclass(frozen=True)
class ProblemStatement:
    """What an optimal control problem says (see :mod:`nhgait.ocp.problem` for the maths).

    Parameters
    ----------
    model : the model the problem is stated on; None for a statement not yet bound to one (a
        gait task's, :class:`nhgait.gaits.task.Task`)
    horizon : float
        T > 0 (the initial value of T when ``free_horizon`` is given).
    intervals : int
        N ≥ 1 control intervals of length h = T / N.
    initial, final : mapping name → value or (lo, hi)
        Boundary conditions on quantities at t = 0 and t = T.
    periodic : sequence of names
        Quantities with y(T) = y(0).
    state_bounds : mapping name → (lo, hi)
        Bounds on quantities at every node t_0 … t_N.
    control_bounds : mapping name → (lo, hi), or a number b meaning |u_j| ≤ b for every input
    control_weights : mapping input name → w ≥ 0 (default 1)
    state_weights : mapping name → c ≥ 0, adds Σ_k h c z_i(t_k)²
    time_weight : float, adds c_T T (free horizon only)
    free_horizon : (T_min, T_max) or None

    Making a statement checks nothing: :meth:`problems` lists what is wrong with it in a
    reader's words (:class:`~nhgait.ocp.problem.OptimalControlProblem` and
    :func:`nhgait.gaits.task.parse_task` raise them in one ProblemError).
    """

    model: Any
    horizon: float
    intervals: int = 50
    initial: Mapping = field(default_factory=dict)
    final: Mapping = field(default_factory=dict)
    periodic: tuple = ()
    state_bounds: Mapping = field(default_factory=dict)
    control_bounds: Any = field(default_factory=dict)
    control_weights: Mapping = field(default_factory=dict)
    state_weights: Mapping = field(default_factory=dict)
    time_weight: float = 0.0
    free_horizon: tuple | None = None

    def __post_init__(self):
        for key in ("initial", "final", "state_bounds", "control_weights", "state_weights"):
            object.__setattr__(self, key, FrozenMap(getattr(self, key)))
        if isinstance(self.control_bounds, Mapping):
            object.__setattr__(self, "control_bounds", FrozenMap(self.control_bounds))
        object.__setattr__(self, "periodic", tuple(self.periodic))

    def problems(self, words: Wording = OCP_WORDS, known=None, inputs=None) -> list:
        """Every problem of the statement, in ``words``: its form (no model needed) and, given
        ``known`` (the quantity names) and ``inputs`` (the input names), its names."""
        return (horizon_problems(self, words) + intervals_problems(self, words) + free_horizon_problems(self, words)
                + table_problems(self, words, known, inputs) + consistency_problems(self, words, known))

    def statement_fields(self) -> dict:
        """The statement's fields after ``model`` (keyword arguments of a problem)."""
        return {key: getattr(self, key) for key in STATEMENT_FIELDS}
