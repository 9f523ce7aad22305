"""A gait checked on the robot's own equations: the planner's solution (in its velocity
coordinates) moved to the momentum coordinates of a chart regular along it, or to x = (q, q̇) on
the Euler–Lagrange equations, and re-simulated there by an independent integrator.

* :func:`verified_gait` — the check the planner and the sweeps run on every converged gait;
* :func:`to_momentum_coordinates`, :func:`momentum_problem` — a solution on another chart of
  the derived model (z = (q, P); P = XᵀM(q)q̇);
* :func:`screening_report`, :func:`unsolved` — what the screening of the guesses repaired or
  skipped, and the answer of a search that solved nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..tasks.statement import quantity_objects
from .checks import check_lines, checks_of, gait_checks

__all__ = ["verified_gait", "GaitReference", "passed", "decided", "to_momentum_coordinates",
           "momentum_problem", "screening_report", "unsolved"]


def screening_report(guesses, search, problem) -> tuple:
    """(search, report): what the screening of ``guesses`` repaired or skipped and where the
    solution (or, when no guess converged, the closest point) met the singular set
    (:class:`~nhgait.gaits.planning.guesses.Screened`); a search in which every candidate was skipped
    (none left in ``guesses``) gets a closest point that says so (:func:`unsolved`)."""
    from ..planning.guesses import Screened
    report = tuple(getattr(guesses, "screened", ()))
    if search.solution is None and search.closest is None and not len(guesses):
        search = replace(search, closest=unsolved(problem, getattr(guesses, "first_skipped", None)))
    check = getattr(guesses, "check", None)
    point = search.solution if search.solution is not None else (search.closest if search.attempts else None)
    verdict = check(point) if check is not None and point is not None else None
    if verdict is not None and not verdict.ok:
        which = "solution" if search.solution is not None else "closest point"
        report += (Screened(f"{which} ({search.won or point.settings.get('guess', '?')})",
                            "reached", verdict),)
    return search, report


def unsolved(problem, guess=None):
    """A failed :class:`~nhgait.ocp.Solution` for a search that solved nothing (every candidate
    skipped by its screening): status ``Not_Solved``, the states of ``guess`` (zeros without one)."""
    from nhgait.ocp import Solution
    from nhgait.ocp.solution import node_arrays
    t = problem.grid()
    states = (node_arrays(guess).states if guess is not None
              else np.zeros((len(problem.state_names), t.size)))
    return Solution(success=False, status="Not_Solved",
                    message="every candidate met the singular set of the equations and was skipped",
                    iterations=0, objective=float("nan"), t=t, z=states.T,
                    u=np.zeros((problem.intervals, problem.n_controls)),
                    state_names=tuple(problem.state_names), control_names=tuple(problem.control_names),
                    horizon=float(problem.horizon), solve_time_s=0.0, setup_time_s=0.0,
                    function_time_s=0.0, solver_time_s=0.0, problem=problem,
                    settings={"guess": getattr(guess, "label", "none"), "intervals": problem.intervals,
                              "transcription": "none", "solver": "none (no candidate solved)"})


@dataclass(frozen=True, eq=False)
class GaitReference:
    """What a gait is verified against: ``model`` the derived model (momentum coordinates, its
    parameters symbolic), ``stated`` the problem as the task states it (before its conditions
    were normalised), ``plan`` the scene and task (:class:`~nhgait.gaits.tasks.sources.Plan`)
    and ``params`` the parameter values (None: the scene's)."""

    model: Any
    stated: Any
    plan: Any
    params: Any = None

    def problem_on(self, model):
        """The stated problem on ``model`` (a chart of the derived model, or the Euler–Lagrange
        ODE) with this reference's parameter values: :func:`momentum_problem`."""
        return momentum_problem(model, self.stated, self.plan, self.params)


def verified_gait(solution, reference: GaitReference, *, verify=True, progress=None):
    """``solution`` (velocity coordinates) in the momentum coordinates of a chart of
    ``reference.model`` regular along it (:func:`~nhgait.gaits.planning.charts.verification_chart`;
    a failed solution in the model's own) and, with ``verify``, verified there to the task's
    tolerance; in x = (q, q̇) on the Euler–Lagrange equations
    (:func:`~nhgait.gaits.planning.charts.lagrange_ode`) when no chart is regular along the gait,
    when the re-simulation in the chart stops (its singular set met between the nodes), when the
    solution's states in the chart are not finite (a failed one too: its trajectory is written
    out), and when the gait fails there before another chart is tried (:func:`_lagrange_first`)."""
    from nhgait.dynamics.progress import Progress

    from ..planning.charts import lagrange_ode, verification_chart
    progress = progress or Progress.silent()
    to_plan, default = reference.plan, reference.model
    n = len(default.system.coordinates)
    model, regular = default, False
    if verify and solution.success:
        model, regular = verification_chart(to_plan.scene.system, default, solution.z[:, :n].T,
                                            reference.params, progress)
        if not regular:
            model = lagrange_ode(to_plan.scene.system)
    def in_lagrange():
        return to_momentum_coordinates(solution, reference.problem_on(lagrange_ode(to_plan.scene.system)))
    moved = to_momentum_coordinates(solution, reference.problem_on(model))
    if not np.all(np.isfinite(moved.z)) and np.all(np.isfinite(solution.z)):
        # a chart singular at some node (where the momenta are not defined): (q, q̇) instead
        moved, regular = in_lagrange(), False
    if not verify:
        return moved
    if regular and model is not default:
        screened = _lagrange_first(in_lagrange(), to_plan, progress)
        if screened is not None:
            return screened
    checked = _verified_once(moved, to_plan, progress)
    if regular and not checked.verification.success:
        progress.note("  the re-simulation stopped in the chart (its singular set between the nodes): "
                      "verifying on the Euler–Lagrange equations (index-1 form, x = (q, q̇)), "
                      "which have none")
        checked = _verified_once(in_lagrange(), to_plan, progress)
    return checked


def _lagrange_first(solution, to_plan, progress):
    """A gait that met the singular set of the planner's chart, re-simulated on the
    Euler–Lagrange equations first: None when it passes there (it is then verified in the
    regular chart found, whose momenta the figures show), else that failed verification — a
    chart near its own singular set can take minutes to re-simulate a trajectory that is not a
    solution (a 5-link chain: 0.3 s on these equations, over 10 minutes in the chart)."""
    checked = _verified_once(solution, to_plan, progress)
    return None if passed(checked) else checked


def passed(solution) -> bool:
    """Whether ``solution``'s deciding verification passed: the open loop for a stable gait, the
    interval and closed-loop checks for an unstable one (:mod:`.verification_checks`)."""
    checks = checks_of(solution)
    if checks is not None:
        return checks.passed
    v = getattr(solution, "verification", None)
    return v is not None and bool(v.passed)


def _verified_once(solution, to_plan, progress):
    """``solution`` verified by the three checks of :mod:`.verification_checks`; success as
    the deciding checks say (an unstable gait whose open loop misses can pass)."""
    tolerance = to_plan.task.verify_tolerance
    with progress.phase("verify: re-simulate the optimal inputs on the general model (DOP853, rtol 1e-10)"):
        opened = solution.verified(tolerance=tolerance)
    v = opened.verification
    progress.note(f"  open loop {'passed' if v.passed else 'FAILED'}: nodes met to {v.max_error:.2e}, "
                  f"conditions to {v.max_condition_error:.2e}; relative to each state's range "
                  f"{v.max_scaled_error:.2e} and "
                  f"{v.max_scaled_condition_error:.2e} (tolerance {v.tolerance:g})"
                  + ("" if v.success else "; the re-simulation stopped early"))
    if not solution.success:
        return opened
    with progress.phase("verify: each interval from its own node, and the whole gait with the plan's "
                        "time-varying LQR (DOP853, rtol 1e-10)"):
        checks = gait_checks(opened, tolerance, steps=int(solution.settings.get("rk4_steps", 4)))
    for line in check_lines(checks):
        progress.note(f"  {line}")
    return decided(solution, opened, checks)


def decided(solution, opened, checks):
    """``opened`` (the open-loop verified copy of the converged ``solution``) carrying ``checks``
    in ``settings["checks"]``, its success as the deciding checks say."""
    settings = {**opened.settings, "checks": checks.to_dict()}
    if checks.stable or checks.open_loop_passed:
        return replace(opened, settings=settings)
    if checks.passed:
        return replace(opened, success=True, status=solution.status, settings=settings,
                       message=f"{solution.message} (verified by the interval and closed-loop checks; the "
                               f"open loop, unstable, misses by {checks.open_loop_error:.3g})")
    return replace(opened, success=False, status="Verification_Failed", settings=settings,
                   message=f"{solution.status}, but the verification failed: " + "; ".join(checks.failures()))


def momentum_problem(model, problem, to_plan, params):
    """The same statement on the derived (momentum-coordinate, unspecialised) model."""
    return problem.replace(model=model, quantities=quantity_objects(model, to_plan.scene), params=params)


def to_momentum_coordinates(solution, momentum):
    """A solution re-expressed on the problem ``momentum`` (z = (q, P), a chart of the derived model).

    The statement is the same (tasks are coordinate-free); only the states change: q̇ from the
    solution's model (``qdot``; regular along the gait in the planner's velocity coordinates),
    then P = XᵀM(q)q̇ of the momentum model's chart (its ``state`` map), so the result does not
    go through the chart of the model the solution was stated on. Any verification is dropped:
    verify the returned solution in momentum coordinates.
    """
    model = solution.problem.model
    same_chart = tuple(model.fiber) == tuple(getattr(momentum.model, "fiber", ()))
    if "momentum_state" not in model.numeric.functions and same_chart:
        return replace(solution, problem=momentum, verification=None)
    n, nz = len(model.system.coordinates), len(model.state_names)    # integral states follow z, unchanged
    state = momentum.model.numeric["state"]
    K = solution.z.shape[0]
    with np.errstate(all="ignore"):
        states = np.asarray(state.map(K)(solution.z[:, :n].T, solution.velocities(),
                                         momentum.model.numeric.params(momentum.params)))
    states = np.vstack([states, solution.z[:, nz:].T])
    settings = {**solution.settings, "transcribed_in": list(solution.state_names)}
    return replace(solution, z=states.T, state_names=momentum.state_names,
                   problem=momentum, verification=None, settings=settings)
