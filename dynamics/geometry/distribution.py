"""The constraint distribution's growth vector, and the Lie-bracket engine the analyses share.

Math
----
D = null ω(q) ⊂ TQ, spanned by the columns of the reduction's basis X(q) (steps 5–6: ξ_Q^a for
each nonholonomic momentum, named ``X_<p>``, and the horizontal lift X_α of each free shape
coordinate, named ``X_<r>``). Its Lie flag D₁ = D, D_{j+1} = D_j + [D₁, D_j] has ranks
(the *growth vector*) r₁ < r₂ < … < r_s at a regular point; s is the *degree of nonholonomy*;
r_s = n means every configuration near q is reachable (Chow–Rashevskii), r_s < n that the
constraints are partly holonomic (an integral manifold of dimension r_s).

Brackets [a, b] = (∂b/∂x)a − (∂a/∂x)b are formed by CasADi forward AD (``jtimes``) on the
model's own expressions. Each level brackets the generators with the fields kept from the
level before; a field is kept when it raises the rank at a *generic* nearby point (random
shape, velocities of order one): a field dependent there is a function-linear combination of
the kept ones on an open set, so its brackets add nothing new there (the flag is a module).
Ranks are singular-value counts of the fields' values, each normalised to unit length,
σ_i > :data:`RANK_TOL`·σ_max (relative), fields shorter than :data:`ZERO_TOL` counted as zero.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..errors import ModelError, SingularConfigurationError
from ..suggestions import known_names

__all__ = ["AnalysisPoint", "analysis_point", "GrowthVector", "growth_vector", "bracket_levels",
           "BracketSearch", "rank_of", "RANK_TOL"]

#: relative rank tolerance: singular values of the unit-normalised field values below RANK_TOL·σ_max
#: count as zero
RANK_TOL = 1e-8
#: a field (or covector) shorter than this at the point counts as zero there
ZERO_TOL = 1e-10
#: levels in a row that add no direction (at the point or a generic one) before the brackets stop
STALL_LEVELS = 2
#: seed of the generic points the engine keeps fields by (deterministic)
GENERIC_SEED = 20260442


# --------------------------------------------------------------------------- the point

@dataclass(frozen=True, kw_only=True)
class AnalysisPoint:
    """A state of a reduced model where the analyses are evaluated.

    q, qdot : (n,) the configuration and admissible velocities (ω(q)q̇ = 0);
    z : (2n − k,) the reduced state (q, P) in ``model.state_names`` order; u : (inputs,);
    params : (parameters,) the parameter vector; at_rest : q̇ = 0.
    """

    q: np.ndarray
    qdot: np.ndarray
    z: np.ndarray
    u: np.ndarray
    params: np.ndarray
    at_rest: bool

    def describe(self, model) -> str:
        """``x=0, y=0, …`` of the coordinates, and the velocities that are not zero."""
        names = model.system.coordinates
        parts = [f"{c}={_num(v)}" for c, v in zip(names, self.q, strict=True)]
        parts += [f"{c}_dot={_num(v)}" for c, v in zip(names, self.qdot, strict=True) if abs(v) > ZERO_TOL]
        parts += [f"{c}={_num(v)}" for c, v in zip(model.system.inputs, self.u, strict=True) if v]
        return ", ".join(parts) + (" (at rest)" if self.at_rest else "")


def _num(v) -> str:
    return f"{float(v):.6g}"


def analysis_point(model, at=None, *, q0=None) -> AnalysisPoint:
    """The state named by ``at`` (a mapping name → value): coordinates, velocities ``<q>_dot``
    or momenta (``model.state_names``), inputs and parameters; everything not named is 0 (the
    configuration: ``q0`` when given), so the default is rest. Velocities named are completed
    to admissible ones (the least-norm q̇ = X(q)c with those components); every unknown name,
    conflicting value or violated constraint is one problem of one :class:`ModelError`."""
    system, num = model.system, model.numeric
    at = dict(at or {})
    names, n = system.coordinates, system.n
    velocities = [f"{c}_dot" for c in names]
    momenta = list(model.state_names[n:])
    params_names = [s.name for s in system.param_symbols]
    problems = point_problems(model, at)
    if problems:
        raise ModelError(problems, title="invalid point")
    q = np.array(q0 if q0 is not None else np.zeros(n), dtype=float)
    for i, c in enumerate(names):
        q[i] = float(at.get(c, q[i]))
    params = system.param_vector({k: float(v) for k, v in at.items() if k in params_names})
    u = np.array([float(at.get(c, 0.0)) for c in system.inputs])
    if system.k and abs(float(num.call("singular", q, params))) < ZERO_TOL:
        where = ", ".join(f"{c}={_num(v)}" for c, v in zip(names, q, strict=True))
        raise SingularConfigurationError([f"q = ({where}) is on the singular set "
                                          f"({model.singular_set_text()}); choose another configuration "
                                          "with --at name=value"])
    z = np.concatenate([q, np.zeros(len(momenta))])
    if any(k in momenta for k in at):
        z[n:] = [float(at.get(c, 0.0)) for c in momenta]
        qdot = np.asarray(num.call("qdot", z, params), dtype=float).ravel()
    else:
        given = {i: float(at[c]) for i, c in enumerate(velocities) if c in at}
        qdot = _admissible_velocity(model, q, params, given)
        z = np.asarray(num.call("state", q, qdot, params), dtype=float).ravel()
    rest = bool(np.all(np.abs(qdot) <= ZERO_TOL))
    return AnalysisPoint(q=q, qdot=qdot, z=z, u=u, params=params, at_rest=rest)


def point_problems(model, at: dict) -> list:
    """One sentence per unknown name, conflicting choice or value that is not a finite number
    of an ``at`` mapping (see :func:`analysis_point`), with "did you mean …?"."""
    system, n = model.system, model.system.n
    velocities = [f"{c}_dot" for c in system.coordinates]
    momenta = list(model.state_names[n:])
    known = (list(system.coordinates) + velocities + momenta + list(system.inputs)
             + [s.name for s in system.param_symbols])
    problems = [f"unknown name {k!r} in --at{known_names(k, known)}" for k in at if k not in known]
    if any(k in velocities for k in at) and any(k in momenta for k in at):
        problems.append("give the velocities (<q>_dot) or the momenta (" + ", ".join(momenta) + "), not both")
    problems += [f"{k} = {v} is not a finite number" for k, v in at.items() if not np.isfinite(float(v))]
    return problems


def _admissible_velocity(model, q, params, given: dict) -> np.ndarray:
    """The least-norm admissible q̇ = X(q)c whose components ``given`` (index → value) are met;
    a :class:`ModelError` when the constraints forbid them."""
    n = model.system.n
    if not given:
        return np.zeros(n)
    z = np.concatenate([q, np.zeros(len(model.state_names) - n)])
    X = np.asarray(model.numeric.call("basis", z, params), dtype=float).reshape(n, -1)
    rows = sorted(given)
    target = np.array([given[i] for i in rows])
    c, *_ = np.linalg.lstsq(X[rows, :], target, rcond=None)
    qdot = X @ c
    miss = np.abs(qdot[rows] - target).max()
    if miss > 1e-9 * max(1.0, np.abs(target).max()):
        names = model.system.coordinates
        named = ", ".join(f"{names[i]}_dot={_num(given[i])}" for i in rows)
        raise ModelError([f"the velocities {named} break the constraints at this configuration (the closest "
                          f"admissible ones miss by {miss:.3g}); name fewer velocities or admissible ones"],
                         title="invalid point")
    return qdot


# --------------------------------------------------------------------------- the engine

def rank_of(values: np.ndarray) -> int:
    """Rank of the columns of ``values``: each normalised to unit length (zero columns dropped),
    singular values above RANK_TOL·σ_max."""
    norms = np.linalg.norm(values, axis=0)
    keep = norms > ZERO_TOL
    if not keep.any():
        return 0
    s = np.linalg.svd(values[:, keep] / norms[keep], compute_uv=False)
    return int(np.sum(s > RANK_TOL * s[0]))


@dataclass(frozen=True)
class Bracket:
    """One field of a bracket level: its ``name`` (``[X_psi, X_phi]``), ``depth``, its value
    at the point and whether it raised the rank there (``new``)."""

    name: str
    depth: int
    value: np.ndarray
    new: bool


@dataclass(frozen=True)
class BracketLevels:
    """The levels of a bracket computation: ``ranks[j]`` the rank at the point of every field
    up to depth j + 1, ``fields`` every field evaluated (in order), ``stalled``: the last level
    added nothing at a generic point (the flag is closed)."""

    ranks: tuple
    fields: tuple
    stalled: bool


def _evaluator(x: ca.SX, exprs: list, value_of=None):
    if value_of is not None:
        exprs = [value_of(e) for e in exprs]
    f = ca.Function("fields", [x], [ca.horzcat(*exprs)])
    return lambda point: np.asarray(f(point), dtype=float).reshape(x.shape[0], len(exprs), order="F")


@dataclass(frozen=True)
class BracketSearch:
    """How :func:`bracket_levels` brackets: ``combine(a, b)`` forms the new element (a
    :class:`LieBracket`, or a Lie derivative for covectors), at most ``max_depth`` levels;
    ``first``: the elements of level 1 when they are not the generators (the outputs of an
    observability test); ``value_of``: what an element's value is (its gradient, for
    functions), the element itself by default."""

    combine: object
    max_depth: int
    first: dict | None = None
    value_of: object = None


def bracket_levels(x: ca.SX, generators: dict, point: np.ndarray, generic: np.ndarray,
                   search: BracketSearch) -> BracketLevels:
    """Levels 1 … ``search.max_depth`` of brackets of ``generators`` (name → SX column of ``x``).

    ``search.combine(a, b)`` forms the new element from a generator ``a`` and a kept element ``b``
    (a Lie bracket of fields, or a Lie derivative for covectors: then ``x``-columns are the
    gradients, see :mod:`.observability`). ``point``: where ranks are reported; ``generic``: a
    generic nearby point. A level keeps, for the next, the fields that raise the rank at the
    point or at the generic point, then others not zero at the generic point up to
    ``len(x)`` fields (a field dependent at the point may still have brackets that are not).
    Stops when the rank at the point is full, after :data:`STALL_LEVELS` levels that add
    nothing at either point, or at ``max_depth`` (:class:`BracketSearch`).
    """
    combine, first, value_of = search.combine, search.first, search.value_of
    dim = x.shape[0]
    names, exprs = list(generators), [generators[k] for k in generators]
    fields, ranks = [], []
    at_point, at_generic = np.zeros((dim, 0)), np.zeros((dim, 0))
    level = list((first or generators).items())
    stalled, idle = False, 0
    for depth in range(1, search.max_depth + 1):
        ev = _evaluator(x, [e for _, e in level], value_of)
        vp, vg = ev(point), ev(generic)
        kept, spare, grew = [], [], False
        for j, (name, expr) in enumerate(level):
            new_p = rank_of(np.column_stack([at_point, vp[:, j]])) > rank_of(at_point)
            new_g = rank_of(np.column_stack([at_generic, vg[:, j]])) > rank_of(at_generic)
            fields.append(Bracket(name=name, depth=depth, value=vp[:, j], new=new_p))
            if new_p or new_g:
                at_point = np.column_stack([at_point, vp[:, j]])
                at_generic = np.column_stack([at_generic, vg[:, j]])
                kept.append((name, expr))
                grew = True
            elif np.linalg.norm(vg[:, j]) > ZERO_TOL or np.linalg.norm(vp[:, j]) > ZERO_TOL:
                spare.append((name, expr))
        kept += spare[:max(0, dim - len(kept))]
        ranks.append(rank_of(at_point))
        idle = 0 if grew else idle + 1
        if ranks[-1] == dim:
            break
        if idle >= STALL_LEVELS or not kept:
            stalled = True
            break
        # level 2 of the generators: [a, a] = 0 and [b, a] = −[a, b] are left out
        pairs = [(a, ea, b, eb) for a, ea in zip(names, exprs, strict=True) for b, eb in kept
                 if first is not None or depth > 1 or names.index(b) > names.index(a)]
        level = [(combine.name(a, b), combine(ea, eb)) for a, ea, b, eb in pairs]
    return BracketLevels(ranks=tuple(ranks), fields=tuple(fields), stalled=stalled)


@dataclass(frozen=True)
class LieBracket:
    """[a, b] = (∂b/∂x)a − (∂a/∂x)b by forward AD (``jtimes``) in the variables ``x``."""

    x: ca.SX

    def __call__(self, a, b):
        return ca.jtimes(b, self.x, a) - ca.jtimes(a, self.x, b)

    @staticmethod
    def name(a, b) -> str:
        return f"[{a}, {b}]"


def lie_bracket(x: ca.SX) -> LieBracket:
    """The Lie bracket of fields of ``x`` (see :class:`LieBracket`)."""
    return LieBracket(x)


def generic_point(point: np.ndarray, n_q: int, seed: int = GENERIC_SEED) -> np.ndarray:
    """A generic point near ``point``: the coordinates moved by up to 0.3 rad, the rest (momenta)
    drawn of order one."""
    rng = np.random.default_rng(seed)
    out = np.array(point, dtype=float)
    out[:n_q] += rng.uniform(-0.3, 0.3, n_q)
    out[n_q:] = rng.uniform(0.5, 1.0, out.size - n_q) * rng.choice([-1.0, 1.0], out.size - n_q)
    return out


def vector_text(value: np.ndarray, names) -> str:
    """``(x: 1, theta: -0.5)``: the components of ``value`` above 1e-9 of its largest."""
    scale = max(np.abs(value).max(), ZERO_TOL)
    parts = [f"{nm}: {v:.4g}" for nm, v in zip(names, value, strict=True) if abs(v) > 1e-9 * scale]
    return "(" + ", ".join(parts) + ")" if parts else "0"


# --------------------------------------------------------------------------- the growth vector

@dataclass(frozen=True, kw_only=True)
class GrowthVector:
    """The growth vector of D = null ω(q) at a configuration.

    ranks : (r₁, r₂, …) ranks of D, D + [D, D], … until they stop growing;
    degree_of_nonholonomy : len(ranks); n : the number of coordinates;
    generators : names of the basis fields of D (``X_<momentum>``, ``X_<shape coordinate>``)
    with their values at q; new_directions : per level j ≥ 2 the brackets that raised the rank
    and their values (in the coordinates' names); coordinates : the names.
    """

    ranks: tuple
    degree_of_nonholonomy: int
    n: int
    generators: tuple
    new_directions: tuple
    coordinates: tuple
    symbolic: dict = field(default_factory=dict)

    @property
    def spans_everything(self) -> bool:
        """r_s = n: every nearby configuration is reachable (Chow–Rashevskii)."""
        return self.ranks[-1] == self.n

    def to_text(self) -> str:
        lines = [f"growth vector of the constraint distribution D: ({', '.join(map(str, self.ranks))}), "
                 f"degree of nonholonomy {self.degree_of_nonholonomy}"]
        if self.spans_everything:
            lines.append(f"  D and its brackets span all {self.n} directions: every nearby configuration is "
                         "reachable (Chow–Rashevskii)")
        else:
            lines.append(f"  D and its brackets span only {self.ranks[-1]} of {self.n} directions: part of "
                         "the constraints is holonomic (the motion stays on a submanifold)")
        for name, value in self.generators:
            lines.append(f"  {name} = {vector_text(value, self.coordinates)}{self._formula(name)}")
        for depth, found in enumerate(self.new_directions, start=2):
            for name, value in found:
                lines.append(f"  depth {depth}: {name} = {vector_text(value, self.coordinates)} (new)"
                             f"{self._formula(name)}")
        return "\n".join(lines)

    def expression(self, name) -> dict:
        """The symbolic components of bracket ``name`` (coordinate → text), {} when not computed."""
        column = self.symbolic.get(name)
        if column is None:
            return {}
        return {c: str(e) for c, e in zip(self.coordinates, column, strict=True) if e != 0}

    def _formula(self, name) -> str:
        parts = self.expression(name)
        if not parts:
            return ""
        return "\n      in general: (" + ", ".join(f"{c}: {e}" for c, e in parts.items()) + ")"


def distribution_fields(model, params: np.ndarray):
    """The basis of D as SX columns of q (name → column) and the SX symbol q."""
    system = model.system
    n = system.n
    q = ca.SX.sym("q", n)
    z = ca.vertcat(q, ca.SX(ca.DM.zeros(len(model.state_names) - n, 1)))
    X = model.numeric["basis"](z, params)
    d = model.layout.d
    labels = [f"X_{m}" for m in model.state_names[n:n + d]] + [
        f"X_{system.coordinates[i]}" for i in model.layout.free]
    return q, {label: X[:, j] for j, label in enumerate(labels)}


def growth_vector(model, point: AnalysisPoint) -> GrowthVector:
    """The growth vector of the constraint distribution at ``point.q`` (see the module docstring)."""
    system = model.system
    q, gens = distribution_fields(model, point.params)
    generic = generic_point(point.q, system.n)
    levels = bracket_levels(q, gens, point.q, generic, BracketSearch(lie_bracket(q), system.n))
    ranks = list(levels.ranks)
    while len(ranks) > 1 and ranks[-1] == ranks[-2]:      # the levels that added nothing at q
        ranks.pop()
    new = [tuple((b.name, b.value) for b in levels.fields if b.depth == depth and b.new)
           for depth in range(2, len(levels.ranks) + 1)]
    while new and not new[-1]:
        new.pop()
    generators = tuple((b.name, b.value) for b in levels.fields if b.depth == 1)
    named = [name for name, _ in generators] + [name for found in new for name, _ in found]
    return GrowthVector(ranks=tuple(ranks), degree_of_nonholonomy=len(ranks), n=system.n,
                        generators=generators, new_directions=tuple(new),
                        coordinates=tuple(system.coordinates), symbolic=symbolic_brackets(model, named))


#: largest number of coordinates whose brackets are also written symbolically (explicit form)
SYMBOLIC_MAX_N = 6


def symbolic_brackets(model, names) -> dict:
    """Bracket name (``[X_p, [X_p, X_phi]]``) → its sympy column, by sympy differentiation of the
    explicit model's basis X(q) (simplified by the trigonometric normal form); {} for the
    implicit form or more than :data:`SYMBOLIC_MAX_N` coordinates. "Symbolic where cheap": the
    ranks stay numeric, the formulas say what each direction is everywhere."""
    import sympy as sp

    from ..algebra.trig import tidy
    if model.form != "explicit" or model.system.n > SYMBOLIC_MAX_N:
        return {}
    system, d = model.system, model.layout.d
    q = sp.Matrix(system.q)
    labels = [f"X_{m}" for m in model.state_names[system.n:system.n + d]] + [
        f"X_{system.coordinates[i]}" for i in model.layout.free]
    memo = {label: model.X[:, j] for j, label in enumerate(labels)}

    def column(name):
        if name not in memo:
            a, b = name[1:-1].split(", ", 1)            # "[a, b]": a generator, b a bracket
            ca_, cb = column(a), column(b)
            memo[name] = tidy(cb.jacobian(q) * ca_ - ca_.jacobian(q) * cb)
        return memo[name]
    return {name: column(name) for name in names}
