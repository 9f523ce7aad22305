"""Printed equations with repeated sub-expressions named once (common-subexpression
elimination, :func:`sympy.cse`), as ``nhgait derive --cse`` prints them::

    where
      w1 = I_c*m + I_c*m_s + a**2*m**2 + a**2*m*m_s + m*m_s*s**2
      w2 = m + m_s
    dx/dt = p*cos(theta)/w2 + m_s*s*cos(theta)*(pt_theta - b*pt_s)/w1
    …

Sub-expressions of at most :data:`MIN_OPS` operations (``cos(theta)``, ``m + m_s`` when used
once) are put back: a name must save reading, not add a look-up. The names ``w1, w2 …`` are
chosen to differ from every symbol of the equations. :func:`wants_cse` is the default rule of
the command line: on when the plain text is long.
"""
from __future__ import annotations

from typing import NamedTuple

import sympy as sp

__all__ = ["cse_lines", "equation_lines", "wants_cse", "LONG_TEXT"]

#: plain equations longer than this (characters in all) are printed with named sub-expressions
LONG_TEXT = 1500
#: named sub-expressions of at most this many operations are substituted back
MIN_OPS = 2


def wants_cse(lines) -> bool:
    """The default: name sub-expressions when the plain equations are long."""
    return sum(len(line) for line in lines) > LONG_TEXT


def _fresh_names(taken: set, prefix: str = "w"):
    k = 1
    while True:
        name = f"{prefix}{k}"
        if name not in taken:
            yield sp.Symbol(name, real=True)
        k += 1


class Subexpressions(NamedTuple):
    """The result of :func:`named_subexpressions`."""

    definitions: list    #: [(name, expr)] in order of use
    reduced: list        #: the expressions rewritten in the names


def named_subexpressions(exprs) -> Subexpressions:
    """(definitions [(name, expr)], exprs rewritten in the names): :func:`sympy.cse` with the
    short sub-expressions put back and the names renumbered w1, w2 … in order of use."""
    exprs = list(exprs)                      # sympy expressions of the models (no user text)
    taken = {s.name for e in exprs for s in e.free_symbols}
    replacements, reduced = sp.cse(exprs, symbols=_fresh_names(taken), order="none")
    kept, back = [], {}
    for sym, sub in replacements:
        sub = sub.xreplace(back)
        uses = sum(e.count(sym) for e in reduced) + sum(s.count(sym) for _, s in replacements)
        if sp.count_ops(sub) <= MIN_OPS and uses <= 2 or sp.count_ops(sub) <= 1:
            back[sym] = sub
        else:
            kept.append((sym, sub))
    renamed = {old: new for (old, _), new in zip(kept, _fresh_names(taken), strict=False)}
    definitions = [(renamed[sym], sub.xreplace(renamed)) for sym, sub in kept]
    return Subexpressions(definitions, [e.xreplace(back).xreplace(renamed) for e in reduced])


def cse_lines(lefts, exprs, *, printer=sp.sstr, indent: str = "  ") -> list:
    """``["where", "  w1 = …", …, "<left> = …", …]``: the definitions, then one line per
    equation ``left = expr`` (``lefts`` are text) with the names substituted."""
    definitions, reduced = named_subexpressions(exprs)
    lines = ["where"] if definitions else []
    lines += [f"{indent}{printer(name)} = {printer(sub)}" for name, sub in definitions]
    return lines + [f"{left} = {printer(e)}" for left, e in zip(lefts, reduced, strict=True)]


def equation_lines(lefts, rights, cse: bool | None = None, *, indent: str = "  ") -> list:
    """``left = right`` lines, indented; with ``cse`` (None: when long) both sides share
    named sub-expressions."""
    plain = [f"{indent}{sp.sstr(a)} = {sp.sstr(b)}" for a, b in zip(lefts, rights, strict=True)]
    if not (cse or (cse is None and wants_cse(plain))):
        return plain
    definitions, reduced = named_subexpressions(list(lefts) + list(rights))
    n = len(lefts)
    lines = [f"{indent}where"] if definitions else []
    lines += [f"{indent}  {sp.sstr(name)} = {sp.sstr(sub)}" for name, sub in definitions]
    return lines + [f"{indent}{sp.sstr(a)} = {sp.sstr(b)}"
                    for a, b in zip(reduced[:n], reduced[n:], strict=True)]
