"""Height functions and loop estimates (issue 42, item 3) against independent computations:
complex-step derivatives of A(r) and the se(2) bracket written by hand (to 1e-9), the
constraint equations integrated directly (DOP853, rtol 1e-12) for a circular shape loop."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from nhgait.dynamics import derive
from nhgait.dynamics.derivation.input.scene import load_scene
from nhgait.dynamics.derivation.models import snakeboard
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.geometry.connection_fields import local_connection, numeric_connection
from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights, height_function
from nhgait.dynamics.geometry.stokes import loop_displacement, stokes_displacement

SNAKE3 = Path(__file__).resolve().parents[1] / "scenes" / "snake3.toml"


@pytest.fixture(scope="module")
def snake3():
    return derive(load_scene(str(SNAKE3)).system, "reduced")


@pytest.fixture(scope="module")
def board():
    return derive(snakeboard(), "reduced")


def _se2_bracket(u, v):
    """[u, v] in se(2), body coordinates (v_x, v_y, ω): (u_y v_ω − u_ω v_y, u_ω v_x − u_x v_ω, 0)."""
    return np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], 0.0])


def _independent_height(model, a, b, q, h=1e-30):
    """−(∂A_b/∂r_a − ∂A_a/∂r_b) + [A_a, A_b] with complex-step derivatives of A (lambdified from
    step 5's matrix) and the hand-written se(2) bracket."""
    system = model.system
    A = local_connection(model).A
    f = sp.lambdify(list(system.q) + list(system.param_symbols), A, "numpy")
    params = list(system.param_vector())
    ia, ib = list(system.coordinates).index(a), list(system.coordinates).index(b)
    shape = [system.coordinates[i] for i in model.layout.free]
    ja, jb = shape.index(a), shape.index(b)

    def d(i):
        z = np.array(q, complex)
        z[i] += 1j * h
        return np.imag(np.array(f(*z, *params), complex)) / h

    A0 = np.array(f(*q, *params), float)
    return -(d(ia)[:, jb] - d(ib)[:, ja]) + _se2_bracket(A0[:, ja], A0[:, jb])


@pytest.mark.parametrize("name,pair", [("snake3", ("alpha1", "alpha2")), ("board", ("psi", "phi"))])
def test_height_function_matches_complex_step_and_se2_bracket(name, pair, request):
    model = request.getfixturevalue(name)
    system = model.system
    H = sp.lambdify(list(system.q) + list(system.param_symbols),
                    height_function(local_connection(model), *pair), "numpy")
    rng = np.random.default_rng(42)
    for q in rng.uniform(-0.9, 0.9, size=(5, system.n)):
        got = np.array(H(*q, *system.param_vector()), float).ravel()
        want = _independent_height(model, *pair, q)
        assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, np.max(np.abs(want)))


def test_the_snakeboard_heights_are_not_trivial(board):
    """The snakeboard's x height over (ψ, φ) is nonzero away from φ = 0 (a drive gait exists)."""
    grid = evaluate_heights(local_connection(board), "psi", "phi",
                            HeightGrid(bounds={"psi": (-1, 1), "phi": (-1, 1)}, points=9))
    assert grid.heights.shape == (3, 9, 9) and grid.fields.shape == (3, 2, 9, 9)
    assert np.max(np.abs(grid.heights[0])) > 1e-3


def test_numeric_connection_equals_step5(snake3):
    """A from the compiled basis (A = −g⁻¹X_s) equals step 5's A (two routes)."""
    system = snake3.system
    f = sp.lambdify(list(system.q) + list(system.param_symbols), local_connection(snake3).A, "numpy")
    nc = numeric_connection(snake3)
    qs = np.random.default_rng(1).uniform(-0.9, 0.9, size=(4, system.n))
    for q in qs:
        assert np.allclose(nc.A(q), np.array(f(*q, *system.param_vector()), float), atol=1e-12)
    # ‖gA‖ in one mapped call = ‖A‖ (g a rotation)
    sizes = [np.linalg.norm(np.array(f(*q, *system.param_vector()), float)) for q in qs]
    assert np.allclose(nc.lift_sizes(qs.T), sizes, rtol=1e-12)


def _log_se2(x, y, th):
    """The se(2) element whose exponential is the pose (x, y, θ)."""
    a = th / 2 / np.tan(th / 2) if abs(th) > 1e-12 else 1.0
    return np.array([a * x + th / 2 * y, -th / 2 * x + a * y, th])


