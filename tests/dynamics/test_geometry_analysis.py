"""Growth vectors, accessibility and observability ranks (nhgait.dynamics.geometry) against
their published values: the chained-form growth vectors of the knife edge / unicycle (2, 3),
the kinematic car and the vertical rolling disc (2, 3, 4), the car with one and two on-axle
trailers (2, 3, 4, 5) and (2, 3, 4, 5, 6), the snakeboard (3, 4, 5) (Murray & Sastry 1993;
Ostrowski & Burdick 1998); full accessibility rank 2n − k at rest of the unicycle, snakeboard,
Chaplygin sleigh and 3-link wheeled snake (Bloch, Nonholonomic Mechanics and Control, §6);
a purely mechanical robot at zero momentum confined to its momentum level set (Noether);
a unicycle's position observable while it moves, its heading alone blind to x and y
(the SE(2) symmetry)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from nhgait.dynamics import derive, load_scene
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.geometry import accessibility, analysis_point, growth_vector, observability

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "tests" / "scenes"


def _model(name):
    """A built-in robot, or a scene of tests/scenes or examples/."""
    if name.endswith(".toml"):
        name = str(SCENES / name if (SCENES / name).exists() else ROOT / "examples" / name)
    scene = load_scene(name)
    return scene, derive(scene.system, "reduced")


@pytest.mark.parametrize("name, at, expected", [
    ("knife_edge.toml", {}, (2, 3)),
    ("unicycle", {"theta": 0.4}, (2, 3, 4)),                 # the vertical rolling disc (x, y, heading, spin)
    ("car.toml", {"phi": 0.2, "theta": 0.3}, (2, 3, 4)),
    ("car_trailer1.toml", {"phi": 0.1, "theta1": 0.2}, (2, 3, 4, 5)),
    ("car_trailer2.toml", {"phi": 0.1, "theta1": 0.2, "theta2": -0.1}, (2, 3, 4, 5, 6)),
    ("snakeboard", {"phi": 0.7}, (3, 4, 5)),
])
def test_growth_vectors(name, at, expected):
    _, model = _model(name)
    growth = growth_vector(model, analysis_point(model, at))
    assert growth.ranks == expected
    assert growth.degree_of_nonholonomy == len(expected) and growth.spans_everything
    assert len(growth.new_directions) == len(expected) - 1


def test_knife_edge_bracket_is_sideways():
    """[forward, turn] of the knife edge at heading θ is ±(−sin θ, cos θ, 0): the sideways direction."""
    _, model = _model("knife_edge.toml")
    growth = growth_vector(model, analysis_point(model, {"theta": 0.5}))
    (name, value), = growth.new_directions[0]
    direction = value / np.linalg.norm(value)
    assert abs(abs(direction @ np.array([-np.sin(0.5), np.cos(0.5), 0.0])) - 1) < 1e-12
    assert name == "[X_p, X_theta]"


@pytest.mark.parametrize("name, at", [
    ("unicycle", {}),
    ("snakeboard", {"phi": 0.7}),
    ("chaplygin_sleigh", {}),
    ("snake3.toml", {"alpha1": 0.3, "alpha2": -0.5}),
])
def test_accessibility_at_rest_is_full(name, at):
    _, model = _model(name)
    point = analysis_point(model, at)
    acc = accessibility(model, point)
    n, k = model.system.n, model.system.k
    assert point.at_rest
    assert acc.rank == acc.dimension == 2 * n - k and acc.full and not acc.confined
    assert acc.depth >= 2 and acc.control_affine


def test_purely_mechanical_at_zero_momentum_is_confined():
    _, model = _model("free_two_link.toml")
    acc = accessibility(model, analysis_point(model, {"alpha": 0.5}))
    assert model.classification == "purely mechanical"
    assert acc.confined and acc.rank < acc.dimension
    assert acc.unreached == ("p1", "p2", "p3")
    assert "conserved" in acc.reason


def test_unicycle_observability():
    _, model = _model("knife_edge.toml")
    moving = analysis_point(model, {"x_dot": 1.0, "theta_dot": 0.5})
    assert not moving.at_rest
    both = observability(model, moving, ["x", "y"])
    assert both.observable and both.rank == both.dimension == 5 and both.unobservable == ()
    heading = observability(model, moving, ["theta"])
    assert not heading.observable and {"x", "y"} <= set(heading.unobservable)
    assert "theta" not in heading.unobservable
    _, disc = _model("unicycle")
    seen = observability(disc, analysis_point(disc, {"phi_dot": 1.0, "theta_dot": 0.5}), ["theta"])
    assert {"x", "y"} <= set(seen.unobservable)


def test_bad_names_are_one_error_with_suggestions():
    _, model = _model("knife_edge.toml")
    with pytest.raises(ModelError, match="did you mean 'theta'") as err:
        analysis_point(model, {"thetaa": 1.0, "x_dot": 1.0, "p": 1.0})
    assert len(err.value.problems) == 2
    with pytest.raises(ModelError, match="did you mean 'y'"):
        observability(model, analysis_point(model, {}), ["yy"])
    with pytest.raises(ModelError, match="break the constraints"):
        analysis_point(model, {"y_dot": 1.0})                 # sideways at heading 0


def _sympy_growth(system, q_values):
    """A second route to the growth vector: a basis of D = null ω from sympy's own nullspace of ω
    (not the reduction's basis), brackets by sympy differentiation, ranks by numpy SVD at q."""
    import sympy as sp
    q = sp.Matrix(system.q)
    at = dict(zip(system.q, q_values, strict=True)) | dict(zip(system.param_symbols, system.param_vector(),
                                                              strict=True))
    omega = system.omega()
    basis = [sp.simplify(v) for v in omega.nullspace(simplify=True)]
    value = lambda f: np.array(f.xreplace(at).evalf(), dtype=float).ravel()   # noqa: E731
    level, collected, ranks = list(basis), [value(b) for b in basis], []
    ranks.append(np.linalg.matrix_rank(np.column_stack(collected), tol=1e-8))
    while ranks[-1] < system.n and len(ranks) < system.n:
        level = [b.jacobian(q) * a - a.jacobian(q) * b for a in basis for b in level]
        collected += [value(f) for f in level]
        ranks.append(np.linalg.matrix_rank(np.column_stack(collected), tol=1e-8))
    return tuple(ranks)


@pytest.mark.parametrize("name, at", [("car.toml", {"phi": 0.2, "theta": 0.3}),
                                      ("snakeboard", {"phi": 0.7}),
                                      ("car_trailer1.toml", {"phi": 0.1, "theta1": 0.2})])
def test_growth_vector_by_a_second_route(name, at):
    scene, model = _model(name)
    point = analysis_point(model, at)
    assert growth_vector(model, point).ranks == _sympy_growth(scene.system, point.q)


def test_symbolic_brackets_of_the_car_agree_with_the_numeric_ones():
    """The car's depth-3 direction is sideways everywhere: ±l(−sin θ, cos θ, 0, 0) by sympy; its value at
    the point equals the AD bracket's."""
    import sympy as sp
    scene, model = _model("car.toml")
    point = analysis_point(model, {"phi": 0.2, "theta": 0.3})
    growth = growth_vector(model, point)
    (name, value), = growth.new_directions[1]
    column = growth.symbolic[name]
    theta, l_ = sp.Symbol("theta", real=True), sp.Symbol("l", real=True)
    assert sp.simplify(column[0] ** 2 + column[1] ** 2 - l_ ** 2) == 0 and column[2] == column[3] == 0
    assert sp.simplify(column[0] * sp.cos(theta) + column[1] * sp.sin(theta)) == 0
    at = dict(zip(scene.system.q, point.q, strict=True)) | dict(zip(scene.system.param_symbols,
                                                                   scene.system.param_vector(), strict=True))
    symbolic_value = np.array(column.xreplace(at).evalf(), dtype=float).ravel()
    assert np.allclose(symbolic_value, value, rtol=1e-12, atol=1e-12)
