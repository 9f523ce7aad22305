"""The gait planner: scene + task → derive → specialise → guesses → solve → verify → write.

:func:`plan` is the one entry point used by ``nhgait plan``; built-in gaits and a user's
scene file take the same path::

    result = plan("my_robot.toml")                         # the scene's [task]
    result = plan("snakeboard", "forward", overrides=["final.x=0.8"], out_dir="out/demo")
    result.solution.objective, result.solution.verification_error, result.guess, result.files

Steps
-----
1. :func:`~nhgait.gaits.tasks.resolve`: the scene and the parsed task (one ProblemError for
   every problem of the task's form).
2. ``derive(system, "reduced")`` (cached) and :func:`~nhgait.dynamics.specialisation.specialise`:
   parameter values bound, the state in velocity coordinates z = (q, y) with y the task's own
   velocity quantities when they parametrise the allowed velocities (else chosen by
   :func:`~nhgait.dynamics.specialisation.choose_velocities`). Conditions on velocities are
   then bounds or linear rows.
3. :func:`~nhgait.gaits.task.to_problem`: the :class:`~nhgait.ocp.OptimalControlProblem`
   (unknown names and impossible counts are one ProblemError).
4. :func:`solve_from_guesses`: the candidates of :mod:`.guesses` in batches of ``workers``
   (separate processes when ``workers > 1``); within the first batch with a success the lowest
   objective wins. When every direct candidate fails, :func:`continuation` solves easier
   versions (the fixed end values moved a fraction 1/4, 1/2, 3/4 of the way from their
   initial values) and grows them to the task, each warm-started from the last.
5. The solution is re-expressed in the momentum coordinates of the derived model
   (:func:`to_momentum_coordinates`) and verified there by an independent re-simulation of the
   general (unspecialised) model: DOP853, rtol 1e-10 (``Solution.verify``), including how far
   the re-simulated trajectory is from each boundary and periodicity condition.
6. ``solution.json``, ``path.png``, ``shape.png``, ``histories.png``, ``momentum.png`` and
   ``motion.gif`` in ``out_dir``.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plan", "PlanResult", "Attempt", "prepare", "solve_from_guesses", "continuation",
           "to_momentum_coordinates", "known_names", "warm_start", "read_solution"]


@dataclass(frozen=True)
class Attempt:
    """One candidate tried: its label, the solver and its verdict."""

    label: str
    status: str
    success: bool
    iterations: int
    objective: float
    solver: str = ""


def solver_order(solver: str, transcription=None) -> tuple:
    """The solvers ``plan`` tries: "auto" is FATROP, then Ipopt if FATROP finds no solution
    (Ipopt alone for collocation, which FATROP does not take)."""
    from nhgait.ocp import ProblemError
    from nhgait.ocp.solver import SOLVERS
    if solver == "auto":
        return ("ipopt",) if transcription == "collocation" else ("fatrop", "ipopt")
    if solver not in SOLVERS:
        raise ProblemError([f"unknown solver {solver!r} (auto, {', '.join(SOLVERS)})"])
    return (solver,)


@dataclass(frozen=True, eq=False)
class PlanResult:
    """What :func:`plan` produced.

    Attributes
    ----------
    label : "<system>/<task>"; task : the Task as solved; solution : the verified Solution
    (momentum coordinates); guess : label of the winning candidate; attempts : every
    candidate tried; files : written files; timings : seconds per step; plan : the Plan.
    """

    label: str
    task: Any
    solution: Any
    guess: str
    attempts: tuple
    files: tuple = ()
    timings: dict = field(default_factory=dict)
    plan: Any = None
    model: Any = None

    @property
    def success(self) -> bool:
        return bool(self.solution.success)


def known_names(model, quantities) -> tuple:
    """The names a task may use on ``model`` (see :func:`~nhgait.gaits.task.task_names`)."""
    from .task import task_names
    return task_names(model.system, quantities)


def quantity_objects(model, scene):
    """The scene's named quantities as :class:`~nhgait.ocp.Quantity` objects on ``model``."""
    from nhgait.dynamics.quantities import quantity_function
    from .task import scene_quantities
    if not scene.quantities:
        return {}
    return scene_quantities(model, quantity_function(model.system, scene.quantities))


