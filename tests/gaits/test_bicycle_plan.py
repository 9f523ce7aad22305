"""Planning for the Whipple bicycle: the built-in scene's lane change (1 m to the left in 3 s at
5 m/s, coasting, the rider's steer torque alone, lean and steer bounded), planned by
``nhgait.gaits.planner.plan`` and checked by a second re-simulation of the planned steer torque
— the general reduced model (momentum coordinates, not the planner's velocity coordinates)
integrated by CVODES through ``simulate`` (the planner's own check is DOP853 on the same
model) — and against the holonomic constraint at every node (the pitch stays on the front
wheel's contact surface). The model itself is checked against Meijaard's eigenvalues and
Basu-Mandal's nonlinear accelerations (tests/dynamics/test_bicycle.py). (The Lagrangian DAE of the
bicycle would be an independent path, but its symbolic derivation takes minutes.)"""
import numpy as np
import pytest

from nhgait.dynamics import derive, simulate
from nhgait.dynamics.derivation.holonomic import holonomic_residual
from nhgait.dynamics.simulation.controllers import OpenLoop
from nhgait.gaits.planner import plan

pytestmark = pytest.mark.slow      # one cold plan: about a minute (a 6 MB NLP compiled at -O0)


@pytest.fixture(scope="module")
def lane_change():
    """The plan without its files (the figures of an 8-coordinate gait cost seconds; writing
    them is tested on smaller robots), from its first converged guess: what is checked here holds
    for any verified gait of the task, and the search over further guesses is tested on smaller
    robots (tests/gaits/test_exploration.py) — a third of this plan's time."""
    return plan("whipple_bicycle", max_guesses=1)


def test_lane_change_is_planned_and_verified(lane_change):
    result = lane_change
    assert result.success if hasattr(result, "success") else result.solution.success
    verification = result.solution.verification
    assert verification.success
    assert verification.max_error <= 1e-6
    sol = result.solution
    names = list(sol.state_names)
    q = sol.z[:, :8].T                                              # 8 × (N+1)
    assert q[names.index("y"), -1] == pytest.approx(1.0, abs=1e-6)
    assert abs(q[names.index("yaw"), -1]) < 1e-6
    assert abs(q[names.index("lean"), -1]) < 1e-6
    assert np.all(np.abs(q[names.index("lean")]) <= 0.3 + 1e-9)
    assert np.all(np.abs(q[names.index("steer")])
                                                                           <= 0.3 + 1e-9)
    controls = dict(zip(sol.control_names, sol.u.T, strict=True))
    assert np.all(controls["T_lean"] == 0.0)
    assert np.max(np.abs(controls["T_steer"])) <= 20.0 + 1e-9
    h = holonomic_residual(result.model.system, q.T)
    assert np.max(np.abs(h)) < 1e-8                                 # the pitch follows lean and steer


def test_the_planned_torque_steers_the_bicycle_the_same_way_under_cvodes(lane_change):
    sol, system = lane_change.solution, lane_change.model.system
    q0, qdot0 = sol.z[0, :8], sol.velocities()[:, 0]
    controller = OpenLoop(sol.t, sol.u, kind="zoh", inputs=tuple(sol.control_names))
    run = simulate(derive(system), (sol.t[0], sol.t[-1]), q0, qdot0, controller=controller,
                   method="CVODES", rtol=1e-10, atol=1e-12, t_eval=sol.t)
    assert run.success
    planned = sol.z[:, :8]
    keep = [i for i, c in enumerate(system.coordinates) if c not in ("rear", "front")]
    assert np.max(np.abs(run.q[:, keep] - planned[:, keep])) < 1e-6
    speed = np.hypot(run.qdot[:, 0], run.qdot[:, 1])
    assert np.ptp(speed) < 0.5                                      # coasting: about 5 m/s throughout
