"""Why a plan failed, and what to change: the lines ``nhgait plan`` prints after FAILED.

Three kinds of failure (:func:`diagnose`):

* **the time budget ran out** — the budget, where it came from, the phase it ran out in and
  what to change (``--time-limit``), then what the attempts so far gave: a converged one (kept,
  not verified), else as below;
* **no guess converged** — the attempts by outcome (the solvers' own status names); at the
  closest point found (smallest constraint violation) the conditions it violates by how much
  (the NLP's rows are labelled: "dynamics", "final.x", "periodic.psi", "bounds.phi"), how often
  the inputs sit at their bounds, and what to change: the minimum-violation (elastic) solve's
  answer — each stated condition the nearest gait moves, by how much, "possibly infeasible"
  where no gait was found (:mod:`.infeasibility`) — else what to relax (never the start the
  user gave when another condition is violated);
* **singular postures** (with either of the above) — where the guesses or the closest point met the
  singular set of the planner's equations (:mod:`.screening`: the velocity states stop
  determining the motion, or the reduction's chart divides by zero): each posture in the
  user's coordinate names, what the screening did (repaired, skipped), and what to change —
  bounds that keep the shape off those postures, a fixed initial shape (where the guesses
  started), velocity states regular over the task's bounds (when the task names its own),
  another chart (``fiber = [...]``);
* **converged but not verified** — the independent re-simulation misses the planned states or
  the task's conditions by more than the task's ``verify_tolerance``: the misses, and the likely
  cause (bang-bang inputs at their bounds whose switching the intervals do not resolve, or RK4
  steps too coarse for the tolerance); for an unstable gait (:mod:`.verification_checks`) the
  interval or closed-loop check that failed and what helps (more intervals, wider bounds —
  never more time).
"""
from __future__ import annotations

import math
from collections import Counter

from .loop_reach import reach_lines

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
    if not result.attempts:
        skipped = sum(1 for x in getattr(result, "screening", ()) if x.action == "skipped")
        return [f"no guess was solved: each of the {skipped} candidates met the singular set of "
                "the planner's equations, and no repair (phase, centre, amplitude) avoided it"]
    counts = Counter(a.status for a in result.attempts)
    lines = [f"no guess converged: {len(result.attempts)} attempts ("
             + ", ".join(f"{n} {status}" for status, n in counts.most_common()) + ")"]
    s = result.solution
    if s is not None and not s.violations and not math.isnan(s.constraint_violation):
        return lines + [f"at the closest point found (guess {s.settings.get('guess', '?')!r}, "
                        f"{s.settings.get('solver', '?')}, {s.status}) every condition holds (constraint "
                        f"violation {s.constraint_violation:.2g}) but it is not optimal: raise max_iter, or "
                        "use the exact Hessian (--hessian exact) if another was asked for"]
    if s is None or not s.violations:
        return lines + ["  the solver stopped before reporting a point (see the attempts in solution.json)"]
    lines.append(f"at the closest point found (guess {s.settings.get('guess', '?')!r}, "
                 f"{s.settings.get('solver', '?')}, "
                 f"{s.status}, constraint violation {s.constraint_violation:.2g}):")
    for label, v in sorted(s.violations.items(), key=lambda kv: -kv[1])[:8]:
        what = "the trajectory does not follow the model (shooting gaps)" if label == "dynamics" else label
        lines.append(f"  {what}: violated by {v:.3g}")
    sat, saturated = _saturation_line(s)
    if sat:
        lines.append(f"  {sat}")
    elastic = s.settings.get("elastic")
    if elastic is not None and elastic.get("converged"):        # the minimum-violation solve (issue 41)
        return lines + list(elastic["lines"])
    return (lines + list((elastic or {}).get("lines", [])) + ["what to relax:"]
            + [f"  {x}" for x in _relax(result, s, saturated)])


def _relax(result, s, saturated) -> list:
    task = result.task
    named = [k for k in s.violations if k != "dynamics"]
    out = []
    if saturated:
        out.append("widen control_bounds (the inputs saturate) or lengthen the horizon "
                   f"(now T = {task.horizon:g} s)")
    ends = [k for k in named if k.startswith(("final.", "periodic."))]
    if not ends and not out:          # the start the user gave is advice only when nothing else is violated
        ends = [k for k in named if k.startswith("initial.")]
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
        out.append(f"{len(timed_out)} attempt(s) were stopped at their time limit "
                   f"({', '.join(solvers) or 'the solver'} "
                   "did not finish: slow, or looping); the other solver (--solver) or a warm start "
                   "may do better")
    return out or ["check the task's values against the robot's reach"]


