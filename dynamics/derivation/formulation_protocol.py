"""The former home of the formulations' vocabulary, kept as thin public aliases.

The vocabulary now lives on the derived models themselves (:class:`~.formulation_base.Formulation`,
subclassed by :class:`~.reduction.ReducedODE`, :class:`~.lagrange.LagrangianDAE` and
:class:`~.hamilton.HamiltonianDAE`): write ``model.loop_dynamics(point, stabilisation)`` and
``formulation_type("lagrange").dae_options_apply``. For code written against the protocol
objects, :func:`protocol_of` and :func:`protocol_named` return the model type, whose methods
called on the class take the model first (``protocol_of(model).singular_set_text(model)``), and
``REDUCED``, ``LAGRANGE``, ``HAMILTON``, ``PROTOCOLS`` name the model types (imported when
first asked for: no sympy at import).
"""
from __future__ import annotations

from .formulation_base import Formulation, LoopDynamics, LoopPoint, Stabilisation, StateLayout  # noqa: F401 - re-exported

#: (``REDUCED``, ``LAGRANGE``, ``HAMILTON``, ``PROTOCOLS``: module attributes resolved on first use)
__all__ = ["FormulationProtocol", "StateLayout", "LoopPoint", "Stabilisation", "LoopDynamics",
           "protocol_of", "protocol_named"]

#: the former abstract protocol: the models' common base
FormulationProtocol = Formulation

_CONSTANTS = {"REDUCED": "reduced", "LAGRANGE": "lagrange", "HAMILTON": "hamilton"}


def protocol_named(name: str) -> type:
    """The model type of the formulation ``name`` (:func:`~.formulations.formulation_type`)."""
    from .formulations import formulation_type
    return formulation_type(name)


def protocol_of(model) -> type:
    """The model type of a derived model: ``type(model)``."""
    return type(model)


def __getattr__(name: str):
    if name in _CONSTANTS:
        return protocol_named(_CONSTANTS[name])
    if name == "PROTOCOLS":
        from .formulations import FORMULATIONS
        return {form: protocol_named(form) for form in FORMULATIONS}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
