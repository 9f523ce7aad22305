"""The feedback along a plan (ocp/feedback.py) and its controller on the compiled closed loop
(dynamics/simulation/gain_schedule.py), each against an independent reference.

Independent references
----------------------
* **scipy's discrete algebraic Riccati solver** (``solve_discrete_are``): a long horizon of a
  time-invariant system makes the finite-horizon recursion converge to it.
* **The exact propagator of a linear ODE**: [A_k B_k] of the RK4 stage equal e^{hA} and
  A⁻¹(e^{hA} − I)B up to RK4's error, bounded by M (h/M)⁵ ‖A‖⁵ e^{h‖A‖} / 120 per step (the
  remainder of the degree-4 Taylor polynomial).
* **scipy's CubicHermiteSpline** for the reference z_ref(t) and numpy for the law.
* **scipy's DOP853 at rtol 1e-11** against the compiled closed loop at rtol 1e-8 (or the scipy
  fallback without a C compiler): agreement to 1e-6.
* **The plan's own verification**: with the model's parameters and no noise the closed loop
  follows the plan to the verification's tolerance (1e-6).
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from linear_ocp import linear_problem

from nhgait.dynamics.simulation.gain_schedule import GainSchedule
from nhgait.ocp.feedback import Feedback, default_weights, riccati, stage_jacobians, state_scales


@pytest.fixture(scope="module")
def parked():
    """The unicycle's parallel park, N = 30, with its feedback (planned once)."""
    from nhgait.gaits.planner import plan, prepare
    result = plan("unicycle", "parallel-park", intervals=30, jit=False)
    assert result.success
    assert result.solution.feedback is not None
    return result, prepare(result.plan)


def test_riccati_converges_to_the_discrete_algebraic_riccati_solution():
    """400 steps of a time-invariant (A, B): K_0 and P_0 equal scipy's DARE solution to 1e-9
    (the recursion contracts by the closed loop's spectral radius squared per step)."""
    from scipy.linalg import solve_discrete_are
    rng = np.random.default_rng(3)
    A = np.eye(4) + 0.1 * rng.normal(size=(4, 4))
    B = rng.normal(size=(4, 2))
    Q, R = rng.uniform(0.5, 2.0, 4), rng.uniform(0.5, 2.0, 2)
    N = 400
    K, P0 = riccati(np.repeat(A[None], N, 0), np.repeat(B[None], N, 0), Q, R, Q, weight=1.0)
    P = solve_discrete_are(A, B, np.diag(Q), np.diag(R))
    K_dare = np.linalg.solve(np.diag(R) + B.T @ P @ B, B.T @ P @ A)
    assert np.max(np.abs(P0 - P)) <= 1e-9 * np.max(np.abs(P))
    assert np.max(np.abs(K[0] - K_dare)) <= 1e-9 * max(1.0, np.max(np.abs(K_dare)))


def test_stage_jacobians_of_a_linear_ode_are_its_exact_propagator():
    """[A_k B_k] = [e^{hA}, A⁻¹(e^{hA} − I)B] up to RK4's error bound (module docstring), at
    every interval; the plan's defect of an exact trajectory is at that level too."""
    from scipy.linalg import expm
    A = np.array([[0.0, 1.0, 0.0], [-4.0, -0.3, 0.5], [0.2, 0.0, -1.0]])
    B = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, -2.0]])
    T, N, M = 2.0, 8, 4
    problem = linear_problem(A, B, T, N)
    h = T / N
    E = expm(h * A)
    rng = np.random.default_rng(5)
    controls = rng.uniform(-1, 1, (2, N))
    states = np.zeros((3, N + 1))
    states[:, 0] = rng.uniform(-1, 1, 3)
    for k in range(N):
        states[:, k + 1] = E @ states[:, k] + np.linalg.solve(A, (E - np.eye(3)) @ B @ controls[:, k])
    Ak, Bk, gap = stage_jacobians(problem, states, controls, T, steps=M)
    a = np.linalg.norm(A, 2)
    bound = M * (h / M) ** 5 * a ** 5 * np.exp(h * a) / 120
    assert Ak.shape == (N, 3, 3)
    assert Bk.shape == (N, 3, 2)
    assert np.max(np.abs(Ak - E)) <= bound
    assert np.max(np.abs(Bk - np.linalg.solve(A, (E - np.eye(3)) @ B))) <= bound * np.linalg.norm(B, 2)
    assert np.max(gap) <= 4 * bound


