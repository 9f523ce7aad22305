"""The one entry point for equations of motion: :func:`derive`."""
from __future__ import annotations

from . import cache as _cache
from .errors import ModelError

FORMULATIONS = ("reduced", "lagrange", "hamilton")


def derive(system, formulation: str = "reduced", *, version: str | None = None,
           use_cache: bool = True, compile: bool = True):
    """Derive (or load from the cache) one formulation of ``system``.

    Parameters
    ----------
    system : System or str
        A :class:`~nhgait.dynamics.system.System` or a built-in name ("unicycle", "snakeboard",
        "chaplygin_sleigh", "knife_edge_incline").
    formulation : {"reduced", "lagrange", "hamilton"}
        :class:`ReducedODE` (20-step method), :class:`LagrangianDAE` (eq. 2.8) or
        :class:`HamiltonianDAE` (eqs. 2.19–2.24). Only the requested formulation is derived.
    version : {"A", "B", None}
        Reduced ODE only: choice of g in the reconstruction (None: B when a planar frame
        with x, y in the fiber exists).
    use_cache : bool
        Read/write the on-disk cache (``$NHGAIT_CACHE_DIR``). False derives afresh.
    compile : bool
        Also build the CasADi functions (``model.numeric``) before caching.
    """
    if isinstance(system, str):
        from .models import builtin
        system = builtin(system)
    if formulation not in FORMULATIONS:
        raise ModelError([f"unknown formulation {formulation!r} (choose from {', '.join(FORMULATIONS)})"],
                         title="invalid request")
    if version not in (None, "A", "B"):
        raise ModelError([f"unknown reconstruction version {version!r} (A or B)"], title="invalid request")
    key = _cache.cache_key(system, formulation, f"version={version}")
    if use_cache:
        hit = _cache.load(key)
        if hit is not None:
            return hit
    if formulation == "reduced":
        from .reduction import derive_reduced
        model = derive_reduced(system, version=version)
    elif formulation == "lagrange":
        from .lagrange import derive_lagrangian
        model = derive_lagrangian(system)
    else:
        from .hamilton import derive_hamiltonian
        model = derive_hamiltonian(system)
    if compile:
        model.numeric  # noqa: B018 - build and keep the compiled functions
    if use_cache:
        _cache.store(key, model)
    return model
