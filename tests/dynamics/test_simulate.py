"""Tests of nhgait.dynamics.simulation.driver and nhgait.dynamics.simulation.controllers.

Reference numbers come from independent sources: the analytic solution of the unicycle's
decoupled heading equation J_θ θ̈ = τ_θ, and the KanesMethod oracle (tests/oracles.py).
"""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from nhgait.dynamics import simulate  # the function (lazy export), before any submodule import
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.simulation.controllers import OpenLoop, PDTracking, Sinusoid, snakeboard_pd, unicycle_pd
from nhgait.dynamics.simulation.driver import NONFINITE

SNAKE_Q0 = np.array([0.0, 0.0, 0.0, 0.0, 1.0])      # Table 3.3: psi_d(0) = 0, phi_d(0) = 1
SNAKE_QDOT0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0])   # psi_dot_d(0) = 1, phi_dot_d(0) = 0
UNI_Q0 = np.zeros(4)
UNI_QDOT0 = np.array([0.1, 0.0, 1.0, 1.0])          # x_dot = r cos(theta) phi_dot, r = 0.1


# ------------------------------------------------------------------------------------------
# controllers
# ------------------------------------------------------------------------------------------
def test_thesis_controllers_match_equations():
    t, q, qd = 0.7, np.array([0.1, 0.2, 0.3, 0.4]), np.array([0.5, -0.1, 0.2, 0.9])
    u = unicycle_pd()(t, q, qd)                      # eq. 3.53, kp = 20, kd = 5
    assert u == pytest.approx([20 * (math.sin(t) - 0.3) + 5 * (math.cos(t) - 0.2),
                               20 * (t - 0.4) + 5 * (1 - 0.9)], abs=1e-14)
    qs, qds = np.array([0, 0, 0, 0.3, 0.8]), np.array([0, 0, 0, 0.1, -0.2])
    u = snakeboard_pd()(t, qs, qds)                  # eq. 3.96, with the feed-forward q̈_d
    psi_d, phi_d = math.sin(t), math.sin(t + math.pi / 2)
    assert u == pytest.approx([-math.sin(t) + 10 * (psi_d - 0.3) + 5 * (math.cos(t) - 0.1),
                               -phi_d + 10 * (phi_d - 0.8) + 5 * (math.cos(t + math.pi / 2) + 0.2)],
                              abs=1e-14)


def test_controller_casadi_form_equals_numeric():
    import casadi as ca
    ctl = snakeboard_pd()
    t, q, qd = ca.SX.sym("t"), ca.SX.sym("q", 5), ca.SX.sym("qd", 5)
    f = ca.Function("u", [t, q, qd], [ctl.casadi(t, q, qd)])
    args = (1.3, np.linspace(-1, 1, 5), np.linspace(2, -2, 5))
    assert np.asarray(f(*args)).ravel() == pytest.approx(ctl(*args), abs=1e-14)


def test_open_loop_zoh_and_linear():
    zoh = OpenLoop([0.0, 1.0, 2.0], [[1.0], [3.0]])
    assert zoh(0.5)[0] == 1.0
    assert zoh(1.0)[0] == 3.0
    assert zoh(5.0)[0] == 3.0
    assert list(zoh.breakpoints) == [1.0]
    lin = OpenLoop([0.0, 1.0, 2.0], [[0.0], [2.0], [0.0]], kind="linear")
    assert lin(0.25)[0] == pytest.approx(0.5)
    assert lin(1.5)[0] == pytest.approx(1.0)
    with pytest.raises(ModelError, match="strictly increasing"):
        OpenLoop([0.0, 0.0], [[1.0]])
    with pytest.raises(ModelError, match=r"values must have shape \(2, m\)"):
        OpenLoop([0.0, 1.0, 2.0], [[1.0]])
    with pytest.raises(ModelError, match="tracked coordinates"):
        PDTracking(coordinates=("nope",), desired={"nope": Sinusoid()}, kp=1, kd=1,
                   feedforward=False, system_coordinates=("x", "y"))


