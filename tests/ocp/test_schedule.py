"""Conditions between the ends (waypoints), integral states, path constraints on inputs and
accelerations, and phases (nhgait.ocp.schedule, nhgait.ocp.statement), on a point mass.

The oracle: a particle of mass m in the plane, ẍ = F_x / m, ÿ = F_y / m, with inputs held
constant on each interval. Within an interval x(t) is quadratic and ∫x dt cubic, so RK4 (the
shooting stage) is exact and the NLP is a linear-quadratic program: minimise Σ_k h_k |u_k|²
subject to linear conditions. Its exact solution comes from the KKT system (numpy), written
here from the closed-form interval maps, independently of the transcription. Ipopt stops at
a relative KKT tolerance of 1e-8, so the stated tolerance is 1e-6.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.ocp import InitialGuess, OptimalControlProblem, ProblemError, Quantity, solve
from nhgait.ocp.problem import qddot_of
from nhgait.ocp.statement import Phase, Waypoint

MASS = 2.0
TOL = 1e-6


# ----------------------------------------------------------------------------- the oracle
def _nodes(h, U):
    """Exact node values from rest at the origin: x, v (2 × (N+1) each) and I = ∫x dt
    (2 × (N+1)) for the inputs U (2 × N) held on intervals of lengths h."""
    N = len(h)
    x, v, I = np.zeros((2, N + 1)), np.zeros((2, N + 1)), np.zeros((2, N + 1))
    for k in range(N):
        a = U[:, k] / MASS
        x[:, k + 1] = x[:, k] + h[k] * v[:, k] + h[k] ** 2 / 2 * a
        v[:, k + 1] = v[:, k] + h[k] * a
        I[:, k + 1] = I[:, k] + h[k] * x[:, k] + h[k] ** 2 / 2 * v[:, k] + h[k] ** 3 / 6 * a
    return x, v, I


def lq_oracle(h, conditions, weights=(1.0, 1.0)):
    """(inputs U, objective) minimising Σ h_k (w_x F_x² + w_y F_y²) subject to each condition
    c(x, v, I, U) = value (c linear), by the KKT system."""
    h = np.asarray(h, float)
    N = len(h)
    n = 2 * N

    def values(u):
        U = u.reshape(N, 2).T
        return np.array([c(*_nodes(h, U), U) for c, _ in conditions])

    c0 = values(np.zeros(n))
    A = np.column_stack([values(e) - c0 for e in np.eye(n)])
    b = np.array([v for _, v in conditions]) - c0
    H = np.diag(2 * np.repeat(h, 2) * np.tile(weights, N))
    K = np.block([[H, A.T], [A, np.zeros((len(b), len(b)))]])
    u = np.linalg.solve(K, np.concatenate([np.zeros(n), b]))[:n]
    U = u.reshape(N, 2).T
    return U, float(np.sum(h * (weights[0] * U[0] ** 2 + weights[1] * U[1] ** 2)))


def _rest_to(x_end, y_end, N):
    """Conditions: from rest at the origin to rest at (x_end, y_end) at node N."""
    return [(lambda x, v, I, U: x[0, N], x_end), (lambda x, v, I, U: x[1, N], y_end),
            (lambda x, v, I, U: v[0, N], 0.0), (lambda x, v, I, U: v[1, N], 0.0)]


def _guess(problem, x_end=1.0, y_end=1.0):
    N = problem.intervals
    states = np.zeros((len(problem.model_state_names), N + 1))
    states[0], states[1] = np.linspace(0, x_end, N + 1), np.linspace(0, y_end, N + 1)
    return InitialGuess(states, np.zeros((2, N)))


REST = {"x": 0.0, "y": 0.0, "x_dot": 0.0, "y_dot": 0.0}


#: the transcriptions and solvers checked against the oracle (collocation of degree 3 is exact
#: here too: the node states are quadratic and ∫x dt cubic in t within an interval)
METHODS = {"shooting": {}, "stages-fatrop": {"solver": "fatrop"},
           "collocation": {"transcription": "collocation"}}


def _solve(problem, method):
    from nhgait.ocp.transcription import get_transcription
    kwargs = dict(METHODS[method])
    if "transcription" in kwargs:
        kwargs["transcription"] = get_transcription(kwargs["transcription"])
    return solve(problem, _guess(problem, 0.5, 0.5), jit=False, **kwargs)


def _check(sol, U, J):
    assert sol.success, sol.message
    assert sol.objective == pytest.approx(J, rel=TOL)
    assert np.max(np.abs(sol.u.T - U)) <= TOL * max(1.0, np.max(np.abs(U)))        # U: nu × N
    v = sol.verify()
    assert v.success, v
    assert v.max_error <= 1e-8, v


# ----------------------------------------------------------------------------- waypoints
@pytest.mark.parametrize("method", METHODS)
def test_a_waypoint_at_a_node_is_met_as_the_exact_lq_optimum_says(particle, method):
    T, N = 4.0, 8
    problem = OptimalControlProblem(particle, T, N, initial=REST, final={**REST, "x": 0.0, "y": 1.0},
                                    waypoints=[Waypoint(2.0, {"x": 1.0, "y_dot": 0.2}, name="corner")])
    sol = _solve(problem, method)
    U, J = lq_oracle(np.full(N, T / N), _rest_to(0.0, 1.0, N) + [(lambda x, v, I, U: x[0, 4], 1.0),
                                                                 (lambda x, v, I, U: v[1, 4], 0.2)])
    _check(sol, U, J)
    assert sol.t[4] == pytest.approx(2.0, abs=1e-15)
    # the re-simulation meets the waypoint (its own label) to the integrator's accuracy
    assert sol.verify().condition_errors["corner.x"] <= 1e-9


def test_a_waypoint_between_nodes_is_refused_with_the_nearest_nodes(particle):
    with pytest.raises(ProblemError, match=r"(?s)waypoints\[0\].*time 1.3 is not a node.*1\.2.*1\.6"
                                           r".*waypoints\[1\].*not between the ends"):
        OptimalControlProblem(particle, 4.0, 10, initial=REST,
                              waypoints=[Waypoint(1.3, {"x": 1.0}), Waypoint(5.0, {"x": 1.0})])
    with pytest.raises(ProblemError, match="a waypoint at a given time needs a fixed horizon"):
        OptimalControlProblem(particle, 4.0, 10, initial=REST, free_horizon=(1.0, 5.0),
                              waypoints=[Waypoint(2.0, {"x": 1.0})])


# ----------------------------------------------------------------------------- integrals
@pytest.mark.parametrize("method", METHODS)
def test_an_integral_state_meets_its_final_value_and_is_the_exact_integral(particle, method):
    T, N = 3.0, 6
    problem = OptimalControlProblem(particle, T, N, initial=REST,
                                    final={**REST, "x": 1.0, "y": 0.0, "area": 2.0}, integrals={"area": "x"})
    assert problem.state_names[-1] == "area"
    assert problem.initial["area"] == 0.0
    sol = _solve(problem, method)
    U, J = lq_oracle(np.full(N, T / N), _rest_to(1.0, 0.0, N) + [(lambda x, v, I, U: I[0, N], 2.0)])
    _check(sol, U, J)
    # the integral state against the trapezoid-free exact integral of the oracle's nodes
    _, _, I = _nodes(np.full(N, T / N), U)
    assert np.max(np.abs(sol.z[:, -1] - I[0])) <= TOL


def test_an_integral_in_the_objective_is_its_final_value(particle):
    """end_weights: J = Σ h |u|² + w I(T) with I = ∫x dt (a Lagrange term on the state)."""
    T, N, w = 3.0, 6, 0.5
    problem = OptimalControlProblem(particle, T, N, initial=REST, final={**REST, "x": 1.0, "y": 0.0},
                                    integrals={"area": "x"}, end_weights={"area": w})
    sol = solve(problem, _guess(problem, 1.0, 0.0), jit=False)
    assert sol.success, sol.message
    # stationarity of the oracle's objective at the solution: the KKT system with the linear term
    h = np.full(N, T / N)
    U = sol.u.T                                       # nu × N, the oracle's layout
    _, _, I = _nodes(h, U)
    assert sol.objective == pytest.approx(np.sum(h * np.sum(U ** 2, axis=0)) + w * I[0, N], rel=1e-9)
    J0 = sol.objective
    rng = np.random.default_rng(3)
    for _ in range(5):       # no feasible direction decreases it: perturb along the null space of the ends
        conditions = _rest_to(1.0, 0.0, N)
        A = np.column_stack([[c(*_nodes(h, e.reshape(N, 2).T), e.reshape(N, 2).T) for c, _ in conditions]
                             for e in np.eye(2 * N)])
        null = np.linalg.svd(A)[2][len(conditions):]
        d = (rng.standard_normal(len(null)) @ null).reshape(N, 2).T * 1e-3
        for s in (d, -d):
            Up = U + s
            _, _, Ip = _nodes(h, Up)
            assert np.sum(h * np.sum(Up ** 2, axis=0)) + w * Ip[0, N] >= J0 - 1e-9


# ----------------------------------------------------------------------------- inputs and accelerations
def _slope(model):
    """ÿ − ẍ/2 + x: a quantity of the accelerations q̈ = ∂q̇/∂z ż (and the state)."""
    def f(z, u, zdot, params):
        qdd = qddot_of(model, z, zdot, params)
        return qdd[1] - 0.5 * qdd[0] + z[0]
    return Quantity("slope", f, "ÿ − ẍ/2 + x", inputs=True)


@pytest.mark.parametrize("method", METHODS)
def test_an_acceleration_path_constraint_holds_at_every_node(particle, method):
    T, N = 2.0, 8
    problem = OptimalControlProblem(particle, T, N, initial=REST, final={**REST, "x": 1.0, "y": 0.5},
                                    quantities={"slope": _slope(particle)},
                                    state_bounds={"slope": (0.0, 0.0)})
    sol = _solve(problem, method)
    rows = [(lambda x, v, I, U, k=k: (U[1, k] - 0.5 * U[0, k]) / MASS + x[0, k], 0.0) for k in range(N)]
    U, J = lq_oracle(np.full(N, T / N), _rest_to(1.0, 0.5, N) + rows)
    _check(sol, U, J)
    assert sol.verify().condition_errors["bounds.slope"] <= 1e-9


def test_a_quantity_of_the_inputs_is_refused_at_one_instant(particle):
    with pytest.raises(ProblemError, match=r"final: 'slope' depends on the inputs or accelerations"):
        OptimalControlProblem(particle, 2.0, 8, initial=REST, final={"slope": 0.0},
                              quantities={"slope": _slope(particle)})


# ----------------------------------------------------------------------------- phases
@pytest.mark.parametrize("method", METHODS)
def test_phases_of_fixed_horizons_are_one_lq_program_with_their_own_steps(particle, method):
    phases = [Phase(1.0, 4, final={"x": 1.0}, name="out"), Phase(3.0, 6, final={**REST, "y": 1.0})]
    problem = OptimalControlProblem(particle, 1.0, 1, initial=REST, phases=phases)
    assert (problem.horizon, problem.intervals) == (4.0, 10)
    sol = _solve(problem, method)
    h = np.concatenate([np.full(4, 0.25), np.full(6, 0.5)])
    U, J = lq_oracle(h, _rest_to(0.0, 1.0, 10) + [(lambda x, v, I, U: x[0, 4], 1.0)])
    _check(sol, U, J)
    assert np.allclose(sol.t, np.concatenate([[0.0], np.cumsum(h)]), atol=1e-15)


@pytest.mark.parametrize("method", METHODS)
def test_free_phase_horizons_find_the_bang_bang_minimum_time(particle, method):
    """Rest to rest over a distance d with |ẍ| ≤ a: T* = 2 √(d / a), reached with piecewise
    constant inputs when the switch is a node — the boundary of two free phases."""
    d, a = 1.0, 1.0
    phases = [Phase(1.5, 5, free_horizon=(0.2, 4.0)), Phase(1.5, 5, free_horizon=(0.2, 4.0))]
    problem = OptimalControlProblem(particle, 1.0, 1, initial=REST, final={**REST, "x": d, "y": 0.0},
                                    phases=phases,
                                    control_bounds={"Fx": (-a * MASS, a * MASS), "Fy": (-1, 1)},
                                    control_weights={"Fx": 0.0, "Fy": 1.0}, time_weight=1.0)
    sol = _solve(problem, method)
    assert sol.success, sol.message
    assert sol.horizon == pytest.approx(2 * np.sqrt(d / a), abs=1e-6)
    assert sol.verify().max_error <= 1e-8


def test_bad_phases_are_listed_together(particle):
    with pytest.raises(ProblemError, match=r"(?s)phases\[0\].intervals = 0.*phases\[1\].horizon = -1"
                                           r".*phases\[1\].*free_horizon: lower bound 0 must be positive"
                                           r".*phases\[1\].final: unknown"):
        OptimalControlProblem(particle, 1.0, 1, initial=REST,
                              phases=[Phase(1.0, 0),
                                      Phase(-1.0, 3, free_horizon=(0.0, 1.0), final={"zz": 1.0})])


# ----------------------------------------------------------------------------- code independent of N
def _wide(inputs: bool, count: int) -> Quantity:
    """A quantity of ``count`` terms (of the state, or of the inputs)."""
    def terms(x, y):
        return sum(ca.sin(j * x + y) / j for j in range(1, count + 1))
    if inputs:
        return Quantity("wide", lambda z, u, zdot, params: terms(u[0], zdot[2]), inputs=True)
    return Quantity("wide", lambda z, params: terms(z[0], z[1]))


def _c_bytes(problem) -> int:
    """The size of the NLP's generated C (a budget of 0 bytes: generated, never compiled)."""
    from nhgait.ocp.solver import CompileBudget, OCPSolver, SolverOptions
    solver = OCPSolver(problem, options=SolverOptions(jit=True, budget=CompileBudget(0, 0)))
    return solver.compile_report.c_bytes


