"""Accuracy refinement: a converged gait that the re-simulation misses, solved again with more
RK4 sub-steps per interval.

Multiple shooting integrates each of the N intervals with M explicit RK4 sub-steps (default
4, :class:`~nhgait.ocp.transcription.MultipleShooting`): a local error O(h⁵) per sub-step,
h = T/(N M), and a drift O(h⁴) of the nodes from the exact flow over the horizon. For robots
with fast shape motion (a steering wheel, a short trailer, a light link) N = 40 with M = 4
resolves the dynamics only to 1e-6 … 1e-3: the solver converges, and the independent
re-simulation (DOP853, rtol 1e-10) misses the nodes by more than the task's
``verify_tolerance``. The optimum can even use the integration error (an input that switches
faster than the sub-steps resolve).

:func:`refinable` says whether a verified failure is of that kind — the re-simulation ran
through and misses the planned nodes (finite errors); for a gait unstable for verification
(:mod:`.verification_checks`: its open loop amplifies errors by more than 10³ over the horizon)
only a failed interval or closed-loop check is refined, sized on its miss (:func:`miss`): no
number of sub-steps brings an unstable open loop to the tolerance, and no budget is spent trying;
:func:`refined_steps` chooses M' from the miss e and the tolerance τ with the h⁴ law and a
margin of :data:`MARGIN`::

    M' = M ⌈(MARGIN e / τ)^{1/4}⌉,   clipped to [2M, MAX_STEPS]

The problem is the same (the task's N, the same piecewise-constant inputs): only the
integration inside each interval is finer, so the objective stays comparable with any other
transcription of the task at that N. :func:`refine` solves it from the converged point (the
planner's solver — Ipopt with the warm-start settings :data:`~nhgait.gaits.planning.search.WARM_IPOPT` —
in a supervised attempt within the plan's budget) and verifies again, at most
:data:`REFINEMENTS` times. Few iterations are needed from there, so its NLP is interpreted
unless that is expected to take longer than compiling it at -O0 (:data:`COMPILE_ABOVE_S`).
"""
from __future__ import annotations

import math
from dataclasses import replace

__all__ = ["refinable", "miss", "refined_steps", "refine", "MARGIN", "MAX_STEPS", "REFINEMENTS"]

#: the refined transcription aims at this fraction of the verification tolerance (the next
#: optimum is not the point whose miss was measured)
MARGIN = 10.0
#: RK4 sub-steps per interval at most (32× the default: 32⁴ ≈ 10⁶× more accurate; a car with
#: three trailers steering at 26 rad/s missed by 1.1 at 4 sub-steps, 1.7e-4 at 32)
MAX_STEPS = 128
#: times a plan refines at most
REFINEMENTS = 2
#: iterations a refinement from the converged point is expected to take (measured 5–33 on the
#: generated robots) ...
EXPECTED_ITERATIONS = 30
#: ... and the expected seconds of an interpreted refinement above which its NLP is compiled
#: at -O0 (1.5–5 s per MB of C, CompileBudget) instead: interpreted, one evaluation took 25 ms
#: for a car (inline stage, 32 sub-steps) and 2.1–2.6 s for 5–6-link chains (structured stage)
COMPILE_ABOVE_S = 10.0


def refinable(solution) -> bool:
    """Whether ``solution`` converged and failed its verification by missing its own nodes —
    what the RK4 transcription's error does — with a re-simulation that ran through and finite
    errors. (Nodes met and a condition missed is another failure: one the normalisation dropped
    as implied, which more sub-steps do not bring back.)"""
    from .checks import checks_of
    v = getattr(solution, "verification", None)
    if v is None or solution.status != "Verification_Failed":
        return False
    checks = checks_of(solution)
    if checks is not None and not checks.stable:       # unstable: the interval and closed-loop checks
        # the defects can add up to N e_int along the closed loop: below a tenth of the tolerance
        # they are not what the closed loop misses by, and more sub-steps would not help
        defects = checks.interval_error * getattr(getattr(solution, "problem", None), "intervals", 1)
        return bool(checks.closed_loop_ran and math.isfinite(miss(solution)) and not checks.passed
                    and defects > 0.1 * checks.tolerance)
    if not v.success:
        return False
    return math.isfinite(v.max_error) and math.isfinite(v.max_condition_error) and v.max_error > v.tolerance