# ------------------------------------------------------------------------------------------
# accuracy
# ------------------------------------------------------------------------------------------
def test_zoh_switching_is_exact(models):
    """θ under a zero-order-hold torque is piecewise quadratic: J_θ θ̈ = τ_θ (decoupled)."""
    model = models["unicycle"]["reduced"]
    times = np.linspace(0.0, 1.0, 6)
    tau = np.array([0.3, -0.2, 0.5, 0.0, -0.4])
    ctl = OpenLoop(times, np.c_[tau, np.zeros(5)], inputs=("tau_theta", "tau_phi"))
    traj = simulate(model, (0.0, 1.0), UNI_Q0, np.zeros(4), controller=ctl, rtol=1e-12, atol=1e-14)
    J = 0.3
    theta, omega = 0.0, 0.0
    for dt, a in zip(np.diff(times), tau / J, strict=True):
        theta, omega = theta + omega * dt + 0.5 * a * dt ** 2, omega + a * dt
    assert traj.success, traj.message
    assert traj.settings["segments"] == 5
    assert traj.q[-1, 2] == pytest.approx(theta, abs=1e-13)
    assert traj.qdot[-1, 2] == pytest.approx(omega, abs=1e-13)


@pytest.mark.parametrize("formulation", ["reduced", "lagrange", "hamilton"])
def test_matches_kane_oracle_short_horizon(models, formulation):
    """Every formulation against KanesMethod + DOP853 on t ∈ [0, 3] (both at rtol 1e-12)."""
    from oracles import oracle
    from scipy.integrate import solve_ivp

    o, ctl = oracle("snakeboard"), snakeboard_pd()
    model = models["snakeboard"][formulation]
    pv = model.numeric.params(None)      # same order as the oracle: m, J, J_r, J_w, r
    assert tuple(model.numeric.param_names) == tuple(o.parameters)
    t_eval = np.linspace(0.0, 3.0, 31)
    ref = solve_ivp(lambda t, y: np.r_[y[5:], o.qddot(y[:5], y[5:], ctl(t, y[:5], y[5:]), pv)],
                    (0.0, 3.0), np.r_[SNAKE_Q0, SNAKE_QDOT0], method="DOP853", rtol=1e-12,
                    atol=1e-12, t_eval=t_eval)
    traj = simulate(model, (0.0, 3.0), SNAKE_Q0, SNAKE_QDOT0, controller=ctl, rtol=1e-12,
                    atol=1e-13, t_eval=t_eval)
    assert traj.success, traj.message
    assert np.max(np.abs(traj.q - ref.y[:5].T)) < 1e-9
    assert np.max(np.abs(traj.qdot - ref.y[5:].T)) < 1e-9


