"""Rational functions as fractions of one polynomial ring over ℚ (dynamics/algebra/ring.py),
against sympy's own ``cancel``/``together`` and Python's ``fractions``: a scene's 0.1 is 1/10
(the shortest decimal of the double), a walked fraction equals the expression, sums over one
denominator stay over it, and what the ring cannot hold is refused."""
from __future__ import annotations

from fractions import Fraction

import pytest
import sympy as sp

from nhgait.dynamics.algebra.ring import NotRational, float_rational, to_field, walk_fraction

x, y, th = sp.symbols("x y theta", real=True)


def test_a_double_is_its_shortest_decimal():
    assert float_rational(sp.Float(0.1)) == sp.Rational(1, 10)
    assert float_rational(sp.Float(2.5)) == sp.Rational(5, 2)
    r = float_rational(sp.Float(1 / 3))
    assert Fraction(int(r.p), int(r.q)) == Fraction(repr(1 / 3)) and float(r) == 1 / 3
    precise = sp.Float("0.1", 30)                    # more than a double: its exact binary value
    assert float_rational(precise) == sp.Rational(precise)


@pytest.mark.parametrize("e", [x / (1 + y) + y ** 2 / (1 + y) - sp.Rational(3, 7),
                               (x ** 2 - 1) / (x - 1) * y ** -2 + 0.1 * x,
                               sp.sin(th) ** 2 / (x + sp.cos(th)) + 1 / x])
def test_a_walked_fraction_is_the_expression(e):
    f = to_field(e, ())
    back = f.num.as_expr() / f.den.as_expr()          # in the ring's generators (x, y, sin θ, cos θ)
    assert sp.simplify(back - e.subs(sp.Float(0.1), sp.Rational(1, 10))) == 0


def test_sums_over_one_denominator_are_added_first():
    f = to_field(x / (1 + y) + y / (1 + y), ())
    assert f.num.as_expr() == x + y and f.den.as_expr() == y + 1          # not (1 + y)²


def test_opaque_subexpressions_are_generators_and_the_rest_is_refused():
    f = to_field(sp.sqrt(x) + x ** y, ())
    assert set(f.ring.symbols) == {sp.sqrt(x), x ** y} and f.den.as_expr() == 1
    with pytest.raises(NotRational):
        to_field(sp.Integer(3), ())                  # no generator: no ring to hold it
    R, gx = to_field(x, ()).ring, to_field(x, ()).num
    with pytest.raises(NotRational):
        walk_fraction(sp.sqrt(x), R, {x: (gx, R.one)})    # a node the table does not map
