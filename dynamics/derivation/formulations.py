"""The one entry point for equations of motion: :func:`derive`, and the registry of the
formulations by name (:data:`FORMULATIONS`, :func:`formulation_type`).

Derivations are cached once per system *structure* (parameters stay symbolic); the caller's
system — its name and parameter values — is bound to the loaded object on every call, so a
cached model always reports this input's values (see :mod:`.cache`).

A formulation's name is resolved here, once, into its model type — :class:`~.reduction.ReducedODE`,
:class:`~.lagrange.LagrangianDAE` or :class:`~.hamilton.HamiltonianDAE`, each carrying its
formulation's vocabulary (:class:`~.formulation_base.Formulation`) — and its derivation. The
model types are imported when first asked for (no sympy at import).
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import NamedTuple

from ..algebra.determinism import seeded
from ..errors import ModelError
from ..numerics import cache as _cache


def _reduced(system, version):
    from .reduction import derive_reduced
    return derive_reduced(system, version=version)


def _lagrange(system, version):
    from .lagrange import derive_lagrangian
    return derive_lagrangian(system)


def _hamilton(system, version):
    from .hamilton import derive_hamiltonian
    return derive_hamiltonian(system)


def _reduced_type() -> type:
    from .reduction import ReducedODE
    return ReducedODE


def _lagrange_type() -> type:
    from .lagrange import LagrangianDAE
    return LagrangianDAE


def _hamilton_type() -> type:
    from .hamilton import HamiltonianDAE
    return HamiltonianDAE


class _Registration(NamedTuple):
    """One formulation: ``model_type()`` imports and returns its model type, ``derive(system,
    version)`` derives it."""

    model_type: Callable[[], type]
    derive: Callable


#: formulation name → its :class:`_Registration`
_REGISTRY = {"reduced": _Registration(_reduced_type, _reduced),
             "lagrange": _Registration(_lagrange_type, _lagrange),
             "hamilton": _Registration(_hamilton_type, _hamilton)}

#: the formulation names, in the order the documentation lists them
FORMULATIONS = tuple(_REGISTRY)


def formulation_type(name: str) -> type:
    """The model type of the formulation ``name`` (its class attributes answer what the
    formulation has: ``dae_options_apply``, ``has_multipliers``, …); raises
    :class:`~nhgait.dynamics.errors.ModelError` for an unknown name."""
    return _registered(name).model_type()


def _registered(name: str) -> _Registration:
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ModelError([f"unknown formulation {name!r} (choose from {', '.join(FORMULATIONS)})"],
                         title="invalid request") from None


@dataclasses.dataclass(frozen=True, eq=False)
class _Entry:
    """What the cache stores for one derivation: the model (with its compiled functions) and
    when and how fast it was derived."""

    model: object
    created: str
    derive_time_s: float


def bind(model, system, provenance=None):
    """``model`` with ``system`` (the same structure: names, L, ω, τ) as its system: the
    caller's name and parameter values, the compiled functions shared (when ``model`` has
    them: given, or compiled and kept by ``model.numeric``), defaults rebound."""
    numeric = model.compiled if model.compiled is not None else model.__dict__.get("numeric")
    return dataclasses.replace(model, system=system, provenance=provenance,
                               compiled=None if numeric is None
                               else numeric.with_defaults(system.param_values))


def derive(system, formulation: str = "reduced", *, version: str | None = None,
           use_cache: bool = True, compile: bool = True):
    """Derive (or load from the cache) one formulation of ``system``.

    Parameters
    ----------
    system : System or str
        A :class:`~nhgait.dynamics.derivation.system.System` or a built-in name ("unicycle", "snakeboard",
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

    Returns
    -------
    The model, whose ``system`` is the ``system`` given here and whose ``provenance``
    (:class:`~nhgait.dynamics.numerics.cache.Provenance`) says whether it came from the cache, its key,
    when the equations were derived and how long that took.

    Examples
    --------
    The vertical rolling disc (n = 4 coordinates, k = 2 rolling constraints): the reduced ODE
    has 2n − k = 6 first-order equations in z = (q, P), the Lagrangian DAE 2n states (q, q̇):

    >>> from nhgait.dynamics import derive
    >>> model = derive("unicycle")
    >>> model.formulation, model.state_names
    ('reduced', ('x', 'y', 'theta', 'phi', 'p', 'pt_theta'))
    >>> model.dimension == 2 * model.system.n - model.system.k
    True
    >>> derive("unicycle", "lagrange").state_names
    ('x', 'y', 'theta', 'phi', 'x_dot', 'y_dot', 'theta_dot', 'phi_dot')
    """
    if isinstance(system, str):
        from .models import builtin
        system = builtin(system)
    registered = _registered(formulation)
    if version not in (None, "A", "B"):
        raise ModelError([f"unknown reconstruction version {version!r} (A or B)"], title="invalid request")
    key = _cache.cache_key(system, formulation, f"version={version};compile={bool(compile)}")
    if use_cache:
        start = time.perf_counter()
        entry = _cache.load(key, _Entry)
        if entry is not None and isinstance(entry.model, registered.model_type()):
            provenance = _cache.Provenance(key, entry.created, entry.derive_time_s, True,
                                           time.perf_counter() - start, _cache.versions())
            return bind(entry.model, system, provenance)
    created, start = _cache.now(), time.perf_counter()
    with seeded():                     # sympy's random choices fixed: the same work every time
        model = registered.derive(system, version)
    if compile:
        model.numeric  # noqa: B018 - build and keep the compiled functions
    elapsed = time.perf_counter() - start
    if use_cache:
        _cache.store(key, _Entry(model, created, elapsed))
    return bind(model, system, _cache.Provenance(key, created, elapsed, False, 0.0, _cache.versions()))
