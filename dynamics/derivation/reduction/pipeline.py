"""Steps 4–20 run in order on one arithmetic back end (:mod:`.arithmetic`): the part of the
20-step method shared by both forms of :class:`~.model.ReducedODE` (the explicit form on exact
rational functions or sympy, the implicit form on CasADi SX)."""
from __future__ import annotations

from ..system import TIME
from . import connection, equations, legendre, poisson
from .arithmetic import make_arithmetic
from .setup import Layout


def run_steps(F, lay: Layout) -> tuple[list, dict]:
    """Steps 4–20 on the arithmetic back end ``F``; returns (steps, outputs) with outputs
    ``qdot``, ``Pdot`` (lists of display values), ``X``, ``K``, ``h``, ``J_z``,
    ``momenta_of_velocity``, ``A``."""
    sy = lay.symbols()
    steps = [connection.momentum(F, lay, sy)]
    s5, con = connection.reconstruction(F, lay, sy)
    steps += [s5, connection.body_basis(F, lay, sy, con), connection.reduced_lagrangian(F, lay, sy, con),
              connection.constrained_lagrangian(F, lay, sy, con)]
    s10, Kinv = legendre.velocities(F, lay, sy, con)
    s11, h = legendre.hamiltonian(F, lay, sy, Kinv)
    steps += [legendre.legendre_transform(F, lay, sy, con), s10, s11]
    s12, _ = poisson.canonical_momenta(F, lay, sy, con)
    lie = poisson.lie_brackets(F, lay, con)
    s16, br = poisson.restricted_brackets(F, lay, sy, con, Kinv, lie)
    s17, J_z = poisson.structure(F, lay, sy, con, br["C"])
    steps += [s12, poisson.body_momentum(F, lay, sy, con), poisson.momenta_in_mu(F, lay, sy, con),
              poisson.brackets_in_mu(F, lay, sy, lie), s16, s17]
    s18, grad = equations.gradient(F, lay, sy, con, Kinv)
    s19, eqs = equations.equations(F, lay, sy, con, Kinv, br, grad)
    steps += [s18, s19, equations.fiber_velocities(F, lay, sy, eqs)]
    nP = len(sy.P)
    out = {"qdot": eqs["qdot"], "Pdot": eqs["Pdot"], "X": F.show(con.X, lay.n, nP),
           "K": F.show(con.K, nP, nP), "h": h, "J_z": J_z, "symbols": sy,
           "A_zero": all(F.is_zero(e) for r in con.A for e in r),
           "momenta_of_velocity": equations.momenta_of_velocity(F, lay, sy, con), "F": F}
    return steps, out


def arithmetic_for(kind, lay):
    """The back end ``kind`` for ``lay``: the steps' variables (q, q̇, momenta, inputs) and the
    time t of the forces, which the steps carry along but never differentiate."""
    s = lay.system
    sy = lay.symbols()
    syms = list(s.q) + list(s.q_dot) + sy.p + sy.P + sy.xi + sy.Om + sy.mu + list(s.input_symbols)
    return make_arithmetic(kind, [lay.M, lay.W, s.L, lay.V, s.force_vector(), lay.N, lay.g], syms, s.q,
                           time=(TIME,))
