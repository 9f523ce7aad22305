"""One vocabulary for the three equation forms: :class:`FormulationProtocol`.

As ``MethodBase`` does for sympy.physics.mechanics' methods, one abstract base names what
every formulation provides, and one frozen object per formulation implements it:
:data:`REDUCED`, :data:`LAGRANGE`, :data:`HAMILTON`. Code that works with any derived model asks
the model's protocol (:func:`protocol_of`, or :func:`protocol_named` for a formulation's name)
instead of comparing ``model.formulation`` with a string.

What a protocol owns
--------------------
* the derivation entry and the model type: :meth:`~FormulationProtocol.derive`,
  :attr:`~FormulationProtocol.model_type`;
* the state layout: :meth:`~FormulationProtocol.state_layout` (the names of x, x[:n] = q, what
  x[n:] holds, the number of multipliers λ);
* the initial-state map (q, q̇) → x, the constraint residual ω(q)q̇ and the measure of the
  configuration check, as CasADi expressions (:mod:`.states` compiles them into one Function
  per model);
* what the closed loop needs: ẋ, λ, the constraint residual, the singular-set measure and the
  constraint Gram matrix S = ω M⁻¹ ωᵀ (:meth:`~FormulationProtocol.loop_dynamics`);
* the sentence that names the singular set, and whether the DAE options (``dae="idas"``,
  ``stabilization``) apply, with the problems of a request that sets them on an ODE.

State layouts (n coordinates, k constraints, d = n − k − (free shape velocities) momenta)
-----------------------------------------------------------------------------------------
* reduced:  z = (q_1 … q_n, P_1 … P_d, P̃_1 …), 2n − k entries; P = Xᵀ M(q) q̇ (Tables
  3.2–3.3); no multipliers;
* lagrange: x = (q_1 … q_n, q̇_1 … q̇_n), 2n entries; λ_1 … λ_k;
* hamilton: x = (q_1 … q_n, p_1 … p_n), 2n entries, p = M(q) q̇; λ_1 … λ_k.

The protocols sit above the model modules: they import the model types and derivation
functions when first asked (no sympy at import); the model types do not import them.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass

import casadi as ca

__all__ = ["FormulationProtocol", "StateLayout", "LoopPoint", "Stabilisation", "LoopDynamics",
           "REDUCED", "LAGRANGE", "HAMILTON", "PROTOCOLS", "protocol_of", "protocol_named"]


@dataclass(frozen=True)
class StateLayout:
    """Where each part of a formulation's state x sits.

    Attributes
    ----------
    names : the names of x in order (``model.state_names``).
    n_coordinates : n; x[:n] = q in the system's coordinate order.
    velocity_part : what x[n:] holds, in words.
    velocity_names : the names of x[n:].
    n_multipliers : the number of multipliers λ (0 for the reduced ODE).
    """

    names: tuple
    n_coordinates: int
    velocity_part: str
    velocity_names: tuple
    n_multipliers: int


@dataclass(frozen=True)
class LoopPoint:
    """CasADi symbols of one closed-loop evaluation: the clamped time t_c, the state x, the
    input u, the parameter vector and the integrals ∫g of the constraint residual (0 entries
    unless Baumgarte stabilisation with β ≠ 0)."""

    t_c: object
    x: object
    u: object
    params: object
    g_int: object


@dataclass(frozen=True)
class Stabilisation:
    """The constraint stabilisation of a DAE form: ``kind`` None, "baumgarte" (ġ + 2αg + β²∫g
    = 0, with ``alpha``, ``beta``) or "projection" (applied by the integrators, not here)."""

    kind: str | None = None
    alpha: float = 0.0
    beta: float = 0.0


@dataclass(frozen=True)
class LoopDynamics:
    """What the closed loop integrates and reports at one point (CasADi expressions): ẋ, λ
    (0 entries for the reduced ODE), the constraint residual g = ω(q)q̇, the singular-set
    measure (1 away from the set, 0 on it) and vec S, S = ω M⁻¹ ωᵀ column-major (0 entries
    for the reduced ODE)."""

    xdot: object
    lam: object
    g: object
    measure: object
    gram: object


class FormulationProtocol(abc.ABC):
    """What every formulation provides (see the module docstring).

    Attributes
    ----------
    name : "reduced", "lagrange" or "hamilton" (``model.formulation``).
    velocity_part : what follows q in the state, in words.
    has_multipliers : the formulation has multipliers λ (a ``Trajectory.lam`` array, possibly
        with 0 columns); the reduced ODE has none.
    dae_options_apply : ``dae="idas"`` and ``stabilization`` apply (the DAE forms).
    has_constraint_gram : the closed loop reports S = ω M⁻¹ ωᵀ (its condition number is a
        diagnostic of the run).
    specialised_for_integration : the driver integrates the model specialised to the run's
        parameter values (the reduced ODE) rather than the model as derived.
    """

    name: str
    velocity_part: str
    has_multipliers: bool
    dae_options_apply: bool
    has_constraint_gram: bool
    specialised_for_integration: bool

    # ---------------------------------------------------------------- derivation
    @property
    @abc.abstractmethod
    def model_type(self) -> type:
        """The result type of :meth:`derive`."""

    @abc.abstractmethod
    def derive(self, system, version: str | None = None):
        """Derive this formulation of ``system`` (``version``: the reduced ODE's choice of g)."""

    # ---------------------------------------------------------------- state layout
    def state_layout(self, model) -> StateLayout:
        """The layout of ``model``'s state (see :class:`StateLayout`)."""
        n = model.system.n
        names = tuple(model.state_names)
        return StateLayout(names=names, n_coordinates=n, velocity_part=self.velocity_part,
                           velocity_names=names[n:], n_multipliers=self.multiplier_count(model))

    @abc.abstractmethod
    def multiplier_count(self, model) -> int:
        """The number of multipliers λ."""

    # ---------------------------------------------------------------- initial-state map
    @abc.abstractmethod
    def initial_state(self, numeric, q, qdot, params):
        """x for the physical state (q, q̇) (CasADi; Tables 3.2–3.3)."""

    @abc.abstractmethod
    def constraint_residual(self, numeric, q, qdot, params):
        """ω(q)q̇ (CasADi, k entries)."""

    def configuration_measure(self, model, q, params):
        """The measure the initial state's configuration is checked with (CasADi; in [0, 1],
        below :data:`~.states.SINGULAR_TOL` on the singular set); 1: no check."""
        return ca.SX(1)

    # ---------------------------------------------------------------- closed loop
    @abc.abstractmethod
    def loop_dynamics(self, model, point: LoopPoint, stabilisation: Stabilisation) -> LoopDynamics:
        """ẋ, λ, g, the singular-set measure and vec S at ``point`` (see :class:`LoopDynamics`)."""

    # ---------------------------------------------------------------- texts and options
    @abc.abstractmethod
    def singular_set_text(self, model) -> str:
        """What the singular set is, in words (the message of a run stopped on it)."""

    def dae_option_problems(self, dae: str, stabilization, *, holonomic: bool = False) -> list:
        """The problems of a request that sets options this formulation does not have
        (``holonomic``: the system keeps holonomic constraints, whose drift projection removes)."""
        return []

    def __repr__(self) -> str:
        return f"<{self.name} formulation protocol>"


@dataclass(frozen=True, repr=False)
class ReducedProtocol(FormulationProtocol):
    """The reduced constrained Hamiltonian ODE, ż = f(t, z, u) (20-step method).

    State z = (q_1 … q_n, P_1 … P_d, P̃ …), 2n − k entries, P = Xᵀ M(q) q̇; no multipliers.
    The singular-set measure is the engine's ``numeric["singular"]`` (0 where a matrix the
    reduction inverts loses rank); the initial configuration is checked against it.
    """

    name: str = "reduced"
    velocity_part: str = "momenta P = Xᵀ M(q) q̇ (nonholonomic P, shape P̃)"
    has_multipliers: bool = False
    dae_options_apply: bool = False
    has_constraint_gram: bool = False
    specialised_for_integration: bool = True

    @property
    def model_type(self) -> type:
        from .reduction import ReducedODE
        return ReducedODE

    def derive(self, system, version=None):
        from .reduction import derive_reduced
        return derive_reduced(system, version=version)

    def multiplier_count(self, model) -> int:
        return 0

    def initial_state(self, numeric, q, qdot, params):
        return numeric["state"](q, qdot, params)

    def constraint_residual(self, numeric, q, qdot, params):
        return numeric["constraint"](q, qdot, params)

    def configuration_measure(self, model, q, params):
        return model.numeric["singular"](q, params) if model.system.k else ca.SX(1)

    def loop_dynamics(self, model, point, stabilisation):
        num, n = model.numeric, model.system.n
        x, params = point.x, point.params
        q, qdot = x[:n], num["qdot"](x, params)
        return LoopDynamics(xdot=num["rhs"](point.t_c, x, point.u, params), lam=ca.SX(0, 1),
                            g=num["constraint"](q, qdot, params),
                            measure=self.configuration_measure(model, q, params), gram=ca.SX(0, 1))

    def singular_set_text(self, model) -> str:
        sset = getattr(model, "singular_set", None)
        if sset:
            return "singular set: " + " or ".join(f"{e} = 0" for e in sset)
        return "the reduction is singular there"

    def dae_option_problems(self, dae, stabilization, *, holonomic: bool = False) -> list:
        problems = []
        if dae == "idas":
            problems.append("dae='idas' applies to the DAE forms (lagrange, hamilton); the reduced "
                            "form is an ODE")
        if stabilization == "projection" and holonomic:
            return problems           # q projected back onto the kept holonomic constraints h(q) = 0
        if stabilization is not None:
            problems.append("stabilization applies to the DAE forms; the reduced ODE satisfies the "
                            "constraints by construction (projection also applies to a reduced ODE "
                            "with kept holonomic constraints: it removes their drift)")
        return problems


@dataclass(frozen=True, repr=False)
class DAEProtocol(FormulationProtocol):
    """What both DAE forms share: x = (q, v) with 2n entries, k multipliers λ solved from the
    differentiated constraint (index reduction, or Baumgarte's ġ + 2αg + β²∫g = 0), and the
    singular-set measure det S / Π Sᵢᵢ (Hadamard ratio) of S = ω M⁻¹ ωᵀ, the matrix λ is
    solved with."""

    name: str = ""
    velocity_part: str = ""
    has_multipliers: bool = True
    dae_options_apply: bool = True
    has_constraint_gram: bool = True
    specialised_for_integration: bool = False

    def multiplier_count(self, model) -> int:
        return len(model.multipliers)

    def constraint_residual(self, numeric, q, qdot, params):
        return numeric["constraint"](self.initial_state(numeric, q, qdot, params), params)

    @abc.abstractmethod
    def constraint_gram(self, numeric, x, params):
        """S = ω M⁻¹ ωᵀ (k×k) from the documented functions ``constraint`` and ``mass``."""

    def loop_dynamics(self, model, point, stabilisation):
        num = model.numeric
        k = self.multiplier_count(model)
        x, u, params, t_c = point.x, point.u, point.params, point.t_c
        g = num["constraint"](x, params)
        if stabilisation.kind == "baumgarte":          # ġ + 2αg + β²∫g = 0 solved for λ
            lam_sym = ca.SX.sym("lam", k)
            res = num["dae_g"](t_c, x, lam_sym, u, params) + 2 * stabilisation.alpha * g
            if point.g_int.shape[0]:
                res = res + stabilisation.beta ** 2 * point.g_int
            S_lam = ca.jacobian(res, lam_sym)
            lam = -ca.solve(S_lam, ca.substitute(res, lam_sym, ca.SX.zeros(k)))
            xdot = num["dae_f"](t_c, x, lam, u, params)
        else:
            xdot, lam = num["ode"](t_c, x, u, params)
        S = self.constraint_gram(num, x, params) if k else ca.SX(0, 0)
        return LoopDynamics(xdot=xdot, lam=lam, g=g, measure=_hadamard_ratio(S, k) if k else ca.SX(1),
                            gram=ca.vec(S))

    def singular_set_text(self, model) -> str:
        return "ω M⁻¹ ωᵀ loses rank: the constraints become dependent"


def _hadamard_ratio(S, k):
    """det S / Π Sᵢᵢ: 1 for orthogonal constraint rows, 0 where they become dependent."""
    diag = 1
    for i in range(k):
        diag = diag * S[i, i]
    return ca.det(S) / (diag + 1e-300)


@dataclass(frozen=True, repr=False)
class LagrangeProtocol(DAEProtocol):
    """Euler–Lagrange equations with multipliers (eq. 2.8): x = (q_1 … q_n, q̇_1 … q̇_n),
    λ_1 … λ_k."""

    name: str = "lagrange"
    velocity_part: str = "velocities q̇"

    @property
    def model_type(self) -> type:
        from .lagrange import LagrangianDAE
        return LagrangianDAE

    def derive(self, system, version=None):
        from .lagrange import derive_lagrangian
        return derive_lagrangian(system)

    def initial_state(self, numeric, q, qdot, params):
        return ca.vertcat(q, qdot)

    def constraint_gram(self, numeric, x, params):
        n = numeric.n_coordinates
        omega = ca.jacobian(numeric["constraint"](x, params), x[n:])
        return ca.mtimes(omega, ca.solve(numeric["mass"](x, params), omega.T))


@dataclass(frozen=True, repr=False)
class HamiltonProtocol(DAEProtocol):
    """Hamilton's equations with multipliers (eqs. 2.19–2.24): x = (q_1 … q_n, p_1 … p_n) with
    p = M(q) q̇, λ_1 … λ_k."""

    name: str = "hamilton"
    velocity_part: str = "canonical momenta p = M(q) q̇"

    @property
    def model_type(self) -> type:
        from .hamilton import HamiltonianDAE
        return HamiltonianDAE

    def derive(self, system, version=None):
        from .hamilton import derive_hamiltonian
        return derive_hamiltonian(system)

    def initial_state(self, numeric, q, qdot, params):
        mass = numeric["mass"](ca.vertcat(q, ca.SX.zeros(q.shape[0])), params)
        return ca.vertcat(q, ca.mtimes(mass, qdot))

    def constraint_gram(self, numeric, x, params):
        n = numeric.n_coordinates
        omega_minv = ca.jacobian(numeric["constraint"](x, params), x[n:])    # ω M⁻¹ (g = ω M⁻¹ p)
        return ca.mtimes(ca.mtimes(omega_minv, numeric["mass"](x, params)), omega_minv.T)


REDUCED = ReducedProtocol()
LAGRANGE = LagrangeProtocol()
HAMILTON = HamiltonProtocol()

#: formulation name → its protocol, in the order of :data:`~.formulations.FORMULATIONS`
PROTOCOLS = {protocol.name: protocol for protocol in (REDUCED, LAGRANGE, HAMILTON)}


def protocol_named(name: str) -> FormulationProtocol:
    """The protocol of the formulation ``name``; raises :class:`~nhgait.dynamics.errors.ModelError`
    for an unknown name."""
    try:
        return PROTOCOLS[name]
    except (KeyError, TypeError):
        from ..errors import ModelError
        raise ModelError([f"unknown formulation {name!r} (choose from {', '.join(PROTOCOLS)})"],
                         title="invalid request") from None


def protocol_of(model) -> FormulationProtocol:
    """The protocol of a derived model (by ``model.formulation``)."""
    return protocol_named(model.formulation)
