"""The robust (scenario) stage of :func:`~nhgait.gaits.planner.plan`, for a task with ``[task.robust]``.

After the nominal plan has converged, the scenario problem (:mod:`nhgait.ocp.scenarios`) is
stated on the same problem and solved by Ipopt from the nominal plan (every copy started by
rolling the nominal inputs out under its parameters), in a supervised attempt within the plan's
budget. Its copies are the parameter vectors of :meth:`~.task_robust.RobustTask.factors`, their
ODE the planner's own in its velocity coordinates with θ as an argument
(:func:`nhgait.dynamics.numerics.parametric.parametric_rhs`), the terminal scales ε s_i
(ε = :data:`END_FRACTION`, s_i :func:`nhgait.ocp.feedback.state_scales` of the nominal plan) and
the weight W = ``weight`` × the nominal plan's objective. The robust plan is a plan of the
nominal problem (verified, fed back and written as any plan); ``settings["robust"]`` records the
copies and each copy's terminal deviation under the nominal and the robust inputs.
"""
from __future__ import annotations

import numpy as np

__all__ = ["robust_search", "scenarios_for", "summary_line", "END_FRACTION"]

#: ε: the terminal deviations are measured in units of ε s_i (the feedback's end fraction)
END_FRACTION = 0.02


def default_terminal(problem, system) -> tuple[str, ...]:
    """The states the task's ``final`` names, then the planar frame's position (x, y)."""
    states = problem.model_state_names
    frame = tuple(getattr(system, "planar_frame", None) or ())[:2]
    names = [n for n in problem.final if n in states] + [n for n in frame if n in states]
    return tuple(dict.fromkeys(names))


def scenarios_for(spec, prepared, nominal, quantities):
    """The :class:`~nhgait.ocp.scenarios.Scenarios` of ``spec`` (a RobustTask) around the
    converged ``nominal`` solution of ``prepared.problem``."""
    from nhgait.dynamics.numerics.parametric import parametric_rhs
    from nhgait.ocp import ProblemError
    from nhgait.ocp.feedback import state_scales
    from nhgait.ocp.scenarios import Scenarios
    problem, specialised = prepared.problem, prepared.specialised
    names = list(specialised.numeric.param_names)
    theta0 = np.asarray(problem.params, dtype=float)
    copies = spec.factors()
    params = np.array([[theta0[i] * c.get(n, 1.0) for i, n in enumerate(names)] for c in copies])
    varied = [names.index(n) for n in spec.parameters]
    terminal = spec.terminal or default_terminal(problem, specialised.system)
    problems = [f"[task].robust.terminal: {n!r} is not a state of the plan "
                f"({', '.join(problem.model_state_names)})"
                for n in terminal if n not in problem.model_state_names]
    if problems:
        raise ProblemError(problems, title="invalid robust planning")
    scale = state_scales(problem, nominal.z.T)[[problem.model_state_names.index(n) for n in terminal]]
    labels = tuple(", ".join(f"{n} ×{c[n]:.4g}" for n in spec.parameters) for c in copies)
    weight = spec.weight * max(float(nominal.objective), 1e-12)
    ode = parametric_rhs(specialised, quantities, varied=varied)
    return Scenarios(ode=ode, params=params, terminal=terminal, scales=END_FRACTION * scale, weight=weight,
                     aggregate=spec.aggregate, labels=labels)