@pytest.mark.parametrize("formulation", ["lagrange", "hamilton"])
def test_idas_agrees_with_index1(models, formulation):
    model = models["snakeboard"][formulation]
    t_eval = np.linspace(0.0, 10.0, 101)
    kw = dict(controller=snakeboard_pd(), rtol=1e-10, atol=1e-12, t_eval=t_eval)
    a = simulate(model, (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, dae="index1", **kw)
    b = simulate(model, (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, dae="idas", **kw)
    assert a.success
    assert b.success
    assert b.method == "IDAS"
    assert b.settings["dae"] == "idas"
    assert np.max(np.abs(a.q - b.q)) < 1e-6
    assert np.max(np.abs(a.lam - b.lam)) < 1e-6
    assert np.max(np.abs(b.constraint_residual)) < 1e-8


def test_energy_balance_and_work(models):
    """E(t) − E(0) = ∫τ·q̇ dt for the PD run (scleronomic constraints, no potential)."""
    traj = simulate(models["unicycle"]["lagrange"], (0.0, 2 * math.pi), UNI_Q0, UNI_QDOT0,
                    controller=unicycle_pd(), rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(traj.energy_balance)) < 1e-8
    assert np.max(np.abs(traj.work)) > 1e-3          # the controller really does work
    assert traj.energy_balance[0] == 0.0


# ------------------------------------------------------------------------------------------
# stabilisation
# ------------------------------------------------------------------------------------------
def test_stabilization_off_by_default_and_recorded(models):
    model = models["snakeboard"]["lagrange"]
    kw = dict(controller=snakeboard_pd(), rtol=1e-6, atol=1e-8, t_eval=np.linspace(0, 10, 21))
    plain = simulate(model, (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, **kw)
    assert plain.settings["stabilization"] is None
    assert plain.settings["baumgarte"] is None
    baum = simulate(model, (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, stabilization="baumgarte",
                    baumgarte=(5.0, 1.0), **kw)
    assert baum.settings["stabilization"] == "baumgarte"
    assert baum.settings["baumgarte"] == (5.0, 1.0)
    proj = simulate(model, (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, stabilization="projection", **kw)
    assert proj.settings["stabilization"] == "projection"
    # drift of ω q̇ at rtol 1e-6: ~1e-10 unstabilised, removed by projection
    assert np.max(np.abs(proj.constraint_residual)) < 1e-14
    for traj in (baum, proj):
        assert np.max(np.abs(traj.q - plain.q)) < 1e-5


# ------------------------------------------------------------------------------------------
# bad input and failure
# ------------------------------------------------------------------------------------------
def test_bad_inputs_raise(models):
    model = models["unicycle"]["lagrange"]
    with pytest.raises(ModelError, match="unknown method 'Euler'"):
        simulate(model, (0, 1), UNI_Q0, UNI_QDOT0, method="Euler")
    with pytest.raises(ModelError, match="t_span must be increasing"):
        simulate(model, (1.0, 0.0), UNI_Q0, UNI_QDOT0)
    with pytest.raises(ModelError, match="q has 3 entries, expected 4"):
        simulate(model, (0, 1), UNI_Q0[:3], UNI_QDOT0)
    with pytest.raises(ModelError, match="unknown dae form") as err:
        simulate(model, (0, 1), UNI_Q0, UNI_QDOT0, dae="index3", method="Euler")
    assert len(err.value.problems) == 2              # every problem reported at once
    with pytest.raises(ModelError, match="needs a controller with a casadi"):
        simulate(model, (0, 1), UNI_Q0, UNI_QDOT0, dae="idas", t_eval=[0, 1],
                 controller=lambda t, q, qd: np.zeros(2))
    with pytest.raises(ModelError, match="controller returned 3 inputs"):
        simulate(model, (0, 1), UNI_Q0, UNI_QDOT0, controller=lambda t, q, qd: np.zeros(3))
    with pytest.raises(ModelError, match="controller outputs"):
        simulate(model, (0, 1), UNI_Q0, UNI_QDOT0, controller=snakeboard_pd())
    with pytest.raises(ModelError, match="reduced ODE satisfies the constraints"):
        simulate(models["unicycle"]["reduced"], (0, 1), UNI_Q0, UNI_QDOT0, stabilization="projection")


def test_inconsistent_initial_state_raises(models):
    bad = UNI_QDOT0 + np.array([0.0, 0.05, 0.0, 0.0])   # sideways slip
    for formulation in ("reduced", "lagrange", "hamilton"):
        with pytest.raises(ModelError, match="violates the constraints"):
            simulate(models["unicycle"][formulation], (0, 1), UNI_Q0, bad)


class _BreaksAtHalf:
    """u = 0 until t = 0.5, NaN after: a deterministic integrator failure."""

    def __call__(self, t, q, qd):
        return np.array([np.nan if t > 0.5 else 0.0, 0.0])

    def casadi(self, t, q, qd):
        import casadi as ca
        return ca.vertcat(ca.if_else(t > 0.5, np.nan, 0.0), 0.0)


def test_integrator_failure_is_a_result(models):
    """A NaN input after t = 0.5 stops the run there (status −3), naming the controller."""
    traj = simulate(models["unicycle"]["reduced"], (0.0, 1.0), UNI_Q0, UNI_QDOT0,
                    controller=_BreaksAtHalf())
    assert not traj.success
    assert traj.status == NONFINITE
    assert "_BreaksAtHalf returned a non-finite input tau_theta" in traj.message
    assert 0.5 - 1e-9 <= traj.t[-1] <= 0.5 + 1e-9
    assert traj.q.shape == (traj.t.size, 4)
    assert np.all(np.isfinite(traj.q))
    assert np.all(np.isfinite(traj.energy_balance))


def test_idas_failure_is_a_result(models):
    traj = simulate(models["unicycle"]["lagrange"], (0.0, 1.0), UNI_Q0, UNI_QDOT0,
                    controller=_BreaksAtHalf(), dae="idas", t_eval=np.linspace(0, 1, 11),
                    max_steps=500)
    assert not traj.success
    assert traj.status == NONFINITE
    assert "returned a non-finite input tau_theta" in traj.message
    # every output before the NaN onset at t = 0.5 is kept (the failed call's reached outputs),
    # then the last state reached, between 0.5 and the next output
    np.testing.assert_allclose(traj.t[:6], np.linspace(0, 0.5, 6), rtol=0, atol=1e-12)
    assert traj.t.size == 6 or (traj.t.size == 7 and 0.5 < traj.t[-1] < 0.6)
    assert np.all(np.isfinite(traj.q))


# ------------------------------------------------------------------------------------------
# output
# ------------------------------------------------------------------------------------------
def test_to_csv_columns(models, tmp_path):
    traj = simulate(models["snakeboard"]["hamilton"], (0.0, 1.0), SNAKE_Q0, SNAKE_QDOT0,
                    controller=snakeboard_pd(), t_eval=np.linspace(0, 1, 11))
    path = tmp_path / "traj.csv"
    traj.to_csv(path)
    rows = list(csv.reader(open(path)))
    assert rows[0] == ["t", "x", "y", "theta", "psi", "phi"]
    assert len(rows) == 12
    assert float(rows[-1][0]) == 1.0
    assert float(rows[-1][4]) == traj.q[-1, 3]
    traj.to_csv(path, columns="all")
    header = next(csv.reader(open(path)))
    assert header[6:11] == ["x_dot", "y_dot", "theta_dot", "psi_dot", "phi_dot"]
    assert header[-7:] == ["lambda1", "lambda2", "constraint1", "constraint2", "energy", "work",
                           "energy_balance"]
    traj.to_csv(path, columns="state")
    assert next(csv.reader(open(path)))[6:] == ["p_x", "p_y", "p_theta", "p_psi", "p_phi"]
    with pytest.raises(ModelError, match="unknown columns"):
        traj.to_csv(path, columns="everything")


def test_trajectory_arrays_are_read_only(models):
    traj = simulate(models["unicycle"]["reduced"], (0.0, 0.1), UNI_Q0, UNI_QDOT0)
    assert traj.lam is None
    assert traj.state.shape[1] == 6
    with pytest.raises(ValueError):
        traj.q[0, 0] = 1.0


@pytest.mark.parametrize("method", ["DOP853", "compiled", "CVODES"])
def test_force_jump_is_a_breakpoint(method):
    """τ_θ = Heaviside(t − 0.3): θ = (t − 0.3)²/(2 J_θ) after the jump (closed form), even though
    no controller announces the jump time (System.force_jump_times splits the run)."""
    from nhgait.dynamics import System, derive
    system = System(name="uni_step", coordinates=["x", "y", "theta", "phi"],
                    lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2",
                    constraints=["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"],
                    forces={"theta": "Heaviside(t - 0.3)"},
                    parameters={"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3})
    traj = simulate(derive(system, "reduced"), (0.0, 1.0), np.zeros(4), np.zeros(4), method=method,
                    rtol=1e-12, atol=1e-14, t_eval=[0.0, 0.3, 1.0])
    assert traj.success, traj.message
    assert traj.settings["segments"] == 2
    assert traj.q[1, 2] == pytest.approx(0.0, abs=1e-14)
    assert traj.q[2, 2] == pytest.approx(0.7 ** 2 / (2 * 0.3), abs=1e-11)
    assert traj.qdot[2, 2] == pytest.approx(0.7 / 0.3, abs=1e-11)
