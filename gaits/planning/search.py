"""Trying initial guesses: the candidates in order, a continuation when none converges.

:func:`solve_with_fallbacks` is what the planner and the sweep call::

    search = solve_with_fallbacks(solver, guesses, SearchRun(workers=2, limit=12, progress=progress))
    search.solution, search.won, search.attempts, search.closest

* :func:`solve_from_guesses` — the guesses in batches of ``workers``, each attempt in a child
  process supervised by :func:`~nhgait.ocp.supervision.supervise` (:func:`solve_attempts`: bounded
  in time, killed at once on an interrupt; ``workers`` children at once); within the first
  batch with a success the lowest objective wins; at most ``limit`` guesses are tried. With
  ``explore`` (the planner) the next few guesses are tried too, two at once on two cores
  (``explore_workers``), within an allowance tied to the first success's iterations — turned
  into seconds at its own cost per iteration for a solver without an iteration callback — and
  the lowest objective of all is kept: the first local optimum found is often not the best
  (:data:`EXPLORE_GUESSES`). The exploration stops early once :data:`EXPLORE_REPEATS` further
  guesses converge to the best objective again (within :data:`EXPLORE_GAIN`).
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
import time
from dataclasses import dataclass, field, replace
from typing import Any

from nhgait.ocp.coarse import WARM_IPOPT as _WARM_IPOPT

from .infeasibility import STALL_ATTEMPTS, stalled

__all__ = ["Attempt", "Search", "SearchRun", "WARM_IPOPT", "attempt_of", "solve_attempts",
           "solve_from_guesses", "solve_with_fallbacks", "continuation"]


@dataclass(kw_only=True, frozen=True)
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
    #: objective and constraint violation per iteration (Ipopt; {} for FATROP): the convergence figure
    history: dict = field(default_factory=dict, repr=False)


@dataclass(frozen=True, eq=False)
class Search:
    """What trying the guesses gave: the winning ``solution`` (None when none converged), its
    label ``won``, every ``attempt`` and the ``closest`` failure (smallest violation); ``first``
    and ``first_won``: the first converged solution when the exploration kept another (the
    planner falls back to it when the kept one fails its verification)."""

    solution: Any
    attempts: tuple
    won: str | None
    closest: Any = None
    first: Any = None               # the first converged solution, when the exploration kept another
    first_won: str | None = None

    def then(self, other: Search) -> Search:
        """This search followed by ``other`` (attempts joined, the closer failure kept)."""
        return Search(other.solution, self.attempts + other.attempts, other.won,
                      _closer(self.closest, other.closest), other.first, other.first_won)


def _closer(a, b):
    if a is None or b is None:
        return a if b is None else b
    va, vb = a.constraint_violation, b.constraint_violation
    return b if (math.isnan(va) or (not math.isnan(vb) and vb < va)) else a


def attempt_of(label, s, solver_name="") -> Attempt:
    """The :class:`Attempt` record of solution ``s`` of the guess ``label``."""
    history = (getattr(s, "stats", None) or {}).get("history") or {}
    return Attempt(label=label, status=s.status, success=bool(s.success), iterations=int(s.iterations),
                   objective=float(s.objective), solver=solver_name,
                   constraint_violation=float(s.constraint_violation), seconds=float(s.solve_time_s),
                   history=dict(history))


#: guesses tried after the first converged one when the search explores (the planner), the
#: lowest objective kept: one task can have many local optima (a snakeboard's sideways gait
#: reached 0.0288 … 0.0479 from twelve guesses, the first 0.0331) ...
EXPLORE_GUESSES = 6
#: ... sharing, in order, an allowance of this many times the first success's iterations (at
#: least EXPLORE_MIN_ITERATIONS): counted in iterations, not seconds, so that a cold plan (the
#: fast compiler's slower code) and a warm one, a slow machine and a fast one, try the same
#: guesses and keep the same optimum; at most EXPLORE_BUDGET_SHARE of what is left of the plan's
#: budget in seconds (a solver without an iteration callback: below). Measured (46 plans: the
#: scale benchmark's 13 robots, P1–P4, 8 user scenes, 20 unseen robots, the user's 3-link snake;
#: docs/gait-planning.md): of 90 attempts 6 found a lower objective, each within 2.6× the first
#: success's iterations of the exploration's start. Of the plans whose first success took under
#: 34 (where a floor of 100 gave more than 3×) one found a lower objective: the user's 3-link
#: snake, 30 iterations in (its first: 21, so 64 now); in the others the extra allowance only
#: let a failing guess run on (the cart with six trailers: 99 iterations, 5 s of a 13 s plan).
EXPLORE_ITERATION_RATIO = 3.0
EXPLORE_MIN_ITERATIONS = 50
EXPLORE_BUDGET_SHARE = 0.25
#: A solver without an iteration callback (FATROP) gets the same allowance of iterations turned
#: into seconds at the first success's own cost per iteration (its solver-measured time over its
#: iterations), plus the first attempt's overhead outside the solver (its process, its guess),
#: and at least EXPLORE_FLOOR_S: the exploration costs what the solves it makes cost, on a slow
#: machine and a fast one (issue 40: the 0.05 s parallel park of the unicycle had 1 s before).
EXPLORE_FLOOR_S = 0.1
#: a later guess replaces the best so far when its objective is lower by more than this
#: fraction (of max(1, |J|)): the same optimum reached from another guess is not a new one
EXPLORE_GAIN = 1e-6
#: the exploration stops once this many further guesses have converged to the best objective
#: so far (within EXPLORE_GAIN) without one lower: the optimum found is the one the guesses
#: lead to (issue 40; the parallel park's 2nd and 3rd guesses reach the 1st's J = 1.53444)
EXPLORE_REPEATS = 2

#: Ipopt settings of warm-started solves (:data:`nhgait.ocp.coarse.WARM_IPOPT`)
WARM_IPOPT = _WARM_IPOPT

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


def solve_attempts(solver, guesses, *, workers: int = 1, budget=None, progress=None, meanwhile=None) -> list:
    """The solutions of ``guesses`` (in order), each solved in a child process that
    :func:`~nhgait.ocp.supervision.supervise` bounds in time and kills on any interrupt, up to
    ``workers`` at once; an attempt killed at its limit (or within what is left of ``budget``)
    is a failed solution with status ``Time_Limit_Exceeded``, one whose process died
    ``Solver_Died``. ``meanwhile``: run in this process while the attempts work
    (:func:`~nhgait.ocp.supervision.supervise`)."""
    from functools import partial

    from nhgait.ocp.supervision import Job, supervise
    limit = _limit(solver, budget)
    jobs = [Job(partial(_detached, solver, g), limit, partial(solver.unsolved, g)) for g in guesses]
    return [replace(s, problem=solver.problem)
            for s in supervise(jobs, workers=workers, progress=progress, meanwhile=meanwhile)]


def _spent(budget) -> bool:
    return budget is not None and budget.spent()


def _take(guesses, indices) -> list:
    """The guesses at ``indices``, fewer when the sequence runs out first (screened candidates
    skip the ones that cannot be repaired, so their length is known only once they are built)."""
    out = []
    for i in indices:
        try:
            out.append(guesses[i])
        except IndexError:
            break
    return out


def _built(guesses, indices, budget) -> list | None:
    """The guesses at ``indices`` (:func:`_take`; built now when lazy: a roll-out integrates the
    model), or None when ``budget`` is spent before or while they are built."""
    if budget is None:
        return _take(guesses, indices)
    from nhgait.ocp.budget import BudgetSpent
    try:
        with budget.stage("the initial guesses"):
            return _take(guesses, indices)
    except BudgetSpent:
        return None


# ----------------------------------------------------------------------------- the search
@dataclass(frozen=True, kw_only=True)
class SearchRun:
    """How :func:`solve_from_guesses` and :func:`solve_with_fallbacks` try the guesses:
    ``workers`` attempts at once, at most ``limit`` guesses (None: all), ``progress`` (None:
    silent), the plan's ``budget`` (None: none), ``explore`` (the next guesses after a first
    success, :func:`_explored`) with ``explore_workers`` at once (None: ``workers``), and
    ``meanwhile``: run in this process while the first attempts work (:func:`solve_attempts`);
    ``in_process``: the seconds per iteration measured on the solve a warm start comes from — a
    batch of one guess is then first solved in this process when that cannot delay a stop
    (:func:`_in_process`); None: never."""

    workers: int = 1
    limit: int | None = None
    progress: Any = None
    budget: Any = None
    explore: bool = False
    explore_workers: int | None = None
    meanwhile: Any = None
    in_process: float | None = None

    @classmethod
    def of(cls, run: SearchRun | None, fields: dict) -> SearchRun:
        """``run`` (None: the defaults) with ``fields`` changed (the keyword form of the calls)."""
        return replace(run or cls(), **fields) if fields else (run or cls())


def solve_from_guesses(solver, guesses, run: SearchRun | None = None, **fields) -> Search:
    """Try ``guesses`` (at most ``run.limit``) in batches of ``run.workers``; the best success of
    the first batch with one — with ``run.explore``, the best of that and of the next
    :data:`EXPLORE_GUESSES` guesses tried within the exploration's window (:func:`_explored`),
    ``run.explore_workers`` at once (None: ``workers``). ``run.meanwhile``: run in this process
    while the first attempts work (:func:`solve_attempts`). ``fields``: :class:`SearchRun`'s
    fields as keywords (``limit=4, explore=True``).
    With a ``run.budget`` (:class:`~nhgait.ocp.budget.Budget`) each attempt gets at most the time
    left, and no batch starts once it is spent."""
    from nhgait.dynamics.progress import Progress
    run = SearchRun.of(run, fields)
    progress, budget, meanwhile = run.progress or Progress.silent(), run.budget, run.meanwhile
    name = solver.options.solver
    workers = max(1, int(run.workers))
    total = len(guesses) if run.limit is None else min(len(guesses), int(run.limit))
    attempts, closest = [], None
    for start in range(0, total, workers):
        batch = _built(guesses, range(start, min(start + workers, total)), budget)
        if not batch:
            break
        solver.adopt_optimised()
        t0, aside = time.monotonic(), _Aside(meanwhile)
        here = _in_process(solver, batch, run) if run.in_process is not None else None
        sols = here or solve_attempts(solver, batch, workers=workers, budget=budget, progress=progress,
                                      meanwhile=aside if meanwhile is not None else None)
        meanwhile = None
        for k, (g, s) in enumerate(zip(batch, sols, strict=True)):
            attempts.append(attempt_of(g.label, s, name))
            _report(progress, start + k + 1, total, g.label, s)
            if not s.success:
                closest = _closer(closest, s)
        good = [(s.objective, i) for i, s in enumerate(sols) if s.success]
        if not good and stalled(attempts):                 # issue 41: the same infeasibility again
            progress.note(f"  the last {STALL_ATTEMPTS} attempts stopped at the same infeasible point: "
                          "no more guesses")
            break
        if good:
            _, i = min(good)
            found = Search(sols[i], tuple(attempts), batch[i].label, closest)
            if not run.explore:
                return found
            window = _Window.after(found.solution, time.monotonic() - t0 - aside.seconds, solver, budget)
            after = start + len(batch)
            return _explored(solver, guesses, found, range(after, min(total, after + EXPLORE_GUESSES)),
                             window, replace(run, progress=progress,
                                             workers=max(1, int(run.explore_workers or workers))))
    return Search(None, tuple(attempts), None, closest)


#: a warm start is solved in this process, not in a supervised child, when its solver stops by
#: itself within this many iterations (:meth:`~nhgait.ocp.solver.OCPSolver.capped`) ...
IN_PROCESS_ITERATIONS = 50
#: ... and so many iterations took at most this long at the cost per iteration measured on the
#: solve it starts from: a stop signal, whose handler runs once the solver returns (FATROP has no
#: callback), then waits at most about that long (the command line's watchdog ends a process
#: still running 1.5 s after one, :mod:`nhgait.gaits.cli.stopping`); a loaded machine, whose
#: iterations take longer, solves in a supervised child. (The cost per iteration may have been
#: measured in a child granted two threads, :mod:`nhgait.dynamics.numerics.openmp`; this process
#: runs its maps on one, so the bound can be up to twice this: still below the watchdog's.)
IN_PROCESS_MAX_S = 0.5


def _in_process(solver, batch, run: SearchRun) -> list | None:
    """[the converged solution of the one guess in ``batch``] solved in this process, or None:
    not one guess, interpreted code, a cap (:data:`IN_PROCESS_ITERATIONS`) whose iterations could
    take longer than :data:`IN_PROCESS_MAX_S` (at ``run.in_process`` seconds each), less than
    twice that left of ``run.budget``, or no convergence within the cap (then the caller's
    supervised attempt solves it as ever). Until the cap the iterates are the supervised solve's,
    so a converged answer is the same one; the supervised child costs a fork and a pickled
    solution, more than a warm start's solve (issue 40)."""
    budget, progress = run.budget, run.progress
    worst = IN_PROCESS_ITERATIONS * float(run.in_process)
    if len(batch) != 1 or worst > IN_PROCESS_MAX_S or (budget is not None
                                                      and budget.remaining() < 2 * IN_PROCESS_MAX_S):
        return None
    capped = solver.capped(IN_PROCESS_ITERATIONS)
    if capped is None:
        return None
    solution = capped.solve(batch[0])
    if not solution.success:
        if progress is not None:
            progress.note(f"  in this process: {solution.status} within {IN_PROCESS_ITERATIONS} iterations; "
                          "solved again in a supervised child")
        return None
    if progress is not None:
        progress.note(f"  solved in this process (a warm start: at most {IN_PROCESS_ITERATIONS} iterations, "
                      f"about {worst:.2g} s at most; no supervised child)")
    return [solution]


