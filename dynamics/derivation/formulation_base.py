"""The vocabulary every derived model speaks: :class:`Formulation`, and the values it speaks in.

As the method objects of sympy.physics.mechanics (``KanesMethod``, ``LagrangesMethod``) carry
their own vocabulary, each derived model carries its formulation's: :class:`~.reduction.ReducedODE`,
:class:`~.lagrange.LagrangianDAE` and :class:`~.hamilton.HamiltonianDAE` subclass
:class:`Formulation`. Code that works with any derived model asks the model —
``model.loop_dynamics(point, stabilisation)``, ``model.has_multipliers`` — and never compares
``model.formulation`` with a string; code that holds only a formulation's name resolves it once
into the model type (:func:`~.formulations.formulation_type`), whose class attributes answer
the same questions.

What a formulation owns
-----------------------
* the state layout: :meth:`~Formulation.state_layout` (the names of x, x[:n] = q, what x[n:]
  holds, the number of multipliers λ);
* the initial-state map (q, q̇) → x, the constraint residual ω(q)q̇ and the measure of the
  configuration check, as CasADi expressions (:mod:`.states` compiles them into one Function
  per model);
* what the closed loop needs: ẋ, λ, the constraint residual, the singular-set measure and the
  constraint Gram matrix S = ω M⁻¹ ωᵀ (:meth:`~Formulation.loop_dynamics`);
* the sentence that names the singular set, and whether the DAE options (``dae="idas"``, a
  :class:`Stabilisation`) apply, with the problems of a request that sets them on an ODE.

State layouts (n coordinates, k constraints, d = n − k − (free shape velocities) momenta)
-----------------------------------------------------------------------------------------
* reduced:  z = (q_1 … q_n, P_1 … P_d, P̃_1 …), 2n − k entries; P = Xᵀ M(q) q̇ (Tables
  3.2–3.3); no multipliers;
* lagrange: x = (q_1 … q_n, q̇_1 … q̇_n), 2n entries; λ_1 … λ_k;
* hamilton: x = (q_1 … q_n, p_1 … p_n), 2n entries, p = M(q) q̇; λ_1 … λ_k.

Constraint stabilisation (the DAE forms)
----------------------------------------
The option ``stabilization`` of :func:`~nhgait.dynamics.simulation.driver.simulate` is resolved
once into one of these objects (:func:`stabilisation_named`):

* :class:`Stabilisation` — none: λ from the index-reduced law ġ = 0 (``numeric["ode"]``);
* :class:`Baumgarte` — λ from ġ + 2αg + β²∫g = 0 (β ≠ 0 adds the k integrals ∫g to the state);
* :class:`Projection` — λ as without; the integrators project the state onto the constraints
  after every step.

This module imports no model type (the model modules import it), and no sympy.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca

__all__ = ["Formulation", "StateLayout", "LoopPoint", "LoopDynamics", "Stabilisation", "Baumgarte",
           "Projection", "STABILISATIONS", "stabilisation_named"]


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


@dataclass(frozen=True)
class Stabilisation:
    """No constraint stabilisation: λ from the index-reduced law ġ = 0.

    Attributes
    ----------
    kind : the option's name (None, "baumgarte", "projection"), as ``Trajectory.settings``
        reports it.
    feeds_back : λ is solved from a law with feedback on g (:meth:`feedback`), not taken
        from the index-reduced ODE.
    projects : the integrators project the state onto the constraints after every step.
    """

    kind: ClassVar[str | None] = None
    feeds_back: ClassVar[bool] = False
    projects: ClassVar[bool] = False

    def integral_states(self, k: int) -> int:
        """How many integrals ∫g the state carries (k constraints)."""
        return 0

    def feedback(self, residual, g, g_int):
        """The law λ is solved from, given the index-reduced ``residual`` (ġ = 0)."""
        return residual

    @property
    def gains(self) -> tuple | None:
        """(α, β) of a Baumgarte law, else None."""
        return None


@dataclass(frozen=True)
class Baumgarte(Stabilisation):
    """Baumgarte's law ġ + 2αg + β²∫g = 0 (α, β ≥ 0)."""

    alpha: float = 1.0
    beta: float = 0.0

    kind: ClassVar[str | None] = "baumgarte"
    feeds_back: ClassVar[bool] = True

    def integral_states(self, k: int) -> int:
        return k if self.beta != 0.0 else 0

    def feedback(self, residual, g, g_int):
        residual = residual + 2 * self.alpha * g
        if g_int.shape[0]:
            residual = residual + self.beta ** 2 * g_int
        return residual

    @property
    def gains(self) -> tuple[float, float]:
        return (self.alpha, self.beta)


