"""The steps of the reduction one module at a time (dynamics/derivation/reduction: ``setup`` steps
1–3, ``connection`` 4–8, ``poisson`` 12–17, ``equations`` 18–20, run in order by
``pipeline``) on the Chaplygin sleigh, against references that are not the code:

* sympy's own algebra on the scene's L and ω (M = ∂²L/∂q̇², the momenta ∂L/∂q̇, K = XᵀMX);
* the sleigh's closed forms (Bloch, *Nonholonomic Mechanics and Control*, §1.7; Neimark &
  Fufaev): with v the forward speed of the blade and ω = θ̇, the locked inertia
  K = diag(m, I_c + m a²), the momenta P = (m v, (I_c + m a²) ω), the bracket
  {P₁, P₂} = m a ω and the equations m v̇ = m a ω² + F, (I_c + m a²) ω̇ = −m a v ω + τ;
* KanesMethod (tests/oracles.py, built from the sleigh's bodies and its no-slip velocity):
  along any consistent state, Ṗ = ∂P/∂q q̇ + ∂P/∂q̇ q̈_Kane and the reconstruction gives q̇ back.

The steps run on the exact back end the derivation uses for a small system (``ring``).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import builtin
from nhgait.dynamics.derivation.reduction import connection, equations, pipeline, poisson, setup

#: the reduced equations are exact rational functions: agreement to rounding
TOL = 1e-10


@pytest.fixture(scope="module")
def sleigh():
    """The sleigh's steps: 1–3 from ``setup``, 4–20 by ``pipeline`` (``run``), and the records
    of steps 4, 8, 16 and 19 computed again by calling each module's own step function."""
    system = builtin("chaplygin_sleigh")
    layout, first = setup.choose_layout(system)
    run = pipeline.run_steps(pipeline.arithmetic_for("ring", layout), layout)
    steps = {s.number: s for s in (*first, *run.steps)}
    m, I_c, a = sp.symbols("m I_c a", real=True)
    return system, layout, run, steps, (m, I_c, a), _one_by_one(layout)


def _one_by_one(layout) -> dict:
    """Steps 4, 8, 16 and 19 by the step functions of ``connection``, ``poisson`` and
    ``equations`` (with ``legendre``'s K⁻¹), on a fresh exact back end."""
    from nhgait.dynamics.derivation.reduction import legendre
    arith, symbols = pipeline.arithmetic_for("ring", layout), layout.symbols()
    step4 = connection.momentum(arith, layout, symbols)
    _, rec = connection.reconstruction(arith, layout, symbols)
    _, xi_c = connection.body_basis(arith, layout, symbols, rec)
    _, l_red = connection.reduced_lagrangian(arith, layout, symbols)
    step8, K = connection.constrained_lagrangian(arith, layout, symbols, rec)
    conn = connection.Connection.of(rec, xi_c=xi_c, l_red=l_red, K=K)
    _, Kinv = legendre.velocities(arith, layout, symbols, conn)
    lie = poisson.lie_brackets(arith, layout, conn)
    step16, brackets = poisson.restricted_brackets(arith, layout, symbols, conn, Kinv, lie)
    _, grad = equations.gradient(arith, layout, symbols, conn, Kinv)
    inputs = equations.MomentumInputs(conn, Kinv, brackets, grad)
    step19, _ = equations.equations(arith, layout, symbols, inputs)
    return {4: step4, 8: step8, 16: step16, 19: step19}


def _zero(expr) -> bool:
    return sp.simplify(sp.Matrix(expr)) == sp.zeros(*sp.Matrix(expr).shape)


def test_steps_1_to_3_state_the_metric_and_the_distribution_from_the_lagrangian(sleigh):
    system, layout, _, steps, _, _ = sleigh
    q_dot = sp.Matrix(system.q_dot)
    M = sp.hessian(system.L, q_dot)                          # eq. 2.5, by sympy
    assert _zero(steps[1].items["M"] - M)
    assert _zero(layout.M - M)
    omega = system.omega()
    D = steps[2].items["D"]
    assert _zero(omega * D) and D.rank() == system.n - system.k       # D = null ω, dimension n − k
    assert layout.fiber == ("x", "y", "theta") and layout.shape == ()  # SE(2) acts on the whole q
    assert _zero(omega * layout.N)                                      # S_q = D here: ξ_Q ∈ D
    assert _zero(setup.body_omega(omega, layout.g, layout.si) - sp.simplify(omega * layout.g))
    assert _zero(layout.Wb - sp.Matrix([[0, 1, 0]]))        # the blade: no sideways body velocity


