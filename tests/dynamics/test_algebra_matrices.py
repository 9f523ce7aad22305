"""Symbolic matrices of the derivations (dynamics/algebra/matrices.py) against sympy's own
determinant and the defining identities: A·N = 0 and rank N = l − k for the division-free null
basis; B·adj(B) = det(B)·I; the numeric pivots independent columns."""
from __future__ import annotations

import numpy as np
import sympy as sp

from nhgait.dynamics.algebra.matrices import (
    is_large,
    null_basis_adjugate,
    numeric_pivots,
    plain_adjugate,
    plain_det,
    strip_factors,
)

a, b, c, th = sp.symbols("a b c theta", real=True)


def test_null_basis_of_the_unicycle_constraint_spans_its_kernel():
    """The unicycle's no-slip row (sin θ, −cos θ, 0): two null vectors, A·N = 0, rank 2."""
    A = sp.Matrix([[sp.sin(th), -sp.cos(th), 0]])
    N = null_basis_adjugate(A, [0])
    assert N.shape == (3, 2)
    assert sp.simplify(A * N) == sp.zeros(1, 2)
    assert N.subs(th, 0.3).rank() == 2


def test_null_basis_of_a_two_row_matrix_and_its_edge_cases():
    A = sp.Matrix([[1, a, 0, b], [0, 1, c, 1]])
    N = null_basis_adjugate(A, [0, 1])
    assert N.shape == (4, 2) and sp.expand(A * N) == sp.zeros(2, 2)
    assert N.subs({a: 0.5, b: -1.0, c: 2.0}).rank() == 2
    assert null_basis_adjugate(sp.zeros(0, 3), []) == sp.eye(3)           # no constraint: all of R³
    assert null_basis_adjugate(sp.Matrix([[1, a]]), [0, 1][:1]).shape == (2, 1)
    assert null_basis_adjugate(sp.Matrix([[1, 0], [0, 1]]), [0, 1]).shape == (2, 0)   # full rank: none


def test_plain_determinant_and_adjugate_agree_with_sympy():
    B = sp.Matrix([[a, sp.sin(th), 1], [b, c, sp.cos(th)], [1, a * b, c]])
    assert sp.simplify(plain_det(B) - B.det()) == 0
    assert sp.simplify(B * plain_adjugate(B) - plain_det(B) * sp.eye(3)) == sp.zeros(3, 3)
    assert not is_large(B)


def test_common_factors_are_stripped_from_columns():
    N = sp.Matrix([[a * sp.cos(th), 2], [a * sp.sin(th), 4]])
    S = strip_factors(N, [th])
    ratio = [sp.simplify(S[i, 0] / N[i, 0]) for i in range(2)]
    assert ratio[0] == ratio[1]                       # a column scaled as a whole
    assert sp.simplify(S[0, 0] * N[1, 0] - S[1, 0] * N[0, 0]) == 0


def test_numeric_pivots_choose_independent_columns():
    A = np.array([[1.0, 2.0, 0.0, 1.0], [2.0, 4.0, 1.0, 0.0]])   # column 1 = 2 × column 0
    pivots = numeric_pivots(A)
    assert len(pivots) == 2 and np.linalg.matrix_rank(A[:, pivots]) == 2
    assert pivots[:1] == [0] and 1 not in pivots
    assert sorted(numeric_pivots(A, order=[3, 2, 1, 0])) == [2, 3]      # the first two in that order
