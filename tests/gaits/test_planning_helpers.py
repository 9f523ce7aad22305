"""The planner's helpers on one prepared unicycle task with a waypoint (gaits/planning:
``path_guess``, ``fitted``, ``screening``, ``robust``), against references written here:

* the path guess's knots and headings from the task's places: (0, 0) → (1, 0.5) at t = 3 s →
  (0, 0.5) at t = 6 s, the legs' directions atan2(0.5, 1) and π at their middles (1.5 s,
  4.5 s), the stated end headings 0;
* the unicycle's rolling constraints ẋ = r cos θ φ̇, ẏ = r sin θ φ̇ (the scene's ω): the fitted
  roll-out moves only along them, from the task's start to its end;
* the unicycle's velocity coordinates (θ̇, φ̇) determine q̇ everywhere (q̇ = (r cos θ φ̇,
  r sin θ φ̇, θ̇, φ̇)): the screening's normalised measure is its typical value (1) at every
  configuration, far from the singular threshold;
* the unicycle's equations in (θ̇, φ̇) in closed form: J_θ θ̈ = τ_θ, (J_φ + m r²) φ̈ = τ_φ — the
  robust copies' ODE with the mass of each copy.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from nhgait.gaits.planner import prepare
from nhgait.gaits.planning import fitted, path_guess, robust, screening
from nhgait.gaits.tasks.robust import RobustTask
from nhgait.gaits.tasks.sources import resolve

TASK = {"name": "via", "horizon": 6.0, "intervals": 60,
        "initial": {"x": 0.0, "y": 0.0, "theta": 0.0, "phi": 0.0},
        "final": {"x": 0.0, "y": 0.5, "theta": 0.0},
        "control_bounds": {"tau_theta": [-5.0, 5.0], "tau_phi": [-1.0, 1.0]},
        "waypoints": [{"time": 3.0, "name": "mid", "conditions": {"x": 1.0, "y": 0.5}}]}


@pytest.fixture(scope="module")
def via():
    to_plan = resolve("unicycle", TASK)
    prepared = prepare(to_plan)
    return to_plan, prepared, prepared.problem


def _ramps(problem):
    return lambda name: (problem.fixed_value(problem.initial, name) or 0.0,
                         problem.fixed_value(problem.final, name) or 0.0)


def test_the_path_guess_runs_through_the_stated_places_with_the_legs_headings(via):
    _, _, problem = via
    assert path_guess.applies(problem)
    coords = tuple(problem.model.system.coordinates)
    guess = path_guess.path_guess(problem, coords, _ramps(problem))
    q = guess.states[:4]                                 # (x, y, θ, φ) at the 61 nodes, Δt = 0.1 s
    assert q[:2, 0] == pytest.approx([0.0, 0.0]) and q[:2, 30] == pytest.approx([1.0, 0.5])
    assert q[:2, 60] == pytest.approx([0.0, 0.5]) and q[:2, 15] == pytest.approx([0.5, 0.25])
    assert q[2, 15] == pytest.approx(math.atan2(0.5, 1.0))       # the first leg's direction
    assert q[2, 45] == pytest.approx(math.pi)                    # the second leg: −x
    assert q[2, 0] == pytest.approx(0.0) and q[2, 60] == pytest.approx(0.0)   # the stated headings
    assert np.all(guess.controls == 0.0) and guess.horizon == pytest.approx(6.0)
    assert guess.label == path_guess.LABEL


def test_the_fitted_roll_out_rolls_from_the_start_to_the_end(via):
    to_plan, _, problem = via
    assert fitted.applies(problem)
    coords = tuple(problem.model.system.coordinates)
    guess = fitted.fitted_guess(problem, coords, np.zeros(4))
    x, y, th, phi = guess.states[:4]
    assert (x[0], y[0], th[0]) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert (x[-1], y[-1], th[-1]) == pytest.approx((0.0, 0.5, 0.0), abs=5e-2)    # the targets, ~1e-3
    r = to_plan.scene.system.parameters["r"]
    t = problem.grid()
    mid = lambda v: (v[1:] + v[:-1]) / 2                   # noqa: E731  interval midpoints
    rate = lambda v: np.diff(v) / np.diff(t)               # noqa: E731  O(h²) at the midpoints
    scale = max(1.0, np.abs(rate(phi)).max() * r)
    assert np.abs(rate(x) - r * np.cos(mid(th)) * rate(phi)).max() <= 2e-2 * scale   # rolls, no slip
    assert np.abs(rate(y) - r * np.sin(mid(th)) * rate(phi)).max() <= 2e-2 * scale


def test_the_unicycles_velocity_coordinates_have_no_singular_set(via):
    _, _, problem = via
    screen = screening.Screen(problem)
    q = np.random.default_rng(4).uniform(-3.0, 3.0, (4, 200))
    measure = screen.measure(q)
    assert np.all(np.isfinite(measure))
    assert measure == pytest.approx(np.ones(200), rel=1e-3)
    assert screening.Screen(problem).check(path_guess.path_guess(
        problem, tuple(problem.model.system.coordinates), _ramps(problem))).ok


def test_the_robust_copies_are_the_unicycle_with_each_copys_mass(via):
    to_plan, prepared, problem = via
    spec = RobustTask(parameters={"m": (0.8, 1.0, 1.2)})
    N, nz = problem.intervals, len(problem.model_state_names)
    nominal = SimpleNamespace(z=np.linspace(0.0, 1.0, (N + 1) * nz).reshape(N + 1, nz), objective=2.0)
    sc = robust.scenarios_for(spec, prepared, nominal, to_plan.scene.quantities)
    assert sc.terminal == robust.default_terminal(problem, prepared.specialised.system) == ("x", "y", "theta")
    assert sc.labels == ("m ×0.8", "m ×1.2") and sc.weight == pytest.approx(2.0)
    values = to_plan.scene.system.parameters
    names = list(prepared.specialised.numeric.param_names)
    r, J_th, J_phi = values["r"], values["J_theta"], values["J_phi"]
    z = np.array([0.1, -0.2, 0.7, 0.3, 0.4, -1.1])                  # (x, y, θ, φ, θ̇, φ̇)
    u = np.array([0.6, -0.9])
    for factor, theta in zip((0.8, 1.2), sc.params, strict=True):
        assert theta[names.index("m")] == pytest.approx(values["m"] * factor)
        rate = np.asarray(sc.ode(0.0, z, u, theta)).ravel()
        m = values["m"] * factor
        want = [r * math.cos(z[2]) * z[5], r * math.sin(z[2]) * z[5], z[4], z[5], u[0] / J_th,
                u[1] / (J_phi + m * r ** 2)]
        assert rate == pytest.approx(want, rel=1e-12, abs=1e-12)
    line = robust.summary_line({"aggregate": "mean", "copies": 2, "parameters": ["m"], "end_fraction": 0.02,
                                "nominal_plan": {"mean": 3.0}, "robust_plan": {"mean": 1.5},
                                "nominal_objective": 2.0, "task_objective": 2.25})
    assert line.startswith("2 copies (m); mean terminal deviation 3 → 1.5")
