"""Periodic rates stated exactly (ocp.conditions._determined_velocities).

The 4-link snake of experiments/user_robots/snake4_fwd.toml (joints α₁…α₃ and their rates
periodic) is planned in the velocity states (θ̇, forward_velocity): no pair of its joint rates
is regular within |α| ≤ 1. Its three periodic joint rates are functions of the shape and of
those two states; two of them determine the states only where a 2 × 2 minor of ∂α̇/∂v is
regular. Dropping the third as "implied" let the optimum end at a posture where the minor is
singular, the third rate missed by 0.078 rad/s. Stated as v(T) = v(0) the set is exact.

Reference: the planner's independent re-simulation (DOP853, rtol 1e-10) checks every condition
as the user wrote it, α̇₃(T) = α̇₃(0) included, to 1e-6.
"""
from __future__ import annotations

from pathlib import Path

from nhgait.gaits.planner import plan

SNAKE4 = str(Path(__file__).resolve().parents[2] / "experiments" / "user_robots" / "snake4_fwd.toml")
RATES = ("alpha1_dot", "alpha2_dot", "alpha3_dot")


def test_periodic_joint_rates_are_stated_as_periodic_velocity_states_and_all_hold():
    result = plan(SNAKE4, intervals=30)
    velocities = tuple(result.solution.settings["velocities"])
    assert not set(velocities) & set(RATES)                  # the states are not the rates
    report = {name: reason for where, name, reason in result.conditions.dropped if where == "periodic"}
    assert set(RATES) <= set(report)
    assert all(report[r].startswith("stated as the periodicity") for r in RATES)
    assert result.success, result.diagnosis
    v = result.solution.verification
    for rate in RATES:                                       # every rate, as written, by the re-simulation
        assert v.condition_errors[f"periodic.{rate}"] <= 1e-6
    assert v.max_error <= 1e-6