def _unstable_not_verified(result, checks) -> list:
    """A gait unstable for verification (:mod:`.verification_checks`) whose interval or
    closed-loop check fails: which, and what helps (never more time: the open loop cannot
    verify it at any budget)."""
    s, N = result.solution, result.task.intervals
    lines = [f"the solver converged (J = {s.objective:.6g}); the gait is unstable (largest growth rate "
             f"{checks.growth_rate:.3g} /s, the open loop amplifies errors by "
             f"e^{checks.amplification:.1f} over "
             f"T = {checks.horizon:g} s), so the interval and closed-loop checks decide, and:"]
    lines += [f"  {x}" for x in checks.failures()]
    if not checks.interval_passed:
        lines.append(f"what to change: more intervals (now {N}, e.g. --set intervals={2 * N}); more time "
                     "does not help")
    else:
        sat, _ = _saturation_line(s)
        lines.append("what to change: the plan's time-varying LQR does not hold the robot on the gait"
                     + (f" ({sat})" if sat else "") + ": widen control_bounds, or a gait that keeps "
                     "further from the bounds (a longer horizon)")
    return lines


def _not_verified(result) -> list:
    from .checks import checks_of
    s, v = result.solution, result.solution.verification
    checks = checks_of(s)
    if checks is not None and not checks.stable:
        return _unstable_not_verified(result, checks)
    lines = [f"the solver converged ({s.stats.get('solver_status', 'Solve_Succeeded')}, J = "
             f"{s.objective:.6g}) but the independent re-simulation (DOP853, rtol {v.rtol:g}) does not meet "
             f"the task to {v.tolerance:g}:"]
    lines += [f"  {x}" for x in v.failures()[:8]]
    sat, saturated = _saturation_line(s)
    N = result.task.intervals
    # nodes met, a condition not
    dropped = _dropped_and_missed(result, v) if v.max_error <= v.tolerance else []
    if dropped:
        lines.append(f"likely cause: {', '.join(dropped)} missed: the planner dropped "
                     f"{'them' if len(dropped) > 1 else 'it'} as implied by the task's other "
                     "conditions, which hold in general but not at this gait's end posture, where the solver "
                     "used the freedom (see 'conditions' above)")
        return lines
    crossed = next((x for x in getattr(result, "screening", ()) if x.action == "reached"), None)
    if crossed is not None:
        shape = tuple(getattr(result.model, "shape", ())) or None
        velocities = ", ".join(s.settings.get("velocities", ()))
        lines.append(f"likely cause: the gait passes through the singular set of the planner's equations at "
                     f"{crossed.check.posture(shape)} (t = {crossed.check.t:.2f} s), where the "
                     f"velocity states ({velocities}) do not determine the motion: the transcription "
                     "steps across it")
        return lines + ["what to change:"] + [f"  {x}" for x in _away_from_singular(result, [crossed], shape)]
    if saturated:
        lines.append(f"likely cause: bang-bang inputs — {sat}; a switch inside an interval is not "
                     f"resolved by piecewise-constant inputs: increase intervals (now {N}, e.g. --set "
                     f"intervals={2 * N})")
    else:
        steps = int(s.settings.get("rk4_steps", 4))
        tried = f" (even refined to {steps} RK4 sub-steps per interval)" if steps > 4 else ""
        lines.append("likely cause: the transcription's integration steps are too coarse for "
                     f"{v.tolerance:g}{tried}: "
                     f"increase intervals (now {N}, e.g. --set intervals={2 * N}), or set "
                     "verify_tolerance to the accuracy you need")
    return lines


def _out_of_time(result) -> list:
    """The budget that ran out (where, what to change), then what the attempts gave and the
    singular postures the guesses met."""
    lines = list(result.overrun.lines())
    converged = [a for a in result.attempts if a.success]
    if converged:
        best = min(converged, key=lambda a: a.objective)
        lines.append(f"a guess had converged ({best.label!r}, {best.status}, J = {best.objective:.6g}): "
                     "solution.json holds it, not verified")
    elif result.attempts:
        lines += _not_converged(result)
    return lines + _singular(result)


