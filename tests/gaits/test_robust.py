"""Robust (scenario) planning: nhgait.ocp.scenarios, [task.robust] and the planner's robust stage.

The oracle: a point mass in the plane pulled sideways by a spring from its forward position,
ẍ = F_x / m, ÿ = (F_y + b x) / m. The ODE is linear with a nilpotent matrix (vx → x → vy → y,
A⁴ = 0), so RK4 (the shooting stage) is exact on each interval and the exact interval map is
the zero-order-hold discretisation exp([[A, B], [0, 0]] h) (scipy). Copies with other values of
b end elsewhere by an amount that depends on the inputs' path (∫∫x), so the scenario problem
— the effort plus W times the mean squared terminal deviation, the nominal copy's end fixed —
is a linear-quadratic program with a non-trivial robust optimum, solved exactly by its KKT
system here, independently of the transcription. Ipopt stops at a relative KKT tolerance of
1e-8: the stated tolerance is 1e-6.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from nhgait.ocp import InitialGuess, OptimalControlProblem, ProblemError, solve
from nhgait.ocp.scenarios import Scenarios, ScenarioShooting

MASS, SPRING = 2.0, 0.5
N, T = 10, 2.0
TARGET = np.array([1.0, 0.5, 0.0, 0.0])            # x, y, x_dot, y_dot at t = T
TERMINAL = ("x", "y", "x_dot", "y_dot")
SCALES = np.array([0.5, 0.2, 1.0, 0.4])
TOL = 1e-6


@pytest.fixture(scope="module")
def coupled():
    from nhgait.dynamics import System, derive
    from nhgait.dynamics.numerics.parametric import parametric_rhs
    from nhgait.dynamics.numerics.specialisation import specialise
    system = System(["x", "y"], "m*(x_dot**2 + y_dot**2)/2", [], forces={"x": "Fx", "y": "Fy + b*x"},
                    parameters={"m": MASS, "b": SPRING}, inputs=["Fx", "Fy"])
    model = specialise(derive(system, "reduced"), velocities=("x_dot", "y_dot"))
    return model, parametric_rhs(model)


def _problem(model):
    rest = {"x": 0.0, "y": 0.0, "x_dot": 0.0, "y_dot": 0.0}
    return OptimalControlProblem(model, T, N, initial=rest, final=dict(zip(TERMINAL, TARGET, strict=True)))


def _final_map(b):
    """The matrix G (4 × 2N) of z(T) = G u from rest (u = (F_x0, F_y0, F_x1, …)), z = (x, y, vx, vy),
    by the exact zero-order-hold map of each interval."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[3, 0] = b / MASS
    B = np.array([[0, 0], [0, 0], [1 / MASS, 0], [0, 1 / MASS]])
    E = expm(np.block([[A, B], [np.zeros((2, 6))]]) * (T / N))
    Phi, Gam = E[:4, :4], E[:4, 4:]
    G = np.zeros((4, 2 * N))
    for k in range(N):
        G = Phi @ G
        G[:, 2 * k:2 * k + 2] += Gam
    return G


def kkt_optimum(copies, weight):
    """(inputs 2 × N, objective) of min Σ h |u_k|² + W/S Σ_s |D(G_s u − t)|² s.t. G_0 u = t."""
    h = T / N
    G0, Gs = _final_map(SPRING), [_final_map(b) for b in copies]
    D2 = np.diag(1 / SCALES ** 2)
    S = len(copies)
    H = 2 * h * np.eye(2 * N) + 2 * weight / S * sum(G.T @ D2 @ G for G in Gs)
    rhs = 2 * weight / S * sum(G.T @ D2 @ TARGET for G in Gs)
    K = np.block([[H, G0.T], [G0, np.zeros((4, 4))]])
    u = np.linalg.solve(K, np.concatenate([rhs, TARGET]))[:2 * N]
    J = h * u @ u + weight / S * sum((G @ u - TARGET) @ D2 @ (G @ u - TARGET) for G in Gs)
    return u.reshape(N, 2).T, float(J)


def _scenarios(ode, copies, weight, aggregate="mean"):
    params = [[MASS, b] for b in copies]                      # the model's parameter order: m, b
    return Scenarios(ode=ode, params=params, terminal=TERMINAL, scales=SCALES, weight=weight,
                     aggregate=aggregate)


def _solve(model, scenarios):
    guess = InitialGuess(np.zeros((4, N + 1)), np.zeros((2, N)))
    return solve(_problem(model), guess, transcription=ScenarioShooting(scenarios=scenarios))


def test_the_parameter_order_of_the_copies_is_the_models(coupled):
    model, ode = coupled
    assert tuple(model.numeric.param_names) == ("m", "b")
    z, u = np.array([0.3, 0.1, 0.2, -0.4]), np.array([0.7, -0.2])
    zdot = np.asarray(ode(0.0, z, u, [MASS, 1.5])).ravel()
    np.testing.assert_allclose(zdot, [0.2, -0.4, 0.7 / MASS, (-0.2 + 1.5 * 0.3) / MASS], rtol=1e-14)


@pytest.mark.parametrize("copies", [(0.25,), (0.25, 1.0, 2.0)], ids=["one copy", "three copies"])
def test_the_mean_scenario_optimum_is_the_exact_lq_one(coupled, copies):
    model, ode = coupled
    U, J = kkt_optimum(copies, weight=30.0)
    sol = _solve(model, _scenarios(ode, copies, 30.0))
    assert sol.success, sol.message
    assert abs(sol.objective - J) <= TOL * J
    assert np.max(np.abs(sol.u.T - U)) <= TOL * np.max(np.abs(U))          # U: nu × N
    np.testing.assert_allclose(sol.z[-1], TARGET, atol=1e-8)        # the nominal end stays hard
    nominal_U, nominal_J = kkt_optimum((SPRING,), weight=0.0)
    assert np.max(np.abs(U - nominal_U)) > 0.1 * np.max(np.abs(U))           # the copies matter


