"""A plan's files: the result first, then what is optional (issue 40).

* :func:`written` — ``solution.json`` (the solution, the task, the guesses tried and screened,
  success, diagnosis) and ``trajectory.csv``: the result, written before anything optional
  (:func:`write_outputs`), to a fallback when ``out`` fails (:func:`nhgait.gaits.files.outputs.rescue`).
* :func:`draw_ahead` — the figures drawn while the gait is verified: supervised children (one per
  figure, two at a time) draw them from the converged solution into a staging folder of the
  output directory (:class:`FigureStaging`) while this process verifies the gait and designs its
  feedback (the children's ``meanwhile``); nothing is in the output directory yet.
* :func:`with_figures` — then, after the result, the figures: those drawn ahead moved into place
  when the verified result is what they show (:meth:`FiguresAhead.shows`: the same nodes and
  inputs in the same chart, a success, the same attempts), else drawn now (a failed
  verification's figures are titled FAILED, a refined gait is another trajectory) — and, on
  request, the animation; a failure there leaves the result written.
* :func:`modules_for_later` — the imports the verification and the figures' processes need,
  made while the solver attempts run (:func:`nhgait.ocp.supervision.supervise`'s ``meanwhile``).

Each file is written whole or not at all (:func:`nhgait.gaits.files.outputs.staged`). ``nhgait plan``
prints its result line between the result and the figures; no figure is in the output directory
before it, and no figure process outlives the plan.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .figures.convergence import write_convergence_figure
from .files.exports import write_trajectory_csv

__all__ = ["written", "with_figures", "write_outputs", "write_figure_files", "modules_for_later",
           "draw_ahead", "FiguresAhead", "FigureStaging"]


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


def with_figures(result, out: Path, *, animate: bool = False, progress=None, ahead=None) -> object:
    """``result`` with its figures (and, with ``animate``, motion.gif) written to ``out`` after
    its result files: those drawn ahead (``ahead``, :func:`draw_ahead`) moved into place when
    they show this result, else drawn now (:func:`write_figure_files`); a write that fails adds
    to ``unwritten`` (the solution is already written)."""
    from .files.outputs import move_into, write_failure
    if result.unwritten or result.solution is None or result.overrun is not None:
        return result               # nothing to draw, or the result itself went elsewhere
    try:
        if ahead is not None and ahead.shows(result):
            files = move_into(out, ahead.paths)
            if animate and result.success:
                files += write_figure_files(result, Path(out), animate=True, progress=progress, figures=False)
        else:
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


def write_figure_files(result, out: Path, *, animate: bool = False, progress=None,
                       figures: bool = True) -> list:
    """The figures of a plan (:func:`nhgait.gaits.figures.plots.write_figures` and convergence.png);
    a failed plan's are titled FAILED and it gets no animation; with ``animate`` a successful one
    also gets motion.gif (``figures=False``: that alone). Written whole or not at all, like the
    result. Returns the paths."""
    from nhgait.dynamics.progress import Progress

    from .files.outputs import staged
    progress = progress or Progress.silent()
    return staged(out, lambda folder: _draw_files(result, folder, animate=animate, progress=progress,
                                                  figures=figures))


def _draw_files(result, out: Path, *, animate: bool, progress, figures: bool = True) -> list:
    files = []
    if figures:
        with progress.phase("write the figures"):
            files = _drawn(result, out)
    if animate and result.success:
        from .figures import plots
        from .figures.animation import animate_solution
        with progress.phase("write the animation motion.gif (60 frames; the longest part of the output)"):
            ctx = plots.figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
            files.append(animate_solution(result.solution, ctx, out / "motion.gif"))
    return files


def _drawn(result, out: Path, meanwhile=None) -> list:
    """The five figures of ``result`` drawn into ``out`` by supervised children, one per figure,
    two at a time (:func:`nhgait.gaits.figures.plots.figure_jobs` and convergence.png);
    ``meanwhile`` runs in this process while they draw. Their paths; an OSError when a child
    failed."""
    from nhgait.ocp.supervision import Job, supervise

    from .figures import plots
    failed = None if result.success else (result.diagnosis[0] if result.diagnosis else result.solution.status)
    jobs = plots.figure_jobs(result.solution, out, units=result.plan.units, drawing=result.plan.drawing,
                             model=result.model, failed=failed)
    jobs.append(Job(partial(_convergence, result.attempts, out / "convergence.png", result.label), None,
                    _not_drawn))
    return [path for paths in supervise(jobs, workers=2, meanwhile=meanwhile) for path in paths]


def _convergence(attempts, path: Path, title: str) -> list:
    return [write_convergence_figure(attempts, path, title=title)]


def _not_drawn(status: str, message: str, seconds: float):
    """A figures' child that died (killed, out of memory): the figures were not written — an
    OSError, which a plan's writer reports as such (solution.json then goes to its fallback)."""
    raise OSError(f"the figures' process ended without an answer ({status}: {message})")


