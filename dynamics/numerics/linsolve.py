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

__all__ = ["solve_spd", "solve_general"]


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
    from ..derivation.reduction.arithmetic import CasadiArithmetic
    rows = CasadiArithmetic().solve(_entries(A), _entries(b))
    n, m = A.shape[0], b.shape[1]
    return ca.vertcat(*[ca.horzcat(*[rows[i][j] for j in range(m)]) for i in range(n)]) if n else ca.SX(0, m)
