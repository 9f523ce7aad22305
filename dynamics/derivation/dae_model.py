"""What the two DAE forms (:class:`~.lagrange.LagrangianDAE`, :class:`~.hamilton.HamiltonianDAE`)
hold besides their equations, and the vocabulary they share, stated once: :class:`DAEModel`."""
from __future__ import annotations

import abc
from dataclasses import dataclass, field

import casadi as ca

from nhgait.dynamics.reprs import ModelDisplay

from .formulation_base import Formulation, LoopDynamics
from .system import System


@dataclass(frozen=True, eq=False, repr=False, kw_only=True)
class DAEModel(ModelDisplay, Formulation):
    """The fields every DAE form has: ``system``; ``state`` and ``state_names`` (x = (q, q̇) or
    (q, p), 2n entries); ``multipliers`` λ_1 … λ_k, one per constraint; the derivation time; the
    compiled functions when they came with the model (the cache) and the cache ``provenance``.
    Both forms are index-2 DAEs (see each form's module docstring).

    The vocabulary both forms share (:class:`~.formulation_base.Formulation`): x = (q, v) with
    2n entries, k multipliers λ solved from the differentiated constraint (index reduction, or
    Baumgarte's ġ + 2αg + β²∫g = 0), and the singular-set measure det S / Π Sᵢᵢ (Hadamard
    ratio) of S = ω M⁻¹ ωᵀ, the matrix λ is solved with."""

    system: System
    state: tuple
    state_names: tuple
    multipliers: tuple
    derive_time_s: float = 0.0
    compiled: object = field(default=None, repr=False)
    provenance: object = field(default=None, repr=False)

    differentiation_index = 2
    has_multipliers = True
    dae_options_apply = True
    has_constraint_gram = True
    specialised_for_integration = False

    def multiplier_count(self) -> int:
        return len(self.multipliers)

    def constraint_residual(self, q, qdot, params):
        return self.numeric["constraint"](self.initial_state(q, qdot, params), params)

    @abc.abstractmethod
    def constraint_gram(self, x, params):
        """S = ω M⁻¹ ωᵀ (k×k) from the documented functions ``constraint`` and ``mass``."""

    def loop_dynamics(self, point, stabilisation):
        num = self.numeric
        k = self.multiplier_count()
        x, u, params, t_c = point.x, point.u, point.params, point.t_c
        g = num["constraint"](x, params)
        if stabilisation.feeds_back:          # e.g. ġ + 2αg + β²∫g = 0, solved for λ
            lam_sym = ca.SX.sym("lam", k)
            res = stabilisation.feedback(num["dae_g"](t_c, x, lam_sym, u, params), g, point.g_int)
            S_lam = ca.jacobian(res, lam_sym)
            lam = -ca.solve(S_lam, ca.substitute(res, lam_sym, ca.SX.zeros(k)))
            xdot = num["dae_f"](t_c, x, lam, u, params)
        else:
            xdot, lam = num["ode"](t_c, x, u, params)
        S = self.constraint_gram(x, params) if k else ca.SX(0, 0)
        return LoopDynamics(xdot=xdot, lam=lam, g=g, measure=_hadamard_ratio(S, k) if k else ca.SX(1),
                            gram=ca.vec(S))

    def singular_set_text(self) -> str:
        return "ω M⁻¹ ωᵀ loses rank: the constraints become dependent"


def _hadamard_ratio(S, k):
    """det S / Π Sᵢᵢ: 1 for orthogonal constraint rows, 0 where they become dependent."""
    diag = 1
    for i in range(k):
        diag = diag * S[i, i]
    return ca.det(S) / (diag + 1e-300)