def test_state_scales_follow_the_documented_rules():
    """Bound width when both ends are finite; else the plan's range; a flat state takes the
    largest range of its kind (configuration coordinates / velocity states)."""
    A, B = np.eye(3), np.ones((3, 2))
    problem = linear_problem(A, B, 1.0, 2).replace(state_bounds={"b": (-2.0, 3.0)})
    states = np.array([[0.0, 0.5, 1.0], [0.0, 0.1, 0.0], [0.0, 1e-6, 0.0]])
    s = state_scales(problem, states)
    assert s.tolist() == [1.0, 5.0, 5.0]        # a: range; b: bound width; c: flat → the largest velocity
    w = default_weights(problem, states, np.array([[0.2, -0.4], [0.0, 0.0]]))
    assert np.allclose(w.state, 1 / (0.1 * s) ** 2)
    assert np.allclose(w.final, 25 * w.state)
    assert np.allclose(w.control_scale, [0.4, 1.0])   # the plan's peak; an unused input: the bound


def _schedule(N=4, seed=1):
    """A schedule on σ(q, q̇) = (q, 2 q̇ + sin q) with random gains and a smooth reference."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, N + 1)
    ref = lambda tt: np.array([np.sin(tt), np.cos(2 * tt), 0.5 * tt ** 2, tt])  # noqa: E731
    dref = lambda tt: np.array([np.cos(tt), -2 * np.sin(2 * tt), tt, 1.0])     # noqa: E731
    rates = np.stack([np.stack([dref(t[k]), dref(t[k + 1])]) for k in range(N)])
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    state_map = ca.Function("s", [q, qd], [ca.vertcat(q, 2 * qd + ca.sin(q))])
    sched = GainSchedule(times=t, controls=rng.normal(size=(N, 2)), gains=rng.normal(size=(N, 2, 4)),
                         reference=np.array([ref(tt) for tt in t]), rates=rates, state_map=state_map,
                         lower=np.array([-0.5, -np.inf]), upper=np.array([0.5, np.inf]))
    return sched, ref


def test_gain_schedule_law_equals_the_formula_with_scipys_hermite_interpolant():
    """u = sat(u_k − K_k(σ(q, q̇) − z_ref(t))) with z_ref the cubic Hermite spline of each
    interval (scipy), at random points; the clip acts on the first input only."""
    from scipy.interpolate import CubicHermiteSpline
    sched, _ = _schedule()
    rng = np.random.default_rng(2)
    clipped = 0
    for _ in range(40):
        tt, q, qd = rng.uniform(0, 2), rng.normal(size=2), rng.normal(size=2)
        k = min(int(tt / 0.5), 3)
        spline = CubicHermiteSpline(sched.times[k:k + 2], sched.reference[k:k + 2], sched.rates[k], axis=0)
        z = np.r_[q, 2 * qd + np.sin(q)]
        u = sched.controls[k] - sched.gains[k] @ (z - spline(tt))
        clipped += abs(u[0]) > 0.5
        u[0] = np.clip(u[0], -0.5, 0.5)
        assert np.allclose(sched(tt, q, qd), u, rtol=1e-12, atol=1e-12)
        assert np.allclose(sched.reference_state(tt), spline(tt), rtol=1e-12, atol=1e-12)
    assert 0 < clipped < 40


def test_hermite_reference_is_exact_for_cubics():
    """z_ref reproduces a cubic polynomial from its values and rates at the knots (1e-12)."""
    sched, _ = _schedule()
    cubic = lambda tt: np.array([tt ** 3 - tt, 2 - tt ** 2, tt, 1.0])                 # noqa: E731
    dcubic = lambda tt: np.array([3 * tt ** 2 - 1, -2 * tt, 1.0, 0.0])                 # noqa: E731
    t = sched.times
    from dataclasses import replace
    sched = replace(sched, reference=np.array([cubic(tt) for tt in t]),
                    rates=np.stack([np.stack([dcubic(t[k]), dcubic(t[k + 1])]) for k in range(t.size - 1)]))
    for tt in np.linspace(0, 2, 37):
        assert np.allclose(sched.reference_state(tt), cubic(tt), atol=1e-12)


def test_feedback_round_trips_through_its_json(parked):
    """Feedback.from_dict(to_dict()) gives back the gains, reference, rates, weights and bounds."""
    import json
    fb = parked[0].solution.feedback
    back = Feedback.from_dict(json.loads(json.dumps(fb.to_dict())))
    for name in ("t", "states", "controls", "gains", "rates", "lower", "upper"):
        assert np.array_equal(getattr(back, name), getattr(fb, name)), name
    assert back.state_names == fb.state_names
    assert np.array_equal(back.weights.final, fb.weights.final)


def _robot_params(model, factor):
    """The unicycle's parameters with the heading inertia J_theta multiplied by ``factor``."""
    pv = np.asarray(model.numeric.params(None), float).copy()
    pv[list(model.numeric.param_names).index("J_theta")] *= factor
    return pv


