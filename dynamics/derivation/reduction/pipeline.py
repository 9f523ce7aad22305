"""Steps 4–20 run in order on one arithmetic back end (:mod:`.arithmetic`): the part of the
20-step method shared by both forms of :class:`~.model.ReducedODE` (the explicit form on exact
rational functions or sympy, the implicit form on CasADi SX)."""
from __future__ import annotations

from dataclasses import dataclass

from ..system import TIME
from . import connection as steps_4_8
from . import equations as steps_18_20
from . import legendre as steps_9_11
from . import poisson as steps_12_17
from .arithmetic import make_arithmetic
from .setup import Layout


@dataclass(frozen=True, eq=False)
class StepsRun:
    """Steps 4–20 run on one back end: the :class:`~nhgait.dynamics.derivation.steps.Step`
    records and what the models are assembled from.

    qdot, Pdot : q̇ (n) and Ṗ (nP) as display values of the back end; X, K : the basis and
    K = XᵀMX shown; h : the Hamiltonian; J_z : the structure matrix in z = (q, P);
    momenta_of_velocity : P = XᵀM(q)q̇ (nP values linear in q̇); A_zero : the local connection
    vanishes; symbols : the steps' symbols; arithmetic : the back end (its ``sym`` map for the
    CasADi form).
    """

    steps: tuple
    qdot: list
    Pdot: list
    X: object
    K: object
    h: object
    J_z: object
    momenta_of_velocity: list
    A_zero: bool
    symbols: object
    arithmetic: object


def run_steps(arith, layout: Layout) -> StepsRun:
    """Steps 4–20 on the arithmetic back end ``arith`` (see :class:`StepsRun`)."""
    symbols = layout.symbols()
    step4 = steps_4_8.momentum(arith, layout, symbols)
    step5, reconstruction = steps_4_8.reconstruction(arith, layout, symbols)
    step6, xi_c = steps_4_8.body_basis(arith, layout, symbols, reconstruction)
    step7, l_red = steps_4_8.reduced_lagrangian(arith, layout, symbols)
    step8, K = steps_4_8.constrained_lagrangian(arith, layout, symbols, reconstruction)
    connection = steps_4_8.Connection.of(reconstruction, xi_c=xi_c, l_red=l_red, K=K)
    step10, Kinv = steps_9_11.velocities(arith, layout, symbols, connection)
    step11, h = steps_9_11.hamiltonian(arith, layout, symbols, Kinv)
    step9 = steps_9_11.legendre_transform(arith, layout, symbols, connection)
    step12, _ = steps_12_17.canonical_momenta(arith, layout, symbols, connection)
    lie = steps_12_17.lie_brackets(arith, layout, connection)
    step16, brackets = steps_12_17.restricted_brackets(arith, layout, symbols, connection, Kinv, lie)
    step17, J_z = steps_12_17.structure(arith, layout, symbols, connection, brackets.C)
    step13 = steps_12_17.body_momentum(arith, layout, symbols, connection)
    step14 = steps_12_17.momenta_in_mu(arith, layout, symbols, connection)
    step15 = steps_12_17.brackets_in_mu(arith, layout, symbols, lie)
    step18, grad = steps_18_20.gradient(arith, layout, symbols, connection, Kinv)
    step19, eqs = steps_18_20.equations(arith, layout, symbols,
                                        steps_18_20.MomentumInputs(connection, Kinv, brackets, grad))
    step20 = steps_18_20.fiber_velocities(arith, layout, symbols, eqs)
    nP = len(symbols.P)
    X_shown, K_shown = arith.show(connection.X, layout.n, nP), arith.show(connection.K, nP, nP)
    A_zero = all(arith.is_zero(e) for r in connection.A for e in r)
    momenta_of_velocity = steps_18_20.momenta_of_velocity(arith, layout, symbols, connection)
    return StepsRun(
        steps=(step4, step5, step6, step7, step8, step9, step10, step11, step12, step13, step14, step15,
               step16, step17, step18, step19, step20),
        qdot=eqs.qdot, Pdot=eqs.Pdot, X=X_shown, K=K_shown, h=h, J_z=J_z,
        momenta_of_velocity=momenta_of_velocity, A_zero=A_zero, symbols=symbols, arithmetic=arith)


def arithmetic_for(kind, layout, budget=None):
    """The back end ``kind`` for ``layout``: the steps' variables (q, q̇, momenta, inputs) and the
    time t of the forces, which the steps carry along but never differentiate; ``budget``: the
    exact ring's work budget (None: no limit)."""
    system, symbols = layout.system, layout.symbols()
    variables = (list(system.q) + list(system.q_dot) + symbols.p + symbols.P + symbols.xi + symbols.Om
                 + symbols.mu
                 + list(system.input_symbols))
    expressions = [layout.M, layout.W, system.L, layout.V, system.force_vector(), layout.N, layout.g]
    return make_arithmetic(kind, expressions, variables, system.q, time=(TIME,), budget=budget)
