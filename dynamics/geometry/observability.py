"""The observability rank of named outputs of the reduced control system at a state.

Math
----
For ż = f(z) + Σ gᵢ(z)uᵢ (the fields of :mod:`.accessibility`) and outputs y = h(z), the
observability codistribution (Hermann–Krener) is spanned by the differentials of h and of its
repeated Lie derivatives L_v h = ∇h·v along v ∈ {f, g₁, …, g_m}. Its rank at z equal to
2n − k means the outputs (and their derivatives under the inputs) determine the state locally;
a state coordinate whose unit direction is in the kernel of every differential is
*unobservable* (no output, however differentiated, changes with it). Lie derivatives by
CasADi forward AD, levels and ranks by the engine of :mod:`.distribution` (relative SVD
rank tolerance :data:`~.distribution.RANK_TOL`).

Outputs are named as the user knows them: coordinates, velocities ``<q>_dot`` (q̇ = X K⁻¹P of
the reduced model), momenta (``model.state_names``) and ``[quantities]`` of the scene in
(q, q̇, parameters).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import ModelError
from ..numerics.bridge import to_casadi
from ..suggestions import known_names
from .accessibility import control_fields
from .distribution import ZERO_TOL, AnalysisPoint, BracketSearch, bracket_levels, generic_point, rank_of

__all__ = ["Observability", "observability"]


@dataclass(frozen=True, kw_only=True)
class Observability:
    """The observability rank of named outputs at a state.

    outputs : the names; rank, dimension : the rank of the codistribution at z and 2n − k;
    depth : the Lie-derivative order that reaches ``rank``; ranks : the rank after each order;
    observable : rank == dimension; unobservable : state names no output sees;
    hidden : unit vectors (in state names) spanning the kernel when it is not spanned by state
    coordinates alone; used : the Lie derivatives that raised the rank (name, order);
    state_names : the names of z.
    """

    outputs: tuple
    rank: int
    dimension: int
    depth: int
    ranks: tuple
    observable: bool
    unobservable: tuple
    hidden: tuple
    used: tuple
    state_names: tuple

    def to_text(self) -> str:
        verdict = ("observable: the outputs and their derivatives determine the state here" if self.observable
                   else "not observable here")
        lines = [f"observability of ({', '.join(self.outputs)}): rank {self.rank} of {self.dimension} "
                 f"(Lie-derivative order {self.depth - 1}); {verdict}"]
        if self.unobservable:
            lines.append(f"  unobservable states: {', '.join(self.unobservable)}")
        for combination in self.hidden:
            lines.append(f"  unobservable direction: {combination}")
        for name, order in self.used:
            lines.append(f"  order {order}: d({name})")
        return "\n".join(lines)


def output_problems(model, outputs, quantities=None) -> list:
    """One sentence per unknown output name (with "did you mean …?"), or none named."""
    velocities = [f"{c}_dot" for c in model.system.coordinates]
    known = list(model.state_names) + velocities + list(quantities or {})
    problems = [f"unknown output {name!r}{known_names(name, known)}" for name in outputs if name not in known]
    if not outputs:
        problems.append("name at least one output (--outputs a,b)")
    return problems


def output_functions(model, outputs, z: ca.SX, params, quantities=None) -> dict:
    """Name → SX scalar of z for every output; one :class:`ModelError` names every unknown one."""
    system = model.system
    n = system.n
    quantities = dict(quantities or {})
    qdot = model.numeric["qdot"](z, params)
    velocities = [f"{c}_dot" for c in system.coordinates]
    problems = output_problems(model, outputs, quantities)
    if problems:
        raise ModelError(problems, title="invalid outputs")
    out = {}
    syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    sx = [z[i] for i in range(n)] + [qdot[i] for i in range(n)] + [ca.SX(float(v)) for v in params]
    for name in outputs:
        if name in model.state_names:
            out[name] = z[list(model.state_names).index(name)]
        elif name in velocities:
            out[name] = qdot[velocities.index(name)]
        else:
            expr = quantities[name]
            extra = sorted(s.name for s in expr.free_symbols if s not in set(syms))
            if extra:
                raise ModelError([f"output {name!r} uses {', '.join(extra)}: an output must be a function "
                                  "of the coordinates, velocities and parameters"], title="invalid outputs")
            out[name] = to_casadi([expr], syms, sx)[0]
    return out


def observability(model, point: AnalysisPoint, outputs, quantities=None) -> Observability:
    """The observability rank of ``outputs`` (names, see the module docstring) at ``point``;
    ``quantities``: the scene's ``[quantities]`` (name → sympy expression of q, q̇, parameters)."""
    z, fields, _ = control_fields(model, point)
    dim = z.shape[0]
    first = output_functions(model, list(outputs), z, point.params, quantities)
    generic = generic_point(point.z, model.system.n)
    levels = bracket_levels(z, fields, point.z, generic,
                            BracketSearch(LieDerivative(z), 2 * dim, first=first,
                                          value_of=lambda h: ca.gradient(h, z)))
    rank = levels.ranks[-1]
    depth = next(j + 1 for j, r in enumerate(levels.ranks) if r == rank)
    rows = np.column_stack([b.value for b in levels.fields]) if levels.fields else np.zeros((dim, 0))
    unobservable, hidden = _kernel(rows, model.state_names, rank)
    return Observability(outputs=tuple(outputs), rank=rank, dimension=dim, depth=depth, ranks=levels.ranks,
                         observable=rank == dim, unobservable=unobservable, hidden=hidden,
                         used=tuple((b.name, b.depth - 1) for b in levels.fields if b.new),
                         state_names=tuple(model.state_names))


@dataclass(frozen=True)
class LieDerivative:
    """L_v h = ∇h·v (forward AD) of a scalar h along a field v of ``x``."""

    x: ca.SX

    def __call__(self, v, h):
        return ca.jtimes(h, self.x, v)

    @staticmethod
    def name(v, h) -> str:
        return f"L_{v} {h}"


def _kernel(rows: np.ndarray, names, rank) -> tuple:
    """The state names in the kernel of every differential (columns of ``rows`` are the
    differentials), and the kernel's other directions as text."""
    dim = rows.shape[0]
    norms = np.linalg.norm(rows, axis=0)
    keep = norms > ZERO_TOL
    O = (rows[:, keep] / norms[keep]).T if keep.any() else np.zeros((0, dim))
    if rank == dim or O.shape[0] == 0:
        return (() if rank == dim else tuple(names)), ()
    _, _, Vt = np.linalg.svd(O)
    kernel = Vt[rank_of(O.T):, :]
    unobservable = tuple(nm for i, nm in enumerate(names) if np.linalg.norm(kernel[:, i]) > 1 - 1e-6)
    projected = kernel.copy()
    projected[:, [names.index(nm) for nm in unobservable]] = 0.0     # kernel ∩ (the named ones)⊥
    hidden = []
    if projected.size:
        _, s_p, V = np.linalg.svd(projected)
        for v in V[:int(np.sum(s_p > 1e-6))]:
            v = v / v[np.argmax(np.abs(v))]
            hidden.append(" + ".join(f"{c:.3g}·{names[i]}" for i, c in enumerate(v) if abs(c) > 1e-9))
    return unobservable, tuple(dict.fromkeys(hidden))
