"""A target no shape motion reaches, answered before any solve (issue 42, item 4;
gaits/tasks/reachability.py: ``shape_reach``).

The two-link sleigh of tests/scenes/sleigh_forward.toml (one shape coordinate φ, |φ| ≤ 1,
|τ| ≤ 2, T = 4 s) asked to move 0.5 m forward from rest. The verdict is checked against an
independent computation: the Lagrange formulation (q, q̇, λ — not the reduced equations the check
uses) simulated under hinge torques within the bounds never brings it 1 cm forward. The same
robot with the target behind it, and a robot whose momentum pushes it forward (the trailing link
longer: L2 = 0.5, where σ_rr·Γ changes sign), are not refused.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from nhgait.dynamics import derive, load_scene, simulate
from nhgait.gaits.planner import plan, prepare
from nhgait.gaits.tasks.reachability import shape_reach, unreachable_targets
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import ProblemError

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "sleigh_forward.toml"


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENE)


def _task_table() -> dict:
    import tomllib
    return dict(tomllib.loads(SCENE.read_text())["task"])


def test_the_planner_answers_not_reachable_before_solving(scene):
    with pytest.raises(ProblemError, match="not reachable within the bounds") as info:
        plan(scene)
    text = str(info.value)
    assert "phi within [-1, 1]" in text and "x by +0.5" in text      # the direction and the bound named
    assert "widen the bounds of phi" in text


def test_no_torque_within_the_bounds_moves_it_forward_on_the_lagrange_equations(scene):
    """The independent reference: the Lagrange DAE with the hinge driven, within |τ| ≤ 2, to
    follow strokes φ_ref = a sin(2πkt/T) (a PD law, saturated) of several sizes, frequencies and
    both signs; x (the lead knife edge, heading 0 at the start) stays below 1 cm (2 % of the
    0.5 m asked, the margin the verdict uses) while |φ| ≤ 1."""
    model = derive(scene.system, "lagrange")
    best, runs = -np.inf, 0
    for a in (0.3, 0.6, 0.95):
        for k in (1.0, 2.0, 3.0):
            for sign in (1.0, -1.0):
                w = 2 * np.pi * k / 4.0

                def law(t, q, q_dot, a=sign * a, w=w):
                    wanted = 40.0 * (a * np.sin(w * t) - q[3]) + 8.0 * (a * w * np.cos(w * t) - q_dot[3])
                    return [float(np.clip(wanted, -2.0, 2.0))]

                traj = simulate(model, (0.0, 4.0), [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0],
                                controller=law, t_eval=np.linspace(0.0, 4.0, 201), rtol=1e-9, atol=1e-12)
                assert traj.success
                if np.max(np.abs(traj.q[:, 3])) <= 1.0:                 # within the shape bound
                    best, runs = max(best, float(np.max(traj.q[:, 0]))), runs + 1
    assert runs >= 6 and best < 0.01


def test_the_verdict_names_the_momentum_and_the_samples(scene):
    verdict = shape_reach(prepare(resolve(scene)).problem)
    assert verdict is not None and not verdict.reachable and verdict.momentum_away
    assert verdict.samples > 0 and verdict.best < 0.02 * verdict.distance


def test_a_target_behind_it_is_not_refused(scene):
    problem = prepare(resolve(scene, {**_task_table(), "final": {"x": -0.3}})).problem
    verdict = shape_reach(problem)
    assert verdict is not None and verdict.reachable
    assert unreachable_targets(problem, problem.model.system) == []


def test_a_sleigh_whose_momentum_pushes_forward_is_not_refused(scene):
    problem = prepare(resolve(scene, _task_table()), params={"L2": 0.5}).problem
    verdict = shape_reach(problem)
    assert verdict is not None and verdict.reachable and not verdict.momentum_away


@pytest.mark.parametrize("scene_name, gait", [
    ("unicycle", "parallel-park"), ("snakeboard", "forward"), ("snakeboard", "lateral"),
    ("examples/car.toml", None), ("examples/rotor_sleigh.toml", None), ("examples/cart_trailer.toml", None),
    ("experiments/user_robots/sleigh_mass.toml", None),
])
def test_the_examples_tasks_are_not_refused(scene_name, gait):
    """No misfire: the tasks the planner is known to solve (P1, P2, P4, the examples, a user's
    sleigh) pass the reach checks — the one-shape check stays out where it does not apply (two
    shape coordinates, an input along the fibre, more than one momentum)."""
    root = Path(__file__).resolve().parents[2]
    source = str(root / scene_name) if "/" in scene_name else scene_name
    problem = prepare(resolve(source, gait)).problem
    assert unreachable_targets(problem, problem.model.system) == []
