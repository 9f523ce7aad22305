"""Figures of a simulated trajectory (``nhgait simulate --plot DIR``), for any scene.

* ``time_series.png`` — the coordinates against time, one panel per unit (m, rad, …), and the
  inputs, one panel per unit; every axis labelled with its unit from the scene's ``[units]``;
* ``path.png`` — the planar frame's path in the x–y plane with the body drawn from the scene's
  ``[drawing]`` at a few instants (:func:`nhgait.gaits.plots.plot_path`, the same figure as a
  planned gait's); without a planar frame, the first two fiber coordinates.

The plots of :mod:`nhgait.gaits.plots` read a solution's ``t``, ``states``, ``state_names`` and
``problem.params``; :class:`TrajectoryView` offers a :class:`~nhgait.dynamics.simulation.Trajectory`
under those names. Figures are :class:`matplotlib.figure.Figure` objects (no pyplot state).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nhgait.gaits.plot_style import series_styles
from nhgait.gaits.plots import figure_context, label, plot_path, unit, with_unit

__all__ = ["TrajectoryView", "plot_time_series", "write_trajectory_figures"]


@dataclass(frozen=True)
class _Problem:
    model: object
    params: np.ndarray


@dataclass(frozen=True, eq=False)
class TrajectoryView:
    """A trajectory seen as the plots see a solution: ``z`` (N, n), time first, the coordinates."""

    t: np.ndarray
    z: np.ndarray
    state_names: tuple
    qdot: np.ndarray
    problem: _Problem

    @classmethod
    def of(cls, traj, model, params=None) -> TrajectoryView:
        system = model.system
        return cls(t=np.asarray(traj.t), z=np.asarray(traj.q), state_names=tuple(system.coordinates),
                   qdot=np.asarray(traj.qdot), problem=_Problem(model, system.param_vector(params or None)))

    def velocities(self) -> np.ndarray:
        return self.qdot.T


def _groups(ctx, names) -> dict:
    """unit → names, in first-seen order."""
    out: dict = {}
    for name in names:
        out.setdefault(unit(ctx, name), []).append(name)
    return out


def plot_time_series(traj, ctx, axes):
    """Coordinates (one panel per unit) and inputs (one panel per unit) against time on
    ``axes`` (as many as :func:`time_series_rows` says)."""
    coords = _groups(ctx, traj.coordinates)
    inputs = _groups(ctx, traj.input_names) if np.asarray(traj.u).size else {}
    axes = list(np.atleast_1d(axes))
    rows = [("coordinate", u, names) for u, names in coords.items()] + \
           [("input", u, names) for u, names in inputs.items()]
    for ax, (kind, u, names) in zip(axes, rows, strict=False):
        source = traj.q if kind == "coordinate" else traj.u
        order = traj.coordinates if kind == "coordinate" else traj.input_names
        styles = series_styles(len(names))
        for name, style in zip(names, styles, strict=True):
            ax.plot(traj.t, np.asarray(source)[:, list(order).index(name)], lw=1.8,
                    label=with_unit(ctx, name), **style)
        what = "coordinates" if kind == "coordinate" else "inputs"
        ax.set_ylabel(f"{what} [{u}]" if u else what)
        ax.legend(fontsize="small", loc="best")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return axes


def time_series_rows(traj, ctx) -> int:
    inputs = _groups(ctx, traj.input_names) if np.asarray(traj.u).size else {}
    return len(_groups(ctx, traj.coordinates)) + len(inputs)


def write_trajectory_figures(traj, model, out, *, units=None, drawing=None, params=None) -> list:
    """``time_series.png`` and ``path.png`` of ``traj`` in the folder ``out``; returns the paths."""
    from matplotlib.figure import Figure
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    view = TrajectoryView.of(traj, model, params)
    ctx = figure_context(view, model, units, drawing)
    name = model.system.name
    rows = time_series_rows(traj, ctx)
    fig = Figure(figsize=(7.5, 2.3 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    plot_time_series(traj, ctx, axes)
    span = f"t = {traj.t[0]:.3g} … {traj.t[-1]:.3g} s" + ("" if traj.success else " — STOPPED")
    fig.suptitle(f"{name}: simulated {traj.formulation} model, {traj.method}, {span}")
    files = [out / "time_series.png"]
    fig.savefig(files[-1], dpi=110)
    fig = Figure(figsize=(7, 5), layout="constrained")
    ax = fig.subplots()
    plot_path(view, ctx, ax)
    ax.set_title(f"{name}: path in the plane (to scale), {label(traj.formulation)} model")
    files.append(out / "path.png")
    fig.savefig(files[-1], dpi=110)
    return files
