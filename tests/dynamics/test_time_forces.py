"""Forces that depend on time t (issue 19, item 7): every formulation and form derives them,
every simulation route integrates them, the specialisation keeps them.

Independent references
----------------------
* The roller racer of ``examples/roller_racer.toml`` modelled here again from its physical
  description with :class:`sympy.physics.mechanics.KanesMethod` (frames, the two bodies, the
  hinge point, the no-side-slip velocities of the two axle midpoints, the hinge torque acting on
  one body and reacting on the other); nothing is read from the scene's Lagrangian or
  constraints. Its accelerations q̈(t, q, q̇) are integrated with scipy DOP853 at rtol 1e-12.
* The unicycle under forces that depend on t only through θ̈ = τ_θ/J_θ and
  (J_φ + m r²)φ̈ = τ_φ with ẋ = r cos θ φ̇, ẏ = r sin θ φ̇, integrated with scipy DOP853 at
  rtol 1e-12.
"""
from __future__ import annotations

import functools
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, solve_ivp

from nhgait.dynamics import System, derive, load_scene, simulate
from nhgait.dynamics.derivation.reduction import derive_reduced
from nhgait.dynamics.derivation.states import consistent_velocities, to_state
from nhgait.dynamics.simulation.controllers import OpenLoop

SCENE = Path(__file__).resolve().parents[2] / "examples" / "roller_racer.toml"
#: the scene's parameter values, restated (kg, kg m², m)
PARAMS = {"m1": 1.5, "m2": 0.8, "I1": 0.04, "I2": 0.02, "d1": 0.3, "d2": 0.25}
T_FINAL = 6.0
Q0 = np.array([0.0, 0.0, 0.0, 0.2])
TIMES = (0.0, 0.37, 1.9, 7.3)                     # several t for pointwise comparisons
KINDS = ("lagrange", "hamilton", "reduced-explicit", "reduced-implicit")


def _hinge_torque(t, phi, phi_dot):
    """The scene's force on φ: 0.6 sin 2.5t − 1.5 φ − 0.1 φ̇ [N m]."""
    return 0.6 * np.sin(2.5 * t) - 1.5 * phi - 0.1 * phi_dot


# ------------------------------------------------------------------------------------------
# the independent Kane model of the roller racer
# ------------------------------------------------------------------------------------------
@functools.cache
def _kane():
    """Numeric functions of the Kane model: qddot(t, q, q̇), residual(q, q̇) (the two axle
    side-slip velocities), energy(q, q̇) (kinetic energy), momentum(q, q̇) = ∂T/∂q̇ and its
    rate momentum_rate(q, q̇, q̈)."""
    import sympy as sp
    from sympy.physics.mechanics import (
        KanesMethod,
        Point,
        ReferenceFrame,
        RigidBody,
        dynamicsymbols,
        inertia,
        kinetic_energy,
        msubs,
    )
    t = dynamicsymbols._t
    q = dynamicsymbols("x y theta phi")
    x, y, th, ph = q
    u = dynamicsymbols("u_x u_y u_theta u_phi")
    m1, m2, I1, I2, d1, d2 = (sp.Float(PARAMS[k]) for k in ("m1", "m2", "I1", "I2", "d1", "d2"))
    N = ReferenceFrame("N")
    B1 = N.orientnew("B1", "Axis", [th, N.z])             # front body
    B2 = N.orientnew("B2", "Axis", [th + ph, N.z])        # rear body
    O = Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", x * N.x + y * N.y)             # front axle midpoint = centre of mass
    P1.set_vel(N, P1.pos_from(O).dt(N))
    H = P1.locatenew("H", -d1 * B1.x)                     # hinge
    H.v2pt_theory(P1, N, B1)
    P2 = H.locatenew("P2", -d2 * B2.x)                    # rear axle midpoint = centre of mass
    P2.v2pt_theory(H, N, B2)
    bodies = [RigidBody("front", P1, B1, m1, (inertia(B1, 0, 0, I1), P1)),
              RigidBody("rear", P2, B2, m2, (inertia(B2, 0, 0, I2), P2))]
    qd = [qi.diff(t) for qi in q]
    to_u = dict(zip(qd, u, strict=True))
    torque = 0.6 * sp.sin(2.5 * t) - 1.5 * ph - 0.1 * u[3]
    loads = [(B2, torque * N.z), (B1, -torque * N.z)]     # hinge torque and its reaction
    cons = [msubs(P1.vel(N).dot(B1.y), to_u), msubs(P2.vel(N).dot(B2.y), to_u)]
    km = KanesMethod(N, q_ind=q, u_ind=[u[0], u[3]], kd_eqs=[a - b for a, b in zip(qd, u, strict=True)],
                     u_dependent=[u[1], u[2]], velocity_constraints=cons)
    km.kanes_equations(bodies, loads)
    qs, us, ts = sp.symbols("q0:4"), sp.symbols("v0:4"), sp.Symbol("time")
    plain = {**dict(zip(q, qs, strict=True)), **dict(zip(u, us, strict=True)), t: ts}

    def lam(args, expr):
        return sp.lambdify(args, msubs(expr, to_u).xreplace(plain), modules="numpy", cse=True)
    T = kinetic_energy(N, *bodies)
    p = sp.Matrix([msubs(T, to_u).diff(v) for v in u])
    qdd = sp.symbols("a0:4")
    p_plain = p.xreplace(plain)
    rate = p_plain.jacobian(qs) * sp.Matrix(us) + p_plain.jacobian(us) * sp.Matrix(qdd)
    mass, forcing = lam([ts, qs, us], km.mass_matrix), lam([ts, qs, us], km.forcing)
    # KanesMethod orders the speeds [independent; dependent] = (x, phi, y, theta)
    order = [0, 3, 1, 2]

    def qddot(tt, qq, vv):
        sol = np.linalg.solve(np.asarray(mass(tt, qq, vv), float),
                              np.asarray(forcing(tt, qq, vv), float).ravel())
        out = np.empty(4)
        out[order] = sol
        return out
    return {"qddot": qddot, "residual": lam([qs, us], sp.Matrix(cons)), "energy": lam([qs, us], T),
            "momentum": lam([qs, us], p), "momentum_rate": sp.lambdify([qs, us, qdd], rate, modules="numpy")}


