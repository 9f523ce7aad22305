"""The values of a ``[task]`` table as data: numbers, ranges, name tables and lists, horizons.

Every parser appends what is wrong to ``problems`` (in the words of the table, at ``where``:
"[task]", "[task].phases[1]", …) and returns a usable value, so that one
:class:`~nhgait.ocp.ProblemError` lists every problem. A value is a number, a constant
expression such as ``"pi/2"`` (parsed by
:func:`nhgait.dynamics.derivation.input.expressions.number_problems`, never evaluated as code), or
``[lo, hi]`` for a range (``"inf"``/``"-inf"`` for one-sided).
"""
from __future__ import annotations

import math
from collections.abc import Mapping

__all__ = ["number", "value", "table", "names_list", "horizon", "control_bounds"]


def number(text, where, problems, *, allow_inf=False) -> float:
    """A number or constant expression (NaN when it is none, reported)."""
    from nhgait.dynamics.derivation.input.expressions import number_problems
    if allow_inf and (text in ("inf", "+inf", "-inf") or (isinstance(text, float) and math.isinf(text))):
        return float(text)
    return number_problems(text, where, problems)


def value(item, where, problems):
    """A number or a [lo, hi] range (its order is the statement's to check)."""
    if isinstance(item, (list, tuple)):
        if len(item) != 2:
            problems.append(f"{where}: a range is [lo, hi], got {len(item)} entries")
            return (-math.inf, math.inf)
        return (number(item[0], f"{where} lower bound", problems, allow_inf=True),
                number(item[1], f"{where} upper bound", problems, allow_inf=True))
    return number(item, where, problems)


def table(data, key, problems, where: str = "[task]") -> dict:
    """``data[key]``: a table of name = value (``bounds``: ranges only)."""
    item = data.get(key, {})
    if not isinstance(item, Mapping):
        problems.append(f"{where}.{key} must be a table of name = value, got {type(item).__name__} {item!r}")
        return {}
    out = {}
    for name, v in item.items():
        if key == "bounds" and not isinstance(v, (list, tuple)):     # said once, not then used as
            problems.append(f"{where}.bounds.{name}: a path bound is a range [lo, hi], got {v!r}")   # [v, v]
            continue
        out[str(name)] = value(v, f"{where}.{key}.{name}", problems)
    return out


def names_list(data, key, problems, *, repeats: bool = True, where: str = "[task]") -> tuple[str, ...]:
    """``data[key]``: a list of names (repeats refused unless ``repeats`` is False)."""
    item = data.get(key, [])
    if isinstance(item, str) or not isinstance(item, (list, tuple)) or not all(isinstance(v, str)
                                                                               for v in item):
        problems.append(f"{where}.{key} must be a list of names such as [\"psi\", \"phi_dot\"], got {item!r}")
        return ()
    if repeats and len(set(item)) != len(item):
        problems.append(f"{where}.{key}: repeated names in {list(item)}")
    return tuple(item)


def horizon(data, problems, where: str = "[task]"):
    """(T, bounds or None) from ``horizon`` (None for T when it is missing): a number of
    seconds, ``[min, max]`` (free, T the middle) or ``{initial, min, max}``; the bounds' order
    is the statement's to check."""
    if "horizon" not in data:
        problems.append(f"{where}: missing key 'horizon' (a number of seconds, or [min, max] for a "
                        "free horizon)")
        return None, None
    item = data["horizon"]
    if isinstance(item, Mapping):
        unknown = set(item) - {"initial", "min", "max"}
        if unknown or not {"min", "max"} <= set(item):
            problems.append(f"{where}.horizon as a table needs min and max (and optionally initial), "
                            f"got keys {sorted(item)}")
            return None, None
        lo = number(item["min"], f"{where}.horizon.min", problems)
        hi = number(item["max"], f"{where}.horizon.max", problems)
        T = number(item.get("initial", (lo + hi) / 2), f"{where}.horizon.initial", problems)
        if 0 < lo <= hi and not lo <= T <= hi:
            problems.append(f"{where}.horizon: initial {T:g} outside [{lo:g}, {hi:g}]")
        return T, (lo, hi)
    if isinstance(item, (list, tuple)):
        if len(item) != 2:
            problems.append(f"{where}.horizon: a free horizon is [min, max], got {len(item)} entries")
            return None, None
        lo = number(item[0], f"{where}.horizon min", problems)
        hi = number(item[1], f"{where}.horizon max", problems)
        return (lo + hi) / 2, (lo, hi)
    T = number(item, f"{where}.horizon", problems)
    return (None if math.isnan(T) else T), None         # a value that is no number is reported once


def control_bounds(data, problems, where: str = "[task]"):
    """``control_bounds``: a table of input = [lo, hi] or b (|u| ≤ b), or one number b for
    every input."""
    item = data.get("control_bounds", {})
    if isinstance(item, Mapping):
        out = {}
        for name, v in item.items():
            out[str(name)] = value(v, f"{where}.control_bounds.{name}", problems)
            if not isinstance(out[str(name)], tuple):
                b = abs(out[str(name)])
                out[str(name)] = (-b, b)
        return out
    b = number(item, f"{where}.control_bounds", problems)
    if not b > 0:
        problems.append(f"{where}.control_bounds = {item!r} must be a positive number or a table")
    return abs(b)
