"""nhgait.dynamics — from (q, L, ω, τ) to equations of motion.

Entry points (imported lazily, so ``import nhgait.dynamics`` does no symbolic work):

* :class:`System` — state a system; :func:`load_scene` — read a TOML scene file;
* :func:`unicycle`, :func:`snakeboard`, :func:`chaplygin_sleigh`, :func:`knife_edge_incline`;
* :func:`derive` — ``derive(system, "reduced" | "lagrange" | "hamilton")``, cached on disk;
* :func:`simulate` — forward simulation of any formulation;
* :func:`jacobi_test` — Jacobi identity of the reduced bracket and holonomy of ω.
"""
from __future__ import annotations

import importlib

_EXPORTS = {
    "System": "derivation.system", "ModelError": "errors", "SingularConfigurationError": "errors",
    "unicycle": "derivation.models", "snakeboard": "derivation.models",
    "chaplygin_sleigh": "derivation.models", "knife_edge_incline": "derivation.models",
    "builtin": "derivation.models",
    "derive": "derivation.formulations", "FORMULATIONS": "derivation.formulations",
    "ReducedODE": "derivation.reduction", "LagrangianDAE": "derivation.lagrange",
    "HamiltonianDAE": "derivation.hamilton",
    "load_scene": "derivation.scene", "Scene": "derivation.scene",
    "simulate": "simulation.driver", "Trajectory": "simulation.driver",
    "jacobi_test": "derivation.analysis", "to_state": "derivation.states",
    "from_state": "derivation.states",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'nhgait.dynamics' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value