def _kane_qdot(q, forward, phi_dot):
    """Velocities on the constraints with ẋ cos θ + ẏ sin θ = ``forward`` and φ̇ = ``phi_dot``
    (the front axle's speed and the hinge rate), from the Kane model's constraint rows."""
    res = _kane()["residual"]
    A = np.array([np.asarray(res(q, e), float).ravel() for e in np.eye(4)]).T       # k × n
    Y = np.array([[np.cos(q[2]), np.sin(q[2]), 0, 0], [0, 0, 0, 1.0]])
    return np.linalg.solve(np.vstack([A, Y]), [0, 0, forward, phi_dot])


@functools.cache
def _reference(t_final):
    """(q, q̇)(t_final) of the Kane model from the scene's initial state (the front axle rolling
    at 0.1 m/s, φ̇ = 0), integrated by scipy DOP853 at rtol 1e-12, atol 1e-13."""
    qddot = _kane()["qddot"]

    def f(t, y):
        return np.concatenate([y[4:], qddot(t, y[:4], y[4:])])
    y0 = np.concatenate([Q0, _kane_qdot(Q0, 0.1, 0.0)])
    sol = solve_ivp(f, (0.0, t_final), y0, method="DOP853", rtol=1e-12, atol=1e-13)
    assert sol.success
    return y0, sol.y[:, -1]


def _random_states(count, seed):
    """Consistent (t, q, q̇) away from the Kane model's dependent-speed singularity (θ = ±π/2)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        q = rng.uniform(-1.2, 1.2, 4)
        out.append((TIMES[i % len(TIMES)], q, _kane_qdot(q, rng.uniform(-1, 1), rng.uniform(-2, 2))))
    return out


# ------------------------------------------------------------------------------------------
# derivation
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def roller(scene):
    """Every formulation and form of the scene, derived once (the explicit and implicit reduced
    forms forced)."""
    system = scene.system
    return {"lagrange": derive(system, "lagrange"), "hamilton": derive(system, "hamilton"),
            "reduced-explicit": derive_reduced(system, form="explicit"),
            "reduced-implicit": derive_reduced(system, form="implicit")}


def test_scene_is_the_physical_roller_racer(scene):
    """The scene's kinetic energy and constraints equal those of the Kane model (random states)."""
    import sympy as sp
    s = scene.system
    assert {k: float(v) for k, v in s.parameters.items()} == PARAMS
    subs = s.param_subs()
    T = sp.lambdify([s.q, s.q_dot], s.L.xreplace(subs))
    W = sp.lambdify([s.q], s.omega().xreplace(subs))
    k = _kane()
    rng = np.random.default_rng(3)
    for _ in range(10):
        q, v = rng.uniform(-2, 2, 4), rng.uniform(-2, 2, 4)
        assert T(q, v) == pytest.approx(float(k["energy"](q, v)), rel=1e-13)
        np.testing.assert_allclose(np.asarray(W(q), float) @ v,
                                   np.asarray(k["residual"](q, v), float).ravel(), rtol=0, atol=1e-13)


