"""Model only what a scene needs: the states a set of outputs depends on.

A scene may name its outputs (``[simulation].outputs``): state names (``psi``, ``p``,
``pt_phi`` …), velocities (``theta_dot``), names of its ``[quantities]``, or the groups
``shape``, ``fiber``, ``momenta``. The run then integrates only the *dependency closure* S of
those outputs in the right-hand side ż = f(t, z, u): the smallest set of state entries that
contains the outputs' own dependencies and is closed under "ż_i reads z_j" (the structural
Jacobian sparsity of f). For a reduced ODE with a symmetry the fiber (group) coordinates are
never read by the shape and momentum equations, so a shape-and-momentum scene drops them; the
pose is integrated (as the reconstruction quadrature) only when an output asks for it.

Everything here works on CasADi functions of ``model.numeric`` (structural dependencies from the
expression graph), so it applies to any formulation the engine produces.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import ModelError

__all__ = ["closure", "resolve_outputs", "expand_outputs", "OutputSeeds", "GROUPS"]

#: output names that stand for a group of state entries
GROUPS = ("shape", "fiber", "momenta")


def closure(depends: np.ndarray, seeds) -> tuple[int, ...]:
    """Smallest index set S ⊇ seeds with ``depends[i, j]`` false for i ∈ S, j ∉ S.

    Parameters
    ----------
    depends : (N, N) bool — ``depends[i, j]``: entry i of the right-hand side reads state j.
    seeds : iterable of int — states the run must report.

    Returns
    -------
    tuple of int, increasing.
    """
    depends = np.asarray(depends, dtype=bool)
    inside = np.zeros(depends.shape[0], dtype=bool)
    stack = [int(s) for s in seeds]
    while stack:
        i = stack.pop()
        if inside[i]:
            continue
        inside[i] = True
        stack.extend(int(j) for j in np.flatnonzero(depends[i]) if not inside[j])
    return tuple(int(i) for i in np.flatnonzero(inside))


@dataclass(frozen=True)
class OutputSeeds:
    """The outputs of a run resolved to state entries.

    Attributes
    ----------
    names : the output names as given.
    seeds : indices into the formulation's state x whose values the outputs read.
    kinds : per name, "state", "velocity", "quantity" or "group".
    """

    names: tuple
    seeds: tuple
    kinds: tuple


def _reads(expr, x) -> list:
    return [i for i in range(x.shape[0]) if ca.depends_on(expr, x[i])]


def resolve_outputs(model, names, quantities=None) -> OutputSeeds:
    """Map output names to the state entries they read (every unknown name in one error).

    Parameters
    ----------
    model : a derived formulation (``model.numeric``, ``model.state_names``).
    names : sequence of str.
    quantities : optional mapping name → sympy expression of (q, q̇, parameters) (a scene's
        ``[quantities]``).
    """
    num = model.numeric
    system = model.system
    state_names = tuple(model.state_names)
    nx, n = len(state_names), system.n
    x = ca.SX.sym("x", nx)
    params = ca.SX.sym("params", len(num.param_names))
    qdot = num["qdot"](x, params)
    velocity_names = {f"{c}_dot": i for i, c in enumerate(system.coordinates)}
    quantities = dict(quantities or {})
    q_fun = None
    if quantities:
        from ..derivation.quantities import quantity_function
        q_fun = quantity_function(system, quantities)
    problems, seeds, kinds = [], set(), []
    for name in names:
        if name in state_names:
            seeds.add(state_names.index(name))
            kinds.append("state")
        elif name in velocity_names:
            seeds.update(_reads(qdot[velocity_names[name]], x))
            kinds.append("velocity")
        elif name in quantities:
            value = q_fun(x[:n], qdot, params)[list(quantities).index(name)]
            seeds.update(_reads(value, x))
            kinds.append("quantity")
        elif name in GROUPS:
            seeds.update(_group(model, name))
            kinds.append("group")
        else:
            problems.append(f"unknown output {name!r}: outputs are state names "
                            f"({', '.join(state_names)}), velocities (<coordinate>_dot), "
                            f"[quantities] names or the groups {', '.join(GROUPS)}")
    if problems:
        raise ModelError(problems, title="invalid outputs")
    return OutputSeeds(names=tuple(names), seeds=tuple(sorted(seeds)), kinds=tuple(kinds))


def _group(model, name) -> list:
    coords = list(model.system.coordinates)
    n = len(coords)
    fiber = list(getattr(model, "fiber", ()) or ())
    if name == "fiber":
        return [coords.index(c) for c in fiber]
    if name == "shape":
        shape = list(getattr(model, "shape", ()) or [c for c in coords if c not in fiber])
        return [coords.index(c) for c in shape]
    return list(range(n, len(model.state_names)))          # momenta / velocities


def expand_outputs(model, names) -> tuple[str, ...]:
    """The output names with each group replaced by its members (coordinates or state names)."""
    out = []
    state_names = list(model.state_names)
    for name in names:
        if name in GROUPS:
            out += [state_names[i] for i in _group(model, name)]
        else:
            out.append(name)
    return tuple(dict.fromkeys(out))
