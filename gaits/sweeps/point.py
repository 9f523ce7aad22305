"""One grid point as data, and the one place where the sweep meets the planner.

A worker gets a :class:`PointJob` — the scene as TOML text (or a built-in name), the point's
``[task]`` table, its parameter values and, for a warm start, the parent point's trajectory
(t, q, q̇, u as plain lists, :func:`warm_data`) — and answers with a plain dict
(:func:`solve_point`). Nothing live (no
CasADi object, no model) crosses a process boundary; each worker derives its model and builds
its solver itself, the derivation coming from the content-hash cache
(:mod:`nhgait.dynamics.numerics.cache`) after the first time.

Everything that knows the planner's API is in :func:`describe_case` (driver side: the scene
and base task as data) and :func:`_plan_point` (worker side: one point, warm or cold). The
worker uses the planner's building blocks (``prepare``, ``warm_start``, the guesses,
``solve_from_guesses``, ``continuation``, ``verified_gait``)
rather than ``plan(guess=...)`` itself, to keep one built solver per structure across points
and to build the cold candidates only when a warm start fails.
"""
from __future__ import annotations

import copy
import hashlib
import importlib
import math
import os
import socket
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from nhgait.dynamics.memo import LruMemo

from ..planning.search import WARM_IPOPT as _WARM
from .grid import GridPoint

__all__ = ["SceneData", "SweepCase", "PointJob", "point_task", "solve_point", "describe_case", "warm_data",
           "scene_of", "prepare_worker", "WARM_IPOPT"]


@dataclass(frozen=True)
class SceneData:
    """A scene as data: a built-in name, or a scene file's TOML text and where it came from."""

    source: str
    builtin: str | None = None
    text: str | None = None

    @property
    def sha256(self) -> str:
        return hashlib.sha256((self.builtin or "").encode() + b"\0" + (self.text or "").encode()).hexdigest()

    def describe(self) -> dict:
        return {"source": self.source, "builtin": self.builtin, "sha256": self.sha256}


@dataclass(frozen=True, eq=False)
class SweepCase:
    """What every point of a sweep shares, as picklable data.

    ``task``: the base ``[task]`` table; ``params``: the scene's parameter values (name →
    value); ``label``: "<system>/<task>"; ``units``: the scene's ``[units]`` table;
    ``shape``: the two coordinates of the shape-loop plots (the shape variables, completed by
    the last fiber coordinate when the shape is one-dimensional, e.g. the unicycle's (θ, φ));
    ``coordinates``, ``inputs``: the system's names; ``options``: planner options (``transcription``,
    ``solver``, ``jit``, ``time_limit``: seconds per point, :func:`point_budget`).
    """

    scene: SceneData
    task: dict
    params: dict
    label: str = ""
    units: dict = field(default_factory=dict)
    shape: tuple = ()
    coordinates: tuple = ()
    inputs: tuple = ()
    options: dict = field(default_factory=dict)

    def describe(self) -> dict:
        return {"scene": self.scene.describe(), "task": self.task, "params": self.params, "label": self.label,
                "options": self.options, "shape": list(self.shape), "coordinates": list(self.coordinates),
                "inputs": list(self.inputs)}


@dataclass(frozen=True, eq=False)
class PointJob:
    """One point for a worker: ``task`` and ``params`` are the point's own (base + axis values);
    ``warm`` is the parent's :func:`warm_data` (None: cold start from the planner's guesses)."""

    case: SweepCase
    point_id: str
    task: dict
    params: dict
    warm: dict | None = None
    warm_from: str | None = None


# ----------------------------------------------------------------------------- task values
def point_task(task: Mapping, params: Mapping, point: GridPoint) -> tuple[dict, dict]:
    """(``[task]`` table, parameter values) of ``point``: the base with each axis value set.

    ``horizon`` keeps a free horizon's bounds (the value becomes its initial guess);
    ``objective.<w>`` turns a one-word objective into a table of weights.
    """
    task = copy.deepcopy(dict(task))
    params = dict(params)
    for name, value in point.values:
        table, _, key = name.partition(".")
        if table == "params":
            params[key] = float(value)
        elif name == "horizon" and isinstance(task.get("horizon"), Mapping):
            task["horizon"] = {**task["horizon"], "initial": float(value)}
        elif name == "intervals":
            task["intervals"] = int(round(value))
        elif not key:
            task[name] = float(value)
        else:
            current = task.get(table, {})
            if isinstance(current, str):             # objective = "effort"
                current = {current: 1.0}
            task[table] = {**dict(current or {}), key: float(value)}
    return task, params