def test_forms_are_the_requested_ones(roller):
    """Both reduced forms as forced; the explicit ż holds the force's time factor, and the
    scene's decimals (0.6, 1.5, 0.1) as the exact decimals 3/5, 3/2, 1/10 — not as the binary
    values of the floats, whose denominators are 2⁵³-sized."""
    import sympy as sp
    ex, im = roller["reduced-explicit"], roller["reduced-implicit"]
    assert ex.form == "explicit"
    assert im.form == "implicit"
    assert im.rhs is None
    assert sp.sin(sp.Float(2.5) * sp.Symbol("t", real=True)) in ex.rhs.atoms(sp.sin)
    assert max(r.q for r in ex.rhs.atoms(sp.Rational)) <= 10


def _accelerations(model, t, q, qdot):
    """q̈ of ``model`` at (t, q, q̇) (no inputs)."""
    pv = model.numeric.params()
    if model.formulation == "reduced":
        return np.asarray(model.numeric.call("qddot", t, to_state(model, q, qdot), [], pv), float)
    if model.formulation == "lagrange":
        xdot, _ = model.numeric.call("ode", t, np.concatenate([q, qdot]), [], pv)
        return np.asarray(xdot, float)[4:]
    raise AssertionError(model.formulation)


@pytest.mark.parametrize("kind", ["lagrange", "reduced-explicit", "reduced-implicit"])
def test_accelerations_match_kane(roller, kind):
    """q̈(t, q, q̇) against KanesMethod at 12 consistent states and 4 times: relative 1e-10."""
    qddot = _kane()["qddot"]
    for t, q, qd in _random_states(12, seed=11):
        ref = qddot(t, q, qd)
        got = _accelerations(roller[kind], t, q, qd)
        assert np.max(np.abs(got - ref)) <= 1e-10 * max(1.0, np.max(np.abs(ref)))


def test_hamilton_momentum_rate_matches_kane(roller):
    """Hamilton's ṗ(t, q, p) = d/dt ∂T/∂q̇ along the Kane accelerations: relative 1e-10."""
    model, k = roller["hamilton"], _kane()
    pv = model.numeric.params()
    for t, q, qd in _random_states(12, seed=12):
        p = np.asarray(k["momentum"](q, qd), float).ravel()
        ref = np.asarray(k["momentum_rate"](q, qd, k["qddot"](t, q, qd)), float).ravel()
        xdot, _ = model.numeric.call("ode", t, np.concatenate([q, p]), [], pv)
        np.testing.assert_allclose(np.asarray(xdot, float)[:4], qd, rtol=0, atol=1e-12)
        got = np.asarray(xdot, float)[4:]
        assert np.max(np.abs(got - ref)) <= 1e-10 * max(1.0, np.max(np.abs(ref)))


def test_reduced_forms_agree(roller):
    """ż of the explicit and the implicit form at 16 consistent states and 4 times: relative
    1e-10 (two derivations sharing no arithmetic: exact fractions against CasADi solves)."""
    ex, im = roller["reduced-explicit"], roller["reduced-implicit"]
    pv = ex.numeric.params()
    changed = 0.0
    for t, q, qd in _random_states(16, seed=13):
        z = to_state(ex, q, qd)
        a = np.asarray(ex.numeric.call("rhs", t, z, [], pv), float)
        b = np.asarray(im.numeric.call("rhs", t, z, [], pv), float)
        assert np.max(np.abs(a - b) / (1 + np.abs(b))) <= 1e-10
        c = np.asarray(ex.numeric.call("rhs", t + 0.5, z, [], pv), float)
        changed = max(changed, float(np.max(np.abs(c - a))))
    assert changed > 1e-3                                  # ż does depend on t


