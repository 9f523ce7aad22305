"""The one small arithmetic interface the 20 steps are written against, and its three back ends.

The steps (``connection``, ``legendre``, ``poisson``, ``equations``) never call sympy or CasADi
directly for their algebra: they combine *elements* (scalars) and *matrices* (lists of rows of
elements) through the methods below. A back end decides what an element is:

* :class:`~nhgait.dynamics.symbolic.FracField` — exact fractions of one sparse polynomial ring
  over ℚ (sin/cos of each angle as generators, sin² → 1 − cos²): the explicit form, canonical
  and fast for rational trigonometric systems;
* :class:`SympyArithmetic` — plain sympy expressions normalised by ``tidy``: the explicit form
  for systems the ring cannot hold (√, exp of coordinates);
* :class:`CasadiArithmetic` — CasADi SX scalars, inverses as linear solves: the implicit form,
  whose cost grows gently with the system (no symbolic inverse, AD and CSE from CasADi).

Scalar methods: ``frac(expr)`` (sympy → element), ``expr(el)`` (element → sympy, or SX),
``add_many``, ``mul``, ``neg``, ``scale``, ``normal``, ``is_zero``, ``diff(el, symbol)``,
``subs(el, {generator index or symbol: element})``, ``linear_split(el, symbols)``,
``sym(symbol)`` (the element of a sympy symbol). Matrix methods (shared, :class:`MatrixOps`):
``mat``, ``matmul``, ``T``, ``madd``, ``mneg``, ``inv``, ``show``, ``form``.
"""
from __future__ import annotations

import sympy as sp

from ..errors import ModelError
from ..symbolic import FracField, MatrixOps, tidy


class SympyArithmetic(MatrixOps):
    """Elements are sympy expressions; ``normal`` is :func:`~nhgait.dynamics.symbolic.tidy`."""

    kind = "sympy"

    def __init__(self, exprs=(), symbols=(), angles=()):
        self.zero = self.ZERO = sp.Integer(0)
        self.one = self.ONE = sp.Integer(1)

    def frac(self, e, normal=False):
        e = sp.sympify(e)
        return tidy(e) if normal else e

    def sym(self, s):
        return s

    def expr(self, f):
        return f

    def add_many(self, terms):
        return sp.Add(*terms)

    def mul(self, f, g):
        return f * g

    def neg(self, f):
        return -f

    def scale(self, f, p, q=1):
        return f * sp.Rational(p, q)

    def is_zero(self, f):
        return f == 0

    def normal(self, f):
        return tidy(f)

    def diff(self, f, x):
        return sp.diff(f, x)

    def subs(self, f, sub):
        return f.xreplace(sub)

    def sub_key(self, s):
        return s

    def linear_split(self, f, variables):
        e = sp.expand(f)
        const = tidy(e.xreplace({v: 0 for v in variables}))
        return const, [tidy(e.coeff(v)) for v in variables]



class CasadiArithmetic(MatrixOps):
    """Elements are CasADi SX scalars; symbols are created on first use (``table``).

    ``inv`` is a linear solve (``casadi.solve`` with the identity), ``normal`` the identity:
    the expression graph carries the structure, CasADi shares common subexpressions and
    differentiates by AD. Used for the implicit form (``model.form == "implicit"``).
    """

    kind = "casadi"

    def __init__(self, exprs=(), symbols=(), angles=()):
        import casadi as ca
        self.ca = ca
        self.zero = self.ZERO = ca.SX(0)
        self.one = self.ONE = ca.SX(1)
        self.table: dict = {}

    def sym(self, s):
        got = self.table.get(s)
        if got is None:
            got = self.table[s] = self.ca.SX.sym(s.name)
        return got

    def frac(self, e, normal=False):
        from ..bridge import to_casadi
        e = sp.sympify(e)
        for s in e.free_symbols:
            self.sym(s)
        syms = list(self.table)
        out = to_casadi([e], syms, [self.table[s] for s in syms])[0]
        return out if isinstance(out, self.ca.SX) else self.ca.SX(out)

    def expr(self, f):
        return f

    def add_many(self, terms):
        out = self.zero
        for t in terms:
            out = out + t
        return out

    def mul(self, f, g):
        return f * g

    def neg(self, f):
        return -f

    def scale(self, f, p, q=1):
        return f * (p / q)

    def is_zero(self, f):
        return f.is_zero()

    def normal(self, f):
        return f

    def diff(self, f, x):
        return self.ca.jacobian(f, self.sym(x))

    def sub_key(self, s):
        return s

    def subs(self, f, sub):
        if not sub:
            return f
        keys = list(sub)
        return self.ca.substitute(f, self.ca.vertcat(*[self.sym(k) for k in keys]),
                                  self.ca.vertcat(*[sub[k] for k in keys]))

    def linear_split(self, f, variables):
        vs = self.ca.vertcat(*[self.sym(v) for v in variables])
        const = self.ca.substitute(f, vs, self.ca.SX.zeros(vs.shape[0]))
        jac = self.ca.jacobian(f, vs)
        return const, [jac[i] for i in range(vs.shape[0])]

    def inv(self, A, what="matrix"):
        ca = self.ca
        n = len(A)
        if n == 0:
            return []
        Am = ca.SX(n, n)
        for i in range(n):
            for j in range(n):
                Am[i, j] = A[i][j]
        Ainv = ca.solve(Am, ca.SX.eye(n))
        return [[Ainv[i, j] for j in range(n)] for i in range(n)]

    def show(self, A, rows=None, cols=None):
        """An SX matrix (printed by CasADi with shared subexpressions)."""
        ca = self.ca
        rows = len(A) if rows is None else rows
        cols = (len(A[0]) if A else 0) if cols is None else cols
        out = ca.SX(rows, cols)
        for i in range(rows):
            for j in range(cols):
                out[i, j] = A[i][j]
        return out

    def form(self, terms):
        return self.add_many([c * _prod(self, vs) for c, vs in terms])

    def value(self, e):
        return self.frac(e)

    def column(self, values):
        return self.ca.vertcat(*values) if values else self.ca.SX(0, 1)


def _prod(F, variables):
    out = F.one
    for v in variables:
        out = out * F.sym(v)
    return out


def make_arithmetic(kind: str, exprs, symbols, angles):
    """The back end ``kind`` ("ring", "sympy" or "casadi") for one derivation."""
    if kind == "ring":
        return FracField(exprs, symbols=symbols, angles=angles)
    if kind == "sympy":
        return SympyArithmetic()
    if kind == "casadi":
        return CasadiArithmetic()
    raise ModelError([f"internal: unknown arithmetic {kind!r}"])
