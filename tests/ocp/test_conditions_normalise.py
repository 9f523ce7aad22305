"""Boundary conditions as users write them (ocp/conditions.py ``normalise``), on a particle of
mass m in the plane, whose reduced state is z = (x, y, p, pt_y) with p = m ẋ, pt_y = m ẏ (the
closed form): "at rest" written as ẋ = ẏ = 0 is exactly p = pt_y = 0; a condition implied by
the others is dropped with its reason; an inconsistent set is one ProblemError."""
from __future__ import annotations

import pytest

from nhgait.ocp import OptimalControlProblem, ProblemError
from nhgait.ocp.conditions import ConditionReport, normalise

MASS = 2.0


def test_at_rest_as_velocities_becomes_the_momenta_fixed_to_zero(particle):
    rest = {"x": 0.0, "y": 0.0, "x_dot": 0.0, "y_dot": 0.0}
    problem = OptimalControlProblem(particle, 1.0, 5, initial=rest, final={**rest, "x": 1.0})
    out = normalise(problem)
    assert dict(out.problem.initial) == {"x": 0.0, "y": 0.0, "p": 0.0, "pt_y": 0.0}
    assert dict(out.problem.final) == {"x": 1.0, "y": 0.0, "p": 0.0, "pt_y": 0.0}
    assert {(where, name) for where, name, _ in out.report.dropped} == {
        ("initial", "x_dot"), ("initial", "y_dot"), ("final", "x_dot"), ("final", "y_dot")}
    assert all("exactly p = 0, pt_y = 0" in reason for _, _, reason in out.report.dropped)


def test_a_velocity_with_its_momentum_is_implied_and_a_contradiction_refused(particle):
    """ẋ = 1 with p = m ẋ = 2 stated too: the second says nothing new (dropped, the state is
    determined and solved for); p = 3 with ẋ = 1 contradicts it (one error)."""
    start = {"x": 0.0, "y": 0.0, "pt_y": 0.0}
    ok = OptimalControlProblem(particle, 1.0, 5, initial={**start, "x_dot": 1.0, "p": MASS * 1.0},
                               final={"x": 1.0})
    out = normalise(ok)
    assert out.report.dropped and out.report.dropped[0][0] == "initial"
    assert dict(out.problem.initial)["p"] == pytest.approx(MASS, abs=1e-12)
    bad = OptimalControlProblem(particle, 1.0, 5, initial={**start, "x_dot": 1.0, "p": 3.0},
                                final={"x": 1.0})
    with pytest.raises(ProblemError, match="x_dot|p"):
        normalise(bad)


def test_the_report_says_what_changed():
    report = ConditionReport(dropped=(("final", "y_dot", "implied"),), solved=(("initial", (0.0, 1.5)),),
                             pinned=("phi",))
    lines = report.lines()
    assert lines[0] == "final.y_dot: dropped, implied"
    assert lines[1].startswith("initial: the conditions determine the whole state; fixed to (0, 1.5)")
    assert lines[2].startswith("initial.phi: fixed to 0")