@dataclass(frozen=True)
class Projection(Stabilisation):
    """Projection onto the constraints after every accepted step (done by the integrators;
    λ as without stabilisation)."""

    kind: ClassVar[str | None] = "projection"
    projects: ClassVar[bool] = True


#: the ``stabilization`` option's values → the type each resolves to
STABILISATIONS = {None: Stabilisation, "baumgarte": Baumgarte, "projection": Projection}


def stabilisation_named(name: str | None, baumgarte=(1.0, 0.0)) -> Stabilisation:
    """The stabilisation object of the option ``name`` (a key of :data:`STABILISATIONS`, checked
    by the caller); ``baumgarte`` = (α, β) for ``"baumgarte"``."""
    kind = STABILISATIONS[name]
    if kind is Baumgarte:
        alpha, beta = (float(v) for v in baumgarte)
        return Baumgarte(alpha, beta)
    return kind()


class Formulation(abc.ABC):
    """What every derived model provides (see the module docstring).

    Attributes (class attributes of each model type)
    -------------------------------------------------
    formulation : "reduced", "lagrange" or "hamilton".
    velocity_part : what follows q in the state, in words.
    has_multipliers : the formulation has multipliers λ (a ``Trajectory.lam`` array, possibly
        with 0 columns); the reduced ODE has none.
    dae_options_apply : ``dae="idas"`` and ``stabilization`` apply (the DAE forms).
    has_constraint_gram : the closed loop reports S = ω M⁻¹ ωᵀ (its condition number is a
        diagnostic of the run).
    specialised_for_integration : the driver integrates the model specialised to the run's
        parameter values (the reduced ODE) rather than the model as derived.
    """

    formulation: ClassVar[str]
    velocity_part: ClassVar[str]
    has_multipliers: ClassVar[bool]
    dae_options_apply: ClassVar[bool]
    has_constraint_gram: ClassVar[bool]
    specialised_for_integration: ClassVar[bool]

    # ---------------------------------------------------------------- state layout
    def state_layout(self) -> StateLayout:
        """The layout of this model's state (see :class:`StateLayout`)."""
        n = self.system.n
        names = tuple(self.state_names)
        return StateLayout(names=names, n_coordinates=n, velocity_part=self.velocity_part,
                           velocity_names=names[n:], n_multipliers=self.multiplier_count())

    @abc.abstractmethod
    def multiplier_count(self) -> int:
        """The number of multipliers λ."""

    # ---------------------------------------------------------------- initial-state map
    @abc.abstractmethod
    def initial_state(self, q, qdot, params):
        """x for the physical state (q, q̇) (CasADi; Tables 3.2–3.3)."""

    @abc.abstractmethod
    def constraint_residual(self, q, qdot, params):
        """ω(q)q̇ (CasADi, k entries)."""

    def configuration_measure(self, q, params):
        """The measure the initial state's configuration is checked with (CasADi; in [0, 1],
        below :data:`~.states.SINGULAR_TOL` on the singular set); 1: no check."""
        return ca.SX(1)

    # ---------------------------------------------------------------- closed loop
    @abc.abstractmethod
    def loop_dynamics(self, point: LoopPoint, stabilisation: Stabilisation) -> LoopDynamics:
        """ẋ, λ, g, the singular-set measure and vec S at ``point`` (see :class:`LoopDynamics`)."""

    # ---------------------------------------------------------------- texts and options
    @abc.abstractmethod
    def singular_set_text(self) -> str:
        """What the singular set is, in words (the message of a run stopped on it)."""

    @classmethod
    def dae_option_problems(cls, idas: bool, stabilisation, *, holonomic: bool = False) -> list:
        """The problems of a request that sets options this formulation does not have
        (``idas``: ``dae="idas"``; ``stabilisation``: the :class:`Stabilisation` type or object
        asked for; ``holonomic``: the system keeps holonomic constraints, whose drift projection
        removes)."""
        return []