# ----------------------------------------------------------------------------- warm starts
def warm_data(solution: Mapping) -> dict:
    """The part of a solution dict (``Solution.to_dict()``, solution.json) a warm start needs:
    ``trajectory.t``, ``q`` and ``q̇`` (coordinate order) and ``u``, and the names of the
    coordinates and inputs — free of the state, so the planner's
    :func:`~nhgait.gaits.planner.warm_start` maps it to any model's own state."""
    tr = solution["trajectory"]
    return {"trajectory": {k: tr[k] for k in ("t", "q", "qdot", "u", "coordinates", "inputs") if k in tr}}


# ----------------------------------------------------------------------------- the worker
def _nan(value) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return math.nan
    return out


def solve_point(job: PointJob) -> dict:
    """Solve one point (in a worker process); never raises for bad input or a failed solve.

    Returns a dict: ``id``, ``success``, ``status``, ``message``, ``objective``,
    ``iterations``, ``solve_time_s``, ``wall_time_s``, ``verification_error``,
    ``constraint_violation``, ``start``, ``worker``, ``solution`` (JSON-able full solution,
    or None) and ``warm`` (:func:`warm_data`, or None); or, for input the planner rejects,
    ``input_error`` (the message; the sweep stops: every point would fail the same way).
    """
    from nhgait.dynamics.errors import ModelError
    t0 = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    try:
        out = _plan_point(job)
    except ModelError as exc:
        return {"id": job.point_id, "input_error": str(exc), "worker": worker}
    return {"id": job.point_id, "worker": worker, "wall_time_s": time.perf_counter() - t0, **out}


def solve_chain(solve, jobs, warm_start: bool = True) -> list:
    """Solve a continuation chain (each job the child of the one before) in order, in one task.

    A job after the first is warm-started from the previous point's solution when that one
    succeeded, else from its own ``warm`` (the nearest solved ancestor's, set by the driver).
    ``solve`` is the point solver (:func:`solve_point`). Returns the answers in order, each with
    its ``warm_from``; stops after an answer with ``input_error``. One task for several points
    divides a distributed back end's fixed cost per task among them.
    """
    answers, previous = [], None
    for job in jobs:
        if (warm_start and previous is not None and previous.get("success")
            and previous.get("warm") is not None):
            job = replace(job, warm=previous["warm"], warm_from=previous["id"])
        answer = solve(job)
        answer["warm_from"] = job.warm_from
        answers.append(answer)
        if "input_error" in answer:
            break
        previous = answer
    return answers


def _outcome(s, start: str) -> dict:
    """The plain-data answer of a verified solution (success needs the deciding verification
    too: :func:`~nhgait.gaits.verification.gait_check.passed`)."""
    from ..verification.gait_check import passed
    verified = passed(s)
    return {"success": bool(s.success) and verified, "status": str(s.status), "message": str(s.message),
            "objective": _nan(s.objective), "iterations": int(s.iterations),
            "solve_time_s": _nan(s.solve_time_s), "verification_error": _nan(s.verification_error),
            "constraint_violation": _nan(s.constraint_violation), "start": start,
            "solution": s.to_dict()}


# ---- the planner adapter (the only code that knows the planner's API) -------------------
def _scene_data(system) -> SceneData:
    from pathlib import Path

    from nhgait.dynamics.errors import ModelError
    if isinstance(system, SceneData):
        return system
    if not isinstance(system, (str, Path)):
        raise ModelError(["a sweep's system is a scene file or a built-in scene name, got "
                          f"{type(system).__name__} (a sweep sends the scene to its workers as data)"],
                         title="invalid sweep")
    from nhgait.dynamics.derivation.input.textfiles import names_a_file, read_text_file
    path = Path(system)
    if names_a_file(path) or path.suffix == ".toml":
        return SceneData(str(path), text=read_text_file(path, "scene file", title="cannot read the scene"))
    return SceneData(f"built-in scene {system}", builtin=str(system))


def scene_of(data: SceneData):
    """What the planner's ``resolve`` takes: the built-in name, or the Scene parsed from the text."""
    if data.builtin is not None:
        return data.builtin
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    return scene_from_text(data.text, data.source)


#: the planner options of a sweep (``sweep(options=...)``; ``--time-limit`` is ``time_limit``)
OPTIONS = ("transcription", "solver", "jit", "time_limit")


def option_problems(options) -> list:
    """What is wrong with a sweep's planner ``options`` (None or a mapping of :data:`OPTIONS`):
    an unknown name (once silently ignored), then the values as a plan's
    (:class:`~..plan_options.PlanOptions`), and a solver a point can run (one: no ``auto``)."""
    from nhgait.dynamics.suggestions import known_names

    from ..planning.options import PlanOptions
    if options is None:
        return []
    if not isinstance(options, Mapping):
        return [f"options = {options!r} must be a mapping ({', '.join(OPTIONS)})"]
    problems = [f"options: unknown option {name!r}" + known_names(str(name), OPTIONS, label="options")
                for name in options if name not in OPTIONS]
    known = {k: v for k, v in options.items() if k in OPTIONS}
    problems += [f"options: {p}" for p in PlanOptions.collect(**known).problems]
    if known.get("solver") == "auto":
        problems.append("options: solver = 'auto': a sweep point runs one solver: use 'ipopt' or 'fatrop'")
    return problems


