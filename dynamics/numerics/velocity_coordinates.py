"""Velocity coordinates: the rows y = Y(q) q̇, where they determine the motion, and the choice.

A reduced model has n − k velocity degrees of freedom; the planner states its problems in
n − k velocity quantities y = Y(q) q̇ (:mod:`.specialisation`). Given y, the velocities solve

    A(q) ξ̄ = (0, y),    A(q) = [ω_b(q); Y_b(q)]  (n × n),                          (1)

with ξ̄ = (ξ, ṙ) the body velocities of the reduction's layout (ξ = g⁻¹ṡ, ṡ the fiber
velocities; forward_velocity = ξ₁ and θ̇ = ξ₃ for SE(2)), ω_b = ω diag(g, I) the constraints
and Y_b = Y diag(g, I) the rows in those velocities (step 5 of the reduction). The velocity
states determine the motion exactly where A is regular, and |det A| = |det [ω; Y]| (g is a
rotation or the identity): a set that belongs to the robot and the names — *not* to the
reduction's chart, whose pivot block may be singular elsewhere (the 3-link snake's chart with
fiber (x, y, θ) is singular where the three axles' lines meet, α₁ = α₂; the velocities
(forward_velocity, α̇₁) determine the motion for every |α₁| < π, (θ̇, α̇₁) everywhere but
α₁ = 0, where the front link's no-slip row has coefficient −sin α₁ on the forward velocity).

* :func:`velocity_rows`, :func:`row_function` — Y(q) (sympy, CasADi).
* :func:`velocity_map` — A(q) of (1) with the parameter values bound; :func:`velocity_measure`
  its normalised determinant |det A| / Π‖rows of A‖ ∈ [0, 1] (0 exactly where (1) is singular).
* :func:`choose_velocities` — the names a planner uses when the task names none.
"""
from __future__ import annotations

from itertools import combinations

import casadi as ca
import numpy as np

from ..errors import ModelError

__all__ = ["BODY_VELOCITIES", "body_velocity", "planar_frame", "velocity_problems", "velocity_rows",
           "row_function", "body_rows", "velocity_map", "velocity_measure", "choose_velocities",
           "REGULAR_RATIO", "BOX_SAMPLES", "CONDITION_RATIO", "region_samples", "group_matrix"]

#: planar body velocities of a frame (x, y, heading θ): coefficients of (ẋ, ẏ)
BODY_VELOCITIES = ("forward_velocity", "lateral_velocity")
#: velocity names whose det A keeps one sign over the task's region and whose normalised |det A|
#: stays above this fraction of its largest value there count as regular in it
#: (:func:`choose_velocities`; the normalised determinant of an n × n map shrinks with n, so the
#: test is relative: a 10-coordinate cart's ranges over [4e-6, 1e-4])
REGULAR_RATIO = 1e-3
#: configurations sampled in the task's region by :func:`choose_velocities`
BOX_SAMPLES = 96
#: a set regular over the region is chosen only when its smallest normalised measure there is
#: within this factor of the best regular set's (:func:`choose_velocities`)
CONDITION_RATIO = 10.0
_RANK_TOL = 1e-8
_COMBINATIONS = 5000     # sets of names examined at most (in order of preference)


def body_velocity(name: str, x_dot, y_dot, heading, cos, sin):
    """The planar body velocity ``name`` of a frame (x, y, θ), in any algebra (sympy, CasADi):

    forward_velocity = ẋ cos θ + ẏ sin θ,   lateral_velocity = −ẋ sin θ + ẏ cos θ.

    The one definition shared by the specialisation (velocity coordinates) and
    :mod:`nhgait.ocp.problem` (conditions on quantities).
    """
    c, s = cos(heading), sin(heading)
    if name == "forward_velocity":
        return x_dot * c + y_dot * s
    if name == "lateral_velocity":
        return -x_dot * s + y_dot * c
    raise KeyError(name)


