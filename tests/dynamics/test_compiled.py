"""The compiled Dormand–Prince integrator (``simulate(method="compiled")``).

Independent references: the closed-form unicycle under constant torques (θ = k t², φ̈ constant,
x, y in closed form), the KanesMethod oracle (tests/oracles.py) with scipy DOP853, the
convergence order of the methods (2⁸ and 2⁵ per halving of the step), and the trust rules of
the cache (a tampered library must never be loaded).
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from nhgait.dynamics import simulate  # the function (lazy export), before any submodule import
from nhgait.dynamics.numerics.compiler import compiler_command
from nhgait.dynamics.simulation.controllers import OpenLoop, snakeboard_pd

#: these need a C compiler ($NHGAIT_CC, $CC, gcc or cc); CI may have none
needs_cc = pytest.mark.skipif(compiler_command() is None, reason="no C compiler")

M, R, J_PHI, J_THETA = 0.5, 0.1, 0.2, 0.3            # unicycle defaults
TAU_THETA, TAU_PHI = 0.9, 0.4


def _closed_form(t):
    """Unicycle from rest under constant torques: θ̈ = τ_θ/J_θ, φ̈ = τ_φ/(J_φ + m r²),
    ẋ = r cos θ φ̇, ẏ = r sin θ φ̇ ⇒ x = r a sin(k t²)/(2k), y = r a (1 − cos(k t²))/(2k)."""
    k, a = TAU_THETA / (2 * J_THETA), TAU_PHI / (J_PHI + M * R * R)
    t = np.asarray(t, dtype=float)
    q = np.stack([R * a * np.sin(k * t * t) / (2 * k), R * a * (1 - np.cos(k * t * t)) / (2 * k),
                  k * t * t, a * t * t / 2], axis=-1)
    return q


def _torques(T):
    return OpenLoop([0.0, T], [[TAU_THETA, TAU_PHI]], inputs=("tau_theta", "tau_phi"))


@needs_cc
@pytest.mark.parametrize("method", ["compiled", "compiled-DOPRI5"])
def test_closed_form_and_dense_output(models, method):
    """Final state and 41 interior (dense-output) points against the closed form."""
    T = 2.0
    t_eval = np.linspace(0.0, T, 41)
    traj = simulate(models["unicycle"]["reduced"], (0.0, T), np.zeros(4), np.zeros(4),
                    controller=_torques(T), method=method, rtol=1e-11, atol=1e-13, t_eval=t_eval)
    assert traj.success, traj.message
    assert traj.method == f"compiled {'DOPRI5' if 'DOPRI5' in method else 'DOP853'}"
    assert np.max(np.abs(traj.q - _closed_form(t_eval))) < 1e-9
    assert traj.t[-1] == T
    assert traj.t.size == 41


@needs_cc
@pytest.mark.parametrize("method, order", [("compiled", 8), ("compiled-DOPRI5", 5)])
def test_convergence_order(models, method, order):
    """With the step fixed by max_step (loose tolerance), halving h divides the error by ≈ 2^p."""
    T = 2.0
    errors = []
    for h in (0.2, 0.1):
        traj = simulate(models["unicycle"]["reduced"], (0.0, T), np.zeros(4), np.zeros(4),
                        controller=_torques(T), method=method, rtol=1e-2, atol=1e-2, max_step=h,
                        t_eval=[0.0, T])
        errors.append(np.max(np.abs(traj.q[-1] - _closed_form(T))))
    observed = np.log2(errors[0] / errors[1])
    assert order - 1.0 < observed < order + 1.5, (errors, observed)


def test_agrees_with_kane_oracle(models):
    """Snakeboard PD run on [0, 3] against KanesMethod + DOP853 (both tight)."""
    from oracles import oracle
    from scipy.integrate import solve_ivp
    o, ctl = oracle("snakeboard"), snakeboard_pd()
    model = models["snakeboard"]["reduced"]
    pv = model.numeric.params(None)
    q0, qd0 = np.array([0, 0, 0, 0, 1.0]), np.array([0, 0, 0, 1.0, 0])
    t_eval = np.linspace(0.0, 3.0, 13)
    ref = solve_ivp(lambda t, y: np.r_[y[5:], o.qddot(y[:5], y[5:], ctl(t, y[:5], y[5:]), pv)],
                    (0.0, 3.0), np.r_[q0, qd0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval)
    for form in ("reduced", "lagrange", "hamilton"):
        traj = simulate(models["snakeboard"][form], (0.0, 3.0), q0, qd0, controller=ctl,
                        method="compiled", rtol=1e-12, atol=1e-13, t_eval=t_eval)
        assert traj.success, traj.message
        assert np.max(np.abs(traj.q - ref.y[:5].T)) < 1e-9
        assert np.max(np.abs(traj.qdot - ref.y[5:].T)) < 1e-9


def test_every_step_output_grows_the_buffer(models):
    """Without t_eval every accepted step is reported (more than the first buffer of 4096)."""
    T = 2.0
    traj = simulate(models["unicycle"]["reduced"], (0.0, T), np.zeros(4), np.zeros(4),
                    controller=_torques(T), method="compiled", rtol=1e-13, atol=1e-15, max_step=4e-4)
    assert traj.t.size == traj.n_steps + 1 > 4097
    assert np.all(np.diff(traj.t) > 0)
    assert traj.t[-1] == T
    assert np.max(np.abs(traj.q - _closed_form(traj.t))) < 1e-10


def test_open_loop_segments_are_exact(models):
    """Zero-order hold integrated by segments: θ is piecewise quadratic (J_θ θ̈ = τ_θ)."""
    model = models["unicycle"]["reduced"]
    times = np.linspace(0.0, 1.0, 6)
    tau = np.array([0.3, -0.2, 0.5, 0.0, -0.4])
    ctl = OpenLoop(times, np.c_[tau, np.zeros(5)], inputs=("tau_theta", "tau_phi"))
    theta, omega = 0.0, 0.0
    for dt, a in zip(np.diff(times), tau / J_THETA, strict=True):
        theta, omega = theta + omega * dt + 0.5 * a * dt ** 2, omega + a * dt
    for method in ("compiled", "CVODES"):
        traj = simulate(model, (0.0, 1.0), np.zeros(4), np.zeros(4), controller=ctl,
                        method=method, rtol=1e-12, atol=1e-14, t_eval=times)
        assert traj.success, traj.message
        assert traj.settings["segments"] == 5
        assert traj.q[-1, 2] == pytest.approx(theta, abs=1e-10)
        assert traj.qdot[-1, 2] == pytest.approx(omega, abs=1e-10)
        assert traj.u[1, 0] == tau[0]                 # left limit at the switch t = 0.2


def test_every_step_output_over_several_segments_keeps_each_segment(models):
    """Every accepted step of a zero-order-hold run over 5 segments (one C call each, each
    writing its own rows): θ(t) at every reported step is the piecewise quadratic."""
    model = models["unicycle"]["reduced"]
    times = np.linspace(0.0, 1.0, 6)
    tau = np.array([0.3, -0.2, 0.5, 0.0, -0.4])
    ctl = OpenLoop(times, np.c_[tau, np.zeros(5)], inputs=("tau_theta", "tau_phi"))
    traj = simulate(model, (0.0, 1.0), np.zeros(4), np.zeros(4), controller=ctl, method="compiled",
                    rtol=1e-12, atol=1e-14)
    assert traj.success, traj.message
    assert traj.settings["segments"] == 5
    assert np.all(np.diff(traj.t) >= 0)
    starts = [(0.0, 0.0)]                               # (θ, ω) at each switch time
    for dt, a in zip(np.diff(times), tau / J_THETA, strict=True):
        theta, omega = starts[-1]
        starts.append((theta + omega * dt + 0.5 * a * dt ** 2, omega + a * dt))
    j = np.clip(np.searchsorted(times, traj.t, side="right") - 1, 0, 4)
    j[traj.t == times[j]] = np.maximum(j[traj.t == times[j]] - 1, 0)   # a switch time: the left piece
    dt = traj.t - times[j]
    expected = np.array([starts[k][0] for k in j]) + np.array([starts[k][1] for k in j]) * dt \
        + 0.5 * (tau / J_THETA)[j] * dt ** 2
    assert np.max(np.abs(traj.q[:, 2] - expected)) < 1e-10


@needs_cc
def test_per_evaluation_cost_and_compile_once(models):
    """The compiled right-hand side equals CasADi's; the library is built once per model."""
    from nhgait.dynamics.simulation.closed_loop import closed_loop
    model = models["snakeboard"]["reduced"]
    loop = closed_loop(model, snakeboard_pd())
    lib = loop.compiled()
    assert loop.compiled() is lib
    y = np.r_[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.0]
    pv = model.numeric.params(None)
    expected = np.asarray(loop.rhs(0.7, 0.7, y, pv)).ravel()
    assert np.max(np.abs(lib.rhs(0.7, 1e300, y, pv) - expected)) < 1e-13


