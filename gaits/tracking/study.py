"""A tracking study, ``nhgait track``: :func:`track` plans (or reads a ``solution.json``), then
re-simulates the plan on the general model with the parameters changed (``mismatch``: name →
factor) and with initial-state and input noise, open loop and with the plan's feedback
(:mod:`nhgait.gaits.plan_feedback`), for K samples (:mod:`.runs`; in this process, or on the
sweep back ends — a process pool or Dask — when K is large or a back end is named), and writes
``tracking.json`` and the figures (:mod:`.plots`).

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

import numpy as np

from .runs import LOOPS, Noise, TrackingCase, run_samples

__all__ = ["track", "TrackingResult", "parse_mismatch", "summarise", "summary_lines",
           "Noise", "SERIAL_SAMPLES"]

#: studies of at most this many samples run in this process unless a back end is named
SERIAL_SAMPLES = 24


def parse_mismatch(items, parameters: dict) -> dict:
    """``["params.m=1.1", ...]`` → {"m": 1.1}: each named parameter multiplied by its factor
    on the simulated robot. One :class:`~nhgait.ocp.ProblemError` lists every problem."""
    from nhgait.dynamics.suggestions import known_names
    from nhgait.ocp import ProblemError
    out, problems = {}, []
    for item in items:
        key, sep, text = str(item).partition("=")
        prefix, _, name = key.strip().partition(".")
        if not sep or prefix != "params" or not name:
            problems.append(f"--mismatch {item!r}: write params.NAME=FACTOR (e.g. params.m=1.1)")
            continue
        if name not in parameters:
            problems.append(f"--mismatch {item!r}: unknown parameter {name!r}"
                            + known_names(name, tuple(parameters), label="parameters"))
            continue
        try:
            factor = float(text)
        except ValueError:
            factor = math.nan
        if not (math.isfinite(factor) and factor > 0):
            problems.append(f"--mismatch {item!r}: the factor must be a positive number, got {text!r}")
            continue
        out[name] = factor
    if problems:
        raise ProblemError(problems, title="invalid mismatch")
    return out


@dataclass(frozen=True, eq=False)
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

    @property
    def success(self) -> bool:
        """Every run of every sample reached the end."""
        return all(self.report[loop]["failed"] == 0 for loop in LOOPS)


def _plan_data(plan_file):
    """The content of a ``solution.json`` to track (one with feedback), or None."""
    from nhgait.ocp import ProblemError
    from ..planner import read_solution
    if plan_file is None:
        return None
    try:
        data = read_solution(plan_file)
    except (OSError, ValueError) as exc:
        raise ProblemError([f"--plan {plan_file}: {exc}"], title="invalid plan file") from None
    if not data.get("feedback") or "task" not in data:
        raise ProblemError([f"{plan_file} holds no feedback (a failed plan, or one written before nhgait "
                            "stored feedback gains): plan it again"], title="invalid plan file")
    return data


def _planned(system, task, overrides, data, progress):
    """(label, task table, nominal parameters, Feedback dict, units, drawing, PlanResult or None)."""
    from ..planner import plan
    from ..task_library import resolve
    if data is not None:
        resolved = resolve(system, data["task"])
        return (data.get("system", resolved.label), data["task"], dict(data["problem"]["params"]), data["feedback"],
                dict(resolved.units), resolved.drawing, None)
    result = plan(system, task, overrides=overrides, progress=progress)
    if not result.success:
        raise _PlanFailed(result)
    p = result.solution.problem
    params = dict(zip(p.model.numeric.param_names, map(float, p.params)))
    return (result.label, result.task.to_dict(), params, result.solution.feedback.to_dict(), dict(result.plan.units),
            result.plan.drawing, result)


class _PlanFailed(Exception):
    """The plan to track did not succeed (exit status 1)."""

    def __init__(self, result):
        super().__init__(result.solution.status)
        self.result = result


def track(system, task=None, *, overrides=(), mismatch=(), samples: int = 20, seed: int = 0, noise: Noise = Noise(),
          plan_file=None, scheduler=None, workers=None, out_dir=None, progress=None) -> TrackingResult:
    """A tracking study (module docstring).

    Parameters
    ----------
    system : scene file or built-in name; task : as for :func:`~nhgait.gaits.planner.plan`
    overrides : ``--set`` strings of the task; mismatch : ``params.NAME=FACTOR`` strings or a
        mapping name → factor; samples : K; seed : of the noise; noise : :class:`Noise`
    plan_file : a ``solution.json`` (with its feedback) to track instead of planning
    scheduler, workers : the sweep back ends (:func:`~nhgait.gaits.sweeps.backends.make_backend`);
        both None and K ≤ :data:`SERIAL_SAMPLES`: in this process
    out_dir : write tracking.json (and the plan's solution.json) and the figures there
    """
    from nhgait.dynamics.progress import Progress
    from ..sweeps.point import describe_case
    from ..task_library import resolve
    progress = progress or Progress.silent()
    data = _plan_data(plan_file)
    scene_system = (resolve(system, task, overrides=overrides) if data is None else
                    resolve(system, data["task"])).scene.system
    factors = _checked_request(samples, mismatch, scene_system)
    timings, t0 = {}, time.perf_counter()
    try:
        label, task_table, params, feedback, units, drawing, planned = _planned(system, task, overrides, data,
                                                                                 progress)
    except _PlanFailed as failed:
        return _failed_plan(failed.result, out_dir)
    timings["plan_s"] = time.perf_counter() - t0
    robot = _robot(params, factors, scene_system)
    base = describe_case(system, task_table, params=params)
    key = hashlib.sha256(json.dumps([base.scene.sha256, task_table, params, robot, feedback["gains"]],
                                    sort_keys=True, default=str).encode()).hexdigest()
    case = TrackingCase(base.scene, base.task, params, robot, feedback, noise, int(seed), key)
    t0 = time.perf_counter()
    answers = _run(case, int(samples), scheduler, workers, progress)
    timings["samples_s"] = time.perf_counter() - t0
    report = summarise(answers, case, label, factors, _context_for_report(scene_system, case, units))
    report["timings"] = {k: round(v, 3) for k, v in timings.items()}
    result = TrackingResult(label, report, tuple(answers), (), timings, planned)
    if out_dir is not None:
        result = _write(result, Path(out_dir), units, drawing, progress)
    return result


def _checked_request(samples, mismatch, system) -> dict:
    """The mismatch factors; one ProblemError for every problem of the request (before planning)."""
    from nhgait.ocp import ProblemError
    ok = isinstance(samples, int) and samples >= 1
    problems = [] if ok else [f"--samples must be an integer ≥ 1, got {samples}"]
    factors = {}
    try:
        factors = dict(mismatch) if isinstance(mismatch, dict) else parse_mismatch(mismatch, system.parameters)
    except ProblemError as exc:
        problems += list(exc.problems)
    if problems:
        raise ProblemError(problems, title="invalid tracking study")
    return factors


def _robot(params: dict, factors: dict, system) -> dict:
    """The robot's parameter values, checked like any parameter values (a singular metric …)."""
    from nhgait.ocp import ProblemError
    robot = {name: value * factors.get(name, 1.0) for name, value in params.items()}
    problems = system.parameter_problems(robot, label="the mismatched params")
    if problems:
        raise ProblemError(problems, title="invalid mismatch")
    return robot


def _failed_plan(result, out_dir) -> TrackingResult:
    report = {"system": result.label, "success": False,
              "message": f"the plan did not succeed ({result.solution.status}); nothing to track",
              "diagnosis": list(result.diagnosis)}
    files = ()
    if out_dir is not None:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        files = (_dump(report, Path(out_dir) / "tracking.json"),)
    return TrackingResult(result.label, report, (), files, {}, result)


def _run(case: TrackingCase, samples: int, scheduler, workers, progress) -> list:
    """The noise-free run (index −1, here: it compiles the closed loop, which the workers then
    load from the cache) and the K samples."""
    from ..sweeps.backends import make_backend
    with progress.phase("the noise-free run, open and closed loop (compiles the closed loop once)"):
        answers = run_samples(case, [-1])
    indices = list(range(samples))
    if scheduler is None and workers is None and samples <= SERIAL_SAMPLES:
        with progress.phase(f"{samples} samples in this process"):
            return answers + _in_chunks(lambda chunk: run_samples(case, chunk), indices, 8, progress)
    backend = make_backend(scheduler, workers)
    with backend, progress.phase(f"{samples} samples on {backend.describe()}"):
        size = max(1, math.ceil(samples / (2 * max(1, backend.workers))))
        futures = [backend.submit(run_samples, case, indices[i:i + size]) for i in range(0, samples, size)]
        done = 0
        for future in futures:
            answers += future.result()
            done = len(answers) - 1
            progress.note(f"  {done}/{samples} samples")
    return answers


def _in_chunks(fn, indices, size, progress) -> list:
    out = []
    for i in range(0, len(indices), size):
        out += fn(indices[i:i + size])
        progress.note(f"  {len(out)}/{len(indices)} samples")
    return out


def _context_for_report(system, case, units) -> dict:
    """Names and units the report needs: the plan's state names and their units (the scene's
    ``[units]``, else the plots' rules), the position's unit, the feedback's weights."""
    from nhgait.ocp.feedback import Feedback
    from ..plots import FigureContext, unit
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
                                    "rms_max": float(np.nanmax(rms[:, i])), "max": float(np.nanmax(peak[:, i]))}
                             for i, name in enumerate(names)},
            "saturation_time_s": _stats([r["saturation_time_s"] for r in rows]),
            "noise_free_final_position_error": free[loop]["final_position_error"],
            "failed": len(failed), "failures": sorted({r["message"] for r in failed})[:5]}
    open_median = report["open_loop"]["final_position_error"]["median"]
    closed_max = report["closed_loop"]["final_position_error"]["max"]
    report["closed_max_over_open_median"] = (closed_max / open_median if open_median and closed_max is not None
                                             else None)
    report["success"] = all(report[loop]["failed"] == 0 for loop in LOOPS)
    return report