def planar_frame(system):
    """The system's planar frame (x, y, heading) names, or None."""
    frame = getattr(system, "planar_frame", None)
    if frame is None and {"x", "y", "theta"} <= set(system.coordinates):
        frame = ("x", "y", "theta")
    return tuple(frame) if frame else None


def velocity_problems(system, names, quantities) -> list:
    """What is wrong with ``names`` as velocity quantities (unknown names, repetitions)."""
    coords = tuple(system.coordinates)
    problems = []
    for name in names:
        if name.endswith("_dot") and name[:-4] in coords:
            continue
        if name in BODY_VELOCITIES and planar_frame(system):
            continue
        if name in quantities:
            continue
        problems.append(f"velocities: {name!r} is not a velocity quantity (use <coordinate>_dot for "
                        f"{', '.join(coords)}" + (", forward_velocity, lateral_velocity"
                                                  if planar_frame(system)
                                                  else "") + (f" or a quantity {', '.join(quantities)}"
                                                             if quantities else "") + ")")
    if len(set(names)) != len(names):
        problems.append(f"velocities: repeated names in {tuple(names)}")
    return problems


def velocity_rows(system, names, quantities=None):
    """Rows Y(q) (sympy Matrix, len(names) × n) of the quantities y = Y(q) q̇.

    Raises :class:`ModelError` listing every name that is unknown or not linear in q̇.
    """
    import sympy as sp
    quantities = dict(quantities or {})
    problems = velocity_problems(system, names, quantities)
    coords = tuple(system.coordinates)
    q, qd = list(system.q), list(system.q_dot)
    rows = []
    for name in names:
        row = [sp.S.Zero] * len(coords)
        if name.endswith("_dot") and name[:-4] in coords:
            row[coords.index(name[:-4])] = sp.S.One
        elif name in BODY_VELOCITIES and planar_frame(system):
            ix, iy, ih = (coords.index(c) for c in planar_frame(system))
            expr = body_velocity(name, qd[ix], qd[iy], q[ih] + getattr(system, "forward_angle", 0),
                                 sp.cos, sp.sin)
            row = [sp.diff(expr, v) for v in qd]
        elif name in quantities:
            expr = sp.expand(quantities[name])
            row = [sp.diff(expr, v) for v in qd]
            rest = sp.expand(expr - sum(r * v for r, v in zip(row, qd, strict=True)))
            if any(r.has(*qd) for r in row) or rest != 0:
                problems.append(f"velocities: quantity {name!r} is not linear in the velocities "
                                "(y = Y(q) q̇ is required for a velocity state)")
        rows.append(row)
    if problems:
        raise ModelError(problems, title="invalid velocity coordinates")
    return sp.Matrix(rows)


def row_function(model, names, quantities) -> ca.Function:
    """Y(q, params) as a CasADi Function (nv × n), from :func:`velocity_rows`."""
    from .bridge import to_casadi
    system = model.system
    Y = velocity_rows(system, names, quantities)
    n, npar = system.n, len(system.param_symbols)
    q, params = ca.SX.sym("q", n), ca.SX.sym("params", npar)
    syms = list(system.q) + list(system.param_symbols)
    sx = [q[i] for i in range(n)] + [params[i] for i in range(npar)]
    entries = to_casadi(list(Y.T), syms, sx) if Y.rows else []
    Ysx = ca.reshape(ca.vertcat(*entries), len(names), n) if entries else ca.SX(0, n)
    return ca.Function("Y", [q, params], [Ysx], ["q", "params"], ["Y"])


def group_matrix(layout):
    """diag(g(q), I) (sympy, n × n): body velocities ξ̄ = (ξ, ṙ) to q̇ (g the identity in
    version A, the planar rotation by the heading in version B)."""
    import sympy as sp
    G = sp.eye(layout.system.n)
    if layout.version == "B":
        si = list(layout.si)
        for a, i in enumerate(si):
            for b, j in enumerate(si):
                G[i, j] = layout.g[a, b]
    return G