# ----------------------------------------------------------------------------- drawn ahead
class FigureStaging(contextlib.AbstractContextManager):
    """The staging folder of the figures drawn ahead in the output directory ``out``
    (:func:`nhgait.gaits.files.outputs.staging_folder`): made when first asked for
    (:meth:`folder`), removed with whatever is left in it when the ``with`` block ends (a plan's
    end, however it ends). ``out`` None: none (:meth:`folder` gives None)."""

    def __init__(self, out):
        self.out = None if out is None else Path(out)
        self._stack = contextlib.ExitStack()
        self._folder = None

    def folder(self) -> Path | None:
        from .files.outputs import staging_folder
        if self._folder is None and self.out is not None:
            self._folder = self._stack.enter_context(staging_folder(self.out))
        return self._folder

    def __exit__(self, *exc) -> None:
        self._stack.close()


@dataclass(frozen=True, eq=False)
class FiguresAhead:
    """The figures drawn while a gait was verified: their ``paths`` in a staging folder (empty:
    their drawing failed; they are drawn again after the result), drawn from the provisional
    ``solution`` (converged, in the derived model's chart, not yet verified) and ``attempts``."""

    paths: tuple
    solution: Any
    attempts: tuple

    def shows(self, result) -> bool:
        """Whether the figures are those of ``result``: drawn, a success (no FAILED title), the
        same nodes, inputs and state names in the same chart (the verification chose no other
        chart; no refinement or other gait replaced it) and the same attempts (convergence.png)."""
        s, a = result.solution, self.solution
        return bool(self.paths and result.success and s is not None
                    and s.problem.model is a.problem.model and tuple(s.state_names) == tuple(a.state_names)
                    and np.array_equal(s.t, a.t) and np.array_equal(s.z, a.z) and np.array_equal(s.u, a.u)
                    and len(result.attempts) == len(self.attempts)
                    and all(x is y for x, y in zip(result.attempts, self.attempts, strict=True)))


def draw_ahead(provisional, staging: FigureStaging, meanwhile, progress=None) -> FiguresAhead | None:
    """Run ``meanwhile()`` (the verification and the feedback) in this process while two
    supervised children draw the figures of ``provisional`` (a PlanResult of the converged,
    unverified gait) into ``staging``'s folder; the :class:`FiguresAhead` (None where there is
    no fork or no folder: ``meanwhile`` alone). A figure that fails leaves the figures to be
    drawn after the result (where its failure is reported); an exception of ``meanwhile`` (a
    spent budget, a stop) kills the children and propagates."""
    from nhgait.ocp.supervision import can_fork
    folder = staging.folder() if can_fork() else None
    if folder is None:
        meanwhile()
        return None
    ran = []                      # "started", then "done"

    def then():
        ran.append("started")
        meanwhile()
        ran.append("done")
    if progress is not None:
        progress.note("  the figures are drawn in two processes while the gait is verified")
    try:
        paths = tuple(_drawn(provisional, folder, meanwhile=then))
    except Exception:             # noqa: BLE001 - a figure's failure: drawn again, and reported, after the result
        if ran == ["started"]:
            raise                 # the verification's own exception propagates
        paths = ()
    if not ran:                   # no child could start: supervise ran the jobs here, without meanwhile
        meanwhile()
    return FiguresAhead(paths, provisional.solution, tuple(provisional.attempts))


def modules_for_later() -> None:
    """Import what the verification (SciPy's integrators) and the figures' children (matplotlib's
    Figure, the Agg canvas, the PNG writer) will use: run while the first attempts work
    (:func:`~nhgait.ocp.supervision.supervise`'s ``meanwhile``), so that the children forked for
    the figures have it already — half a second a child, off the critical path (issue 40)."""
    import matplotlib.figure  # noqa: F401
    import scipy.integrate  # noqa: F401
    from matplotlib.backends import backend_agg  # noqa: F401
    from PIL import Image
    Image.preinit()                  # the image plugins a first save imports (PNG, GIF, BMP, ...)