def _simulated_loop(system, centre, eps):
    """The pose after the circular loop r = centre + ε(cos t, sin t), t ∈ [0, 2π], from the
    identity, integrating the constraints ω_s ṡ = −ω_r ṙ themselves (no reduction)."""
    W = sp.lambdify(list(system.q) + list(system.param_symbols), system.omega(), "numpy")
    params = system.param_vector()

    def f(t, s):
        r = centre + eps * np.array([np.cos(t), np.sin(t)])
        Wq = np.asarray(W(*s, *r, *params), float)
        return np.linalg.solve(Wq[:, :3], -Wq[:, 3:] @ (eps * np.array([-np.sin(t), np.cos(t)])))

    return solve_ivp(f, (0, 2 * np.pi), np.zeros(3), method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]


def _estimates(model, connection, centre, eps):
    system = model.system
    H = sp.lambdify(system.q[3:5], height_function(connection, "alpha1", "alpha2").subs(
        dict(zip(system.param_symbols, system.param_vector(), strict=True))), "numpy")
    t = np.linspace(0, 2 * np.pi, 401)
    a, b = centre[0] + eps * np.cos(t), centre[1] + eps * np.sin(t)
    q = np.vstack([np.zeros((3, t.size)), a, b])
    return stokes_displacement(H, a[:-1], b[:-1]), loop_displacement(numeric_connection(model), q).total


def test_stokes_estimate_error_falls_linearly_in_the_loop_size(snake3):
    """Relative error of ∬H (and of the body-velocity integral) against the simulated
    displacement: O(ε) (Magnus terms of order ε³ over a displacement of order ε²)."""
    centre = np.array([0.3, -0.2])
    connection = local_connection(snake3)
    errors = []
    for eps in (0.1, 0.05, 0.025):
        exact = _log_se2(*_simulated_loop(snake3.system, centre, eps))
        stokes, bvi = _estimates(snake3, connection, centre, eps)
        errors.append([np.linalg.norm(e - exact) / np.linalg.norm(exact) for e in (stokes, bvi)])
    errors = np.array(errors)
    assert np.all(errors[1:] <= 0.6 * errors[:-1])          # at least linear: halving ε at least
    assert errors[-1, 0] < 0.01 and errors[-1, 1] < 0.002     # nearly halves the error


def test_a_flipped_connection_fails_the_simulation_check(snake3):
    """With A → −A (a sign error in the connection) the estimates point the wrong way."""
    centre, eps = np.array([0.3, -0.2]), 0.05
    flipped = dataclasses.replace(local_connection(snake3), A=-local_connection(snake3).A)
    exact = _log_se2(*_simulated_loop(snake3.system, centre, eps))
    stokes, _ = _estimates(snake3, flipped, centre, eps)
    assert np.linalg.norm(stokes - exact) / np.linalg.norm(exact) > 0.5


def test_bad_requests_name_every_problem(board):
    with pytest.raises(ModelError, match=r"(?s)'x' is not a shape coordinate.*bounds of 'phi'.*points"):
        evaluate_heights(local_connection(board), "x", "phi", HeightGrid(bounds={}, points=1))


def test_fibre_motion_of_a_prescribed_loop_equals_the_constraints(snake3):
    """prescribed.fibre_motion (the reduced equations along r(t)) against the constraint
    equations integrated directly, for the kinematic snake (p absent): 1e-6 at 1600 steps."""
    from nhgait.dynamics.geometry.prescribed import fibre_motion
    centre, eps = np.array([0.3, -0.2]), 0.1
    t = np.linspace(0, 2 * np.pi, 1601)
    q = np.vstack([np.zeros((3, t.size)), centre[0] + eps * np.cos(t), centre[1] + eps * np.sin(t)])
    got = fibre_motion(snake3, t, q).fiber[:, -1]
    assert np.max(np.abs(got - _simulated_loop(snake3.system, centre, eps))) < 1e-6


