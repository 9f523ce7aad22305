"""Sweep grids: axes over task values and parameters, grid points and their continuation order.

An axis is written ``NAME=SPEC`` (``nhgait sweep --grid``):

* ``NAME`` is a task value — ``horizon``, ``intervals``, ``control_bounds``,
  ``initial.<name>``, ``final.<name>``, ``objective.<weight>`` — or a parameter,
  ``params.<name>``;
* ``SPEC`` is ``lo:hi:n`` (n evenly spaced values from lo to hi, both included), a list
  ``a,b,c`` or one value ``a``. Each number is a TOML-style number or a constant expression
  (``pi/2``, ``2*sqrt(2)``) read by :func:`nhgait.dynamics.derivation.input.expressions.number_problems` —
  data, never evaluated as code; ``n`` is a whole number ≥ 2.

Every problem of every axis (syntax, unknown kinds of name, repeated axes, counts, values
that cannot hold such as a negative horizon) is listed in one :class:`~nhgait.ocp.ProblemError`.

Continuation order
------------------
Each point is warm-started from a *parent*, a neighbour one grid step closer to the centre
point c of the grid (indices ⌊(n_k − 1)/2⌋): with the axes taken longest first, the parent of
p ≠ c moves the first index that differs from c one step towards it. The parents form a tree
rooted at c (depth Σ_k |p_k − c_k|); the centre is solved cold, its neighbours along the last
axes form a short spine and the longest axis is covered by chains running outwards in both
directions, which keeps independent work for every worker after a few points.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

from nhgait.dynamics.suggestions import known_names
from nhgait.ocp import ProblemError

__all__ = ["Axis", "Grid", "GridPoint", "parse_axis", "parse_grid", "TASK_AXES", "TABLE_AXES"]

#: axis names that are task values on their own
TASK_AXES = ("horizon", "intervals", "control_bounds")
#: prefixes ``<table>.<name>`` of axes naming one entry of a task table, or a parameter
TABLE_AXES = ("initial", "final", "objective", "params")
_MAX_POINTS = 1_000_000


@dataclass(frozen=True)
class Axis:
    """One grid axis: ``name`` (``final.x``, ``horizon``, ``params.J_r``) and its values."""

    name: str
    values: tuple

    @property
    def is_parameter(self) -> bool:
        return self.name.startswith("params.")

    @property
    def key(self) -> str:
        """The task key or parameter name the axis sets (``x`` of ``final.x``)."""
        return self.name.partition(".")[2] or self.name

    def __len__(self) -> int:
        return len(self.values)


@dataclass(frozen=True)
class GridPoint:
    """One point: its index on every axis, the values and the id used by the store."""

    index: tuple
    values: tuple            # ((axis name, value), ...) in axis order

    @property
    def id(self) -> str:
        return "-".join(str(i) for i in self.index)

    def value(self, name: str) -> float:
        return dict(self.values)[name]


@dataclass(frozen=True)
class Grid:
    """The Cartesian product of its axes (C order: the last axis varies fastest)."""

    axes: tuple

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a) for a in self.axes)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    @property
    def size(self) -> int:
        return int(math.prod(self.shape))

    def axis(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise ProblemError([f"no grid axis {name!r} (axes: {', '.join(self.names)})"],
                           title="invalid grid axis")

    def point(self, index) -> GridPoint:
        index = tuple(int(i) for i in index)
        return GridPoint(index, tuple((a.name, a.values[i]) for a, i in zip(self.axes, index, strict=True)))

    def points(self) -> Iterator[GridPoint]:
        for index in itertools.product(*(range(n) for n in self.shape)):
            yield self.point(index)

    @property
    def centre(self) -> tuple[int, ...]:
        return tuple((n - 1) // 2 for n in self.shape)

    def parent(self, index) -> tuple | None:
        """The neighbour ``index`` is warm-started from (see the module docstring); None at the centre."""
        centre = self.centre
        for k in sorted(range(len(self.axes)), key=lambda k: -self.shape[k]):   # stable: ties keep axis order
            if index[k] != centre[k]:
                step = 1 if index[k] < centre[k] else -1
                return tuple(i + step if j == k else i for j, i in enumerate(index))
        return None

    def to_dict(self) -> dict:
        return {"axes": [{"name": a.name, "values": list(a.values)} for a in self.axes]}

    @classmethod
    def from_dict(cls, data: Mapping) -> Grid:
        return cls(tuple(Axis(a["name"], tuple(a["values"])) for a in data["axes"]))


# ----------------------------------------------------------------------------- parsing
def _check_name(name: str, where: str, problems: list) -> None:
    table, dot, key = name.partition(".")
    if not dot:
        if name not in TASK_AXES:
            problems.append(f"{where}: unknown axis {name!r} (use {', '.join(TASK_AXES)}, or "
                            f"{', '.join(t + '.<name>' for t in TABLE_AXES)})")
    elif table not in TABLE_AXES or not key or "." in key or not key.isidentifier():
        problems.append(f"{where}: unknown axis {name!r} (use {', '.join(TASK_AXES)}, or "
                        f"{', '.join(t + '.<name>' for t in TABLE_AXES)} with a plain name)")


def _count(text: str, where: str, problems: list) -> int:
    text = text.strip()
    if not text.isdigit() or int(text) < 2:
        problems.append(f"{where}: the number of values in lo:hi:n must be a whole number ≥ 2, got {text!r}")
        return 0
    if int(text) > _MAX_POINTS:
        problems.append(f"{where}: {text} values on one axis is more than {_MAX_POINTS}")
        return 0
    return int(text)


def _values(spec: str, where: str, problems: list) -> tuple:
    from nhgait.dynamics.derivation.input.expressions import number_problems
    if not spec.strip():
        problems.append(f"{where}: no values (use lo:hi:n, a,b,c or one value)")
        return ()
    parts = spec.split(":")
    if len(parts) == 3:
        before = len(problems)
        lo = number_problems(parts[0].strip(), f"{where} lower end", problems)
        hi = number_problems(parts[1].strip(), f"{where} upper end", problems)
        n = _count(parts[2], where, problems)
        if len(problems) > before:
            return ()
        if lo == hi:
            problems.append(f"{where}: lower and upper end are both {lo:g} (give one value instead)")
            return ()
        return tuple(float(v) for v in np.linspace(lo, hi, n))
    if len(parts) != 1:
        problems.append(f"{where}: expected lo:hi:n, a,b,c or one value, got {spec!r}")
        return ()
    items = [s.strip() for s in spec.split(",")]
    values = tuple(number_problems(s, f"{where} value {i + 1}", problems) for i, s in enumerate(items))
    if len(set(values)) != len(values) and not any(math.isnan(v) for v in values):
        problems.append(f"{where}: repeated values in {spec!r}")
    return values


def _value_problems(axis: Axis, where: str, problems: list) -> None:
    """Values that cannot hold whatever the task: T ≤ 0, N not a whole number ≥ 1, bounds ≤ 0."""
    if axis.name == "horizon" and any(v <= 0 for v in axis.values):
        problems.append(f"{where}: a horizon must be positive, got {min(axis.values):g}")
    if axis.name == "intervals" and any(v < 1 or v != int(v) for v in axis.values):
        problems.append(f"{where}: intervals must be whole numbers ≥ 1, got {list(axis.values)}")
    if axis.name == "control_bounds" and any(v <= 0 for v in axis.values):
        problems.append(f"{where}: a control bound must be positive, got {min(axis.values):g}")
    if axis.name.startswith("objective.") and any(v < 0 for v in axis.values):
        problems.append(f"{where}: objective weights must be ≥ 0, got {min(axis.values):g}")


def parse_axis(text: str, problems: list, *, where: str | None = None) -> Axis | None:
    """One ``NAME=SPEC`` axis (see the module docstring); problems are appended, None returned."""
    where = where or f"--grid {text!r}"
    if not isinstance(text, str):
        problems.append(f"{where}: expected NAME=SPEC text, got {type(text).__name__}")
        return None
    name, sep, spec = text.partition("=")
    name = name.strip()
    if not sep or not name:
        problems.append(f"{where}: expected NAME=lo:hi:n (e.g. final.x=0.2:2.0:10)")
        return None
    before = len(problems)
    _check_name(name, where, problems)
    values = _values(spec, where, problems)
    if len(problems) > before:
        return None
    axis = Axis(name, values)
    _value_problems(axis, where, problems)
    return axis if len(problems) == before else None


def parse_grid(axes, *, parameters: tuple | None = None) -> Grid:
    """A :class:`Grid` from ``NAME=SPEC`` texts (or a mapping name → values).

    ``parameters``: the system's parameter names; ``params.<name>`` axes must name one.
    Raises one :class:`~nhgait.ocp.ProblemError` listing every problem.
    """
    problems: list = []
    if isinstance(axes, Mapping):
        axes = [f"{name}={','.join(repr(float(v)) for v in np.atleast_1d(values))}"
                for name, values in axes.items()]
    if isinstance(axes, str) or not axes:
        raise ProblemError([f"a sweep needs at least one axis NAME=lo:hi:n, got {axes!r}"],
                           title="invalid grid")
    parsed = [parse_axis(text, problems) for text in axes]
    names = [str(text).partition("=")[0].strip() for text in axes if "=" in str(text)]
    for name in sorted({n for n in names if names.count(n) > 1}):
        problems.append(f"axis {name!r} is given {names.count(name)} times")
    if parameters is not None:
        for a in parsed:
            if a is not None and a.is_parameter and a.key not in parameters:
                problems.append(f"--grid {a.name}: unknown parameter {a.key!r}"
                                f"{known_names(a.key, parameters, label='parameters')}")
    size = math.prod(len(a) for a in parsed if a is not None)
    if size > _MAX_POINTS:
        problems.append(f"the grid has {size} points, more than {_MAX_POINTS}")
    if problems:
        raise ProblemError(problems, title="invalid sweep grid")
    return Grid(tuple(parsed))
