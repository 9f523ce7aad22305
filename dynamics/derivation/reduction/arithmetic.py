"""The one small arithmetic interface the 20 steps are written against, and its three back ends.

The steps (``connection``, ``legendre``, ``poisson``, ``equations``) never call sympy or CasADi
directly for their algebra: they combine *elements* (scalars) and *matrices* (lists of rows of
elements) through the methods below. A back end decides what an element is:

* :class:`~nhgait.dynamics.algebra.fraction_field.FracField` — exact fractions of one sparse polynomial ring
  over ℚ (sin/cos of each angle as generators, sin² → 1 − cos²; time factors of the forces
  such as sin(2.5t) or exp(−t) as further generators): the explicit form, canonical and fast
  for rational trigonometric systems;
* :class:`SympyArithmetic` — plain sympy expressions normalised by ``tidy``: the explicit form
  for systems the ring cannot hold (√, exp of coordinates, sin(t·φ) in a force);
* :class:`CasadiArithmetic` — CasADi SX scalars, inverses as linear solves: the implicit form,
  whose cost grows gently with the system (no symbolic inverse, AD and CSE from CasADi).

Scalar methods: ``frac(expr)`` (sympy → element), ``expr(el)`` (element → sympy, or SX),
``add_many``, ``mul``, ``neg``, ``scale``, ``normal``, ``is_zero``, ``diff(el, symbol)``,
``subs(el, {generator index or symbol: element})``, ``linear_split(el, symbols)``,
``sym(symbol)`` (the element of a sympy symbol). Matrix methods (shared, :class:`MatrixOps`):
``mat``, ``zeros``, ``block_diag``, ``matmul``, ``T``, ``madd``, ``mneg``, ``inv``, ``show``, ``form``.
"""
from __future__ import annotations

import sympy as sp

from ...algebra.fraction_field import FracField, as_sympy
from ...algebra.matrix_ops import MatrixOps
from ...algebra.trig import tidy
from ...errors import ModelError


class SympyArithmetic(MatrixOps):
    """Elements are sympy expressions; ``normal`` is :func:`~nhgait.dynamics.algebra.trig.tidy`."""

    kind = "sympy"

    def __init__(self, exprs=(), symbols=(), angles=()):
        self.zero = self.ZERO = sp.Integer(0)
        self.one = self.ONE = sp.Integer(1)

    def frac(self, e, normal=False):
        e = as_sympy(e)
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
    symbolic = False

    def __init__(self, exprs=(), symbols=(), angles=()):
        import casadi as ca
        self.ca = ca
        self.zero = self.ZERO = ca.SX(0)
        self.one = self.ONE = ca.SX(1)
        self.table: dict = {}
        self._mats: dict = {}

    def sym(self, s):
        got = self.table.get(s)
        if got is None:
            got = self.table[s] = self.ca.SX.sym(s.name)
        return got

    def frac(self, e, normal=False):
        from ...numerics.bridge import to_casadi
        e = as_sympy(e)
        for s in e.free_symbols:
            self.sym(s)
        syms = list(self.table)
        out = to_casadi([e], syms, [self.table[s] for s in syms])[0]
        return out if isinstance(out, self.ca.SX) else self.ca.SX(out)

    def mat(self, A, normal=False):
        """All entries of a sympy Matrix in one conversion (shared subexpressions), memoised."""
        from ...numerics.bridge import to_casadi
        key = sp.ImmutableMatrix(A)
        got = self._mats.get(key)
        if got is None:
            for s in A.free_symbols:
                self.sym(s)
            syms = list(self.table)
            flat = to_casadi(list(A), syms, [self.table[s] for s in syms]) if A.shape[0] * A.shape[1] else []
            flat = [x if isinstance(x, self.ca.SX) else self.ca.SX(x) for x in flat]
            got = self._mats[key] = [flat[i * A.shape[1]:(i + 1) * A.shape[1]] for i in range(A.shape[0])]
        return [list(r) for r in got]

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

    def _sx(self, A):
        return self.show(A)

    def _rows(self, M):
        return [[M[i, j] for j in range(M.shape[1])] for i in range(M.shape[0])]

    def jvp(self, col, xs, direction):
        """Forward-mode AD of the column along ``direction`` (one pass, no per-entry Jacobians)."""
        ca = self.ca
        c = ca.vertcat(*col)
        x = ca.vertcat(*[self.sym(s) for s in xs])
        out = ca.jtimes(c, x, ca.vertcat(*direction))
        return [out[i] for i in range(out.shape[0])]

    def diff_inverse(self, Ainv, A, x):
        """∂(A⁻¹)/∂x = −A⁻¹(∂A/∂x)A⁻¹ (no inverse is differentiated)."""
        ca = self.ca
        dA = ca.jacobian(ca.vec(self._sx(A)), self.sym(x))
        dA = ca.reshape(dA, len(A), len(A))
        return self._rows(-ca.mtimes([self._sx(Ainv), dA, self._sx(Ainv)]))

    def directional_inverse(self, Ainv, A, xs, direction, partials=None):
        """−A⁻¹(D_dir A)A⁻¹ with D_dir A by forward AD along ``direction``."""
        ca = self.ca
        n = len(A)
        x = ca.vertcat(*[self.sym(s) for s in xs])
        dA = ca.reshape(ca.jtimes(ca.vec(self._sx(A)), x, ca.vertcat(*direction)), n, n)
        return self._rows(-ca.mtimes([self._sx(Ainv), dA, self._sx(Ainv)]))

    def solve(self, A, B, what="matrix"):
        """A⁻¹B without forming an inverse (:func:`~nhgait.dynamics.numerics.linsolve.solve_rows`:
        elimination on the constant nonzero entries of A, QR of the rest)."""
        from ...numerics.linsolve import solve_rows
        return solve_rows(A, B)

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

    def square(self, rows):
        ca = self.ca
        return ca.vertcat(*[ca.horzcat(*r) for r in rows]) if rows else ca.SX(0, 0)

    def zero_block(self, rows, cols):
        return self.ca.SX(rows, cols)

    def blocks(self, rows):
        ca = self.ca
        return ca.vertcat(*[ca.horzcat(*r) for r in rows])


def _prod(arith, variables):
    out = arith.one
    for v in variables:
        out = out * arith.sym(v)
    return out


def _ring(exprs, symbols, angles, time, budget):
    return FracField(exprs, symbols=symbols, angles=angles, time=time, budget=budget)


def _sympy(exprs, symbols, angles, time, budget):
    return SympyArithmetic()


def _casadi(exprs, symbols, angles, time, budget):
    return CasadiArithmetic()


#: back-end name → its constructor (exprs, symbols, angles, time, budget)
ARITHMETICS = {"ring": _ring, "sympy": _sympy, "casadi": _casadi}


def make_arithmetic(kind: str, exprs, symbols, angles, time=(), budget=None):
    """The back end ``kind`` (a key of :data:`ARITHMETICS`: "ring", "sympy" or "casadi") for one
    derivation; ``time``: the symbols the steps carry along but never differentiate (t, see
    :class:`FracField`); ``budget``: the ring's work budget (None: no limit)."""
    try:
        make = ARITHMETICS[kind]
    except KeyError:
        raise ModelError([f"internal: unknown arithmetic {kind!r}"]) from None
    return make(exprs, symbols, angles, time, budget)
