"""Which stated condition must move, and by how much, for a gait to exist: the minimum-violation
(elastic) solve a plan runs when its attempts stall at the same infeasibility (issue 41).

Problem (the task's states z, inputs u, N intervals of h = T/N; the dynamics hard, each stated
condition c elastic with a slack s_c ≥ 0)::

    minimise    Σ_c s_c / size_c                              (an L1 penalty: exact — a condition
                                                               moves only when it must)
    subject to  z_{k+1} = F(z_k, u_k)                         (M RK4 sub-steps of ż = f(t, z, u))
                lo_c − s_c ≤ y_c(z_0) ≤ hi_c + s_c            initial.<y>
                lo_c − s_c ≤ y_c(z_N) ≤ hi_c + s_c            final.<y>, waypoints[j].<y> at their node
                lo_c − s_c ≤ y_c(z_k, u_k) ≤ hi_c + s_c  ∀k   bounds.<y> (one slack per condition)
                lo_c − s_c ≤ u_{j,k} ≤ hi_c + s_c         ∀k   control_bounds.<u>
                |y_c(z_N) − y_c(z_0)| ≤ s_c                   periodic.<y>

with size_c the largest finite |bound| of condition c (1, SI, for a condition on 0): each move
is measured relative to the value the user wrote (widening |τ| ≤ 0.012 by 0.0015 is a move of
12 %; moving y(T) = 0.5 m by 0.5 m one of 100 %). The solve is local: it is made from the
closest point of the attempts and from a plain start (every unknown 0), and the smaller total
kept. The **start is moved last**: the solve is made first
with the ``initial`` conditions hard (the rest the user wants to start from is not advice to give);
only when no gait exists even then are they made elastic too (``start_moved``). The result names
each condition the nearest gait moves, by how much, and the value it then takes (:class:`Elastic`).

Verdicts (:meth:`Elastic.lines`): every slack ≤ the task's ``verify_tolerance`` — a gait meeting
every stated condition exists (the failures were the solver's, from its guesses); else **possibly
infeasible**: the elastic solve is local (a minimum of the total move, found from the closest
point of the attempts), so a gait may exist elsewhere, but none near what was tried.

:func:`stalled` says when the attempts stall at the same infeasibility: the last
:data:`STALL_WINDOW` attempts all ended with the same status that reports infeasibility
(:data:`INFEASIBLE`), :data:`STALL_ATTEMPTS` of them at constraint violations within
:data:`STALL_SPREAD` of each other — the same infeasible point reached from different guesses.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Elastic", "Move", "elastic_solve", "stalled", "with_elastic", "STALL_ATTEMPTS", "STALL_WINDOW",
           "INFEASIBLE"]

#: failures at the same infeasibility that end a search ...
STALL_ATTEMPTS = 3
#: ... among this many last attempts, every one infeasible: the planner interleaves two kinds of
#: guesses (shape loops and roll-outs), which stop at two different infeasible points, so "three
#: in a row" never happened there (a snakeboard under tight torque bounds: 0.1, 0.18, 0.18, 0.11,
#: 0.18, … through 12 guesses of each solver, 142 s, instead of stopping at the fifth)
STALL_WINDOW = 5
#: ... with these statuses (Ipopt's and the NLP's verdicts of an infeasible point) ...
INFEASIBLE = ("Infeasible_Problem_Detected", "Restoration_Failed", "Local_Infeasibility")
#: ... whose constraint violations differ by at most this fraction of the largest
STALL_SPREAD = 0.05
#: seconds the elastic solve may take at most (within the plan's budget)
ELASTIC_SECONDS = 60.0
#: conditions moved one at a time at most (:meth:`Elastic.lines`: "each alone")
ALONE = 6


def stalled(attempts) -> bool:
    """Whether the attempts stall at the same infeasibility (module docstring): the last
    :data:`STALL_WINDOW` of ``attempts`` (:class:`~nhgait.gaits.planning.search.Attempt`; at
    least :data:`STALL_ATTEMPTS`) all failed with one status of :data:`INFEASIBLE`, and
    :data:`STALL_ATTEMPTS` of them at constraint violations within :data:`STALL_SPREAD` of each
    other."""
    tail = list(attempts)[-STALL_WINDOW:]
    if len(tail) < STALL_ATTEMPTS or any(a.success or a.status not in INFEASIBLE for a in tail):
        return False
    if len({a.status for a in tail}) != 1:
        return False
    v = sorted(a.constraint_violation for a in tail)
    if not all(math.isfinite(x) and x > 0 for x in v):
        return False
    return any(v[i + STALL_ATTEMPTS - 1] - v[i] <= STALL_SPREAD * v[i + STALL_ATTEMPTS - 1]
               for i in range(len(v) - STALL_ATTEMPTS + 1))


@dataclass(frozen=True)
class Move:
    """How far condition ``label`` moves: ``asked`` (lo, hi) as stated, ``by`` ≥ 0 (the slack) and
    ``reached``, the value the nearest gait takes (for a path or input bound, its extreme)."""

    label: str
    asked: tuple
    by: float
    reached: float

    def text(self, unit: str = "") -> str:
        lo, hi = self.asked
        u = f" {unit}" if unit else ""
        asked = f"= {lo:g}" if lo == hi else f"in [{lo:g}, {hi:g}]"
        verb = "widen by" if self.label.startswith(("bounds.", "control_bounds.")) else "move by"
        return (f"{self.label} {asked}{u}: {verb} {self.by:.4g}{u} (the nearest gait reaches "
                f"{self.reached:.6g})")


@dataclass(frozen=True, kw_only=True)
class Elastic:
    """The minimum-violation solve's answer (module docstring): ``converged`` (Ipopt's verdict),
    ``status``, ``moves`` (every elastic condition, largest first), ``start_moved`` (the initial
    conditions had to be elastic too), ``tolerance`` (moves below it count as met), ``seconds``."""

    converged: bool
    status: str
    moves: tuple
    start_moved: bool
    tolerance: float
    seconds: float
    units: dict = field(default_factory=dict)
    alone: tuple = ()

    @property
    def moved(self) -> tuple:
        return tuple(m for m in self.moves if m.by > self.tolerance)

    @property
    def total(self) -> float:
        return float(sum(m.by for m in self.moves))

    @property
    def feasible(self) -> bool:
        return self.converged and not self.moved

    def lines(self) -> list:
        """What the diagnosis prints."""
        if not self.converged:
            return [f"the minimum-violation solve did not converge ({self.status}, {self.seconds:.1f} s): no "
                    "estimate of what must move"]
        if self.feasible:
            return [f"the minimum-violation solve found a trajectory meeting every stated condition (to "
                    f"{self.tolerance:g}, {self.seconds:.1f} s): a gait exists; the attempts failed from "
                    "their guesses — raise max_iter, try the other solver (--solver), or warm-start "
                    "(--guess)"]
        head = ("possibly infeasible: even with its start moved, no gait was found near the attempts; the "
                "nearest one moves" if self.start_moved else
                "possibly infeasible: no gait meets every stated condition near the attempts; the least "
                "total move (L1) that gives one, the start kept as stated")
        unit = lambda label: self.units.get(label.split(".", 1)[-1], "")  # noqa: E731
        alone = [f"  {m.text(unit(label))}" if m is not None else
                 f"  {label}: no gait found by moving it alone" for label, m in self.alone]
        return ([f"{head} ({self.seconds:.1f} s):"]
                + [f"  {m.text(unit(m.label))}" for m in self.moved]
                + (["each alone, the others as stated:"] + alone if alone else [])
                + ["  (a local answer: a gait may exist elsewhere; moving these conditions by these amounts "
                   "gives one)"])

    def to_dict(self) -> dict:
        return {"converged": self.converged, "status": self.status, "start_moved": self.start_moved,
                "tolerance": self.tolerance, "seconds": self.seconds, "feasible": self.feasible,
                "total_move": self.total, "lines": self.lines(),
                "moves": [{"condition": m.label, "asked": list(m.asked), "by": m.by, "reached": m.reached}
                          for m in self.moves],
                "alone": [{"condition": label, "by": None if m is None else m.by,
                           "reached": None if m is None else m.reached} for label, m in self.alone]}


# ----------------------------------------------------------------------------- the NLP
def _stage(problem, steps: int):
    """F(z, u, t0, h): ``steps`` RK4 sub-steps of the problem's ODE over one interval (SX)."""
    import casadi as ca
    f = problem.ode()
    z, u = ca.SX.sym("z", problem.n_states), ca.SX.sym("u", problem.n_controls)
    t0, h = ca.SX.sym("t0"), ca.SX.sym("h")
    x, dt = z, h / steps
    for j in range(steps):
        t = t0 + j * dt
        k1 = f(t, x, u)
        k2 = f(t + dt / 2, x + dt / 2 * k1, u)
        k3 = f(t + dt / 2, x + dt / 2 * k2, u)
        k4 = f(t + dt, x + dt * k3, u)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("F", [z, u, t0, h], [x])