def prepare(the_plan, *, params=None):
    """(derived model, specialised model, problem) of a :class:`~nhgait.gaits.tasks.Plan`."""
    from nhgait.dynamics import derive
    from nhgait.dynamics.specialisation import choose_velocities, specialise
    from .task import check_names, to_problem

    task, scene = the_plan.task, the_plan.scene
    model = derive(scene.system, "reduced")
    n = len(model.system.coordinates)
    check_names(task, known_names(model, scene.quantities), tuple(model.system.inputs),
                n_states=len(model.state_names), n_velocities=len(model.state_names) - n)
    velocities = task.velocities or choose_velocities(model, task.names, scene.quantities, params)
    fast = specialise(model, params, velocities=velocities, quantities=scene.quantities)
    problem = to_problem(task, fast, quantities=quantity_objects(fast, scene), params=params,
                         name=the_plan.label)
    return model, fast, problem


# ----------------------------------------------------------------------------- candidates
_BATCH: tuple = ()


def _solve_index(i):
    """Worker of a forked process: solve candidate i of the batch set up by the parent."""
    solver, guesses = _BATCH
    return replace(solver.solve(guesses[i]), problem=None)


def _solve_batch(solver, guesses, workers: int) -> list:
    """Solutions of ``guesses`` (in order), in ``workers`` forked processes when possible."""
    import multiprocessing as mp
    if workers > 1 and len(guesses) > 1 and "fork" in mp.get_all_start_methods():
        global _BATCH
        _BATCH = (solver, guesses)
        try:
            with mp.get_context("fork").Pool(min(workers, len(guesses))) as pool:
                sols = pool.map(_solve_index, range(len(guesses)))
            return [replace(s, problem=solver.problem) for s in sols]
        except (OSError, RuntimeError):   # no fork here (sandbox, resources): solve in turn
            pass
        finally:
            _BATCH = ()
    return [solver.solve(g) for g in guesses]


def solve_from_guesses(solver, guesses, *, workers: int = 1):
    """Try ``guesses`` in batches of ``workers``; the best success of the first batch with one.

    Returns (solution or None, attempts, winning label or None).
    """
    attempts = []
    workers = max(1, int(workers))
    for start in range(0, len(guesses), workers):
        batch = guesses[start:start + workers]
        sols = _solve_batch(solver, batch, workers)
        for g, s in zip(batch, sols):
            attempts.append(Attempt(g.label, s.status, bool(s.success), int(s.iterations), float(s.objective)))
        good = [(s.objective, i) for i, s in enumerate(sols) if s.success]
        if good:
            _, i = min(good)
            return sols[i], tuple(attempts), batch[i].label
    return None, tuple(attempts), None


def solve_with_fallbacks(solver, guesses, *, workers: int = 1):
    """The guesses in order (:func:`solve_from_guesses`), then :func:`continuation` from the
    first one. Returns (solution or None, attempts, winning label or None)."""
    solution, tried, won = solve_from_guesses(solver, guesses, workers=workers)
    if solution is None:
        solution, more = continuation(solver, guesses[0])
        tried += more
        won = more[-1].label if solution is not None else None
    return solution, tried, won


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


def continuation(solver, guess, steps=(0.25, 0.5, 0.75, 1.0)):
    """Grow an easier problem into ``solver.problem`` (see the module docstring, step 4).

    Returns (solution or None, attempts).
    """
    from nhgait.ocp import InitialGuess
    attempts, current = [], guess
    solution = None
    for alpha in steps:
        sub = solver.with_problem(_moved(solver.problem, alpha))
        solution = sub.solve(current)
        label = f"continuation {alpha:g} from {guess.label}"
        attempts.append(Attempt(label, solution.status, bool(solution.success), int(solution.iterations),
                                float(solution.objective)))
        if not solution.success:
            return None, tuple(attempts)
        current = InitialGuess(solution.states, solution.controls, solution.horizon, label)
    return replace(solution, problem=solver.problem), tuple(attempts)


# ----------------------------------------------------------------------------- warm start
def read_solution(path) -> dict:
    """The content of a ``solution.json`` written by :func:`plan` (a dict)."""
    import json
    return json.loads(Path(path).read_text())


