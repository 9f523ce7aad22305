"""Jacobi identity of the reduced bracket ⇔ holonomic constraints (thesis §2.2.2, eq. 2.31)."""
import pytest
from conftest import SYSTEMS

from nhgait.dynamics import System, derive, jacobi_test

L = "(x_dot**2 + y_dot**2 + z_dot**2)/2"


def test_holonomic_constraint_gives_a_poisson_bracket():
    s = System(coordinates=["x", "y", "z"], lagrangian=L, constraints=["z_dot - y*x_dot - x*y_dot"])  # z = xy
    res = jacobi_test(derive(s, use_cache=False))
    assert res.holonomic
    assert res.jacobi_holds
    assert res.jacobiator < 1e-12


def test_heisenberg_constraint_breaks_jacobi():
    s = System(coordinates=["x", "y", "z"], lagrangian=L, constraints=["z_dot - y*x_dot"])
    res = jacobi_test(derive(s, use_cache=False))
    assert not res.holonomic
    assert not res.jacobi_holds
    assert res.jacobiator > 1e-3
    assert res.consistent


@pytest.mark.parametrize("name", SYSTEMS)
def test_builtin_systems_are_nonholonomic_and_consistent(name, models):
    res = jacobi_test(models[name]["reduced"])
    assert not res.holonomic
    assert not res.jacobi_holds
    assert res.consistent


def test_classification_table_2_1(models):
    assert models["unicycle"]["reduced"].classification == "purely dynamic"
    assert models["snakeboard"]["reduced"].classification == "mixed"
    assert models["chaplygin_sleigh"]["reduced"].classification == "purely dynamic"
    assert models["knife_edge_incline"]["reduced"].classification == "principally kinematic"
    free = System(coordinates=["x", "y"], lagrangian="(x_dot**2 + y_dot**2)/2")
    assert derive(free, use_cache=False).classification == "purely mechanical"
