"""Monodromy matrices and Floquet multipliers (ocp/floquet.py) against independent references.

Independent references
----------------------
* **Closed form of a linear periodic system** ż = a(t) A₀ z + b u, a(t) = 1 + ½ cos(2πt/T):
  the matrices a(t)A₀ commute, so the open loop's monodromy is e^{A₀ ∫a} = e^{A₀T}; with the
  feedback u = −k z (B = b I, K = k I) the closed loop's is e^{−bkT} e^{A₀T}; the multipliers
  are e^{λ(A₀)T} and e^{−bkT} e^{λ(A₀)T}. CVODES at rtol 1e-10 gives the entries to ~1e-9
  relative: tolerance 1e-7.
* **Central differences of the flow** computed by another integrator (scipy's DOP853 at rtol
  1e-13, :func:`~nhgait.ocp.floquet.finite_difference_monodromy`: no derivative of f) for a
  nonlinear time-varying loop and for the snakeboard's periodic forward gait: the truncation
  of ε = √rtol steps is ~1e-9 there (measured 3e-9 on the gait at N = 100): tolerance 1e-6,
  the issue's target. The open loop of the snakeboard is a chain of integrators (a fully
  actuated shape, no restoring force): its multipliers are 1, a defective eigenvalue whose
  computed value moves like the square root of a perturbation — its matrix is compared
  entrywise, its multipliers to 1e-3.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.ocp.feedback import Feedback, Weights
from nhgait.ocp.floquet import Loop, finite_difference_monodromy, monodromy, stability, verdict

A0 = np.array([[-0.1, 1.0, 0.0], [-1.0, -0.1, 0.0], [0.0, 0.0, 0.05]])
T, N, B_GAIN, K_GAIN = 2.0, 16, 1.5, 0.4


def _linear_periodic():
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", 3), ca.SX.sym("u", 3)
    a = 1 + 0.5 * ca.cos(2 * np.pi * t / T)
    return ca.Function("ode", [t, z, u], [a * ca.mtimes(ca.DM(A0), z) + B_GAIN * u])


def _zero_plan(gain):
    t = np.linspace(0.0, T, N + 1)
    return (t, np.zeros((3, N + 1)), np.zeros((3, N)), np.zeros((N, 2, 3)),
            np.repeat((gain * np.eye(3))[None], N, 0))


def test_monodromy_of_a_linear_periodic_system_is_its_closed_form():
    """Open loop e^{A₀T}, closed loop e^{−bkT}e^{A₀T} (module docstring), entries to 1e-7."""
    from scipy.linalg import expm
    ode = _linear_periodic()
    t, ref, u, rates, gains = _zero_plan(K_GAIN)
    open_loop, _ = monodromy(Loop(ode, t, ref, u, rates, None))
    closed_loop, _ = monodromy(Loop(ode, t, ref, u, rates, gains))
    exact = expm(A0 * T)
    assert np.max(np.abs(open_loop - exact)) <= 1e-7
    assert np.max(np.abs(closed_loop - np.exp(-B_GAIN * K_GAIN * T) * exact)) <= 1e-7


def test_stability_reports_the_closed_form_multipliers_and_verdicts():
    """Multipliers e^{λ(A₀)T} (open: the growing third state makes it unstable by e^{0.1}) and
    e^{−bkT}e^{λ(A₀)T} (closed: stable); fibre states are left out of the open loop's map."""
    ode = _linear_periodic()
    t, ref, u, rates, gains = _zero_plan(K_GAIN)
    ones = np.ones(3)
    feedback = Feedback(t=t, states=ref, controls=u, gains=gains, rates=rates, state_names=("p", "q", "r"),
                        control_names=("u1", "u2", "u3"), weights=Weights(ones, ones, ones, ones, ones),
                        lower=-np.inf * ones, upper=np.inf * ones)
    result = stability(ode, feedback)
    expected = np.exp(np.linalg.eigvals(A0) * T)
    expected = expected[np.argsort(-np.abs(expected))]
    assert np.allclose(result.open_multipliers, expected, atol=1e-8)
    assert np.allclose(result.closed_multipliers, np.exp(-B_GAIN * K_GAIN * T) * expected, atol=1e-8)
    assert result.verdicts()["open_loop"] == ("unstable", pytest.approx(np.exp(0.05 * T), abs=1e-8))
    assert result.verdicts()["closed_loop"][0] == "stable"
    assert "grows by 1.11× each period" in result.summary()[0]
    fibre = stability(ode, feedback, fiber=("r",))
    assert fibre.periodic_states == ("p", "q")
    assert np.allclose(np.abs(fibre.open_multipliers), np.exp(-0.1 * T), atol=1e-8)


