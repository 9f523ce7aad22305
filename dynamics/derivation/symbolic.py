"""Small symbolic helpers shared by the derivations (no physics here)."""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

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


class NotRational(Exception):
    """An expression the exact rational back end cannot represent (a trig function of a
    non-angle, a power with a symbolic exponent, ...): the sympy back end takes over."""


class WorkBudgetExceeded(Exception):
    """The exact arithmetic exceeded its work budget (the caller then uses the implicit form)."""


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


def _add_fractions(terms, zero, one):
    """Σ num/den over fractions of one ring: equal denominators are summed first, so a sum
    over a common denominator costs no multiplication of denominators."""
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


def _float_rational(x):
    """The rational a Float stands for: for a double (a number written in a scene, 0.1) the
    shortest decimal that rounds to it (1/10, which evaluates to the same double), otherwise
    its exact binary value."""
    if x._prec <= 53:
        from fractions import Fraction
        f = Fraction(repr(float(x)))
        return sp.Rational(f.numerator, f.denominator)
    return sp.Rational(x)


def _walk_fraction(e, R, table: dict):
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
            r = _float_rational(x)
            out = (R(QQ(int(r.p), int(r.q))), one)
        elif x.is_Add:
            out = _add_fractions([ev(a) for a in x.args], R.zero, one)
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
        raise NotRational
    R, *g = make_ring(order, QQ)
    num, den = _walk_fraction(e, R, {k: (v, R.one) for k, v in zip(order, g)})
    return R, num, den


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
        e = e.replace(sp.tan, lambda a: sp.sin(a) / sp.cos(a)).replace(sp.cot, lambda a: sp.cos(a) / sp.sin(a))
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
        R, num, den = _to_field(e, [x for pair in pairs_expr for x in pair])
    except NotRational:
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
    null vector v = det(B)·e_j − (adj(B)·A[:, j]) placed on the pivot rows. Its entries are
    k×k minors of A, so no vector vanishes through a division; the vectors do become
    dependent where det B = 0, which may happen where rank A = k (a singular point of the
    basis, listed in the reduction's singular set). Returns an l×(l−k) matrix.
    """
    k, l = A.shape
    free = [j for j in range(l) if j not in pivots]
    if k == 0:
        return sp.eye(l)
    if not free:
        return sp.zeros(l, 0)
    B = A.extract(list(range(k)), pivots)
    large = is_large(A)
    if large:                      # entries from bodies: plain products, no intermediate simplification
        detB, adjB = plain_det(B), plain_adjugate(B)
    else:
        detB, adjB = B.det(method="berkowitz"), B.adjugate(method="berkowitz")
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
            g = None if large else sp.gcd(list(v))
        except (sp.PolynomialError, sp.GeneratorsNeeded, TypeError):
            g = None          # no gcd of these entries: v is a basis vector as it is
        if g is not None and g not in (0, 1) and g.is_Number:
            v = tidy(v / g)
        if v[j].could_extract_minus_sign():
            v = -v
        cols.append(v)
    return sp.Matrix.hstack(*cols) if cols else sp.zeros(l, 0)


#: a matrix whose entries have more tree nodes together than this is "large": its minors and
#: their gcd are formed without simplification (the wheeled 8-link snake's ω_s has 329 nodes,
#: the Whipple bicycle's 912, whose 4×4 minors then take seconds instead of a minute)
LARGE_MATRIX_NODES = 600


def is_large(A: sp.Matrix) -> bool:
    """More than :data:`LARGE_MATRIX_NODES` tree nodes in the entries of ``A`` together."""
    total = 0
    for e in A:
        total += tree_size(e, LARGE_MATRIX_NODES)
        if total > LARGE_MATRIX_NODES:
            return True
    return False


def plain_det(B: sp.Matrix):
    """det B by expansion along the first row, without simplification (for large entries,
    where sympy's methods spend minutes simplifying intermediate products)."""
    n = B.shape[0]
    if n == 0:
        return sp.Integer(1)
    if n == 1:
        return B[0, 0]
    terms = []
    for j in range(n):
        if B[0, j] != 0:
            minor = B.extract(list(range(1, n)), [c for c in range(n) if c != j])
            terms.append((-1) ** j * B[0, j] * plain_det(minor))
    return sp.Add(*terms)


def plain_adjugate(B: sp.Matrix) -> sp.Matrix:
    """adj B (the transposed cofactor matrix) by :func:`plain_det` of the minors."""
    n = B.shape[0]
    if n == 1:
        return sp.Matrix([[1]])
    out = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            minor = B.extract([r for r in range(n) if r != i], [c for c in range(n) if c != j])
            out[j, i] = (-1) ** (i + j) * plain_det(minor)
    return out


def strip_factors(N: sp.Matrix, symbols) -> sp.Matrix:
    """Divide each column of ``N`` by the common factor of its entries that depends on
    ``symbols`` (e.g. a sin θ common to a null vector when θ is a group variable), so a basis
    vector does not vanish at a spurious point. Factors of other symbols are kept. A large
    ``N`` (:func:`is_large`) is returned as it is (its gcd alone would take minutes)."""
    if is_large(N):
        return N
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


class MatrixOps:
    """Matrix operations shared by every arithmetic back end (matrices are lists of rows of
    elements); the back end supplies the scalar operations (see
    :mod:`nhgait.dynamics.derivation.reduction.arithmetic`)."""

    def mat(self, A, normal=False):
        return [[self.frac(A[i, j], normal) for j in range(A.shape[1])] for i in range(A.shape[0])]

    def vec(self, symbols):
        return [[self.sym(s)] for s in symbols]

    def zeros(self, rows, cols):
        return [[self.ZERO for _ in range(cols)] for _ in range(rows)]

    def block_diag(self, A, B):
        """[[A, 0], [0, B]] of two square matrices (either may be empty)."""
        a, b = len(A), len(B)
        out = self.zeros(a + b, a + b)
        for i in range(a):
            out[i][:a] = A[i][:a]
        for i in range(b):
            out[a + i][a:] = B[i][:b]
        return out

    def matmul(self, A, B, normal=True):
        n_ = len(B)
        cols = len(B[0]) if B else 0
        out = []
        for row in A:
            r = []
            for j in range(cols):
                s = self.add_many([self.mul(row[k], B[k][j]) for k in range(n_)
                                   if not self.is_zero(row[k]) and not self.is_zero(B[k][j])])
                r.append(self.normal(s) if normal else s)
            out.append(r)
        return out

    def T(self, A):
        if not A:
            return []
        return [[A[i][j] for i in range(len(A))] for j in range(len(A[0]))]

    def madd(self, A, B, normal=True):
        return [[(self.normal if normal else (lambda x: x))(self.add_many([a, b])) for a, b in zip(ra, rb)]
                for ra, rb in zip(A, B)]

    def mneg(self, A):
        return [[self.neg(x) for x in r] for r in A]

    def inv(self, A, what="matrix"):
        return self.gauss_jordan(A, what)

    def gauss_jordan(self, A, what="matrix"):
        """Inverse of a small square matrix by Gauss–Jordan over the back end's field.

        Raises :class:`~nhgait.dynamics.errors.ModelError` naming ``what`` when no nonzero
        pivot exists (the matrix is singular for every configuration)."""
        from ..errors import ModelError
        n_ = len(A)
        one, zero = self.frac(1), self.frac(0)
        W = [list(r) + [one if i == j else zero for j in range(n_)] for i, r in enumerate(A)]
        for c in range(n_):
            p = next((r for r in range(c, n_) if not self.is_zero(W[r][c])), None)
            if p is None:
                raise ModelError([f"the {what} is singular for every configuration (no pivot in "
                                  f"column {c + 1}); the reduction cannot invert it"],
                                 title="singular matrix in the reduction")
            W[c], W[p] = W[p], W[c]
            piv = W[c][c]
            W[c] = [self.normal(self.div(x, piv)) for x in W[c]]
            for r in range(n_):
                if r != c and not self.is_zero(W[r][c]):
                    fct = W[r][c]
                    W[r] = [self.normal(self.add_many([x, self.neg(self.mul(fct, y))])) for x, y in zip(W[r], W[c])]
        return [r[n_:] for r in W]

    def div(self, f, g):
        return f / g

    def solve(self, A, B, what="matrix"):
        """A⁻¹B (exact back ends: through the inverse, which they normalise)."""
        return self.matmul(self.inv(A, what), B)

    def jvp(self, col, xs, direction):
        """Σ_j ∂col_i/∂x_j · direction_j (the derivative of a column along a vector field)."""
        out = []
        for c in col:
            terms = [self.mul(self.diff(c, x), dj) for x, dj in zip(xs, direction)
                     if not self.is_zero(dj) and not self.is_zero(c)]
            out.append(self.normal(self.add_many(terms)))
        return out

    def directional_inverse(self, Ainv, A, xs, direction, partials):
        """Σ_j ∂(A⁻¹)/∂x_j · direction_j, from the per-coordinate ``partials`` {j: ∂A⁻¹/∂x_j}."""
        n_ = len(Ainv)
        out = [[[] for _ in range(n_)] for _ in range(n_)]
        for j, D in partials.items():
            dj = direction[j]
            if self.is_zero(dj):
                continue
            for a in range(n_):
                for b in range(n_):
                    if not self.is_zero(D[a][b]):
                        out[a][b].append(self.mul(dj, D[a][b]))
        return [[self.normal(self.add_many(t)) for t in r] for r in out]

    def diff_inverse(self, Ainv, A, x):
        """∂(A⁻¹)/∂x given A⁻¹ and A: entry by entry (exact back ends)."""
        return [[self.normal(self.diff(e, x)) for e in r] for r in Ainv]

    def show(self, A, rows=None, cols=None):
        """The sympy Matrix of ``A`` (normal forms)."""
        rows = len(A) if rows is None else rows
        cols = (len(A[0]) if A else 0) if cols is None else cols
        if rows == 0 or cols == 0:
            return sp.zeros(rows, cols)
        return sp.Matrix(rows, cols, [self.expr(A[i][j]) for i in range(rows) for j in range(cols)])

    def value(self, e):
        """A sympy expression as a display value (sympy itself for the sympy back ends)."""
        return e

    def column(self, values):
        """Display values as a column (a sympy Matrix)."""
        return sp.Matrix(values) if values else sp.zeros(0, 1)

    def form(self, terms):
        """Σ coefficient · monomial for [(element, [symbols])]: a sympy expression."""
        out = sp.Integer(0)
        for c, variables in terms:
            if not self.is_zero(c):
                out += self.expr(c) * sp.Mul(*variables)
        return out

    def quadratic(self, Q, variables, half=False):
        """Σ_{i≤j} c_ij v_i v_j with c_ii = Q_ii, c_ij = Q_ij + Q_ji (normal coefficients)."""
        terms = []
        nv = len(variables)
        for i in range(nv):
            for j in range(i, nv):
                c = Q[i][j] if i == j else self.add_many([Q[i][j], Q[j][i]])
                if not self.is_zero(c):
                    if half:
                        c = self.scale(c, 1, 2)
                    terms.append((self.normal(c), [variables[i], variables[j]]))
        return self.form(terms)

class FracField(MatrixOps):
    """One field ℚ(generators) per derivation: symbols, sin/cos of the angles and opaque
    subexpressions are generators of a sparse polynomial ring; elements are pairs (num, den).

    Intermediate quantities stay as ring fractions across steps (no round trips through sympy
    expressions); :meth:`normal` gives exactly the normal form of :func:`trig_normal` and
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
                _check_trig(x, variables, time)
                _collect_generators(x, gens)
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
        self.table = {x: (v, self.one) for x, v in zip(order, g)}
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
        return _walk_fraction(e, self.R, self.table)

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
        return _add_fractions(terms, self.zero, self.one)

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
        """Exactly the normal form of :func:`trig_normal` (sin² → 1 − cos², one cancel)."""
        num, den = f
        if not num:
            return (self.zero, self.one)
        if self.budget is not None:
            self.work += len(num) * len(den)
            if self.work > self.budget:
                raise WorkBudgetExceeded
        num = _reduce_poly(num, self.pairs)
        if not num:
            return (self.zero, self.one)
        den = _reduce_poly(den, self.pairs)
        used, (Rs, spairs) = self._compress(num, den)
        if Rs is None:
            c = num.LC / den.LC
            return (self.R(c), self.one)
        n_ = Rs({tuple(m[i] for i in used): c for m, c in num.items()})
        d_ = Rs({tuple(m[i] for i in used): c for m, c in den.items()})
        n_, d_ = n_.cancel(d_)
        n_ = _reduce_poly(n_, spairs)
        d_ = _reduce_poly(d_, spairs)
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


def _check_trig(x, variables=frozenset(), time=frozenset()):
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
