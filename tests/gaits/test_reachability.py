"""Targets no admissible input can reach (gaits/tasks/reachability.py), on a particle of mass m = 2 in
the plane with |F_x| ≤ 3, |F_y| ≤ 1 over T = 2 s from rest. By hand: full thrust moves x at most
½ (3/m) T² = 3 m and y at most 1 m — reachable, so never refused; a target beyond the module's
energy bound (which must be ≥ those maxima) is refused in one sentence naming the coordinate."""
from __future__ import annotations

import re

from nhgait.gaits.tasks.reachability import unreachable_targets
from nhgait.ocp import OptimalControlProblem

MASS, T = 2.0, 2.0
REST = {"x": 0.0, "y": 0.0, "p": 0.0, "pt_y": 0.0}


def _problem(model, final, initial=REST):
    return OptimalControlProblem(model, T, 10, initial=initial, final=final,
                                 control_bounds={"Fx": (-3.0, 3.0), "Fy": (-1.0, 1.0)})


def test_reachable_targets_are_never_refused(particle):
    system, model = particle.system, particle
    assert unreachable_targets(_problem(model, {"x": 0.5 * 3 / MASS * T ** 2, "y": 0.5 * 1 / MASS * T ** 2}),
                               system) == []


def test_a_target_beyond_every_input_is_refused(particle):
    system, model = particle.system, particle
    found = unreachable_targets(_problem(model, {"x": 40.0, "y": 0.5}), system)
    assert len(found) == 1 and found[0].startswith("final x is 40 from initial x = 0")
    bound = float(re.search(r"more than ([0-9.e+-]+) in T", found[0]).group(1))
    assert 0.5 * 3 / MASS * T ** 2 <= bound < 40.0                  # an upper bound of the true reach
    moving = {**REST, "p": 1.0}                                    # not at rest: not judged
    assert unreachable_targets(_problem(model, {"x": 40.0}, initial=moving), system) == []
