"""The wheel constraints of a URDF robot (dynamics/derivation/urdf/wheels.py) against the rolling
and skating conditions written by hand for a planar base with body velocity ν = (u, w, θ̇, φ̇):

* a wheel of radius ρ spinning by φ about the base's y axis at the base point rolls when its
  contact point does not move: u − ρ φ̇ = 0 (along the ground) and w = 0 (along the axle);
* a skate (the snakeboard's) at x = l on the base, axle along y, does not slide sideways:
  w + l θ̇ = 0;
* in q̇ a row (a, b, c, d) of ν reads (a cos θ − b sin θ) ẋ + (a sin θ + b cos θ) ẏ + c θ̇ + d φ̇;
* a differential drive (two rolling wheels on one axle) has three independent rows of its four.
"""
from __future__ import annotations

from types import SimpleNamespace

import sympy as sp

from nhgait.dynamics.derivation.urdf import wheels

u, w, th_dot, phi_dot = NU = sp.symbols("u w theta_dot phi_dot", real=True)
rho, l_, b = sp.Rational(1, 10), sp.Rational(2, 5), sp.Symbol("b", positive=True)   # URDFs hold numbers
x_dot, y_dot = sp.symbols("x_dot y_dot", real=True)
theta = sp.Symbol("theta", real=True)


def _row_value(row) -> sp.Expr:
    return sp.expand((sp.Matrix(row) * sp.Matrix(NU))[0])


def test_a_rolling_wheel_and_a_skate_give_the_hand_written_rows():
    rolling_body = SimpleNamespace(R=sp.eye(3),                       # the wheel at φ = 0
                                   Jv=sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]]),
                                   Jw=sp.Matrix([[0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 1, 0]]))
    rows = wheels.wheel_rows(rolling_body, sp.eye(3), sp.zeros(3, 1), sp.Matrix([0, 1, 0]), rho)
    assert sp.simplify(_row_value(rows.side) - w) == 0
    assert sp.simplify(_row_value(rows.rolling) + (u - rho * phi_dot)) == 0      # forward = n × a = −x
    base = SimpleNamespace(R=sp.eye(3), Jv=sp.Matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]]),
                           Jw=sp.Matrix([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 1, 0]]))
    skate = wheels.wheel_rows(base, sp.eye(3), sp.Matrix([l_, 0, 0]), sp.Matrix([0, 1, 0]), None)
    assert skate.rolling is None
    assert sp.simplify(_row_value(skate.side) - (w + l_ * th_dot)) == 0


def test_a_row_in_body_velocities_is_written_in_qdot():
    a, b_, c, d = sp.symbols("a b c d", real=True)
    got = wheels.in_qdot(sp.Matrix([a, b_, c, d]), theta, (x_dot, y_dot, sp.Symbol("th_dot"),
                                                              sp.Symbol("ph_dot")))
    want = ((a * sp.cos(theta) - b_ * sp.sin(theta)) * x_dot
            + (a * sp.sin(theta) + b_ * sp.cos(theta)) * y_dot
            + c * sp.Symbol("th_dot") + d * sp.Symbol("ph_dot"))
    assert sp.simplify(got - want) == 0


def test_a_differential_drive_keeps_three_of_its_four_rows():
    """Wheels at y = ±b spinning by φ_L, φ_R: side rows −sin θ ẋ + cos θ ẏ twice, rolling rows
    cos θ ẋ + sin θ ẏ ∓ b θ̇ − ρ φ̇. The second side row is the first: it goes."""
    th_d, pl_d, pr_d = sp.symbols("theta_dot phiL_dot phiR_dot", real=True)
    side = -sp.sin(theta) * x_dot + sp.cos(theta) * y_dot
    forward = sp.cos(theta) * x_dot + sp.sin(theta) * y_dot
    rows = [side, forward - b * th_d - rho * pl_d, side, forward + b * th_d - rho * pr_d]
    rows = [r.subs({b: 0.25}) for r in rows]
    kept = wheels.independent_rows(rows, ([theta], [x_dot, y_dot, th_d, pl_d, pr_d]))
    assert kept == [0, 1, 3]