def describe_case(system, task=None, *, overrides=(), params=None, options=None) -> SweepCase:
    """The :class:`SweepCase` of a scene (file, built-in name) and a task (None: the scene's
    ``[task]``; a built-in gait name; a ``[task]`` dict), with ``--set`` overrides and
    parameter values; the planner checks the task on the model here, before any point runs."""
    from nhgait.dynamics import derive

    from ..planning.arguments import check_params
    from ..tasks.sources import resolve
    data = _scene_data(system)
    resolved = resolve(scene_of(data), task, overrides=overrides)
    sys_ = resolved.scene.system
    check_params(sys_, dict(params) if params else None)      # as a plan's, before the derivation
    values = {**dict(sys_.parameters), **{k: float(v) for k, v in dict(params or {}).items()}}
    model = derive(sys_, "reduced")
    opts = {"jit": False, **dict(options or {})}
    return SweepCase(data, resolved.task.to_dict(), values, label=resolved.label,
                     units=_units(resolved, model),
                     shape=(tuple(model.shape) + tuple(reversed(model.fiber)))[:2],
                     coordinates=tuple(sys_.coordinates), inputs=tuple(sys_.inputs), options=opts)


def _units(resolved, model) -> dict:
    """Units of the coordinates, their rates and the inputs by the planner's plot rules (the
    scene's ``[units]`` first, then rad/m from the model), and every ``[units]`` entry."""
    from ..figures.plots import FigureContext, unit
    sys_ = model.system
    ctx = FigureContext(sys_, dict(resolved.units), None, None, tuple(model.fiber), tuple(model.shape))
    names = [*sys_.coordinates, *(f"{c}_dot" for c in sys_.coordinates), *sys_.inputs]
    found = {name: unit(ctx, name) for name in names}
    return {**{k: str(v) for k, v in resolved.units.items()}, **{k: v for k, v in found.items() if v}}


def check_case(case: SweepCase, job: PointJob) -> None:
    """Raise the planner's error when ``job``'s task or parameters do not fit the model (run
    once by the driver on the centre point, so bad input stops the sweep before it starts)."""
    from ..planner import prepare
    from ..tasks.sources import resolve
    prepare(resolve(scene_of(case.scene), job.task), params=job.params)


#: this worker process's built solvers by structure (scene, parameters, task shape, options):
#: (derived model, specialised model, OCPSolver), the least recently used dropped beyond 8 —
#: a cache, never a source of results
SOLVERS = LruMemo("built NLP solvers of this worker by structure", size=8)


def _structure(task: Mapping) -> str:
    """The task with the values that only enter the NLP's bounds (initial, final, path and
    control bounds) replaced by their names: points with equal structure share one NLP."""
    import json
    shape = {}
    for key, value in task.items():
        if key in ("initial", "final", "bounds") and isinstance(value, Mapping):
            shape[key] = sorted(value)
        elif key == "control_bounds":
            shape[key] = sorted(value) if isinstance(value, Mapping) else "one bound"
        elif key not in ("name", "description"):
            shape[key] = value
    return json.dumps(shape, sort_keys=True, default=str)


#: Ipopt settings of a sweep point's warm start (:data:`nhgait.gaits.planning.search.WARM_IPOPT`); a warm
#: start that fails falls back to the planner's guesses.
WARM_IPOPT = _WARM


def _solver_for(job: PointJob, *, warm: bool = False):
    """(derived model, (stated problem, problem solved), OCPSolver, plan) of ``job``, reusing
    this process's solver of the same structure (``OCPSolver.with_problem``: same NLP
    functions, new bounds); ``warm``: the solver with :data:`WARM_IPOPT` (Ipopt only). A new
    solver gets the planner's time limit per attempt
    (:func:`~nhgait.gaits.planning.time_limits.attempt_limited`)."""
    from nhgait.ocp import OCPSolver, SolverOptions

    from ..planner import prepare, state_problem
    from ..planning.time_limits import attempt_limited
    from ..tasks.sources import resolve
    case = job.case
    resolved = resolve(scene_of(case.scene), job.task)
    warm = warm and case.options.get("solver", "ipopt") == "ipopt"
    key = (case.scene.sha256, tuple(sorted(job.params.items())), _structure(job.task),
           tuple(sorted(case.options.items())), warm)
    if key in SOLVERS:
        model, specialised, solver = SOLVERS.get(key, None)
        solver.adopt_optimised()      # a long-lived worker: the optimised library once it has landed
        stated, problem, _ = state_problem(resolved.task, specialised, resolved.scene, params=job.params,
                                           name=resolved.label)
        return model, (stated, problem), solver.with_problem(problem), resolved
    prepared = prepare(resolved, params=job.params)
    solver = OCPSolver(prepared.problem, case.options.get("transcription"),
                       SolverOptions(jit=case.options.get("jit"), solver=case.options.get("solver", "ipopt"),
                                     ipopt=dict(WARM_IPOPT) if warm else {}))
    solver = attempt_limited(solver)
    SOLVERS.get(key, lambda: (prepared.model, prepared.specialised, solver))
    return prepared.model, (prepared.stated, prepared.problem), solver, resolved