def _trajectory_of(previous) -> tuple:
    """(t (K+1,), q (n × K+1), q̇ (n × K+1), u (m × K)) of a previous result of any kind."""
    from nhgait.ocp import Solution
    if isinstance(previous, PlanResult):
        previous = previous.solution
    if isinstance(previous, (str, Path)):
        previous = read_solution(previous)
    if isinstance(previous, Solution):
        n = len(previous.problem.model.system.coordinates)
        return previous.t, previous.states[:n], previous.velocities(), previous.controls
    tr = previous["trajectory"]
    return (np.asarray(tr["t"], float), np.asarray(tr["q"], float).T, np.asarray(tr["qdot"], float).T,
            np.asarray(tr["u"], float).T)


def warm_start(previous, problem, label: str = "warm start"):
    """An initial guess for ``problem`` from a previous solution (Solution, PlanResult,
    solution.json dict or path, or an InitialGuess), resampled on the problem's grid in
    normalised time t/T (configurations and velocities linearly, inputs piecewise constant)
    and mapped to the problem's state by the model's ``state(q, q̇)``."""
    from nhgait.ocp import InitialGuess
    if isinstance(previous, InitialGuess):
        return previous
    t, q, qdot, u = _trajectory_of(previous)
    grid = problem.grid()
    s_old, s_new = t / t[-1], grid / grid[-1]
    q_new = np.vstack([np.interp(s_new, s_old, row) for row in q])
    qd_new = np.vstack([np.interp(s_new, s_old, row) for row in qdot]) * (t[-1] / grid[-1])
    mid = (s_new[:-1] + s_new[1:]) / 2
    k = np.clip(np.searchsorted(s_old, mid, side="right") - 1, 0, u.shape[1] - 1)
    state = problem.model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q_new[:, j], qd_new[:, j], problem.params)).ravel()
                         for j in range(grid.size)])
    return InitialGuess(Z, u[:, k], horizon=float(grid[-1]), label=label)


# ----------------------------------------------------------------------------- plan
def _default_workers() -> int:
    return max(1, min(2, (os.cpu_count() or 1)))


def plan(system, task=None, *, overrides=(), intervals=None, solver="auto", transcription=None,
         jit=None, workers=1, params=None, max_iter=500, guess=None, out_dir=None, animate=False,
         verify=True) -> PlanResult:
    """Plan a gait: see the module docstring.

    Parameters
    ----------
    system : scene file, built-in scene name, Scene or System
    task : None (the scene's ``[task]``), a built-in gait name, a ``[task]`` dict or a Task
    overrides : ``key.sub=value`` strings (``--set``), e.g. ``["final.x=2.0"]``
    intervals : N, overriding the task's
    solver : "auto" (default: FATROP, then Ipopt when FATROP finds no solution), "fatrop" or
        "ipopt"
    transcription : None (multiple shooting; stage-ordered for FATROP) or "collocation"
    jit : compile the NLP functions (None: when a C compiler is found)
    workers : candidates tried at once (separate processes); "auto" for up to 2 per machine
    params : parameter values overriding the scene's (mapping)
    max_iter : iteration limit of each candidate's solve
    guess : a previous result to start from (Solution, PlanResult, solution.json dict or path,
        InitialGuess), tried before the planner's own candidates (:func:`warm_start`)
    out_dir : write solution.json and the figures there (``animate``: also motion.gif)
    """
    from nhgait.ocp import OCPSolver, SolverOptions
    from .guesses import candidates
    from .tasks import resolve

    timings = {}
    t0 = time.perf_counter()
    if intervals is not None:
        overrides = [*overrides, f"intervals={int(intervals)}"]
    the_plan = resolve(system, task, overrides=overrides)
    model, fast, problem = prepare(the_plan, params=params)
    timings["prepare_s"] = time.perf_counter() - t0
    workers = _default_workers() if workers in (None, "auto") else int(workers)
    guesses = candidates(problem)
    if guess is not None:
        guesses = guesses.with_first(warm_start(guess, problem))
    t0 = time.perf_counter()
    solution, attempts, won = None, (), None
    for name in solver_order(solver, transcription):
        t1 = time.perf_counter()
        ocp_solver = OCPSolver(problem, transcription, SolverOptions(jit=jit, solver=name, max_iter=max_iter))
        timings["setup_s"] = timings.get("setup_s", 0.0) + time.perf_counter() - t1
        solution, tried, won = solve_with_fallbacks(ocp_solver, guesses, workers=workers)
        attempts += tuple(replace(a, solver=name) for a in tried)
        if solution is not None:
            break
    if solution is None:   # report the first candidate's failure
        solution = ocp_solver.solve(guesses[0])
    timings["solve_s"] = time.perf_counter() - t0 - timings["setup_s"]
    momentum = momentum_problem(model, problem, the_plan, params)
    solution = to_momentum_coordinates(solution, momentum)
    if verify:
        t0 = time.perf_counter()
        solution = solution.verified()
        timings["verify_s"] = time.perf_counter() - t0
    solution = replace(solution, settings={**solution.settings, "system": the_plan.label,
                                           "velocities": list(fast.velocities), "specialisation": fast.route,
                                           "workers": workers, **{k: round(v, 6) for k, v in timings.items()}})
    result = PlanResult(the_plan.label, the_plan.task.replace(intervals=problem.intervals), solution,
                        won or "none", attempts, (), timings, the_plan, model)
    if out_dir is not None:
        result = replace(result, files=tuple(write_outputs(result, Path(out_dir), animate=animate)))
    return result


