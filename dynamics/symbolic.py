"""Small symbolic helpers shared by the derivations (no physics here)."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp
from sympy.polys.fields import sfield

_TRIG = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)


def has_trig(expr) -> bool:
    return any(expr.has(f) for f in _TRIG)


def tidy(expr):
    """Cheap, predictable simplification: trig identities where trig functions appear, then
    cancellation of rational factors. Keeps expressions readable without ``simplify``'s cost.
    Results are memoised (the same minors recur across candidates and steps)."""
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(tidy)
    if expr == 0 or expr.is_Number or expr.is_Symbol:
        return expr
    return _tidy_scalar(expr)


@lru_cache(maxsize=8192)
def _tidy_scalar(expr):
    return trig_normal(expr)


def _reduce_poly(poly, pairs):
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


class _NotRational(Exception):
    pass


def _collect_generators(e, gens: dict):
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
            _collect_generators(a, gens)
    elif e.is_Pow and e.exp.is_Integer:
        _collect_generators(e.base, gens)
    elif e.is_Number or e.is_NumberSymbol:
        gens.setdefault(e, None) if not e.is_Rational else None
    else:
        if any(s.is_Symbol for s in e.free_symbols):
            gens.setdefault(e, None)
        else:
            gens.setdefault(e, None)


def _to_field(e, extra):
    """Evaluate ``e`` as a fraction num/den of sparse polynomials over QQ in the generators of
    ``e`` (plus ``extra``), walking the tree without intermediate gcds (one cancellation at
    the end is cheaper than one per operation). Returns (ring, num, den)."""
    from sympy.polys.domains import QQ
    from sympy.polys.rings import ring as make_ring
    gens: dict = {}
    _collect_generators(e, gens)
    for x in extra:
        gens.setdefault(x, None)
    order = sorted(gens, key=sp.default_sort_key)
    if not order:
        raise _NotRational
    R, *g = make_ring(order, QQ)
    one = R.one
    table = {k: (v, one) for k, v in zip(order, g)}
    memo = {}

    def ev(x):
        if x in table:
            return table[x]
        got = memo.get(x)
        if got is not None:
            return got
        if x.is_Rational:
            out = (R(QQ(int(x.p), int(x.q))), one)
        elif x.is_Float:
            r = sp.Rational(x)
            out = (R(QQ(int(r.p), int(r.q))), one)
        elif x.is_Add:
            terms = [ev(a) for a in x.args]
            # group terms with equal denominators first
            groups: dict = {}
            for nmr, dnm in terms:
                groups[dnm] = groups.get(dnm, R.zero) + nmr
            num, den = None, None
            for dnm, nmr in groups.items():
                if num is None:
                    num, den = nmr, dnm
                elif dnm == den:
                    num = num + nmr
                else:
                    num, den = num * dnm + nmr * den, den * dnm
            out = (num, den)
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
                    raise ZeroDivisionError("division by zero in trig_normal")
                out = (bd ** (-k), bn ** (-k))
            else:
                out = (bn ** k, bd ** k)
        else:  # pragma: no cover - every other node was registered as a generator
            raise _NotRational
        memo[x] = out
        return out

    num, den = ev(e)
    return R, num, den


def trig_normal(expr):
    """Normal form of a rational expression in sines and cosines.

    Trig functions are expanded to sin/cos of single symbols; sin(x) and cos(x) become
    generators of a sparse polynomial ring over ℚ in which the expression is evaluated as a
    fraction (walking the tree, one gcd at the end); sin(x)² is reduced to 1 − cos(x)². The
    result is canonical (a zero expression always returns 0) and costs only sparse polynomial
    arithmetic — orders of magnitude cheaper than ``trigsimp`` on the expressions of steps
    15–19.
    """
    if not expr.free_symbols:
        return sp.nsimplify(expr) if expr.is_Float else sp.simplify(expr)
    e = expr
    if e.has(sp.tan, sp.cot, sp.sec, sp.csc):
        e = e.replace(sp.tan, lambda a: sp.sin(a) / sp.cos(a)).replace(sp.cot, lambda a: sp.cos(a) / sp.sin(a))
        e = e.replace(sp.sec, lambda a: 1 / sp.cos(a)).replace(sp.csc, lambda a: 1 / sp.sin(a))
    atoms = e.atoms(sp.sin, sp.cos)
    if any(not a.args[0].is_Symbol for a in atoms):
        e = sp.expand_trig(e)
        if not e.free_symbols:
            return sp.nsimplify(e) if e.is_Float else e
        atoms = e.atoms(sp.sin, sp.cos)
    args = sorted({a.args[0] for a in atoms}, key=sp.default_sort_key)
    if any(not a.is_Symbol for a in args):
        # arguments expand_trig could not split (e.g. sin(x**2)): fall back to trigsimp
        return sp.factor_terms(sp.trigsimp(expr))
    pairs_expr = [(sp.sin(a), sp.cos(a)) for a in args]
    try:
        R, num, den = _to_field(e, [x for pair in pairs_expr for x in pair])
    except _NotRational:
        return sp.factor_terms(sp.cancel(e))
    syms = list(R.symbols)
    pairs = [(syms.index(S), syms.index(C)) for S, C in pairs_expr]
    num = _reduce_poly(num, pairs)
    if not num:
        return sp.Integer(0)
    den = _reduce_poly(den, pairs)
    num, den = num.cancel(den)
    num = _reduce_poly(num, pairs)
    den = _reduce_poly(den, pairs)
    num, den = num.cancel(den)
    return num.as_expr() / den.as_expr()


def null_basis_adjugate(A: sp.Matrix, pivots: list[int]) -> sp.Matrix:
    """Basis of the right null space of the k×l matrix ``A`` (rank k) without divisions.

    With B = A[:, pivots] (k×k, invertible at generic points) each free column j gives the
    null vector v = det(B)·e_j − (adj(B)·A[:, j]) placed on the pivot rows. Its entries are the
    k×k minors of A, so v vanishes exactly where rank A < k (the singular set), never at a
    spurious point. Returns an l×(l−k) matrix.
    """
    k, l = A.shape
    free = [j for j in range(l) if j not in pivots]
    if k == 0:
        return sp.eye(l)
    B = A.extract(list(range(k)), pivots)
    detB = B.det(method="berkowitz")
    adjB = B.adjugate(method="berkowitz")
    cols = []
    for j in free:
        v = sp.zeros(l, 1)
        v[j] = detB
        w = adjB * A[:, j]
        for i, p in enumerate(pivots):
            v[p] = -w[i]
        v = tidy(v)
        # remove a common constant/polynomial factor, fix the sign of the free entry
        try:
            g = sp.gcd(list(v))
            if g not in (0, 1) and g.is_Number:
                v = tidy(v / g)
        except (sp.PolynomialError, sp.GeneratorsNeeded, TypeError):
            pass
        if v[j].could_extract_minus_sign():
            v = -v
        cols.append(v)
    return sp.Matrix.hstack(*cols) if cols else sp.zeros(l, 0)


def strip_factors(N: sp.Matrix, symbols) -> sp.Matrix:
    """Divide each column of ``N`` by the common factor of its entries that depends on
    ``symbols`` (e.g. a sin θ common to a null vector when θ is a group variable), so a basis
    vector does not vanish at a spurious point. Factors of other symbols are kept."""
    symbols = set(symbols)
    cols = []
    for j in range(N.shape[1]):
        v = N[:, j]
        try:
            g = sp.factor(sp.gcd([e for e in v if e != 0]))
        except (sp.PolynomialError, sp.GeneratorsNeeded, TypeError):
            cols.append(v)
            continue
        keep = sp.Integer(1)
        for f in sp.Mul.make_args(g):
            if f.free_symbols & symbols:
                keep *= f
        if keep != 1:
            v = tidy(v / keep)
            nz = [e for e in v if e != 0]
            if nz and nz[-1].could_extract_minus_sign():
                v = -v
        cols.append(v)
    return sp.Matrix.hstack(*cols) if cols else N


def numeric_pivots(A_num: np.ndarray, order=None, tol=1e-9) -> list[int]:
    """Greedy choice of linearly independent columns of a numeric matrix (in ``order``)."""
    k, l = A_num.shape
    order = list(range(l)) if order is None else list(order)
    chosen: list[int] = []
    for j in order:
        trial = chosen + [j]
        sub = A_num[:, trial]
        if np.linalg.matrix_rank(sub, tol=tol * max(1.0, np.abs(A_num).max())) == len(trial):
            chosen.append(j)
        if len(chosen) == k:
            break
    return sorted(chosen)
