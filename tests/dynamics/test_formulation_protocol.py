"""The formulations' vocabulary on the models (dynamics/derivation/formulation_base.py, the
model types and the registry in formulations.py): every
formulation answers the same questions, and its answers agree with an independent evaluation of
the system's own sympy expressions (M(q), ω(q), V(q)) at constraint-consistent states.

Tolerances: the maps are a few dozen floating-point operations on O(1) numbers, so 1e-12
relative is loose enough for rounding and far below any modelling error."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
import scipy.linalg
import sympy as sp

from nhgait.dynamics import HamiltonianDAE, LagrangianDAE, ModelError, ReducedODE, derive
from nhgait.dynamics.derivation.formulation_base import (
    Baumgarte,
    LoopPoint,
    Projection,
    Stabilisation,
    stabilisation_named,
)
from nhgait.dynamics.derivation.formulations import FORMULATIONS, formulation_type
from nhgait.dynamics.derivation.states import constraint_residual, from_state, initial_state_map, to_state
from nhgait.dynamics.numerics.numeric_model import NumericModel

TOL = 1e-12
CASES = [(name, form) for name in ("unicycle", "snakeboard", "chaplygin_sleigh") for form in FORMULATIONS]


def _reference(system):
    """M(q), ω(q), V(q) at the default parameter values, lambdified from the system's sympy
    expressions (not through the engine's compiled functions)."""
    values = dict(zip(system.param_symbols, system.param_values, strict=True))
    args = list(system.q)
    mass = sp.lambdify(args, system.mass_matrix().subs(values), "numpy")
    omega = sp.lambdify(args, system.omega().subs(values), "numpy")
    potential = sp.lambdify(args, system.potential().subs(values), "numpy")
    return (lambda q: np.array(mass(*q), dtype=float), lambda q: np.array(omega(*q), dtype=float)
            .reshape(system.k, system.n), lambda q: float(potential(*q)))


def _consistent_state(system, omega, seed=3):
    """A random configuration and a velocity in the null space of ω(q) (scipy, not the engine)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-0.6, 0.6, system.n)
    basis = scipy.linalg.null_space(omega(q))
    return q, basis @ rng.uniform(-1.0, 1.0, basis.shape[1])


def test_every_formulation_name_resolves_to_its_model_type():
    assert FORMULATIONS == ("reduced", "lagrange", "hamilton")
    types = [formulation_type(name) for name in FORMULATIONS]
    assert types == [ReducedODE, LagrangianDAE, HamiltonianDAE]
    assert [t.formulation for t in types] == list(FORMULATIONS)
    with pytest.raises(ModelError,
                       match=r"unknown formulation 'euler' \(choose from reduced, lagrange, hamilton\)"):
        formulation_type("euler")


@pytest.mark.parametrize("name, form", CASES)
def test_model_type_and_state_layout(models, name, form):
    model = models[name][form]
    system = model.system
    layout = model.state_layout()
    assert model.formulation == form
    assert isinstance(model, formulation_type(form))
    assert layout.names[:system.n] == tuple(system.coordinates)
    assert layout.velocity_names == layout.names[system.n:]
    if form == "reduced":
        assert len(layout.names) == 2 * system.n - system.k
        assert layout.n_multipliers == 0
        assert not (model.has_multipliers or model.dae_options_apply or model.has_constraint_gram)
    else:
        assert len(layout.names) == 2 * system.n
        assert layout.n_multipliers == system.k
        assert model.has_multipliers
        assert model.dae_options_apply
        assert model.has_constraint_gram
        prefix = "" if form == "lagrange" else "p_"
        suffix = "_dot" if form == "lagrange" else ""
        assert layout.velocity_names == tuple(f"{prefix}{c}{suffix}" for c in system.coordinates)


@pytest.mark.parametrize("name, form", CASES)
def test_initial_state_map_against_the_system_expressions(models, name, form):
    model = models[name][form]
    system = model.system
    mass, omega, potential = _reference(system)
    q, qdot = _consistent_state(system, omega)
    x = to_state(model, q, qdot)
    np.testing.assert_allclose(x[:system.n], q, rtol=0, atol=0)
    if form == "lagrange":
        np.testing.assert_allclose(x[system.n:], qdot, rtol=0, atol=0)
    if form == "hamilton":
        np.testing.assert_allclose(x[system.n:], mass(q) @ qdot, rtol=TOL, atol=TOL)
    q_back, qdot_back = from_state(model, x)
    np.testing.assert_allclose(qdot_back, qdot, rtol=1e-10, atol=1e-10)
    energy = float(model.numeric.call("energy", x, model.numeric.params()))
    assert energy == pytest.approx(0.5 * qdot @ mass(q) @ qdot + potential(q), rel=TOL, abs=TOL)


@pytest.mark.parametrize("name, form", CASES)
def test_constraint_residual_is_omega_times_qdot(models, name, form):
    model = models[name][form]
    mass, omega, _ = _reference(model.system)
    rng = np.random.default_rng(11)
    q, qdot = rng.uniform(-0.6, 0.6, model.system.n), rng.uniform(-1.0, 1.0, model.system.n)
    np.testing.assert_allclose(constraint_residual(model, q, qdot), omega(q) @ qdot, rtol=TOL, atol=TOL)


@pytest.mark.parametrize("form", ["reduced", "lagrange", "hamilton"])
def test_to_state_evaluates_one_compiled_function_per_model(models, monkeypatch, form):
    model = models["snakeboard"][form]
    assert initial_state_map(model) is initial_state_map(model)

    def generic_call(*args):
        raise AssertionError("to_state went through NumericModel.call")
    monkeypatch.setattr(NumericModel, "call", generic_call)
    q = np.array([0.0, 0.0, 0.2, 0.1, 0.3])
    _, omega, _ = _reference(model.system)
    qdot = scipy.linalg.null_space(omega(q)) @ np.array([0.4, -0.3, 0.2])
    assert to_state(model, q, qdot).shape == (len(model.state_names),)


@pytest.mark.parametrize("name", ["unicycle", "snakeboard"])
def test_both_dae_forms_report_the_same_constraint_gram(models, name):
    """S = ω M⁻¹ ωᵀ at one physical state from the Lagrangian and the Hamiltonian closed-loop
    pieces, against S from the system's expressions; the measure is det S / Π Sᵢᵢ."""
    system = models[name]["lagrange"].system
    mass, omega, _ = _reference(system)
    q, qdot = _consistent_state(system, omega)
    W = omega(q)
    S_ref = W @ np.linalg.solve(mass(q), W.T)
    for form in ("lagrange", "hamilton"):
        model = models[name][form]
        num = model.numeric
        x = ca.SX.sym("x", 2 * system.n)
        params = ca.SX.sym("params", len(num.param_names))
        point = LoopPoint(t_c=ca.SX.sym("t"), x=x, u=ca.SX.zeros(len(system.inputs)), params=params,
                          g_int=ca.SX(0, 1))
        out = model.loop_dynamics(point, Stabilisation())
        f = ca.Function("f", [x, params], [out.gram, out.measure, out.g])
        gram, measure, g = (np.asarray(v, dtype=float) for v in f(to_state(model, q, qdot), num.params()))
        np.testing.assert_allclose(gram.reshape(system.k, system.k, order="F"), S_ref, rtol=1e-10, atol=1e-12)
        assert measure.item() == pytest.approx(np.linalg.det(S_ref) / np.prod(np.diag(S_ref)), rel=1e-10)
        np.testing.assert_allclose(g.ravel(), 0.0, atol=1e-12)


def test_options_and_singular_set_texts(models):
    reduced = models["snakeboard"]["reduced"]
    problems = ReducedODE.dae_option_problems(True, Baumgarte)
    assert len(problems) == 2
    assert "reduced form is an ODE" in problems[0]
    assert ReducedODE.dae_option_problems(False, Stabilisation) == []
    assert ReducedODE.dae_option_problems(False, Projection, holonomic=True) == []
    assert LagrangianDAE.dae_option_problems(True, Baumgarte) == []
    assert HamiltonianDAE.dae_option_problems(True, Stabilisation) == []
    expected = "singular set: " + " or ".join(f"{e} = 0" for e in reduced.singular_set)
    assert reduced.singular_set_text() == expected
    assert models["snakeboard"]["lagrange"].singular_set_text() == (
        "ω M⁻¹ ωᵀ loses rank: the constraints become dependent")


def test_stabilisation_options_resolve_to_objects():
    """The option strings become objects once; Baumgarte's law adds 2αg + β²∫g to the residual."""
    assert stabilisation_named(None) == Stabilisation()
    assert stabilisation_named("projection").projects
    law = stabilisation_named("baumgarte", (2, 3))
    assert law == Baumgarte(alpha=2.0, beta=3.0)
    assert law.integral_states(2) == 2                         # β ≠ 0: the integrals ∫g are states
    assert Baumgarte(1.0, 0.0).integral_states(2) == Stabilisation().integral_states(2) == 0
    g, g_int, res = ca.SX.sym("g"), ca.SX.sym("g_int"), ca.SX.sym("r")
    value = ca.Function("f", [res, g, g_int], [law.feedback(res, g, g_int)])(0.5, 0.25, 0.125)
    assert float(value) == 0.5 + 2 * 2.0 * 0.25 + 3.0 ** 2 * 0.125


def test_derive_entry_returns_the_model_type(systems):
    model = derive(systems["unicycle"], "lagrange", use_cache=False)
    assert isinstance(model, LagrangianDAE)
    assert model.formulation == "lagrange"
    assert derive(systems["unicycle"], "hamilton", use_cache=False).formulation == "hamilton"
