"""BufferedCall: a CasADi Function called through its buffer interface gives the values of the
expression it holds (checked against the closed form in numpy) and the same numbers, bit for
bit, as the ordinary call; a sparse Function falls back to the ordinary call."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics.buffered_call import BufferedCall


def _unicycle_like():
    """ż = (cos θ v, sin θ v, ω, u₀ − c v, u₁ + t) with z = (x, y, θ, v, ω), c = 0.3."""
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", 5), ca.SX.sym("u", 2)
    rate = ca.vertcat(ca.cos(z[2]) * z[3], ca.sin(z[2]) * z[3], z[4], u[0] - 0.3 * z[3], u[1] + t)
    return ca.Function("ode", [t, z, u], [rate])


def _closed_form(t, z, u):
    return np.array([np.cos(z[2]) * z[3], np.sin(z[2]) * z[3], z[4], u[0] - 0.3 * z[3], u[1] + t])


def test_values_match_the_closed_form_and_the_ordinary_call():
    f = _unicycle_like()
    fast = BufferedCall(f)
    rng = np.random.default_rng(7)
    for _ in range(20):
        t, z, u = float(rng.uniform(-2, 2)), rng.uniform(-3, 3, 5), rng.uniform(-1, 1, 2)
        got = fast(t, z, u)
        np.testing.assert_allclose(got, _closed_form(t, z, u), rtol=1e-15, atol=1e-15)
        assert np.array_equal(got, np.asarray(f(t, z, u)).ravel())        # the same evaluation


def test_each_call_returns_its_own_array():
    fast = BufferedCall(_unicycle_like())
    first = fast(0.0, np.ones(5), np.zeros(2))
    fast(1.0, np.zeros(5), np.ones(2))
    np.testing.assert_allclose(first, _closed_form(0.0, np.ones(5), np.zeros(2)), rtol=1e-15)


def test_matrix_inputs_are_read_column_major():
    M, x = ca.SX.sym("M", 2, 3), ca.SX.sym("x", 3)
    fast = BufferedCall(ca.Function("Mx", [M, x], [ca.mtimes(M, x)]))
    A, v = np.arange(6.0).reshape(2, 3), np.array([1.0, -2.0, 0.5])
    np.testing.assert_allclose(fast(A, v), A @ v, rtol=1e-15)


def test_a_sparse_output_falls_back_to_the_ordinary_call():
    x = ca.SX.sym("x", 3)
    sparse = ca.Function("s", [x], [ca.vertcat(x[0], ca.SX(1, 1), x[2])])   # a structural zero
    assert not sparse.sparsity_out(0).is_dense()
    np.testing.assert_allclose(BufferedCall(sparse)([1.0, 2.0, 3.0]), [1.0, 0.0, 3.0])


def test_a_wrong_number_of_arguments_is_an_error():
    with pytest.raises(TypeError, match="takes 3 arguments, got 2"):
        BufferedCall(_unicycle_like())(0.0, np.zeros(5))
