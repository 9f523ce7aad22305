"""The arithmetic the 20 steps are written against (dynamics/derivation/reduction/arithmetic.py,
with the ring of dynamics/algebra/fraction_field.py): the three back ends — exact ring
fractions, plain sympy and CasADi SX — give the same inverse, product and derivative of a
trigonometric kinetic metric as sympy's own ``Matrix.inv`` and ``diff`` (the independent
reference), evaluated at random points to 1e-12."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics.algebra.fraction_field import FracField
from nhgait.dynamics.derivation.reduction.arithmetic import CasadiArithmetic, SympyArithmetic

th, a, m = sp.symbols("theta a m", real=True)
#: a 2 × 2 metric of a body whose centre of mass sits a ahead of the axle (Chaplygin-like)
K = sp.Matrix([[m, m * a * sp.sin(th)], [m * a * sp.sin(th), 1 + m * a ** 2]])
P = sp.Matrix([[sp.cos(th)], [a]])
POINTS = [{th: 0.3, a: 0.5, m: 2.0}, {th: -1.2, a: 0.1, m: 0.7}, {th: 2.5, a: 1.3, m: 1.1}]


def _backends():
    return {"ring": FracField([K, P], symbols=(a, m), angles=(th,)), "sympy": SympyArithmetic(),
            "casadi": CasadiArithmetic()}


def _values(backend, rows, point) -> np.ndarray:
    """The numbers of a back end's matrix (rows of elements) at ``point``."""
    if isinstance(backend, CasadiArithmetic):
        sx = backend.show(rows)
        syms = list(backend.table)
        f = ca.Function("f", [ca.vertcat(*[backend.table[s] for s in syms])], [sx])
        return np.asarray(f([point[s] for s in syms]), float)
    return np.array([[float(sp.sympify(backend.expr(e)).subs(point)) for e in r] for r in rows])


@pytest.mark.parametrize("name", ["ring", "sympy", "casadi"])
def test_inverse_product_and_derivative_agree_with_sympy(name):
    backend = _backends()[name]
    Kb, Pb = backend.mat(K), backend.mat(P)
    Kinv = backend.inv(Kb)
    h = backend.matmul(backend.T(Pb), backend.matmul(Kinv, Pb))       # Pᵀ K⁻¹ P (the energy's form)
    dK = [[backend.diff(e, th) for e in r] for r in Kb]
    references = {"inv": K.inv(), "h": (P.T * K.inv() * P), "dK": K.diff(th)}
    for point in POINTS:
        for got, key in ((Kinv, "inv"), (h, "h"), (dK, "dK")):
            want = np.array(references[key].subs(point), dtype=float)
            np.testing.assert_allclose(_values(backend, got, point), want, rtol=1e-12, atol=1e-12,
                                       err_msg=f"{name} {key} at {point}")
