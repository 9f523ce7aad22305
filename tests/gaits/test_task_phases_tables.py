"""Waypoints, phases and integrals of a ``[task]`` (gaits/tasks/phases.py): the format of the
module docstring (docs/gait-planning.md) read into Waypoint and Phase values; the intervals of
``--intervals N`` shared in proportion (40 : 20 of 30 → 20 : 10); a table back out of a phase
reads in again to the same phase; every problem named in the table's words."""
from __future__ import annotations

import math

from nhgait.gaits.tasks.phases import parse_integrals, parse_phases, parse_waypoints, phase_table
from nhgait.ocp.statement import Waypoint

TASK = {"phases": [{"name": "to the pylon", "horizon": [1.0, 10.0], "intervals": 40, "final": {"x": 10.0},
                    "bounds": {"phi": [-0.5, 0.5]}, "control_bounds": {"F": [0.0, 5.0]},
                    "waypoints": [{"time": 1.0, "conditions": {"y": 0.0}}]},
                   {"horizon": "pi", "intervals": 20, "control_bounds": {"F": 2}}]}


def test_phases_are_read_as_written():
    problems = []
    first, second = parse_phases(TASK, problems)
    assert not problems
    assert (first.horizon, first.intervals, first.free_horizon, first.name) == (5.5, 40, (1.0, 10.0),
                                                                               "to the pylon")
    assert dict(first.final) == {"x": 10.0} and dict(first.state_bounds) == {"phi": (-0.5, 0.5)}
    assert dict(first.control_bounds) == {"F": (0.0, 5.0)}
    assert first.waypoints == (Waypoint(1.0, {"y": 0.0}, ""),)
    assert second.horizon == math.pi and second.control_bounds == {"F": (-2.0, 2.0)}
    refined = parse_phases({**TASK, "intervals": 30}, problems)
    assert [p.intervals for p in refined] == [20, 10] and not problems


def test_a_phase_table_reads_back_to_the_same_phase():
    problems = []
    phases = parse_phases(TASK, problems)
    again = parse_phases({"phases": [phase_table(p) for p in phases]}, problems)
    assert not problems
    for a, b in zip(phases, again, strict=True):
        assert (a.horizon, a.intervals, a.free_horizon, a.name) == (b.horizon, b.intervals, b.free_horizon,
                                                                    b.name)
        assert dict(a.final) == dict(b.final) and dict(a.state_bounds) == dict(b.state_bounds)
        assert dict(a.control_bounds) == dict(b.control_bounds) and a.waypoints == b.waypoints


def test_waypoints_and_integrals_and_their_problems():
    problems = []
    (w,) = parse_waypoints({"waypoints": [{"time": 3.0, "name": "corner", "conditions": {"x": 1.0}}]},
                           problems)
    assert (w.time, dict(w.conditions), w.name) == (3.0, {"x": 1.0}, "corner") and not problems
    assert parse_integrals({"integrals": {"near1": "hump1"}}, problems) == {"near1": "hump1"}
    parse_waypoints({"waypoints": [{"name": "a.b", "conditions": {}, "when": 2}]}, problems)
    parse_phases({"horizon": 3, "phases": [{"horizon": 1, "intervals": 2.5}]}, problems)
    parse_integrals({"integrals": {"I": 3}}, problems)
    said = "\n".join(problems)
    for words in ("[task].waypoints[0]: missing key 'time'", "'conditions' must be a table",
                  "[task].waypoints[0].name must be a string without '.'", "when",
                  "[task].phases[0].intervals = 2.5 must be an integer", "remove horizon",
                  "[task].integrals.I: the integrand is the name of a quantity"):
        assert words in said, words
