"""The NLP solvers as objects (ocp/backends.py): the options each one builds from a
``SolverOptions`` are accepted by CasADi's plugin and solve a small NLP to its closed-form
optimum; the user's own solver options win (Ipopt's with or without the ``ipopt.`` prefix);
FATROP gets the stage dimensions."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nhgait.ocp import SolverOptions
from nhgait.ocp.backends import BACKENDS, FATROP, IPOPT


def test_ipopt_options_solve_a_small_nlp_to_its_closed_form_optimum():
    """min (x − 1)² + (y − 2)² s.t. x + y = 1: x* = 0, y* = 1, f* = 2 (Lagrange by hand)."""
    options = SolverOptions(max_iter=50, tol=1e-10, print_level=0, time_limit=30.0,
                            ipopt={"mu_init": 0.01, "ipopt.bound_push": 1e-3})
    opts = IPOPT.nlpsol_options(options, {})
    assert opts["ipopt.max_iter"] == 50 and opts["ipopt.max_wall_time"] == 30.0
    assert opts["ipopt.mu_init"] == 0.01 and opts["ipopt.bound_push"] == 1e-3      # either spelling
    assert opts["ipopt.hessian_approximation"] == "exact"
    z = ca.MX.sym("z", 2)
    solver = ca.nlpsol("s", "ipopt", {"x": z, "f": (z[0] - 1) ** 2 + (z[1] - 2) ** 2, "g": z[0] + z[1]},
                       {**opts, "print_time": False})
    out = solver(x0=[5.0, -3.0], lbg=1.0, ubg=1.0)
    np.testing.assert_allclose(np.asarray(out["x"]).ravel(), [0.0, 1.0], atol=1e-8)
    assert float(out["f"]) == pytest.approx(2.0, abs=1e-8) and solver.stats()["success"]
    limited = IPOPT.nlpsol_options(SolverOptions(hessian="limited-memory"), {})
    assert limited["ipopt.hessian_approximation"] == "limited-memory"
    assert IPOPT.verbose_options({})["ipopt.print_level"] == 5


def test_fatrop_options_and_the_stage_dimensions():
    opts = FATROP.nlpsol_options(SolverOptions(solver="fatrop", max_iter=7, fatrop={"mu_init": 0.1}), {})
    assert opts["fatrop"]["max_iter"] == 7 and opts["fatrop"]["mu_init"] == 0.1
    assert FATROP.verbose_options(opts)["fatrop"]["max_iter"] == 7
    nlp = type("NLP", (), {"structure": {"N": 3, "nx": [2] * 4, "nu": [1] * 3, "ng": [0] * 4}})()
    staged = FATROP.structure_options(nlp, {"a": 1})
    assert staged["structure_detection"] == "manual" and staged["N"] == 3 and staged["a"] == 1
    assert IPOPT.structure_options(nlp, {"a": 1}) == {"a": 1}


def test_the_registry_and_what_differs():
    assert BACKENDS == {"ipopt": IPOPT, "fatrop": FATROP}
    assert IPOPT.limited_memory and not FATROP.limited_memory
    assert FATROP.stage_structure and not IPOPT.stage_structure
    assert SolverOptions(solver="fatrop").backend is FATROP
