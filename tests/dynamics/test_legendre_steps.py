"""Steps 9–11 of the reduction (dynamics/derivation/reduction/legendre.py, thesis §3.2.3) on a
metric written here, with the exact sympy back end, against sympy's matrix algebra: P = K v
(step 9), v = K⁻¹ P with K⁻¹ = blockdiag(K_Ω⁻¹, K_r⁻¹) (step 10), h = ½ Pᵀ K⁻¹ P + V (step 11)."""
from __future__ import annotations

from types import SimpleNamespace

import sympy as sp

from nhgait.dynamics.derivation.reduction.arithmetic import SympyArithmetic
from nhgait.dynamics.derivation.reduction.legendre import hamiltonian, legendre_transform, velocities

th, m, J, g = sp.symbols("theta m J g", real=True)
P = sp.symbols("p pt_psi", real=True)
V_SYM = sp.symbols("Omega psi_dot", real=True)
#: a block-diagonal metric: one nonholonomic direction (d = 1), one shape coordinate
K = sp.Matrix([[m + J * sp.sin(th) ** 2, 0], [0, J]])
POTENTIAL = m * g * sp.cos(th)


def _pieces():
    arith = SympyArithmetic()
    layout = SimpleNamespace(d=1, V=POTENTIAL)
    symbols = SimpleNamespace(P=list(P), v=list(V_SYM))
    connection = SimpleNamespace(K=arith.mat(K), K_nh_inv=arith.mat(K[:1, :1].inv()))
    return arith, layout, symbols, connection


def test_steps_9_to_11_are_the_legendre_transform_of_the_metric():
    arith, layout, symbols, connection = _pieces()
    step9 = legendre_transform(arith, layout, symbols, connection)
    assert step9.number == 9
    assert sp.simplify(step9.items["P"] - K * sp.Matrix(V_SYM)) == sp.zeros(2, 1)
    stepped = velocities(arith, layout, symbols, connection)
    assert stepped[0].number == 10
    assert sp.simplify(arith.show(stepped[1]) - K.inv()) == sp.zeros(2, 2)
    assert sp.simplify(stepped[0].items["v"] - K.inv() * sp.Matrix(P)) == sp.zeros(2, 1)
    step11, h = hamiltonian(arith, layout, symbols, stepped[1])
    want = (sp.Matrix(P).T * K.inv() * sp.Matrix(P))[0] / 2 + POTENTIAL
    assert step11.number == 11 and sp.simplify(h - want) == 0