class _Aside:
    """``work`` (a callable, or None) timed: ``seconds`` it took — this process's time spent
    aside while the attempts ran, not theirs."""

    def __init__(self, work):
        self.work, self.seconds = work, 0.0

    def __call__(self):
        t0 = time.monotonic()
        try:
            self.work()
        finally:
            self.seconds += time.monotonic() - t0


@dataclass(frozen=True)
class _Window:
    """What the exploration may still spend: ``iterations`` (None: not counted — a solver
    without an iteration callback) and a ``deadline`` (``time.monotonic()``; None: none)."""

    iterations: float | None
    deadline: float | None

    @classmethod
    def after(cls, first, seconds: float, solver, budget) -> _Window:
        """The window after a first success ``first`` that took ``seconds`` (:data:`EXPLORE_GUESSES`)."""
        now = time.monotonic()
        share = None if budget is None else EXPLORE_BUDGET_SHARE * budget.remaining()
        iterations = max(EXPLORE_MIN_ITERATIONS, math.ceil(EXPLORE_ITERATION_RATIO * _cost(first)))
        if solver.options.backend.iteration_callback:
            return cls(iterations, None if share is None else now + share)
        solving = float(first.solve_time_s)
        per_iteration = solving / max(1.0, _cost(first))
        spend = max(EXPLORE_FLOOR_S, iterations * per_iteration + max(0.0, seconds - solving))
        return cls(None, now + (spend if share is None else min(spend, share)))

    def text(self) -> str:
        if self.iterations is not None:
            return f"{self.iterations:.0f} iterations in all"
        left = max(0.0, self.deadline - time.monotonic())
        return f"{left:.0f} s" if left >= 10 else f"{left:.2g} s"

    def left(self) -> float | None:
        """Seconds left now (None: no deadline), or 0 when nothing is left of either kind."""
        seconds = None if self.deadline is None else max(0.0, self.deadline - time.monotonic())
        return 0.0 if self.iterations is not None and self.iterations <= 0 else seconds

    def less(self, iterations: float) -> _Window:
        """This window after attempts that took ``iterations`` in all."""
        return self if self.iterations is None else replace(self, iterations=self.iterations - iterations)

    def limited(self, solver, left: float | None):
        """``solver`` bounded by what is left: the iterations and ``left`` seconds (:meth:`left`, > 0)."""
        own = solver.options.time_limit
        seconds = own if left is None else (left if own is None else min(left, own))
        iterations = None if self.iterations is None else max(1, math.ceil(self.iterations))
        return solver.with_time_limit(seconds).with_iteration_limit(iterations)