def robust_search(search, prepared, to_plan, settings, budget, progress):
    """The :class:`~.search.Search` of the scenario problem from the nominal ``search``'s
    solution (a failure when it does not converge), its record in ``settings["robust"]``."""
    from dataclasses import replace

    from nhgait.ocp import OCPSolver, SolverOptions
    from nhgait.ocp.scenarios import ScenarioShooting
    from nhgait.ocp.solver import InitialGuess

    from .search import Attempt, Search, solve_attempts
    from .time_limits import attempt_limited
    nominal, spec = search.solution, to_plan.task.robust
    sc = scenarios_for(spec, prepared, nominal, to_plan.scene.quantities)
    method = ScenarioShooting(scenarios=sc)
    with budget.stage("the robust NLP set-up"):
        with progress.phase(f"robust: the scenario NLP of {sc.count} copies ({', '.join(spec.parameters)}) "
                            f"with Ipopt, {sc.aggregate} terminal deviation"):
            ocp = OCPSolver(prepared.problem, method, SolverOptions(jit=settings.jit, solver="ipopt",
                                                                    max_iter=settings.max_iter,
                                                                    hessian=settings.hessian),
                            progress=progress)
            ocp = attempt_limited(ocp, None, progress)
    guess = InitialGuess(nominal.z.T, nominal.u.T, nominal.horizon, "the nominal plan")
    with budget.stage("the robust solve", interrupt=False):
        with progress.phase("robust: solve from the nominal plan"):
            solution = solve_attempts(ocp, [guess], budget=budget, progress=progress)[0]
    record = robust_record(sc, ocp, nominal, solution, spec)
    progress.note(f"  robust: {solution.status} after {solution.iterations} iterations; terminal deviation "
                  f"(mean over copies, in units of {END_FRACTION:g} s_i) "
                  f"{record['nominal_plan']['mean']:.3g} → {record['robust_plan']['mean']:.3g}")
    solution = replace(solution, settings={**solution.settings, "robust": record})
    attempt = Attempt(label="robust: from the nominal plan", status=solution.status,
                      success=bool(solution.success), iterations=int(solution.iterations),
                      objective=float(solution.objective), solver="ipopt",
                      constraint_violation=float(solution.constraint_violation),
                      seconds=float(solution.solve_time_s))
    return Search(solution if solution.success else None, search.attempts + (attempt,),
                  "robust: from the nominal plan" if solution.success else None,
                  None if solution.success else solution)


def robust_record(sc, ocp, nominal, solution, spec) -> dict:
    """What solution.json says of a robust plan: the copies and each one's terminal deviation
    e_s (:func:`~nhgait.ocp.scenarios.terminal_deviations`) under the nominal and the robust inputs."""
    robust_plan = _deviations(sc, ocp, solution)
    term = sc.weight * robust_plan[sc.aggregate]
    return {"robust": True, **spec.to_dict(), **sc.describe(), "end_fraction": END_FRACTION,
            "nominal_objective": float(nominal.objective), "task_objective": float(solution.objective) - term,
            "robust_term": term, "nominal_plan": _deviations(sc, ocp, nominal), "robust_plan": robust_plan,
            "rule": "objective J + W·A_s Σ_i ((y_i(c_N^s) − y_i(z_N)) / σ_i)², σ_i = end_fraction·s_i, "
                    "W = weight × the nominal plan's objective"}


def _deviations(sc, ocp, solution) -> dict:
    """e_s of each copy under ``solution``'s inputs (the copies rolled out from its z_0)."""
    from nhgait.ocp.scenarios import copy_states, terminal_deviations
    w = ocp.nlp.pack(solution.z.T, solution.u.T, solution.horizon)
    copies = copy_states(ocp.nlp, sc, w)
    e = terminal_deviations(sc, ocp.problem, solution.z[-1], copies[:, :, -1].T)
    return {"deviations": [float(v) for v in e], "mean": float(np.mean(e)), "worst": float(np.max(e))}


def summary_line(record: dict) -> str:
    """The robust plan's line in ``nhgait plan``'s summary, from its ``settings["robust"]``."""
    key = record["aggregate"]
    return (f"{record['copies']} copies ({', '.join(record['parameters'])}); {key} terminal deviation "
            f"{record['nominal_plan'][key]:.3g} → {record['robust_plan'][key]:.3g} (units of "
            f"({record['end_fraction']:g} s_i)²); the task's objective {record['nominal_objective']:.6g} → "
            f"{record['task_objective']:.6g}")