def prepare_worker(job: PointJob) -> bool:
    """Build this worker's warm-start solver for ``job``'s structure (submitted by the driver
    to the other workers while the centre point is solved cold, so that they start at once)."""
    importlib.import_module("scipy.integrate")     # the verification's integrator, imported now
    _solver_for(job, warm=True)
    return True


def point_budget(job: PointJob):
    """The time budget of one point (:func:`~nhgait.gaits.planning.time_limits.budget_for`): the sweep's
    ``time_limit`` option (``--time-limit``), else the task's ``time_limit``, else the planner's
    default for the robot's size."""
    from ..planning.time_limits import budget_for
    return budget_for(len(job.case.coordinates), job.case.options.get("time_limit"),
                      job.task.get("time_limit"), given_as="--time-limit per point")


def _plan_point(job: PointJob) -> dict:
    """Warm start from the parent when there is one; else (or when it fails) the planner's own
    guesses and continuation; then the planner's verification in momentum coordinates — all
    within the point's budget (:func:`point_budget`): a point that runs out is a failure with
    status ``Time_Limit_Exceeded`` and the closest point reached."""
    from nhgait.ocp.budget import BudgetSpent
    budget = point_budget(job)
    reached: dict = {"start": "cold", "spent": 0}
    try:
        return _solve_within(job, budget, reached)
    except BudgetSpent as exc:
        return _out_of_time(exc.overrun, reached)


def _solve_within(job: PointJob, budget, reached: dict) -> dict:
    from ..planning.guesses import candidates
    from ..planning.search import solve_attempts, solve_with_fallbacks
    from ..planning.warm_start import warm_start
    from ..verification.gait_check import GaitReference, unsolved, verified_gait
    solution = None
    if job.warm is not None:
        with budget.stage("the derivation and the NLP set-up"):
            model, (stated, problem), solver, resolved = _solver_for(job, warm=True)
        guess = warm_start(job.warm, problem, f"warm start from point {job.warm_from}")
        solution, = solve_attempts(solver, [guess], budget=budget)
        reached.update(closest=solution, spent=int(solution.iterations),
                       start="warm" if solution.success else "cold after warm failed")
    if solution is None or not solution.success:
        with budget.stage("the derivation and the NLP set-up"):
            model, (stated, problem), solver, resolved = _solver_for(job)
        with budget.stage("the solves", interrupt=False):
            guesses = candidates(problem)
            search = solve_with_fallbacks(solver, guesses, budget=budget)
            reached["spent"] += sum(a.iterations for a in search.attempts)
            solution = search.solution if search.solution is not None else search.closest
            reached["closest"] = solution if solution is not None else reached.get("closest")
        if solution is None:           # every candidate skipped by its screening
            solution = unsolved(problem, guesses.first_skipped)
    with budget.stage("verification"):
        solution = verified_gait(solution, GaitReference(model, stated, resolved, job.params))
    out = _outcome(solution, reached["start"])
    return {**out, "warm": warm_data(out["solution"]) if out["success"] else None,
            "total_iterations": reached["spent"]}


def _out_of_time(overrun, reached: dict) -> dict:
    """The answer of a point whose budget ran out: a failure naming the budget and the phase,
    with the closest point reached (in the coordinates it was solved in) when there is one."""
    closest = reached.get("closest")
    message = " ".join(overrun.lines("--time-limit SECONDS (per point)"))
    nan = math.nan
    return {"success": False, "status": "Time_Limit_Exceeded", "message": message,
            "objective": _nan(closest.objective) if closest is not None else nan,
            "iterations": int(closest.iterations) if closest is not None else 0, "solve_time_s": nan,
            "verification_error": nan,
            "constraint_violation": _nan(closest.constraint_violation) if closest is not None else nan,
            "start": reached["start"], "solution": closest.to_dict() if closest is not None else None,
            "warm": None, "total_iterations": reached["spent"]}