def _cost(solution) -> float:
    """An attempt's iterations in the task grid's terms: a coarse grid's (:mod:`nhgait.ocp.coarse`)
    in proportion to its intervals."""
    n = solution.stats.get("coarse_intervals")
    coarse = solution.stats.get("coarse_iterations", 0) * n / solution.problem.intervals if n else 0.0
    return solution.iterations + coarse


def _explored(solver, guesses, found: Search, indices, window: _Window, run: SearchRun) -> Search:
    """``found`` or a lower objective among the guesses at ``indices`` tried after it, in order,
    each attempt within what is left of ``window`` (the closest failure and every attempt kept;
    the first success kept as ``first`` when another wins).
    The exploration solves on the task's grid directly (:meth:`~nhgait.ocp.solver.OCPSolver.direct`):
    a coarse grid (:mod:`nhgait.ocp.coarse`) leads a guess to the optimum it leads to, which need
    not be the direct solve's — the exploration keeps the optima the direct solves reach within
    its reach (the user's 3-link snake: the coarse grid led the first guess to J = 0.01105, the
    direct solve of the second reaches 0.008693). ``run``: its ``workers`` at once, within its
    ``budget``, talking on its ``progress``."""
    name, workers, budget, progress = solver.options.solver, run.workers, run.budget, run.progress
    attempts, best, label, repeats = list(found.attempts), found.solution, found.won, 0
    indices = list(indices)
    if indices and window.left() != 0.0:
        progress.note(f"  looking for a lower objective: up to {len(indices)} more guesses within "
                      f"{window.text()}")
    first_s = float(found.solution.solve_time_s)
    for start in range(0, len(indices), workers):
        left = window.left()
        if left == 0.0 or _spent(budget) or (left is not None and left < first_s):
            break                            # nothing left that could pay for an attempt
        batch = _built(guesses, indices[start:start + workers], budget)
        if not batch:
            break
        solver.adopt_optimised()
        sols = solve_attempts(window.limited(solver.direct(), left), batch, workers=workers, budget=budget,
                              progress=progress)
        window = window.less(sum(_cost(s) for s in sols))
        for k, (g, s) in enumerate(zip(batch, sols, strict=True)):
            attempts.append(attempt_of(g.label, s, name))
            _report(progress, indices[start] + k + 1, indices[-1] + 1, g.label, s)
            tolerance = EXPLORE_GAIN * max(1.0, abs(best.objective))
            if s.success and s.objective < best.objective - tolerance:
                best, label, repeats = s, g.label, 0
            elif s.success and abs(s.objective - best.objective) <= tolerance:
                repeats += 1
        if repeats >= EXPLORE_REPEATS:
            progress.note(f"  {repeats} more guesses reached J = {best.objective:.6g} again: no more")
            break
    if label != found.won:
        progress.note(f"  kept {label!r}: J = {best.objective:.6g} (the first converged: "
                      f"{found.solution.objective:.6g})")
    if label == found.won:
        return Search(best, tuple(attempts), label, found.closest)
    return Search(best, tuple(attempts), label, found.closest, found.solution, found.won)


