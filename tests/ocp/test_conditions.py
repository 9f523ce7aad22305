"""Boundary conditions as users write them (issue 19, item 5): a full consistent state, a
redundant set, an inconsistent set, the "at rest" shorthand, implied periodicity.

References: two statements of one task describe the same set of trajectories, so they must
have the same optimum (the minimal statement is the library's P1 / P2); residuals come from the
unicycle's rolling constraint ẋ = r cos θ φ̇ with r = 0.1 (its scene file), not from nhgait.
"""
from __future__ import annotations

import experiment_scripts
import pytest

from nhgait.gaits.planner import plan, prepare
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import ProblemError

P1 = {"horizon": 4.0, "intervals": 20, "control_bounds": 5.0,
      "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0, "phi_dot": 0.0, "theta_dot": 0.0},
      "final": {"x": 0.0, "y": 0.5, "theta": 0.0, "phi_dot": 0.0, "theta_dot": 0.0}}
VELOCITIES = ("x_dot", "y_dot", "theta_dot", "phi_dot")


def _solve(task, scene="unicycle"):
    result = plan(scene, task, jit=False, solver="ipopt")
    assert result.success, result.diagnosis
    return result


@pytest.fixture(scope="module")
def minimal():
    return _solve(P1).solution.objective


def test_rest_to_rest_written_as_full_states(minimal):
    """Every coordinate and every velocity at both ends (as people write "from rest"):
    accepted, the dependent ones replaced by what they say exactly (ẋ = r cos θ φ̇ and
    ẏ = r sin θ φ̇ are zero together exactly when φ̇ = 0), same optimum as P1."""
    task = {**P1, "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0, **{v: 0.0 for v in VELOCITIES}},
            "final": {"x": 0.0, "y": 0.5, "theta": 0.0, **{v: 0.0 for v in VELOCITIES}}}
    result = _solve(task)
    assert result.solution.objective == pytest.approx(minimal, rel=1e-8)
    lines = result.conditions.lines()
    assert "initial.x_dot: dropped, with x_dot = 0, y_dot = 0: exactly phi_dot = 0 (theta_dot free)" in lines
    # the verification checks the task as written: every one of its conditions, dropped or not
    checked = set(result.solution.verification.condition_errors)
    assert {f"initial.{v}" for v in VELOCITIES} <= checked
    assert {f"final.{v}" for v in VELOCITIES} <= checked


def test_rest_shorthand(minimal):
    task = {**P1, "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0},
            "final": {"x": 0.0, "y": 0.5, "theta": 0.0}, "rest": ["initial", "final"]}
    assert _solve(task).solution.objective == pytest.approx(minimal, rel=1e-8)


def test_rest_contradicted_by_a_given_velocity():
    task = {**P1, "rest": ["initial"], "initial": {**P1["initial"], "phi_dot": 1.0}}
    with pytest.raises(ProblemError, match=r"initial\.phi_dot = 1\.0 contradicts rest"):
        prepare(resolve("unicycle", task))


def test_full_state_violating_a_constraint_names_it():
    """ẋ = 1 at rest otherwise breaks ẋ = r cos θ φ̇ by 1 (and only that constraint)."""
    task = {**P1, "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0, "x_dot": 1.0, "y_dot": 0.0,
                              "theta_dot": 0.0, "phi_dot": 0.0}}
    with pytest.raises(ProblemError) as info:
        prepare(resolve("unicycle", task))
    lines = [p for p in info.value.problems if "constraint 1" in p]
    assert len(lines) == 1
    assert "x_dot" in lines[0]
    assert "residual 1 " in lines[0]
    assert not any("constraint 2" in p for p in info.value.problems)


def test_inconsistent_partial_set_gives_the_value_the_others_imply():
    """θ = 0 and φ̇ = 0 imply ẋ = r cos θ φ̇ = 0: ẋ = 1 contradicts them, residual −1."""
    task = {**P1, "initial": {"theta": 0.0, "x_dot": 1.0, "phi_dot": 0.0}}
    with pytest.raises(ProblemError, match="inconsistent boundary conditions") as info:
        prepare(resolve("unicycle", task))
    text = str(info.value)
    assert "x_dot = 1 contradicts theta = 0, phi_dot = 0" in text
    assert "x_dot = 0 (residual -1)" in text


def test_fibre_at_rest_on_the_snakeboard():
    """ẋ = ẏ = θ̇ = 0 is one condition on the snakeboard (its fibre velocities are v cos θ,
    v sin θ, v tan φ / r): exactly v = 0 — the three replaced by the forward velocity stopped —
    and the optimum is P2's."""
    fibre = {"x_dot": 0.0, "y_dot": 0.0, "theta_dot": 0.0}
    p2 = plan("snakeboard", "forward", intervals=25, jit=False, solver="ipopt")
    task = p2.task.to_dict()
    task["initial"] = {**{k: v for k, v in task["initial"].items() if k != "forward_velocity"}, **fibre}
    task["final"] = {**{k: v for k, v in task["final"].items() if k != "forward_velocity"}, **fibre}
    result = _solve(task, "snakeboard")
    dropped = [line for line in result.conditions.lines() if "exactly forward_velocity = 0" in line]
    assert len([d for d in dropped if d.startswith("initial.")]) == 3
    assert len([d for d in dropped if d.startswith("final.")]) == 3
    assert result.solution.objective == pytest.approx(p2.solution.objective, rel=1e-6)


