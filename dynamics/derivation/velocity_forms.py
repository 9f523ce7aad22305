"""Reading L and the constraints as polynomials in the velocities, without differentiating.

A user's Lagrangian is usually written from bodies — ``m*((x_dot - a*theta_dot*sin(theta))**2
+ ...)/2`` — and each constraint as a sum of velocity terms. Both are then polynomials in q̇
whose coefficients are free of q̇, and reading those coefficients off the expression tree is a
single pass, where ∂²L/∂q̇² costs n² symbolic derivatives and the structural check of
eq. 2.6 by differentiation n + n² + n³ (1.9 s of the start-up of a car with six trailers,
n = 10). :func:`velocity_polynomial` does the reading; :func:`quadratic_split` (L = ½q̇ᵀMq̇ − V,
eq. 2.6) and :func:`linear_split` (ω(q)q̇, eq. 2.11) use it. Each returns None when the
expression is not written so (a velocity inside a function, a power above two): the callers
then differentiate, and their checks name the problem.
"""
from __future__ import annotations

from typing import NamedTuple

import sympy as sp

__all__ = ["velocity_polynomial", "linear_split", "quadratic_split", "QuadraticSplit"]


def velocity_polynomial(expr, q_dot, degree: int = 2) -> dict | None:
    """``expr`` (a sympy expression) as Σ c_m q̇^m over monomials m of degree ≤ ``degree``:
    {m: c_m} with m a sorted tuple of velocity indices (``()`` the velocity-free part, ``(i,)``,
    ``(i, j)``) and every c_m free of the velocities — read off sums, products and integer
    powers, the velocity-free subexpressions kept whole. None when ``expr`` is not such a
    polynomial as written."""
    index = {v: i for i, v in enumerate(q_dot)}
    return _read(expr, index, frozenset(index), degree)


def _read(expr, index, velocities, degree):
    if not expr.free_symbols & velocities:
        return {(): expr}
    if expr in index:
        return {(index[expr],): sp.Integer(1)} if degree >= 1 else None
    if expr.is_Add:
        out: dict = {}
        for arg in expr.args:
            part = _read(arg, index, velocities, degree)
            if part is None:
                return None
            _accumulate(out, part)
        return out
    if expr.is_Mul:
        free = [f for f in expr.args if not f.free_symbols & velocities]
        out = {(): sp.Mul(*free)}
        for factor in expr.args:
            if factor.free_symbols & velocities:
                out = _times(out, _read(factor, index, velocities, degree), degree)
                if out is None:
                    return None
        return out
    if expr.is_Pow and expr.exp.is_Integer and 0 < expr.exp <= degree:
        base = _read(expr.base, index, velocities, degree)
        out = base
        for _ in range(int(expr.exp) - 1):
            out = _times(out, base, degree)
        return out
    return None


def _accumulate(out: dict, part: dict) -> None:
    for m, c in part.items():
        out[m] = out[m] + c if m in out else c


def _times(a: dict | None, b: dict | None, degree: int) -> dict | None:
    if a is None or b is None:
        return None
    out: dict = {}
    for ma, ca in a.items():
        for mb, cb in b.items():
            if len(ma) + len(mb) > degree:
                return None
            _accumulate(out, {tuple(sorted(ma + mb)): ca * cb})
    return out


def linear_split(c, q_dot):
    """The coefficients [ω_1 … ω_n] of ``c`` written as Σ ω_i q̇_i (eq. 2.11: a Pfaffian row),
    read off the expression (:func:`velocity_polynomial`); None when ``c`` is not so written,
    has a velocity-free term, or no velocity at all."""
    poly = velocity_polynomial(c, q_dot, degree=1)
    if poly is None or sp.expand(poly.get((), 0)) != 0:
        return None
    row = [poly.get((i,), sp.Integer(0)) for i in range(len(q_dot))]
    return row if any(r != 0 for r in row) else None


class QuadraticSplit(NamedTuple):
    """L = ½q̇ᵀ``M``q̇ − ``V``, read off term by term."""

    M: object
    V: object


def quadratic_split(L, q_dot) -> QuadraticSplit | None:
    """(M, V) of L = ½q̇ᵀMq̇ − V (eq. 2.6) read off L (:func:`velocity_polynomial`): M_ii twice
    the coefficient of q̇_i², M_ij = M_ji that of q̇_i q̇_j, V minus the velocity-free part; no
    differentiation. None when L is not so written or has a term linear in the velocities
    that does not vanish on expansion (then M = ∂²L/∂q̇² is differentiated and the structural
    check names the problem)."""
    poly = velocity_polynomial(L, q_dot, degree=2)
    if poly is None:
        return None
    if any(len(m) == 1 and sp.expand(c) != 0 for m, c in poly.items()):
        return None
    n = len(q_dot)
    M = [[sp.Integer(0)] * n for _ in range(n)]
    for m, c in poly.items():
        if len(m) == 2:
            i, j = m
            if i == j:
                M[i][i] = 2 * c
            else:
                M[i][j] = M[j][i] = c
    return QuadraticSplit(sp.Matrix(M), -poly.get((), sp.Integer(0)))
