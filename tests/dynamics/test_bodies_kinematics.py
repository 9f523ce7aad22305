"""The kinematics and the energy of a body tree (dynamics/derivation/bodies/kinematics.py,
builder.py) against the same quantities written by hand here for a planar two-link arm on a
moving base: link 1 turns about the vertical axis at the base point by s1, link 2 about the
vertical axis at the end of link 1 (x = l1) by s2, a point mass m at the tip of link 2.

In the base frame the tip is at p = (l1 cos s1 + l2 cos(s1+s2), l1 sin s1 + l2 sin(s1+s2), 0);
with the base's body velocity ν = (u, w, ψ̇, ṡ1, ṡ2) its velocity is
(u, w, 0) + ψ̇ e_z × p + ∂p/∂s ṡ, and T = ½ m |v|² (sympy's derivatives, not the product of
exponentials the library uses)."""
from __future__ import annotations

import numpy as np
import sympy as sp

from nhgait.dynamics.derivation.bodies import builder, kinematics
from nhgait.dynamics.derivation.bodies.statement import read_multibody

l1, l2, m, g = sp.symbols("l1 l2 m g", real=True)
s1, s2 = sp.symbols("s1 s2", real=True)
NAMES = {"l1": l1, "l2": l2, "m": m, "g": g}
ARM = {"base": ["x", "y", "psi"], "bodies": [
    {"name": "upper", "parent": "base", "joint": "s1", "axis": [0, 0, 1], "point": [0, 0, 0]},
    {"name": "lower", "parent": "upper", "joint": "s2", "axis": [0, 0, 1], "point": ["l1", 0, 0],
     "mass": "m", "com": ["l1 + l2", 0, 0], "inertia": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}]}


def _arm():
    problems: list = []
    multibody = read_multibody(ARM, NAMES, problems)
    assert problems == [] and multibody.coordinates == ("x", "y", "psi", "s1", "s2")
    return multibody


def _tip():
    return sp.Matrix([l1 * sp.cos(s1) + l2 * sp.cos(s1 + s2), l1 * sp.sin(s1) + l2 * sp.sin(s1 + s2), 0])


def _zero(matrix) -> bool:
    """Zero at 8 random values of every symbol (to rounding: the entries are O(1) trigonometric
    polynomials)."""
    matrix = sp.Matrix(matrix)
    symbols = sorted(matrix.free_symbols, key=str)
    f = sp.lambdify(symbols, matrix, "numpy")
    rng = np.random.default_rng(0)
    return all(np.max(np.abs(np.asarray(f(*rng.uniform(-2, 2, len(symbols))), dtype=float)), initial=0.0)
               < 1e-12 for _ in range(8))


def test_the_tip_is_placed_and_moves_as_the_hand_written_kinematics_say():
    multibody = _arm()
    columns = {c: i for i, c in enumerate(multibody.coordinates)}
    placed = kinematics.frames(multibody, columns)
    lower = placed["lower"]
    tip = lower.place(sp.Matrix([l1 + l2, 0, 0]))
    assert _zero(tip - _tip())
    J = kinematics.point_jacobian(lower, tip, 5)
    want = sp.zeros(3, 5)
    want[0, 0] = want[1, 1] = 1                                   # the base's own velocity (u, w)
    want[:, 2] = kinematics.EZ.cross(_tip())                      # ψ̇ e_z × p
    want[:, 3:] = _tip().jacobian([s1, s2])                       # ∂p/∂s
    assert _zero(J - want)
    assert _zero(lower.angular_jacobian(5) - sp.Matrix([[0, 0, 0, 0, 0], [0, 0, 0, 0, 0], [0, 0, 1, 1, 1]]))
    w = sp.Matrix(sp.symbols("w0:3", real=True))
    assert _zero(kinematics.cross_matrix(tip) * w - tip.cross(w))


def test_the_kinetic_metric_is_the_hand_written_energy():
    multibody = _arm()
    K, V = builder.multibody_energy(multibody)
    nu = sp.Matrix(sp.symbols("u w psi_dot s1_dot s2_dot", real=True))
    p = _tip()
    v = sp.Matrix([nu[0], nu[1], 0]) + nu[2] * kinematics.EZ.cross(p) + p.jacobian([s1, s2]) * nu[3:, :]
    T = m * (v.T * v)[0] / 2
    assert _zero(K - sp.hessian(T, nu))
    assert V == 0                                                  # a planar arm: no height
