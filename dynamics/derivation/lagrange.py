"""Euler–Lagrange equations with multipliers (thesis eq. 2.8) — a DAE.

    M(q) q̈ = F(q, q̇) + ω(q)ᵀ λ + τ(t, q, q̇, u),      ω(q) q̇ = 0,

with F = ∂L/∂q − (∂²L/∂q̇∂q) q̇ (Coriolis, centrifugal and potential forces).

Differentiation index: the constraint ω q̇ = 0 does not contain λ; one time derivative gives
ω q̈ + ω̇ q̇ = 0, which does (through q̈), and a second one gives λ̇: index 2 (as the thesis
says). The index-1 form solved by the simulators replaces the constraint with its derivative
and keeps ω q̇ = 0 as an invariant.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import sympy as sp

from nhgait.dynamics.derivation.cse_text import equation_lines
from nhgait.dynamics.derivation.input.notation import method_name, system_names

from .dae_model import DAEModel
from .system import System


@dataclass(frozen=True, eq=False, repr=False)
class LagrangianDAE(DAEModel):
    """M(q)q̈ = F(q, q̇) + ωᵀλ + τ, ωq̇ = 0 (eq. 2.8).

    State ordering (``state_names``): x = (q_1 … q_n, q̇_1 … q̇_n) — coordinates then velocities
    named ``<q>_dot``; algebraic variables λ_1 … λ_k (``lambda1`` …), one per constraint.

    Attributes: ``M`` (n×n), ``F`` (n×1), ``omega`` (k×n), ``omega_dot_qdot`` = ω̇q̇ (k×1),
    ``tau`` (n×1), ``energy`` = T + V.
    """

    M: sp.Matrix
    F: sp.Matrix
    omega: sp.Matrix
    omega_dot_qdot: sp.Matrix
    tau: sp.Matrix
    energy: sp.Expr
    formulation = "lagrange"
    velocity_part = "velocities q̇"

    def initial_state(self, q, qdot, params):
        return ca.vertcat(q, qdot)

    def constraint_gram(self, x, params):
        numeric = self.numeric
        n = numeric.n_coordinates
        omega = ca.jacobian(numeric["constraint"](x, params), x[n:])
        return ca.mtimes(omega, ca.solve(numeric["mass"](x, params), omega.T))


    def equations(self) -> list:
        """The n dynamic equations and k constraints as sympy Eq objects."""
        qdd = sp.Matrix([sp.Symbol(f"{c}_ddot") for c in self.system.coordinates])
        lam = sp.Matrix(self.multipliers) if self.multipliers else sp.zeros(0, 1)
        lhs = self.M * qdd
        rhs = self.F + self.omega.T * lam + self.tau
        eqs = [sp.Eq(a, b) for a, b in zip(lhs, rhs, strict=True)]
        eqs += [sp.Eq(c, 0) for c in self.omega * sp.Matrix(self.system.q_dot)]
        return eqs

    def to_text(self, cse: bool | None = None) -> str:
        """The equations as text; ``cse``: name repeated sub-expressions once (None: when long)."""
        lines = [f"Euler–Lagrange equations with multipliers of {self.system.name} "
                 f"(index-{self.differentiation_index} DAE)", *self.system.holonomic_lines()]
        eqs = self.equations()
        return "\n".join(lines + equation_lines([e.lhs for e in eqs], [e.rhs for e in eqs], cse))

    @cached_property
    def numeric(self):
        """CasADi/numpy functions of this model
        (:func:`~nhgait.dynamics.numerics.numeric_model.compile_lagrange`)."""
        if self.compiled is not None:
            return self.compiled
        from ..numerics.numeric_model import compile_lagrange
        return compile_lagrange(self)


def derive_lagrangian(system: System) -> LagrangianDAE:
    """Derive the Euler–Lagrange DAE (eq. 2.8) of ``system``."""
    t0 = time.perf_counter()
    q, qd = sp.Matrix(system.q), sp.Matrix(system.q_dot)
    L = system.L
    M = system.mass_matrix()
    dLdqd = sp.Matrix([sp.diff(L, v) for v in qd])
    F = sp.Matrix([sp.diff(L, x) for x in q]) - dLdqd.jacobian(q) * qd
    W = system.omega()
    k = system.k
    Wdot_qd = (W * qd).jacobian(q) * qd if k else sp.zeros(0, 1)
    T = (qd.T * M * qd)[0, 0] / 2
    energy = sp.expand(T + system.potential())
    lam = tuple(sp.Symbol(method_name(f"lambda{i + 1}", system_names(system)), real=True) for i in range(k))
    names = tuple(system.coordinates) + tuple(v.name for v in system.q_dot)
    return LagrangianDAE(system=system, M=M, F=F.applyfunc(sp.expand), omega=W,
                         omega_dot_qdot=Wdot_qd.applyfunc(sp.expand), tau=system.force_vector(),
                         energy=energy, state=tuple(q) + tuple(qd), state_names=names,
                         multipliers=lam, derive_time_s=time.perf_counter() - t0)
