"""The numeric checks of a system's parameter values: finite numbers, a kinetic metric M(q)
that is positive definite (eq. 2.5), independent constraints (rank ω(q) = k, eq. 2.11) —
sampled at random configurations.

:func:`parameter_problems` checks a parameter set (the defaults, a mapping of overrides or a
vector); :func:`numeric_checks` the values already known to be numbers. M(q), ω(q) and V(q)
are lambdified once per system (:func:`numeric_functions`, memo :data:`LAMBDIFIED`, dropped
with the system) and shared with the symmetry test and the initial-state checks.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import sympy as sp

from nhgait.dynamics.suggestions import known_names

from ..memo import OwnerMemo
from .input.expressions import number_problems

__all__ = ["parameter_problems", "numeric_checks", "numeric_functions", "sample_configurations", "LAMBDIFIED"]

#: per system (dropped with it): (M(q, params), ω(q, params) or None, V(q, params)) as numpy
#: callables (lambdify takes ~10 ms per system; the checks and the symmetry test share them)
LAMBDIFIED = OwnerMemo("lambdified M, ω and V per system")


class NumericFunctions(NamedTuple):
    """M(q, params), ω(q, params) (None when k = 0) and V(q, params) as numpy callables."""

    mass: object
    omega: object
    potential: object


def numeric_functions(system) -> NumericFunctions:
    """(M(q, params), ω(q, params) or None, V(q, params)) as numpy callables (:data:`LAMBDIFIED`)."""
    def lambdify():
        args = [system.q, system.param_symbols]     # cse: a system built from bodies repeats much
        # numpy the module, not "numpy": the same printer and functions, without sympy's
        # ``from numpy import *`` (which imports numpy.f2py, .testing, .ma, ...: 0.1-0.3 s a process)
        return NumericFunctions(sp.lambdify(args, system.mass_matrix(), [np], cse=True),
                                sp.lambdify(args, system.omega(), [np], cse=True) if system.k else None,
                                sp.lambdify(args, system.potential(), [np], cse=True))
    return LAMBDIFIED.get(system, None, lambdify)


def sample_configurations(n: int, count: int, seed: int = 0) -> np.ndarray:
    """Random configurations (count×n) for numeric checks, uniform in [−1.2, 1.2], seeded."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.2, 1.2, size=(count, n))


def parameter_problems(system, values=None, label: str = "the default parameters") -> list:
    """Every problem with a parameter set (``values`` overriding the defaults; a mapping
    name → number or a vector in ``system.param_symbols`` order), as sentences (empty when the
    values are valid)."""
    problems: list = []
    if values is None:
        pv = system.param_vector()
    elif isinstance(values, Mapping):
        unknown = [k for k in values if k not in system.parameters]
        problems += [f"unknown parameter {k!r}{known_names(k, system.parameters, label='parameters')}"
                     for k in unknown]
        merged = dict(system.parameters)
        merged.update({k: number_problems(v, f"parameter {k!r}", problems) for k, v in values.items()
                       if k in system.parameters})
        pv = np.array([merged[s.name] for s in system.param_symbols], dtype=float)
    else:
        pv = np.asarray(values, dtype=float).ravel()
        if pv.size != len(system.param_symbols):
            return [f"expected {len(system.param_symbols)} parameter values "
                    f"({', '.join(system.parameters)}), got {pv.size}"]
        problems += [f"parameter {s.name!r}: {v!r} is not finite"
                     for s, v in zip(system.param_symbols, pv, strict=True)
                     if not np.isfinite(v)]
    return problems or numeric_checks(system, pv, label)


def numeric_checks(system, pv=None, label: str = "the default parameters") -> list:
    """The problems of finite parameter values ``pv`` (default: the system's): M(q) singular
    or not positive definite, dependent constraints, no motion left (k ≥ n)."""
    problems = []
    pv = system.param_vector() if pv is None else pv
    worst, largest, max_rank = _sampled_spectrum(system, pv)
    tiny = 1e-12 * max(1.0, largest)
    if worst is not None and worst[0] <= tiny:
        problems.append(_metric_problem(system, worst, tiny, label))
    if system.k and max_rank < system.k:
        problems.append(f"the constraints are dependent: rank ω(q) = {max_rank} < k = {system.k}"
                        f" at every sampled configuration with {label} (remove redundant constraints)")
    if system.k >= system.n:
        problems.append(f"{system.k} constraints on {system.n} coordinates leave no motion")
    return problems


def _sampled_spectrum(system, pv) -> tuple:
    """At 8 seeded configurations: ((smallest eigenvalue of M, where) or None, the largest
    |eigenvalue|, the largest rank of ω)."""
    mass, omega, _ = numeric_functions(system)
    worst, largest, max_rank = None, 0.0, 0
    for qs in sample_configurations(system.n, 8, seed=1):
        with np.errstate(all="ignore"):
            M = np.array(mass(qs, pv), dtype=float)
        if not np.all(np.isfinite(M)):
            continue
        try:                        # halves first: M + Mᵀ of entries near the largest double overflows
            eigenvalues = np.linalg.eigvalsh(0.5 * M + 0.5 * M.T)
        except np.linalg.LinAlgError:
            continue
        largest = max(largest, abs(eigenvalues[-1]), abs(eigenvalues[0]))
        if worst is None or eigenvalues[0] < worst[0]:
            worst = (eigenvalues[0], qs)
        if omega is not None:
            with np.errstate(all="ignore"):
                W = np.array(omega(qs, pv), dtype=float).reshape(system.k, system.n)
            if np.all(np.isfinite(W)):
                max_rank = max(max_rank, np.linalg.matrix_rank(W, tol=1e-9 * max(1, np.abs(W).max())))
    return worst, largest, max_rank


def _metric_problem(system, worst: tuple, tiny: float, label: str) -> str:
    """The sentence for a singular (|λ_min| ≤ tiny) or indefinite kinetic metric."""
    eigenvalue, where = worst
    zero_rows = [c for c, v in zip(system.coordinates, system.q_dot, strict=True)
                 if all(sp.diff(system.L, v, w) == 0 for w in system.q_dot)]
    extra = f" (no kinetic energy in {', '.join(zero_rows)})" if zero_rows else ""
    at = f"at q = {np.round(where, 3).tolist()} with {label}"
    if abs(eigenvalue) <= tiny:
        return (f"the kinetic metric M(q) = ∂²L/∂q̇² is singular {at}{extra}: a "
                "velocity direction carries no kinetic energy (a zero mass or inertia?)")
    return ("the kinetic metric M(q) = ∂²L/∂q̇² is not positive definite: smallest "
            f"eigenvalue {eigenvalue:.3g} {at}{extra} (a negative mass or inertia?)")
