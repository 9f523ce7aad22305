"""Matrix operations over any arithmetic back end: :class:`MatrixOps` (matrices are lists of
rows of elements; the back end — :class:`~.fraction_field.FracField`, or the sympy and CasADi
back ends of :mod:`nhgait.dynamics.derivation.reduction.arithmetic` — supplies the scalar
operations).
"""
from __future__ import annotations

import sympy as sp

__all__ = ["MatrixOps"]


class MatrixOps:
    """Matrix operations shared by every arithmetic back end (matrices are lists of rows of
    elements); the back end supplies the scalar operations (see
    :mod:`nhgait.dynamics.derivation.reduction.arithmetic`).

    ``symbolic``: the elements are exact (sympy expressions or ring fractions), so the steps
    can test identities exactly and show the thesis's block matrices; the displayed matrices
    are sympy Matrices (:meth:`square`, :meth:`blocks`, :meth:`zero_block`)."""

    symbolic = True

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
        return [[(self.normal if normal else (lambda x: x))(self.add_many([a, b]))
                 for a, b in zip(ra, rb, strict=True)]
                for ra, rb in zip(A, B, strict=True)]

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
                    W[r] = [self.normal(self.add_many([x, self.neg(self.mul(fct, y))]))
                            for x, y in zip(W[r], W[c], strict=True)]
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
            terms = [self.mul(self.diff(c, x), dj) for x, dj in zip(xs, direction, strict=True)
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

    def square(self, rows):
        """A displayed matrix from rows of display values (a sympy Matrix)."""
        return sp.Matrix(rows) if rows else sp.zeros(0, 0)

    def zero_block(self, rows, cols):
        """A displayed zero matrix."""
        return sp.zeros(rows, cols)

    def blocks(self, rows):
        """A displayed matrix from rows of displayed blocks."""
        return sp.BlockMatrix(rows).as_explicit()

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
