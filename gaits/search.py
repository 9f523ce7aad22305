"""Trying initial guesses: the candidates in order, a continuation when none converges.

:func:`solve_with_fallbacks` is what the planner and the sweep call::

    search = solve_with_fallbacks(solver, guesses, workers=2, limit=12, progress=progress)
    search.solution, search.won, search.attempts, search.closest

* :func:`solve_from_guesses` — the guesses in batches of ``workers`` (forked processes when
  ``workers > 1``); within the first batch with a success the lowest objective wins; at most
  ``limit`` guesses are tried.
* :func:`continuation` — when every guess fails: easier versions of the problem (the end
  values fixed at both ends moved a fraction 1/4, 1/2, 3/4 of the way from their initial
  values) grown to the task, each warm-started from the last.

Every attempt is recorded (:class:`Attempt`); the failed solution with the smallest
constraint violation is kept as ``closest`` — the point a failure report describes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

__all__ = ["Attempt", "Search", "solve_from_guesses", "solve_with_fallbacks", "continuation"]


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


def _report(progress, index, total, label, s) -> None:
    if s.success:
        progress.note(f"  guess {index}/{total} {label!r}: {s.status} after {s.iterations} iterations, "
                      f"J = {s.objective:.6g} ({s.solve_time_s:.2f} s)")
    else:
        progress.note(f"  guess {index}/{total} {label!r}: {s.status} after {s.iterations} iterations "
                      f"({s.solve_time_s:.2f} s; constraint violation {s.constraint_violation:.2g}) — next")


# ----------------------------------------------------------------------------- parallel batches
_WORKER: dict = {}   # set by the pool initializer, in forked worker processes only


def _receive(solver, guesses, parent):
    """Pool initializer: the batch, inherited through fork (nothing is pickled). A worker dies
    at once on SIGTERM (``pool.terminate()``, even inside the solver) and leaves Ctrl-C to the
    parent, which terminates the pool (inheriting the CLI's handlers, workers raised inside the
    solver and deadlocked the pool). On Linux it is also killed when the thread that forked it
    ends (``PR_SET_PDEATHSIG``): the pool's handler thread can fork a replacement while the
    pool is being terminated, and that worker outlived the planner, waiting on the task queue."""
    import os
    import signal
    import sys
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes
        ctypes.CDLL(None).prctl(1, signal.SIGKILL)          # PR_SET_PDEATHSIG
        if os.getppid() != parent:                          # the parent ended before that
            os._exit(1)
    _WORKER["batch"] = (solver, guesses)


def _solve_index(i):
    """Worker of a forked process: solve candidate i of the batch set up by the parent."""
    solver, guesses = _WORKER["batch"]
    return replace(solver.solve(guesses[i]), problem=None)


def _solve_batch(solver, guesses, workers: int, progress) -> list:
    """Solutions of ``guesses`` (in order), in ``workers`` forked processes when possible."""
    import multiprocessing as mp
    import os
    if workers > 1 and len(guesses) > 1 and "fork" in mp.get_all_start_methods():
        try:
            with mp.get_context("fork").Pool(min(workers, len(guesses)), initializer=_receive,
                                             initargs=(solver, guesses, os.getpid())) as pool:
                sols = pool.map(_solve_index, range(len(guesses)))
            return [replace(s, problem=solver.problem) for s in sols]
        except (OSError, RuntimeError) as exc:   # no fork here (sandbox, resources)
            progress.note(f"  solving in parallel is not possible here ({exc}); one guess at a time")
    return [solver.solve(g) for g in guesses]


# ----------------------------------------------------------------------------- the search
def solve_from_guesses(solver, guesses, *, workers: int = 1, limit: int | None = None, progress=None) -> Search:
    """Try ``guesses`` (at most ``limit``) in batches of ``workers``; the best success of the
    first batch with one."""
    from nhgait.dynamics.progress import Progress
    progress = progress or Progress.silent()
    name = solver.options.solver
    workers = max(1, int(workers))
    total = len(guesses) if limit is None else min(len(guesses), int(limit))
    attempts, closest = [], None
    for start in range(0, total, workers):
        batch = _take(guesses, start, min(start + workers, total))
        if not batch:
            break
        sols = _solve_batch(solver, batch, workers, progress)
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


def _take(guesses, start: int, stop: int) -> list:
    """guesses[start:stop], shorter when the sequence runs out (screened candidates skip the
    ones that cannot be repaired, so their length is known only once they are built)."""
    out = []
    for i in range(start, stop):
        try:
            out.append(guesses[i])
        except IndexError:
            break
    return out


def solve_with_fallbacks(solver, guesses, *, workers: int = 1, limit: int | None = None, progress=None) -> Search:
    """The guesses in order (:func:`solve_from_guesses`), then :func:`continuation` from the
    first one (for screened candidates, the first that passed its screening: a regular guess)."""
    search = solve_from_guesses(solver, guesses, workers=workers, limit=limit, progress=progress)
    first = _take(guesses, 0, 1)
    if search.solution is None and first:
        if progress is not None:
            progress.note(f"  no guess converged: continuation from {first[0].label!r} (the task's end values "
                          "approached in 4 steps)")
        search = search.then(continuation(solver, first[0], progress=progress))
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


def continuation(solver, guess, steps=(0.25, 0.5, 0.75, 1.0), *, progress=None) -> Search:
    """Grow an easier problem into ``solver.problem`` (module docstring)."""
    from nhgait.ocp import InitialGuess
    attempts, current, closest = [], guess, None
    solution = None
    for k, alpha in enumerate(steps, 1):
        sub = solver.with_problem(_moved(solver.problem, alpha))
        solution = sub.solve(current)
        label = f"continuation {alpha:g} from {guess.label}"
        attempts.append(_attempt(label, solution, solver.options.solver))
        if progress is not None:
            _report(progress, k, len(steps), label, solution)
        if not solution.success:
            return Search(None, tuple(attempts), None, solution)
        current = InitialGuess(solution.states, solution.controls, solution.horizon, label)
    return Search(replace(solution, problem=solver.problem), tuple(attempts), attempts[-1].label, closest)
