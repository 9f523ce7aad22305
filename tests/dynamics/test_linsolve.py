"""Small linear solves in SX (dynamics/numerics/linsolve.py) against numpy's LAPACK solve.

Each solve is built symbolically, turned into a CasADi function of the matrix entries, and
evaluated at random well-conditioned matrices: the answer must match ``numpy.linalg.solve`` to
1e-10 relative (condition numbers below 1e3, so double precision leaves ~1e-13)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics.linsolve import solve_general, solve_rows, solve_spd

RNG = np.random.default_rng(11)


def _function(solve, n: int, m: int) -> ca.Function:
    A, b = ca.SX.sym("A", n, n), ca.SX.sym("b", n, m)
    return ca.Function("solve", [A, b], [solve(A, b)])


@pytest.mark.parametrize("n", [1, 2, 4, 6])
def test_ldlt_solves_a_symmetric_positive_definite_system(n):
    f = _function(solve_spd, n, 2)
    for _ in range(5):
        G = RNG.normal(size=(n, n))
        A = G @ G.T + n * np.eye(n)                 # SPD, condition number bounded
        b = RNG.normal(size=(n, 2))
        np.testing.assert_allclose(np.asarray(f(A, b)), np.linalg.solve(A, b), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("n", [1, 3, 5])
def test_general_solve_matches_lapack_on_dense_matrices(n):
    f = _function(solve_general, n, 3)
    for _ in range(5):
        A = RNG.normal(size=(n, n)) + 3 * np.eye(n)
        b = RNG.normal(size=(n, 3))
        np.testing.assert_allclose(np.asarray(f(A, b)), np.linalg.solve(A, b), rtol=1e-10, atol=1e-12)


def test_constant_pivots_are_eliminated_and_the_rest_solved():
    """A velocity map's shape: identity rows and a constant entry beside a symbolic block. The
    constant pivots are eliminated exactly (no division by a symbol), the rest by QR."""
    s = ca.SX.sym("s", 4)
    A = ca.SX([[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]])
    A[2, 0], A[2, 2], A[2, 3] = s[0], ca.cos(s[1]), s[2]
    A[3, 1], A[3, 2], A[3, 3] = s[3], ca.sin(s[1]), 1 + s[0] ** 2
    b = ca.SX.sym("b", 4, 1)
    f = ca.Function("solve", [s, b], [solve_general(A, b)])
    g = ca.Function("A", [s], [A])
    for _ in range(5):
        sv, bv = RNG.uniform(-1, 1, 4), RNG.normal(size=(4, 1))
        An = np.asarray(g(sv))
        np.testing.assert_allclose(np.asarray(f(sv, bv)), np.linalg.solve(An, bv), rtol=1e-10, atol=1e-12)
    # the two identity-like rows are solved without touching the symbolic block: x0 = b0, x1 = b1/2
    x = solve_rows([[A[i, j] for j in range(4)] for i in range(4)], [[b[i]] for i in range(4)])
    assert ca.is_equal(ca.simplify(x[0][0] - b[0]), ca.SX(0)) and ca.is_equal(ca.simplify(x[1][0] - b[1] / 2),
                                                                             ca.SX(0))
