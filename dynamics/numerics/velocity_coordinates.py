"""Velocity coordinates of a reduced model: the velocity quantities y = Y(q) q̇ that may replace
the momenta as states (:mod:`.specialisation` builds the equations in them).

The candidates are ``<coordinate>_dot``, the planar body velocities (:func:`body_velocity`) and
named quantities linear in q̇ (:func:`velocity_rows` gives Y(q), :func:`row_function` its CasADi
Function); with q̇ = Q(q) P (:func:`momentum_basis`) the momenta are P = (Y Q)⁻¹ y, so
:func:`choose_velocities` picks n − k candidates whose B = Y Q is regular.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import ModelError

__all__ = ["BODY_VELOCITIES", "body_velocity", "planar_frame", "velocity_problems", "velocity_rows",
           "row_function", "momentum_basis", "choose_velocities"]

#: planar body velocities of a frame (x, y, heading θ): coefficients of (ẋ, ẏ)
BODY_VELOCITIES = ("forward_velocity", "lateral_velocity")

#: a velocity candidate whose row of B shrinks below this fraction of its largest norm somewhere
#: is placed after the others (:func:`choose_velocities`)
DEGENERATE_SPREAD = 0.05


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


# ----------------------------------------------------------------------------- velocity rows
def planar_frame(system):
    frame = getattr(system, "planar_frame", None)
    if frame is None and {"x", "y", "theta"} <= set(system.coordinates):
        frame = ("x", "y", "theta")
    return tuple(frame) if frame else None


def velocity_problems(system, names, quantities) -> list:
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
                        f"{', '.join(coords)}" + (", forward_velocity, lateral_velocity" if planar_frame(system)
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
            rest = sp.expand(expr - sum(r * v for r, v in zip(row, qd)))
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


def momentum_basis(model, params) -> ca.Function:
    """Q(q) with q̇ = Q(q) P (q̇ is linear in the momenta), by automatic differentiation."""
    n, nz = model.system.n, len(model.state_names)
    q, P = ca.SX.sym("q", n), ca.SX.sym("P", nz - n)
    qdot = model.numeric["qdot"](ca.vertcat(q, P), params)
    Q = ca.substitute(ca.jacobian(qdot, P), P, ca.DM.zeros(nz - n))
    return ca.Function("Q", [q], [Q])


@dataclass(frozen=True, eq=False)
class _CandidateRows:
    """B(q) = Y(q) Q(q): one row per candidate velocity, in the momenta (q̇ = Q(q) P, ``Q``; the
    candidates' rows in q̇, ``Y``), at the parameter values ``params``."""

    Y: ca.Function
    Q: ca.Function
    params: np.ndarray

    @property
    def count(self) -> int:
        return self.Y.size1_out(0)

    def at(self, q) -> np.ndarray:
        return np.asarray(self.Y(q, self.params)) @ np.asarray(self.Q(q))


def choose_velocities(model, preferred=(), quantities=None, params=None, bounds=None, points=()) -> tuple:
    """n − k velocity quantities that parametrise the allowed velocities, ``preferred`` first.

    Candidates: ``preferred`` (names a task uses), the shape velocities, the planar body
    velocities, the fiber velocities. A candidate whose row of B = Y Q (q̇ = Q P) nearly
    vanishes somewhere — its norm over configurations within ``bounds`` (name → (lo, hi); other
    coordinates over [−π, π]; samples near the model's singular set skipped) varies by more
    than :data:`DEGENERATE_SPREAD` — comes after the others: a state built on it is singular
    wherever the row vanishes (ẋ of a unicycle is r cos θ φ̇, zero for every φ̇ at θ = ±π/2,
    where (ẋ, θ̇) stop determining the motion). Within each group the order above is kept. A
    candidate is taken when it raises the rank of B at three random configurations and at
    ``points`` (configurations the task fixes, where the state must be regular: a cart with
    three trailers starting straight has θ̇ and β̇₁ dependent there, β̇₁ = −θ̇), the smallest
    singular value > 1e-8 of the largest.
    """
    system = model.system
    quantities = dict(quantities or {})
    params = np.asarray(model.numeric.params(params), dtype=float)
    n, nv = system.n, len(model.state_names) - system.n
    candidates = []
    for name in list(preferred) + [f"{c}_dot" for c in tuple(model.shape)] + list(
            BODY_VELOCITIES if planar_frame(system) else ()) + [f"{c}_dot" for c in tuple(model.fiber)]:
        if name not in candidates and not velocity_problems(system, [name], quantities):
            try:
                velocity_rows(system, [name], quantities)
            except ModelError:
                continue
            candidates.append(name)
    Q = momentum_basis(model, params)
    rng = np.random.default_rng(7)
    samples = [rng.uniform(-0.7, 0.7, n) for _ in range(3)] + [np.asarray(point, float) for point in points]
    rows = _CandidateRows(row_function(model, candidates, quantities), Q, params) if candidates else None
    with np.errstate(all="ignore"):
        B_all = [rows.at(q) for q in samples] if rows else []
    B_all = [B for B in B_all if np.all(np.isfinite(B))]      # a point on the chart's singular set
    degenerate = _degenerate_rows(model, rows, rng, bounds or {}) if rows else []
    order = sorted(range(len(candidates)), key=lambda i: (degenerate[i], i))
    chosen = []
    for i in order:
        trial = chosen + [i]
        ok = True
        for B in B_all:
            s = np.linalg.svd(B[trial], compute_uv=False)
            ok &= s[-1] > 1e-8 * max(s[0], 1.0)
        if ok:
            chosen = trial
        if len(chosen) == nv:
            return tuple(candidates[i] for i in sorted(chosen))
    raise ModelError([f"no {nv} velocity quantities among {', '.join(candidates)} parametrise the "
                      f"allowed velocities of {system.name}"], title="invalid velocity coordinates")


def _degenerate_rows(model, rows: _CandidateRows, rng, bounds, samples: int = 64) -> list:
    """Per candidate: does its row of B = Y Q nearly vanish at some configuration within
    ``bounds``? See :func:`choose_velocities`."""
    params, count = rows.params, rows.count
    coords = tuple(model.system.coordinates)
    lo = np.array([bounds.get(c, (-np.pi, np.pi))[0] for c in coords], dtype=float)
    hi = np.array([bounds.get(c, (-np.pi, np.pi))[1] for c in coords], dtype=float)
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    singular = model.numeric.functions.get("singular")
    qs = [rng.uniform(lo, hi) for _ in range(samples)]
    with np.errstate(all="ignore"):
        measure = np.array([float(singular(q, params)) if singular is not None else 1.0 for q in qs])
    keep = np.isfinite(measure) & (measure > 1e-2 * np.median(measure[np.isfinite(measure)] if
                                                               np.isfinite(measure).any() else [1.0]))
    small, large = np.full(count, np.inf), np.zeros(count)
    for q in (q for q, ok in zip(qs, keep) if ok):      # near the model's singular set every row degrades
        with np.errstate(all="ignore"):
            B = rows.at(q)
        if not np.all(np.isfinite(B)):
            continue
        norms = np.linalg.norm(B, axis=1)
        small, large = np.minimum(small, norms), np.maximum(large, norms)
    return list(small < DEGENERATE_SPREAD * large)
