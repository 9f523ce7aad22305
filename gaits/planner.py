"""The gait planner: scene + task → derive → specialise → guesses → solve → verify → write.

:func:`plan` is the one entry point used by ``nhgait plan``; built-in gaits and a user's
scene file take the same path::

    result = plan("my_robot.toml")                         # the scene's [task]
    result = plan("snakeboard", "forward", overrides=["final.x=0.8"], out_dir="out/demo")
    result.solution.objective, result.solution.verification_error, result.guess, result.files

Steps
-----
1. :func:`~nhgait.gaits.tasks.sources.resolve`: the scene and the parsed task (one ProblemError for
   every problem of the task's form).
2. ``derive(system, "reduced")`` (cached; in a chart whose singular set misses the task's
   fixed end configurations, :mod:`.charts`) and :func:`~nhgait.dynamics.numerics.specialisation.specialise`:
   parameter values bound, the state in velocity coordinates z = (q, y) with y the task's own
   velocity quantities when they parametrise the allowed velocities (else chosen by
   :func:`~nhgait.dynamics.numerics.specialisation.choose_velocities`). Conditions on velocities are
   then bounds or linear rows.
3. :func:`~nhgait.gaits.tasks.statement.to_problem`: the :class:`~nhgait.ocp.OptimalControlProblem`
   (unknown names and impossible counts are one ProblemError).
4. :func:`solve_from_guesses`: the candidates of :mod:`.guesses` in batches of ``workers``,
   each attempt in a supervised child process (step 7); within the first batch with a success the lowest
   objective wins. When every direct candidate fails, :func:`continuation` solves easier
   versions (the fixed end values moved a fraction 1/4, 1/2, 3/4 of the way from their
   initial values) and grows them to the task, each warm-started from the last.
5. The solution is re-expressed in the momentum coordinates of the derived model
   (:func:`to_momentum_coordinates`) and verified there by an independent re-simulation of the
   general (unspecialised) model: DOP853, rtol 1e-10 (``Solution.verify``), including how far
   the re-simulated trajectory is from each boundary and periodicity condition.
6. ``solution.json``, ``path.png``, ``shape.png``, ``histories.png``, ``momentum.png`` and
   ``motion.gif`` in ``out_dir`` (each written whole or not at all: into a staging folder,
   then moved).
7. **Time.** The whole plan runs within a wall-clock budget (:func:`plan_budget`:
   ``time_limit``, the task's ``time_limit`` or a default from the robot's size) and each
   solver attempt within its own limit (:func:`~.time_limits.attempt_limited`, at most the time left). Each
   attempt runs in a supervised child process (:mod:`nhgait.ocp.supervision`), so that a solver
   looping in its C code is killed at its limit and an interrupt stops it at once. A budget
   that runs out — in the derivation, the compilation, the solves, the continuation or the
   verification — ends the plan as a failure naming the phase (``PlanResult.overrun``), with
   the closest point reached written to ``solution.json`` (no figures).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from typing import Any

from .files.exports import states_text
from .plan_files import figure_modules, with_figures, write_figure_files, write_outputs, written  # noqa: F401
from .planning.infeasibility import stalled, with_elastic
from .planning.search import (  # noqa: F401
    Attempt,
    Search,
    SearchRun,
    continuation,
    solve_from_guesses,
    solve_with_fallbacks,
)
from .planning.warm_start import MAX_SOLUTION_BYTES, previous_answer, read_solution, warm_start  # noqa: F401
from .tasks.statement import quantity_objects  # noqa: F401
from .verification.checks import open_loop_label, solution_check_lines
from .verification.gait_check import (  # noqa: F401
    momentum_problem,
    screening_report,
    to_momentum_coordinates,
    unsolved,
    verified_gait,
)
from .verification.refinement import refinable, refine

__all__ = ["plan", "PlanResult", "prepare", "Prepared", "state_problem", "to_momentum_coordinates",
           "verified_gait", "unsolved", "known_names", "warm_start", "read_solution", "summary_lines"]


def solver_order(solver: str, transcription=None, problem=None, hessian: str = "exact") -> tuple:
    """The solvers ``plan`` tries, the next one when the previous finds no solution.

    "auto": Ipopt alone for collocation (FATROP does not take it) and for the limited-memory
    Hessian (Ipopt's L-BFGS; FATROP has none); for shooting, FATROP first
    when the stage function is written inline (small ODEs: FATROP is the faster there), Ipopt
    first when it is structured (robots of 5–10 coordinates: Ipopt is the faster there; the
    measurements are in docs/gait-planning.md and docs/benchmarks.md)."""
    from nhgait.ocp import ProblemError
    from nhgait.ocp.solver import SOLVERS
    if solver == "auto":
        if transcription == "collocation" or hessian == "limited-memory":
            return ("ipopt",)
        return (("ipopt", "fatrop") if problem is not None and _structured_stage(problem)
                else ("fatrop", "ipopt"))
    if solver not in SOLVERS:
        raise ProblemError([f"unknown solver {solver!r} (auto, {', '.join(SOLVERS)})"])
    return (solver,)


def _structured_stage(problem) -> bool:
    from nhgait.ocp.stage import stage_mode
    from nhgait.ocp.transcription import ode_function
    return stage_mode(ode_function(problem), free_horizon=problem.free_horizon is not None) == "structured"


@dataclass(kw_only=True, frozen=True, eq=False)
class PlanResult:
    """What :func:`plan` produced.

    Attributes
    ----------
    label : "<system>/<task>"; task : the Task as solved; solution : the verified Solution
    (momentum coordinates) — for a failure, the closest point found; guess : label of the
    winning candidate; attempts : every candidate tried; files : written files; timings :
    seconds per step; plan : the Plan; conditions : what was dropped from the task's
    conditions and why (:class:`~nhgait.ocp.conditions.ConditionReport`); diagnosis : why a
    failure failed and what to change (:func:`~nhgait.gaits.verification.diagnosis.diagnose`); overrun : None,
    or where the time budget ran out (:class:`~nhgait.ocp.budget.Overrun`: the plan failed;
    ``solution`` is then the closest point reached, or None before any attempt); unwritten :
    empty, or what could not be written to ``out_dir`` and where solution.json went instead.
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
    conditions: Any = None
    diagnosis: tuple = ()
    overrun: Any = None
    unwritten: str = ""
    screening: tuple = ()

    def __repr__(self) -> str:
        from nhgait.dynamics.reprs import plan_repr
        return plan_repr(self)

    @property
    def success(self) -> bool:
        """Converged and verified: ``Solution.verified`` turns a converged solution whose
        re-simulation misses the task into a failure (only ``plan(verify=False)`` skips it)."""
        return bool(self.solution is not None and self.solution.success)


def known_names(model, quantities) -> tuple:
    """The names a task may use on ``model`` (see :func:`~nhgait.gaits.tasks.statement.task_names`)."""
    from .tasks.statement import task_names
    return task_names(model.system, quantities)


@dataclass(frozen=True, eq=False)
class Prepared:
    """What :func:`prepare` makes of a plan.

    ``model``: the derived reduced ODE (momentum coordinates); ``specialised``: the model
    specialised to the parameter values, which the NLP is stated on; ``problem``: the statement
    with independent conditions (what is solved); ``stated``: the statement as the task gives it
    (what the verification checks); ``conditions``: what :func:`~nhgait.ocp.conditions.normalise`
    dropped or solved, and why."""

    model: Any
    specialised: Any
    problem: Any
    stated: Any
    conditions: Any


def state_problem(task, specialised, scene, *, params=None, name: str = ""):
    """(stated problem, problem with independent conditions, ConditionReport) of ``task`` on
    the specialised model: an end that gives every coordinate and velocity is checked
    against ω(q)q̇ = 0 first (the error names each violated constraint)."""
    from nhgait.ocp.conditions import normalise

    from .tasks.statement import to_problem
    _check_full_states(task, specialised.base, params)
    stated = to_problem(task, specialised, quantities=quantity_objects(specialised, scene), params=params,
                        name=name)
    problem, report = normalise(stated)
    return stated, problem, report


def _check_full_states(task, model, params) -> None:
    """A full (q, q̇) at an end must satisfy the constraints
    (:func:`nhgait.dynamics.derivation.states.check_physical_state`; a posture on the singular
    set of the reduction's chart is allowed: the velocity states may be regular there)."""
    from nhgait.dynamics.derivation.states import check_physical_state
    from nhgait.dynamics.errors import ModelError
    from nhgait.ocp import ProblemError
    coords = tuple(model.system.coordinates)
    problems = []
    for where in ("initial", "final"):
        mapping = getattr(task, where)
        values = {k: v for k, v in mapping.items() if not isinstance(v, tuple)}
        if all(c in values and f"{c}_dot" in values for c in coords):
            try:
                check_physical_state(model, [values[c] for c in coords],
                                     [values[f"{c}_dot"] for c in coords], params)
            except ModelError as exc:
                problems += [f"[task].{where}: {p}" for p in exc.problems]
    if problems:
        raise ProblemError(problems, title="inconsistent boundary conditions")


def prepare(to_plan, *, params=None, progress=None) -> Prepared:
    """The :class:`Prepared` model and problems of a :class:`~nhgait.gaits.tasks.sources.Plan`."""
    from nhgait.dynamics.numerics.specialisation import choose_velocities, specialise
    from nhgait.dynamics.progress import Progress

    from .planning.arguments import check_params
    from .planning.charts import derive_for_task, end_postures
    from .tasks.statement import check_names

    progress = progress or Progress.silent()
    task, scene = to_plan.task, to_plan.scene
    check_params(scene.system, params)      # values: names, numbers, the metric (before any derivation)
    model = derive_for_task(scene.system, task, params, progress)
    prov = getattr(model, "provenance", None)
    progress.note(f"  n = {model.system.n} coordinates, {len(model.state_names)} states, {model.form} form"
                  + (" (from the cache)" if prov is not None and prov.cache_hit else ""))
    n = len(model.system.coordinates)
    check_names(task, known_names(model, scene.all_quantities), tuple(model.system.inputs),
                n_velocities=len(model.state_names) - n, motion=tuple(scene.motion_quantities))
    bounds = {k: v for k, v in task.bounds.items() if isinstance(v, tuple)}
    ends = end_postures(task, tuple(model.system.coordinates))
    velocities = task.velocities or choose_velocities(model, task.names, scene.quantities, params,
                                                      bounds, ends)
    with progress.phase(f"specialise: parameter values bound, velocity states ({', '.join(velocities)})"):
        specialised = specialise(model, params, velocities=velocities, quantities=scene.quantities)
    stated, problem, report = state_problem(task, specialised, scene, params=params, name=to_plan.label)
    for line in report.lines():
        progress.note(f"  conditions: {line}")
    return Prepared(model, specialised, problem, stated, report)


# ----------------------------------------------------------------------------- plan
#: above this many intervals a plan says what it costs before it builds the NLP
LARGE_INTERVALS = 1000


def large_request_note(problem) -> str:
    """What a plan of many intervals costs, said before the NLP is built: its size, and the
    times measured for the 4-coordinate car at N = 2000 on a 2-core machine (both grow about
    linearly with N and with the states)."""
    N, nx, nu = problem.intervals, problem.n_states, problem.n_controls
    return (f"N = {N} intervals is a large request: {(N + 1) * nx + N * nu} NLP variables and {N * nx} "
            "continuity constraints; expect minutes (the 4-coordinate car at N = 2000: 34 s to "
            f"build the NLP, 105 s to solve, on a 2-core machine; both grow about linearly with N)")


def _default_workers() -> int:
    return max(1, min(2, (os.cpu_count() or 1)))


def choose_hessian(hessian: str) -> str:
    """``hessian`` unless "auto": the exact Hessian at every size — measured against
    Gauss–Newton (no convergence in 500 iterations on the snake and the two-steering
    snakeboard, faster only on a nearly kinematic cart) and limited-memory BFGS (many times the
    iterations); the numbers are in docs/gait-planning.md and docs/benchmarks.md."""
    return "exact" if hessian == "auto" else hessian


def plan(system, task=None, *, overrides=(), params=None, guess=None, out_dir=None, animate=False,
         figures=True, progress=None, options=None, memo=None, **values) -> PlanResult:
    r"""Plan a gait: see the module docstring.

    Parameters
    ----------
    system : scene file, built-in scene name, Scene or System
    task : None (the scene's ``[task]``), a built-in gait name, a ``[task]`` dict or a Task
    overrides : ``key.sub=value`` strings (``--set``), e.g. ``["final.x=2.0"]``; one string is
        one override
    params : parameter values overriding the scene's (mapping)
    guess : a previous result to start from (Solution, PlanResult, solution.json dict or path,
        InitialGuess), tried before the planner's own candidates (:func:`warm_start`); one of
        another robot, or a solution.json whose trajectory is not well formed, is a ProblemError
        before any derivation
    out_dir : write solution.json and the figures there (``animate``: also motion.gif, which
        needs ``out_dir``)
    figures : False: in ``out_dir`` only solution.json and trajectory.csv (the result); the
        figures are then :func:`with_figures`'s (``nhgait plan`` prints the result line first)
    progress : a :class:`~nhgait.dynamics.progress.Progress` (None: silent)
    memo : what this process keeps between plans, a
        :class:`~nhgait.gaits.planning.plan_memo.PlanMemo` (None: the module's
        :data:`~nhgait.gaits.planning.plan_memo.PLAN_MEMO`, bounded and clearable; False: none):
        the built solver of each plan structure, reused by a plan of the same structure (also with
        changed boundary values), and the last optimum of each task, from which a repeated plan
        starts (without the exploration when it had been explored)
    options : how the plan is solved, a :class:`~.plan_options.PlanOptions` (or a mapping of its
        names; None: the defaults) — the grid (``intervals``), ``solver``, ``transcription``,
        ``jit``, ``workers``, ``max_iter``, ``hessian``, ``max_guesses``, ``verify`` and
        ``time_limit`` (a plan that runs out is a failure whose ``overrun`` says in which phase:
        step 7 of the module docstring)
    \*\*values : the same options as keywords, on top of ``options``, e.g.
        ``plan(..., intervals=40, verify=False)``

    Notes
    -----
    Every problem of these arguments (:mod:`.plan_arguments`), of ``out_dir``, the scene and
    the task is one :class:`~nhgait.ocp.ProblemError`, raised before any derivation.
    """
    from nhgait.dynamics.progress import Progress
    from nhgait.ocp.budget import BudgetSpent

    from .planning.arguments import checked_request
    from .verification.diagnosis import diagnose

    started = time.monotonic()
    to_plan, out_dir, options = checked_request(system, task, dict(   # one ProblemError, before any work
        overrides=overrides, params=params, out_dir=out_dir, animate=animate, progress=progress,
        options=options, values=values))
    if guess is not None:              # checked before any derivation (exit 2 for a bad guess)
        guess = previous_answer(guess, to_plan.system.coordinates, to_plan.system.inputs, to_plan.label)
    progress = progress or Progress.silent()
    budget = plan_budget(to_plan, options.time_limit, started=started, progress=progress)
    if options.changed():
        progress.note(f"options: {options.summary()}")
    settings = SearchSettings.of(options, warm_figures=out_dir is not None)
    reached = _Reached()
    request = _Request(to_plan=to_plan, settings=settings, budget=budget, params=params, guess=guess,
                       verify=options.verify, progress=progress, memo=_memo(memo))
    try:
        _run_plan(request, reached)
    except BudgetSpent as exc:
        reached.overrun = exc.overrun
        progress.note(f"  the time budget of {exc.overrun.seconds:g} s ran out during {exc.overrun.phase}")
    result = _result(to_plan, reached, settings, params)
    result = with_elastic(result, reached.prepared, reached.search, budget, progress)     # issue 41
    result = replace(result, diagnosis=diagnose(result))
    if out_dir is not None:
        result = written(result, out_dir, progress=progress)
        if figures:
            result = with_figures(result, out_dir, animate=animate, progress=progress)
    return result


def plan_budget(to_plan, time_limit=None, *, started=None, progress=None):
    """The :class:`~nhgait.ocp.budget.Budget` of a plan
    (:func:`~nhgait.gaits.planning.time_limits.budget_for`:
    ``time_limit``, else the task's, else the default for the robot's size), said on ``progress``."""
    from .planning.time_limits import budget_for
    budget = budget_for(len(to_plan.scene.system.coordinates), time_limit, to_plan.task.time_limit,
                        started=started)
    if progress is not None:
        progress.note(f"time budget: {budget.describe()}; --time-limit SECONDS to change it")
    return budget


@dataclass(eq=False)
class _Reached:
    """How far a plan got (kept when its budget runs out): the prepared model and problem, the
    guesses' search, the solution in momentum coordinates (verified when ``verified``), the
    seconds per step, what the screening of the guesses found (``screening``) and, when the
    budget ran out, where."""

    prepared: Any = None
    search: Any = None
    solution: Any = None
    timings: dict = field(default_factory=dict)
    overrun: Any = None
    screening: tuple = ()
    optimum: tuple | None = None     # (task key, Optimum) of the search's solution, for the memo
    task_key: str | None = None      # the task's key in the memo (:mod:`.planning.plan_memo`)


@dataclass(frozen=True, kw_only=True)
class _Request:
    """One plan as :func:`plan` checked it: what to plan (``to_plan``), how to search
    (``settings``), within which ``budget``, the parameter values, the user's ``guess``
    (or None), whether to ``verify``, where to talk (``progress``) and the process's ``memo``
    (:class:`~.planning.plan_memo.PlanMemo`, or None: none)."""

    to_plan: Any
    settings: Any
    budget: Any
    params: Any
    guess: Any
    verify: bool
    progress: Any
    memo: Any = None


def _memo(memo):
    """The :class:`~.planning.plan_memo.PlanMemo` of ``plan(memo=...)``: None → the default one,
    False → none; none either in a thread the memo does not serve."""
    if memo is False:
        return None
    if memo is None:
        from .planning.plan_memo import PLAN_MEMO
        memo = PLAN_MEMO
    return memo if memo.serves_this_thread() else None


def _run_plan(request: _Request, reached: _Reached) -> None:
    """Steps 2–5 of the module docstring and the feedback along a converged plan, each within
    ``request.budget``, recorded in ``reached``."""
    from nhgait.ocp import ProblemError

    from .tasks.reachability import unreachable_targets
    to_plan, settings, budget, progress = request.to_plan, request.settings, request.budget, request.progress
    params, verify = request.params, request.verify
    t0 = time.perf_counter()
    with budget.stage("derivation"):
        reached.prepared = _prepared(request)
    reached.timings["prepare_s"] = time.perf_counter() - t0
    problem = reached.prepared.problem
    unreachable = unreachable_targets(problem, reached.prepared.model.system, params)
    if unreachable:
        raise ProblemError(unreachable, title="unreachable task")
    if problem.intervals > LARGE_INTERVALS:
        progress.note(large_request_note(problem))
    def verify_one(solution):
        with budget.stage("verification"):
            prepared = reached.prepared
            return _derived(request, reached, solution, "verification", lambda: verified_gait(
                solution, prepared.model, prepared.stated, to_plan, params, progress=progress))
    t0 = time.perf_counter()
    try:
        _searched(request, problem, reached)
    finally:                       # a spent budget still reports where the time went
        reached.timings["solve_s"] = time.perf_counter() - t0 - reached.timings.get("setup_s", 0.0)
    if to_plan.task.robust is not None and reached.search.solution is not None:    # [task.robust]
        from .planning.robust import robust_search
        t0 = time.perf_counter()
        reached.search = robust_search(reached.search, reached.prepared, to_plan, settings, budget, progress)
        reached.timings["robust_s"] = time.perf_counter() - t0
    search = reached.search
    reached.solution = _derived(request, reached, search.solution, "momentum coordinates",
                                lambda: _in_momentum(search, reached.prepared, to_plan, params))
    if verify and search.solution is not None:
        t0 = time.perf_counter()
        reached.solution = verify_one(search.solution)
        # refined: nominal again
        if refinable(reached.solution) and "robust" not in search.solution.settings:
            _refined(reached, settings, budget, progress, verify_one)
        if not _passed(reached.solution) and search.first is not None:
            search = _first_instead(reached, search, settings, budget, progress, verify_one)
            _remember_kept(request, reached)
        reached.timings["verify_s"] = time.perf_counter() - t0
        _keep_verified(reached)
    if search.solution is not None:                                          # issue 28
        t0 = time.perf_counter()
        with budget.stage("the feedback and stability"):
            extra = _derived(request, reached, search.solution, "feedback and stability",
                             lambda: _feedback_and_stability(search, progress))
            reached.solution = replace(reached.solution, **extra)
        reached.timings["feedback_s"] = time.perf_counter() - t0


def _derived(request: _Request, reached: _Reached, solution, what: str, make):
    """``make()``, the value ``what`` of ``solution``, or the memo's of the same solution
    (:func:`~.planning.plan_memo.solution_key`: the same content), said on the progress stream."""
    if request.memo is None:
        return make()
    from .planning.plan_memo import solution_key
    value, reused = request.memo.of_solution(solution_key(reached.task_key, solution, what), make)
    if reused:
        request.progress.note(f"  {what}: those of this same solution (bit for bit), computed before in "
                              "this process")
        if hasattr(value, "solve_time_s"):       # a Solution: this attempt's own record, not the earlier's
            own = {k: value.settings[k] for k in ("transcribed_in",) if k in value.settings}
            value = replace(value, **{name: getattr(solution, name) for name in ATTEMPT_RECORD},
                            settings={**value.settings, **solution.settings, **own})
    return value


#: what a Solution records of the attempt that produced it (not of its trajectory)
ATTEMPT_RECORD = ("iterations", "solve_time_s", "setup_time_s", "function_time_s", "solver_time_s", "stats")


def _remember_kept(request: _Request, reached: _Reached) -> None:
    """After the verification kept the first converged gait instead of the exploration's lower
    objective (:func:`_first_instead`): that gait is the task's last optimum in the memo (a warm
    start from the other would fail its verification again, with no first gait to fall back on)."""
    if request.memo is None or reached.optimum is None or reached.search.solution is None:
        return
    from nhgait.ocp import InitialGuess

    from .planning.plan_memo import LAST_OPTIMUM
    kept = reached.search.solution
    key, optimum = reached.optimum
    if float(kept.objective) != optimum.objective:
        guess = InitialGuess(kept.z.T, kept.u.T, kept.horizon, LAST_OPTIMUM)
        reached.optimum = (key, replace(optimum, guess=guess, objective=float(kept.objective)))
        request.memo.remember(*reached.optimum)


def _keep_verified(reached: _Reached) -> None:
    """The search's optimum in the disk cache for the next process (:mod:`.planning.plan_memo`)
    when it is the solution kept and it passed its verification."""
    if reached.optimum is None or reached.solution is None or not _passed(reached.solution):
        return
    key, optimum = reached.optimum
    if reached.search.solution is not None and float(reached.search.solution.objective) == optimum.objective:
        from .planning.plan_memo import store_optimum
        store_optimum(key, optimum)


def _passed(solution) -> bool:
    from .verification.gait_check import passed  # the deciding checks (issue 41)
    return passed(solution)


def _first_instead(reached: _Reached, search, settings, budget, progress, verify_one):
    """The exploration's lower objective failed its verification (refined or not): the first
    converged gait instead, verified (and refined) the same way, when it passes — a verified gait
    beats a lower objective that is not one; else the failure stands. Returns the search whose
    solution the plan keeps."""
    kept = (reached.search, reached.solution)
    first = replace(reached.search, solution=search.first, won=search.first_won, first=None, first_won=None)
    reached.search, reached.solution = first, verify_one(search.first)
    if refinable(reached.solution):
        _refined(reached, settings, budget, progress, verify_one)
    if not _passed(reached.solution):
        reached.search, reached.solution = kept
        return search
    progress.note(f"  kept the first converged gait {search.first_won!r} (J = {search.first.objective:.6g}): "
                  f"the lower objective's, {search.won!r} (J = {search.solution.objective:.6g}), failed its "
                  "verification")
    return first


def _refined(reached: _Reached, settings, budget, progress, verify_one) -> None:
    """The converged solution solved again with more RK4 sub-steps (:mod:`.refinement`), in
    ``reached``: its search gets the refined solution (when one converged) and the attempts."""
    search = reached.search
    solution, verified, attempts = refine(search.solution, reached.solution, settings, budget,
                                          progress, verify_one)
    won = (search.won if solution is search.solution
           else f"{search.won}, refined ({solution.settings['rk4_steps']} RK4 sub-steps)")
    reached.search = replace(search, solution=solution, attempts=search.attempts + attempts, won=won)
    reached.solution = verified


def _result(to_plan, reached: _Reached, settings, params) -> PlanResult:
    """The PlanResult of what the plan reached (a failure when its budget ran out)."""
    prepared, search, solution = reached.prepared, reached.search, reached.solution
    if solution is None and search is not None:
        solution = _in_momentum(search, prepared, to_plan, params)
    if solution is not None:
        if reached.overrun is not None:
            solution = replace(solution, success=False,
                               message=f"{solution.message} (then the time budget of "
                               f"{reached.overrun.seconds:g} s ran out during {reached.overrun.phase})")
        extra = {"system": to_plan.label, "velocities": list(prepared.specialised.velocities),
                 "specialisation": prepared.specialised.route, "workers": settings.workers,
                 "conditions": prepared.conditions.lines(),
                 **{k: round(v, 6) for k, v in reached.timings.items()}}
        solution = replace(solution, settings={**solution.settings, **extra})
    task = to_plan.task if prepared is None else to_plan.task.replace(intervals=prepared.problem.intervals)
    return PlanResult(label=to_plan.label, task=task, solution=solution,
                      guess=(search.won if search is not None else None) or "none",
                      attempts=search.attempts if search is not None else (), files=(),
                      timings=dict(reached.timings), plan=to_plan,
                      model=prepared.model if prepared is not None else None,
                      conditions=prepared.conditions if prepared is not None else None,
                      overrun=reached.overrun, screening=reached.screening)


@dataclass(frozen=True, kw_only=True)
class SearchSettings:
    """How :func:`plan` searches: the ``solver`` choice (:func:`solver_order`), the
    ``transcription``, ``jit``, the ``hessian`` (already chosen), ``max_iter`` per solve,
    ``workers`` (candidates at once) and ``limit`` (guesses per solver before the continuation)."""

    solver: str
    transcription: Any
    jit: Any
    hessian: str
    max_iter: int
    workers: int
    limit: int
    warm_figures: bool = False

    @classmethod
    def of(cls, options, *, warm_figures: bool = False) -> SearchSettings:
        """The settings of a plan's :class:`~.plan_options.PlanOptions` (the Hessian chosen, the
        workers counted)."""
        workers = _default_workers() if options.workers in (None, "auto") else int(options.workers)
        return cls(solver=options.solver, transcription=options.transcription, jit=options.jit,
                   hessian=choose_hessian(options.hessian), max_iter=options.max_iter, workers=workers,
                   limit=options.max_guesses, warm_figures=warm_figures)


def _prepared(request: _Request) -> Prepared:
    """:func:`prepare`, or the memo's :class:`Prepared` of the same plan (:mod:`.planning.plan_memo`)."""
    to_plan, params, progress = request.to_plan, request.params, request.progress
    if request.memo is None:
        return prepare(to_plan, params=params, progress=progress)
    from .planning.plan_memo import prepared_key
    prepared, reused = request.memo.prepare(prepared_key(to_plan, params),
                                            lambda: prepare(to_plan, params=params, progress=progress))
    if reused:
        velocities = ", ".join(prepared.specialised.velocities)
        progress.note(f"  the model, its specialisation ({velocities}) and the problem of this plan, "
                      "prepared before in this process: reused")
    return prepared


def _cold_guesses(request: _Request, problem):
    """The planner's own candidates (:mod:`.planning.guesses`), the user's guess first."""
    from .planning.guesses import candidates
    with request.budget.stage("the initial guesses"):
        guesses = candidates(problem, progress=request.progress)
        if request.guess is not None:
            guesses = guesses.with_first(warm_start(request.guess, problem))
    return guesses


def _searched(request: _Request, problem, reached: _Reached):
    """The search of :func:`_search` in ``reached.search``, from the last optimum of this task
    when the memo keeps one (:mod:`.planning.plan_memo`): alone when it had been explored (the
    candidates built only when it fails), else in front of the candidates with the exploration.
    The screening report of the guesses searched in ``reached.screening``; the optimum found is
    remembered."""
    memo, progress = request.memo, request.progress
    keys = _memo_keys(request, reached.prepared)
    last = memo.optimum(keys[1]) if memo is not None and request.guess is None else None
    where = "kept in this process"
    if last is None and memo is not None and request.guess is None:
        from .planning.plan_memo import stored_optimum
        last, where = stored_optimum(keys[1]), "verified, kept in the cache"      # an earlier process's
    explore = request.guess is None               # a user's warm start answers where the user asked
    guesses = []
    if last is not None:
        progress.note(f"  warm start from the last optimum of this task ({where}; J = {last.objective:.6g})"
                      + ("; explored before: no exploration" if last.explored else ""))
    try:
        if last is not None and last.explored:
            guesses = [last.guess]
            _search(request, guesses, reached, explore=False, fallbacks=False, in_process=last.iteration_s)
            if reached.search.solution is None:
                progress.note("  the last optimum did not converge again: the planner's own guesses")
        if reached.search is None or reached.search.solution is None:
            guesses = _cold_guesses(request, problem)
            if last is not None and not last.explored:
                guesses = guesses.with_first(last.guess)
            _search(request, guesses, reached, explore=explore)
    finally:                       # a spent budget still reports what was screened
        if reached.search is not None:
            reached.search, reached.screening = screening_report(guesses, reached.search, problem)
    found, reached.task_key = reached.search.solution, keys[1]
    if memo is not None and found is not None:
        from nhgait.ocp import InitialGuess

        from .planning.plan_memo import LAST_OPTIMUM, Optimum
        per_iteration = float(found.solve_time_s) / max(1, int(found.iterations))
        if reached.search.won == LAST_OPTIMUM:     # kept as it was: every repetition starts there
            reached.optimum = (keys[1], replace(last, iteration_s=per_iteration))
        else:
            explored = explore or (last is not None and last.explored)
            guess = InitialGuess(found.z.T, found.u.T, found.horizon, LAST_OPTIMUM)
            reached.optimum = (keys[1], Optimum(guess, float(found.objective), explored, per_iteration))
        memo.remember(*reached.optimum)


def _memo_keys(request: _Request, prepared) -> tuple:
    """(structure key of the first solver, task key) of :mod:`.planning.plan_memo` (None, None
    without a memo)."""
    if request.memo is None:
        return None, None
    from .planning.plan_memo import structure_key, task_key
    structure = structure_key(prepared, request.to_plan.scene, request.to_plan.task, request.settings, "")
    return structure, task_key(structure, request.to_plan.task)


def _built_solver(request: _Request, prepared, name: str, explore: bool):
    """The solver ``name`` of ``problem``: the memo's of this structure (with this problem's
    values), else built (with its time limit per attempt) and kept."""
    from nhgait.ocp import OCPSolver, ProblemError, SolverOptions

    from .planning.plan_memo import structure_key
    from .planning.time_limits import attempt_limited
    s, progress, problem = request.settings, request.progress, prepared.problem

    memo = request.memo

    def build():                    # a kept solver has the coarse grid a later cold plan uses
        with progress.phase(f"build the NLP for {name} ({problem.intervals} intervals, {s.hessian} Hessian)"):
            ocp = OCPSolver(problem, s.transcription,
                            SolverOptions(jit=s.jit, solver=name, max_iter=s.max_iter, hessian=s.hessian,
                                          coarse=explore or memo is not None), progress=progress)
            return attempt_limited(ocp, None, progress)
    if memo is None:
        ocp = build()
    else:
        key = structure_key(prepared, request.to_plan.scene, request.to_plan.task, s,
                            f"{name}{' (its own log)' if progress.verbose else ''}")
        ocp, reused = memo.solver(key, build)
        if reused:
            ocp.talk_to(progress).adopt_optimised()     # kept switched: its copies inherit the library
            try:
                ocp = ocp.for_values(problem)
            except ProblemError:            # not the NLP it seemed: built anew (and kept)
                memo.solvers.clear()
                ocp, _ = memo.solver(key, build)
            else:
                progress.note(f"  the NLP and the {name} solver of this structure, built before in this "
                              "process: reused")
    return ocp if explore else ocp.direct()


def _search(request: _Request, guesses, reached: _Reached, *, explore: bool, fallbacks: bool = True,
            in_process: float | None = None) -> None:
    """The solvers of :func:`solver_order` in turn until one converges: the search so far in
    ``reached.search``, the set-up seconds in ``reached.timings["setup_s"]``. Building a solver
    is interrupted when the budget runs out; each attempt gets at most the time left
    (:func:`~.time_limits.attempt_limited`). ``explore``: solves from generic guesses (the
    coarse grid, the exploration after a first success); else from a warm start (neither).
    ``fallbacks``: the continuation when no guess converges (:func:`solve_with_fallbacks`);
    ``in_process``: the seconds per iteration of the solve a warm start comes from (its solve
    may then run in this process: :class:`~.planning.search.SearchRun`)."""
    s, progress, budget = request.settings, request.progress, request.budget
    problem = reached.prepared.problem
    reached.search = reached.search if reached.search is not None else Search(None, (), None)
    for name in solver_order(s.solver, s.transcription, problem, s.hessian):
        t0 = time.perf_counter()
        try:
            with budget.stage(f"the NLP set-up and compilation for {name}"):
                ocp = _built_solver(request, reached.prepared, name, explore)
        finally:
            reached.timings["setup_s"] = reached.timings.get("setup_s", 0.0) + time.perf_counter() - t0
        with budget.stage(f"the solves with {name}", interrupt=False):
            with progress.phase(f"solve with {name} from up to {min(s.limit, len(guesses))} guesses"):
                run = SearchRun(workers=s.workers, limit=s.limit, progress=progress, budget=budget,
                                explore=explore, explore_workers=max(s.workers, _default_workers()),
                                meanwhile=figure_modules if s.warm_figures else None,
                                in_process=in_process)
                searched = (solve_with_fallbacks if fallbacks else solve_from_guesses)(ocp, guesses, run)
                reached.search = reached.search.then(searched)
        if reached.search.solution is not None or stalled(reached.search.attempts):    # issue 41
            break


def _in_momentum(search, prepared, to_plan, params):
    """The winning solution, else the closest failure, in momentum coordinates of the derived
    model (None: no attempt): :func:`verified_gait` without the verification."""
    solution = search.solution if search.solution is not None else search.closest
    if solution is None:
        return None
    return verified_gait(solution, prepared.model, prepared.stated, to_plan, params, verify=False)


def _feedback_and_stability(search, progress) -> dict:
    """The time-varying LQR along a converged plan in its own (velocity) coordinates
    (:mod:`nhgait.ocp.feedback`) and, for a periodic plan, the Floquet multipliers of the open and
    the closed loop (:mod:`nhgait.ocp.floquet`); {} for a failed plan."""
    if search.solution is None:
        return {}
    from .verification.feedback import feedback_and_stability
    return feedback_and_stability(search.solution, progress)


def summary_lines(result: PlanResult) -> list:
    """The lines ``nhgait plan`` prints."""
    s = result.solution
    if s is None:             # the budget ran out before any attempt
        lines = [f"nhgait plan {result.label}: FAILED (time budget spent)", "  no attempt was made"]
        return lines + _closing_lines(result)
    v = s.verification
    status = "time budget spent; closest point: " + s.status if result.overrun is not None else s.status
    lines = [f"nhgait plan {result.label}: {'SUCCESS' if result.success else 'FAILED'} ({status})",
             f"  objective          J = {s.objective:.6f}",
             f"  iterations         {s.iterations}  (guess: {result.guess}; tried {len(result.attempts)})",
             f"  solve time         {s.solve_time_s * 1e3:.1f} ms  (functions "
             f"{s.function_time_s * 1e3:.1f} ms, "
             f"solver {s.solver_time_s * 1e3:.1f} ms); set-up {s.setup_time_s * 1e3:.1f} ms"]
    if v is not None:
        lines.append(f"  {open_loop_label(s)}{'passed' if v.passed else 'FAILED'}: max state error "
                     f"{v.max_error:.2e}, conditions met to {v.max_condition_error:.2e}; relative to each "
                     f"state's range {v.max_scaled_error:.2e}, {v.max_scaled_condition_error:.2e} (tolerance "
                     f"{v.tolerance:g}; DOP853, rtol {v.rtol:g})")
    else:
        lines.append("  verification       not run")
    lines += [f"  {line}" for line in solution_check_lines(s)]              # issue 41
    st = s.settings
    lines.append(f"  N = {st.get('intervals')}, T = {s.horizon:.4f} s, {st.get('transcription')}, "
                 f"{st.get('solver')}, {st.get('hessian', 'exact')} Hessian, {_compiled_text(st)}, "
                 f"{states_text(s)}")
    lines += [f"  conditions         {line}"
              for line in (result.conditions.lines() if result.conditions else ())]
    if s.feedback is not None:                                               # issue 28
        lines.append(f"  feedback           time-varying LQR, {s.feedback.gains.shape[0]} gains "
                     f"{s.feedback.gains.shape[1]}×{s.feedback.gains.shape[2]} in solution.json; "
                     "nhgait track applies it to a robot that differs")
    if s.stability is not None:
        lines += [f"  stability          {line}" for line in s.stability.summary()]
    if st.get("robust"):                                                     # [task.robust]
        from .planning.robust import summary_line
        lines.append(f"  robust             {summary_line(st['robust'])}")
    symmetry = getattr(result.model, "symmetry", None)
    if symmetry is not None:
        lines.append(f"  symmetry           {symmetry.chosen.group} moves the fibre "
                     f"({', '.join(result.model.fiber)}); "
                     f"the guesses loop the shape ({', '.join(result.model.shape)}); why, and the "
                     "other choices (fiber = [...] in [system]): nhgait derive")
    checked = getattr(s.problem, "model", None)
    if symmetry is not None and checked is not None and not hasattr(checked, "fiber"):
        lines.append("  verified in        x = (q, q̇) on the Euler–Lagrange equations: the gait crosses "
                     "the singular set of every chart of the reduction tried")
    elif symmetry is not None and checked is not None and tuple(checked.fiber) != tuple(result.model.fiber):
        lines.append(f"  verified in        the chart with fiber ({', '.join(checked.fiber)}): the gait "
                     "crosses the "
                     f"singular set of fiber ({', '.join(result.model.fiber)}), where its momenta "
                     "are not defined")
    return lines + _closing_lines(result)


def _closing_lines(result: PlanResult) -> list:
    """The diagnosis and the files written."""
    lines = []
    if result.diagnosis:
        lines.append("  why:")
        lines.extend(f"    {line}" for line in result.diagnosis)
    if result.unwritten:
        lines.append(f"  files              NOT WRITTEN: {result.unwritten}")
    if result.files:
        lines.append("  files:")
        lines.extend(f"    {f}" for f in result.files)
        if result.success and not any(str(f).endswith(".gif") for f in result.files):
            lines.append("  animation          not written (made on request): add --gif "
                         "(plan(..., animate=True)) to write motion.gif")
    if result.overrun is not None:
        lines.append("  figures            not written: the time budget was spent")
    return lines


def _compiled_text(settings) -> str:
    """Which code solved and what was started for later (:class:`~nhgait.ocp.nlp_code.CompileReport`)."""
    c = settings.get("compile") or {}
    later = c.get("later") or {}
    after = ""
    if later.get("summary"):
        after = f"; {later['summary']}"
    if not settings.get("jit"):
        reason = settings.get("jit_fallback")
        return "interpreted" + (f" ({reason}{after})" if reason else (f" ({after[2:]})" if after else ""))
    size = f"{c.get('c_bytes', 0) / 1e6:.2f} MB of C"
    if c.get("code") == "fast":
        return f"compiled fast ({c.get('compiler')}, {size}, {c.get('compile_s', 0):.2f} s{after})"
    size += f", {' '.join(c.get('flags') or [])}"
    if c.get("switched_from"):
        return (f"compiled ({size}, built in the background during this plan; the attempts before it ran "
                f"{c['switched_from']})")
    return f"compiled ({size}" + (", cached)" if settings.get("jit_cached")
                                  else f", {c.get('compile_s', 0):.1f} s)")