def body_rows(model, names, quantities=None):
    """Y_b = Y(q) diag(g(q), I) (sympy, trigonometric normal form): the rows of ``names`` in the
    body velocities of the model's layout (forward_velocity → ξ₁, θ̇ → ξ₃ for SE(2))."""
    from ..algebra.trig import trig_normal
    rows = velocity_rows(model.system, names, quantities) * group_matrix(model.layout)
    return rows.applyfunc(trig_normal)


def velocity_map(model, params, names, quantities=None) -> ca.Function:
    """A(q) = [ω_b(q); Y_b(q)] of eq. (1) (CasADi, (k + len(names)) × n, the parameter values
    ``params`` bound): the constraints then the rows of ``names``, in body velocities."""
    from .bridge import to_casadi
    layout, system = model.layout, model.system
    n = system.n
    subs = {s: float(v) for s, v in zip(system.param_symbols, params, strict=True)}
    rows = layout.Wb.xreplace(subs).col_join(body_rows(model, names, quantities).xreplace(subs))
    q = ca.SX.sym("q", n)
    entries = to_casadi(list(rows.T), list(system.q), [q[i] for i in range(n)])
    return ca.Function("velocity_map", [q], [ca.reshape(ca.vertcat(*entries), rows.rows, n)], ["q"], ["A"])


def velocity_measure(A: ca.SX) -> ca.SX:
    """|det A| / Π‖rows of A‖ ∈ [0, 1] (Hadamard) of a square SX matrix, by QR."""
    _, R = ca.qr(A)
    out, norm = ca.SX(1), ca.SX(1)
    for i in range(A.shape[0]):
        out = out * ca.fabs(R[i, i])
        norm = norm * ca.norm_2(A[i, :].T)
    return out / (norm + 1e-300)


# ----------------------------------------------------------------------------- the choice
def _candidates(model, preferred, quantities) -> list:
    """Velocity names to choose from, in order of preference: the task's, the shape rates,
    the planar body velocities, the fiber rates (unknown and non-linear names dropped)."""
    system = model.system
    out = []
    for name in list(preferred) + [f"{c}_dot" for c in tuple(model.shape)] + list(
            BODY_VELOCITIES if planar_frame(system) else ()) + [f"{c}_dot" for c in tuple(model.fiber)]:
        if name not in out and not velocity_problems(system, [name], quantities):
            try:
                velocity_rows(system, [name], quantities)
            except ModelError:
                continue
            out.append(name)
    return out


def region_samples(coordinates, bounds, points=(), count: int = BOX_SAMPLES, seed: int = 7) -> np.ndarray:
    """(count + len(points) + 1) × n configurations: ``points``, the centre of the region and
    uniform samples in it (``bounds``: name → (lo, hi); an unbounded coordinate spans [−π, π])."""
    lo = np.array([bounds.get(c, (-np.pi, np.pi))[0] for c in coordinates], dtype=float)
    hi = np.array([bounds.get(c, (-np.pi, np.pi))[1] for c in coordinates], dtype=float)
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    rng = np.random.default_rng(seed)
    fixed = [np.asarray(p, float) for p in points] + [(lo + hi) / 2]
    return np.vstack(fixed + [rng.uniform(lo, hi) for _ in range(count)])


def _signed_measures(A: np.ndarray, rows: list) -> np.ndarray:
    """det A[:, rows] / Π‖rows‖ at every sample (A: samples × rows × n)."""
    sub = A[:, rows, :]
    with np.errstate(all="ignore"):
        return np.linalg.det(sub) / np.prod(np.linalg.norm(sub, axis=2), axis=1)