def test_a_variational_process_that_dies_is_a_runtime_error(monkeypatch):
    """The two monodromies of a larger state (above floquet.INLINE_STATES) run in supervised
    children: one that dies without an answer is the RuntimeError the planner reports as "not
    computed" — not a hang, not a wrong matrix."""
    import os

    from nhgait.ocp import floquet
    from nhgait.ocp.supervision import can_fork
    if not can_fork():
        pytest.skip("the monodromies run in this process without fork")
    ode = _linear_periodic()
    t, ref, u, rates, gains = _zero_plan(K_GAIN)
    ones = np.ones(3)
    feedback = Feedback(t=t, states=ref, controls=u, gains=gains, rates=rates, state_names=("p", "q", "r"),
                        control_names=("u1", "u2", "u3"), weights=Weights(ones, ones, ones, ones, ones),
                        lower=-np.inf * ones, upper=np.inf * ones)
    monkeypatch.setattr(floquet, "INLINE_STATES", 0)       # this 3-state loop as a larger one
    monkeypatch.setattr(floquet, "monodromy", lambda *a, **k: os._exit(3))
    with pytest.raises(RuntimeError, match="variational equations' process ended without an answer"):
        stability(ode, feedback)


def test_verdict_thresholds():
    assert verdict([0.5, 0.99])[0] == "stable"
    assert verdict([1.0 + 1e-6j])[0] == "marginal"
    assert verdict([1.01])[0] == "unstable"


def test_monodromy_of_a_nonlinear_time_varying_loop_matches_finite_differences():
    """A forced Duffing–van der Pol pair with a varying reference, gains and inputs: the
    variational equation (CVODES) against central differences of DOP853 flows, to 1e-6."""
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", 2), ca.SX.sym("u", 1)
    f = ca.vertcat(z[1], -z[0] - 0.3 * z[0] ** 3 + 0.2 * (1 - z[0] ** 2) * z[1] + ca.sin(1.3 * t) + u[0])
    ode = ca.Function("ode", [t, z, u], [f])
    n = 12
    times = np.linspace(0.0, 3.0, n + 1)
    rng = np.random.default_rng(4)
    ref = np.vstack([np.sin(times), np.cos(times)])
    rates = np.stack([np.stack([[np.cos(a), -np.sin(a)], [np.cos(b), -np.sin(b)]]) for a, b in
                      zip(times[:-1], times[1:], strict=True)])
    controls, gains = rng.normal(size=(1, n)), rng.uniform(0.2, 1.5, (n, 1, 2))
    analytic, _ = monodromy(Loop(ode, times, ref, controls, rates, gains))
    reference = finite_difference_monodromy(Loop(ode, times, ref, controls, rates, gains))
    assert np.max(np.abs(analytic - reference)) <= 1e-6 * max(1.0, np.max(np.abs(reference)))


@pytest.fixture(scope="module")
def forward():
    from nhgait.gaits.planner import plan, prepare
    result = plan("snakeboard", "forward", intervals=40, jit=False)
    assert result.success
    return result, prepare(result.plan)


def test_snakeboard_forward_gait_multipliers_match_finite_differences(forward, tmp_path):
    """The periodic forward gait: the closed loop's monodromy and multipliers agree with central
    differences of DOP853 flows (rtol 1e-13) to 1e-6; the open loop's matrix too, its
    multipliers are the chain of integrators' 1 (marginal); solution.json carries both."""
    import json

    from nhgait.ocp.transcription import ode_function
    result, prepared = forward
    st, fb = result.solution.stability, result.solution.feedback
    ode = ode_function(prepared.problem)
    closed = finite_difference_monodromy(Loop(ode, fb.t, fb.states, fb.controls, fb.rates, fb.gains))
    assert np.max(np.abs(closed - st.closed_loop)) <= 1e-6
    mu = np.linalg.eigvals(closed)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    assert np.max(np.abs(mu - st.closed_multipliers)) <= 1e-6
    assert verdict(st.closed_multipliers)[0] == "stable"
    opened = finite_difference_monodromy(Loop(ode, fb.t, fb.states, fb.controls, fb.rates, None))
    assert np.max(np.abs(opened - st.open_loop)) <= 1e-6
    assert st.periodic_states == ("psi", "phi", "forward_velocity", "psi_dot", "phi_dot")
    assert np.max(np.abs(st.open_multipliers - 1)) <= 1e-3
    assert verdict(st.open_multipliers)[0] == "marginal"
    data = json.loads(result.solution.to_json(tmp_path / "solution.json").read_text())
    assert data["stability"]["closed_loop"]["verdict"] == "stable"
    assert len(data["stability"]["closed_loop"]["multipliers"]) == 8


def test_a_plan_without_periodic_conditions_has_no_stability():
    from nhgait.gaits.planner import plan
    result = plan("unicycle", "parallel-park", intervals=20, jit=False)
    assert result.solution.feedback is not None
    assert result.solution.stability is None
