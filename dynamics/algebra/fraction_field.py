"""The exact fraction field of a derivation: :class:`FracField`, the explicit back end of the
20-step reduction (elements are fractions num/den of one sparse polynomial ring, :mod:`.ring`).
"""
from __future__ import annotations

import sympy as sp

from .matrix_ops import MatrixOps
from .ring import (
    NotRational,
    WorkBudgetExceeded,
    add_fractions,
    collect_generators,
    reduce_poly,
    walk_fraction,
)
from .trig import has_trig, tidy

__all__ = ["FracField", "as_sympy", "check_trig"]


class FracField(MatrixOps):
    """One field ℚ(generators) per derivation: symbols, sin/cos of the angles and opaque
    subexpressions are generators of a sparse polynomial ring; elements are pairs (num, den).

    Intermediate quantities stay as ring fractions across steps (no round trips through sympy
    expressions); :meth:`normal` gives exactly the normal form of :func:`~.trig.trig_normal` and
    :meth:`expr` its sympy expression. Raises ``NotRational`` for anything it cannot represent
    (the caller then falls back to the plain sympy derivation).

    ``symbols`` and ``angles`` are the field's *variables* (differentiated and substituted by
    the steps); ``time`` names symbols the steps only carry along (the time t of the forces).
    A *time factor* — a subexpression that involves a ``time`` symbol and no variable, such as
    sin(2.5t), exp(−t) or sin(ωt) — is one more opaque generator: ∂/∂x of it is 0 for every
    variable x and no substitution reaches into it. Time factors need not be independent of
    one another (sin t and sin 2.5t may both appear): since the Lagrangian and the constraints
    cannot depend on t they enter only through the forces, which the steps multiply and add
    but never invert or test for a zero pivot, so a relation among them can leave a force term
    unsimplified, never wrong. A sin/cos of any other non-symbol argument raises
    ``NotRational``. ``budget``: the most work (Σ terms of num × terms of den over all
    normalisations) before ``WorkBudgetExceeded``; None, no limit."""

    def __init__(self, exprs, symbols=(), angles=(), time=(), budget=None):
        from sympy.polys.domains import QQ
        from sympy.polys.rings import ring as make_ring
        gens: dict = {}
        variables = frozenset(symbols) | frozenset(angles)
        time = frozenset(time)
        for e in exprs:
            for x in (e if isinstance(e, sp.MatrixBase) else [as_sympy(e)]):
                x = tidy(x) if has_trig(x) else x
                check_trig(x, variables, time)
                collect_generators(x, gens)
        for s in symbols:
            gens.setdefault(s, None)
        for a in angles:
            gens.setdefault(sp.sin(a), None)
            gens.setdefault(sp.cos(a), None)
        order = sorted(gens, key=sp.default_sort_key)
        self.QQ = QQ
        self.R, *g = make_ring(order, QQ)
        self.order = order
        self.index = {x: i for i, x in enumerate(order)}
        self.one, self.zero = self.R.one, self.R.zero
        self.ZERO, self.ONE = (self.zero, self.one), (self.one, self.one)
        self.work = 0
        self.budget = budget
        self.table = {x: (v, self.one) for x, v in zip(order, g, strict=True)}
        self.gens = g
        self.angle = {}
        pairs = []
        for x in order:
            if isinstance(x, sp.sin) and sp.cos(x.args[0]) in self.index:
                iS, iC = self.index[x], self.index[sp.cos(x.args[0])]
                pairs.append((iS, iC))
                self.angle[x.args[0]] = (iS, iC)
        self.pairs = pairs
        self.opaque = [x for x in order if not x.is_Symbol and x not in {sp.sin(a) for a in self.angle}
                       and x not in {sp.cos(a) for a in self.angle}]
        self._sub = {}

    # -- conversion ------------------------------------------------------------------------
    def frac(self, e, normal=False):
        e = as_sympy(e)
        try:
            out = self._walk(e)
        except (NotRational, KeyError):
            e2 = tidy(e)
            out = self._walk(e2)
            normal = False
        return self.normal(out) if normal else out

    def _walk(self, e):
        return walk_fraction(e, self.R, self.table)

    kind = "ring"

    def sym(self, s):
        return self.table[s]

    def sub_key(self, s):
        return self.index[s]

    def div(self, f, g):
        if not g[0]:
            raise ZeroDivisionError("division by zero in FracField")
        return (f[0] * g[1], f[1] * g[0])

    def matrix(self, F, rows=None, cols=None):
        return self.show(F, rows, cols)

    def expr(self, f):
        num, den = f
        if not num:
            return sp.Integer(0)
        if den == self.one:
            return num.as_expr()
        return num.as_expr() / den.as_expr()

    def add_many(self, terms):
        return add_fractions(terms, self.zero, self.one)

    def mul(self, f, g):
        if not f[0] or not g[0]:
            return (self.zero, self.one)
        return (f[0] * g[0], f[1] * g[1])

    def neg(self, f):
        return (-f[0], f[1])

    def scale(self, f, p, q=1):
        return (f[0] * self.QQ(p, q), f[1])

    def is_zero(self, f):
        return not f[0]

    def _compress(self, num, den):
        used = set()
        for p in (num, den):
            for mon in p.itermonoms():
                for i, k in enumerate(mon):
                    if k:
                        used.add(i)
        used = tuple(sorted(used))
        sub = self._sub.get(used)
        if sub is None:
            from sympy.polys.rings import ring as make_ring
            if used:
                Rs = make_ring([self.order[i] for i in used], self.QQ)[0]
            else:
                Rs = None
            pos = {i: a for a, i in enumerate(used)}
            spairs = [(pos[s], pos[c]) for s, c in self.pairs if s in pos and c in pos]
            sub = self._sub[used] = (Rs, spairs)
        return used, sub

    def normal(self, f):
        """Exactly the normal form of :func:`~.trig.trig_normal` (sin² → 1 − cos², one cancel)."""
        num, den = f
        if not num:
            return (self.zero, self.one)
        if self.budget is not None:
            self.work += len(num) * len(den)
            if self.work > self.budget:
                raise WorkBudgetExceeded
        num = reduce_poly(num, self.pairs)
        if not num:
            return (self.zero, self.one)
        den = reduce_poly(den, self.pairs)
        used, (Rs, spairs) = self._compress(num, den)
        if Rs is None:
            c = num.LC / den.LC
            return (self.R(c), self.one)
        n_ = Rs({tuple(m[i] for i in used): c for m, c in num.items()})
        d_ = Rs({tuple(m[i] for i in used): c for m, c in den.items()})
        n_, d_ = n_.cancel(d_)
        n_ = reduce_poly(n_, spairs)
        d_ = reduce_poly(d_, spairs)
        n_, d_ = n_.cancel(d_)
        ng = self.R.ngens

        def back(p):
            out = {}
            for m, c in p.items():
                full = [0] * ng
                for a, i in enumerate(used):
                    full[i] = m[a]
                out[tuple(full)] = c
            return self.R(out)
        return (back(n_), back(d_))

    def diff(self, f, x):
        """d f/d x with d sin x = cos x dx, d cos x = −sin x dx."""
        num, den = f
        if not num:
            return f
        for o in self.opaque:
            if x in o.free_symbols:
                raise NotRational
        gens = self.gens

        def dp(p):
            out = self.zero
            i = self.index.get(x)
            if i is not None:
                out = p.diff(gens[i])
            ang = self.angle.get(x)
            if ang is not None:
                iS, iC = ang
                out = out + p.diff(gens[iS]) * gens[iC] - p.diff(gens[iC]) * gens[iS]
            return out
        dn, dd = dp(num), dp(den)
        if not dd:
            return (dn, den)
        return (dn * den - num * dd, den * den)

    def subs(self, f, sub):
        """Substitute generators (index -> fraction) in f = (num, den); den must not contain them
        and no opaque generator (e.g. sign(φ̇)) may depend on them — the substitution could not
        reach inside it, so the plain sympy back end takes over (``NotRational``)."""
        num, den = f
        for m in den.itermonoms():
            if any(m[i] for i in sub):
                raise NotRational
        targets = {self.order[i] for i in sub}
        used = {i for m in num.itermonoms() for i, k in enumerate(m) if k}
        if any(self.order[i] in self.opaque and self.order[i].free_symbols & targets for i in used):
            raise NotRational
        terms = []
        idx = list(sub)
        for m, c in num.items():
            mm = list(m)
            for i in idx:
                mm[i] = 0
            t = (self.R({tuple(mm): c}), self.one)
            for i in idx:
                k = m[i]
                if k:
                    sn, sd = sub[i]
                    t = (t[0] * sn ** k, t[1] * sd ** k)
            terms.append(t)
        s = self.add_many(terms)
        return (s[0], s[1] * den)

    def linear_split(self, f, variables):
        """(constant part, [coefficient of v]) like ``_linear_tidy``: terms of degree 1 in v."""
        num, den = f
        vi = [self.index[v] for v in variables]
        for m in den.itermonoms():
            if any(m[i] for i in vi):
                raise NotRational
        const = {}
        coefs = [{} for _ in vi]
        for m, c in num.items():
            if not any(m[i] for i in vi):
                const[m] = c
            for a, i in enumerate(vi):
                if m[i] == 1:
                    mm = list(m)
                    mm[i] = 0
                    coefs[a][tuple(mm)] = c
        return (self.normal((self.R(const), den)), [self.normal((self.R(cd), den)) for cd in coefs])


def as_sympy(e):
    """A sympy object for an internal value (sympy objects pass through; numbers convert)."""
    if isinstance(e, sp.Basic):
        return e
    return sp.Integer(e) if isinstance(e, int) else sp.Float(e)


def check_trig(x, variables=frozenset(), time=frozenset()):
    """Raise ``NotRational`` unless every trig function of ``x`` (a normal form, so only sin
    and cos) is sin/cos of a symbol or a time factor: an argument that involves a ``time``
    symbol and none of the ``variables`` (see :class:`FracField`)."""
    if x.has(sp.tan, sp.cot, sp.sec, sp.csc):
        raise NotRational
    for a in x.atoms(sp.sin, sp.cos):
        arg = a.args[0]
        if arg.is_Symbol:
            continue
        free = arg.free_symbols
        if not free & time or free & variables:
            raise NotRational