def _conditions(problem, Z, U, t) -> list:
    """(label, expressions, (lo, hi), is_start) of every stated condition (module docstring);
    ``Z`` (nz × N+1), ``U`` (nu × N) MX, ``t`` the node times."""
    N = U.shape[1]
    y = lambda name, k: problem.quantity(name, Z[:, k], u=U[:, min(k, N - 1)], t=t[k])  # noqa: E731
    out = [(f"initial.{n}", [y(n, 0)], problem.bounds(problem.initial, n), True) for n in problem.initial]
    out += [(f"final.{n}", [y(n, N)], problem.bounds(problem.final, n), False) for n in problem.final]
    for j, point in enumerate(problem.waypoints):
        k = int(round(float(point.time) * N / float(problem.horizon)))
        out += [(f"waypoints[{j}].{n}", [y(n, k)], problem.bounds(point.conditions, n), False)
                for n in point.conditions]
    for n in problem.state_bounds:
        nodes = range(N) if problem.uses_inputs(n) else range(N + 1)
        out.append((f"bounds.{n}", [y(n, k) for k in nodes], problem.bounds(problem.state_bounds, n), False))
    for i, n in enumerate(problem.control_names):
        if n in problem.control_bounds:
            out.append((f"control_bounds.{n}", [U[i, k] for k in range(N)],
                        problem.bounds(problem.control_bounds, n), False))
    return out