def _singular(result) -> list:
    """The singular postures met (module docstring); empty when none was."""
    met = [x for x in getattr(result, "screening", ()) if not x.check.ok]
    if not met:
        return []
    settings = result.solution.settings if result.solution is not None else {}
    velocities = tuple(settings.get("velocities", ()))
    route = str(settings.get("specialisation", ""))
    shape = tuple(getattr(result.model, "shape", ())) or None
    what = (f"the velocity states ({', '.join(velocities)}) do not determine the motion there"
            if velocities else "the reduction's chart is singular there")
    if velocities and "velocity basis" not in route:
        what += f", or the chart with fiber ({', '.join(result.model.fiber)}) is singular"
    lines = [f"the planner's equations are singular at postures the guesses met ({what}):"]
    groups: dict = {}
    for x in met:                  # the same posture met by several candidates: one line
        done = {"repaired": f"repaired: {x.repair}", "skipped": "skipped, not solved",
                "moved": f"every guess started at {x.repair} instead",
                "reached": "where the solver ended"}[x.action]
        key = (x.check.posture(shape), f"{x.check.t:.2f}", done if x.action != "repaired" else "repaired")
        groups.setdefault(key, []).append((x.label, done))
    for (posture, t, _), members in list(groups.items())[:6]:
        who = repr(members[0][0]) + (f" and {len(members) - 1} other candidates" if len(members) > 1 else "")
        lines.append(f"  {who}: {posture} at t = {t} s ({members[0][1]})")
    return lines + ["what to change:"] + [f"  {line}" for line in _away_from_singular(result, met, shape)]


def _away_from_singular(result, met, shape) -> list:
    task = result.task
    names = sorted({c for x in met for c, v in zip(x.check.coordinates, x.check.q, strict=True)
                    if shape is None or c in shape})
    now = ", ".join(f"{c} in [{task.bounds[c][0]:g}, {task.bounds[c][1]:g}]" for c in names
                    if isinstance(task.bounds.get(c), tuple))
    out = [f"bounds on {', '.join(names)} that keep the shape off these postures"
           + (f" (now {now})" if now else "")]
    start = next((x.repair for x in met if x.action == "moved"), None)
    free = [c for c in names if c not in task.initial]
    fixed = sorted({(c, v) for x in met if x.check.t == 0.0
                    for c, v in zip(x.check.coordinates, x.check.q, strict=True)
                    if c in names and c in task.initial})
    if fixed:
        out.append(f"the fixed initial shape ({', '.join(f'{c} = {v:.3g}' for c, v in fixed)}) lies on "
                   "the singular set: start elsewhere, or leave it free")
    if free:
        out.append(f"a fixed initial shape off them ([task].initial: {start})" if start else
                   f"a fixed initial shape off them ([task].initial.{free[0]} = ...)")
    better = _regular_velocities(result)
    if better:
        out.append(f"velocities = [{', '.join(repr(v) for v in better)}] in [task]: they "
                   "determine the motion everywhere within the task's bounds")
    route = str(result.solution.settings.get("specialisation", "")) if result.solution is not None else ""
    if "velocity basis" not in route:
        out.append("another chart: fiber = [...] in [system] (nhgait derive lists the choices and their "
                   "singular sets)")
    return out


def _regular_velocities(result) -> tuple:
    """Velocity states regular over the task's bounds when the task named others, else ()."""
    task, model = result.task, result.model
    if not getattr(task, "velocities", None) or model is None or not hasattr(model, "layout"):
        return ()
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.numerics.velocity_coordinates import choose_velocities
    bounds = {k: v for k, v in task.bounds.items() if isinstance(v, tuple)}
    try:
        scene = getattr(result.plan, "scene", None)
        chosen = choose_velocities(model, task.names, getattr(scene, "quantities", None),
                                   result.solution.problem.params, bounds)
    except ModelError:
        return ()
    return chosen if set(chosen) != set(task.velocities) else ()


def _dropped_and_missed(result, v) -> list:
    """The conditions the normalisation dropped as implied that the re-simulation misses."""
    report = getattr(result, "conditions", None)
    implied = {f"{where}.{name}" for where, name, reason in getattr(report, "dropped", ())
               if reason.startswith("implied")}
    return [name for name, err in v.condition_errors.items() if err > v.tolerance and name in implied]


def diagnose(result) -> tuple:
    """The failure report of a :class:`~nhgait.gaits.planner.PlanResult` (empty on success)."""
    if result.success:
        return ()
    if getattr(result, "overrun", None) is not None:
        return tuple(_out_of_time(result) + reach_lines(result))
    s = result.solution
    if s is not None and s.verification is not None and s.status == "Verification_Failed":
        return tuple(_not_verified(result))
    return tuple(_not_converged(result) + _singular(result) + reach_lines(result))
