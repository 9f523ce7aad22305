"""Trying initial guesses: the candidates in order, a continuation when none converges.

:func:`solve_with_fallbacks` is what the planner and the sweep call::

    search = solve_with_fallbacks(solver, guesses, workers=2, limit=12, progress=progress)
    search.solution, search.won, search.attempts, search.closest

* :func:`solve_from_guesses` — the guesses in batches of ``workers``, each attempt in a child
  process supervised by :func:`~nhgait.ocp.supervision.supervise` (:func:`solve_attempts`: bounded
  in time, killed at once on an interrupt; ``workers`` children at once); within the first
  batch with a success the lowest objective wins; at most ``limit`` guesses are tried.
* :func:`continuation` — when every guess fails: easier versions of the problem (the end
  values fixed at both ends moved a fraction 1/4, 1/2, 3/4 of the way from their initial
  values) grown to the task, each warm-started from the last.

Every attempt is recorded (:class:`Attempt`); the failed solution with the smallest
constraint violation is kept as ``closest`` — the point a failure report describes. With a
``budget`` (:class:`~nhgait.ocp.budget.Budget`) no attempt runs past the time left and nothing
new starts once it is spent: the caller checks ``budget.spent()`` and reports it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

__all__ = ["Attempt", "Search", "solve_attempts", "solve_from_guesses", "solve_with_fallbacks", "continuation"]


@dataclass(frozen=True)
class Attempt:
    """One candidate tried: its label, the solver and its verdict."""

    label: str
    status: str
    success: bool
    iterations: int
    objective: float
    solver: str = ""
    constraint_violation: float = math.nan
    seconds: float = 0.0


@dataclass(frozen=True, eq=False)
class Search:
    """What trying the guesses gave: the winning ``solution`` (None when none converged), its
    label ``won``, every ``attempt`` and the ``closest`` failure (smallest violation)."""

    solution: Any
    attempts: tuple
    won: str | None
    closest: Any = None

    def then(self, other: "Search") -> "Search":
        """This search followed by ``other`` (attempts joined, the closer failure kept)."""
        return Search(other.solution, self.attempts + other.attempts, other.won,
                      _closer(self.closest, other.closest))


def _closer(a, b):
    if a is None or b is None:
        return a if b is None else b
    va, vb = a.constraint_violation, b.constraint_violation
    return b if (math.isnan(va) or (not math.isnan(vb) and vb < va)) else a


def _attempt(label, s, solver_name="") -> Attempt:
    return Attempt(label, s.status, bool(s.success), int(s.iterations), float(s.objective), solver_name,
                   float(s.constraint_violation), float(s.solve_time_s))


#: statuses of attempts that gave no answer of their own (their supervisor's message says why)
UNANSWERED = ("Time_Limit_Exceeded", "Solver_Died")


def _report(progress, index, total, label, s) -> None:
    if s.success:
        progress.note(f"  guess {index}/{total} {label!r}: {s.status} after {s.iterations} iterations, "
                      f"J = {s.objective:.6g} ({s.solve_time_s:.2f} s)")
    elif s.status in UNANSWERED and s.iterations == 0:
        progress.note(f"  guess {index}/{total} {label!r}: {s.message} — next")
    else:
        progress.note(f"  guess {index}/{total} {label!r}: {s.status} after {s.iterations} iterations "
                      f"({s.solve_time_s:.2f} s; constraint violation {s.constraint_violation:.2g}) — next")


# ----------------------------------------------------------------------------- supervised attempts
def _detached(solver, guess):
    """In the attempt's child: the solve, without its problem (the parent puts it back)."""
    return replace(solver.solve(guess), problem=None)


def _limit(solver, budget) -> float | None:
    """When the supervisor kills an attempt: at the solver's time limit — plus a grace in which
    a solver that honours it (Ipopt) stops itself and answers — within what is left of ``budget``."""
    from nhgait.ocp.budget import KILL_GRACE_S
    options = solver.options
    limit = None if options.time_limit is None else float(options.time_limit)
    if limit is not None and options.stops_in_time:
        limit += KILL_GRACE_S
    return limit if budget is None else budget.limit(limit)


def solve_attempts(solver, guesses, *, workers: int = 1, budget=None, progress=None) -> list:
    """The solutions of ``guesses`` (in order), each solved in a child process that
    :func:`~nhgait.ocp.supervision.supervise` bounds in time and kills on any interrupt, up to
    ``workers`` at once; an attempt killed at its limit (or within what is left of ``budget``)
    is a failed solution with status ``Time_Limit_Exceeded``, one whose process died
    ``Solver_Died``."""
    from functools import partial
    from nhgait.ocp.supervision import Job, supervise
    limit = _limit(solver, budget)
    jobs = [Job(partial(_detached, solver, g), limit, partial(solver.unsolved, g)) for g in guesses]
    return [replace(s, problem=solver.problem) for s in supervise(jobs, workers=workers, progress=progress)]