def _dump(report: dict, path: Path) -> Path:
    path.write_text(json.dumps(report, indent=1, default=float))
    return path


def _write(result: TrackingResult, out: Path, units, drawing, progress) -> TrackingResult:
    from dataclasses import replace
    from .plots import write_tracking_figures
    out.mkdir(parents=True, exist_ok=True)
    files = [_dump(result.report, out / "tracking.json")]
    if result.plan is not None:
        extra = {"task": result.plan.task.to_dict(), "system": result.label, "success": result.plan.success}
        files.append(result.plan.solution.to_json(out / "solution.json", extra=extra))
    with progress.phase("write tracking.json and the figures"):
        files += write_tracking_figures(result, out, units=units)
    return replace(result, files=tuple(files))


def summary_lines(result: TrackingResult) -> list:
    """The lines ``nhgait track`` prints."""
    r = result.report
    if "open_loop" not in r:
        return [f"nhgait track {result.label}: FAILED — {r['message']}"] + [f"  {d}" for d in r.get("diagnosis", ())]
    unit = r["position_unit"]
    mism = ", ".join(f"{k} ×{v:g}" for k, v in r["mismatch"].items()) or "none"
    lines = [f"nhgait track {result.label}: {r['samples']} samples, mismatch {mism}, noise {r['noise']['state']:g} "
             f"(state) / {r['noise']['input']:g} (input) of scale, seed {r['seed']}"]
    for loop in LOOPS:
        f, s = r[loop]["final_position_error"], r[loop]["saturation_time_s"]
        lines.append(f"  {loop.replace('_', ' '):12s} final position error median {_num(f['median'])} {unit}, "
                     f"max {_num(f['max'])} {unit}; inputs at a bound {_num(s['median'])} s (median), "
                     f"{r[loop]['failed']} run(s) stopped early")
    ratio = r["closed_max_over_open_median"]
    lines.append(f"  closed-loop worst / open-loop median = {_num(ratio)}")
    if result.files:
        lines.append("  files:")
        lines += [f"    {f}" for f in result.files]
    return lines


def _num(value) -> str:
    return "—" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.4g}"