def test_python_controller_falls_back_with_a_note(models):
    model = models["unicycle"]["reduced"]
    traj = simulate(model, (0.0, 1.0), np.zeros(4), np.zeros(4), method="compiled",
                    controller=lambda t, q, qd: np.array([TAU_THETA, TAU_PHI]), rtol=1e-10, atol=1e-12)
    assert traj.success, traj.message
    assert traj.method == "DOP853"
    assert "no casadi(t, q, qdot) method" in traj.settings["fallback"]
    assert np.max(np.abs(traj.q[-1] - _closed_form(1.0))) < 1e-8


def test_missing_compiler_falls_back_to_scipy(models, monkeypatch):
    monkeypatch.setenv("NHGAIT_CC", "/nonexistent/bin/cc")
    model = models["unicycle"]["reduced"]
    with pytest.warns(UserWarning, match="no usable C compiler"):
        traj = simulate(model, (0.0, 1.0), np.zeros(4), np.zeros(4), controller=_torques(1.0),
                        method="compiled", rtol=1e-10, atol=1e-12)
    assert traj.success, traj.message
    assert traj.method == "DOP853"
    assert "not found" in traj.settings["fallback"]
    assert "scipy DOP853" in traj.settings["fallback"]
    assert np.max(np.abs(traj.q[-1] - _closed_form(1.0))) < 1e-8


