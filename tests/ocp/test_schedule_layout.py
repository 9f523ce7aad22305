"""Phases laid on one chain of intervals (ocp/schedule.py), against the arithmetic of the
module docstring done by hand: N = Σ N_p, phase p from node starts[p] to starts[p+1], node times
t0_p + κ T_p / N_p, ν = 1 / N_p, the events at their nodes in order."""
from __future__ import annotations

import numpy as np

from nhgait.ocp import OptimalControlProblem
from nhgait.ocp.schedule import schedule
from nhgait.ocp.statement import Phase, Waypoint

REST = {"x": 0.0, "y": 0.0, "x_dot": 0.0, "y_dot": 0.0}


def test_two_phases_of_fixed_horizons(particle):
    phases = [Phase(1.0, 4, final={"x": 1.0}, name="out"), Phase(3.0, 6, final={**REST, "y": 1.0})]
    s = schedule(OptimalControlProblem(particle, 1.0, 1, initial=REST, phases=phases))
    assert s.intervals == 10 and s.n_phases == 2 and not s.variable_horizons
    assert list(s.starts) == [0, 4, 10]
    assert list(s.interval_phase) == [0] * 4 + [1] * 6
    assert list(s.local_index()) == [0, 1, 2, 3, 0, 1, 2, 3, 4, 5]
    expected = np.concatenate([[0.0], 0.25 * np.arange(1, 5), 1.0 + 0.5 * np.arange(1, 7)])
    np.testing.assert_allclose(s.grid(), expected, rtol=0, atol=1e-15)
    nu, t0 = s.phase_rows()
    np.testing.assert_allclose(nu, [0.25] * 4 + [1 / 6] * 6, rtol=1e-15)
    np.testing.assert_allclose(t0, [0.0] * 4 + [1.0] * 6, rtol=0, atol=0)
    assert s.horizon_bounds() == [(1.0, 1.0), (3.0, 3.0)]
    assert list(s.nodes_of_phase(1)) == list(range(4, 11))       # the boundary node 4 is shared
    nodes = [e.node for e in s.events]
    assert nodes == sorted(nodes) and nodes[0] == 0 and nodes[-1] == 10
    assert any(e.node == 4 and e.label.startswith("out") for e in s.events)


def test_free_horizons_make_every_phase_horizon_a_variable(particle):
    phases = [Phase(1.5, 5, free_horizon=(0.2, 4.0)), Phase(2.0, 3)]
    s = schedule(OptimalControlProblem(particle, 1.0, 1, initial=REST, final={**REST, "x": 1.0},
                                       phases=phases))
    assert s.variable_horizons and s.horizon_bounds() == [(0.2, 4.0), (2.0, 2.0)]
    np.testing.assert_allclose(s.initial_horizons(7.0), [3.0, 4.0])       # 1.5 : 2.0 scaled to 7
    np.testing.assert_allclose(s.grid(horizons=[1.0, 3.0])[[0, 5, 8]], [0.0, 1.0, 4.0])


def test_a_problem_without_phases_is_one_phase_with_its_waypoints_at_their_nodes(particle):
    problem = OptimalControlProblem(particle, 2.0, 8, initial=REST, final={**REST, "x": 1.0},
                                    waypoints=[Waypoint(0.5, {"y": 0.3})])
    s = schedule(problem)
    assert s.n_phases == 1 and list(s.starts) == [0, 8] and s.intervals == 8
    np.testing.assert_allclose(s.grid(), np.linspace(0.0, 2.0, 9), rtol=0, atol=1e-15)
    assert [e.node for e in s.events] == [0, 2, 8]                # t = 0.5 of 2 s: node 0.5·8/2
