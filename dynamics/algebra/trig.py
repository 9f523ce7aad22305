"""The trig normal form: :func:`trig_normal` (canonical: a zero expression returns 0) and
:func:`tidy`, its memoised, size-capped use on every expression the derivations show.

sin(a) and cos(a) of each argument become generators of one sparse polynomial ring
(:mod:`.ring`), sin² → 1 − cos²; arguments that are not symbols are kept when independent of
the others (:func:`independent_arguments`), else ``trigsimp`` decides.
"""
from __future__ import annotations

from functools import lru_cache

import sympy as sp

from .ring import NotRational, reduce_poly, to_field

__all__ = ["has_trig", "TIDY_NODES", "tree_size", "tidy", "independent_arguments", "trig_normal",
           "forget_normal_forms"]

_TRIG = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)


def has_trig(expr) -> bool:
    return any(expr.has(f) for f in _TRIG)


#: expressions with more tree nodes than this are left as they are by :func:`tidy` (a system
#: built from bodies — the Whipple bicycle — has minors of 10⁵ nodes, whose normal form costs
#: minutes; the implicit form never needs it, the numeric steps see the same function)
TIDY_NODES = 6000


def tree_size(expr, limit: int) -> int:
    """Number of nodes of ``expr``'s tree, counted up to ``limit`` + 1 (cost O(limit))."""
    count = 0
    for _ in sp.preorder_traversal(expr):
        count += 1
        if count > limit:
            break
    return count


def tidy(expr):
    """Cheap, predictable simplification: trig identities where trig functions appear, then
    cancellation of rational factors. Keeps expressions readable without ``simplify``'s cost.
    Results are memoised (the same minors recur across candidates and steps). Expressions
    above :data:`TIDY_NODES` nodes are returned unchanged."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(tidy)
    if expr == 0 or expr.is_Number or expr.is_Symbol:
        return expr
    if tree_size(expr, TIDY_NODES) > TIDY_NODES:
        return expr
    return _tidy_scalar(expr)


@lru_cache(maxsize=8192)
def _tidy_scalar(expr):
    return trig_normal(expr)


def forget_normal_forms() -> None:
    """Empty the memo of :func:`tidy` (benchmarks of a cold derivation)."""
    _tidy_scalar.cache_clear()


def independent_arguments(args) -> bool:
    """True when sin a and cos a of every argument a in ``args`` can be generators of one
    polynomial ring whose only relations are sin²a + cos²a = 1.

    A symbol is such an argument; so is an expression that shares no symbol with any other
    argument (sin(2.5t) next to sin φ, cos φ; sin(x²) next to sin θ): it is then transcendental
    over the field of the other generators. Arguments that share a symbol (t and 2.5t, φ and
    φ/2) are related in a way sin² = 1 − cos² does not capture (sin 2.5t is no polynomial in
    sin t, cos t), and a constant argument (sin 1 next to sin ½) may be too: both are refused.
    """
    for a in args:
        if a.is_Symbol:
            continue
        free = a.free_symbols
        if not free or any(free & b.free_symbols for b in args if b != a):
            return False
    return True


def trig_normal(expr):
    """Normal form of a rational expression in sines and cosines.

    Trig functions are expanded to sin/cos of single symbols (``expand_trig``: sums and
    integer multiples of arguments are split); sin(a) and cos(a) become generators of a sparse
    polynomial ring over ℚ in which the expression is evaluated as a fraction (walking the
    tree, one gcd at the end); sin(a)² is reduced to 1 − cos(a)². An argument that is not a
    symbol after the expansion (sin(2.5t), sin(x²)) is kept as a generator when it is
    independent of the others (:func:`independent_arguments`); otherwise ``trigsimp`` is used.
    The result is canonical (a zero expression always returns 0) and costs only sparse
    polynomial arithmetic — orders of magnitude cheaper than ``trigsimp`` on the expressions of
    steps 15–19.
    """
    if not expr.free_symbols:
        return sp.nsimplify(expr) if expr.is_Float else sp.simplify(expr)
    e = expr
    if e.has(sp.tan, sp.cot, sp.sec, sp.csc):
        e = (e.replace(sp.tan, lambda a: sp.sin(a) / sp.cos(a))
             .replace(sp.cot, lambda a: sp.cos(a) / sp.sin(a)))
        e = e.replace(sp.sec, lambda a: 1 / sp.cos(a)).replace(sp.csc, lambda a: 1 / sp.sin(a))
    atoms = e.atoms(sp.sin, sp.cos)
    if any(not a.args[0].is_Symbol for a in atoms):
        e = sp.expand_trig(e)
        if not e.free_symbols:
            return sp.nsimplify(e) if e.is_Float else e
        atoms = e.atoms(sp.sin, sp.cos)
    args = sorted({a.args[0] for a in atoms}, key=sp.default_sort_key)
    if not independent_arguments(args):
        # related arguments expand_trig could not split (sin(t) and sin(2.5*t)): trigsimp
        return sp.factor_terms(sp.trigsimp(expr))
    pairs_expr = [(sp.sin(a), sp.cos(a)) for a in args]
    try:
        R, num, den = to_field(e, [x for pair in pairs_expr for x in pair])
    except NotRational:
        return sp.factor_terms(sp.cancel(e))
    syms = list(R.symbols)
    pairs = [(syms.index(S), syms.index(C)) for S, C in pairs_expr]
    num = reduce_poly(num, pairs)
    if not num:
        return sp.Integer(0)
    den = reduce_poly(den, pairs)
    num, den = num.cancel(den)
    num = reduce_poly(num, pairs)
    den = reduce_poly(den, pairs)
    num, den = num.cancel(den)
    return num.as_expr() / den.as_expr()