def test_the_worst_case_of_one_copy_is_its_mean(coupled):
    """With one copy the largest deviation is the deviation: the epigraph form (τ ≥ e_1, W τ)
    reaches the same LQ optimum."""
    model, ode = coupled
    U, J = kkt_optimum((1.0,), weight=2.0)
    sol = _solve(model, _scenarios(ode, (1.0,), 2.0, aggregate="worst"))
    assert sol.success, sol.message
    assert abs(sol.objective - J) <= TOL * J
    assert np.max(np.abs(sol.u.T - U)) <= TOL * np.max(np.abs(U))


def test_no_copies_is_the_nominal_problem(coupled):
    model, ode = coupled
    _, J = kkt_optimum((SPRING,), weight=0.0)
    sol = _solve(model, Scenarios(ode=ode, params=np.zeros((0, 2)), terminal=TERMINAL, scales=SCALES,
                                  weight=1.0))
    assert sol.success
    assert abs(sol.objective - J) <= TOL * J


def test_bad_copies_are_listed_together(coupled):
    model, ode = coupled
    bad = Scenarios(ode=ode, params=[[MASS, np.nan]], terminal=("x", "speed"), scales=[1.0], weight=-1.0,
                    aggregate="median")
    with pytest.raises(ProblemError) as info:
        _solve(model, bad)
    text = str(info.value)
    for part in ("aggregate = 'median'", "weight = -1.0", "finite", "'speed' not a state",
                 "one positive scale"):
        assert part in text, (part, text)


# ----------------------------------------------------------------------------- [task.robust]
def _task(robust, **extra):
    from nhgait.gaits.tasks.sources import resolve
    table = {**resolve("unicycle", "parallel-park").task.to_dict(), **extra}
    return table if robust is None else {**table, "robust": robust}


def test_bad_robust_tables_are_one_error_naming_every_problem():
    from nhgait.gaits.tasks.sources import resolve
    robust = {"parameters": {"m": [0.9, -1.0], "mass": [1.1]}, "samples": 0, "aggregate": "median",
              "weight": -2, "terminal": ["x", "speed"], "extra": 1}
    with pytest.raises(ProblemError) as info:
        resolve("unicycle", _task(robust))
    text = str(info.value)
    for part in ("robust: unknown key(s) ['extra']", "robust.parameters.m: factors must be positive",
                 "robust.samples = 0", "robust.aggregate = 'median'", "robust.weight = -2",
                 "unknown parameter 'mass'", "robust.terminal: unknown name 'speed'"):
        assert part in text, (part, text)


def test_a_robust_task_round_trips_through_its_table():
    from nhgait.gaits.tasks.sources import resolve
    robust = {"parameters": {"m": [0.9, 1.1], "J_theta": [1.2]}, "aggregate": "worst", "weight": 0.5}
    task = resolve("unicycle", _task(robust)).task
    assert resolve("unicycle", task).task.robust == task.robust
    assert [sorted(c.items()) for c in task.robust.factors()] == [
        [("J_theta", 1.2), ("m", 0.9)], [("J_theta", 1.2), ("m", 1.1)]]
    drawn = resolve("unicycle", _task({**robust, "samples": 5, "seed": 3})).task.robust.factors()
    assert len(drawn) == 5
    assert all(0.9 <= c["m"] <= 1.1 and c["J_theta"] == 1.2 for c in drawn)
    changed = resolve("unicycle", task, overrides=["robust.weight=2", "robust.samples=3"]).task
    assert (changed.robust.weight, changed.robust.samples) == (2.0, 3)
    assert "robust.weight=2" in changed.name


def test_a_copy_at_the_nominal_parameters_reproduces_the_nominal_plan():
    """One copy with θ_1 = θ_0 (one draw of the factor 1): it follows the nominal copy exactly,
    its deviation is 0 and the robust plan is the nominal one, objective to 1e-8 — the
    parametric ODE (θ an argument, the numeric route) against the specialised one."""
    from nhgait.gaits.planner import plan
    nominal = plan("unicycle", _task(None)).solution
    robust = plan("unicycle", _task({"parameters": {"m": [1.0]}, "samples": 1})).solution
    assert nominal.success
    assert robust.success
    assert abs(robust.objective - nominal.objective) <= 1e-8 * nominal.objective
    record = robust.settings["robust"]
    assert record["copies"] == 1
    assert record["robust_plan"]["worst"] < 1e-12


def test_the_robust_plan_spreads_less_under_the_mismatch_it_was_planned_for():
    """The snakeboard's forward gait (N = 50) planned against m ×1.1 (weight 10), then both plans
    re-simulated open loop on the general model by nhgait track (its compiled loop, rtol 1e-8,
    no noise) with m ×1.1: the robust plan ends closer to where it was planned to."""
    from nhgait.gaits.tasks.sources import resolve
    from nhgait.gaits.tracking.runs import Noise
    from nhgait.gaits.tracking.study import track
    task = {**resolve("snakeboard", "forward").task.to_dict(), "intervals": 50}
    errors = {}
    for label, robust in (("nominal", {}),
                          ("robust", {"robust": {"parameters": {"m": [1.1]}, "weight": 10.0}})):
        report = track("snakeboard", {**task, **robust}, mismatch={"m": 1.1}, samples=1, seed=0,
                       noise=Noise(0.0, 0.0)).report
        errors[label] = report["open_loop"]["final_position_error"]["max"]
    assert errors["robust"] < 0.5 * errors["nominal"], errors
