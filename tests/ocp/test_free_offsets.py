"""State components nothing depends on (ocp.offsets): found, and pinned at t = 0 by normalise.

Reference: the invariance itself, checked numerically — the car's equations of motion are the
same at z and at z shifted along x (a world-frame translation: the robot's dynamics cannot
depend on where it stands), so with x named by no condition every shift of a solution along x
is a solution; the heading θ and the steering angle φ do enter the equations.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from nhgait.gaits.planner import prepare
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp.offsets import free_offsets

CAR = str(Path(__file__).resolve().parents[2] / "examples" / "car.toml")
#: the car's parallel park without any condition on x
SIDEWAYS = {"name": "sideways", "horizon": 6.0, "intervals": 20,
            "initial": {"y": 0.0, "theta": 0.0, "phi": 0.0, "forward_velocity": 0.0, "phi_dot": 0.0},
            "final": {"y": 0.5, "theta": 0.0, "phi": 0.0, "forward_velocity": 0.0, "phi_dot": 0.0},
            "bounds": {"phi": [-0.7, 0.7]}, "control_bounds": {"F": [-5.0, 5.0], "tau_phi": [-1.0, 1.0]},
            "objective": "effort"}


def test_a_coordinate_nothing_depends_on_is_pinned_at_zero():
    prepared = prepare(resolve(CAR, SIDEWAYS))
    problem, stated = prepared.problem, prepared.stated
    rhs, params = problem.model.numeric["rhs"], problem.params
    rng = np.random.default_rng(3)
    ix, ith = stated.state_names.index("x"), stated.state_names.index("theta")
    for _ in range(5):                                   # the reference: shift invariance
        z, u = rng.uniform(-0.5, 0.5, stated.n_states), rng.normal(size=stated.n_controls)
        for i, invariant in ((ix, True), (ith, False)):
            shifted = z.copy()
            shifted[i] += 1.7
            same = np.allclose(np.asarray(rhs(0, z, u, params)), np.asarray(rhs(0, shifted, u, params)),
                               rtol=1e-12, atol=1e-12)
            assert same == invariant, stated.state_names[i]
    assert free_offsets(stated) == ("x",)
    assert prepared.conditions.pinned == ("x",)
    assert problem.fixed_value(problem.initial, "x") == 0.0
    assert "x" not in problem.final
    assert any(line.startswith("initial.x: fixed to 0") for line in prepared.conditions.lines())


def test_a_coordinate_named_anywhere_is_left_alone():
    for where in ("final", "bounds"):
        task = {**SIDEWAYS, where: {**SIDEWAYS.get(where, {}), "x": 0.3 if where == "final" else [-2.0, 2.0]}}
        prepared = prepare(resolve(CAR, task))
        assert free_offsets(prepared.stated) == (), where
        assert prepared.conditions.pinned == (), where
    periodic = {**SIDEWAYS, "periodic": ["x"]}           # a periodic state is shift-invariant: still pinned
    assert prepare(resolve(CAR, periodic)).conditions.pinned == ("x",)
