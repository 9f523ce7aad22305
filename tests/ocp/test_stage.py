"""The exact derivatives of the shooting stage (ocp/stage.py) and of the NLP assembled from
them (ocp/derivatives.py, ocp/transcription.py), each against an independent reference.

Independent references
----------------------
* **RK4 written out here** in unscaled time (t_k = k h, sub-step δ = h/M, the classical
  k1…k4 formulas, no Butcher tuples, no scaled time) in CasADi SX, and differentiated by
  CasADi (``ca.jacobian``, ``ca.hessian``). The stage under test integrates in scaled time
  with a tableau and assembles J and ∇²(λᵀF) by forward sensitivities and second-order
  adjoints: only the arithmetic of RK4 is shared.
* **Closed form of RK4 on a linear ODE** ż = Az + Bu: one sub-step is
  z⁺ = P(δA) z + δ Q(δA) B u with P(X) = Σ_{n≤4} Xⁿ/n! and Q(X) = Σ_{n≤3} Xⁿ/(n+1)!
  (the degree-4 Taylor polynomial of the exact propagator). All matrices are polynomials in
  A, so they commute, and the δ-derivatives (hence the T-derivatives of a free horizon) are
  closed forms too.
* **Central finite differences** of the stage step (Jacobian) and of λᵀJ (Hessian).
* **CasADi's own AD of the whole NLP graph**: ``ca.jacobian(nlp.g, nlp.w)`` and
  ``ca.hessian(λ_f f + λᵀg, w)``, and Ipopt through plain ``nlpsol`` on (w, f, g) without the
  ``cache`` option.
* **scipy ``solve_ivp``** (DOP853) of the test's own numpy right-hand side with absolute time t.

Tolerances
----------
Every comparison is max-norm relative: max|a − b| ≤ rel · max(1, max|b|). The stage and the
references compute the same real numbers through different roundings of O(10³) operations on
O(1) values, so they agree to ~1e-16 (measured ≤ 3e-16, stage and NLP); 1e-10 (stage) and
1e-9 (NLP, whose Hessian sums up to N + 1 stage blocks and the boundary rows) leave six orders
of margin for rounding and none for a wrong term (a dropped or misplaced term is O(1e-2) or
larger at these points; the tests assert that the curvature they check is at least 1e-2).
The closed form is evaluated in numpy in another order: 1e-12. Finite differences: central
differences with step δ = 1e-5 have truncation error c δ² (c = |φ'''| / 6) and rounding error
≈ ε|φ|/δ ≈ 2e-11 |φ|; the test bounds its own truncation error through D(10δ) − D(δ) ≈ 99 c δ²
(asserted ≤ 1e-9, measured 2.6e-11), so 1e-8 is safe. Optima: the two Ipopt runs see the same
functions up to rounding, so their iterates agree to ~1e-12: objectives to 1e-8 (relative),
decision vectors to 1e-6, the same iteration count. RK4 with 80 sub-steps on T ≈ 3–4 differs
from DOP853 (rtol 1e-11) by O(δ⁴) (measured 3e-8 and 6e-8): tolerance 1e-6, the planner's own.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np
import pytest

from nhgait.dynamics.numerics.numeric_model import NumericModel
from nhgait.ocp import InitialGuess, OCPSolver, OptimalControlProblem, Quantity, SolverOptions
from nhgait.ocp.derivatives import nlp_functions
from nhgait.ocp.stage import stage_functions
from nhgait.ocp.transcription import Collocation, MultipleShooting, StageShooting

#: the friction-like coefficient c of the test ODE (its one parameter)
C = 0.3
STATES = ("x", "y", "theta", "v", "w")
INPUTS = ("a", "omega")


# ------------------------------------------------------------------------------------------
# the test's own ODE, RK4 and model
# ------------------------------------------------------------------------------------------
def _rhs(t, z, u, timed, lib=ca, c=C):
    """A unicycle-like ODE, 5 states (x, y, θ, v, w), 2 inputs (a, ω), trig and bilinear
    terms in states and inputs; ``timed`` adds the force 0.6 sin(2.5 t) cos θ on ẇ."""
    x, y, th, v, w = (z[i] for i in range(5))
    a, om = u[0], u[1]
    out = [v * lib.cos(th), v * lib.sin(th), w,
           a + 0.2 * a * om * lib.cos(th) - c * v * w * lib.sin(th),
           om - 0.5 * lib.sin(x) * v + (0.6 * lib.sin(2.5 * t) * lib.cos(th) if timed else 0.0)]
    return ca.vertcat(*out) if lib is ca else np.array(out, dtype=float)


def _ode(timed) -> ca.Function:
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", 5), ca.SX.sym("u", 2)
    return ca.Function("ode", [t, z, u], [_rhs(t, z, u, timed)])


def _rk4(f, z, u, T, N, k, M):
    """M classical RK4 steps of ż = f(t, z, u) over [k h, (k + 1) h], h = T / N."""
    h = T / N
    d = h / M
    for i in range(M):
        t = k * h + i * d
        k1 = f(t, z, u)
        k2 = f(t + d / 2, z + d / 2 * k1, u)
        k3 = f(t + d / 2, z + d / 2 * k2, u)
        k4 = f(t + d, z + d * k3, u)
        z = z + d / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return z


def _reference_stage(f, nz, nu, N, k, M, free) -> ca.Function:
    """(z, u, T, λ) -> (F, ∂F/∂x, ∇²_x λᵀF) of the test's RK4, by CasADi AD."""
    z, u, T, lam = ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("T"), ca.SX.sym("lam", nz)
    F = _rk4(f, z, u, T, N, k, M)
    x = ca.vertcat(z, u, T) if free else ca.vertcat(z, u)
    return ca.Function("reference", [z, u, T, lam], [F, ca.jacobian(F, x), ca.hessian(ca.dot(lam, F), x)[0]])