def test_the_snakeboard_drive_loop_moves_it_and_the_momentum_returns(board):
    """ψ = 0.8 sin t, φ = 0.6 cos t from rest: the board moves along x (y, θ back to 0 by the
    loop's symmetry) and p returns to 0 (ṗ is odd over the loop); halving the step changes
    the result by < 1e-5 (midpoint rule, second order)."""
    from nhgait.dynamics.geometry.prescribed import fibre_motion
    ends = []
    for count in (801, 1601):
        t = np.linspace(0, 2 * np.pi, count)
        q = np.vstack([np.zeros((3, t.size)), 0.8 * np.sin(t), 0.6 * np.cos(t)])
        motion = fibre_motion(board, t, q)
        ends.append(motion.fiber[:, -1])
        assert abs(motion.momentum[0, -1]) < 1e-6
    assert abs(ends[1][0]) > 0.1 and np.max(np.abs(ends[1][1:])) < 1e-6
    assert np.max(np.abs(ends[1] - ends[0])) < 1e-5


@pytest.mark.parametrize("name,pair,box", [
    ("snake3", ("alpha1", "alpha2"), {"alpha1": (0.2, 0.9), "alpha2": (-0.9, -0.2)}),
    ("board", ("psi", "phi"), {"psi": (-1, 1), "phi": (-1, 1)})])
def test_numeric_heights_equal_the_symbolic_ones(name, pair, box, request):
    """evaluate_heights_numeric (compiled basis, central differences) = evaluate_heights (sympy)
    to 1e-7 of the largest height on the grid (differences of step 1e-5: error ~1e-10)."""
    from nhgait.dynamics.geometry.heights import evaluate_heights_numeric
    model = request.getfixturevalue(name)
    symbolic = evaluate_heights(local_connection(model), *pair, HeightGrid(bounds=box, points=7))
    numeric = evaluate_heights_numeric(numeric_connection(model), *pair, HeightGrid(bounds=box, points=7))
    scale = np.max(np.abs(symbolic.heights))
    assert np.max(np.abs(numeric.heights - symbolic.heights)) <= 1e-7 * scale
    assert np.allclose(numeric.fields, symbolic.fields, atol=1e-12)


def test_grid_axes_are_named_and_evenly_spaced_over_the_bounds():
    axes = HeightGrid(bounds={"a": (0.0, 1.0), "b": (-2.0, 2.0)}, points=5).axes("a", "b")
    np.testing.assert_allclose(axes.a_values, [0.0, 0.25, 0.5, 0.75, 1.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(axes.b_values, [-2.0, -1.0, 0.0, 1.0, 2.0], rtol=0, atol=1e-15)


@pytest.mark.parametrize("name", ["snake3", "board"])
def test_the_mapped_connection_equals_the_pointwise_one(name, request):
    """NumericConnection.A_many (one mapped call of the basis, a frame per distinct fibre
    configuration) = A at each column to 1e-12, for configurations with different fibres."""
    model = request.getfixturevalue(name)
    connection = numeric_connection(model)
    rng = np.random.default_rng(3)
    q = rng.uniform(-0.8, 0.8, (len(connection.names), 9))
    q[:, 5:] = q[:, [5]]                      # some columns share a fibre configuration
    many = connection.A_many(q)
    for k in range(q.shape[1]):
        assert np.allclose(many[k], connection.A(q[:, k]), rtol=0, atol=1e-12)


def test_numeric_structure_constants_equal_the_symbolic_ones(snake3, board):
    """numeric_structure_constants (numbers at three fibre configurations) = structure_constants
    (sympy inverse and simplification) to 1e-12, for SE(2) in both frames and the identity; a
    frame that is no group frame still gets the symbolic route's error."""
    from nhgait.dynamics.geometry.connection_fields import numeric_structure_constants, structure_constants
    for model in (snake3, board):
        layout = model.layout
        s = [layout.system.q[i] for i in layout.si]
        g = sp.Matrix(layout.g)
        assert np.allclose(numeric_structure_constants(g, s), structure_constants(g, s), rtol=0, atol=1e-12)
    x, y, th = sp.symbols("x y theta")
    turning = sp.Matrix([[sp.cos(th), -sp.sin(th), 0], [sp.sin(th), sp.cos(th), 0], [0, 0, 1]])
    c = numeric_structure_constants(turning, [x, y, th])
    assert np.allclose([c[0, 1, 2], c[1, 2, 0], c[2, 0, 1]], [1.0, 1.0, 0.0], atol=1e-12)
    assert np.allclose(numeric_structure_constants(sp.eye(3), [x, y, th]), 0.0)
    with pytest.raises(ModelError, match="not constant"):
        numeric_structure_constants(sp.Matrix([[1, 0], [0, 1 + x ** 2]]), [x, y])
