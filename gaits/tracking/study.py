"""A tracking study, ``nhgait track``: :func:`track` plans (or reads a ``solution.json``), then
re-simulates the plan on the general model with the parameters changed (``mismatch``: name →
factor) and with initial-state and input noise, open loop and with the plan's feedback
(:mod:`nhgait.gaits.verification.feedback`), for K samples (:mod:`.runs`; in this process, or on the
sweep back ends — a process pool or Dask — when K is large or a back end is named), and writes
``tracking.json`` and the figures (:mod:`.plots`).

Like ``nhgait plan``: the output directory is checked before any work
(:func:`~nhgait.gaits.files.outputs.output_directory`), the files are written whole or not at all
(:func:`~nhgait.gaits.files.outputs.staged`) and a write that fails puts tracking.json in a fallback
folder (:func:`~nhgait.gaits.files.outputs.rescue`, ``unwritten`` says where). The study runs within
one time budget (:func:`~nhgait.gaits.planning.time_limits.budget_for`: ``time_limit``, else the task's,
else the planner's default for the robot's size), shared by the plan and the samples; samples
that run out of it end the study as a failure whose tracking.json summarises the samples done.

How the feedback acts on the real robot: the plan and its gains live in the planner's velocity
coordinates z = (q, y); the robot (the general model, momentum coordinates, the changed
parameters) is measured as (q, q̇) and the controller computes z = σ(q, q̇) with the *nominal*
parameters (the specialised model's state map) — what a controller on the robot would do.
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .request import TrackingOptions, parse_mismatch, request_problems
from .runs import LOOPS, Noise, TrackingCase, run_samples

__all__ = ["track", "TrackingResult", "TrackingOptions", "parse_mismatch", "summarise", "summary_lines",
           "Noise", "SERIAL_SAMPLES"]

#: studies of at most this many samples run in this process unless a back end is named
SERIAL_SAMPLES = 24


@dataclass(kw_only=True, frozen=True, eq=False)
class TrackingResult:
    """What :func:`track` produced: ``report`` (the content of tracking.json), ``samples`` (the
    answers of :func:`~.tracking_runs.run_samples`, the noise-free run first), ``files``,
    ``timings`` (seconds per phase) and the ``plan`` (a PlanResult, or None when read from a file)."""

    label: str
    report: dict
    samples: tuple = field(repr=False, default=())
    files: tuple = ()
    timings: dict = field(default_factory=dict)
    plan: object = field(repr=False, default=None)
    overrun: object = None            # where the time budget ran out (an Overrun), else None
    unwritten: str = ""               # what could not be written, and where the report went instead

    @property
    def success(self) -> bool:
        """The study ran to its end and every run of every sample reached the end of the plan."""
        return bool(self.report.get("success")) and self.overrun is None


def _plan_data(plan_file, system):
    """The content of a ``solution.json`` to track (one with feedback, planned for ``system``'s
    robot: its coordinates and inputs), or None. One ProblemError lists every problem."""
    from nhgait.ocp import ProblemError

    from ..files.solution_file import file_robot_problems, read_solution
    from ..tasks.sources import scene_of
    if plan_file is None:
        return None
    data = read_solution(plan_file)             # a file that is not a solution: ModelError
    scene, name = scene_of(system)
    problems = file_robot_problems(data, scene.system.coordinates, scene.system.inputs, name, str(plan_file))
    if not data.get("feedback") or "task" not in data:
        problems.append(f"{plan_file} holds no feedback (a failed plan, or one written before nhgait "
                        "stored feedback gains): plan it again")
    elif not problems:                          # another robot's parameters and gains: said above
        problems = _plan_file_problems(data, plan_file)
    if problems:
        raise ProblemError(problems, title="invalid plan file")
    return data


def _plan_file_problems(data: dict, plan_file) -> list:
    """What keeps ``data`` (a solution.json with feedback) from being tracked: its parameter
    values and its feedback must read back."""
    from nhgait.ocp.feedback import Feedback
    problems = []
    params = (data.get("problem") or {}).get("params") if isinstance(data.get("problem"), dict) else None
    if not (isinstance(params, dict) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                             for v in params.values())):
        problems.append(f"{plan_file}: problem.params must map each parameter name to its value")
    try:
        fb = Feedback.from_dict(data["feedback"])
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        return problems + [f"{plan_file}: its feedback cannot be read ({type(exc).__name__}: {exc})"]
    N, nz, nu = len(fb.t) - 1, len(fb.state_names), len(fb.control_names)
    shapes = {"gains": (fb.gains, (N, nu, nz)), "reference": (fb.states, (nz, N + 1)),
              "controls": (fb.controls, (nu, N)), "rates": (fb.rates, (N, 2, nz))}
    problems += [f"{plan_file}: feedback.{name} has the shape {a.shape}, its t and names need {shape}"
                 for name, (a, shape) in shapes.items() if a.shape != shape]
    if N < 1 or not all(np.all(np.isfinite(a)) for a, _ in shapes.values()) or np.any(np.diff(fb.t) <= 0):
        problems.append(f"{plan_file}: the feedback needs increasing times and finite numbers")
    return problems


def _planned(system, task, data, options: TrackingOptions, progress):
    """(label, task table, nominal parameters, Feedback dict, units, PlanResult or None);
    the plan solved with ``options.plan`` (its time limit the planner's rule; it counts from
    the plan's start)."""
    from ..planner import plan
    from ..tasks.sources import resolve
    if data is not None:
        resolved = resolve(system, data["task"])
        return (data.get("system", resolved.label), data["task"], dict(data["problem"]["params"]),
                data["feedback"], dict(resolved.units), None)
    result = plan(system, task, overrides=options.overrides, progress=progress, options=options.plan)
    if not result.success:
        raise _PlanFailed(result)
    p = result.solution.problem
    params = dict(zip(p.model.numeric.param_names, map(float, p.params), strict=True))
    return (result.label, result.task.to_dict(), params, result.solution.feedback.to_dict(),
            dict(result.plan.units), result)


class _PlanFailed(Exception):
    """The plan to track did not succeed (exit status 1)."""

    def __init__(self, result):
        super().__init__("the plan did not succeed")
        self.result = result


def track(system, task=None, *, out_dir=None, progress=None, options: TrackingOptions | None = None,
          **values) -> TrackingResult:
    r"""A tracking study (module docstring).

    Parameters
    ----------
    system : scene file or built-in name; task : as for :func:`~nhgait.gaits.planner.plan`
    out_dir : write tracking.json (and the plan's solution.json) and the figures there (checked
        before any work)
    progress : a :class:`~nhgait.dynamics.progress.Progress` (None: silent)
    options : the study, a :class:`~.request.TrackingOptions` — ``overrides`` (``--set``
        strings of the task), ``mismatch`` (``params.NAME=FACTOR`` strings or a mapping name →
        factor), ``samples`` (K), ``seed`` (of the noise), ``noise`` (:class:`Noise`),
        ``plan_file`` (a ``solution.json`` with its feedback, tracked instead of planning),
        ``scheduler`` and ``workers`` (the sweep back ends,
        :func:`~nhgait.gaits.sweeps.backends.make_backend`; both None and K ≤
        :data:`SERIAL_SAMPLES`: in this process) and ``plan``: how the plan is solved, the
        planner's :class:`~nhgait.gaits.planning.options.PlanOptions`, whose ``time_limit`` is
        the seconds the whole study may take (module docstring; ``inf``: unlimited)
    \*\*values : the same options as keywords, on top of ``options`` — also a plan option by its
        name (``time_limit=60``, ``intervals=40``; ``workers`` is the samples')

    Notes
    -----
    Every problem of the request is one :class:`~nhgait.ocp.ProblemError`, raised before planning.
    """
    from nhgait.dynamics.progress import Progress
    from nhgait.ocp.budget import BudgetSpent

    from ..files.outputs import output_directory
    from ..sweeps.point import describe_case
    started = time.monotonic()
    progress = progress or Progress.silent()
    if out_dir is not None:
        out_dir = output_directory(out_dir, "out_dir")
    options, early = _collected(task, options, values)
    data, resolved = _read_request(system, task, options, early)
    scene_system = resolved.scene.system
    factors, budget = _checked_request(early, options, scene_system,
                                       lambda: _budget(scene_system, resolved.task, options, started))
    progress.note(f"time budget of the study (the plan and the samples): {budget.describe()}; "
                  "--time-limit SECONDS to change it")
    timings, t0 = {}, time.perf_counter()
    try:
        label, task_table, params, feedback, units, planned = _planned(system, task, data, options, progress)
    except _PlanFailed as failed:
        return _failed_plan(failed.result, out_dir)
    timings["plan_s"] = time.perf_counter() - t0
    robot = _robot(params, factors, scene_system)
    base = describe_case(system, task_table, params=params)
    key = hashlib.sha256(json.dumps([base.scene.sha256, task_table, params, robot, feedback["gains"]],
                                    sort_keys=True, default=str).encode()).hexdigest()
    samples = options.samples
    case = TrackingCase(scene=base.scene, task=base.task, params=params, robot=robot, feedback=feedback,
                        noise=options.noise, seed=int(options.seed), key=key)
    t0, answers, overrun = time.perf_counter(), [], None
    try:
        _run(case, options, progress, budget, answers)
    except BudgetSpent as exc:
        overrun = exc.overrun
        progress.note(f"  the time budget of {overrun.seconds:g} s ran out during {overrun.phase}")
    timings["samples_s"] = time.perf_counter() - t0
    if overrun is not None and len(answers) < 2:      # not one sample: nothing to summarise
        report = {"system": label, "success": False, "samples": 0, "samples_requested": int(samples)}
    else:
        report = summarise(answers, case, label, factors, _context_for_report(scene_system, case, units))
        report["samples_requested"] = int(samples)
    if overrun is not None:
        report.update(success=False, message=f"the time budget ran out after {len(answers[1:])} of {samples} "
                                             "samples", time_budget=_overrun_lines(overrun))
    report["timings"] = {k: round(v, 3) for k, v in timings.items()}
    result = TrackingResult(label=label, report=report, samples=tuple(answers), files=(), timings=timings,
                            plan=planned, overrun=overrun)
    if out_dir is not None:
        result = _written(result, out_dir, units, progress)
    return result


class _Collected(NamedTuple):
    options: TrackingOptions     #: the study's options
    problems: list               #: the problems of its values that need no scene


def _collected(task, options, values: dict) -> _Collected:
    """The study's :class:`~.request.TrackingOptions` and the problems of its values that need
    no scene (:func:`~.request.request_problems`, with the plan options'); an unknown name: one
    ProblemError at once."""
    from nhgait.ocp import ProblemError
    options, problems = TrackingOptions.collect(options, **values)
    if options is None:
        raise ProblemError(problems, title="invalid tracking study")
    return _Collected(options, problems + request_problems(options.samples, options.seed, options.noise,
                                                           plan_file=options.plan_file, task=task,
                                                           overrides=options.overrides))


def _budget(system, task, options: TrackingOptions, started: float):
    """The study's :class:`~nhgait.ocp.budget.Budget`: the plan options' ``time_limit``, else
    the task's, else the planner's default for the robot's size."""
    from ..planning.time_limits import budget_for
    return budget_for(len(system.coordinates), options.plan.time_limit, task.time_limit, given_as=GIVEN,
                      started=started)


#: how a budget given by the caller is named in the progress output and in failures
GIVEN = "--time-limit / track(time_limit=...)"


def _overrun_lines(overrun) -> list:
    """What ran out, where, and what to change (a study's version of ``Overrun.lines``)."""
    return [overrun.lines()[0],
            "to give it more time: --time-limit SECONDS ('inf': unlimited); to need less: "
                                "fewer --samples, or more --workers"]


def _read_request(system, task, options: TrackingOptions, problems: list) -> tuple:
    """(the plan file's content or None, the resolved scene and task); when they cannot be read,
    one ProblemError that lists ``problems`` (the rest of the request's) as well."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.ocp import ProblemError

    from ..tasks.sources import resolve
    try:
        data = _plan_data(options.plan_file, system)
        resolved = (resolve(system, task, overrides=options.overrides) if data is None
                    else resolve(system, data["task"]))
    except ModelError as exc:
        if not problems:
            raise
        raise ProblemError([*problems, *exc.problems], title="invalid tracking study") from exc
    return data, resolved


def _checked_request(problems: list, options: TrackingOptions, system, make_budget) -> tuple:
    """(the mismatch factors, the study's budget from ``make_budget()``); one ProblemError for
    every problem of the request — ``problems`` (:func:`_collected`'s), the mismatch's, the
    budget's and the back end's — before planning."""
    from nhgait.ocp import ProblemError

    from ..sweeps.backends import backend_problems
    problems = [*problems, *backend_problems(options.scheduler, options.workers)]
    factors, budget = {}, None
    try:
        factors = parse_mismatch(options.mismatch, system.parameters)
    except ProblemError as exc:
        problems += list(exc.problems)
    try:
        budget = make_budget()
    except ProblemError as exc:              # a time_limit the plan options' check named already: once
        problems += [p for p in exc.problems if p not in problems]
    if problems:
        raise ProblemError(problems, title="invalid tracking study")
    return factors, budget


def _robot(params: dict, factors: dict, system) -> dict:
    """The robot's parameter values, checked like any parameter values (a singular metric …)."""
    from nhgait.ocp import ProblemError
    robot = {name: value * factors.get(name, 1.0) for name, value in params.items()}
    problems = system.parameter_problems(robot, label="the mismatched params")
    if problems:
        raise ProblemError(problems, title="invalid mismatch")
    return robot


def _failed_plan(result, out_dir) -> TrackingResult:
    if result.solution is None:
        why = "no attempt was made"
    else:
        why = result.solution.status if result.overrun is None else "time budget spent"
    report = {"system": result.label, "success": False,
              "message": f"the plan did not succeed ({why}); nothing to track",
              "diagnosis": list(result.diagnosis)}
    failed = TrackingResult(label=result.label, report=report, samples=(), files=(), timings={}, plan=result,
                            overrun=result.overrun)
    return failed if out_dir is None else _written(failed, out_dir, None, None)


def _run(case: TrackingCase, options: TrackingOptions, progress, budget, answers: list) -> None:
    """The noise-free run (index −1, here: it compiles the closed loop, which the workers then
    load from the cache) and the K = ``options.samples`` samples (in this process or on the back
    end of ``options.scheduler``, ``options.workers``), appended to ``answers`` as they come,
    within ``budget`` (:class:`~nhgait.ocp.budget.BudgetSpent` when it runs out; ``answers``
    then holds what was done)."""
    from ..sweeps.backends import make_backend
    samples, scheduler, workers = int(options.samples), options.scheduler, options.workers
    with budget.stage("the noise-free run"), \
            progress.phase("the noise-free run, open and closed loop (compiles the closed loop once)"):
        answers += run_samples(case, [-1])
    indices = list(range(samples))
    if scheduler is None and workers is None and samples <= SERIAL_SAMPLES:
        with budget.stage("the samples"), progress.phase(f"{samples} samples in this process"):
            for i in indices:
                answers += run_samples(case, [i])
                if (i + 1) % 8 == 0 or i + 1 == samples:
                    progress.note(f"  {i + 1}/{samples} samples")
        return
    backend = make_backend(scheduler, workers)
    with budget.stage("the samples"), backend, progress.phase(f"{samples} samples on {backend.describe()}"):
        size = max(1, math.ceil(samples / (2 * max(1, backend.workers))))
        futures = [backend.submit(run_samples, case, indices[i:i + size]) for i in range(0, samples, size)]
        for future in futures:
            answers += future.result()
            progress.note(f"  {len(answers) - 1}/{samples} samples")


def _context_for_report(system, case, units) -> dict:
    """Names and units the report needs: the plan's state names and their units (the scene's
    ``[units]``, else the plots' rules), the position's unit, the feedback's weights."""
    from nhgait.ocp.feedback import Feedback

    from ..figures.plots import FigureContext, unit
    fb = Feedback.from_dict(case.feedback)
    ctx = FigureContext(system, dict(units), None, None, (), ())
    frame = tuple(system.planar_frame or ())[:1] or tuple(system.coordinates)[:1]
    return {"state_names": fb.state_names, "units": {name: unit(ctx, name) for name in fb.state_names},
            "position_unit": unit(ctx, frame[0]),
            "weights": fb.weights.to_dict(fb.state_names, fb.control_names)}


def _stats(values) -> dict:
    a = np.asarray(values, dtype=float)
    ok = a[np.isfinite(a)]
    if not ok.size:
        return {"median": None, "max": None, "mean": None}
    return {"median": float(np.median(ok)), "max": float(ok.max()), "mean": float(ok.mean())}


def summarise(answers, case: TrackingCase, label: str, factors: dict, context: dict) -> dict:
    """The content of tracking.json from the answers of the runs (the noise-free run first)."""
    names, units, length = context["state_names"], context["units"], context["position_unit"]
    free, runs = answers[0], answers[1:]
    report = {"system": label, "samples": len(runs), "seed": case.seed, "mismatch": factors,
              "params": {"nominal": case.params, "robot": case.robot}, "noise": case.noise.to_dict(),
              "position_unit": length, "feedback_weights": context["weights"]}
    for loop in LOOPS:
        rows = [a[loop] for a in runs]
        finals = [r["final_position_error"] for r in rows]
        rms, peak = np.array([r["state_rms"] for r in rows]), np.array([r["state_max"] for r in rows])
        failed = [r for r in rows if not r["success"]]
        report[loop] = {
            "final_position_error": {**_stats(finals), "unit": length, "samples": finals},
            "state_errors": {name: {"unit": units.get(name, ""), "rms_median": float(np.nanmedian(rms[:, i])),
                                    "rms_max": float(np.nanmax(rms[:, i])),
                                    "max": float(np.nanmax(peak[:, i]))}
                             for i, name in enumerate(names)},
            "saturation_time_s": _stats([r["saturation_time_s"] for r in rows]),
            "noise_free_final_position_error": free[loop]["final_position_error"],
            "failed": len(failed), "failures": sorted({r["message"] for r in failed})[:5]}
    open_median = report["open_loop"]["final_position_error"]["median"]
    closed_max = report["closed_loop"]["final_position_error"]["max"]
    report["closed_max_over_open_median"] = (closed_max / open_median if open_median
                                             and closed_max is not None
                                             else None)
    report["success"] = all(report[loop]["failed"] == 0 for loop in LOOPS)
    return report


def _dump(report: dict, path: Path) -> Path:
    path.write_text(json.dumps(report, indent=1, default=float))
    return path


def _written(result: TrackingResult, out: Path, units, progress) -> TrackingResult:
    """``result`` with its files written to ``out`` (:func:`_write_files`, staged); a write that
    fails puts tracking.json in a fallback folder and says so in ``unwritten``."""
    from dataclasses import replace

    from ..files.outputs import rescue, staged, write_failure
    try:
        return replace(result, files=tuple(staged(out, lambda folder: _write_files(result, folder,
                                                                                   units, progress))))
    except OSError as exc:
        failed = write_failure(exc, getattr(exc, "filename", None) or out)
    return replace(result, unwritten=f"{failed}; {rescue('tracking.json', result.report, 'tracking report')}")


def _write_files(result: TrackingResult, out: Path, units, progress) -> list:
    """tracking.json; the plan's solution.json when it was planned here; the figures when
    there are samples."""
    from .plots import write_tracking_figures
    files = [_dump(result.report, out / "tracking.json")]
    plan = result.plan
    if plan is not None and plan.solution is not None:
        extra = {"task": plan.task.to_dict(), "system": result.label, "success": plan.success,
                 "diagnosis": list(plan.diagnosis)}
        files.append(plan.solution.to_json(out / "solution.json", extra=extra))
    if "open_loop" in result.report and progress is not None:
        with progress.phase("write tracking.json and the figures"):
            files += write_tracking_figures(result, out, units=units)
    return files


def summary_lines(result: TrackingResult) -> list:
    """The lines ``nhgait track`` prints."""
    r = result.report
    if "open_loop" not in r:
        lines = [f"nhgait track {result.label}: FAILED — {r['message']}"]
        lines += [f"  {d}" for d in (*r.get("diagnosis", ()), *r.get("time_budget", ()))]
        return lines + _file_lines(result)
    unit = r["position_unit"]
    mism = ", ".join(f"{k} ×{v:g}" for k, v in r["mismatch"].items()) or "none"
    lines = [f"nhgait track {result.label}: {r['samples']} samples, mismatch {mism}, noise "
             f"{r['noise']['state']:g} (state) / {r['noise']['input']:g} (input) of scale, seed {r['seed']}"]
    for loop in LOOPS:
        f, s = r[loop]["final_position_error"], r[loop]["saturation_time_s"]
        lines.append(f"  {loop.replace('_', ' '):12s} final position error median "
                     f"{_num(f['median'])} {unit}, "
                     f"max {_num(f['max'])} {unit}; inputs at a bound {_num(s['median'])} s (median), "
                     f"{r[loop]['failed']} run(s) stopped early")
    ratio = r["closed_max_over_open_median"]
    lines.append(f"  closed-loop worst / open-loop median = {_num(ratio)}")
    if result.overrun is not None:
        lines += [f"  FAILED — {r['message']}"] + [f"  {line}" for line in r["time_budget"]]
    return lines + _file_lines(result)


def _file_lines(result: TrackingResult) -> list:
    lines = ["  files:", *(f"    {f}" for f in result.files)] if result.files else []
    return lines + ([f"  NOT WRITTEN: {result.unwritten}"] if result.unwritten else [])


def _num(value) -> str:
    return "—" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.4g}"