# ------------------------------------------------------------------------------------------
# simulation
# ------------------------------------------------------------------------------------------
def _initial(scene):
    return scene.simulation.q0, scene.simulation.qdot0


def _final(traj):
    return np.concatenate([traj.q[-1], traj.qdot[-1]])


#: max |Δ(q, q̇)(T)| allowed against the reference. Every run uses rtol 1e-11, atol 1e-12 over
#: 4–6 s of a smooth, non-stiff motion whose sensitivity to a perturbation stays O(1), and the
#: reference is 10× tighter. The one-step methods (DOP853, Radau, compiled DOP853, which
#: ``auto`` picks here) then land within a few 1e-12 (measured ≤ 4e-12): 1e-10. The
#: variable-order multistep methods (CVODES, IDAS, BDF, LSODA) accumulate the errors of their
#: local tolerance over many more, lower-order steps (measured ≤ 1.7e-9): 1e-8. A wrong force is
#: far outside either: dropping the time factor moves (q, q̇)(6 s) by 0.68.
SIM_TOL = {"DOP853": 1e-10, "Radau": 1e-10, "compiled": 1e-10, "auto": 1e-10,
           "CVODES": 1e-8, "IDAS": 1e-8, "BDF": 1e-8, "LSODA": 1e-8}


@pytest.mark.parametrize("method", ["DOP853", "Radau", "CVODES"])
@pytest.mark.parametrize("kind", KINDS)
def test_simulation_matches_reference(scene, roller, kind, method):
    y0, ref = _reference(T_FINAL)
    q0, qd0 = _initial(scene)
    np.testing.assert_allclose(np.concatenate([q0, qd0]), y0, rtol=0, atol=1e-15)
    traj = simulate(roller[kind], (0.0, T_FINAL), q0, qd0, method=method, rtol=1e-11, atol=1e-12)
    assert traj.success, traj.message
    assert np.max(np.abs(_final(traj) - ref)) < SIM_TOL[method]


@pytest.mark.parametrize("kind, options", [
    ("lagrange", {"dae": "idas"}), ("hamilton", {"dae": "idas"}), ("reduced-explicit", {"method": "BDF"}),
    ("reduced-implicit", {"method": "LSODA"}), ("reduced-explicit", {"method": "auto"})])
def test_other_routes_match_reference(scene, roller, kind, options):
    """The SUNDIALS DAE route (IDAS), the remaining scipy multistep methods and ``auto``."""
    q0, qd0 = _initial(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)          # auto without a compiler
        traj = simulate(roller[kind], (0.0, T_FINAL), q0, qd0, rtol=1e-11, atol=1e-12, **options)
    assert traj.success, traj.message
    route = "IDAS" if options.get("dae") == "idas" else options["method"]
    assert np.max(np.abs(_final(traj) - _reference(T_FINAL)[1])) < SIM_TOL[route]


def test_lagrange_run_is_the_yardstick_of_every_route(scene, roller):
    """The brief's yardstick: every formulation and form against the Lagrange DAE run at
    rtol 1e-11 (which itself matches the Kane reference above)."""
    q0, qd0 = _initial(scene)
    runs = {kind: simulate(roller[kind], (0.0, T_FINAL), q0, qd0, rtol=1e-11, atol=1e-12) for kind in KINDS}
    base = _final(runs["lagrange"])
    for kind, traj in runs.items():
        assert traj.success, kind
        assert np.max(np.abs(_final(traj) - base)) < SIM_TOL["DOP853"], kind


def _has_compiler():
    from nhgait.dynamics.numerics.compiler import compiler_command
    return compiler_command() is not None