def momentum_problem(model, problem, the_plan, params):
    """The same statement on the derived (momentum-coordinate, unspecialised) model."""
    return problem.replace(model=model, quantities=quantity_objects(model, the_plan.scene), params=params)


def to_momentum_coordinates(solution, momentum):
    """A velocity-coordinate solution re-expressed on the problem ``momentum`` (z = (q, P)).

    The statement is the same (tasks are coordinate-free); only the states change. Any
    verification is dropped: verify the returned solution in momentum coordinates.
    """
    model = solution.problem.model
    if "momentum_state" not in model.numeric.functions:
        return replace(solution, problem=momentum, verification=None)
    to_p = model.numeric["momentum_state"]
    params = solution.problem.params
    states = np.column_stack([np.asarray(to_p(solution.states[:, k], params)).ravel()
                              for k in range(solution.states.shape[1])])
    settings = {**solution.settings, "transcribed_in": list(solution.state_names)}
    return replace(solution, states=states, state_names=momentum.state_names,
                   problem=momentum, verification=None, settings=settings)


# ----------------------------------------------------------------------------- outputs
def write_outputs(result: PlanResult, out: Path, *, animate: bool = True) -> list:
    """solution.json (with ``task`` and ``guess``) and the figures; returns the paths."""
    from . import plots
    out.mkdir(parents=True, exist_ok=True)
    extra = {"task": result.task.to_dict(), "system": result.label,
             "guess": {"won": result.guess, "tried": [a.__dict__ for a in result.attempts]}}
    files = [result.solution.to_json(out / "solution.json", extra=extra)]
    files.extend(plots.write_figures(result.solution, out, units=result.plan.units,
                                     drawing=result.plan.drawing, model=result.model, animate=animate))
    return files


def summary_lines(result: PlanResult) -> list:
    """The lines ``nhgait plan`` prints."""
    s = result.solution
    v = s.verification
    lines = [f"nhgait plan {result.label}: {'SUCCESS' if s.success else 'FAILED'} ({s.status})",
             f"  objective          J = {s.objective:.6f}",
             f"  iterations         {s.iterations}  (guess: {result.guess}; tried {len(result.attempts)})",
             f"  solve time         {s.solve_time_s * 1e3:.1f} ms  (functions {s.function_time_s * 1e3:.1f} ms, "
             f"solver {s.solver_time_s * 1e3:.1f} ms); set-up {s.setup_time_s * 1e3:.1f} ms"]
    if v is not None:
        lines.append(f"  verification       max state error {v.max_error:.2e}, conditions met to "
                     f"{v.max_condition_error:.2e} (DOP853, rtol {v.rtol:g})")
    else:
        lines.append("  verification       not run")
    st = s.settings
    jit = "compiled" + (" (cached)" if st.get("jit_cached") else "") if st.get("jit") else "interpreted"
    if st.get("jit_fallback"):
        jit += f" (no compiled code: {st['jit_fallback']})"
    lines.append(f"  N = {st.get('intervals')}, T = {s.horizon:.4f} s, {st.get('transcription')}, "
                 f"{st.get('solver')}, {jit}, states ({', '.join(st.get('transcribed_in', s.state_names))})")
    if result.files:
        lines.append("  files:")
        lines.extend(f"    {f}" for f in result.files)
    return lines

