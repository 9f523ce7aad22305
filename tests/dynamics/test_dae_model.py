"""What the DAE forms share (dynamics/derivation/dae_model.py), on the thesis's unicycle
(M = diag(m, m, J_θ, J_φ), ω(q) = [[1, 0, 0, −r cos θ], [0, 1, 0, −r sin θ]]) in both DAE forms:
two multipliers; the constraint Gram matrix S = ω M⁻¹ ωᵀ written out by hand,
S = [[1/m + r² cos²θ / J_φ, r² sin θ cos θ / J_φ], [·, 1/m + r² sin²θ / J_φ]]; the singular-set
measure det S / (S₁₁ S₂₂) of the closed loop; the residual ω q̇ zero at a rolling state."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.derivation.dae_model import DAEModel
from nhgait.dynamics.derivation.formulation_base import LoopPoint, Stabilisation

Q, QDOT = np.array([0.1, 0.2, 0.3, 0.4]), np.array([0.05 * np.cos(0.3), 0.05 * np.sin(0.3), 1.0, 0.5])


def _by_hand(params: dict, theta: float) -> np.ndarray:
    m, r, J = params["m"], params["r"], params["J_phi"]
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[1 / m + r * r * c * c / J, r * r * s * c / J],
                     [r * r * s * c / J, 1 / m + r * r * s * s / J]])


@pytest.mark.parametrize("formulation", ["lagrange", "hamilton"])
def test_the_gram_matrix_and_the_measure(models, formulation):
    model = models["unicycle"][formulation]
    assert isinstance(model, DAEModel) and model.multiplier_count() == 2
    system = model.system
    params = system.param_vector(None)
    named = {s.name: float(v) for s, v in zip(system.param_symbols, params, strict=True)}
    x_sym, p_sym = ca.SX.sym("x", len(model.state)), ca.SX.sym("p", len(params))
    gram = ca.Function("S", [x_sym, p_sym], [model.constraint_gram(x_sym, p_sym)])
    q_sym, qd_sym = ca.SX.sym("q", 4), ca.SX.sym("qdot", 4)
    state = ca.Function("x", [q_sym, qd_sym, p_sym], [model.initial_state(q_sym, qd_sym, p_sym)])
    x = np.asarray(state(Q, QDOT, params), dtype=float).ravel()              # (q, q̇) or (q, M q̇)
    residual = ca.Function("g", [q_sym, qd_sym, p_sym], [model.constraint_residual(q_sym, qd_sym, p_sym)])
    np.testing.assert_allclose(np.asarray(residual(Q, QDOT, params)).ravel(), 0.0, atol=1e-15)
    S = np.asarray(gram(x, params))
    np.testing.assert_allclose(S, _by_hand(named, Q[2]), rtol=1e-12)
    point = LoopPoint(x=x_sym, u=ca.SX.zeros(2), params=p_sym, t_c=ca.SX(0), g_int=ca.SX.zeros(2))
    loop = model.loop_dynamics(point, Stabilisation())
    measure = float(ca.Function("h", [x_sym, p_sym], [loop.measure])(x, params))
    assert measure == pytest.approx(np.linalg.det(S) / (S[0, 0] * S[1, 1]), rel=1e-12)
