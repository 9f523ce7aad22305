"""nhgait.dynamics — from (q, L, ω, τ) to equations of motion.

Entry points (imported lazily, so ``import nhgait.dynamics`` does no symbolic work):

* :class:`System` — state a system; :func:`load_scene` — read a TOML scene file;
* :func:`unicycle`, :func:`snakeboard`, :func:`chaplygin_sleigh`, :func:`knife_edge_incline`;
* :func:`derive` — ``derive(system, "reduced" | "lagrange" | "hamilton")``, cached on disk;
* :func:`simulate` — forward simulation of any formulation (its options: :class:`SimulationOptions`);
* :func:`jacobi_test` — Jacobi identity of the reduced bracket and holonomy of ω.
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {
    "System": "derivation.system", "ModelError": "errors", "SingularConfigurationError": "errors",
    "unicycle": "derivation.models", "snakeboard": "derivation.models",
    "chaplygin_sleigh": "derivation.models", "knife_edge_incline": "derivation.models",
    "builtin": "derivation.models",
    "derive": "derivation.formulations", "FORMULATIONS": "derivation.formulations",
    "ReducedODE": "derivation.reduction", "LagrangianDAE": "derivation.lagrange",
    "HamiltonianDAE": "derivation.hamilton",
    "load_scene": "derivation.input.scene", "Scene": "derivation.input.scene",
    "simulate": "simulation.driver", "SimulationOptions": "simulation.options",
    "Trajectory": "simulation.trajectory",
    "jacobi_test": "derivation.analysis", "to_state": "derivation.states",
    "from_state": "derivation.states",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
