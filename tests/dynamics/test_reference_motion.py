"""The motion a linearisation is taken about (dynamics/linearisation/reference.py), on the
thesis's unicycle (a vertical rolling disc, ẋ = r cos θ φ̇, ẏ = r sin θ φ̇, r = 0.1): the straight
steady motion at V along heading θ has ẋ = V cos θ, ẏ = V sin θ, θ̇ = 0, φ̇ = V / r (by hand);
its reduced state is linear in V along ``family``; an equilibrium is at rest; bad requests are
one ModelError naming every problem."""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.linearisation.reference import EQUILIBRIUM, STEADY, reference_motion

R = 0.1


def test_straight_steady_motion(models):
    model = models["unicycle"]["reduced"]
    theta, V = 0.4, 1.5
    ref = reference_motion(model, speed=V, configuration={"theta": theta, "x": 2.0}, inputs={"tau_phi": 0.01})
    assert ref.kind == STEADY and ref.speed == V
    np.testing.assert_allclose(ref.q, [2.0, 0.0, theta, 0.0])
    np.testing.assert_allclose(ref.qdot, [V * np.cos(theta), V * np.sin(theta), 0.0, V / R], rtol=1e-12)
    np.testing.assert_allclose(ref.u, [0.0, 0.01])
    at_rest = reference_motion(model, configuration={"theta": theta, "x": 2.0})
    np.testing.assert_allclose(ref.z, at_rest.z + V * ref.family, rtol=1e-12, atol=1e-12)
    assert ref.describe(model.system.coordinates) == "straight steady motion at 1.5 m/s (x = 2, theta = 0.4)"


def test_equilibrium_at_rest(models):
    model = models["unicycle"]["reduced"]
    ref = reference_motion(model)
    assert ref.kind == EQUILIBRIUM and ref.family is None and not ref.qdot.any()
    assert ref.describe(model.system.coordinates) == "equilibrium at rest (q = 0)"


def test_bad_requests_name_every_problem(models):
    model = models["unicycle"]["reduced"]
    with pytest.raises(ModelError) as caught:
        reference_motion(model, speed=float("inf"), configuration={"thetta": 1.0}, inputs={"tau": 1.0})
    text = str(caught.value)
    assert "3 problem" in text and "did you mean 'theta'" in text and "'tau' is not an input" in text
    assert "the speed must be a finite number" in text