@pytest.mark.parametrize("kind", KINDS)
def test_compiled_route(scene, roller, kind):
    """The compiled C route when a compiler is present; otherwise the scipy fallback (noted)."""
    q0, qd0 = _initial(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        traj = simulate(roller[kind], (0.0, T_FINAL), q0, qd0, method="compiled", rtol=1e-11, atol=1e-12)
    assert traj.success, traj.message
    if _has_compiler():
        assert traj.method == "compiled DOP853"
        assert "fallback" not in traj.settings
    else:
        assert traj.method == "DOP853"
        assert "no usable C compiler" in traj.settings["fallback"]
    assert np.max(np.abs(_final(traj) - _reference(T_FINAL)[1])) < SIM_TOL["compiled"]


def test_compiled_route_falls_back_without_a_compiler(scene, roller, monkeypatch):
    monkeypatch.setenv("NHGAIT_CC", "/nonexistent/bin/cc")
    q0, qd0 = _initial(scene)
    with pytest.warns(UserWarning, match="no usable C compiler"):
        traj = simulate(roller["reduced-explicit"], (0.0, T_FINAL), q0, qd0, method="compiled",
                        rtol=1e-11, atol=1e-12)
    assert traj.success, traj.message
    assert traj.method == "DOP853"
    assert np.max(np.abs(_final(traj) - _reference(T_FINAL)[1])) < SIM_TOL["DOP853"]


@pytest.mark.parametrize("kind", ["reduced-explicit", "reduced-implicit"])
def test_reduced_run_keeps_the_constraint_and_the_energy_balance(scene, roller, kind):
    """On the reduced run: ω(q)q̇ (the Kane model's side-slip velocities) at round-off, and
    E(t) − E(0) = ∫₀ᵗ τ·q̇ dt with E the Kane model's kinetic energy and the power of the
    scene's force integrated by cumulative Simpson on 12001 samples (h = 5e-4 s).

    Tolerances: the residual is 0 by construction (q̇ = X(q)v lies in the constraint
    distribution), so only round-off remains (entries of ω and q̇ ≤ 1, 4 terms): 1e-14.
    Energy: Simpson's error is ≤ T h⁴ max|P⁗| / 180 = 6 · 6.25e-14 · 4.3e4 / 180 ≈ 9e-11 J
    (max|P⁗| ≈ 4.3e4 W/s⁴ measured by finite differences on this run; halving h from 1e-3 s
    shrinks the imbalance 16-fold, as h⁴ predicts); the run's own error (rtol 1e-11 on
    E ≈ 2e-2 J) is ≲ 1e-12 J: 1e-10 J, against a work of 1.3e-2 J."""
    q0, qd0 = _initial(scene)
    t = np.linspace(0.0, T_FINAL, 12001)
    traj = simulate(roller[kind], (0.0, T_FINAL), q0, qd0, t_eval=t, rtol=1e-11, atol=1e-12)
    assert traj.success, traj.message
    k = _kane()
    residual = np.asarray(k["residual"](traj.q.T, traj.qdot.T), float)
    assert np.max(np.abs(residual)) < 1e-14
    energy = np.asarray(k["energy"](traj.q.T, traj.qdot.T), float)
    power = _hinge_torque(t, traj.q[:, 3], traj.qdot[:, 3]) * traj.qdot[:, 3]
    work = cumulative_simpson(power, x=t, initial=0.0)
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-10
    assert np.max(np.abs(work)) > 1e-2                     # the input does work


# ------------------------------------------------------------------------------------------
# other expressions of t on a small system (the unicycle)
# ------------------------------------------------------------------------------------------
UNICYCLE = {"m": 0.5, "r": 0.1, "J_phi": 0.2, "J_theta": 0.3, "omega": 1.3}
#: τ_θ(t, θ, φ, ...), τ_φ(t, ...) as expressions and as numpy functions (the reference)
CASES = {
    "t**2 and exp(-t)": (("t**2/10 - 0.2*theta_dot", "exp(-t)"),
                         (lambda t, th, thd, ph, phd: t * t / 10 - 0.2 * thd,
                          lambda t, th, thd, ph, phd: np.exp(-t))),
    "sin(3*t + phi)": (("0.5*sin(3*t + phi)", "0.2*cos(2.5*t) - 0.1*phi_dot"),
                       (lambda t, th, thd, ph, phd: 0.5 * np.sin(3 * t + ph),
                        lambda t, th, thd, ph, phd: 0.2 * np.cos(2.5 * t) - 0.1 * phd)),
    "two frequencies, sqrt, a parameter": (("0.3*sin(t) + 0.2*sin(2.5*t)", "sqrt(1 + t)*sin(omega*t)/5"),
                                           (lambda t, th, thd, ph, phd: 0.3 * np.sin(t)
                                            + 0.2 * np.sin(2.5 * t),
                                            lambda t, th, thd, ph, phd: np.sqrt(1 + t) * np.sin(1.3 * t)
                                            / 5)),
    "t inside a coordinate's function": (("0.4*sin(t*phi)", "exp(-t*phi_dot)/4"),
                                         (lambda t, th, thd, ph, phd: 0.4 * np.sin(t * ph),
                                          lambda t, th, thd, ph, phd: np.exp(-t * phd) / 4)),
    "an input times a time factor": (("u*cos(0.5*t) - 0.1*theta_dot", "0.05*t*exp(-t/2)"),
                                     (lambda t, th, thd, ph, phd: U * np.cos(0.5 * t) - 0.1 * thd,
                                      lambda t, th, thd, ph, phd: 0.05 * t * np.exp(-t / 2))),
}
U = 0.7                      # the constant value of the input u (an open-loop law)


def _unicycle(forces):
    return System(coordinates=["x", "y", "theta", "phi"],
                  lagrangian="m*(x_dot**2 + y_dot**2)/2 + J_theta*theta_dot**2/2 + J_phi*phi_dot**2/2",
                  constraints=["x_dot - r*cos(theta)*phi_dot", "y_dot - r*sin(theta)*phi_dot"],
                  forces={"theta": forces[0], "phi": forces[1]}, parameters=UNICYCLE)


def _unicycle_reference(funcs, q0, qd0, T):
    """θ̈ = τ_θ/J_θ, φ̈ = τ_φ/(J_φ + m r²), ẋ = r cos θ φ̇, ẏ = r sin θ φ̇ (DOP853, rtol 1e-12)."""
    m, r, Jp, Jt = (UNICYCLE[k] for k in ("m", "r", "J_phi", "J_theta"))
    f_th, f_ph = funcs

    def f(t, s):
        x, y, th, ph, thd, phd = s
        return [r * np.cos(th) * phd, r * np.sin(th) * phd, thd, phd,
                f_th(t, th, thd, ph, phd) / Jt, f_ph(t, th, thd, ph, phd) / (Jp + m * r * r)]
    sol = solve_ivp(f, (0.0, T), [*q0, qd0[2], qd0[3]], method="DOP853", rtol=1e-12, atol=1e-13)
    x, y, th, ph, thd, phd = sol.y[:, -1]
    return np.array([x, y, th, ph, r * np.cos(th) * phd, r * np.sin(th) * phd, thd, phd])


@pytest.mark.parametrize("case", sorted(CASES))
def test_time_expressions_on_the_unicycle(case):
    """Every formulation and both reduced forms derive and simulate (DOP853 and CVODES) to the
    reference's (q, q̇)(4 s) within SIM_TOL."""
    exprs, funcs = CASES[case]
    system = _unicycle(exprs)
    q0 = np.array([0.0, 0.0, 0.2, 0.1])
    qd0 = consistent_velocities(system, q0, {"theta": 0.5, "phi": 1.0})
    ref = _unicycle_reference(funcs, q0, qd0, 4.0)
    models = {"lagrange": derive(system, "lagrange"), "hamilton": derive(system, "hamilton"),
              "reduced-explicit": derive_reduced(system, form="explicit"),
              "reduced-implicit": derive_reduced(system, form="implicit")}
    assert models["reduced-explicit"].form == "explicit"
    controller = OpenLoop([0.0, 4.0], [[U]], inputs=("u",)) if system.inputs else None
    for kind, model in models.items():
        for method in ("DOP853", "CVODES"):
            traj = simulate(model, (0.0, 4.0), q0, qd0, method=method, rtol=1e-11, atol=1e-12,
                            controller=controller)
            assert traj.success, (kind, method, traj.message)
            assert np.max(np.abs(_final(traj) - ref)) < SIM_TOL[method], (kind, method)


def test_time_expression_compiled_on_the_unicycle():
    exprs, funcs = CASES["sin(3*t + phi)"]
    system = _unicycle(exprs)
    q0 = np.array([0.0, 0.0, 0.2, 0.1])
    qd0 = consistent_velocities(system, q0, {"theta": 0.5, "phi": 1.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        traj = simulate(derive(system), (0.0, 4.0), q0, qd0, method="compiled", rtol=1e-11, atol=1e-12)
    assert traj.success, traj.message
    assert traj.method == ("compiled DOP853" if _has_compiler() else "DOP853")
    assert np.max(np.abs(_final(traj) - _unicycle_reference(funcs, q0, qd0, 4.0))) < SIM_TOL["compiled"]


# ------------------------------------------------------------------------------------------
# specialisation
# ------------------------------------------------------------------------------------------
def test_specialised_velocity_coordinates_keep_t(roller):
    """specialise(explicit, velocities=(forward_velocity, phi_dot)) takes the symbolic route and
    its ż = (q̇, ẏ) equals the Kane model's: ẏ = d/dt (Y(q) q̇) = Ẏ q̇ + Y q̈ (relative 1e-9)."""
    from nhgait.dynamics.numerics.specialisation import specialise
    fast = specialise(roller["reduced-explicit"], velocities=("forward_velocity", "phi_dot"), use_cache=False)
    assert fast.route == "symbolic"
    qddot = _kane()["qddot"]
    for t, q, qd in _random_states(12, seed=14):
        y = np.array([np.cos(q[2]) * qd[0] + np.sin(q[2]) * qd[1], qd[3]])
        qdd = qddot(t, q, qd)
        s, c, w = np.sin(q[2]), np.cos(q[2]), qd[2]
        ydot = np.array([-s * w * qd[0] + c * w * qd[1] + c * qdd[0] + s * qdd[1], qdd[3]])
        ref = np.concatenate([qd, ydot])
        got = np.asarray(fast.numeric["rhs"](t, np.concatenate([q, y]), [], [])).ravel()
        assert np.max(np.abs(got - ref)) <= 1e-9 * max(1.0, np.max(np.abs(ref)))


def test_specialised_momentum_coordinates_keep_t(roller):
    """specialise(explicit) (momentum coordinates) is symbolic and equals the unbound model's
    ż at 4 times, which was checked against Kane above (relative 1e-10)."""
    from nhgait.dynamics.numerics.specialisation import specialise
    model = roller["reduced-explicit"]
    fast = specialise(model, use_cache=False)
    assert fast.route == "symbolic"
    pv = model.numeric.params()
    for t, q, qd in _random_states(8, seed=15):
        z = to_state(model, q, qd)
        ref = np.asarray(model.numeric.call("rhs", t, z, [], pv), float)
        got = np.asarray(fast.numeric["rhs"](t, z, [], [])).ravel()
        assert np.max(np.abs(got - ref) / (1 + np.abs(ref))) <= 1e-10


def test_agreement_check_samples_time(roller):
    """The specialisation's check rejects a candidate that evaluates the forces at one fixed t."""
    import casadi as ca

    from nhgait.dynamics.numerics.specialisation import _agrees, _numeric_bound, _Reference
    model = roller["reduced-explicit"]
    pv = model.numeric.params()
    ref = _numeric_bound(model, pv)
    t, z, u, p = ca.SX.sym("t"), ca.SX.sym("z", 6), ca.SX.sym("u", 0), ca.SX.sym("params", len(pv))
    frozen = dict(ref, rhs=ca.Function("rhs", [t, z, u, p], [ref["rhs"](0.3, z, u, p)]))
    assert _agrees(ref, _Reference(ref, 6, 0, pv), 1e-10)
    assert not _agrees(frozen, _Reference(ref, 6, 0, pv), 1e-10)


# ------------------------------------------------------------------------------------------
# command line
# ------------------------------------------------------------------------------------------
def test_cli_derive_and_simulate_the_example(tmp_path, capsys):
    from nhgait.gaits.cli.main import main
    assert main(["derive", str(SCENE), "--formulation", "all"]) == 0
    out = capsys.readouterr().out
    assert "6 = 2n − k first-order ODEs" in out
    assert "0.6*sin(2.5*t)" in out
    csv_path = tmp_path / "roller_racer.csv"
    assert main(["simulate", str(SCENE), "--method", "compiled", "--out", str(csv_path)]) == 0
    data = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    assert data.shape == (501, 5)
    # the scene runs to t = 10 s at rtol 1e-10, atol 1e-12 (100× looser than the reference;
    # measured 3e-13 apart): 1e-9
    np.testing.assert_allclose(data[-1, 1:], _reference(10.0)[1][:4], rtol=0, atol=1e-9)