def choose_velocities(model, preferred=(), quantities=None, params=None, bounds=None,
                      points=()) -> tuple[str, ...]:
    """n − k velocity quantities that determine the allowed velocities, ``preferred`` first.

    Candidates, in order: ``preferred`` (names a task uses), the shape velocities, the planar
    body velocities, the fiber velocities. The sets of n − k candidates are examined in that
    order (lexicographically) with the normalised determinant of A (eq. (1), chart-free) at
    the configurations ``points`` (the task's fixed ends), the centre of the region ``bounds``
    (name → (lo, hi); unbounded coordinates over [−π, π]) and :data:`BOX_SAMPLES` samples in it:

    1. the first set whose determinant keeps one sign and whose measure stays above
       :data:`REGULAR_RATIO` of its largest value — regular over the whole region, so no guess
       and no iterate of the planner meets its singular set (the 3-link snake with |α| ≤ 1:
       (θ̇, forward_velocity), not (θ̇, α̇₁), singular at α₁ = 0, nor (α̇₁, α̇₂), singular at
       α₁ = α₂) — and whose smallest measure there is within :data:`CONDITION_RATIO` of the
       best such set's (a 5-link chain's (ẋ, ẏ, q̇₄) is regular over the region but 300× worse
       conditioned than (q̇₃, q̇₄, forward_velocity): its equations are stiff, its optimum was
       accurate only to 3e-3 at 128 RK4 sub-steps per interval);
    2. else the first set regular (measure > 1e-8 of its largest) at every sample and well away
       from its singular set (above :data:`REGULAR_RATIO` of its largest) at the task's fixed
       ends, where every guess starts or ends (a car whose base is its last trailer, turned by
       π/2: ẋ of that trailer does not determine the motion there, its forward velocity does);
       else the first regular at every sample — the planner's guesses are then screened
       against its singular set (:mod:`nhgait.gaits.planning.screening`).

    Raises :class:`ModelError` when no set is regular at the samples.
    """
    system = model.system
    quantities = dict(quantities or {})
    params = np.asarray(model.numeric.params(params), dtype=float)
    nv, k = len(model.state_names) - system.n, system.k
    names = _candidates(model, preferred, quantities)
    if not names:
        raise ModelError([f"no velocity quantities parametrise the allowed velocities of {system.name}"],
                         title="invalid velocity coordinates")
    A_of = velocity_map(model, params, names, quantities)
    qs = region_samples(tuple(system.coordinates), dict(bounds or {}), points)
    with np.errstate(all="ignore"):
        A = np.asarray(A_of.map(qs.shape[0])(qs.T)).reshape(k + len(names), qs.shape[0], system.n)
    A = np.transpose(A, (1, 0, 2))
    fallback, at_ends, regular = None, None, []
    ends = len(points)
    for count, chosen in enumerate(combinations(range(len(names)), nv)):
        if count == _COMBINATIONS:
            break
        m = _signed_measures(A, list(range(k)) + [k + i for i in chosen])
        scale = float(np.max(np.abs(m))) if np.all(np.isfinite(m)) else 0.0
        if not scale > _RANK_TOL or not np.all(np.abs(m) > _RANK_TOL * scale):
            continue
        if np.all(np.abs(m) >= REGULAR_RATIO * scale) and (np.all(m > 0) or np.all(m < 0)):
            regular.append((chosen, float(np.min(np.abs(m)))))
            continue
        fallback = fallback or chosen
        if at_ends is None and np.all(np.abs(m[:ends]) >= REGULAR_RATIO * scale):
            at_ends = chosen
    if regular:
        best = max(measure for _, measure in regular)
        chosen = next(c for c, measure in regular if measure >= best / CONDITION_RATIO)
        return tuple(names[i] for i in chosen)
    if fallback is not None:
        return tuple(names[i] for i in (at_ends or fallback))
    raise ModelError([f"no {nv} velocity quantities among {', '.join(names)} parametrise the "
                      f"allowed velocities of {system.name}"], title="invalid velocity coordinates")
