"""Discontinuous forces: Heaviside/sign of time are supported (the jump is an integration
breakpoint); their derivatives (DiracDelta) are taken as 0 away from the jump. Reference: the
closed form of a particle pushed by a unit step of force."""
import numpy as np
import pytest

from nhgait.dynamics import System, derive, simulate
from nhgait.dynamics.derivation.input.scene import parse_scene


def _particle(force):
    return System(coordinates=["x", "y"], lagrangian="m*(x_dot**2 + y_dot**2)/2",
                  forces={"x": force}, parameters={"m": 2.0})


@pytest.mark.parametrize("formulation", ["reduced", "lagrange"])
def test_step_force_matches_closed_form(formulation):
    # m ẍ = H(t − 1): x(t) = (t − 1)²/(2m) after the step, 0 before
    model = derive(_particle("Heaviside(t - 1)"), formulation)
    assert model.system.force_jump_times() == (1.0,)
    t = np.array([0.0, 0.5, 1.0, 2.0, 3.0])
    traj = simulate(model, (0.0, 3.0), [0, 0], [0, 0], t_eval=t, rtol=1e-10, atol=1e-12)
    assert traj.success, traj.message
    expected = np.where(t > 1, (t - 1) ** 2 / 4.0, 0.0)
    np.testing.assert_allclose(traj.q[:, 0], expected, atol=1e-10)


def test_step_input_law_is_a_breakpoint():
    scene = parse_scene({
        "system": {"coordinates": ["x", "y"], "lagrangian": "m*(x_dot**2 + y_dot**2)/2",
                   "forces": {"x": "u"}, "parameters": {"m": 2.0}},
        "simulation": {"q0": [0, 0], "qdot0": [0, 0], "t_final": 3.0, "samples": 4,
                       "inputs": {"u": "3*Heaviside(2*t - 3)"}}}, "step.toml")
    spec = scene.simulation
    np.testing.assert_array_equal(spec.controller.breakpoints, [1.5])
    traj = simulate(derive(scene.system), (0, 3), spec.q0, spec.qdot0, controller=spec.controller,
                    t_eval=spec.t_eval, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(traj.q[-1, 0], 3 * 1.5 ** 2 / 4.0, rtol=1e-10)
