"""M(q), V(q) and the Pfaffian rows read off L and ω(q)q̇ without differentiating
(dynamics/derivation/velocity_forms.py), against sympy's derivatives: M = ∂²L/∂q̇²,
V = −L(q, 0), ω_i = ∂c/∂q̇_i, compared exactly (their difference simplifies to 0)."""
import pytest
import sympy as sp

from nhgait.dynamics.derivation.system import System
from nhgait.dynamics.derivation.velocity_forms import linear_split, quadratic_split, velocity_polynomial

x, y, th, b1, b2 = sp.symbols("x y theta beta1 beta2")
xd, yd, thd, b1d, b2d = sp.symbols("x_dot y_dot theta_dot beta1_dot beta2_dot")
QD = [xd, yd, thd, b1d, b2d]
m, a, c, ell, g = sp.symbols("m a c l g", positive=True)

#: bodies written as squares of velocity sums, nested products, a double angle: a cart with two
#: trailers' form (its hitch velocities are sums of terms like l*(beta1_dot + theta_dot)*sin(...))
CART = (m * ((xd - a * thd * sp.sin(th)) ** 2 + (yd + a * thd * sp.cos(th)) ** 2) / 2
        + m * ((xd + c * (b1d + thd) * sp.sin(b1 + th)) ** 2
               + (yd - c * (b1d + thd) * sp.cos(b1 + th)) ** 2) / 2
        + m * ((xd + ell * (b1d + thd) * sp.sin(b1 + th) + c * (b1d + b2d + thd) * sp.sin(b1 + b2 + th)) ** 2
               + (yd - ell * (b1d + thd) * sp.cos(b1 + th)
                  - c * (b1d + b2d + thd) * sp.cos(b1 + b2 + th)) ** 2) / 2
        + a * c * thd * (thd + b1d) * sp.cos(2 * b1) - m * g * sp.sin(b2) * a)


def _zero(expr) -> bool:
    return sp.simplify(sp.expand(expr)) == 0


def test_mass_matrix_and_potential_read_off_equal_the_derivatives():
    split = quadratic_split(CART, QD)
    assert split is not None
    hessian = sp.hessian(CART, QD)
    assert all(_zero(split.M[i, j] - hessian[i, j]) for i in range(5) for j in range(5))
    assert _zero(split.V + CART.xreplace({v: 0 for v in QD}))


def test_pfaffian_rows_read_off_equal_the_derivatives():
    hitch = (xd + ell * (b1d + thd) * sp.sin(b1 + th)) * sp.sin(b1 + th) \
        - (yd - ell * (b1d + thd) * sp.cos(b1 + th)) * sp.cos(b1 + th)
    row = linear_split(hitch, QD)
    assert row is not None
    assert all(_zero(r - sp.diff(hitch, v)) for r, v in zip(row, QD, strict=True))


@pytest.mark.parametrize("expr", [xd ** 3, sp.sin(xd) * yd, xd / (1 + yd ** 2), sp.sqrt(xd ** 2 + 1),
                                  (xd + yd) ** 2 * thd])
def test_not_a_polynomial_of_degree_two_as_written(expr):
    assert velocity_polynomial(expr, QD) is None
    assert quadratic_split(expr + CART, QD) is None


def test_terms_linear_or_free_of_velocities_are_refused():
    assert quadratic_split(CART + a * xd * sp.cos(th), QD) is None          # gyroscopic term
    assert quadratic_split(CART + a * xd * (yd + 1) - a * xd * yd, QD) is None
    assert linear_split(xd * sp.sin(th) + a, QD) is None                     # velocity-free term
    assert linear_split(sp.sin(th) * a, QD) is None                          # no velocity
    assert linear_split((xd + 1) * yd, QD) is None                           # degree two
    # a linear term that cancels on expansion is no linear term
    assert quadratic_split(CART + a * xd * sp.cos(th) - a * sp.cos(th) * xd, QD) is not None


def test_the_structural_check_still_names_the_problem():
    """What the reader refuses, the system's differentiating check names (one error each)."""
    base = dict(coordinates=["x", "y", "theta"], constraints=["x_dot*sin(theta) - y_dot*cos(theta)"],
                parameters={"m": 1.0, "a": 0.5})
    with pytest.raises(Exception, match="not quadratic in the velocities"):
        System(**base, lagrangian="m*(x_dot**2 + y_dot**2)/2 + theta_dot**4")
    with pytest.raises(Exception, match="linear in the velocities"):
        System(**base, lagrangian="m*(x_dot**2 + y_dot**2 + theta_dot**2)/2 + a*x_dot")
    s = System(**base, lagrangian="m*((x_dot - a*theta_dot*sin(theta))**2"
                                  " + (y_dot + a*theta_dot*cos(theta))**2)/2 + theta_dot**2/2")
    arm, mass = sorted(s.param_symbols, key=str)
    assert _zero(s.mass_matrix()[0, 2] + mass * arm * sp.sin(s.q[2]))     # M_xθ = −m a sin θ

