"""Matrix operations shared by the arithmetic back ends (dynamics/algebra/matrix_ops.py), with
the plain sympy back end, against sympy's Matrix algebra: Gauss–Jordan inverse (with a row swap:
a zero first pivot), block diagonal, transpose, sums, products, a derivative along a vector
field; a matrix singular for every configuration is one ModelError naming it."""
from __future__ import annotations

import pytest
import sympy as sp

from nhgait.dynamics.algebra.matrix_ops import MatrixOps
from nhgait.dynamics.derivation.reduction.arithmetic import SympyArithmetic
from nhgait.dynamics.errors import ModelError

a, b, th = sp.symbols("a b theta", real=True)
A = sp.Matrix([[0, a, 1], [sp.cos(th), 1, 0], [b, 0, 2]])       # A[0, 0] = 0: a row swap
B = sp.Matrix([[1, a], [sp.sin(th), 2]])


@pytest.fixture
def ops() -> MatrixOps:
    return SympyArithmetic()


def _same(ops, rows, matrix):
    return sp.simplify(ops.show(rows) - matrix) == sp.zeros(*matrix.shape)


def test_inverse_and_products(ops):
    inv = ops.gauss_jordan(ops.mat(A))
    assert _same(ops, inv, A.inv())
    assert _same(ops, ops.matmul(ops.mat(A), inv), sp.eye(3))
    rhs = sp.Matrix([[1], [th]])
    assert _same(ops, ops.solve(ops.mat(B), ops.mat(rhs)), B.inv() * rhs)


def test_blocks_transpose_sums(ops):
    assert _same(ops, ops.block_diag(ops.mat(B), ops.mat(A)), sp.diag(B, A))
    assert _same(ops, ops.block_diag([], ops.mat(B)), B)
    assert _same(ops, ops.T(ops.mat(A)), A.T) and ops.T([]) == []
    assert _same(ops, ops.madd(ops.mat(B), ops.mneg(ops.mat(B))), sp.zeros(2, 2))
    assert _same(ops, ops.zeros(2, 3), sp.zeros(2, 3))


def test_derivative_along_a_vector_field(ops):
    col = [a * sp.sin(th), b ** 2]
    got = ops.jvp(col, [a, b, th], [1, 2, 3])
    want = [sp.diff(c, a) + 2 * sp.diff(c, b) + 3 * sp.diff(c, th) for c in col]
    assert all(sp.simplify(g - w) == 0 for g, w in zip(got, want, strict=True))


def test_a_matrix_singular_everywhere_is_named(ops):
    with pytest.raises(ModelError, match="the kinetic metric is singular for every configuration"):
        ops.gauss_jordan(ops.mat(sp.Matrix([[a, 2 * a], [1, 2]])), "kinetic metric")
