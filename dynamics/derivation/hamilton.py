"""Hamilton's equations with multipliers (thesis eqs. 2.19–2.24) — a DAE.

    q̇ = ∂H/∂p,   ṗ = −∂H/∂q + ω(q)ᵀλ + τ,   ω(q) ∂H/∂p = 0,
    H(q, p) = ½ pᵀ M(q)⁻¹ p + V(q),   p = ∂L/∂q̇ = M(q) q̇.

Differentiation index: the constraint ω ∂H/∂p = 0 does not contain λ; differentiating once
gives ω M⁻¹ ωᵀ λ + (terms in q, p, τ) = 0, solvable for λ, and a second derivative gives λ̇.
The index is therefore 2, the same as the Lagrangian form — not 1 as the thesis states in
§3.1 and §3.2.6 (see docs/thesis-errata.md). Both forms are related by the change of variables
p = M q̇, which cannot change the index.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import sympy as sp

from nhgait.dynamics.derivation.cse_text import equation_lines
from nhgait.dynamics.derivation.input.notation import method_name, system_names

from ..algebra.trig import TIDY_NODES, tidy, tree_size
from .dae_model import DAEModel
from .system import System


@dataclass(frozen=True, eq=False, repr=False)
class HamiltonianDAE(DAEModel):
    """q̇ = ∂H/∂p, ṗ = −∂H/∂q + ωᵀλ + τ, ω∂H/∂p = 0 (eqs. 2.20, 2.24).

    State ordering (``state_names``): x = (q_1 … q_n, p_1 … p_n) — coordinates then canonical
    momenta named ``p_<q>``; algebraic variables λ_1 … λ_k.

    Attributes: ``H``, ``Minv`` (n×n), ``dH_dq``, ``dH_dp`` (n×1), ``omega`` (k×n),
    ``tau`` (n×1, in (t, q, p, u): velocities replaced by ∂H/∂p).
    """

    H: sp.Expr
    Minv: sp.Matrix
    dH_dq: sp.Matrix
    dH_dp: sp.Matrix
    omega: sp.Matrix
    tau: sp.Matrix
    formulation = "hamilton"
    velocity_part = "canonical momenta p = M(q) q̇"

    def initial_state(self, q, qdot, params):
        mass = self.numeric["mass"](ca.vertcat(q, ca.SX.zeros(q.shape[0])), params)
        return ca.vertcat(q, ca.mtimes(mass, qdot))

    def constraint_gram(self, x, params):
        numeric = self.numeric
        n = numeric.n_coordinates
        omega_minv = ca.jacobian(numeric["constraint"](x, params), x[n:])    # ω M⁻¹ (g = ω M⁻¹ p)
        return ca.mtimes(ca.mtimes(omega_minv, numeric["mass"](x, params)), omega_minv.T)


    @property
    def momenta(self) -> tuple[sp.Symbol, ...]:
        return self.state[self.system.n:]

    def equations(self) -> list:
        lam = sp.Matrix(self.multipliers) if self.multipliers else sp.zeros(0, 1)
        n = self.system.n
        eqs = [sp.Eq(sp.Symbol(f"{nm}_dot"), e)
               for nm, e in zip(self.state_names[:n], self.dH_dp, strict=True)]
        pd = -self.dH_dq + self.omega.T * lam + self.tau
        eqs += [sp.Eq(sp.Symbol(f"{nm}_dot"), e) for nm, e in zip(self.state_names[n:], pd, strict=True)]
        eqs += [sp.Eq(c, 0) for c in self.omega * self.dH_dp]
        return eqs

    def to_text(self, cse: bool | None = None) -> str:
        """The equations as text; ``cse``: name repeated sub-expressions once (None: when long)."""
        lines = [f"Hamilton's equations with multipliers of {self.system.name} "
                 f"(index-{self.differentiation_index} DAE)", *self.system.holonomic_lines()]
        eqs = self.equations()
        return "\n".join(lines + equation_lines([sp.Symbol("H"), *(e.lhs for e in eqs)],
                                                 [self.H, *(e.rhs for e in eqs)], cse))

    @cached_property
    def numeric(self):
        """CasADi/numpy functions of this model
        (:func:`~nhgait.dynamics.numerics.numeric_model.compile_hamilton`)."""
        if self.compiled is not None:
            return self.compiled
        from ..numerics.numeric_model import compile_hamilton
        return compile_hamilton(self)


def _inverse_metric(M: sp.Matrix) -> sp.Matrix:
    """M(q)⁻¹ = adj(M)/det(M), each entry in trig normal form.

    The cofactors and the determinant come from Berkowitz's division-free algorithm, so each
    entry is one fraction of polynomials and its normal form one cancellation; an LU inverse
    nests the fractions of every elimination step, whose normal form grows explosively for a
    dense metric (minutes against about a second for the roller racer and a cart with a
    trailer: docs/benchmarks.md, "Measured numbers behind design choices")."""
    det = tidy(M.det(method="berkowitz"))
    return (M.adjugate(method="berkowitz") / det).applyfunc(tidy)


def _dH_dq(M: sp.Matrix, V, q: sp.Matrix, v: sp.Matrix) -> sp.Matrix:
    """∂H/∂q_i = ∂V/∂q_i − ½ vᵀ (∂M/∂q_i) v with v = M⁻¹p = ∂H/∂p (eq. 2.22), from
    ∂(M⁻¹)/∂q_i = −M⁻¹ (∂M/∂q_i) M⁻¹: the small ∂M/∂q_i instead of differentiating M⁻¹'s
    entries, whose derivatives a configuration-dependent 5 × 5 metric (a sleigh carrying a
    mass on a ring) grew to 3 million nodes in 22 s after an expansion that did not end."""
    return sp.Matrix([sp.diff(V, x) - (v.T * M.diff(x) * v)[0, 0] / 2 for x in q])


def derive_hamiltonian(system: System) -> HamiltonianDAE:
    """Derive the Hamiltonian DAE (eqs. 2.19–2.24) of ``system``."""
    t0 = time.perf_counter()
    q = sp.Matrix(system.q)
    taken = system_names(system)           # a user's p_x or lambda1 never meets the method's
    p = sp.Matrix([sp.Symbol(method_name(f"p_{c}", taken), real=True) for c in system.coordinates])
    M = system.mass_matrix()
    Minv = _inverse_metric(M) if any(e.free_symbols & set(system.q) for e in M) else tidy(M.inv())
    V = system.potential()
    T = (p.T * Minv * p)[0, 0] / 2
    H = (sp.expand(T) if tree_size(T, TIDY_NODES) <= TIDY_NODES else T) + V
    dH_dp = Minv * p
    dH_dq = _dH_dq(M, V, q, dH_dp)
    tau = system.force_vector().xreplace({v: dH_dp[i] for i, v in enumerate(system.q_dot)})
    lam = tuple(sp.Symbol(method_name(f"lambda{i + 1}", taken), real=True) for i in range(system.k))
    names = tuple(system.coordinates) + tuple(s.name for s in p)
    return HamiltonianDAE(system=system, H=H, Minv=Minv, dH_dq=dH_dq, dH_dp=dH_dp,
                          omega=system.omega(), tau=tau, state=tuple(q) + tuple(p),
                          state_names=names, multipliers=lam,
                          derive_time_s=time.perf_counter() - t0)