@dataclass(frozen=True, eq=False)
class _Model:
    """The smallest model an OptimalControlProblem accepts: ``numeric`` and ``state_names``
    (inputs from ``numeric.input_names``, coordinates the first ``n_coordinates`` states)."""

    numeric: NumericModel
    state_names: tuple


def _model(timed: bool) -> _Model:
    t, z, u, params = ca.SX.sym("t"), ca.SX.sym("z", 5), ca.SX.sym("u", 2), ca.SX.sym("params", 1)
    rhs = _rhs(t, z, u, timed, ca, params[0])           # c enters as the model's parameter
    functions = {"rhs": ca.Function("rhs", [t, z, u, params], [rhs]),
                 "qdot": ca.Function("qdot", [z, params], [rhs[:3]])}
    numeric = NumericModel("reduced", STATES, INPUTS, ("c",), (C,), functions, n_coordinates=3)
    return _Model(numeric, STATES)


#: a derived quantity with curvature in three states (rows of g: final, periodic)
ENERGY = {"energy": Quantity("energy", lambda z, params: z[3] ** 2 + 0.5 * z[4] ** 2 * ca.cos(z[2]))}


def _energy(z):
    return z[3] ** 2 + 0.5 * z[4] ** 2 * np.cos(z[2])


def _rich_problem(model, N, free):
    """Every kind of row of g: dynamics, initial/final conditions on derived quantities
    (x_dot, y_dot, energy), periodic derived quantity and state (energy, w; θ is fixed at the
    start, so its periodicity is a bound), a path bound on a derived quantity; weights on
    states and inputs; a time weight when the horizon is free."""
    return OptimalControlProblem(
        model, 2.0, N, initial={"x": 0.0, "y": 0.0, "theta": 0.0, "v": 0.0, "x_dot": 0.0},
        final={"x": 1.0, "y_dot": (-0.1, 0.1), "energy": 0.2}, periodic=("theta", "energy", "w"),
        state_bounds={"forward_velocity": (-2.0, 2.0), "v": (-3.0, 3.0)}, control_bounds=4.0,
        control_weights={"a": 2.0}, state_weights={"w": 0.5, "theta": 0.1}, quantities=ENERGY,
        free_horizon=(1.0, 4.0) if free else None, time_weight=0.3 if free else 0.0)


def _park(model, N=10, free=False):
    """Drive from rest at the origin to rest at (1, 0.5), heading 0."""
    return OptimalControlProblem(model, 3.0, N, initial={n: 0.0 for n in STATES},
                                 final={"x": 1.0, "y": 0.5, "theta": 0.0, "v": 0.0, "w": 0.0},
                                 control_bounds=3.0, free_horizon=(1.5, 6.0) if free else None,
                                 time_weight=0.2 if free else 0.0)


def _park_guess(N):
    s = np.linspace(0.0, 1.0, N + 1)
    states = np.zeros((5, N + 1))
    states[0], states[1] = s, 0.5 * s
    return InitialGuess(states, np.zeros((2, N)), label="straight line")


def _phase(N, t0=0.0):
    """The stage's ``phase`` argument (ν, t0) of a problem of N intervals starting at t0."""
    return [1.0 / N, t0]


def _vec(x) -> np.ndarray:
    """A casadi DM (or array) as a flat float array."""
    return np.asarray(x, dtype=float).ravel()


def _assert_close(actual, expected, rel, what=""):
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    assert actual.shape == expected.shape, (what, actual.shape, expected.shape)
    err = float(np.max(np.abs(actual - expected), initial=0.0))
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    assert err <= rel * scale, f"{what}: max error {err:.3e} > {rel:g} × {scale:.3g}"


