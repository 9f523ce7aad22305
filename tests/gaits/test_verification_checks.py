"""The three verification checks (gaits/verification/checks.py, issue 41) on an unstable linear
robot whose growth rate and open-loop amplification are known in closed form.

tests/scenes/unstable_line.toml: x'' = (k/m) x + F/m beside a free cart s; in the momentum
coordinates z = (s, x, p, pt_x) (p = m ṡ, pt_x = m ẋ) the linear ODE ż = A z + B F has

    A = [[0, 0, 1/m, 0], [0, 0, 0, 1/m], [0, 0, 0, 0], [0, k, 0, 0]],   eig A = {0, 0, ±√(k/m)},

so the growth rate is √(k/m) = 4 /s exactly and the open loop's transition over T is
expm(A T) (scipy's Padé approximant, independent of the plan's RK4 stage Jacobians).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from nhgait.gaits.plan_summary import summary_lines
from nhgait.gaits.planner import plan
from nhgait.gaits.verification import checks as verification_checks
from nhgait.gaits.verification.checks import GaitChecks, checks_of, log_amplification

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "unstable_line.toml"
M, K, T = 1.0, 16.0, 5.0


def _A(k: float) -> np.ndarray:
    return np.array([[0, 0, 1 / M, 0], [0, 0, 0, 1 / M], [0, 0, 0, 0], [0, k, 0, 0]], float)


@pytest.fixture(scope="module")
def unstable():
    return plan(str(SCENE), jit=False, max_guesses=1)


def test_an_unstable_plan_verifies_by_the_interval_and_closed_loop_checks_and_fails_open_loop(unstable):
    checks = checks_of(unstable.solution)
    assert unstable.success, unstable.solution.message
    assert checks.decided_by == "interval and closed loop"
    assert checks.interval_error <= 1e-6 and checks.closed_loop_error <= 1e-6
    # the open loop misses (reported, not deciding), and no refinement was spent on it
    assert not unstable.solution.verification.passed and checks.open_loop_error > 1e-6
    assert int(unstable.solution.settings.get("rk4_steps", 4)) == 4
    assert not any("refined" in a.label for a in unstable.attempts)
    # the growth rate named: sqrt(k/m), the eigenvalue of the linear ODE (exact for a linear f)
    assert checks.growth_rate == pytest.approx(math.sqrt(K / M), abs=1e-9)
    text = "\n".join(summary_lines(unstable))
    assert "largest growth rate 4 /s" in text and "decided by         the interval and closed loop" in text
    assert "verified by the interval and closed-loop checks" in repr(unstable.solution)


def test_the_amplification_is_that_of_the_exact_transition(unstable):
    # ln σ_max(expm(A T)); the plan's RK4 stage Jacobians (h/4 = 0.0125 s, λh/4 = 0.05) differ by
    # a relative O((λh/4)^4 / 120 · N M) ≈ 2e-5 of the e-folds: tolerance 1e-3
    checks = checks_of(unstable.solution)
    exact = math.log(np.linalg.norm(expm(_A(K) * T), 2))
    assert checks.amplification == pytest.approx(exact, abs=1e-3)
    assert checks.amplification > math.log(verification_checks.STABLE_AMPLIFICATION)


def test_a_stable_gait_is_decided_by_the_open_loop():
    # k < 0: a spring, eigenvalues ±4i — the open loop amplifies errors by a bounded factor
    result = plan(str(SCENE), jit=False, max_guesses=1, params={"k": -K})
    checks = checks_of(result.solution)
    assert checks.stable and checks.decided_by == "open loop"
    assert result.success == result.solution.verification.passed
    assert checks.growth_rate == pytest.approx(0.0, abs=1e-9)
    assert checks.amplification == pytest.approx(math.log(np.linalg.norm(expm(_A(-K) * T), 2)), abs=1e-3)


def test_log_amplification_does_not_overflow():
    # 400 steps of ×10: 10⁴⁰⁰ overflows a float; its logarithm does not
    A = np.stack([10.0 * np.eye(2)] * 400)
    assert log_amplification(A) == pytest.approx(400 * math.log(10.0), rel=1e-12)
    assert math.isnan(log_amplification(np.full((3, 2, 2), np.nan)))


def test_the_checks_round_trip_through_solution_json(unstable):
    checks = checks_of(unstable.solution)
    assert GaitChecks.from_dict(checks.to_dict()) == checks
    data = unstable.solution.to_dict()["settings"]["checks"]
    assert data["decided_by"] == "interval and closed loop" and data["stability"]["stable"] is False


COIN = Path(__file__).resolve().parents[1] / "scenes" / "coin_park.toml"


@pytest.mark.slow          # about 15-30 s: a 5-coordinate robot, derived and compiled once
def test_the_coin_parallel_park_is_verified_by_the_interval_and_closed_loop_checks():
    """Issue 41's target: a thin coin (r = 0.2 m) rolling upright, parked 1 m sideways in 6 s.
    Upright at rest its lean is an inverted pendulum, (I + m r²) lean'' = m g r lean with
    I = m r²/4: growth rate √(4g/(5r)) = 6.264 /s at the first node (rest), e^{38} over 6 s."""
    result = plan(str(COIN), max_guesses=1)
    checks = checks_of(result.solution)
    assert result.success, result.solution.message
    assert checks.decided_by == "interval and closed loop"
    assert checks.interval_error <= 1e-6 and checks.closed_loop_error <= 1e-6
    assert checks.open_loop_error > 1e-3                     # the open loop falls over
    assert int(result.solution.settings.get("rk4_steps", 4)) == 4      # nothing spent refining
    s = result.solution
    at_rest = verification_checks.growth_rate(s.problem.ode(), s.t[:1], s.z[:1].T, s.u[:1].T)
    assert at_rest == pytest.approx(math.sqrt(4 * 9.81 / (5 * 0.2)), abs=1e-9)
    assert checks.growth_rate >= at_rest - 1e-12


def test_an_unstable_gait_that_fails_its_deciding_checks_says_what_helps():
    # a tolerance below what 128 RK4 sub-steps give: the interval check fails after both refinements
    result = plan(str(SCENE), overrides=["verify_tolerance=1e-15"], jit=False, max_guesses=1)
    checks = checks_of(result.solution)
    assert not result.success and not checks.stable and not checks.interval_passed
    assert checks.growth_rate == pytest.approx(math.sqrt(K / M), abs=1e-9)
    text = "\n".join(result.diagnosis)
    assert "the gait is unstable (largest growth rate 4 /s" in text
    assert "more intervals" in text and "more time does not help" in text and "--time-limit" not in text
