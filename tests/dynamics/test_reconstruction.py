"""The reconstruction equation ξ = −A(r)ṙ + Γ(r)pᵀ and the momentum equation
ṗ = ṙᵀσ_rr ṙ + ṙᵀσ_rp p + pᵀσ_pp p (thesis Table 2.1, eq. 2.47) against the independent
KanesMethod oracle (tests/oracles.py): admissible velocities and accelerations from the oracle,
the momentum p = ⟨∂L/∂q̇, ξ_Q⟩ differentiated from the Lagrangian by sympy. A sign flipped in A,
Γ or σ fails these tests (the snakeboard has A ≠ 0 and σ_rr, σ_rp ≠ 0)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from oracles import oracle

from nhgait.dynamics import derive, load_scene
from nhgait.dynamics.derivation.reduction import derive_reduced
from nhgait.dynamics.geometry import reconstruction
from nhgait.dynamics.geometry.reconstruction import ReconstructionValues

SCENES = Path(__file__).resolve().parents[1] / "scenes"
#: relative agreement with the oracle (double precision through two linear solves)
TOL = 1e-9


def _momentum_functions(model):
    """p(q, q̇) = Nᵀ ∂L/∂ṡ (the definition, step 4) and its time derivative along (q̇, q̈), from
    the Lagrangian by sympy differentiation (no step of the reduction used)."""
    system, layout = model.system, model.layout
    dL = sp.Matrix([sp.diff(system.L, system.q_dot[i]) for i in layout.si])
    p = layout.N.T * dL
    qdd = sp.symbols(f"qdd0:{system.n}")
    pdot = p.jacobian(system.q) * sp.Matrix(system.q_dot) + p.jacobian(system.q_dot) * sp.Matrix(qdd)
    args = [system.q, system.q_dot, qdd, system.param_symbols]
    return sp.lambdify(args, p, "numpy"), sp.lambdify(args, pdot, "numpy")


def _states(name, count=6, seed=3):
    orc = oracle(name)
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = rng.uniform(-1.0, 1.0, len(orc.coordinates))
        yield orc, q, rng.uniform(-1.0, 1.0, len(orc.independent))


def _check(model, eq, name, values=None):
    system, layout = model.system, model.layout
    pv = system.param_vector()
    p_of, pdot_of = _momentum_functions(model)
    g = sp.lambdify([system.q, system.param_symbols], layout.g, "numpy")
    for orc, q, qi in _states(name):
        po = np.array([system.parameters[p] for p in orc.parameters])
        qd = orc.consistent_qdot(q, qi, po)
        qdd = orc.qddot(q, qd, np.zeros(len(orc.inputs)), po)
        val = eq.evaluate(q) if values is None else values(eq.evaluate(q))
        rdot = qd[list(layout.free)]
        p = np.asarray(p_of(q, qd, qdd, pv), dtype=float).ravel()
        xi = np.linalg.solve(np.asarray(g(q, pv), dtype=float), qd[list(layout.si)])
        predicted = -val.A @ rdot + val.Gamma @ p
        assert np.allclose(predicted, xi, rtol=TOL, atol=TOL * max(1.0, np.abs(xi).max())), (q, predicted, xi)
        pdot = np.asarray(pdot_of(q, qd, qdd, pv), dtype=float).ravel()
        rate = np.array([rdot @ val.sigma_rr[a] @ rdot + rdot @ val.sigma_rp[a] @ p + p @ val.sigma_pp[a] @ p
                         for a in range(len(p))])
        assert np.allclose(rate, pdot, rtol=TOL, atol=TOL * max(1.0, np.abs(pdot).max())), (q, rate, pdot)


@pytest.mark.parametrize("name", ["snakeboard", "chaplygin_sleigh", "unicycle"])
def test_reconstruction_matches_the_kane_oracle(name):
    model = derive(load_scene(name).system, "reduced")
    eq = reconstruction(model)
    assert eq.symbolic
    _check(model, eq, name)


def test_snakeboard_is_mixed_and_its_implicit_form_agrees_with_the_oracle():
    system = load_scene("snakeboard").system
    model = derive_reduced(system, form="implicit")
    eq = reconstruction(model)
    assert (eq.classification, eq.fiber, eq.shape, eq.momenta) == ("mixed", ("x", "y", "theta"),
                                                                   ("psi", "phi"), ("p",))
    assert not eq.symbolic and eq.equation == "2.47"
    _check(model, eq, "snakeboard")


@pytest.mark.parametrize("field", ["A", "sigma_rr", "sigma_rp"])
def test_a_flipped_sign_fails(field):
    """The check above is sharp: the snakeboard with one matrix negated disagrees with the oracle."""
    model = derive(load_scene("snakeboard").system, "reduced")
    eq = reconstruction(model)

    def flipped(val: ReconstructionValues):
        return dataclasses.replace(val, **{field: -getattr(val, field)})
    with pytest.raises(AssertionError):
        _check(model, eq, "snakeboard", values=flipped)


def test_table_types_and_text():
    sleigh = reconstruction(derive(load_scene("chaplygin_sleigh").system, "reduced"))
    assert sleigh.classification == "purely dynamic" and sleigh.shape == ()
    text = reconstruction(derive(load_scene("snakeboard").system, "reduced")).to_text()
    assert "thesis Table 2.1: mixed" in text and "A(r)[ξ1, psi_dot]" in text and "dp/dt" in text
    snake = reconstruction(derive(load_scene(str(SCENES / "snake3.toml")).system, "reduced"))
    assert snake.classification == "principally kinematic" and snake.momenta == ()


def test_purely_mechanical_connection_is_zero_momentum():
    """ξ = −A(r)ṙ (eq. 2.49) of a free-floating two-link robot: at zero momentum ∂L/∂ṡ = 0,
    solved for ṡ from the Lagrangian by sympy (the conservation law, not a step of the reduction)."""
    model = derive(load_scene(str(SCENES / "free_two_link.toml")).system, "reduced")
    system, layout = model.system, model.layout
    eq = reconstruction(model)
    assert eq.classification == "purely mechanical" and eq.shape == ("alpha",)
    sdot = [system.q_dot[i] for i in layout.si]
    momentum = sp.Matrix([sp.diff(system.L, v) for v in sdot])
    rng = np.random.default_rng(5)
    for _ in range(4):
        q, alpha_dot = rng.uniform(-1.0, 1.0, system.n), rng.uniform(-1.0, 1.0)
        values = dict(zip(system.q, q, strict=True)) | dict(zip(system.param_symbols, system.param_vector(),
                                                               strict=True)) | {system.q_dot[3]: alpha_dot}
        solved = sp.solve(list(momentum.xreplace(values)), sdot, dict=True)[0]
        sd = np.array([float(solved[v]) for v in sdot])
        g = np.array(layout.g.xreplace(values).evalf(), dtype=float)
        xi = np.linalg.solve(g, sd)
        assert np.allclose(-eq.evaluate(q).A @ [alpha_dot], xi, rtol=TOL, atol=TOL)