def test_compiled_closed_loop_agrees_with_scipy_at_tighter_tolerance(parked):
    """The plan's schedule on the general model with J_θ +20 %: the compiled route (rtol 1e-8)
    and scipy's DOP853 (rtol 1e-11) end in the same state to 1e-6."""
    from nhgait.dynamics import simulate
    from nhgait.gaits.tracking.runs import schedule_of
    result, prepared = parked
    sched = schedule_of(result.solution.feedback, prepared.specialised, prepared.model.system)
    z0 = sched.reference[0]
    n = prepared.model.system.n
    qd0 = np.asarray(prepared.specialised.numeric["qdot"](z0, []), float).ravel()
    span, params = (0.0, float(sched.times[-1])), _robot_params(prepared.model, 1.2)
    fast = simulate(prepared.model, span, z0[:n], qd0, controller=sched, params=params, method="compiled",
                    rtol=1e-8, atol=1e-10)
    tight = simulate(prepared.model, span, z0[:n], qd0, controller=sched, params=params, method="DOP853",
                     rtol=1e-11, atol=1e-13)
    assert fast.success
    assert tight.success
    assert np.max(np.abs(fast.q[-1] - tight.q[-1])) <= 1e-6
    assert np.max(np.abs(fast.qdot[-1] - tight.qdot[-1])) <= 1e-6


def test_nominal_closed_loop_follows_the_plan_and_feedback_cuts_a_mismatch(parked):
    """With the model's parameters and no noise both loops end where the plan ends (to the
    verification's 1e-6); with J_θ +20 % the closed loop ends at least ten times closer than the
    open loop (a physical claim of the feedback, measured 0.0010 m against 0.136 m)."""
    from nhgait.dynamics import simulate
    from nhgait.gaits.tracking.runs import schedule_of
    result, prepared = parked
    sched = schedule_of(result.solution.feedback, prepared.specialised, prepared.model.system)
    z0 = sched.reference[0]
    n = prepared.model.system.n
    qd0 = np.asarray(prepared.specialised.numeric["qdot"](z0, []), float).ravel()
    span = (0.0, float(sched.times[-1]))
    errors = {}
    for factor in (1.0, 1.2):
        for name, law in (("open", sched.open_loop()), ("closed", sched)):
            run = simulate(prepared.model, span, z0[:n], qd0, controller=law,
                           params=_robot_params(prepared.model, factor), method="compiled",
                           rtol=1e-10, atol=1e-12)
            errors[name, factor] = float(np.linalg.norm(run.q[-1, :2] - sched.reference[-1, :2]))
    assert errors["open", 1.0] <= 1e-6
    assert errors["closed", 1.0] <= 1e-6
    assert errors["open", 1.2] >= 0.05
    assert errors["closed", 1.2] <= 0.1 * errors["open", 1.2]
