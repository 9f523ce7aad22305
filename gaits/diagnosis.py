"""Why a plan failed, and what to change: the lines ``nhgait plan`` prints after FAILED.

Three kinds of failure (:func:`diagnose`):

* **the time budget ran out** — the budget, where it came from, the phase it ran out in and
  what to change (``--time-limit``), then what the attempts so far gave (as below);
* **no guess converged** — the attempts by outcome (the solvers' own status names); at the
  closest point found (smallest constraint violation) the conditions it violates by how much
  (the NLP's rows are labelled: "dynamics", "final.x", "periodic.psi", "bounds.phi"), how often
  the inputs sit at their bounds, and what to relax;
* **converged but not verified** — the independent re-simulation misses the planned states or
  the task's conditions by more than the task's ``verify_tolerance``: the misses, and the likely
  cause (bang-bang inputs at their bounds whose switching the intervals do not resolve, or RK4
  steps too coarse for the tolerance).
"""
from __future__ import annotations

from collections import Counter

__all__ = ["diagnose", "SATURATED"]

#: inputs at a bound on more than this fraction of the intervals count as saturated
SATURATED = 0.3


def _saturation_line(solution) -> tuple:
    """(text or None, saturated?) about inputs sitting at their bounds."""
    sat = solution.saturation()
    if not sat:
        return None, False
    mean = sum(sat.values()) / len(sat)
    if mean <= 0.05:
        return None, False
    parts = ", ".join(f"{k} {100 * v:.0f} %" for k, v in sat.items())
    return f"inputs at their bounds on {100 * mean:.0f} % of the intervals ({parts})", mean > SATURATED


def _not_converged(result) -> list:
    counts = Counter(a.status for a in result.attempts)
    lines = [f"no guess converged: {len(result.attempts)} attempts ("
             + ", ".join(f"{n} {status}" for status, n in counts.most_common()) + ")"]
    s = result.solution
    if s is None or not s.violations:
        return lines + ["  the solver stopped before reporting a point (see the attempts in solution.json)"]
    lines.append(f"at the closest point found (guess {s.settings.get('guess', '?')!r}, {s.settings.get('solver', '?')}, "
                 f"{s.status}, constraint violation {s.constraint_violation:.2g}):")
    for label, v in sorted(s.violations.items(), key=lambda kv: -kv[1])[:8]:
        what = "the trajectory does not follow the model (shooting gaps)" if label == "dynamics" else label
        lines.append(f"  {what}: violated by {v:.3g}")
    sat, saturated = _saturation_line(s)
    if sat:
        lines.append(f"  {sat}")
    return lines + ["what to relax:"] + [f"  {x}" for x in _relax(result, s, saturated)]


def _relax(result, s, saturated) -> list:
    task = result.task
    named = [k for k in s.violations if k != "dynamics"]
    out = []
    if saturated:
        out.append("widen control_bounds (the inputs saturate) or lengthen the horizon "
                   f"(now T = {task.horizon:g} s)")
    ends = [k for k in named if k.startswith(("initial.", "final.", "periodic."))]
    if ends:
        out.append("the end conditions " + ", ".join(ends) + " (make them ranges, or move them)")
    paths = [k for k in named if k.startswith("bounds.")]
    if paths:
        out.append("the path bounds " + ", ".join(p[len("bounds."):] for p in paths))
    if "dynamics" in s.violations and not out:
        out.append(f"the task may be out of reach in T = {task.horizon:g} s: lengthen the horizon, shorten "
                   "the distance or widen control_bounds")
    if all(a.status == "Maximum_Iterations_Exceeded" for a in result.attempts):
        out.append("every attempt hit the iteration limit: raise max_iter")
    timed_out = [a for a in result.attempts if a.status == "Time_Limit_Exceeded"]
    if timed_out:
        solvers = sorted({a.solver for a in timed_out if a.solver})
        out.append(f"{len(timed_out)} attempt(s) were stopped at their time limit ({', '.join(solvers) or 'the solver'} "
                   "did not finish: slow, or looping); the other solver (--solver) or a warm start may do better")
    return out or ["check the task's values against the robot's reach"]


def _not_verified(result) -> list:
    s, v = result.solution, result.solution.verification
    lines = [f"the solver converged ({s.stats.get('solver_status', 'Solve_Succeeded')}, J = {s.objective:.6g}) "
             f"but the independent re-simulation (DOP853, rtol {v.rtol:g}) does not meet the task to "
             f"{v.tolerance:g}:"]
    lines += [f"  {x}" for x in v.failures()[:8]]
    sat, saturated = _saturation_line(s)
    N = result.task.intervals
    if saturated:
        lines.append(f"likely cause: bang-bang inputs — {sat}; a switch inside an interval is not resolved by "
                     f"piecewise-constant inputs: increase intervals (now {N}, e.g. --set intervals={2 * N})")
    else:
        lines.append(f"likely cause: the transcription's integration steps are too coarse for {v.tolerance:g}: "
                     f"increase intervals (now {N}, e.g. --set intervals={2 * N}), or set verify_tolerance to "
                     "the accuracy you need")
    return lines


def _out_of_time(result) -> list:
    """The budget that ran out (where, what to change), then what the attempts gave."""
    lines = list(result.overrun.lines())
    if result.attempts:
        lines += _not_converged(result)
    return lines


def diagnose(result) -> tuple:
    """The failure report of a :class:`~nhgait.gaits.planner.PlanResult` (empty on success)."""
    if result.success:
        return ()
    if getattr(result, "overrun", None) is not None:
        return tuple(_out_of_time(result))
    s = result.solution
    if s is not None and s.verification is not None and s.status == "Verification_Failed":
        return tuple(_not_verified(result))
    return tuple(_not_converged(result))
