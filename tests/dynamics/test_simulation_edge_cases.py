"""Hard cases of issue 9 (and issue 7 items 5–7): no hang, no NaN passed on, the singular set,
stiff gains, 100 gait cycles, extreme parameters.

Independent references: a separate process under a generous timeout (a hang cannot hide), the
closed form of where a NaN appears (t = 5 for sqrt(5 − t), t = 0.5 for the controller), the
KanesMethod oracle (tests/oracles.py) for the state at the singular-set stop and for the
extreme parameters, the physical invariants ω(q)q̇ = 0 and E(t) − E(t₀) = W(t).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from nhgait.dynamics import simulate  # the function (lazy export), before any submodule import
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.numerics.compiler import compiler_command
from nhgait.dynamics.simulation.controllers import PDTracking, Sinusoid, snakeboard_pd, unicycle_pd
from nhgait.dynamics.simulation.driver import MAX_STEPS, NONFINITE, SINGULAR

#: these need a C compiler ($NHGAIT_CC, $CC, gcc or cc); CI may have none
needs_cc = pytest.mark.skipif(compiler_command() is None, reason="no C compiler")

SNAKE = ("x", "y", "theta", "psi", "phi")
SNAKE_Q0, SNAKE_QDOT0 = np.array([0, 0, 0, 0, 1.0]), np.array([0, 0, 0, 1.0, 0])
UNI_Q0, UNI_QDOT0 = np.zeros(4), np.array([0.1, 0.0, 1.0, 1.0])

_NAN_SCRIPT = textwrap.dedent('''
    import json, sys
    import numpy as np
    from nhgait.dynamics import System, derive, simulate
    def system(force):
        return System(name="uni", coordinates=["x", "y", "theta", "phi"],
                      lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2",
                      constraints=["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"],
                      forces={"theta": force, "phi": "tau"}, inputs=["tau"],
                      parameters={"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3})
    class NaNAfterHalf:
        def __call__(self, t, q, qd):
            return np.array([np.nan if t > 0.5 else 0.1])
    out = []
    q0, qd0 = np.zeros(4), np.array([0.1, 0.0, 1.0, 1.0])
    for label, force, controller in (("force sqrt(5 - t)", "sqrt(5 - t)", None),
                                     ("force sqrt(t - 5)", "sqrt(t - 5)", None),
                                     ("Python controller NaN after 0.5", "0", NaNAfterHalf())):
        for form in ("reduced", "lagrange"):
            model = derive(system(force), form)
            routes = [dict(method=m) for m in ("compiled", "DOP853", "RK45", "Radau", "BDF", "LSODA")]
            if controller is None:
                routes += [dict(method="CVODES")] + ([dict(dae="idas", t_eval=np.linspace(0, 10, 11))]
                                                     if form != "reduced" else [])
            for opts in routes:
                tr = simulate(model, (0.0, 10.0), q0, qd0, controller=controller, max_steps=1000, **opts)
                out.append(dict(case=label, form=form,
                                route=opts.get("method", "IDAS") if "dae" not in opts else "IDAS",
                                success=bool(tr.success), status=tr.status,
                                t_end=float(tr.t[-1]), message=tr.message,
                                finite=bool(np.all(np.isfinite(tr.q))
                                            and np.all(np.isfinite(tr.energy_balance)))))
    json.dump(out, sys.stdout)
''')


@pytest.fixture(scope="module")
def nan_runs():
    """Every route on a NaN force and a NaN controller, in a separate process whose timeout
    (240 s) fails only on a hang: each route stopping at the NaN is checked by its end time."""
    proc = subprocess.run([sys.executable, "-c", _NAN_SCRIPT], capture_output=True, text=True,
                          timeout=240, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout)


def test_nan_force_and_controller_stop_at_once(nan_runs):
    assert len(nan_runs) == 3 * 2 * 6 + 2 * (2 * 1) + 2 * 1
    for r in nan_runs:
        where = f"{r['case']} / {r['form']} / {r['route']}"
        assert not r["success"], where  # no NaN passed on
        assert r["finite"], where
        nan_from = {"force sqrt(5 - t)": 5.0, "force sqrt(t - 5)": 0.0}.get(r["case"], 0.5)
        assert r["t_end"] <= nan_from + 1e-2, where
        if r["status"] == NONFINITE:
            assert "stopped at t = " in r["message"], where
            culprit = "the controller NaNAfterHalf" if "controller" in r["case"] else "the force on theta"
            assert culprit in r["message"], where
        else:   # implicit methods creep up to the sqrt singularity of sqrt(5 - t): the step cap
            assert r["status"] == MAX_STEPS, where
            assert r["route"] in ("Radau", "BDF", "LSODA"), where
            assert "max_steps = 1000" in r["message"], where
    explicit = [r for r in nan_runs if r["route"] in ("compiled", "DOP853", "RK45", "CVODES", "IDAS")]
    assert all(r["status"] == NONFINITE for r in explicit)
    assert all(abs(r["t_end"] - 5.0) < 1e-9 for r in explicit
               if r["case"] == "force sqrt(5 - t)" and r["route"] in ("compiled", "DOP853", "RK45"))


@pytest.mark.parametrize("method", ["compiled", "DOP853", "RK45", "Radau", "BDF", "LSODA", "CVODES"])
def test_max_steps_honoured_by_every_method(models, method):
    traj = simulate(models["snakeboard"]["reduced"], (0.0, 10 * math.pi), SNAKE_Q0, SNAKE_QDOT0,
                    controller=snakeboard_pd(), method=method, max_steps=20)
    assert not traj.success
    assert traj.status == MAX_STEPS
    assert "max_steps = 20" in traj.message
    assert traj.t[-1] < 10 * math.pi
    assert np.all(np.isfinite(traj.q))
    if method not in ("CVODES",):
        assert traj.n_steps <= 20


def _crossing():
    """φ_d = 2 cos t: the steering is driven through φ = ±π/2, where the snakeboard's two
    constraints become dependent (the singular set)."""
    return PDTracking(coordinates=("psi", "phi"),
                      desired={"psi": Sinusoid(), "phi": Sinusoid(amplitude=2.0, phase=math.pi / 2)},
                      kp=10.0, kd=5.0, feedforward=True, system_coordinates=SNAKE,
                      inputs=("tau_psi", "tau_phi"))


def test_singular_set_crossing_stops_with_status(models):
    from oracles import oracle
    from scipy.integrate import solve_ivp
    stops = []
    for form in ("reduced", "lagrange", "hamilton"):
        for method in ("compiled", "DOP853", "Radau"):
            traj = simulate(models["snakeboard"][form], (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0,
                            controller=_crossing(), method=method, rtol=1e-10, atol=1e-12,
                            t_eval=np.linspace(0, 10, 101))
            assert not traj.success, (form, method, traj.message)
            assert traj.status == SINGULAR, (form, method, traj.message)
            assert "reached the singular set at t = " in traj.message
            assert np.all(np.isfinite(traj.q))
            assert np.all(np.isfinite(traj.energy_balance))
            assert abs(abs(traj.q[-1, 4]) - math.pi / 2) < 1e-3     # |cos φ| ~ 5e-4 at measure 1e-6
            assert traj.diagnostics["t_event"] == traj.t[-1]
            if form != "reduced":                                 # conditioning of ω M⁻¹ ωᵀ
                assert traj.diagnostics["max_cond_gram"] > 1e5
            stops.append(traj.t[-1])
    assert max(stops) - min(stops) < 1e-7                         # one crossing time for all
    # the state at the stop against KanesMethod + DOP853 integrated to the same time
    o, ctl = oracle("snakeboard"), _crossing()
    pv = models["snakeboard"]["reduced"].numeric.params(None)
    ref = solve_ivp(lambda t, y: np.r_[y[5:], o.qddot(y[:5], y[5:], ctl(t, y[:5], y[5:]), pv)],
                    (0.0, stops[0]), np.r_[SNAKE_Q0, SNAKE_QDOT0], method="DOP853", rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(traj.q[-1] - ref.y[:5, -1])) < 1e-6


@pytest.mark.parametrize("form, method",
                         [("lagrange", "CVODES"), ("hamilton", "CVODES"), ("lagrange", "IDAS")])
def test_sundials_keep_every_output_before_a_failure(models, form, method):
    """SUNDIALS routes integrate 16 outputs per call; when a call fails next to the singular set
    the outputs it reached before the failure are kept (they were lost: the run ended at
    t = 1.6 for a stop near 2.52). Reference: the compiled run of the same model at 1e-10."""
    grid = np.linspace(0, 10, 101)
    opts = dict(method="CVODES") if method == "CVODES" else dict(dae="idas")
    traj = simulate(models["snakeboard"][form], (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, controller=_crossing(),
                    rtol=1e-8, atol=1e-10, t_eval=grid, **opts)
    ref = simulate(models["snakeboard"][form], (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0, controller=_crossing(),
                   method="compiled", rtol=1e-10, atol=1e-12, t_eval=grid)
    assert not traj.success, traj.message
    assert traj.status == SINGULAR, traj.message
    on_grid = traj.t[:-1] if traj.t[-1] not in grid else traj.t      # then the last state reached
    n = len(on_grid)
    assert grid[n - 1] > ref.t[-1] - 0.1 - 1e-9                       # every grid time before the stop
    np.testing.assert_allclose(on_grid, grid[:n], rtol=0, atol=1e-12)
    assert np.max(np.abs(traj.q[:n] - ref.q[:n])) < 1e-4               # ≈ 1e-6 where the set is near
    assert traj.t[-1] <= ref.t[-1] + 1e-9
    assert np.all(np.isfinite(traj.q))


def test_singular_event_off_runs_on_and_degrades(models):
    """Without the event the reduced run passes next to the set and loses accuracy — the reason
    the event is on by default."""
    traj = simulate(models["snakeboard"]["reduced"], (0.0, 10.0), SNAKE_Q0, SNAKE_QDOT0,
                    controller=_crossing(), rtol=1e-10, atol=1e-12, singular_tol=None)
    assert traj.diagnostics["min_singular_measure"] < 1e-6
    assert np.max(np.abs(traj.energy_balance)) > 1e-9


def test_issue7_basis_singularity_stops_the_run():
    """Issue 7's example: fiber (x, y, z), constraint sin φ ẋ + cos φ ẏ + ż = 0; the constraint-
    adapted basis loses rank at φ = 0. Under τ_φ = −1 from rest at φ = 1, φ(t) = 1 − t²
    (J = 1/2) crosses 0 at t = 1."""
    from nhgait.dynamics import System, derive
    from nhgait.dynamics.simulation.controllers import OpenLoop
    system = System(name="issue7", coordinates=["x", "y", "z", "phi"],
                    lagrangian="m*(x_dot**2 + y_dot**2 + z_dot**2)/2 + J*phi_dot**2/2",
                    constraints=["sin(phi)*x_dot + cos(phi)*y_dot + z_dot"], forces={"phi": "tau"},
                    parameters={"m": 1.0, "J": 0.5}, fiber=["x", "y", "z"])
    model = derive(system, "reduced")
    measure = float(model.numeric["singular"]([0, 0, 0, 0.0], model.numeric.params(None)))
    if measure > 1e-6:
        pytest.xfail("numeric['singular'] does not yet vanish where the basis loses rank "
                     "(issue 7 item 6, engine owner); the event uses it as soon as it does")
    traj = simulate(model, (0.0, 5.0), [0, 0, 0, 1.0], np.zeros(4), method="compiled",
                    controller=OpenLoop([0.0, 5.0], [[-1.0]], inputs=("tau",)))
    assert traj.status == SINGULAR
    assert abs(traj.t[-1] - 1.0) < 1e-2


@needs_cc
def test_stiff_gains_auto_picks_bdf(models):
    """k_p = 10⁴, k_d = 200: eigenvalues ≈ −950 and −50 s⁻¹. At rtol 1e-6 the explicit methods'
    step is set by stability (h|λ| ≈ 5); ``auto`` detects it and redoes the run with CVODES
    (BDF). (At rtol 1e-8 the same steps are set by accuracy: h|λ| ≤ 1.6, no switch.)"""
    stiff = PDTracking(coordinates=("psi", "phi"),
                       desired={"psi": Sinusoid(), "phi": Sinusoid(phase=math.pi / 2)},
                       kp=1e4, kd=200.0, feedforward=True, system_coordinates=SNAKE,
                       inputs=("tau_psi", "tau_phi"))
    kw = dict(controller=stiff, rtol=1e-6, atol=1e-8, t_eval=[0.0, 4.0])
    model = models["snakeboard"]["reduced"]
    explicit = simulate(model, (0.0, 4.0), SNAKE_Q0, SNAKE_QDOT0, method="compiled", **kw)
    assert explicit.success
    assert "use method='CVODES', 'Radau' or 'BDF'" in explicit.diagnostics["recommendation"]
    auto = simulate(model, (0.0, 4.0), SNAKE_Q0, SNAKE_QDOT0, method="auto", **kw)
    assert auto.success
    assert auto.method == "CVODES"
    assert "detected stiffness" in auto.settings["auto"]
    assert auto.nfev < explicit.nfev / 5
    ref = simulate(model, (0.0, 4.0), SNAKE_Q0, SNAKE_QDOT0, method="Radau",
                   **{**kw, "rtol": 1e-9, "atol": 1e-11})
    assert np.max(np.abs(auto.q[-1] - ref.q[-1])) < 1e-3
    assert np.max(np.abs(explicit.q[-1] - ref.q[-1])) < 1e-5
    accurate = simulate(model, (0.0, 4.0), SNAKE_Q0, SNAKE_QDOT0, method="auto",
                        **{**kw, "rtol": 1e-8, "atol": 1e-10})
    assert accurate.method == "compiled DOP853"
    assert "auto" not in accurate.settings


def test_hundred_gait_cycles_constraint_drift(models):
    """100 cycles (t ∈ [0, 200π]): the reduced ODE keeps ω q̇ = 0 to round-off; the index-1
    DAE drifts; projection removes the drift; Baumgarte (α = 5) bounds it."""
    T = 200 * math.pi
    kw = dict(controller=snakeboard_pd(), method="compiled", rtol=1e-8, atol=1e-10,
              t_eval=np.linspace(0, T, 401))
    reduced = simulate(models["snakeboard"]["reduced"], (0.0, T), SNAKE_Q0, SNAKE_QDOT0, **kw)
    plain = simulate(models["snakeboard"]["lagrange"], (0.0, T), SNAKE_Q0, SNAKE_QDOT0, **kw)
    baum = simulate(models["snakeboard"]["lagrange"], (0.0, T), SNAKE_Q0, SNAKE_QDOT0,
                    stabilization="baumgarte", baumgarte=(5.0, 0.0), **kw)
    proj = simulate(models["snakeboard"]["lagrange"], (0.0, T), SNAKE_Q0, SNAKE_QDOT0,
                    stabilization="projection", **kw)
    res = {k: np.max(np.abs(t.constraint_residual)) for k, t in
           (("reduced", reduced), ("plain", plain), ("baumgarte", baum), ("projection", proj))}
    assert all(t.success for t in (reduced, plain, baum, proj))
    assert res["reduced"] < 1e-14
    assert res["projection"] < 1e-14
    assert res["plain"] > 100 * res["reduced"]
    assert res["baumgarte"] < res["plain"]
    for t in (reduced, plain, baum, proj):                 # E(t) − E(0) = W(t) along 100 cycles
        assert np.max(np.abs(t.energy_balance)) < 1e-6
    assert np.max(np.abs(reduced.q[-1] - proj.q[-1])) < 1e-5


@pytest.mark.parametrize("params", [{"J": 1e-3, "J_w": 1e-4, "J_r": 0.99 * 1.4 * 0.5},
                                    {"J_w": 1e-6}])
def test_extreme_parameters_report_conditioning(models, params):
    """J_r → m r² (board and wheels almost without inertia) and very light wheels: the kinetic
    metric is ill-conditioned and the steering dynamics stiff (λ ~ −k_d/J_w). ``auto`` switches
    to CVODES; every formulation agrees with KanesMethod + Radau (same parameters) and reports
    the conditioning."""
    from oracles import oracle
    from scipy.integrate import solve_ivp
    o, ctl = oracle("snakeboard"), snakeboard_pd()
    pv = models["snakeboard"]["reduced"].numeric.params(params)
    T = 1.0
    ref = solve_ivp(lambda t, y: np.r_[y[5:], o.qddot(y[:5], y[5:], ctl(t, y[:5], y[5:]), pv)],
                    (0.0, T), np.r_[SNAKE_Q0, SNAKE_QDOT0], method="Radau", rtol=1e-10, atol=1e-12)
    for form in ("reduced", "lagrange", "hamilton"):
        kw = dict(controller=ctl, method="auto", rtol=1e-9, atol=1e-11, t_eval=[0.0, T])
        traj = simulate(models["snakeboard"][form], (0.0, T), SNAKE_Q0, SNAKE_QDOT0, params=params, **kw)
        default = simulate(models["snakeboard"][form], (0.0, T), SNAKE_Q0, SNAKE_QDOT0, **kw)
        assert traj.success, traj.message
        assert traj.method == "CVODES"
        assert "detected stiffness" in traj.settings["auto"]
        assert np.max(np.abs(traj.q[-1] - ref.y[:5, -1])) < 1e-8
        assert traj.diagnostics["max_cond_metric"] > 100 * default.diagnostics["max_cond_metric"]
        if form != "reduced":
            assert traj.diagnostics["max_cond_gram"] >= 1.0


def test_energy_balance_uses_the_initial_state(models):
    """t_eval starting after t0: the balance still measures E(t) − E(t0) − W(t) (≈ 0)."""
    t_eval = np.linspace(1.0, 2 * math.pi, 50)
    traj = simulate(models["unicycle"]["lagrange"], (0.0, 2 * math.pi), UNI_Q0, UNI_QDOT0,
                    controller=unicycle_pd(), rtol=1e-10, atol=1e-12, t_eval=t_eval)
    assert traj.t[0] == 1.0
    assert np.max(np.abs(traj.energy_balance)) < 1e-8
    assert abs(traj.work[0]) > 1e-3                   # the controller did work before t = 1


def test_simulation_parameters_are_validated(models):
    model = models["snakeboard"]["reduced"]
    with pytest.raises(ModelError, match="not positive definite|singular"):
        simulate(model, (0, 1), SNAKE_Q0, SNAKE_QDOT0, params={"m": -0.5})
    with pytest.raises(ModelError, match="not finite"):
        simulate(model, (0, 1), SNAKE_Q0, SNAKE_QDOT0, params={"J": float("nan")})
    with pytest.raises(ModelError, match="unknown parameter 'mass'"):
        simulate(model, (0, 1), SNAKE_Q0, SNAKE_QDOT0, params={"mass": 1.0})
