"""What produced a failed run (dynamics/simulation/failures.py): a particle on a line driven by
τ = F + √(0.5 − t), real only until t = 0.5 (by hand), and by a controller that returns NaN
after t = 0.25: the run stops with status NONFINITE at that time, and its message names the
quantity — the right-hand side of the momentum, the controller's input F."""
from __future__ import annotations

import pytest

from nhgait.dynamics import System, derive, simulate
from nhgait.dynamics.simulation import failures  # noqa: F401 - the module whose sentences these are
from nhgait.dynamics.simulation.integrators import NONFINITE


@pytest.fixture(scope="module")
def line():
    system = System(["x"], "m*x_dot**2/2", [], forces={"x": "F + sqrt(0.5 - t)"}, parameters={"m": 1.0},
                    inputs=["F"])
    return derive(system, "reduced")


@pytest.mark.parametrize("method", ["RK45", "compiled"])
def test_a_force_that_stops_being_real(line, method):
    run = simulate(line, (0.0, 1.0), [0.0], [0.0], method=method)
    assert not run.success and run.status == NONFINITE
    assert run.message.startswith("stopped at t = 0.5: the right-hand side d/dt p is non-finite at t = 0.5")


def test_a_controller_that_returns_nan(line):
    def controller(t, q, qdot):
        return [float("nan")] if t > 0.25 else [0.0]

    run = simulate(line, (0.0, 0.4), [0.0], [0.0], controller=controller, method="RK45")
    assert run.status == NONFINITE
    assert run.message.startswith("stopped at t = 0.25: the controller function returned a non-finite "
                                  "input F = nan at t = 0.25")
