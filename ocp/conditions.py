"""Boundary conditions as users write them: redundant ones dropped, inconsistent ones refused.

People write "at rest" as every coordinate *and every velocity* zero, "fibre at rest" as
ẋ = ẏ = θ̇ = 0 and "joints periodic" as every joint angle and rate periodic — more conditions
than the reduced state (2n − k components) can take independently. Imposed literally they make
the NLP's constraint Jacobian rank-deficient (Ipopt then crawls or stops at a wrong point).
:func:`normalise` states the same set of trajectories with independent conditions:

* **A point at rest** (first, at each end): velocity quantities stated zero that are linear
  in the velocity states ν (ẋ = ẏ = 0 of a car's front axle) are rows of A(q) ν = 0; when the
  columns S of A that are not identically zero keep full rank at every configuration (the
  smallest eigenvalue of A_Sᵀ A_S minimised over the coordinates the end leaves free), they
  say exactly ν_S = 0 and are replaced by those states fixed to 0 (bounds). One such row alone
  usually loses rank somewhere (ẋ = v cos θ vanishes at θ = π/2 for any v) and stays as written:
  dropping either row of the pair, as the rank test below would, admits that branch.
* **At one end** (t = 0 or t = T), with F the state components the end fixes by value and
  c_j(z) = a_j the equality conditions on derived quantities: at sample states z with z_F
  fixed, moved (Gauss–Newton in the free components) onto the set where the conditions kept
  before j hold, condition j is *dependent* when the gradient of c_j with respect to the free
  components lies in the span of the kept ones' (rank test at every such point). A dependent
  condition satisfied at those points is dropped ("implied by …"). Violated there, it is
  judged where the kept conditions and it hold *together* (solved over the free components
  from the same starts): the kept set may have several branches (θ̇₀ = v a(q) = 0 at v = 0 and
  wherever a(q) = 0; θ̇₁ = v b(q) = 0 holds only on the first). No common point: an
  inconsistent set, reported with the residual (one ProblemError); a common point where it
  adds no rank: dropped ("implied … where they all hold"; the verification checks it as
  written); adding rank there: kept. (Testing away from that
  set would miss dependence that holds only on it: a snakeboard's θ̇ = v tan φ / r is
  independent of ẋ = v cos θ in general, but zero wherever ẋ = 0 at θ = 0.) When the fixed values
  and the kept conditions determine the whole state and the kept conditions are linear in
  the free components (velocities at a fixed configuration), the end state is solved for and
  fixed by value (bounds on the node, no rows at all).
* **Periodicity** y(T) = y(0) of a derived quantity: when the values an end fixes make y
  constant there (rest at both ends and "rates periodic"), the condition is a value at the
  other end (y(T) = y(0) = c becomes ``final.y = c``) or, constant at both ends, implied
  (equal values) or contradictory (different ones). Otherwise, a periodic quantity whose
  gradient lies in the span of the periodic states' and of the periodic quantities kept
  before it is implied (locally a function of them) and dropped — only locally: when the
  periodic quantities are rates determined by the velocity states v and the periodic states,
  the set is stated exactly as v(T) = v(0) instead (:func:`_determined_velocities`).
* **Free offsets**: a state the dynamics do not depend on and no condition, bound or weight
  names by value (a rotor angle free at both ends) is fixed to 0 at t = 0
  (:mod:`.offsets`: otherwise the NLP has a flat direction the solver drifts along).
* **Counts** need no rule of their own: a condition is kept only when it raises the rank in
  the free components, so at most the state's size are kept; every further one is implied or
  contradicts the others (an error naming both).

Ranges (lo < hi) are kept as they are. Samples are drawn from a seeded generator (the result is
reproducible); a sample where the model is not finite (the singular set) is skipped.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np

from .offsets import free_offsets
from .problem import OptimalControlProblem, ProblemError

__all__ = ["normalise", "ConditionReport"]

SAMPLES = 6
RANK_TOL = 1e-8            # singular values below this fraction of the largest are zero
RESIDUAL_TOL = 1e-8        # a condition holds when |c(z) − a| ≤ RESIDUAL_TOL (1 + |a|)
# A_Sᵀ A_S loses rank where its smallest eigenvalue falls below this fraction of its largest
REST_RANK_TOL = 1e-8


@dataclass(frozen=True)
class ConditionReport:
    """What :func:`normalise` changed: ``dropped`` (where, name, reason), ``solved``
    (where → the end state fixed by value, or absent) and ``pinned`` (the states whose initial
    value it fixed at 0: :func:`~nhgait.ocp.offsets.free_offsets`)."""

    dropped: tuple = ()
    solved: tuple = ()
    pinned: tuple = ()

    def lines(self) -> list:
        out = [f"{where}.{name}: dropped, {reason}" for where, name, reason in self.dropped]
        out += [f"{where}: the conditions determine the whole state; fixed to "
                f"({', '.join(f'{v:.6g}' for v in z)})"
                for where, z in self.solved]
        out += [f"initial.{name}: fixed to 0 — nothing depends on its value (the dynamics, the objective and "
                "every condition are the same for any value; left free, the solver drifts along it)"
                for name in self.pinned]
        return out


def _fixed(problem, mapping) -> dict:
    """State index → value of the states an end fixes by value."""
    out = {}
    for name in mapping:
        if problem.is_state(name):
            lo, hi = problem.bounds(mapping, name)
            if lo == hi:
                out[problem.state_names.index(name)] = lo
    return out


def _equalities(problem, mapping) -> list:
    """(name, value) of the derived quantities an end fixes by value, in order."""
    out = []
    for name in mapping:
        if not problem.is_state(name):
            lo, hi = problem.bounds(mapping, name)
            if lo == hi:
                out.append((name, lo))
    return out


def _samples(problem, fixed: dict, rng, count: int) -> np.ndarray:
    """States (count × nz) with the fixed components set, the others random within bounds."""
    nz = problem.n_states
    Z = rng.uniform(-0.8, 0.8, (count, nz))
    for name in problem.state_bounds:
        if problem.is_state(name):
            i = problem.state_names.index(name)
            lo, hi = problem.bounds(problem.state_bounds, name)
            a, b = max(lo, -1.0 if hi > -1.0 else lo), min(hi, 1.0 if lo < 1.0 else hi)
            Z[:, i] = rng.uniform(a, b, count) if np.isfinite(a) and np.isfinite(b) else Z[:, i]
    for i, v in fixed.items():
        Z[:, i] = v
    return Z


def _rank(M: np.ndarray) -> int:
    if M.size == 0:
        return 0
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > RANK_TOL * max(s[0], 1.0)))


class _End:
    """The derived equality conditions of one end as one CasADi function c(z) and its Jacobian."""

    def __init__(self, problem, names):
        z = ca.SX.sym("z", problem.n_states)
        c = ca.vertcat(*[problem.quantity(n, z) for n in names]) if names else ca.SX(0, 1)
        self.f = ca.Function("c", [z], [c, ca.jacobian(c, z)])

    def __call__(self, z):
        c, J = self.f(z)
        return np.asarray(c, float).ravel(), np.asarray(J, float).reshape(-1, len(z))


def _point_on(end: _End, kept: list, values: np.ndarray, z0: np.ndarray, free: np.ndarray):
    """A state near ``z0`` (free components moved) where the kept conditions hold, or None."""
    z = z0.copy()
    for _ in range(30):
        c, J = end(z)
        r = c[kept] - values[kept]
        if not np.all(np.isfinite(r)):
            return None
        if (np.max(np.abs(r), initial=0.0)
            <= RESIDUAL_TOL * 1e-2 * (1 + np.max(np.abs(values[kept]), initial=0.0))):
            return z
        step = np.linalg.lstsq(J[np.ix_(kept, free)], -r, rcond=None)[0]
        z[free] += step
    return None


def _end(problem, where: str, rng):
    """(new mapping, dropped [(name, reason)], solved state or None) of one end."""
    mapping = problem.initial if where == "initial" else problem.final
    mapping, replaced = _velocities_at_rest(problem, mapping, rng)
    out, dropped, solved = _end_conditions(problem, mapping, where, rng)
    return out, replaced + dropped, solved


def _end_conditions(problem, mapping, where: str, rng):
    fixed = _fixed(problem, mapping)
    eqs = _equalities(problem, mapping)
    if not eqs:
        return dict(mapping), [], None
    names = [n for n, _ in eqs]
    values = np.array([v for _, v in eqs])
    end = _End(problem, names)
    free = np.array([i for i in range(problem.n_states) if i not in fixed], dtype=int)
    Z = [z for z in _samples(problem, fixed, rng, 4 * SAMPLES) if np.all(np.isfinite(end(z)[1]))][:SAMPLES]
    if not Z:
        return dict(mapping), [], None
    anywhere = [end(z)[1] for z in _samples(problem, {}, rng, SAMPLES)]     # which states a condition uses
    kept, dropped, problems = [], [], []
    for j, name in enumerate(names):
        points = _feasible(end, kept, values, Z, free)
        jac = [end(z)[1][:, free] for z in points]
        if not points or all(_rank(J[kept + [j]]) > _rank(J[kept]) for J in jac):
            kept.append(j)
            continue
        uses = [i for i in fixed if any(abs(J[j, i]) > RANK_TOL * (1 + np.abs(J[j]).max()) for J in anywhere)]
        implied_by = ", ".join([f"{problem.state_names[i]} = {fixed[i]:g}" for i in uses]
                               + [f"{names[k]} = {values[k]:g}" for k in kept])
        verdict = _dependent(_Search(end, values, Z, free), kept, j, points)
        if verdict == "implied":
            dropped.append((name, f"implied by {implied_by or 'the other conditions'}"))
        elif verdict == "implied where both hold":
            dropped.append((name, f"implied by {implied_by or 'the other conditions'} where they all hold "
                                  "(dependent there; the verification checks it)"))
        elif verdict == "independent":
            kept.append(j)
        else:
            worst = verdict
            problems.append(f"[task].{where}: {name} = {values[j]:g} contradicts {implied_by}: where "
                            f"those hold, {name} = {values[j] + worst:.6g} (residual {worst:.3g})")
    if problems:
        raise ProblemError(problems, title="inconsistent boundary conditions")
    independent = len(fixed) + len(kept)          # ≤ nz: a kept condition raises the rank in the free part
    out = {k: v for k, v in mapping.items() if k not in {n for n, _ in dropped}}
    points = _feasible(end, kept, values, Z, free)
    jac = [end(z)[1][:, free] for z in points]
    linear = bool(points) and all(np.allclose(J[kept], jac[0][kept], rtol=1e-9, atol=1e-12) for J in jac)
    if independent == problem.n_states and linear:
        return out, dropped, points[0]
    return out, dropped, None


def _velocities_at_rest(problem, mapping, rng) -> tuple:
    """Velocity quantities stated zero at an end, replaced by the velocity states they stop.

    With ν the velocity states (the model's states after its coordinates), a quantity c that
    is linear in them, c = a(q)ᵀν, stated c = 0 ("the front axle at rest": ẋ = ẏ = 0) is one
    row of A(q) ν = 0. When the columns S of A that are not identically zero have full rank at
    *every* configuration — the smallest eigenvalue of A_Sᵀ A_S, minimised over q from the
    samples (within the bounds), stays away from 0 — the rows say exactly ν_S = 0 (the other
    velocity states stay free): they are replaced by those states fixed to 0, which the NLP
    takes as bounds. Testing rank at sample points only would miss the configurations where it
    drops (ẋ = 0 alone holds also for a car moving along y; ẋ = ẏ = 0 only at rest). Returns
    (new mapping, dropped [(name, reason)])."""
    n = len(getattr(problem.model.system, "coordinates", ()))
    velocity = list(range(n, len(problem.model_state_names)))
    fixed = _fixed(problem, mapping)
    rows = [name for name, value in _equalities(problem, mapping) if value == 0.0]
    if not rows or not velocity or any(fixed.get(i, 0.0) != 0.0 for i in velocity):
        return mapping, []
    end = _End(problem, rows)
    Z = [z for z in _samples(problem, fixed, rng, 4 * SAMPLES) if np.all(np.isfinite(end(z)[1]))][:SAMPLES]
    linear = [j for j, _ in enumerate(rows) if Z and all(_linear_in(end, z, j, velocity) for z in Z)]
    if not linear:
        return mapping, []
    A = [end(z)[1][np.ix_(linear, velocity)] for z in Z]
    scale = max(float(np.abs(a).max()) for a in A)
    S = [k for k in range(len(velocity)) if scale > 0
         and max(float(np.abs(a[:, k]).max()) for a in A) > RANK_TOL * scale]
    if not S or len(S) > len(linear) or not _full_rank_everywhere(problem, end, linear,
                                                                  [velocity[k] for k in S], Z, fixed):
        return mapping, []
    stopped = [problem.state_names[velocity[k]] for k in S]
    names = [rows[j] for j in linear]
    out = {k: v for k, v in mapping.items() if k not in names}
    out.update({name: 0.0 for name in stopped})
    free = [problem.state_names[i] for i in velocity if problem.state_names[i] not in stopped]
    reason = (f"with {', '.join(f'{m} = 0' for m in names)}: exactly {', '.join(f'{m} = 0' for m in stopped)}"
              + (f" ({', '.join(free)} free)" if free else ""))
    return out, [(name, reason) for name in names]


def _linear_in(end: _End, z, j: int, velocity: list) -> bool:
    """c_j(z) = ∂c_j/∂ν · ν and c_j(q, 0) = 0 at ``z`` (homogeneous linear in the velocities)."""
    c, J = end(z)
    zero = z.copy()
    zero[velocity] = 0.0
    c0 = end(zero)[0][j]
    predicted = float(J[j, velocity] @ z[velocity])
    tol = RESIDUAL_TOL * (1 + abs(c[j]))
    return abs(c0) <= tol and abs(c[j] - predicted) <= tol


def _full_rank_everywhere(problem, end: _End, rows: list, columns: list, Z, fixed: dict) -> bool:
    """Whether A_S = ∂c_rows/∂ν_S keeps full column rank over the configurations: the smallest
    eigenvalue of A_Sᵀ A_S, minimised over the coordinates the end leaves free (Nelder–Mead from
    each sample, within the coordinates' bounds), stays above :data:`REST_RANK_TOL` of its
    largest sampled value (σ_min above 1e-4 of σ_max)."""
    from scipy.optimize import minimize
    n = len(problem.model.system.coordinates)
    coords = [i for i in range(n) if i not in fixed]
    if not coords:
        return True
    lo = np.array([problem.bounds(problem.state_bounds, problem.state_names[i])[0]
                   if problem.state_names[i] in problem.state_bounds else -np.inf for i in coords])
    hi = np.array([problem.bounds(problem.state_bounds, problem.state_names[i])[1]
                   if problem.state_names[i] in problem.state_bounds else np.inf for i in coords])

    def smallest(values, z0):
        z = z0.copy()
        z[coords] = np.clip(values, lo, hi)
        A = end(z)[1][np.ix_(rows, columns)]
        return float(np.linalg.eigvalsh(A.T @ A)[0]) if np.all(np.isfinite(A)) else np.inf

    sampled = [smallest(z[coords], z) for z in Z]
    top = max(v for v in sampled if np.isfinite(v)) if any(np.isfinite(sampled)) else 0.0
    if not top > 0:
        return False
    for z in Z:
        best = minimize(smallest, z[coords], args=(z,), method="Nelder-Mead",
                        options={"xatol": 1e-9, "fatol": REST_RANK_TOL * top * 1e-4,
                                 "maxiter": 200 * len(coords)})
        if best.fun <= REST_RANK_TOL * top:
            return False
    return True


class _Search(NamedTuple):
    """One end's conditions searched: ``end`` (c(z) and its Jacobian), their stated ``values``
    (m,), the sampled states ``samples`` and the indices of the ``free`` components of z."""

    end: _End
    values: np.ndarray
    samples: list
    free: np.ndarray


def _dependent(search: _Search, kept: list, j: int, points: list):
    """The verdict on condition j, whose gradient (in the free components) lies in the span of
    the kept ones' at some of ``points`` (where the kept conditions hold):

    * ``"implied"`` — c_j = a_j at every such point;
    * otherwise the kept conditions and c_j are solved *together* over the free components from
      the same starts (the implication is judged where they all hold, not on one branch of the
      kept set: θ̇₀ = v a(q) = 0 holds at v = 0 and wherever a(q) = 0, and θ̇₁ = v b(q) = 0 only
      on the first branch); no common point: the residual on the kept set (an inconsistent set);
      at the common points the rank test again — ``"implied where both hold"`` when c_j adds no
      rank there (near those points it is a function of the kept ones, so imposing it would
      only make the constraint Jacobian rank-deficient), ``"independent"`` when it does.
    """
    end, values, Z, free = search
    residuals = [float(end(z)[0][j] - values[j]) for z in points]
    worst = max(residuals, key=abs)
    if abs(worst) <= RESIDUAL_TOL * (1 + abs(values[j])):
        return "implied"
    common = _feasible(end, kept + [j], values, Z, free)
    if not common:
        return worst
    jac = [end(z)[1][:, free] for z in common]
    if all(_rank(J[kept + [j]]) == _rank(J[kept]) for J in jac):
        return "implied where both hold"
    return "independent"


def _feasible(end: _End, kept: list, values, Z, free) -> list:
    """The samples moved onto the set where the kept conditions hold (those that get there)."""
    if not kept:
        return list(Z)
    points = [_point_on(end, kept, values, z, free) for z in Z]
    return [z for z in points if z is not None and np.all(np.isfinite(end(z)[1]))]


def _constant(problem, fixed: dict, name: str, rng):
    """The value of quantity ``name`` where the fixed components hold, when it does not depend
    on the others there (None otherwise)."""
    end = _End(problem, [name])
    free = np.array([i for i in range(problem.n_states) if i not in fixed], dtype=int)
    values = []
    for z in _samples(problem, fixed, rng, 4 * SAMPLES):
        c, J = end(z)
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(J))):
            continue
        if np.max(np.abs(J[0, free]), initial=0.0) > RANK_TOL * (1 + np.max(np.abs(J), initial=0.0)):
            return None
        values.append(float(c[0]))
        if len(values) == SAMPLES:
            break
    if not values or max(values) - min(values) > RESIDUAL_TOL * (1 + abs(values[0])):
        return None
    return values[0]


def _periodic_at_fixed_ends(problem, rng) -> tuple:
    """Periodic derived quantities that an end makes constant, turned into end values (module
    docstring). Returns (initial, final, periodic, dropped [(name, reason)])."""
    initial, final, periodic, dropped, problems = dict(problem.initial), dict(problem.final), [], [], []
    fixed0, fixedN = _fixed(problem, problem.initial), _fixed(problem, problem.final)
    for name in problem.periodic:
        if problem.is_state(name):
            periodic.append(name)
            continue
        c0, cN = _constant(problem, fixed0, name, rng), _constant(problem, fixedN, name, rng)
        if c0 is not None and cN is not None:
            if abs(c0 - cN) > RESIDUAL_TOL * (1 + abs(c0)):
                problems.append(f"[task].periodic: {name} is {c0:.6g} at t = 0 and {cN:.6g} at t = T by the "
                                "values the task fixes there; it cannot be periodic")
            dropped.append((name, f"fixed to {c0:.6g} at both ends by the task's values"))
        elif c0 is not None or cN is not None:
            value, target = (c0, final) if c0 is not None else (cN, initial)
            other = "final" if c0 is not None else "initial"
            if name in target:
                lo, hi = problem.bounds(target, name)
                if not lo - RESIDUAL_TOL <= value <= hi + RESIDUAL_TOL:
                    problems.append(f"[task]: {name} is periodic and {value:.6g} at the other end, but "
                                    f"{other}.{name} = {target[name]}")
            else:
                target[name] = value
            dropped.append((name, f"the task's values fix it to {value:.6g} at one end: {other}.{name} = "
                                  f"{value:.6g} instead"))
        else:
            periodic.append(name)
    if problems:
        raise ProblemError(problems, title="inconsistent boundary conditions")
    return initial, final, tuple(periodic), dropped


def _periodic(problem, rng) -> tuple:
    """(kept names, dropped [(name, reason)]) of the periodicity conditions."""
    states = [n for n in problem.periodic if problem.is_state(n)]
    derived = [n for n in problem.periodic if not problem.is_state(n)]
    if not derived:
        return tuple(problem.periodic), []
    end = _End(problem, derived)
    unit = np.eye(problem.n_states)[[problem.state_names.index(n) for n in states]]
    Z = [z for z in _samples(problem, {}, rng, 4 * SAMPLES) if np.all(np.isfinite(end(z)[1]))][:SAMPLES]
    jac = [end(z)[1] for z in Z]
    kept, dropped = [], []
    for j, name in enumerate(derived):
        if Z and all(_rank(np.vstack([unit, J[kept + [j]]])) == _rank(np.vstack([unit, J[kept]]))
                     for J in jac):
            dropped.append((name, "implied by the periodicity of "
                            + ", ".join(states + [derived[k] for k in kept])))
        else:
            kept.append(j)
    velocities = (_determined_velocities(problem, states, derived, [derived[k] for k in kept], jac)
                  if dropped else ())
    if velocities:
        reason = (f"stated as the periodicity of the velocity states {', '.join(velocities)}, which "
                  "the periodic "
                  "rates determine and which determine them (the rates alone could repeat at a "
                  "posture where they stop determining the motion, without the motion repeating)")
        return tuple(states + [v for v in velocities if v not in states]), [(name, reason)
                                                                            for name in derived]
    return tuple(states + [derived[k] for k in kept]), dropped


def _determined_velocities(problem, states, derived, kept, jac) -> tuple:
    """The velocity states v (the state components after the coordinates) when the periodic
    derived quantities r are functions of the periodic states and v alone and the kept ones
    determine v (∂r_kept/∂v of full column rank at every sample); else ().

    Then, the periodic states being equal at both ends, r(T) = r(0) for every r follows from
    v(T) = v(0); and v(T) = v(0) follows from the kept rows wherever ∂r_kept/∂v is regular. Keeping
    the kept rows and dropping the others as "implied" is exact only there: a 4-link snake in
    the velocities (θ̇, forward_velocity), two of its three periodic joint rates kept, ended at
    a posture where those two no longer determine the motion, the third rate missed by 0.078.
    Stated as v(T) = v(0) (n − k independent rows), every rate is periodic exactly."""
    n = int(getattr(problem.model.numeric, "n_coordinates", 0) or 0)
    velocity = list(problem.state_names[n:]) if n else []
    if not velocity or len(kept) < len(velocity) or not jac:
        return ()
    z = ca.SX.sym("z", problem.n_states)
    allowed = {problem.state_names.index(s) for s in states} | set(range(n, problem.n_states))
    for name in derived:
        expr = problem.quantity(name, z)
        if any(ca.depends_on(expr, z[j]) for j in range(problem.n_states) if j not in allowed):
            return ()
    rows = [derived.index(name) for name in kept]
    if not all(_rank(J[np.ix_(rows, range(n, problem.n_states))]) == len(velocity) for J in jac):
        return ()
    return tuple(velocity)


class Normalised(NamedTuple):
    """What :func:`normalise` returns."""

    problem: OptimalControlProblem   #: with independent conditions
    report: ConditionReport          #: what was dropped or moved, and why


def normalise(problem: OptimalControlProblem, *, seed: int = 0) -> Normalised:
    """``problem`` with independent boundary and periodicity conditions (module docstring),
    and a :class:`ConditionReport`. Raises ProblemError for an inconsistent set."""
    rng = np.random.default_rng(seed)
    initial, final, periodic, moved = _periodic_at_fixed_ends(problem, rng)
    dropped = [("periodic", n, r) for n, r in moved]
    current = problem.replace(initial=initial, final=final, periodic=periodic) if moved else problem
    changes, solved = {}, []
    for where in ("initial", "final"):
        mapping, gone, z = _end(current, where, rng)
        dropped += [(where, n, r) for n, r in gone]
        if z is not None:
            ranges = {k: v for k, v in mapping.items()
                      if not current.is_state(k)
                      and current.bounds(mapping, k)[0] != current.bounds(mapping, k)[1]}
            mapping = {**ranges, **dict(zip(current.state_names, map(float, z), strict=True))}
            solved.append((where, tuple(map(float, z))))
        changes[where] = mapping
    periodic, gone = _periodic(current, rng)
    dropped += [("periodic", n, r) for n, r in gone]
    pinned = free_offsets(current)
    if pinned:
        changes["initial"] = {**changes.get("initial", current.initial), **{name: 0.0 for name in pinned}}
    if not dropped and not solved and not pinned:
        return Normalised(problem, ConditionReport())
    return Normalised(current.replace(periodic=periodic, **changes),
            ConditionReport(tuple(dropped), tuple(solved), tuple(pinned)))