@pytest.mark.parametrize("inputs", [False, True], ids=["of the state", "of the inputs"])
def test_the_generated_code_does_not_grow_with_n_times_a_bounded_quantity(particle, inputs):
    """A path bound on a derived quantity is a mapped function: from N = 10 to N = 100 the C
    grows by the same amount (the sparsity patterns, indices) whether the bounded quantity has
    1 term or 60 (each term about 60 bytes of C) — not by 90 copies of its expression."""
    growth = {}
    for count in (1, 60):
        sizes = [_c_bytes(_bounded_problem(particle, N, _wide(inputs, count))) for N in (10, 100)]
        growth[count] = sizes[1] - sizes[0]
    assert abs(growth[60] - growth[1]) <= 0.02 * growth[1], growth


def _bounded_problem(particle, N, wide):
    return OptimalControlProblem(particle, 2.0, N, initial=REST, final={**REST, "x": 1.0},
                                 quantities={"wide": wide}, state_bounds={"wide": (-1.0, 1.0)},
                                 waypoints=[Waypoint(1.0, {"y": 0.1})], integrals={"area": "x"})


# ----------------------------------------------------------------------------- objective scale
@pytest.mark.parametrize("method", ["shooting", "stages-fatrop"])
def test_a_large_effort_objective_is_scaled_for_the_solver_and_reported_as_stated(particle, method):
    """Inputs bounded by ±1000 N over 3 s: J_ref = 3 · 2 · 10⁶, the NLP's objective scaled by
    10⁴ / J_ref; the optimum (a 30 m move, J = 1646) is the exact LQ one and is reported
    unscaled."""
    from nhgait.ocp.transcription import MultipleShooting, objective_scale
    T, N = 3.0, 6
    problem = OptimalControlProblem(particle, T, N, initial=REST, final={**REST, "x": 30.0, "y": 0.0},
                                    control_bounds=1000.0)
    assert objective_scale(problem) == pytest.approx(1e4 / (T * 2 * 1000.0 ** 2), rel=1e-15)
    assert MultipleShooting().build(problem).objective_scale == objective_scale(problem)
    sol = _solve(problem, method)
    U, J = lq_oracle(np.full(N, T / N), _rest_to(30.0, 0.0, N))
    _check(sol, U, J)
    assert J > 1e3
