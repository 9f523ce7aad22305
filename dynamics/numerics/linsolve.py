"""Small linear solves in CasADi SX expressions, cheaper than ``casadi.solve``'s symbolic QR.

The equations of motion solve small systems at every evaluation: the metric K = XᵀMX for the
accelerations, a velocity map B for the velocity states. In an SX graph a symbolic QR costs
≈ 4 n³ operations with square roots, and automatic differentiation (the planner's Jacobians
and Hessians of every RK4 stage) multiplies that. Two cheaper exact factorisations:

* :func:`solve_spd` — LDLᵀ without pivoting for a symmetric positive definite matrix (a kinetic
  metric): stable without pivoting, no square roots, ≈ n³/3 multiplications (n = 4: 82 SX
  operations against 200 for QR);
* :func:`solve_general` — Gaussian elimination on the entries that are nonzero *constants*
  (they never vanish, so this adds no singular point; identity rows of a velocity map cost
  nothing), then QR of what is left (usually nothing or a small block).
"""
from __future__ import annotations

import casadi as ca

__all__ = ["solve_spd", "solve_general", "solve_rows"]


def _entries(A) -> list:
    return [[A[i, j] for j in range(A.shape[1])] for i in range(A.shape[0])]


def solve_spd(A: ca.SX, b: ca.SX) -> ca.SX:
    """A⁻¹b for symmetric positive definite A (n × n) by LDLᵀ (no pivoting needed)."""
    n = A.shape[0]
    a = _entries(A)
    zero = ca.SX(0)
    L = [[zero] * n for _ in range(n)]
    D = [zero] * n
    for j in range(n):
        D[j] = a[j][j] - sum((L[j][k] * L[j][k] * D[k] for k in range(j)), zero)
        for i in range(j + 1, n):
            L[i][j] = (a[i][j] - sum((L[i][k] * L[j][k] * D[k] for k in range(j)), zero)) / D[j]
    cols = []
    for c in range(b.shape[1]):
        y = []
        for i in range(n):
            y.append(b[i, c] - sum((L[i][k] * y[k] for k in range(i)), zero))
        x = [zero] * n
        for i in reversed(range(n)):
            x[i] = y[i] / D[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), zero)
        cols.append(ca.vertcat(*x))
    return ca.horzcat(*cols) if cols else ca.SX(n, 0)


def solve_general(A: ca.SX, b: ca.SX) -> ca.SX:
    """A⁻¹b: elimination on constant nonzero pivots first, QR for the remaining block."""
    rows = solve_rows(_entries(A), _entries(b))
    n, m = A.shape[0], b.shape[1]
    return ca.vertcat(*[ca.horzcat(*[rows[i][j] for j in range(m)]) for i in range(n)]) if n else ca.SX(0, m)


def solve_rows(A, B) -> list:
    """A⁻¹B for A (k × k) and B (k × m) given as rows of SX elements, as rows of SX elements,
    without forming an inverse: Gaussian elimination on the entries of A that are nonzero
    constants (they never vanish, so this adds no singular point; sparse rows keep the cost
    near the number of nonzeros), then one symbolic QR solve of the remaining Schur
    complement, then back-substitution."""
    k = len(A)
    M = [list(r) for r in A]
    R = [list(r) for r in B]
    rows, cols, pivots = set(range(k)), set(range(k)), []
    while True:
        best = None
        for r in rows:
            nnz_r = sum(1 for c in cols if not M[r][c].is_zero())
            for c in cols:
                e = M[r][c]
                if e.is_constant() and not e.is_zero():
                    nnz_c = sum(1 for r2 in rows if not M[r2][c].is_zero())
                    cost = (nnz_r - 1) * (nnz_c - 1)
                    if best is None or cost < best[0]:
                        best = (cost, r, c)
        if best is None:
            break
        _, r, c = best
        rows.discard(r)
        cols.discard(c)
        pivots.append((r, c))
        for r2 in rows:
            if not M[r2][c].is_zero():
                f = M[r2][c] / M[r][c]
                M[r2] = [x - f * y if not y.is_zero() else x for x, y in zip(M[r2], M[r], strict=True)]
                M[r2][c] = ca.SX(0)
                R[r2] = [x - f * y for x, y in zip(R[r2], R[r], strict=True)]
    m = len(B[0]) if B else 0
    X = {}
    if rows:
        rr, cc = sorted(rows), sorted(cols)
        S = ca.SX(len(rr), len(cc))
        rhs = ca.SX(len(rr), m)
        for i, r in enumerate(rr):
            for j, c in enumerate(cc):
                S[i, j] = M[r][c]
            for j in range(m):
                rhs[i, j] = R[r][j]
        sol = ca.solve(S, rhs)
        for j, c in enumerate(cc):
            X[c] = [sol[j, t] for t in range(m)]
    for r, c in reversed(pivots):
        X[c] = [(R[r][t] - _sum([M[r][j] * X[j][t] for j in X if j != c and not M[r][j].is_zero()]))
                / M[r][c] for t in range(m)]
    return [X[c] for c in range(k)]


def _sum(terms):
    """Σ terms as SX, added one by one from 0."""
    out = ca.SX(0)
    for t in terms:
        out = out + t
    return out
