"""The system statement read once (system_parsing) and its parameter checks (parameter_checks):
the normalised fields, pickling without the lambdified functions, their memo's lifetime."""
import gc
import pickle

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import builtin
from nhgait.dynamics.derivation import parameter_checks
from nhgait.dynamics.derivation.input.system_parsing import parse_system
from nhgait.dynamics.derivation.system import System


def test_parse_system_reads_a_statement_without_building_a_system():
    class Statement:                       # any object with the fields of System
        coordinates, lagrangian = ["x", "theta"], "m*x_dot**2/2 + J*theta_dot**2/2"
        constraints, forces = (), {"x": "F", "theta": "tau*sin(t)"}
        parameters, inputs, fiber, planar_frame = {"m": 2.0, "J": 0.5}, None, None, "auto"
    parsed = parse_system(Statement())
    assert parsed.problems == ()
    assert parsed.complete
    assert parsed.coordinates == ("x", "theta")
    assert parsed.inputs == ("F", "tau")
    assert parsed.planar_frame is None                   # no y: no planar frame
    x_dot = sp.Symbol("x_dot", real=True)
    assert sp.diff(parsed.L, x_dot, 2) == sp.Symbol("m", real=True)


def test_every_field_problem_is_listed_once():
    class Statement:
        coordinates, lagrangian = ["x", "x"], "m*x_dot**2/2"
        constraints, forces = "x_dot", {"z": "1"}
        parameters, inputs, fiber, planar_frame = {"m": "abc"}, None, ["q"], ("x",)
    problems = parse_system(Statement()).problems
    assert any("used twice" in p for p in problems)
    assert any("constraints: expected a list" in p for p in problems)
    assert any(p.startswith("fiber: q not coordinates") for p in problems)
    assert any(p.startswith("planar_frame:") for p in problems)


def test_lambdified_functions_match_sympy_and_are_not_pickled():
    system = builtin("snakeboard")
    mass, omega, _ = system.numeric_functions()
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5])
    pv = system.param_vector()
    subs = {**dict(zip(system.q, q, strict=True)), **dict(zip(system.param_symbols, pv, strict=True))}
    expected = np.array(system.mass_matrix().xreplace(subs).evalf(), dtype=float)
    np.testing.assert_allclose(mass(q, pv), expected, rtol=1e-14, atol=1e-14)
    copy = pickle.loads(pickle.dumps(system))
    assert copy.canonical_text() == system.canonical_text()
    assert copy.parameter_problems({"m": -1.0})          # rebuilt on demand for the copy
    assert "lambdified" not in " ".join(vars(copy))


def test_the_memo_drops_a_system_with_it():
    gc.collect()
    before = len(parameter_checks.LAMBDIFIED)
    system = System(["x", "y"], "x_dot**2/2 + y_dot**2/2", name="memo-lifetime")
    assert system.parameter_problems() == []
    assert len(parameter_checks.LAMBDIFIED) == before + 1
    del system
    gc.collect()
    assert len(parameter_checks.LAMBDIFIED) == before


def test_with_fiber_is_the_same_system_in_another_chart():
    """System.with_fiber skips the statement's checks: every field equals replace()'s, which
    re-reads and re-checks the whole statement; a bad fiber is still refused."""
    import dataclasses

    from nhgait.dynamics.derivation.models import snakeboard
    from nhgait.dynamics.errors import ModelError
    system = snakeboard()
    fast = system.with_fiber(["x", "y", "theta"])
    checked = dataclasses.replace(system, fiber=("x", "y", "theta"))
    assert fast.fiber == ("x", "y", "theta") != system.fiber
    for item in dataclasses.fields(system):
        assert getattr(fast, item.name) == getattr(checked, item.name), item.name
    with pytest.raises(ModelError, match="xi not coordinates") as bad:
        system.with_fiber(["x", "xi", "x"])
    assert "repeated coordinate" in str(bad.value)