def _guess(opti, Z, U, problem, closest) -> None:
    if closest is not None and closest.z.shape == (problem.intervals + 1, problem.n_states) \
            and closest.u.shape == (problem.intervals, problem.n_controls) and np.all(np.isfinite(closest.z)):
        opti.set_initial(Z, closest.z.T)
        opti.set_initial(U, np.nan_to_num(closest.u.T))


def _solve(problem, closest, *, elastic, steps: int, seconds: float) -> tuple:
    """(converged, status, moves) of one elastic NLP; ``elastic(label, is_start)`` says which
    conditions get a slack (the others are hard)."""
    import casadi as ca
    N, T = problem.intervals, float(problem.horizon)
    t = np.linspace(0.0, T, N + 1)
    opti = ca.Opti()
    Z, U = opti.variable(problem.n_states, N + 1), opti.variable(problem.n_controls, N)
    F = _stage(problem, steps).map(N)
    opti.subject_to(Z[:, 1:] == F(Z[:, :N], U, ca.DM(t[:N]).T, T / N))
    cost, slacks = 0, []
    for label, exprs, (lo, hi), start in _conditions(problem, Z, U, t):
        if not elastic(label, start):
            for e in exprs:
                opti.subject_to(opti.bounded(lo, e, hi) if lo < hi else e == lo)
            continue
        s = opti.variable()
        opti.subject_to(s >= 0)
        for e in exprs:
            if math.isfinite(lo):
                opti.subject_to(e >= lo - s)
            if math.isfinite(hi):
                opti.subject_to(e <= hi + s)
        cost, slacks = cost + s / _size(lo, hi), slacks + [(label, exprs, (lo, hi), s)]
    for name in problem.periodic:
        if not elastic(f"periodic.{name}", False):
            opti.subject_to(y_end(problem, Z, name) == y_start(problem, Z, name))
            continue
        s = opti.variable()
        opti.subject_to(opti.bounded(-s, y_end(problem, Z, name) - y_start(problem, Z, name), s))
        cost, slacks = cost + s, slacks + [(f"periodic.{name}", [], (0.0, 0.0), s)]
    opti.minimize(cost)
    _guess(opti, Z, U, problem, closest)
    # both clocks: CPU time alone let a loaded machine stretch the 60 s to 77 s of wall time
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "max_iter": 3000, "max_cpu_time": seconds,
                                                "max_wall_time": seconds, "tol": 1e-10, "acceptable_iter": 0,
                                                "sb": "yes"})
    try:
        sol = opti.solve()
        value, status = sol.value, "Solve_Succeeded"
    except RuntimeError:
        value, status = opti.debug.value, str(opti.stats().get("return_status", "failed"))
    return status == "Solve_Succeeded", status, tuple(_move(label, exprs, bounds, value(s), value)
                                                      for label, exprs, bounds, s in slacks)


def _size(lo: float, hi: float) -> float:
    """The size a move of a condition [lo, hi] is measured against: its largest finite |bound|,
    1 (SI) for a condition on 0."""
    size = max((abs(b) for b in (lo, hi) if math.isfinite(b)), default=0.0)
    return size if size > 0 else 1.0


def y_start(problem, Z, name):
    return problem.quantity(name, Z[:, 0])


def y_end(problem, Z, name):
    return problem.quantity(name, Z[:, -1])


