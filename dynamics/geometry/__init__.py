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

and why a shape loop moves it:

* :func:`local_connection` — A(r), Γ(r) and the fibre group's bracket (:mod:`.connection_fields`);
* :func:`height_function`, :func:`evaluate_heights` — the curvature H = −(dA − [A, A]) of the
  connection over two shape coordinates, as expressions and arrays (:mod:`.heights`);
* :func:`scaled_momentum` — Shammas's scaled momentum of a mixed system (p̄ = e^{−F}p, σ̄, Γ̄) and
  the momentum's part of its height functions, H̄ = H − σ̄_abΓ̄ (:mod:`.scaled_momentum`);
* :func:`loop_displacement` — the Stokes and body-velocity-integral estimates of a shape loop's
  net displacement (:mod:`.stokes`); :func:`fibre_motion` — the fibre and momentum motion along
  a prescribed shape path (:mod:`.prescribed`).

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
    "LocalConnection": "connection_fields", "local_connection": "connection_fields",
    "HeightFunctions": "heights", "height_function": "heights", "evaluate_heights": "heights",
    "HeightGrid": "heights", "ScaledMomentum": "scaled_momentum", "scaled_momentum": "scaled_momentum",
    "LoopDisplacement": "stokes", "loop_displacement": "stokes",
    "FibreMotion": "prescribed", "fibre_motion": "prescribed",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
