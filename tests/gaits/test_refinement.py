"""Accuracy refinement (gaits.verification.refinement): a converged gait that the re-simulation misses is
solved again with more RK4 sub-steps per interval, at the task's N, and then verified.

References: the sub-step rule is the h⁴ law of RK4 written out; the refined gait is checked by
an independent re-simulation — the car's Euler–Lagrange equations written here by hand in CasADi
(index-1 form with the multipliers eliminated, tests/dae_reference.py: no chart, no velocity
coordinates, nothing of nhgait), integrated by scipy's DOP853 at rtol 1e-11 from the plan's
initial (q, q̇) with the plan's piecewise-constant inputs — and by the planner's own verification.
"""
from __future__ import annotations

from pathlib import Path

import dae_reference
import numpy as np
from scipy.integrate import solve_ivp

from nhgait.gaits.planner import plan
from nhgait.gaits.verification.refinement import MARGIN, MAX_STEPS, refined_steps

CAR = str(Path(__file__).resolve().parents[2] / "examples" / "car.toml")


def test_the_sub_steps_follow_the_h4_law():
    """M' = M ⌈(MARGIN e / τ)^{1/4}⌉, at least 2M, at most MAX_STEPS."""
    assert refined_steps(4, 1.6e-6, 1e-6) == 8                    # (16)^¼ = 2
    assert refined_steps(4, 1.2e-5, 1e-6) == 16                   # (120)^¼ = 3.3 → 4
    assert refined_steps(4, 1e-9, 1e-6) == 8                      # never less than 2M
    assert refined_steps(4, 4.3e-4, 1e-6) == 36                   # (4300)^¼ = 8.1 → 9
    assert refined_steps(32, 1.7e-4, 1e-6) == MAX_STEPS           # (1700)^¼ = 6.4 → 224, capped
    assert MARGIN == 10.0


def test_a_gait_four_sub_steps_do_not_resolve_is_refined_and_verified():
    """The car's parallel park at N = 9: with 4 sub-steps the optimum misses its re-simulation
    by about 4e-4; the planner solves it again with more sub-steps from that point, verified."""
    result = plan(CAR, intervals=9)
    s = result.solution
    assert result.success
    assert s.verification.passed
    assert s.verification.max_error <= 1e-6
    first, again = result.attempts[0], result.attempts[-1]
    assert first.success
    assert "refined to" in again.label
    assert again.success
    steps = s.settings["rk4_steps"]
    assert steps > 4
    assert f"refined ({steps} RK4 sub-steps)" in result.guess
    f = dae_reference.car_ode()
    t, q, qd, u = s.t, s.z[:, :4].T, s.velocities(), s.u.T       # q, q̇: n × (N+1); u: nu × N
    z = np.concatenate([q[:, 0], qd[:, 0]])
    for k in range(t.size - 1):
        sol = solve_ivp(lambda _, x, uk=u[:, k]: np.asarray(f(x, uk)).ravel(), (t[k], t[k + 1]), z,
                        method="DOP853", rtol=1e-11, atol=1e-12)
        z = sol.y[:, -1]
        assert np.max(np.abs(z[:4] - q[:, k + 1])) <= 1e-6, k
