"""A linear time-invariant optimal-control problem ż = A z + B u with three states (a, b, c) and
two inputs, for the tests whose references are closed forms of linear systems (the stage
Jacobians' exact propagator, the stored feedback's discrete Riccati gain)."""
from __future__ import annotations

import casadi as ca

from nhgait.dynamics.numerics.numeric_model import NumericModel
from nhgait.ocp import OptimalControlProblem


def linear_problem(A, B, T: float, N: int) -> OptimalControlProblem:
    """ż = A z + B u (A 3×3, B 3×2) over T with N intervals, a(0) = 0 and |u| ≤ 1."""
    t, z, u, params = ca.SX.sym("t"), ca.SX.sym("z", 3), ca.SX.sym("u", 2), ca.SX.sym("params", 0)
    rhs = ca.mtimes(ca.DM(A), z) + ca.mtimes(ca.DM(B), u)
    numeric = NumericModel("reduced", ("a", "b", "c"), ("u1", "u2"), (), (),
                           {"rhs": ca.Function("rhs", [t, z, u, params], [rhs]),
                            "qdot": ca.Function("qdot", [z, params], [z[1:2]])}, n_coordinates=1)

    class Model:
        state_names = ("a", "b", "c")
    Model.numeric = numeric
    return OptimalControlProblem(Model(), T, N, initial={"a": 0.0}, control_bounds=1.0)