# ------------------------------------------------------------------------------------------
# 1. the stage functions
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("steps", [1, 4])
@pytest.mark.parametrize("free", [False, True], ids=["fixed-T", "free-T"])
@pytest.mark.parametrize("timed", [False, True], ids=["autonomous", "sin(2.5t)"])
@pytest.mark.parametrize("mode", ["inline", "structured"])
def test_stage_matches_rk4_differentiated_by_casadi(mode, timed, free, steps):
    """step, jacobian (F, ∂F/∂x) and hessian ∇²_x λᵀF at random points of three intervals k
    equal the test's RK4 in unscaled time, differentiated by CasADi (relative 1e-10)."""
    N = 7
    f = _ode(timed)
    stage = stage_functions(f, N, steps=steps, free_horizon=free, mode=mode)
    assert stage.mode == mode
    assert stage.n_variables == 7 + free
    if mode == "structured":       # the value function evaluates g only, no Jacobian (issue 25)
        assert stage.step.get_function() == ["g"]
    rng = np.random.default_rng(1000 * steps + 10 * timed + free)
    for k in (0, 3, N - 1):
        ref = _reference_stage(f, 5, 2, N, k, steps, free)
        for _ in range(2):
            z, u = rng.uniform(-2, 2, 5), rng.uniform(-2, 2, 2)
            T, lam = rng.uniform(1.5, 3.5), rng.uniform(-1, 1, 5)
            F0, J0, H0 = (np.array(a) for a in ref(z, u, T, lam))
            assert np.max(np.abs(H0)) > 1e-2            # the curvature checked is not negligible
            _assert_close(stage.step(z, u, T, k, _phase(N)), F0, 1e-10, "step")
            F, J = stage.jacobian(z, u, T, k, _phase(N))
            _assert_close(F, F0, 1e-10, "jacobian's F")
            _assert_close(J, J0, 1e-10, "J")
            _assert_close(stage.hessian(z, u, T, k, _phase(N), lam), H0, 1e-10, "H")


def _linear_rk4_closed_form(A, B, z, u, T, N, M):
    """F, ∂F/∂z, ∂F/∂u, ∂F/∂T, ∂²F/∂T² and ∂²F/∂T∂(z, u) of M RK4 sub-steps of ż = Az + Bu
    (the module docstring: polynomials in δA that commute; δ = T/(N M))."""
    n = A.shape[0]
    d = T / (N * M)
    X, I = d * A, np.eye(n)
    mp = np.linalg.matrix_power
    P = I + X + X @ X / 2 + mp(X, 3) / 6 + mp(X, 4) / 24
    P3 = I + X + X @ X / 2 + mp(X, 3) / 6                  # dP/dδ = A P3
    P2 = I + X + X @ X / 2                                  # d²P/dδ² = A² P2
    Q = d * (I + X / 2 + X @ X / 6 + mp(X, 3) / 24)         # dQ/dδ = P3, d²Q/dδ² = A P2
    dP, ddP, dQ, ddQ = A @ P3, A @ A @ P2, P3, A @ P2

    def power(i):            # (P^i, d P^i/dδ, d² P^i/dδ²) for commuting P, dP, ddP
        if i == 0:
            return I, 0 * I, 0 * I
        d1 = i * mp(P, i - 1) @ dP
        d2 = i * mp(P, i - 1) @ ddP + (i * (i - 1) * mp(P, i - 2) @ dP @ dP if i > 1 else 0 * I)
        return mp(P, i), d1, d2

    PM, dPM, ddPM = power(M)
    S, dS, ddS = (sum(power(i)[j] for i in range(M)) for j in range(3))   # Σ_{i<M} P^i
    G, dG, ddG = S @ Q, dS @ Q + S @ dQ, ddS @ Q + 2 * dS @ dQ + S @ ddQ  # F = P^M z + G B u
    F = PM @ z + G @ B @ u
    dT = 1.0 / (N * M)
    dF_dT = (dPM @ z + dG @ B @ u) * dT
    d2F_dT2 = (ddPM @ z + ddG @ B @ u) * dT ** 2
    return F, PM, G @ B, dF_dT, d2F_dT2, dPM * dT, dG @ B * dT


