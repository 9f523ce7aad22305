"""How each attempt of a plan converged (issue 41): the objective J and the constraint violation
per iteration, one line per attempt, beside the plan's other figures (``convergence.png``).

The history is Ipopt's (``stats["iterations"]``: ``obj``, and ``inf_pr``, the largest violation
of the NLP's constraints — the dynamics' shooting gaps and the task's conditions — at the
iterate, :func:`nhgait.ocp.solver.iteration_history`). FATROP keeps none: its attempts are one
marker each, at their last iteration with their final objective and violation. The violation is
drawn on a logarithmic axis (a converged attempt falls to ~1e-9, an infeasible one levels off at
the violation it cannot remove — what :func:`~nhgait.gaits.planning.infeasibility.stalled` detects). The
functions take an optional ``ax`` and change no global setting.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .style import series_styles

__all__ = ["plot_convergence", "write_convergence_figure", "FLOOR"]

#: violations below this are drawn at it (a log axis has no zero)
FLOOR = 1e-14
#: attempts drawn at most (the legend stays readable); the rest are counted in the title
MAX_ATTEMPTS = 20


def _series(attempt) -> tuple:
    """(iterations, objective, violation, kept a history?) of one attempt."""
    h = getattr(attempt, "history", None) or {}
    if h.get("objective"):
        J, v = np.asarray(h["objective"], float), np.asarray(h["violation"], float)
        return np.arange(J.size), J, np.maximum(v, FLOOR), True
    v = attempt.constraint_violation
    v = max(v, FLOOR) if math.isfinite(v) else math.nan
    return np.array([attempt.iterations]), np.array([attempt.objective]), np.array([v]), False


def plot_convergence(attempts, axes=None):
    """Draw ``attempts`` (:class:`~nhgait.gaits.planning.search.Attempt`) into ``axes`` = (objective axes,
    violation axes) sharing the iteration axis (a new Figure without them); returns the axes."""
    if axes is None:
        from matplotlib.figure import Figure
        axes = Figure(figsize=(11.0, 6.0), layout="constrained").subplots(2, 1, sharex=True)
    top, bottom = axes
    shown = list(attempts)[:MAX_ATTEMPTS]
    for a, style in zip(shown, series_styles(len(shown), markers=True), strict=True):
        k, J, v, full = _series(a)
        label = f"{a.label} ({a.solver or 'solver'}: {a.status})"
        kw = {**style, "markersize": 3 if full else 7, "linewidth": 1.2 if full else 0}
        top.plot(k, J, label=label, markevery=max(1, k.size // 12), **kw)
        bottom.plot(k, v, markevery=max(1, k.size // 12), **kw)
    top.set_ylabel("objective J [the task's units]")
    bottom.set_ylabel("largest constraint violation [SI]")
    bottom.set_yscale("log")
    bottom.set_xlabel("solver iteration [1]")
    top.grid(alpha=0.3)
    bottom.grid(alpha=0.3, which="both")
    if shown:                          # beside the axes: the curves stay visible
        top.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return axes


def write_convergence_figure(attempts, path, *, title: str = "") -> Path:
    """``path`` (a PNG): :func:`plot_convergence` with a title naming the plan and how many
    attempts were made (and drawn); returns the path."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(11.0, 6.0), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    plot_convergence(attempts, axes)
    n = len(list(attempts))
    more = f", the first {MAX_ATTEMPTS} drawn" if n > MAX_ATTEMPTS else ""
    fig.suptitle(f"{title + ': ' if title else ''}convergence of {n} attempt{'s' if n != 1 else ''}{more} "
                 "(lines: Ipopt per iteration; markers alone: FATROP's final point)", fontsize=9)
    path = Path(path)
    fig.savefig(path, dpi=110)
    return path