def test_steps_4_to_8_give_the_momenta_and_the_locked_inertia_in_closed_form(sleigh):
    system, layout, run, steps, (m, I_c, a), alone = sleigh
    dL = sp.Matrix([system.L.diff(v) for v in system.q_dot])
    for record in (steps[4], alone[4]):                       # p_i = <∂L/∂q̇, ξ_Q^i> (eq. 3.9)
        assert _zero(record.items["p"] - layout.N.T * dL)
    X = run.X
    assert _zero(system.omega() * X)                          # the lifts lie in D
    assert _zero(run.K - X.T * layout.M * X)                  # K = XᵀMX, by sympy
    assert _zero(run.K - sp.diag(m, I_c + m * a ** 2))        # the sleigh's locked inertia
    assert _zero(steps[8].items["K"] - run.K) and _zero(alone[8].items["K"] - run.K)
    x_dot, y_dot, th_dot = system.q_dot
    th = system.q[2]
    momenta = sp.Matrix(run.momenta_of_velocity)
    assert _zero(momenta - X.T * layout.M * sp.Matrix(system.q_dot))       # P = XᵀM q̇
    on_D = {y_dot: x_dot * sp.tan(th)}                         # ω q̇ = 0: ẏ = tan θ ẋ
    v = x_dot / sp.cos(th)                                     # the blade's forward speed there
    assert _zero(momenta.xreplace(on_D) - sp.Matrix([m * v, (I_c + m * a ** 2) * th_dot]))


def test_steps_12_to_17_give_an_antisymmetric_structure_with_the_sleighs_bracket(sleigh):
    _, _, run, steps, (m, I_c, a), alone = sleigh
    J = run.J_z
    assert _zero(J + J.T)                                      # an almost-Poisson structure
    assert _zero(J[:3, 3:] - run.X)                            # q̇ = X ∂h/∂P
    p1, p2 = run.symbols.P
    omega = p2 / (I_c + m * a ** 2)
    for record in (steps[16], alone[16]):                     # {P₁, P₂} = m a ω
        assert _zero(record.items["C"] - sp.Matrix([[0, m * a * omega], [-m * a * omega, 0]]))


def test_steps_18_to_20_are_the_sleighs_equations(sleigh):
    system, _, run, steps, (m, I_c, a), alone = sleigh
    p1, p2 = run.symbols.P
    F, tau = system.input_symbols
    th = system.q[2]
    v, omega = p1 / m, p2 / (I_c + m * a ** 2)
    rates = sp.Matrix([F + m * a * omega ** 2, tau - m * a * v * omega])
    assert _zero(sp.Matrix(run.Pdot) - rates) and _zero(alone[19].items["P_dot"] - rates)
    assert _zero(sp.Matrix(run.qdot) - sp.Matrix([v * sp.cos(th), v * sp.sin(th), omega]))
    assert _zero(steps[20].items["s_dot"] - sp.Matrix(run.qdot))


def test_the_pipeline_agrees_with_kanes_method_at_random_consistent_states(sleigh):
    """Ṗ of the steps against d/dt P(q, q̇) along KanesMethod's q̈, and q̇(q, P(q, q̇)) = q̇, at
    20 random consistent states with random inputs (the sleigh's own parameter values)."""
    from oracles import oracle
    system, _, run, _, _, _ = sleigh
    kane = oracle("chaplygin_sleigh")
    params = {sp.Symbol(k, real=True): v for k, v in system.parameters.items()}
    q, qd, u, P = list(system.q), list(system.q_dot), list(system.input_symbols), run.symbols.P
    qdd = sp.symbols("qdd0:3", real=True)
    momenta = sp.Matrix(run.momenta_of_velocity).xreplace(params)
    rate = momenta.jacobian(q) * sp.Matrix(qd) + momenta.jacobian(qd) * sp.Matrix(qdd)
    f_rate = sp.lambdify([q, qd, qdd], rate, "numpy")
    f_momenta = sp.lambdify([q, qd], momenta, "numpy")
    f_pdot = sp.lambdify([q, P, u], sp.Matrix(run.Pdot).xreplace(params), "numpy")
    f_qdot = sp.lambdify([q, P], sp.Matrix(run.qdot).xreplace(params), "numpy")
    kp = np.array([system.parameters[name] for name in kane.parameters])
    rng = np.random.default_rng(3)
    for _ in range(20):
        qv = rng.uniform(-1.2, 1.2, 3)
        qdv = kane.consistent_qdot(qv, rng.uniform(-1.0, 1.0, 2), kp)
        uv = rng.uniform(-2.0, 2.0, 2)
        uk = np.array([uv[system.inputs.index(name)] for name in kane.inputs])
        qddv = kane.qddot(qv, qdv, uk, kp)
        Pv = np.ravel(f_momenta(qv, qdv))
        np.testing.assert_allclose(np.ravel(f_qdot(qv, Pv)), qdv, rtol=0, atol=TOL)
        np.testing.assert_allclose(np.ravel(f_pdot(qv, Pv, uv)), np.ravel(f_rate(qv, qdv, qddv)),
                                   rtol=0, atol=TOL * (1 + np.abs(qddv).max()))
