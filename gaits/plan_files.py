"""A plan's files: the result first, then what is optional (issue 40).

* :func:`written` — ``solution.json`` (the solution, the task, the guesses tried and screened,
  success, diagnosis) and ``trajectory.csv``: the result, written before anything optional
  (:func:`write_outputs`), to a fallback when ``out`` fails (:func:`nhgait.gaits.files.outputs.rescue`).
* :func:`with_figures` — then the figures (:func:`nhgait.gaits.figures.plots.write_figures`) and, on
  request, the animation (:func:`write_figure_files`); a failure there leaves the result written.
* :func:`figure_modules` — the imports the figures' processes need, made while the solver
  attempts run (:func:`nhgait.ocp.supervision.supervise`'s ``meanwhile``).

Each file is written whole or not at all (:func:`nhgait.gaits.files.outputs.staged`). ``nhgait plan``
prints its result line between the two steps.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from .figures.convergence import write_convergence_figure
from .files.exports import write_trajectory_csv

__all__ = ["written", "with_figures", "write_outputs", "write_figure_files", "figure_modules"]


def written(result, out: Path, *, progress=None) -> object:
    """``result`` with its result files — solution.json and trajectory.csv — written to ``out``
    (:func:`write_outputs`), before anything optional (the figures: :func:`with_figures`). A
    write that fails (disk full, folder removed or made read-only meanwhile) does not lose the
    plan: solution.json goes to a fallback (:func:`nhgait.gaits.files.outputs.rescue`) and
    ``unwritten`` says what failed and where the solution is."""
    from .files.outputs import rescue, write_failure
    try:
        return replace(result, files=tuple(write_outputs(result, Path(out), progress=progress)))
    except OSError as exc:
        failed = write_failure(exc, getattr(exc, "filename", None) or out)
    if result.solution is None:
        return replace(result, unwritten=failed)
    data = {**result.solution.to_dict(), **_solution_extra(result)}
    return replace(result, unwritten=f"{failed}; {rescue('solution.json', data, 'solution')}")


def with_figures(result, out: Path, *, animate: bool = False, progress=None) -> object:
    """``result`` with its figures (and, with ``animate``, motion.gif) written to ``out`` after
    its result files (:func:`write_figure_files`); a write that fails adds to ``unwritten``
    (the solution is already written)."""
    from .files.outputs import write_failure
    if result.unwritten or result.solution is None or result.overrun is not None:
        return result               # nothing to draw, or the result itself went elsewhere
    try:
        files = write_figure_files(result, Path(out), animate=animate, progress=progress)
    except OSError as exc:
        return replace(result, unwritten=write_failure(exc, getattr(exc, "filename", None) or out))
    return replace(result, files=result.files + tuple(files))


def _solution_extra(result) -> dict:
    """What solution.json holds beyond the Solution: the task, the guess (tried, screened),
    success, diagnosis."""
    from .planning.guesses import screened_dict
    return {"task": result.task.to_dict(), "system": result.label, "success": result.success,
            "diagnosis": list(result.diagnosis),
            "guess": {"won": result.guess, "tried": [a.__dict__ for a in result.attempts],
                      "screened": [screened_dict(x) for x in result.screening]}}


def write_outputs(result, out: Path, *, progress=None) -> list:
    """solution.json (with ``task``, ``guess``, ``success`` and ``diagnosis``) and
    trajectory.csv: the result, nothing optional (a plan whose time budget ran out, too; nothing
    without a point). Each file is written whole or not at all
    (:func:`nhgait.gaits.files.outputs.staged`). Returns the paths."""
    from .files.outputs import staged
    if result.solution is None:
        return []

    def write(folder):
        return [result.solution.to_json(folder / "solution.json", extra=_solution_extra(result)),
                write_trajectory_csv(result.solution, folder, result.plan.units)]
    return staged(out, write)


def write_figure_files(result, out: Path, *, animate: bool = False, progress=None) -> list:
    """The figures of a plan (:func:`nhgait.gaits.figures.plots.write_figures`); a failed plan's are
    titled FAILED and it gets no animation; with ``animate`` a successful one also gets
    motion.gif. Written whole or not at all, like the result. Returns the paths."""
    from nhgait.dynamics.progress import Progress

    from .files.outputs import staged
    progress = progress or Progress.silent()
    return staged(out, lambda folder: _draw_files(result, folder, animate=animate, progress=progress))


def _draw_files(result, out: Path, *, animate: bool, progress) -> list:
    from .figures import plots
    failed = None if result.success else (result.diagnosis[0] if result.diagnosis else result.solution.status)
    with progress.phase("write the figures"):
        files = list(plots.write_figures(result.solution, out, units=result.plan.units,
                                         drawing=result.plan.drawing, model=result.model, failed=failed))
        files.append(write_convergence_figure(result.attempts, out / "convergence.png", title=result.label))
    if animate and result.success:
        from .figures.animation import animate_solution
        with progress.phase("write the animation motion.gif (60 frames; the longest part of the output)"):
            ctx = plots.figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
            files.append(animate_solution(result.solution, ctx, out / "motion.gif"))
    return files


def figure_modules() -> None:
    """Import what the figures' children will use (matplotlib's Figure, the Agg canvas, the PNG
    writer): run while the first attempts work (:func:`~nhgait.ocp.supervision.supervise`'s
    ``meanwhile``), so that the children forked for the figures after the result have it
    already — half a second a child, off the critical path (issue 40)."""
    import matplotlib.figure  # noqa: F401
    from matplotlib.backends import backend_agg  # noqa: F401
    from PIL import Image
    Image.preinit()                  # the image plugins a first save imports (PNG, GIF, BMP, ...)