@pytest.mark.parametrize("free", [False, True], ids=["fixed-T", "free-T"])
@pytest.mark.parametrize("steps", [1, 4])
@pytest.mark.parametrize("mode", ["inline", "structured"])
def test_stage_of_a_linear_ode_is_the_taylor_polynomial_of_the_propagator(mode, steps, free):
    """ż = Az + Bu: F, J and (free horizon) the T-rows of the Hessian equal the closed form
    of RK4 (degree-4 Taylor polynomial of e^{δA}) to 1e-12; with a fixed horizon the Hessian
    of a linear map is zero."""
    A = np.array([[0.0, 1.0, 0.0], [-4.0, -0.3, 0.5], [0.2, 0.0, -1.0]])
    B = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, -2.0]])
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", 3), ca.SX.sym("u", 2)
    f = ca.Function("linear", [t, z, u], [ca.mtimes(ca.DM(A), z) + ca.mtimes(ca.DM(B), u)])
    N, T = 5, 2.5
    stage = stage_functions(f, N, steps=steps, free_horizon=free, mode=mode)
    rng = np.random.default_rng(7)
    z0, u0, lam = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 2), rng.uniform(-1, 1, 3)
    F, Jz, Ju, dF, d2F, dJz, dJu = _linear_rk4_closed_form(A, B, z0, u0, T, N, steps)
    _assert_close(_vec(stage.step(z0, u0, T, 2, _phase(N))), F, 1e-12, "step")
    J = np.array(stage.jacobian(z0, u0, T, 2, _phase(N))[1])
    expected = np.hstack([Jz, Ju] + ([dF[:, None]] if free else []))
    _assert_close(J, expected, 1e-12, "J")
    H = np.array(stage.hessian(z0, u0, T, 2, _phase(N), lam))
    if not free:
        assert np.max(np.abs(H)) <= 1e-14
        return
    # ∇² λᵀF: zero in the (z, u) block; T-row λᵀ ∂²F/∂T∂(z, u) and corner λᵀ ∂²F/∂T²
    _assert_close(H[:5, :5], np.zeros((5, 5)), 1e-12, "H_(z,u)")
    _assert_close(H[5, :5], np.concatenate([lam @ dJz, lam @ dJu]), 1e-12, "H_T,(z,u)")
    _assert_close(H[:5, 5], H[5, :5], 1e-14, "symmetry")
    _assert_close(H[5, 5], lam @ d2F, 1e-12, "H_TT")
    # and the closed form is RK4 of the exact propagator: O(δ⁴) from e^{TA/N}
    from scipy.linalg import expm
    d = T / (N * steps)
    exact = expm(T / N * A) @ z0 + np.linalg.solve(A, (expm(T / N * A) - np.eye(3)) @ B @ u0)
    assert np.max(np.abs(F - exact)) <= 10 * steps * d ** 5 * np.linalg.norm(A, 2) ** 5


@pytest.mark.parametrize("mode", ["inline", "structured"])
def test_stage_derivatives_match_central_differences(mode):
    """∂F/∂x by central differences of ``step``, ∇²λᵀF by central differences of λᵀJ, for the
    time-dependent ODE with a free horizon (the T-column carries ∂t/∂T = τ/N): tolerance 1e-8
    (module docstring: δ = 1e-5, the differences' own error bounded here by 1e-9)."""
    N, k, delta = 6, 4, 1e-5
    stage = stage_functions(_ode(True), N, steps=2, free_horizon=True, mode=mode)
    rng = np.random.default_rng(11)
    x0 = np.concatenate([rng.uniform(-1.5, 1.5, 7), [2.2]])
    lam = rng.uniform(-1, 1, 5)

    def step(x):
        return _vec(stage.step(x[:5], x[5:7], x[7], k, _phase(N)))

    def grad(x):                                          # λᵀJ
        return lam @ np.array(stage.jacobian(x[:5], x[5:7], x[7], k, _phase(N))[1])

    def central(fun, d):
        return np.column_stack([(fun(x0 + e) - fun(x0 - e)) / (2 * d) for e in np.eye(8) * d])

    J_fd, H_fd = central(step, delta), central(grad, delta)
    # the reference's own error: truncation c δ² (c = |φ'''| / 6), so D(10δ) − D(δ) ≈ 99 c δ²
    for fun, D in ((step, J_fd), (grad, H_fd)):
        assert np.max(np.abs(central(fun, 10 * delta) - D)) / 99 <= 1e-9
    _assert_close(stage.jacobian(x0[:5], x0[5:7], x0[7], k, _phase(N))[1], J_fd, 1e-8, "J vs FD")
    _assert_close(stage.hessian(x0[:5], x0[5:7], x0[7], k, _phase(N), lam), H_fd, 1e-8, "H vs FD")


# ------------------------------------------------------------------------------------------
# 2. the NLP's Jacobian and Hessian assembled from the stage
# ------------------------------------------------------------------------------------------
TRANSCRIPTIONS = {
    "shooting-inline": MultipleShooting(steps=2, stage="inline"),
    "shooting-structured": MultipleShooting(steps=2, stage="structured"),
    "stages-inline": StageShooting(steps=2, stage="inline"),
    "stages-structured": StageShooting(steps=3, stage="structured"),
}


@pytest.fixture(scope="module")
def timed_model():
    return _model(True)


