"""The singular set names every matrix the reduction inverts (issue 7, engine side).

Reference: the basis of S_q for the fiber (x, y, z) of the constraint
sin φ ẋ + cos φ ẏ + ż = 0 is, by hand, (−cos φ, sin φ, 0) and (−1, 0, sin φ) (k×k minors with
the pivot x): at φ = 0 both are (−1, 0, 0), the basis loses rank, and the reduction's q̇ = XK⁻¹P
is undefined there although ω itself has full rank (its Gram determinant is 2).
"""
import math

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import ModelError, SingularConfigurationError, System, derive, from_state, to_state


@pytest.fixture(scope="module")
def tilted():
    s = System(coordinates=["x", "y", "z", "phi"],
               lagrangian="(x_dot**2 + y_dot**2 + z_dot**2)/2 + J*phi_dot**2/2",
               constraints=["sin(phi)*x_dot + cos(phi)*y_dot + z_dot"], forces={"phi": "tau"},
               parameters={"J": 0.5}, fiber=["x", "y", "z"], name="tilted")
    return derive(s, "reduced", use_cache=False)


def _consistent_qdot(phi, a=0.3, b=-0.7, w=0.4):
    # ẋ, ẏ free, ż from the constraint
    return [a, b, -(math.sin(phi) * a + math.cos(phi) * b), w]


def test_singular_set_vanishes_where_the_basis_loses_rank(tilted):
    phi = tilted.system.q[3]
    values = [sp.simplify(e.subs(phi, 0)) for e in tilted.singular_set]
    assert any(v == 0 for v in values), tilted.singular_set
    assert all(sp.simplify(e.subs(phi, 0.7)) != 0 for e in tilted.singular_set)


def test_to_state_refuses_the_basis_singularity(tilted):
    with pytest.raises(SingularConfigurationError, match=r"phi = 0\).*singular set"):
        to_state(tilted, [0, 0, 0, 0.0], _consistent_qdot(0.0))


def test_off_the_singular_set_the_state_round_trips(tilted):
    qd = _consistent_qdot(0.3)
    z = to_state(tilted, [0.1, 0.2, 0.3, 0.3], qd)
    q, qd_back = from_state(tilted, z)
    np.testing.assert_allclose(qd_back, qd, rtol=1e-12, atol=1e-12)


def test_singular_measure_is_normalised(tilted):
    num = tilted.numeric
    pv = num.params()
    assert num.call("singular", [0, 0, 0, 0.0], pv) == pytest.approx(0.0, abs=1e-15)
    for phi in (0.3, 1.0, -2.0):
        assert 0.0 < num.call("singular", [0, 0, 0, phi], pv) <= 1.0


def test_a_matrix_singular_for_every_configuration_is_a_model_error():
    from nhgait.dynamics.algebra.fraction_field import FracField
    x = sp.Symbol("x", real=True)
    F = FracField([x], symbols=[x])
    with pytest.raises(ModelError, match="the test block is singular for every configuration"):
        F.inv(F.mat(sp.Matrix([[x, 2 * x], [1, 2]])), "test block")


def test_factors_that_never_vanish_are_not_listed():
    """The unicycle's Gram determinant of ω_s is (r² + 1)(…): r² + 1 > 0 for every real r, so
    the stated set is J_φ + m r² = 0 alone; factors that can vanish are kept (square-free)."""
    from nhgait.dynamics.derivation.reduction.model import _drop_positive_factors, _positive_everywhere
    r, m, J, phi = sp.symbols("r m J_phi phi")
    assert _positive_everywhere(r**2 + 1)
    assert _positive_everywhere(sp.cos(phi)**2 + 2 * r**4 + 3)
    for can_vanish in (r**2 - 1, r + 1, sp.cos(phi) + 1, J + m * r**2, r**2, sp.cos(phi)**2):
        assert not _positive_everywhere(can_vanish), can_vanish
    assert (_drop_positive_factors(3 * (r**2 + 1) * (J + m * r**2) * sp.cos(phi)**2)
            == (J + m * r**2) * sp.cos(phi))
    unicycle = derive("unicycle", "reduced")
    assert [str(sp.expand(e)) for e in unicycle.singular_set] == ["J_phi + m*r**2"]   # model's own symbols


def test_a_quotient_keeps_the_factors_of_its_numerator_that_can_vanish():
    """A differential drive's Gram determinant of ω_s is the quotient
    (b²r² + 4b² + r²)/(4b²) (sympy's factor of it), which vanishes where its numerator does
    (only at r = b = 0): the stated factor is that numerator, a polynomial — it used to stop the
    derivation with sympy's "a polynomial expected" (a user's robot, 2026-11-29)."""
    from nhgait.dynamics.derivation.reduction.model import _drop_positive_factors
    r, b, phi = sp.symbols("r b phi")
    kept = _drop_positive_factors((b**2 * r**2 + 4 * b**2 + r**2) / (4 * b**2))
    assert sp.fraction(sp.together(kept))[1] == 1
    assert kept.subs({r: 0, b: 0}) == 0 and kept.subs({r: 0.05, b: 0.15}) > 0
    assert _drop_positive_factors(sp.sin(phi) * (r**2 + 1) / b**2) == sp.sin(phi)
    drive = System(coordinates=["x", "y", "theta", "phiL", "phiR"],
                   lagrangian="m/2*(x_dot**2 + y_dot**2) + I/2*theta_dot**2"
                              " + Iw/2*(phiL_dot**2 + phiR_dot**2)",
                   constraints=["cos(theta)*x_dot + sin(theta)*y_dot - r/2*(phiL_dot + phiR_dot)",
                                "-sin(theta)*x_dot + cos(theta)*y_dot",
                                "theta_dot - r/(2*b)*(phiR_dot - phiL_dot)"],
                   forces={"phiL": "tauL", "phiR": "tauR"},
                   parameters={"m": 4.0, "I": 0.08, "Iw": 0.002, "r": 0.05, "b": 0.15}, name="drive")
    model = derive(drive, "reduced", use_cache=False)
    theta, values = drive.q[2], {sp.Symbol(k): v for k, v in (("r", 0.05), ("b", 0.15), ("m", 4.0),
                                                                ("I", 0.08), ("Iw", 0.002))}
    # nothing the reduction inverts loses rank at any heading (the rows of ω are independent for r, b > 0)
    at = [complex(e.subs({s: values[sp.Symbol(s.name)] for s in e.free_symbols if sp.Symbol(s.name) in values}
                         ).subs(theta, v)) for e in model.singular_set for v in (0.0, 0.7, 2.0)]
    assert model.singular_set and all(abs(a) > 1e-6 for a in at), model.singular_set
