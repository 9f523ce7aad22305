"""The method's symbols kept apart from the user's (dynamics/derivation/input/notation.py) and named
quantities as numbers (dynamics/derivation/quantities.py).

References: the qualification rule of the notation module written out (``p`` → ``p_nh`` →
``p_red`` → ``p_m`` → ``p_nh2`` …); a unicycle's forward speed v = ẋ cos θ + ẏ sin θ and a
kinetic energy written with numpy."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import System
from nhgait.dynamics.derivation.input.notation import method_name, system_names
from nhgait.dynamics.derivation.quantities import motion_quantity_function, quantity_function


def test_method_names_step_aside_for_the_users():
    assert method_name("p", {"x", "y"}) == "p"
    assert method_name("p", {"p"}) == "p_nh"
    assert method_name("p", {"p", "p_nh"}) == "p_red"
    assert method_name("p", {"p", "p_nh", "p_red", "p_m"}) == "p_nh2"
    assert method_name("p", {"p", "p_nh", "p_red", "p_m", "p_nh2"}) == "p_nh3"


@pytest.fixture(scope="module")
def cart():
    """A unicycle-like cart whose heading is named ``p`` and mass ``s`` (the method's letters)."""
    return System(["x", "y", "p"], "s*(x_dot**2 + y_dot**2)/2 + J*p_dot**2/2",
                  ["sin(p)*x_dot - cos(p)*y_dot"], forces={"x": "F*cos(p)", "y": "F*sin(p)", "p": "tau"},
                  parameters={"s": 2.0, "J": 0.5}, inputs=["F", "tau"])


def test_system_names_are_every_name_the_user_gave(cart):
    assert system_names(cart) == {"x", "y", "p", "x_dot", "y_dot", "p_dot", "s", "J", "F", "tau", "t"}


def test_quantities_evaluate_to_their_closed_forms(cart):
    q, qd = cart.q, cart.q_dot
    s = next(v for v in cart.param_symbols if v.name == "s")
    f = quantity_function(cart, {"v": qd[0] * sp.cos(q[2]) + qd[1] * sp.sin(q[2]),
                                 "T": s * (qd[0] ** 2 + qd[1] ** 2) / 2})
    rng = np.random.default_rng(5)
    for _ in range(3):
        qv, qdv = rng.uniform(-2, 2, 3), rng.uniform(-2, 2, 3)
        params = [2.0 if v.name == "s" else 0.5 for v in cart.param_symbols]
        y = np.asarray(f(qv, qdv, params)).ravel()
        np.testing.assert_allclose(y, [qdv[0] * np.cos(qv[2]) + qdv[1] * np.sin(qv[2]),
                                       2.0 * (qdv[0] ** 2 + qdv[1] ** 2) / 2], rtol=1e-14)
    assert quantity_function(cart, {}).size1_out(0) == 0


def test_motion_quantities_take_accelerations_and_inputs(cart):
    F = next(u for u in cart.input_symbols if u.name == "F")
    xdd = sp.Symbol("x_ddot", real=True)
    f = motion_quantity_function(cart, {"ax": xdd, "F2": F ** 2})
    y = np.asarray(f([0, 0, 0], [0, 0, 0], [1.5, 0, 0], [3.0, 0.1], [2.0, 0.5])).ravel()
    np.testing.assert_array_equal(y, [1.5, 9.0])


def test_a_derivation_names_its_momentum_apart_from_a_coordinate_named_p(cart):
    """The reduced state of the cart: its coordinates, then the nonholonomic momentum (``p``,
    here ``p_nh`` since the heading is ``p``) and the shape momentum ``pt_p``."""
    from nhgait.dynamics import derive
    model = derive(cart, "reduced", use_cache=False)
    assert model.state_names == ("x", "y", "p", "p_nh", "pt_p")
