"""Holonomic constraints h(q) = 0 of a system: eliminated where they can be solved, kept with
their velocity form otherwise (docs/holonomic.md).

A configuration constraint h_i(q) = 0 confines the system to the submanifold Q_h = h⁻¹(0)
of the configuration space. nhgait states the dynamics on Q_h in one of two ways, per
constraint:

* **eliminated**: when h_i is linear in one coordinate c with a coefficient a free of the
  coordinates (``z - r*cos(lean)``: c = z, a = 1), c = φ(q') = c − h_i/a is substituted
  everywhere — L(q', q̇') = L(q', φ, q̇', ∇φ·q̇'), the constraints, the other holonomic
  constraints — and the force on c is carried over by virtual work, τ'_j = τ_j + τ_c ∂φ/∂q_j.
  The system has one coordinate fewer; ``System.eliminated`` records c = φ.
* **kept**: otherwise (the Whipple bicycle's pitch, a root of a quartic in lean and steer) the
  coordinate stays and the constraint enters ω as its velocity form ∇h_i(q)·q̇ = 0, a Pfaffian
  row like the others; every formulation then keeps h constant along its solutions, the
  simulation can project q back onto h = 0 (``stabilization="projection"``), the drift
  max |h(q(t))| is reported with the trajectory, and a configuration is made consistent by
  solving h(q) = 0 for the *dependent* coordinate of each constraint (the ``dependent`` the
  user names, else the one with the largest |∂h_i/∂q_j| at q = 0) with the others given
  (:func:`consistent_configuration`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..errors import ModelError
from ..memo import OwnerMemo

__all__ = ["Elimination", "solvable_for", "eliminate", "velocity_row", "choose_dependent",
           "consistent_configuration", "constraint_gradient", "holonomic_residual", "NEWTON_TOL"]

#: |h(q)| accepted as consistent (relative to max(1, |q|)), with a last Newton step of rounding size
NEWTON_TOL = 1e-12
#: the lambdified h and ∂h/∂q per system (dropped with it)
HOLONOMIC_FUNCTIONS = OwnerMemo("holonomic constraint functions per system")
#: Newton iterations of :func:`consistent_configuration` before it reports no solution
NEWTON_ITERATIONS = 50


@dataclass(frozen=True, kw_only=True)
class Elimination:
    """A statement before or after eliminating coordinates: the coordinate symbols q, q̇ and
    the expressions L, constraints, forces in them; ``holonomic`` the (h, dependent) pairs of
    the holonomic constraints — before :func:`eliminate` every one, each with the coordinate
    it is asked to solve for (a name, or None: any); after it those kept (the name None:
    chosen later); ``eliminated`` the (name, φ) pairs in the order eliminated."""

    q: tuple
    q_dot: tuple
    L: object
    constraints: tuple
    tau: tuple
    holonomic: tuple
    eliminated: tuple = ()


def solvable_for(h, c, q) -> sp.Expr | None:
    """φ with (h = 0 ⟺ c = φ) when h is linear in ``c`` with a coefficient free of the
    coordinates ``q`` and not zero; else None."""
    if c not in h.free_symbols or sp.diff(h, c, 2) != 0:
        return None
    a = sp.simplify(sp.diff(h, c))
    if a == 0 or a.free_symbols & set(q):
        return None
    phi = sp.expand(c - h / a)
    return None if c in phi.free_symbols else phi


def eliminate(stated: Elimination) -> Elimination:
    """Eliminate, constraint by constraint, a coordinate solved from each holonomic constraint
    h of ``stated.holonomic`` (pairs (h, wanted)): the coordinate ``wanted`` (a name) when h can
    be solved for it, else — with ``wanted`` None — the last coordinate it can be solved for; a
    constraint solved for none is kept (module docstring). Returns the statement in the
    remaining coordinates, its ``eliminated`` extended."""
    q, q_dot, tau, L = list(stated.q), list(stated.q_dot), list(stated.tau), stated.L
    constraints, kept, done = list(stated.constraints), [], list(stated.eliminated)
    pending = list(stated.holonomic)
    while pending:
        h, name = pending.pop(0)
        names = [c.name for c in q]
        candidates = [names.index(name)] if name in names else [] if name else list(range(len(q)))[::-1]
        solved = [(i, phi) for i in candidates for phi in [solvable_for(h, q[i], q)] if phi is not None]
        if not solved:
            kept.append((h, name))
            continue
        i, phi = solved[0]
        c = q[i]
        rest, rest_dot = q[:i] + q[i + 1:], q_dot[:i] + q_dot[i + 1:]
        rate = sp.Add(*[sp.diff(phi, qj) * vj for qj, vj in zip(rest, rest_dot, strict=True)])
        subs = {c: phi, q_dot[i]: rate}
        L = L.xreplace(subs)
        constraints = [e.xreplace(subs) for e in constraints]
        tau_c = tau[i]
        tau = [(t + tau_c * sp.diff(phi, qj)).xreplace(subs)
               for t, qj in zip(tau[:i] + tau[i + 1:], rest, strict=True)]
        pending = [(e.xreplace(subs), d) for e, d in pending]
        kept = [(e.xreplace(subs), d) for e, d in kept]
        done.append((c.name, phi))
        q, q_dot = rest, rest_dot
    return Elimination(q=tuple(q), q_dot=tuple(q_dot), L=L, constraints=tuple(constraints), tau=tuple(tau),
                       holonomic=tuple(kept), eliminated=tuple(done))


def velocity_row(h, q, q_dot) -> sp.Expr:
    """ḣ = ∇h(q)·q̇, the Pfaffian row of a kept holonomic constraint."""
    return sp.Add(*[sp.diff(h, qj) * vj for qj, vj in zip(q, q_dot, strict=True)])


def choose_dependent(h, q, params: dict) -> int:
    """Index of the coordinate a kept constraint is solved for by default: the largest
    |∂h/∂q_j| at q = 0 with the default parameters (at a fixed random configuration when every
    derivative vanishes at q = 0)."""
    grad = sp.lambdify([q, list(params)], [sp.diff(h, qj) for qj in q], "numpy")
    values = list(params.values())
    for point in (np.zeros(len(q)), np.random.default_rng(5).uniform(-0.5, 0.5, len(q))):
        with np.errstate(all="ignore"):
            g = np.abs(np.array(grad(point, values), dtype=float))
        if np.isfinite(g).all() and g.max() > 0:
            best = np.flatnonzero(g >= g.max() * (1 - 1e-12))
            return int(best[-1])
    return max(i for i, qj in enumerate(q) if qj in h.free_symbols)


def _functions(system):
    """(h(q, params), ∂h/∂q(q, params)) of a system's kept holonomic constraints, numpy
    (lambdified once per system, :data:`HOLONOMIC_FUNCTIONS`)."""
    return HOLONOMIC_FUNCTIONS.get(system, "h", lambda: _lambdified(system))


def _lambdified(system):
    H = sp.Matrix(system.holonomic)
    J = H.jacobian(sp.Matrix(system.q))
    h = sp.lambdify([system.q, system.param_symbols], H, "numpy")
    dh = sp.lambdify([system.q, system.param_symbols], J, "numpy")
    return h, dh


def _param_values(system, params) -> np.ndarray:
    """The parameter vector of ``params``: a mapping (defaults for the rest), None (the defaults)
    or already the vector in :attr:`~.system.System.param_symbols` order."""
    return np.asarray(params, dtype=float) if isinstance(params, np.ndarray) else system.param_vector(params)


def holonomic_residual(system, q, params=None) -> np.ndarray:
    """h(q) of the kept holonomic constraints at the configuration(s) ``q`` ((n,) → (c,);
    (N, n) → (N, c)); empty without kept constraints. ``params``: a mapping overriding the
    defaults, or the parameter vector itself."""
    q = np.asarray(q, dtype=float)
    if not system.holonomic:
        return np.zeros(q.shape[:-1] + (0,))
    h, _ = _functions(system)
    pv = _param_values(system, params)
    if q.ndim == 1:
        return np.array(h(q, pv), dtype=float).ravel()
    return np.array([np.array(h(row, pv), dtype=float).ravel() for row in q]).reshape(q.shape[0], -1)


def constraint_gradient(system, q, params=None) -> np.ndarray:
    """∂h/∂q (c, n) of the kept holonomic constraints at q (``params`` a mapping or the
    parameter vector)."""
    _, dh = _functions(system)
    pv = _param_values(system, params)
    return np.array(dh(np.asarray(q, dtype=float), pv), dtype=float).reshape(len(system.holonomic), system.n)


def consistent_configuration(system, q, *, params=None, dependent=None) -> np.ndarray:
    """A configuration on h(q) = 0: the dependent coordinates (``dependent``: names, default
    the system's) solved by Newton's method from their values in ``q``, the others as given.

    Raises :class:`ModelError` naming the given coordinates when Newton's method finds no
    solution (no configuration with those values satisfies the constraints, or it is not
    near the start)."""
    system = getattr(system, "system", system)
    q = np.array(q, dtype=float).ravel()
    if not system.holonomic:
        return q
    names = list(system.coordinates)
    dependent = list(dependent or system.dependent)
    cols = [names.index(c) for c in dependent]
    h, dh = _functions(system)
    pv = _param_values(system, params)
    start = q.copy()
    for _ in range(NEWTON_ITERATIONS):
        with np.errstate(all="ignore"):
            r = np.array(h(q, pv), dtype=float).ravel()
            J = np.array(dh(q, pv), dtype=float).reshape(r.size, len(names))[:, cols]
        if not (np.isfinite(r).all() and np.isfinite(J).all()):
            break
        try:
            step = np.linalg.solve(J, r)
        except np.linalg.LinAlgError:
            break
        q[cols] -= step
        small = np.max(np.abs(step)) <= 4 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(q[cols]))))
        if np.max(np.abs(r)) <= NEWTON_TOL * max(1.0, float(np.max(np.abs(q)))) and small:
            return q          # converged: the last step changed nothing but rounding
    given = ", ".join(f"{c} = {v:.6g}" for c, v in zip(names, start, strict=True) if c not in dependent)
    with np.errstate(all="ignore"):
        r = np.array(h(q, pv), dtype=float).ravel()
    raise ModelError([f"no configuration satisfies the holonomic constraint(s) "
                      f"{'; '.join(f'{e} = 0' for e in system.holonomic)} with {given}: Newton's method on "
                      f"{', '.join(dependent)} from {', '.join(f'{start[i]:.6g}' for i in cols)} ended at "
                      f"residual {np.max(np.abs(r)):.3g}; give other values (or a start for "
                      f"{', '.join(dependent)} near the solution)"], title="inconsistent configuration")