def test_periodic_joint_rates_of_a_four_link_snake_are_implied():
    """The 4-link snake has two velocity degrees of freedom: with α̇₁, α̇₂ as states and every
    joint angle periodic, "α̇₃ periodic" follows (α̇₃ is a function of the joint angles and
    (α̇₁, α̇₂)) and is dropped instead of making the constraint Jacobian rank-deficient."""
    scaling = experiment_scripts.load("scaling_systems")
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    scene = scene_from_text(scaling.snake(4), "<snake_4>")
    joints = ["alpha1", "alpha2", "alpha3"]
    task = {"horizon": 6.0, "intervals": 10, "control_bounds": 5.0,
            "velocities": ["alpha1_dot", "alpha2_dot"],
            "initial": {"x": 0.0, "y": 0.0, "theta": 0.0}, "final": {"x": 0.3, "y": 0.0, "theta": 0.0},
            "periodic": joints + [f"{j}_dot" for j in joints],
            "bounds": {"alpha1": [0.2, 1.5], "alpha2": [-1.5, -0.2], "alpha3": [-1.5, 1.5]}}
    prepared = prepare(resolve(scene, task))
    assert prepared.problem.periodic == ("alpha1", "alpha2", "alpha3", "alpha1_dot", "alpha2_dot")
    assert any(line.startswith("periodic.alpha3_dot: dropped, implied by the periodicity")
               for line in prepared.conditions.lines())


def test_dependent_conditions_at_a_free_configuration_are_not_called_contradictory():
    """The benchmark's car with two off-axle trailers (robot_generator pair 24/17), periodic from
    rest: the final rates θ̇₀ = θ̇₁ = 0 come from periodicity while the final shape (φ, θ₀, θ₁) is
    free at that end. Every velocity 0 satisfies the task (the closed-form reference), so the
    set is consistent: it was refused ("theta1_dot = -0 contradicts theta2 = 0, theta0_dot = -0
    … residual -0.63", judged on the branch of θ̇₀ = 0 where the velocity is not zero). Now
    accepted, and every condition — kept or dropped — holds at the final configuration with
    every velocity zero."""
    import numpy as np

    from nhgait.dynamics.derivation.input.scene import scene_from_text
    from nhgait.ocp.problem import builtin_quantities
    pair = experiment_scripts.load("robot_generator").pair(24, 17)
    prepared = prepare(resolve(scene_from_text(pair.scene, "<car2_24_17>"), None))
    stated, problem = prepared.stated, prepared.problem
    names = stated.state_names
    n = len(stated.model.system.coordinates)
    q_end = [stated.final[c] if c in stated.final else stated.initial[c] for c in names[:n]]
    z = np.concatenate([q_end, np.zeros(len(names) - n)])          # every velocity zero
    quantities = builtin_quantities(stated.model)
    for mapping in (stated.final, problem.final):
        for name, value in mapping.items():
            y = z[names.index(name)] if name in names else float(quantities[name].function(z, stated.params))
            assert y == pytest.approx(value, abs=1e-12), name
    assert "final.theta1_dot" in {f"final.{k}" for k in problem.final} | {
        line.split(":")[0] for line in prepared.conditions.lines()}


CAR_PARK = {"horizon": 6.0, "intervals": 30, "control_bounds": {"F": [-5.0, 5.0], "tau_phi": [-1.0, 1.0]},
            "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0, "forward_velocity": 0.0,
                        "phi_dot": 0.0},
            "final": {"x": 0.0, "y": 0.5, "theta": 0.0}, "bounds": {"phi": [-0.7, 0.7]}}


def test_a_point_at_rest_is_its_velocity_state_stopped_and_one_velocity_alone_is_not():
    """examples/car.toml: the rear axle's ẋ = v cos θ, ẏ = v sin θ (closed form, v the forward
    velocity). ẋ = ẏ = 0 says exactly v = 0 at every heading — replaced by the state fixed to 0,
    the steering rate left free; ẋ = 0 alone also holds at θ = ±π/2 with v ≠ 0, so it is kept
    as written (replacing it by v = 0 would lose that branch)."""
    from pathlib import Path
    car = str(Path(__file__).parents[2] / "examples" / "car.toml")
    both = prepare(resolve(car, {**CAR_PARK, "final": {**CAR_PARK["final"], "x_dot": 0.0, "y_dot": 0.0}}))
    assert dict(both.problem.final) == {"x": 0.0, "y": 0.5, "theta": 0.0, "forward_velocity": 0.0}
    assert any("exactly forward_velocity = 0 (phi_dot free)" in line for line in both.conditions.lines())
    alone = prepare(resolve(car, {**CAR_PARK, "final": {"x": 0.0, "y": 0.5, "x_dot": 0.0}}))
    assert dict(alone.problem.final) == {"x": 0.0, "y": 0.5, "x_dot": 0.0}
    assert not alone.conditions.lines()
