"""nhgait.dynamics.geometry — why a gait moves a robot, and whether a robot can move at all.

The analyses of a derived reduced model (thesis §2.3, Table 2.1; Shammas's gait generation, the
thesis's reference [1]), each a function returning a frozen result:

* :func:`reconstruction` — the reconstruction equation ξ = −A(r)ṙ + Γ(r)pᵀ (eq. 2.47) of the
  chosen fibre, with its Table 2.1 type, and for mixed systems the momentum equation
  ṗ = ṙᵀσ_rr ṙ + ṙᵀσ_rp p + pᵀσ_pp p (:mod:`.reconstruction`);
* :func:`growth_vector` — the constraint distribution's growth vector at a configuration
  (ranks of D, D + [D, D], …) and the brackets that give each new direction
  (:mod:`.distribution`);
* :func:`accessibility` — the accessibility rank of the reduced control system
  ż = f(z) + Σ gᵢ(z)uᵢ at a state and the bracket depth it needs (:mod:`.accessibility`);
* :func:`observability` — the rank of the observability codistribution of named outputs and
  the states it cannot see (:mod:`.observability`).

The height functions, connection vector fields and loop estimates of issue 42 items 3–4
(:mod:`.connection_fields`, :mod:`.heights`, :mod:`.stokes`, :mod:`.prescribed`) live beside
them, written by the ``heights`` helper.

Imported lazily: ``import nhgait.dynamics.geometry`` does no symbolic work.
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {
    "ReconstructionEquation": "reconstruction", "reconstruction": "reconstruction",
    "GrowthVector": "distribution", "growth_vector": "distribution",
    "Accessibility": "accessibility", "accessibility": "accessibility",
    "Observability": "observability", "observability": "observability",
    "AnalysisPoint": "distribution", "analysis_point": "distribution",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
