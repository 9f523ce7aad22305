"""Rational functions as fractions of one sparse polynomial ring over ℚ: the evaluation both the
trig normal form (:mod:`.trig`) and the fraction field of the reduction (:mod:`.fraction_field`)
rest on.

A sympy expression is read as num/den of polynomials in its *generators* — symbols, sin/cos of
symbols, opaque subexpressions (:func:`collect_generators`) — by one walk of its tree with no
intermediate gcd (:func:`walk_fraction`, :func:`to_field`); sums over equal denominators are
added first (:func:`add_fractions`); sin² is reduced to 1 − cos² (:func:`reduce_poly`). A node
the ring cannot hold raises :class:`NotRational`; a derivation over its work budget raises
:class:`WorkBudgetExceeded`.
"""
from __future__ import annotations

from typing import NamedTuple

import sympy as sp

__all__ = ["NotRational", "WorkBudgetExceeded", "reduce_poly", "collect_generators", "add_fractions",
           "float_rational", "walk_fraction", "to_field", "RingFraction"]


class NotRational(Exception):
    """An expression the exact rational back end cannot represent (a trig function of a
    non-angle, a power with a symbolic exponent, ...): the sympy back end takes over."""


class WorkBudgetExceeded(Exception):
    """The exact arithmetic exceeded its work budget (the caller then uses the implicit form)."""


def reduce_poly(poly, pairs):
    """Reduce a PolyElement modulo S² + C² − 1 for each (index S, index C) pair: S² → 1 − C²."""
    if not pairs:
        return poly
    ring = poly.ring
    out = ring.zero
    one = ring.one
    for monom, coeff in poly.terms():
        mon = list(monom)
        factor = one
        for iS, iC in pairs:
            k = mon[iS]
            if k >= 2:
                mon[iS] = k % 2
                factor = factor * (one - ring.gens[iC] ** 2) ** (k // 2)
        out += ring({tuple(mon): coeff}) * factor
    return out


def collect_generators(e, gens: dict):
    """Generators of ``e`` as a rational function: symbols and opaque subexpressions."""
    if e.is_Symbol:
        gens.setdefault(e, None)
    elif isinstance(e, (sp.sin, sp.cos)) and e.args[0].is_Symbol:
        gens.setdefault(e, None)
    elif e.is_Rational:
        return
    elif e.is_Float:
        return
    elif e.is_Add or e.is_Mul:
        for a in e.args:
            collect_generators(a, gens)
    elif e.is_Pow and e.exp.is_Integer:
        collect_generators(e.base, gens)
    elif e.is_Number or e.is_NumberSymbol:
        gens.setdefault(e, None) if not e.is_Rational else None
    else:
        if any(s.is_Symbol for s in e.free_symbols):
            gens.setdefault(e, None)
        else:
            gens.setdefault(e, None)


def add_fractions(terms, zero, one):
    """Σ num/den over fractions of one ring, as a pair (num, den) — the representation of an
    element of :class:`~.fraction_field.FracField`: equal denominators are summed first, so a
    sum over a common denominator costs no multiplication of denominators."""
    groups: list = []
    for nmr, dnm in terms:
        if not nmr:
            continue
        for i, (gd, gn) in enumerate(groups):
            if gd is dnm or gd == dnm:
                groups[i] = (gd, gn + nmr)
                break
        else:
            groups.append((dnm, nmr))
    if not groups:
        return (zero, one)
    den, num = groups[0]
    for dnm, nmr in groups[1:]:
        num, den = num * dnm + nmr * den, den * dnm
    return (num, den)


def float_rational(x):
    """The rational a Float stands for: for a double (a number written in a scene, 0.1) the
    shortest decimal that rounds to it (1/10, which evaluates to the same double), otherwise
    its exact binary value."""
    if x._prec <= 53:
        from fractions import Fraction
        f = Fraction(repr(float(x)))
        return sp.Rational(f.numerator, f.denominator)
    return sp.Rational(x)


def walk_fraction(e, R, table: dict):
    """Evaluate the sympy expression ``e`` as a fraction (num, den) of the ring ``R``, where
    ``table`` maps every generator (symbol, sin/cos, opaque subexpression) to its fraction.
    No gcd is taken on the way; raises ``NotRational`` for a node it cannot represent."""
    from sympy.polys.domains import QQ
    one = R.one
    memo: dict = {}

    def ev(x):
        got = table.get(x)
        if got is not None:
            return got
        got = memo.get(x)
        if got is not None:
            return got
        if x.is_Rational:
            out = (R(QQ(int(x.p), int(x.q))), one)
        elif x.is_Float:
            r = float_rational(x)
            out = (R(QQ(int(r.p), int(r.q))), one)
        elif x.is_Add:
            out = add_fractions([ev(a) for a in x.args], R.zero, one)
        elif x.is_Mul:
            num, den = one, one
            for a in x.args:
                an, ad = ev(a)
                num, den = num * an, den * ad
            out = (num, den)
        elif x.is_Pow and x.exp.is_Integer:
            bn, bd = ev(x.base)
            k = int(x.exp)
            if k < 0:
                if not bn:
                    raise ZeroDivisionError(f"division by zero in {e}")
                out = (bd ** (-k), bn ** (-k))
            else:
                out = (bn ** k, bd ** k)
        else:
            raise NotRational
        memo[x] = out
        return out

    return ev(e)


class RingFraction(NamedTuple):
    """An expression as ``num``/``den``, polynomials of the sparse ``ring`` over ℚ."""

    ring: object
    num: object
    den: object


def to_field(e, extra) -> RingFraction:
    """Evaluate ``e`` as a fraction num/den of sparse polynomials over QQ in the generators of
    ``e`` (plus ``extra``), walking the tree without intermediate gcds (one cancellation at
    the end is cheaper than one per operation)."""
    from sympy.polys.domains import QQ
    from sympy.polys.rings import ring as make_ring
    gens: dict = {}
    collect_generators(e, gens)
    for x in extra:
        gens.setdefault(x, None)
    order = sorted(gens, key=sp.default_sort_key)
    if not order:
        raise NotRational
    R, *g = make_ring(order, QQ)
    num, den = walk_fraction(e, R, {k: (v, R.one) for k, v in zip(order, g, strict=True)})
    return RingFraction(R, num, den)