def _reference_nlp(nlp) -> ca.Function:
    """(w, λ_f, λ) -> (g, ∂g/∂w, ∇²L, ∇L) of L = λ_f f + λᵀg by CasADi AD of the NLP graph."""
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", nlp.g.shape[0])
    L = lam_f * nlp.f + ca.dot(lam_g, nlp.g)
    H, grad = ca.hessian(L, nlp.w)
    return ca.Function("reference", [nlp.w, lam_f, lam_g], [nlp.g, ca.jacobian(nlp.g, nlp.w), H, grad])


@pytest.mark.parametrize("N", [1, 4])
@pytest.mark.parametrize("free", [False, True], ids=["fixed-T", "free-T"])
@pytest.mark.parametrize("name", list(TRANSCRIPTIONS))
def test_assembled_jacobian_and_hessian_equal_casadi_ad(timed_model, name, free, N):
    """Ipopt form: nlp_jac_g = (g, ∂g/∂w) and nlp_hess_l = triu ∇²(λ_f f + λᵀg) (upper
    triangular sparsity); FATROP form: (∇L, full symmetric ∇²L) — all equal to CasADi's AD of
    the NLP graph at random (w, λ), relative 1e-9. The dynamics rows equal the test's own RK4
    (absolute t_k = k T/N) at a packed point."""
    problem = _rich_problem(timed_model, N, free)
    nlp = TRANSCRIPTIONS[name].build(problem)
    labels = set(nlp.row_labels)
    assert {"dynamics", "initial.x_dot", "final.y_dot", "final.energy", "periodic.energy",
            "periodic.w", "bounds.forward_velocity"} == labels
    ref = _reference_nlp(nlp)
    ipopt = nlp_functions(nlp, hessian="exact", solver="ipopt")
    fatrop = nlp_functions(nlp, hessian="exact", solver="fatrop")
    assert ipopt["nlp_hess_l"].sparsity_out(0).is_triu()
    rng = np.random.default_rng(N + 10 * free)
    for _ in range(2):
        w = rng.uniform(-1.5, 1.5, nlp.n_w)
        lam_f, lam = rng.uniform(0.5, 2.0), rng.uniform(-1, 1, nlp.g.shape[0])
        g0, J0, H0, grad0 = (np.array(a) for a in ref(w, lam_f, lam))
        g, J = ipopt["nlp_jac_g"](w, [])
        _assert_close(g, g0, 1e-9, "g")
        _assert_close(J, J0, 1e-9, "∂g/∂w")
        _assert_close(ipopt["nlp_hess_l"](w, [], lam_f, lam), np.triu(H0), 1e-9, "triu ∇²L")
        grad, H = fatrop["nlp_hess_l"](w, [], lam_f, lam)
        _assert_close(grad, grad0, 1e-9, "∇L (FATROP)")
        _assert_close(H, H0, 1e-9, "∇²L (FATROP)")
        _assert_close(H, np.array(H).T, 1e-14, "symmetry")    # to rounding (L_ijᵀ H L_ij)
    # dynamics rows at a packed point against the test's RK4
    states, controls = rng.uniform(-1, 1, (5, N + 1)), rng.uniform(-1, 1, (2, N))
    T = 2.7 if free else 2.0
    w = nlp.pack(states, controls, T)
    g = _vec(ca.Function("g", [nlp.w], [nlp.g])(w))
    dyn = g[np.array(nlp.row_labels) == "dynamics"].reshape((N, -1)).T    # column k: interval k
    rk4 = np.column_stack([_vec(_rk4(lambda t, z, u: _rhs(t, z, u, True, np), states[:, k], controls[:, k],
                                         T, N, k, TRANSCRIPTIONS[name].steps)) for k in range(N)])
    sign = -1.0 if isinstance(nlp.transcription, StageShooting) else 1.0  # x̃_{k+1} − F vs F − z_{k+1}
    _assert_close(dyn[:5], sign * (rk4 - states[:, 1:]), 1e-12, "dynamics rows")
    _assert_close(dyn[5:], np.zeros_like(dyn[5:]), 0.0, "carried copies")