def _fresh_build(model, controller):
    """Build the loop's library ignoring every in-process memo (as a new process would)."""
    from nhgait.dynamics.simulation import compiled
    from nhgait.dynamics.simulation.closed_loop import closed_loop
    compiled.LOADED_LIBRARIES.clear()
    loop = closed_loop(model, controller)
    return compiled.build(loop.rhs, loop.outputs, loop.event)


@needs_cc
def test_tampered_library_is_refused_and_rebuilt(models, monkeypatch, tmp_path):
    from nhgait.dynamics.numerics.cache import UntrustedCacheWarning, file_sha256
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path))
    model = models["unicycle"]["reduced"]
    first = _fresh_build(model, _torques(1.0))
    assert first.compile_time_s > 0
    jit = tmp_path / "jit"
    so = jit / f"{first.key}.so"
    assert oct(jit.stat().st_mode & 0o777) == "0o700"
    again = _fresh_build(model, _torques(1.0))           # a trusted entry is loaded, not rebuilt
    assert again.compile_time_s == 0.0
    with open(so, "ab") as fh:                           # tamper with the library
        fh.write(b"\0")
    with pytest.warns(UntrustedCacheWarning, match="does not match its recorded SHA-256"):
        rebuilt = _fresh_build(model, _torques(1.0))
    assert rebuilt.compile_time_s > 0
    record = __import__("json").loads((jit / f"{first.key}.json").read_text())
    assert record["library_sha256"] == file_sha256(so)


