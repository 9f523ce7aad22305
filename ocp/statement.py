"""The statement of a problem before a model is chosen: its fields and their validators, once.

:class:`ProblemStatement` holds what an optimal control problem says that needs no model —
horizon, grid, boundary and periodicity conditions, path and control bounds, weights.
:class:`~nhgait.ocp.problem.OptimalControlProblem` is a statement bound to a model (it adds
the model's own checks: names, parameters, quantities); a gait task
(:class:`nhgait.gaits.tasks.statement.Task`) is a statement parsed from a ``[task]`` table, with what
only a task says (objective words, ends at rest, velocity states, the verification
tolerance). Each field is checked by one small validator below; the two speak to their
readers in their own words (:class:`Wording`: :data:`OCP_WORDS` here, the ``[task]`` table's
in :mod:`nhgait.gaits.tasks.statement`). A validator appends to one list, so every problem found is
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

__all__ = ["ProblemStatement", "ProblemError", "Wording", "OCP_WORDS", "FrozenMap", "interval",
           "STATEMENT_FIELDS", "MAX_INTERVALS", "Phase", "Waypoint", "NODE_TOLERANCE", "instant_problems"]

#: the statement's fields after ``model``, in order (an OptimalControlProblem's too)
STATEMENT_FIELDS = ("horizon", "intervals", "initial", "final", "periodic", "state_bounds", "control_bounds",
                    "control_weights", "state_weights", "time_weight", "free_horizon", "waypoints",
                    "integrals", "phases", "end_weights")
#: a waypoint's time is a node when t N / T is an integer to this (relative) tolerance
NODE_TOLERANCE = 1e-9


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


def interval(value, where: str = "", problems: list | None = None,
             words: Wording = OCP_WORDS) -> tuple[float, float]:
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
def horizon_problems(statement: ProblemStatement, words: Wording) -> list:
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


def free_horizon_problems(statement: ProblemStatement, words: Wording) -> list:
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


def intervals_problems(statement: ProblemStatement, words: Wording) -> list:
    """N an integer from 1 to :data:`MAX_INTERVALS`."""
    N = statement.intervals
    if isinstance(N, bool) or not isinstance(N, numbers.Integral) or not 1 <= N <= MAX_INTERVALS:
        return [words.intervals.format(value=N, max=MAX_INTERVALS)]
    return []


def _ends(statement: ProblemStatement) -> tuple:
    return (("initial", statement.initial), ("final", statement.final))


def table_problems(statement: ProblemStatement, words: Wording, known=None, inputs=None) -> list:
    """Each condition and bound a number or a (lo, hi) pair with lo ≤ hi, no periodic name
    twice and, given ``known`` (quantity names) and ``inputs`` (input names), every name known."""
    problems: list = []
    for where, mapping in (*_ends(statement), ("state_bounds", statement.state_bounds)):
        for name, value in mapping.items():
            problems += ((_misplaced(name, inputs, known, _prefix(words) + words.field(where),
                                     _prefix(words) + words.field("control_bounds"))
                          if where == "state_bounds" else [])
                         or _unknown(name, known, words.unknown_quantity, words.field(where)))
            interval(value, words.at(where, name), problems, words)
    for name in statement.periodic:
        problems += _unknown(name, known, words.unknown_quantity, words.field("periodic"))
    if len(set(statement.periodic)) != len(statement.periodic):
        problems.append(words.repeated.format(field=words.field("periodic"), names=statement.periodic,
                                              names_list=list(statement.periodic)))
    if isinstance(statement.control_bounds, Mapping):
        for name, value in statement.control_bounds.items():
            problems += (_misplaced(name, known, inputs, _prefix(words) + words.field("control_bounds"),
                                    _prefix(words) + words.field("state_bounds"))
                         or _unknown(name, inputs, words.unknown_input, words.field("control_bounds"),
                                     label="inputs"))
            interval(value, words.at("control_bounds", name), problems, words)
    return problems


def _misplaced(name, other, own, field: str, instead: str) -> list:
    """A name of the other kind in ``field`` (an input among the state bounds, a state or
    quantity among the input bounds): the one problem, naming the field ``instead`` it belongs in."""
    if other is None or name not in other or (own is not None and name in own):
        return []
    return [f"{field}: {name!r} is {'an input' if 'control' in instead else 'not an input'}: "
            f"bound it in {instead}"]


def _unknown(name, known, template: str, where: str, label: str = "known") -> list:
    if known is None or name in known:
        return []
    return [template.format(field=where, name=name, hint=known_names(name, known, label=label))]


def consistency_problems(statement: ProblemStatement, words: Wording, known=None) -> list:
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
                problems.append(words.outside_bounds.format(place=words.at(where, name), name=name,
                                                            value=value, lo=bound_lo, hi=bound_hi))
    for name in statement.periodic:
        if name in statement.initial and name in statement.final:
            a, b = interval(statement.initial[name]), interval(statement.final[name])
            if max(a[0], b[0]) > min(a[1], b[1]):
                problems.append(words.periodic_unequal.format(name=name, initial=statement.initial[name],
                                                              final=statement.final[name]))
    return problems


def integral_problems(statement: ProblemStatement, words: Wording, known=None) -> list:
    """An integral's name is new (not one of the ``known`` quantities) and its integrand a
    known quantity; an end weight names a quantity or an integral."""
    problems: list = []
    base = None if known is None else list(known)
    where = f"{_prefix(words)}{words.field('integrals')}"
    for name, integrand in statement.integrals.items():
        if base is not None and name in base:
            problems.append(f"{where}: {name!r} is a quantity already; an integral needs a new name")
        if not isinstance(integrand, str):
            problems.append(f"{where}.{name}: the integrand is a quantity's name, got {integrand!r}")
        else:
            problems += _unknown(integrand, base, words.unknown_quantity,
                                 f"{words.field('integrals')}.{name}")
    names = None if known is None else base + list(statement.integrals)
    for name in statement.end_weights:
        problems += _unknown(name, names, words.unknown_quantity, words.field("end_weights"))
    return problems


# ----------------------------------------------------------------------------- conditions between the ends
@dataclass(frozen=True)
class Waypoint:
    """Conditions at a given time between the ends: ``time`` t_w (s, from the start of the
    problem, or of its phase for a phase's waypoint) and ``conditions`` (name → value or
    (lo, hi), as ``initial``/``final``). The time must be a node, t_w = k T / N (a waypoint at
    a *free* time is the end of a :class:`Phase`). ``name`` labels its rows ("waypoint1.x")."""

    time: float
    conditions: Mapping = field(default_factory=dict)
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "conditions", FrozenMap(self.conditions))


@dataclass(frozen=True)
class Phase:
    """One phase of a multi-phase problem: ``intervals`` N_p of length T_p / N_p, its horizon
    T_p (``horizon``; the initial value when ``free_horizon`` = (lo, hi) is given), the
    conditions at its end (``final``: the phase boundary, at a time the solver chooses when the
    horizon is free), path bounds on its nodes (``state_bounds``, added to the problem's) and
    bounds on its inputs (``control_bounds``, intersected with the problem's), ``waypoints`` at
    given times from its start. Consecutive phases share their boundary node (the state is
    continuous); ``name`` labels its rows ("<name>.final.x"; default "phase<i>")."""

    horizon: float
    intervals: int = 20
    free_horizon: tuple | None = None
    final: Mapping = field(default_factory=dict)
    state_bounds: Mapping = field(default_factory=dict)
    control_bounds: Mapping = field(default_factory=dict)
    waypoints: tuple = ()
    name: str = ""

    def __post_init__(self):
        for key in ("final", "state_bounds", "control_bounds"):
            object.__setattr__(self, key, FrozenMap(getattr(self, key)))
        object.__setattr__(self, "waypoints", tuple(self.waypoints))


def phase_problems(statement: ProblemStatement, words: Wording, known=None, inputs=None) -> list:
    """Each phase: N an integer in range, T > 0, a free horizon 0 < lo ≤ hi, its tables' values
    and names; waypoints at nodes of a fixed horizon. Without phases, the problem's own
    waypoints (its horizon must then be fixed)."""
    problems: list = []
    prefix = _prefix(words)
    if not statement.phases:
        return _waypoint_problems(statement, statement.intervals, f"{prefix}waypoints", known, problems)
    if statement.waypoints:
        problems.append(f"{prefix}waypoints: with phases, each phase states its own waypoints (times "
                        "from its start)")
    for i, phase in enumerate(statement.phases):
        where = f"{prefix}phases[{i}]" + (f" ({phase.name})" if phase.name else "")
        N = phase.intervals
        if isinstance(N, bool) or not isinstance(N, numbers.Integral) or not 1 <= N <= MAX_INTERVALS:
            problems.append(f"{where}.intervals = {N!r} must be an integer from 1 to {MAX_INTERVALS}")
        try:
            if not (float(phase.horizon) > 0 and math.isfinite(float(phase.horizon))):
                problems.append(f"{where}.horizon = {phase.horizon!r} must be positive and finite")
        except (TypeError, ValueError):
            problems.append(f"{where}.horizon = {phase.horizon!r} is not a number")
        if phase.free_horizon is not None:
            lo, hi = interval(phase.free_horizon, f"{where}.free_horizon", problems, words)
            if not lo > 0:
                problems.append(f"{where}.free_horizon: lower bound {lo:g} must be positive")
        for key, mapping in (("final", phase.final), ("state_bounds", phase.state_bounds)):
            for name, value in mapping.items():
                problems += ((_misplaced(name, inputs, known, f"{where}.{words.field(key)}",
                                          f"{where}.{words.field('control_bounds')}")
                              if key == "state_bounds" else [])
                             or _unknown(name, known, words.unknown_quantity,
                                         f"{where[len(prefix):]}.{words.field(key)}"))
                interval(value, f"{where}.{key}[{name!r}]", problems, words)
        for name, value in phase.control_bounds.items():
            problems += (_misplaced(name, known, inputs, f"{where}.{words.field('control_bounds')}",
                                    f"{where}.{words.field('state_bounds')}")
                         or _unknown(name, inputs, words.unknown_input,
                                     f"{where[len(prefix):]}.{words.field('control_bounds')}",
                                     label="inputs"))
            interval(value, f"{where}.control_bounds[{name!r}]", problems, words)
        _waypoint_problems(phase, N, f"{where}.waypoints", known, problems)
    return problems


def _prefix(words: Wording) -> str:
    """What starts a place in ``words`` ("[task]." for a task table, "" for a problem's keywords)."""
    return words.place.split("{field}")[0]


def _waypoint_problems(owner, intervals, where, known, problems) -> list:
    """The problems of the waypoints of ``owner`` (a statement or a phase: its ``waypoints``,
    ``horizon`` and ``free_horizon``) on ``intervals`` intervals, appended to ``problems``."""
    horizon, free_horizon = owner.horizon, owner.free_horizon
    for j, point in enumerate(owner.waypoints):
        at = f"{where}[{j}]" + (f" ({point.name})" if point.name else "")
        for name, value in point.conditions.items():
            problems += _unknown(name, known, "{field}: unknown name {name!r}{hint}", at)
            interval(value, f"{at}[{name!r}]", problems)
        if point.time is None:           # no time (said by the reader of the table)
            continue
        if free_horizon is not None:
            problems.append(f"{at}: a waypoint at a given time needs a fixed horizon (a waypoint at a "
                            "free time is the end of a phase: phases = [...])")
            continue
        try:
            t, T, N = float(point.time), float(horizon), int(intervals)
        except (TypeError, ValueError):
            problems.append(f"{at}: time {point.time!r} is not a number")
            continue
        k = t * N / T
        if not 0 < t < T:
            problems.append(f"{at}: time {t:g} is not between the ends (0, {T:g})")
        elif abs(k - round(k)) > NODE_TOLERANCE * max(1.0, k):
            h = T / N
            problems.append(f"{at}: time {t:g} is not a node (every {h:g} s with T = {T:g}, N = {N}): "
                            f"the nearest nodes are {math.floor(k) * h:g} and {math.ceil(k) * h:g}")
    return problems


def instant_problems(statement: ProblemStatement, motion, prefix: str = "") -> list:
    """A quantity of the inputs or accelerations (a name in ``motion``) is a path bound or an
    integrand only: never a condition at one instant (an end, a waypoint, periodicity).
    ``prefix`` starts each place ("[task]." for a task table)."""
    motion = set(motion)
    places = [(f"{prefix}initial", statement.initial), (f"{prefix}final", statement.final),
              (f"{prefix}periodic", dict.fromkeys(statement.periodic))]
    places += [(f"{prefix}waypoints[{i}]", w.conditions) for i, w in enumerate(statement.waypoints)]
    for i, phase in enumerate(statement.phases):
        places += [(f"{prefix}phases[{i}].final", phase.final)]
        places += [(f"{prefix}phases[{i}].waypoints[{j}]", w.conditions)
                   for j, w in enumerate(phase.waypoints)]
    return [f"{where}: {name!r} depends on the inputs or accelerations: it can be bounded on the path "
            "(bounds) or integrated (integrals), not fixed at one instant"
            for where, mapping in places for name in mapping if name in motion]


def waypoint_node(point: Waypoint, horizon: float, intervals: int) -> int:
    """The node k = t_w N / T of a waypoint (checked by :func:`phase_problems`)."""
    return int(round(float(point.time) * int(intervals) / float(horizon)))


# ----------------------------------------------------------------------------- the statement
@dataclass(frozen=True)
class ProblemStatement:
    """What an optimal control problem says (see :mod:`nhgait.ocp.problem` for the maths).

    Parameters
    ----------
    model : the model the problem is stated on; None for a statement not yet bound to one (a
        gait task's, :class:`nhgait.gaits.tasks.statement.Task`)
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
    waypoints : sequence of :class:`Waypoint` — conditions at given times (nodes) between the ends
    integrals : mapping name → quantity name: an integral state I(t) = I(0) + ∫₀ᵗ y(z, u) dt of
        the quantity y (I(0) = 0 unless ``initial`` gives it), usable in every condition, bound
        and ``end_weights``
    phases : sequence of :class:`Phase` — a multi-phase problem (the phases joined at shared
        nodes); ``horizon``, ``intervals`` and ``free_horizon`` are then their sums (set here)
    end_weights : mapping name → w, adds Σ w y(T) (an integral's final value: a Lagrange term)

    Making a statement checks nothing: :meth:`problems` lists what is wrong with it in a
    reader's words (:class:`~nhgait.ocp.problem.OptimalControlProblem` and
    :func:`nhgait.gaits.tasks.statement.parse_task` raise them in one ProblemError).
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
    waypoints: tuple = ()
    integrals: Mapping = field(default_factory=dict)
    phases: tuple = ()
    end_weights: Mapping = field(default_factory=dict)

    def __post_init__(self):
        for key in ("initial", "final", "state_bounds", "control_weights", "state_weights", "integrals",
                    "end_weights"):
            object.__setattr__(self, key, FrozenMap(getattr(self, key)))
        if isinstance(self.control_bounds, Mapping):
            object.__setattr__(self, "control_bounds", FrozenMap(self.control_bounds))
        for key in ("periodic", "waypoints", "phases"):
            object.__setattr__(self, key, tuple(getattr(self, key)))
        if self.phases:
            self._sum_phases()

    def _sum_phases(self) -> None:
        """horizon, intervals and free_horizon of a multi-phase statement: the phases' sums."""
        try:
            horizon = sum(float(p.horizon) for p in self.phases)
            intervals = sum(int(p.intervals) for p in self.phases)
        except (TypeError, ValueError):
            return                                   # reported by phase_problems
        free = None
        if any(p.free_horizon is not None for p in self.phases):
            bounds = [interval(p.free_horizon) if p.free_horizon is not None else (float(p.horizon),) * 2
                      for p in self.phases]
            free = (sum(b[0] for b in bounds), sum(b[1] for b in bounds))
        object.__setattr__(self, "horizon", horizon)
        object.__setattr__(self, "intervals", intervals)
        object.__setattr__(self, "free_horizon", free)

    def problems(self, words: Wording = OCP_WORDS, known=None, inputs=None) -> list:
        """Every problem of the statement, in ``words``: its form (no model needed) and, given
        ``known`` (the quantity names) and ``inputs`` (the input names), its names."""
        with_integrals = None if known is None else tuple(known) + tuple(self.integrals)
        return (horizon_problems(self, words) + intervals_problems(self, words)
                + free_horizon_problems(self, words)
                + table_problems(self, words, with_integrals, inputs)
                + consistency_problems(self, words, with_integrals)
                + phase_problems(self, words, with_integrals, inputs) + integral_problems(self, words, known))

    def statement_fields(self) -> dict:
        """The statement's fields after ``model`` (keyword arguments of a problem)."""
        return {key: getattr(self, key) for key in STATEMENT_FIELDS}