@pytest.mark.parametrize("name", list(TRANSCRIPTIONS))
def test_gauss_newton_drops_exactly_the_stage_curvature(timed_model, name):
    """hessian="gauss-newton" = ∇²(λ_f f + λᵀ g_linear): every row of g but the dynamics is
    kept and the dynamics rows are F minus a linear term, so it equals CasADi's Hessian of
    λ_f f + λ'ᵀg with λ' = λ with the dynamics multipliers zeroed; exact − Gauss–Newton is
    the Hessian of λ_dynᵀ g. FATROP's gradient stays exact."""
    nlp = TRANSCRIPTIONS[name].build(_rich_problem(timed_model, 4, True))
    ref = _reference_nlp(nlp)
    dynamics = np.array(nlp.row_labels) == "dynamics"
    gn = nlp_functions(nlp, hessian="gauss-newton", solver="ipopt")["nlp_hess_l"]
    gn_fatrop = nlp_functions(nlp, hessian="gauss-newton", solver="fatrop")["nlp_hess_l"]
    exact = nlp_functions(nlp, hessian="exact", solver="ipopt")["nlp_hess_l"]
    rng = np.random.default_rng(5)
    w, lam_f, lam = rng.uniform(-1.5, 1.5, nlp.n_w), 1.3, rng.uniform(-1, 1, nlp.g.shape[0])
    H_rest = np.array(ref(w, lam_f, np.where(dynamics, 0.0, lam))[2])
    H_dyn = np.array(ref(w, 0.0, np.where(dynamics, lam, 0.0))[2])
    assert np.max(np.abs(H_dyn)) > 1e-2                 # the dropped curvature is not negligible
    _assert_close(gn(w, [], lam_f, lam), np.triu(H_rest), 1e-9, "Gauss–Newton (Ipopt)")
    _assert_close(np.array(exact(w, [], lam_f, lam)) - np.array(gn(w, [], lam_f, lam)), np.triu(H_dyn), 1e-9,
                  "exact − Gauss–Newton")
    grad, H = gn_fatrop(w, [], lam_f, lam)
    _assert_close(H, H_rest, 1e-9, "Gauss–Newton (FATROP)")
    _assert_close(grad, ref(w, lam_f, lam)[3], 1e-9, "∇L (FATROP, Gauss–Newton)")


def test_collocation_has_no_stage_layout(timed_model):
    """Collocation differentiates its whole graph: no assembled functions."""
    nlp = Collocation(degree=2).build(_rich_problem(timed_model, 3, False))
    assert nlp.layout is None
    assert nlp_functions(nlp) == {}


