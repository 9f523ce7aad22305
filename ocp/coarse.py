"""A coarse grid first: each cold attempt solves the task on about N/3 intervals, then the task's
own NLP from that answer (issue 25: the first gait in seconds, fewer iterations from generic
guesses).

Grid continuation, as direct-transcription solvers do it: an iteration of the multiple-shooting
NLP costs about N times the work of one interval (the stage functions and their Hessians, and
MUMPS on a banded KKT system), and most of the iterations from a generic guess are spent moving
a rough shape to the right one — work a coarser grid does at a third of the price. So an
attempt from a guess z⁰ on the task's grid t_k = k T/N:

1. the guess resampled onto the coarse grid (N_c = ⌊N / :data:`RATIO`⌋ intervals, the same RK4
   sub-steps per interval: states linearly, inputs piecewise constant), solved there;
2. if that converged, its states interpolated linearly onto the task's grid and its inputs
   sampled at the intervals' midpoints (:func:`interpolated`), and the task's NLP solved from
   there with Ipopt's warm-start settings (:data:`WARM_IPOPT`) — a handful of iterations;
3. if the coarse solve failed, the task's NLP from the guess itself, as without a coarse grid.

Measured (the 4-link snake, N = 50, the planner's first guess, -O2 code, one run): 55
iterations and 530 ms directly; N_c = 17: 60 coarse + 13 fine iterations, 0.57× the time, the
same optimum to 2e-9 relative (N_c = 25: 46 + 13, 0.73×; N_c = 12 failed with a non-finite
constraint: :data:`MIN_INTERVALS`).

A coarse grid is used for a problem of at least :data:`RATIO` × :data:`MIN_INTERVALS`
intervals without waypoints (their times must be nodes) or phases, with Ipopt, when the solver
is made with ``SolverOptions(coarse=True)``: the planner's search from its own guesses until one
converges — the exploration after it solves on the task's grid directly
(:meth:`~.solver.OCPSolver.direct`), since a coarse grid leads a guess to the optimum *it* leads
to, not always the direct solve's (the user's 3-link snake: J = 0.01105 from the first guess
through the coarse grid, 0.008693 from the second directly, kept) — and not a warm start (a
user's guess, a sweep's neighbour, a refinement). The returned solution is the
task's; its ``stats`` add ``coarse_intervals``, ``coarse_iterations`` and ``coarse_status``, and
its times include both solves.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .solution import node_arrays

__all__ = ["RATIO", "MIN_INTERVALS", "WARM_IPOPT", "coarse_intervals", "resampled", "interpolated",
           "combined"]

#: the coarse grid has ⌊N / RATIO⌋ intervals ...
RATIO = 3
#: ... and at least this many (the 4-link snake's first guess met a singular configuration on 12)
MIN_INTERVALS = 15
#: Ipopt settings of warm-started solves (a sweep point from its neighbour, a refinement from the
#: converged point, the task's grid from the coarse grid's answer): a small initial barrier
#: parameter (the start is near the optimum: a large μ would first pull it back to the central
#: path, and a refinement once wandered from J = 40.8 to a local optimum at 57.4) and the start
#: kept close to its active bounds (Ipopt would push it 1e-2 inside). On the benchmark's P2 grid
#: (15 points) a warm point takes 7 iterations with Ipopt's defaults, 5.1 with μ₀ = 1e-4 and
#: bounds pushed 1e-6, 4.6 with these, against 8.5 from the planner's guesses; the 4-link snake
#: from its coarse answer 13 against 20 with the defaults.
WARM_IPOPT = {"mu_init": 1e-6, "bound_push": 1e-8, "bound_frac": 1e-8}


def coarse_intervals(problem, solver: str) -> int | None:
    """N_c for ``problem`` solved by ``solver`` (module docstring), or None: no coarse grid."""
    n = int(problem.intervals) // RATIO
    if solver != "ipopt" or n < MIN_INTERVALS or problem.phases or problem.waypoints:
        return None
    return n


def resampled(guess, source, target):
    """``guess`` (an InitialGuess) on the grid of ``source`` (an OptimalControlProblem) on the
    grid of ``target``: states interpolated linearly, inputs piecewise constant (each target
    interval takes the input of the source interval holding its midpoint)."""
    T = guess.horizon
    ts, tt = source.grid(T), target.grid(T)
    states, controls = node_arrays(guess)
    Z = np.vstack([np.interp(tt, ts, row) for row in states])
    mids = (tt[:-1] + tt[1:]) / 2
    k = np.clip(np.searchsorted(ts, mids, side="right") - 1, 0, ts.size - 2)
    U = controls[:, k]
    return replace(guess, states=Z, controls=U)


def interpolated(solution, source, target, guess):
    """A converged coarse ``solution`` of ``source`` as an InitialGuess of ``target`` (``guess``,
    the attempt's own, gives its type and label)."""
    coarse = replace(guess, states=np.asarray(solution.z, float).T,
                     controls=np.asarray(solution.u, float).T,
                     horizon=float(solution.horizon) if source.free_horizon else None)
    return resampled(coarse, source, target)


def combined(fine, coarse, intervals: int):
    """The task's solution ``fine`` with the coarse solve's iterations, status and seconds."""
    stats = {**fine.stats, "coarse_intervals": intervals, "coarse_iterations": coarse.iterations,
             "coarse_status": coarse.status}
    return replace(fine, stats=stats, solve_time_s=fine.solve_time_s + coarse.solve_time_s,
                   function_time_s=fine.function_time_s + coarse.function_time_s,
                   solver_time_s=fine.solver_time_s + coarse.solver_time_s)