@needs_cc
@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX permissions")
def test_world_writable_jit_directory_is_refused(models, monkeypatch, tmp_path):
    from nhgait.dynamics.numerics.cache import UntrustedCacheWarning
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path))
    jit = tmp_path / "jit"
    jit.mkdir(mode=0o700)
    os.chmod(jit, 0o777)
    model = models["unicycle"]["reduced"]
    with pytest.warns(UntrustedCacheWarning, match="writable by group or others"):
        lib = _fresh_build(model, _torques(1.0))
    assert lib.compile_time_s > 0  # nothing written there
    assert not list(jit.glob("*.so"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UntrustedCacheWarning)
        traj = simulate(model, (0.0, 1.0), np.zeros(4), np.zeros(4), controller=_torques(1.0),
                        method="compiled", rtol=1e-10, atol=1e-12)
    assert traj.success, traj.message
    assert np.max(np.abs(traj.q[-1] - _closed_form(1.0))) < 1e-8
    assert Path(tmp_path / "jit").stat().st_mode & 0o777 == 0o777    # left as the user set it


def test_auto_without_compiler_still_switches_when_stiff(models, monkeypatch):
    """method="auto" on scipy DOP853 (no compiler) detects the stiff gains and switches."""
    import math

    from nhgait.dynamics.simulation.controllers import PDTracking, Sinusoid
    monkeypatch.setenv("NHGAIT_CC", "/nonexistent/bin/cc")
    stiff = PDTracking(coordinates=("psi", "phi"),
                       desired={"psi": Sinusoid(), "phi": Sinusoid(phase=math.pi / 2)},
                       kp=1e4, kd=1000.0, feedforward=True,
                       system_coordinates=("x", "y", "theta", "psi", "phi"), inputs=("tau_psi", "tau_phi"))
    with pytest.warns(UserWarning, match="no usable C compiler"):
        traj = simulate(models["snakeboard"]["reduced"], (0.0, 2.0), np.array([0, 0, 0, 0, 1.0]),
                        np.array([0, 0, 0, 1.0, 0]), controller=stiff, method="auto", rtol=1e-6,
                        atol=1e-8, t_eval=[0.0, 2.0])
    assert traj.success, traj.message
    assert traj.method == "CVODES"
    assert "DOP853 detected stiffness" in traj.settings["auto"]
    assert "fallback" in traj.settings


@pytest.mark.parametrize("name", ["chaplygin_sleigh", "knife_edge_incline"])
def test_one_constraint_systems(models, name):
    """Systems with k = 1: compiled and CVODES against scipy DOP853 at 1e-12 and the energy
    balance E(t) − E(0) = W(t). (The torque keeps the heading below π/2, where the knife edge's
    reduction is singular.)"""
    from nhgait.dynamics.simulation.controllers import OpenLoop
    model = models[name]["reduced"]
    n, m = model.system.n, len(model.system.inputs)
    q0 = np.zeros(n)
    qdot0 = np.zeros(n)
    ctl = OpenLoop([0.0, 2.0], [[0.05] * m], inputs=tuple(model.system.inputs))
    ref = simulate(model, (0.0, 2.0), q0, qdot0, controller=ctl, rtol=1e-12, atol=1e-14, t_eval=[0.0, 2.0])
    for method, tol in (("compiled", 1e-8), ("CVODES", 1e-6)):     # BDF is less accurate per rtol
        traj = simulate(model, (0.0, 2.0), q0, qdot0, controller=ctl, method=method, rtol=1e-10,
                        atol=1e-12, t_eval=[0.0, 2.0])
        assert traj.success, traj.message
        assert np.max(np.abs(traj.q[-1] - ref.q[-1])) < 10 * tol
        assert np.max(np.abs(traj.energy_balance)) < tol * max(1.0, abs(traj.energy[-1]))