def _move(label, exprs, bounds, slack, value) -> Move:
    """The :class:`Move` of one condition at the solution (``value`` evaluates an expression)."""
    values = [float(value(e)) for e in exprs]
    lo, hi = bounds
    reached = (max(values, key=lambda v: max(lo - v, v - hi)) if values else float("nan"))
    return Move(label, (float(lo), float(hi)), max(float(slack), 0.0), float(reached))


def _alone(problem, closest, moves, tolerance, steps, left) -> tuple:
    """((label, Move or None, answer), …): the move of each of at most :data:`ALONE` conditions
    when it alone is elastic (the others as stated), and that solve's answer: the conditions the
    L1 answer moved and every path and input bound — when the L1 answer moved anything. None: no
    gait found by moving it alone."""
    moved = [m.label for m in moves if m.by > tolerance]
    if not moved:
        return ()
    labels = list(dict.fromkeys(moved + [m.label for m in moves
                                         if m.label.startswith(("bounds.", "control_bounds."))]))
    if len(moved) == 1 and len(labels) == 1:
        return ()
    out = []
    for label in labels[:ALONE]:
        answer = _solve(problem, closest, elastic=lambda lab, start, c=label: lab == c,
                        steps=steps, seconds=left() / 2)
        out.append((label, next((m for m in answer[2] if m.label == label), None) if answer[0] else None,
                    answer))
    return tuple(out)


def _cost(answer) -> float:
    """The weighted total move of one elastic answer (converged, status, moves)."""
    return sum(m.by / _size(*m.asked) for m in answer[2])


def elastic_solve(problem, closest=None, *, tolerance: float = 1e-6, steps: int = 4,
                  seconds: float = ELASTIC_SECONDS, units=None) -> Elastic:
    """The minimum-violation solve of the module docstring on ``problem`` (the task as stated,
    in the planner's states), started from ``closest`` (a failed Solution on the same grid, or
    None); moves below ``tolerance`` count as met."""
    t0 = time.perf_counter()
    left = lambda: max(1.0, seconds - (time.perf_counter() - t0))  # noqa: E731
    start_moved = False
    for start_elastic in (False, True):
        elastic = lambda label, start, e=start_elastic: e or not start  # noqa: E731
        tries = [_solve(problem, start, elastic=elastic, steps=steps, seconds=left() / 2)
                 for start in ((closest, None) if closest is not None else (None,))]
        done = [x for x in tries if x[0]]
        converged, status, moves = min(done, key=_cost) if done else tries[0]
        start_moved = start_elastic
        if converged:
            break
    moves = tuple(sorted(moves, key=lambda m: -m.by))
    alone = (_alone(problem, closest, moves, tolerance, steps, left) if converged and not start_moved
             else ())
    better = [a for _, m, a in alone if m is not None and _cost(a) < _cost((True, "", moves))]
    if better:                      # a one-condition answer the L1 solve missed (it is local)
        moves = tuple(sorted(min(better, key=_cost)[2], key=lambda m: -m.by))
    alone = tuple((label, m) for label, m, _ in alone)
    return Elastic(converged=converged, status=status, moves=moves, tolerance=float(tolerance), alone=alone,
                   start_moved=start_moved and any(m.by > tolerance and m.label.startswith("initial.")
                                                   for m in moves),
                   seconds=time.perf_counter() - t0, units=dict(units or {}))


def with_elastic(result, prepared, search, budget, progress):
    """``result`` (a :class:`~nhgait.gaits.planner.PlanResult`) with the elastic solve's answer in
    ``solution.settings["elastic"]`` when attempts were made and the search solved nothing (not when the
    budget ran out, not for a task with phases), within :data:`ELASTIC_SECONDS` and the budget;
    said on ``progress``."""
    from dataclasses import replace
    s = result.solution
    if (s is None or result.overrun is not None or prepared is None or search is None
            or not result.attempts or search.solution is not None or prepared.stated.phases):
        return result
    seconds = min(ELASTIC_SECONDS, budget.remaining())
    if seconds < 1.0:
        return result
    closest = search.closest
    steps = int((closest.settings if closest is not None else {}).get("rk4_steps", 4))
    with progress.phase("minimum-violation (elastic) solve: how far each stated condition must move"):
        try:
            elastic = elastic_solve(prepared.stated, closest, tolerance=result.task.verify_tolerance,
                                    steps=steps, seconds=seconds, units=getattr(result.plan, "units", None))
        except (RuntimeError, ValueError, KeyError, IndexError) as exc:      # CasADi refused the NLP
            progress.note(f"  not made: {str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__}")
            return result
    for line in elastic.lines():
        progress.note(f"  {line}")
    return replace(result, solution=replace(s, settings={**s.settings, "elastic": elastic.to_dict()}))