def solve_with_fallbacks(solver, guesses, run: SearchRun | None = None, **fields) -> Search:
    """The guesses in order (:func:`solve_from_guesses`, exploring with ``run.explore``), then
    :func:`continuation` from the first one (for screened candidates, the first that passed its
    screening: a regular guess; not once ``run.budget`` is spent). ``fields``: :class:`SearchRun`'s
    fields as keywords."""
    run = SearchRun.of(run, fields)
    budget, progress = run.budget, run.progress
    search = solve_from_guesses(solver, guesses, run)
    first = (None if search.solution is not None or _spent(budget) or stalled(search.attempts)
             else _built(guesses, range(1), budget))
    if first:
        if progress is not None:
            progress.note(f"  no guess converged: continuation from {first[0].label!r} (the "
                          "task's end values approached in 4 steps)")
        search = search.then(continuation(solver, first[0], progress=progress, budget=budget))
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
    supervised attempt (:func:`solve_attempts`), none started once ``budget`` is spent. A
    failed step is the search's ``closest`` only when it is the task itself (the last): an
    easier problem's point is not one of the task's."""
    from nhgait.ocp import InitialGuess
    attempts, current, closest = [], guess, None
    solution = None
    for k, alpha in enumerate(steps, 1):
        if _spent(budget):             # every step so far converged: no failure to report
            return Search(None, tuple(attempts), None, closest)
        sub = solver.with_problem(_moved(solver.problem, alpha))
        solution, = solve_attempts(sub, [current], budget=budget, progress=progress)
        label = f"continuation {alpha:g} from {guess.label}"
        attempts.append(attempt_of(label, solution, solver.options.solver))
        if progress is not None:
            _report(progress, k, len(steps), label, solution)
        if not solution.success:          # a step short of the task is not a point of it
            return Search(None, tuple(attempts), None, solution if alpha == steps[-1] else None)
        current = InitialGuess(solution.z.T, solution.u.T, solution.horizon, label)
    return Search(replace(solution, problem=solver.problem), tuple(attempts), attempts[-1].label, closest)