def _spent(budget) -> bool:
    return budget is not None and budget.spent()


def _built(guesses, indices, budget) -> list | None:
    """The guesses at ``indices`` (built now when lazy: a roll-out integrates the model), or
    None when ``budget`` is spent before or while they are built."""
    if budget is None:
        return [guesses[i] for i in indices]
    from nhgait.ocp.budget import BudgetSpent
    try:
        with budget.stage("the initial guesses"):
            return [guesses[i] for i in indices]
    except BudgetSpent:
        return None


# ----------------------------------------------------------------------------- the search
def solve_from_guesses(solver, guesses, *, workers: int = 1, limit: int | None = None, progress=None,
                       budget=None) -> Search:
    """Try ``guesses`` (at most ``limit``) in batches of ``workers``; the best success of the
    first batch with one. With a ``budget`` (:class:`~nhgait.ocp.budget.Budget`) each attempt
    gets at most the time left, and no batch starts once it is spent."""
    from nhgait.dynamics.progress import Progress
    progress = progress or Progress.silent()
    name = solver.options.solver
    workers = max(1, int(workers))
    total = len(guesses) if limit is None else min(len(guesses), int(limit))
    attempts, closest = [], None
    for start in range(0, total, workers):
        batch = _built(guesses, range(start, min(start + workers, total)), budget)
        if batch is None:
            break
        sols = solve_attempts(solver, batch, workers=workers, budget=budget, progress=progress)
        for k, (g, s) in enumerate(zip(batch, sols)):
            attempts.append(_attempt(g.label, s, name))
            _report(progress, start + k + 1, total, g.label, s)
            if not s.success:
                closest = _closer(closest, s)
        good = [(s.objective, i) for i, s in enumerate(sols) if s.success]
        if good:
            _, i = min(good)
            return Search(sols[i], tuple(attempts), batch[i].label, closest)
    return Search(None, tuple(attempts), None, closest)


def solve_with_fallbacks(solver, guesses, *, workers: int = 1, limit: int | None = None, progress=None,
                         budget=None) -> Search:
    """The guesses in order (:func:`solve_from_guesses`), then :func:`continuation` from the
    first one (not once ``budget`` is spent)."""
    search = solve_from_guesses(solver, guesses, workers=workers, limit=limit, progress=progress, budget=budget)
    if search.solution is None and len(guesses) and not _spent(budget):
        if progress is not None:
            progress.note(f"  no guess converged: continuation from {guesses[0].label!r} (the task's end values "
                          "approached in 4 steps)")
        search = search.then(continuation(solver, guesses[0], progress=progress, budget=budget))
    return search


def _moved(problem, alpha):
    """``problem`` with every end value fixed at both ends moved a fraction ``alpha`` of the way."""
    final = {}
    for name, value in problem.final.items():
        lo, hi = problem.bounds(problem.final, name)
        if name in problem.initial and lo == hi:
            a0, b0 = problem.bounds(problem.initial, name)
            if a0 == b0:
                final[name] = a0 + alpha * (lo - a0)
                continue
        final[name] = value
    return problem.replace(final=final)


def continuation(solver, guess, steps=(0.25, 0.5, 0.75, 1.0), *, progress=None, budget=None) -> Search:
    """Grow an easier problem into ``solver.problem`` (module docstring); each step a
    supervised attempt (:func:`solve_attempts`), none started once ``budget`` is spent."""
    from nhgait.ocp import InitialGuess
    attempts, current, closest = [], guess, None
    solution = None
    for k, alpha in enumerate(steps, 1):
        if _spent(budget):             # every step so far converged: no failure to report
            return Search(None, tuple(attempts), None, closest)
        sub = solver.with_problem(_moved(solver.problem, alpha))
        solution, = solve_attempts(sub, [current], budget=budget, progress=progress)
        label = f"continuation {alpha:g} from {guess.label}"
        attempts.append(_attempt(label, solution, solver.options.solver))
        if progress is not None:
            _report(progress, k, len(steps), label, solution)
        if not solution.success:
            return Search(None, tuple(attempts), None, solution)
        current = InitialGuess(solution.states, solution.controls, solution.horizon, label)
    return Search(replace(solution, problem=solver.problem), tuple(attempts), attempts[-1].label, closest)