def miss(verified) -> float:
    """The miss a refinement is sized on: for an unstable gait the larger of the interval and
    closed-loop checks' (both made of the transcription's defects, the second carried by the
    stable closed loop; the open loop's cannot shrink below e^{λT} × the integrator's error),
    else the open loop's."""
    from .checks import checks_of
    v, checks = verified.verification, checks_of(verified)
    if checks is not None and not checks.stable:
        return max(checks.interval_error, checks.closed_loop_error,
                   *checks.closed_loop_conditions.values())
    return max(v.max_error, v.max_condition_error)


def _which(verified) -> str:
    from .checks import checks_of
    checks = checks_of(verified)
    return ("interval or closed-loop check" if checks is not None and not checks.stable
            else "re-simulation")


def refined_steps(steps: int, miss: float, tolerance: float) -> int:
    """M' of the module docstring for a miss ``miss`` at ``steps`` sub-steps."""
    factor = math.ceil((MARGIN * max(miss, tolerance) / tolerance) ** 0.25)
    return int(min(MAX_STEPS, max(2 * steps, steps * factor)))


def _transcription(settings: dict, steps: int):
    from nhgait.ocp.transcription import MultipleShooting, StageShooting
    name = settings.get("transcription", "multiple-shooting")
    if name == StageShooting.name:
        return StageShooting(steps=steps)
    if name == MultipleShooting.name:
        return MultipleShooting(steps=steps)
    return None                      # collocation: not refined by sub-steps


def _solver(problem, transcription, name, search_settings, progress):
    """The refinement's solver (module docstring): interpreted when its expected cost is below
    :data:`COMPILE_ABOVE_S`, else compiled at -O0 (unless the plan does not compile at all)."""
    from nhgait.ocp import OCPSolver, SolverOptions
    from nhgait.ocp.budget import EVALUATIONS_PER_ITERATION

    from ..planning.search import WARM_IPOPT
    from ..planning.time_limits import attempt_limited
    s = search_settings
    options = SolverOptions(jit=False, solver=name, max_iter=s.max_iter, hessian=s.hessian,
                            ipopt=dict(WARM_IPOPT) if name == "ipopt" else {})
    ocp = OCPSolver(problem, transcription, options)
    expected = ocp.evaluation_seconds() * EVALUATIONS_PER_ITERATION * EXPECTED_ITERATIONS
    if s.jit is not False and expected > COMPILE_ABOVE_S:
        ocp = OCPSolver(problem, transcription, replace(options, jit=True, jit_flags=("-O0",)),
                        progress=progress)
    return attempt_limited(ocp, None, progress)


def refine(solution, verified, search_settings, budget, progress, verify):
    """(solution, verified solution, attempts): ``solution`` (velocity coordinates, converged)
    solved again with more sub-steps while ``verified`` (its verified form) is
    :func:`refinable`, each result verified by ``verify(solution)``; the attempts made. Returns
    the inputs unchanged when nothing was refined or no refined solve converged."""
    from nhgait.ocp import InitialGuess

    from ..planning.search import attempt_of, solve_attempts
    attempts = []
    for _ in range(REFINEMENTS):
        v, settings = verified.verification, solution.settings
        steps = int(settings.get("rk4_steps", 4))
        transcription = _transcription(settings, refined_steps(steps, miss(verified), v.tolerance))
        if transcription is None or transcription.steps <= steps or budget.spent():
            break
        name = settings.get("solver", "ipopt")
        progress.note(f"  the {_which(verified)} misses by {miss(verified):.2g} "
                      f"with {steps} "
                      f"RK4 sub-steps per interval: solving again with {transcription.steps}, "
                      "from this point")
        with budget.stage(f"the refinement's NLP set-up ({transcription.steps} RK4 sub-steps)"):
            ocp = _solver(solution.problem, transcription, name, search_settings, progress)
        guess = InitialGuess(solution.z.T, solution.u.T, horizon=float(solution.horizon),
                             label=f"{settings.get('guess', 'solution')}, refined to "
                                   f"{transcription.steps} sub-steps")
        with budget.stage("the refinement's solve", interrupt=False):
            again, = solve_attempts(ocp, [guess], budget=budget, progress=progress)
        again = replace(again, settings={**again.settings, "guess": guess.label})
        attempts.append(attempt_of(guess.label, again, name))
        progress.note(f"  refined: {again.status} after {again.iterations} iterations"
                      + (f", J = {again.objective:.6g}" if again.success else ""))
        if not again.success:
            break
        solution, verified = again, verify(again)
        if not refinable(verified):
            break
    return solution, verified, tuple(attempts)
