"""What the two DAE forms (:class:`~.lagrange.LagrangianDAE`, :class:`~.hamilton.HamiltonianDAE`)
hold besides their equations, stated once: :class:`DAEModel`."""
from __future__ import annotations

from dataclasses import dataclass, field

from nhgait.dynamics.reprs import ModelDisplay

from .system import System


@dataclass(frozen=True, eq=False, repr=False, kw_only=True)
class DAEModel(ModelDisplay):
    """The fields every DAE form has: ``system``; ``state`` and ``state_names`` (x = (q, q̇) or
    (q, p), 2n entries); ``multipliers`` λ_1 … λ_k, one per constraint; the derivation time; the
    compiled functions when they came with the model (the cache) and the cache ``provenance``.
    Both forms are index-2 DAEs (see each form's module docstring)."""

    system: System
    state: tuple
    state_names: tuple
    multipliers: tuple
    derive_time_s: float = 0.0
    compiled: object = field(default=None, repr=False)
    provenance: object = field(default=None, repr=False)

    differentiation_index = 2