# ------------------------------------------------------------------------------------------
# 3. solves
# ------------------------------------------------------------------------------------------
def _plain_ipopt(nlp, guess):
    """Ipopt through nlpsol on (w, f, g): CasADi's own derivatives, no cache."""
    solver = ca.nlpsol("plain", "ipopt", {"x": nlp.w, "f": nlp.f, "g": nlp.g},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.tol": 1e-8})
    w0 = np.clip(nlp.pack(guess.states, guess.controls, guess.horizon), nlp.lbx, nlp.ubx)
    out = solver(x0=w0, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
    stats = solver.stats()
    assert stats["success"], stats["return_status"]
    return float(out["f"]), int(stats["iter_count"]), _vec(out["x"])


@pytest.mark.parametrize("free", [False, True], ids=["fixed-T", "free-T"])
@pytest.mark.parametrize("name", ["default", "shooting-structured", "stages-inline"])
def test_assembled_derivatives_solve_like_casadi_ad(timed_model, name, free):
    """OCPSolver (assembled exact derivatives through nlpsol's cache) and plain nlpsol (CasADi's
    AD) on the same NLP: same optimum (objective 1e-8, decision vector 1e-6) in the same
    number of Ipopt iterations."""
    problem = _park(timed_model, free=free)
    guess = _park_guess(problem.intervals)
    transcription = None if name == "default" else TRANSCRIPTIONS[name]
    solver = OCPSolver(problem, transcription, SolverOptions(jit=False))
    assert solver.functions  # the assembled functions are used
    assert not solver.compiled
    sol = solver.solve(guess)
    assert sol.success, sol.message
    f_ref, iterations, w_ref = _plain_ipopt(solver.nlp, guess)
    assert sol.objective == pytest.approx(f_ref, rel=1e-8)
    assert sol.iterations == iterations
    Z, U, T = solver.nlp.unpack(w_ref)
    _assert_close(sol.z.T, Z, 1e-6, "states")                   # Z, U: the NLP layout (nz × (N+1), nu × N)
    _assert_close(sol.u.T, U, 1e-6, "controls")
    assert sol.horizon == pytest.approx(T, rel=1e-8)


def test_inline_structured_gauss_newton_and_fatrop_reach_the_same_optimum(timed_model):
    """The two stage realisations, the Gauss–Newton Hessian and FATROP on the stage-ordered
    NLP all reach plain Ipopt's optimum of the park problem (objective 1e-8; FATROP, whose
    own termination test differs, 1e-6); Ipopt's solvers are made without CasADi's
    ``nlp_grad`` (FATROP's interface calls it)."""
    problem = _park(timed_model)
    guess = _park_guess(problem.intervals)
    f_ref = _plain_ipopt(MultipleShooting().build(problem), guess)[0]
    for transcription, options in ((MultipleShooting(stage="inline"), SolverOptions(jit=False)),
                                   (MultipleShooting(stage="structured"), SolverOptions(jit=False)),
                                   (None, SolverOptions(jit=False, hessian="gauss-newton"))):
        ocp = OCPSolver(problem, transcription, options)
        assert "nlp_grad" not in ocp.solver.get_function()    # serves only lam_p; there is no p
        sol = ocp.solve(guess)
        assert sol.success, (transcription, options.hessian)
        assert sol.objective == pytest.approx(f_ref, rel=1e-8), (transcription, options.hessian)
    fatrop = OCPSolver(problem, options=SolverOptions(jit=False, solver="fatrop")).solve(guess)
    assert fatrop.success
    assert fatrop.objective == pytest.approx(f_ref, rel=1e-6)


@pytest.mark.parametrize("free", [False, True], ids=["fixed-T", "free-T"])
def test_time_dependent_force_plans_and_verifies(timed_model, free):
    """A plan under the force 0.6 sin(2.5 t) cos θ passes Solution.verified(), and the test's
    own scipy integration with absolute t meets the nodes to 1e-6; the same integration with
    the time restarted at 0 on every interval misses them by far more (the check sees t)."""
    from scipy.integrate import solve_ivp
    problem = _park(timed_model, N=20, free=free)
    sol = OCPSolver(problem, options=SolverOptions(jit=False)).solve(_park_guess(20)).verified()
    assert sol.success, sol.message
    assert sol.verification.passed
    assert sol.verification.max_error <= 1e-6

    def resimulate(restart):
        z, out = sol.z[0], [sol.z[0]]
        for k in range(problem.intervals):
            t0, t1 = sol.t[k], sol.t[k + 1]
            shift = t0 if restart else 0.0
            run = solve_ivp(lambda t, zz, shift=shift, k=k: _rhs(t - shift, zz, sol.u[k], True, np),
                            (t0, t1), z, method="DOP853", rtol=1e-11, atol=1e-12)
            z = run.y[:, -1]
            out.append(z)
        return np.vstack(out)                                    # (N+1) × nz, like sol.z

    assert np.max(np.abs(resimulate(False) - sol.z)) <= 1e-6
    assert np.max(np.abs(resimulate(True) - sol.z)) >= 1e-3


# ------------------------------------------------------------------------------------------
# 4. which rows a point violates
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("transcription", [MultipleShooting(steps=2), StageShooting(steps=2)],
                         ids=["shooting", "stages"])
def test_violations_name_the_violated_rows(timed_model, transcription):
    """A hand-made point: nodes from the test's RK4 rollout (dynamics met to rounding) except
    one node moved by 0.01, a final x_dot, the periodic energy and w and the path bound on the
    forward velocity (= v for this model) missed by amounts computed here; initial x_dot met;
    no bounds on w. ``violations`` names exactly those rows with those amounts (relative 1e-9)."""
    N, T = 4, 2.0
    problem = OptimalControlProblem(
        timed_model, T, N, final={"x_dot": 0.5}, initial={"x_dot": 0.0}, periodic=("energy", "w"),
        state_bounds={"forward_velocity": (-0.5, 0.5)}, quantities=ENERGY)
    nlp = transcription.build(problem)
    controls = np.array([[1.5, 1.0, -0.5, 0.2], [0.4, -0.3, 0.8, 0.1]])
    states = np.zeros((5, N + 1))
    states[:, 0] = [0.0, 0.0, 0.3, 0.0, 0.2]                            # v_0 = 0: x_dot(0) = 0
    f = lambda t, z, u: _rhs(t, z, u, True, np)              # noqa: E731
    for k in range(N):
        states[:, k + 1] = _rk4(f, states[:, k], controls[:, k], T, N, k, transcription.steps)
    exact = states.copy()
    states[1, 2] += 0.01                                     # y_2 off the rollout
    w = nlp.pack(states, controls)
    g = _vec(ca.Function("g", [nlp.w], [nlp.g])(w))
    gaps = [_rk4(f, states[:, k], controls[:, k], T, N, k, transcription.steps) - states[:, k + 1]
            for k in range(N)]
    zN = states[:, N]
    expected = {
        "dynamics": np.max(np.abs(gaps)),
        "final.x_dot": abs(zN[3] * np.cos(zN[2]) - 0.5),
        "periodic.energy": abs(_energy(zN) - _energy(states[:, 0])),
        "periodic.w": abs(zN[4] - states[4, 0]),
        "bounds.forward_velocity": np.max(np.abs(states[3])) - 0.5,
    }
    assert np.max(np.abs(exact[3])) > 0.6  # all clearly violated
    assert min(expected.values()) > 1e-3
    found = nlp.violations(g, w)
    assert set(found) == set(expected)                       # initial.x_dot is met
    for label, value in expected.items():
        assert found[label] == pytest.approx(value, rel=1e-9), label
    # a tolerance above a violation drops its label
    loose = nlp.violations(g, w, tol=expected["dynamics"] * 1.01)
    assert set(loose) == {k for k, v in expected.items() if v > expected["dynamics"] * 1.01}
    assert "dynamics" not in loose


@pytest.mark.parametrize("transcription", [MultipleShooting(steps=2), StageShooting(steps=2)],
                         ids=["shooting", "stages"])
def test_violations_name_the_violated_bounds_on_w(timed_model, transcription):
    """Bounds on the decision vector are named by the condition they state: x fixed at the
    start ("initial.x"), y at the end ("final.y"), θ fixed at the start and periodic, hence
    fixed at the end by periodicity ("periodic.θ"), a path bound on v ("bounds.v"), an input
    bound ("control_bounds.a") and the free horizon ("horizon", every carried copy of T in the
    stage-ordered NLP). Each is missed by a known amount at a hand-made point; the rows of g
    are met there (the nodes are the test's RK4 rollout)."""
    N, T = 3, 5.0
    problem = OptimalControlProblem(
        timed_model, 2.0, N, initial={"x": 0.0, "theta": 0.0}, final={"y": 0.0}, periodic=("theta",),
        state_bounds={"v": (-1.0, 1.0)}, control_bounds={"a": (-1.0, 1.0)}, free_horizon=(1.0, 4.0))
    nlp = transcription.build(problem)
    controls = np.array([[1.25, 0.0, -0.5], [0.4, -0.3, 0.8]])          # a_0 above 1 by 0.25
    states = np.zeros((5, N + 1))
    states[:, 0] = [0.1, 0.0, 0.0, 0.9, 0.2]                            # x_0 = 0.1, v_0 inside
    f = lambda t, z, u: _rhs(t, z, u, True, np)              # noqa: E731
    for k in range(N):
        states[:, k + 1] = _rk4(f, states[:, k], controls[:, k], T, N, k, transcription.steps)
    w = nlp.pack(states, controls, T)
    g = _vec(ca.Function("g", [nlp.w], [nlp.g])(w))
    expected = {"initial.x": 0.1, "final.y": abs(states[1, N]), "periodic.theta": abs(states[2, N]),
                "bounds.v": np.max(np.abs(states[3])) - 1.0, "control_bounds.a": 0.25, "horizon": 1.0}
    assert min(expected.values()) > 1e-3
    found = nlp.violations(g, w)
    assert set(found) == set(expected)
    for label, value in expected.items():
        assert found[label] == pytest.approx(value, rel=1e-9), label


# ------------------------------------------------------------------------------------------
# 5. a guess where the dynamics are not finite
# ------------------------------------------------------------------------------------------
def _singular_model():
    """ṙ = 1/r + f, ṡ = r: infinite at r = 0."""
    t, z, u, params = ca.SX.sym("t"), ca.SX.sym("z", 2), ca.SX.sym("u", 1), ca.SX.sym("params", 0)
    functions = {"rhs": ca.Function("rhs", [t, z, u, params], [ca.vertcat(1 / z[0] + u[0], z[0])]),
                 "qdot": ca.Function("qdot", [z, params], [z])}
    return _Model(NumericModel("reduced", ("r", "s"), ("f",), (), (), functions, n_coordinates=2), ("r", "s"))


def _singular_case():
    problem = OptimalControlProblem(_singular_model(), 1.0, 6, initial={"r": 1.0, "s": 0.0}, final={"r": 2.0})
    states = np.vstack([np.linspace(1.0, 2.0, 7), np.zeros(7)])
    bad = states.copy()
    bad[0, 3] = 0.0                                          # node 3 on the singular set
    return problem, InitialGuess(states, np.zeros((1, 6))), InitialGuess(bad, np.zeros((1, 6)))


@pytest.mark.parametrize("solver", ["ipopt", "fatrop"])
def test_non_finite_guess_is_refused_before_the_solver_runs(solver):
    """A fresh solver given a guess with 1/r infinite at node 3 returns success=False, status
    Invalid_Initial_Point naming interval 3 (only the stage starting there is infinite), no
    iterations, within seconds."""
    problem, _, bad = _singular_case()
    ocp = OCPSolver(problem, options=SolverOptions(jit=False, solver=solver))
    t0 = time.perf_counter()
    sol = ocp.solve(bad)
    assert time.perf_counter() - t0 < 5.0
    assert sol.success is False
    assert sol.status == "Invalid_Initial_Point"
    assert "at intervals 3 " in sol.message
    assert sol.iterations == 0


def test_refused_guess_after_a_solve_reports_its_own_outcome():
    """The same refusal after a successful solve on the same OCPSolver: no iterations and no
    success carried over from the previous solve's statistics."""
    problem, good, bad = _singular_case()
    ocp = OCPSolver(problem, options=SolverOptions(jit=False))
    assert ocp.solve(good).success
    sol = ocp.solve(bad)
    assert sol.success is False
    assert sol.status == "Invalid_Initial_Point"
    assert sol.iterations == 0
    assert not sol.stats.get("success", False)
