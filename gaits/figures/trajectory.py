"""Figures of a simulated trajectory (``nhgait simulate --plot DIR``), for any scene.

* ``time_series.png`` — the coordinates against time, one panel per unit (m, rad, …), and the
  inputs, one panel per unit; every axis labelled with its unit from the scene's ``[units]``;
* ``path.png`` — the planar frame's path in the x–y plane with the body drawn from the scene's
  ``[drawing]`` (a built-in scene's from its gait library) at a few instants coloured by time
  (:func:`nhgait.gaits.figures.plots.plot_path`, the same figure as a planned gait's); without a planar
  frame, the first two fiber coordinates;
* ``checks.png`` — the run's own checks against time: the constraint residual ``|ω(q) q̇|`` of
  each row (and ``|h(q)|`` of kept holonomic constraints) on a log scale, and the energy balance
  E(t) − E(t₀) − W(t) (W = ∫ τ·q̇ dt, the work of the inputs), zero for an exact solution.

The plots of :mod:`nhgait.gaits.figures.plots` read a solution's ``t``, ``states``, ``state_names`` and
``problem.params``; :class:`TrajectoryView` offers a :class:`~nhgait.dynamics.simulation.Trajectory`
under those names. Figures are :class:`matplotlib.figure.Figure` objects (no pyplot state).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nhgait.gaits.figures.plots import figure_context, label, path_figure_size, plot_path, unit, with_unit
from nhgait.gaits.figures.style import series_styles

__all__ = ["TrajectoryView", "plot_time_series", "plot_checks", "write_trajectory_figures"]

#: a residual below this is drawn at this value on the log scale (an exact zero has no logarithm)
RESIDUAL_FLOOR = 1e-18


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
        ax.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return axes


def time_series_rows(traj, ctx) -> int:
    inputs = _groups(ctx, traj.input_names) if np.asarray(traj.u).size else {}
    return len(_groups(ctx, traj.coordinates)) + len(inputs)


def _row_unit(ctx, row) -> str:
    """The unit of the constraint row ω_i q̇: that of q̇_j for a coordinate whose coefficient has
    no parameter in it (a pure number or a function of angles); "" when every one has."""
    params = set(ctx.system.param_symbols)
    for c, entry in zip(ctx.system.coordinates, row, strict=True):
        if entry != 0 and not (getattr(entry, "free_symbols", set()) & params):
            return unit(ctx, f"{c}_dot")
    return ""


def plot_checks(traj, ctx, axes):
    """The constraint residual ``|ω(q) q̇|`` of each row (log scale) on ``axes[0]`` and the energy
    balance E − E(t₀) − W on ``axes[1]``: the run's own checks, zero for an exact solution."""
    ax_res, ax_energy = axes
    residual = np.abs(np.asarray(traj.constraint_residual, dtype=float).reshape(len(traj.t), -1))
    omega = ctx.system.omega() if residual.shape[1] else None
    units = [_row_unit(ctx, omega.row(i)) if omega is not None else "" for i in range(residual.shape[1])]
    styles = series_styles(residual.shape[1] + 1)
    for i in range(residual.shape[1]):
        u = f" [{units[i]}]" if units[i] else ""
        ax_res.semilogy(traj.t, np.maximum(residual[:, i], RESIDUAL_FLOOR), lw=1.5,
                        label=f"|ω_{i + 1}(q) q̇|{u}", **styles[i])
    held = traj.holonomic_residual
    if held is not None and np.size(held):
        ax_res.semilogy(traj.t, np.maximum(np.abs(held).max(axis=1), RESIDUAL_FLOOR), lw=1.5, ls="--",
                        color="0.3", label="max |h(q)| (kept holonomic constraints)")
    shown = sorted({u for u in units if u})
    ax_res.set_ylabel(f"constraint residual [{', '.join(shown)}]" if shown else "constraint residual")
    ax_res.set_title("constraint residual (drawn at ≥ 1e-18)", fontsize="small")
    if residual.shape[1] or (held is not None and np.size(held)):
        ax_res.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    balance = np.asarray(traj.energy_balance, dtype=float)
    ax_energy.plot(traj.t, balance, lw=1.5, color="C3", label="E(t) − E(t₀) − W(t)")
    ax_energy.set_ylabel("energy balance [J]")
    ax_energy.set_title("energy balance: energy minus the inputs' work W = ∫ τ·q̇ dt", fontsize="small")
    ax_energy.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    ax_energy.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    ax_energy.set_xlabel("t [s]")
    return axes


def write_trajectory_figures(traj, model, out, *, units=None, drawing=None, params=None) -> list:
    """``time_series.png``, ``path.png`` and ``checks.png`` of ``traj`` in the folder ``out``;
    returns the paths."""
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
    stopped = "" if traj.success else " — STOPPED"
    span = f"t = {traj.t[0]:.3g} … {traj.t[-1]:.3g} s{stopped}"
    fig.suptitle(f"{name}: simulated {traj.formulation} model, {traj.method}, {span}")
    files = [out / "time_series.png"]
    fig.savefig(files[-1], dpi=110)
    fig = Figure(figsize=path_figure_size(view, ctx), layout="constrained")
    ax = fig.subplots()
    plot_path(view, ctx, ax)
    ax.set_title(f"{name}: path in the plane (to scale), {label(traj.formulation)} model")
    files.append(out / "path.png")
    fig.savefig(files[-1], dpi=110)
    fig = Figure(figsize=(8.2, 5.2), layout="constrained")
    plot_checks(traj, ctx, fig.subplots(2, 1, sharex=True))
    fig.suptitle(f"{name}: the run's own checks, {label(traj.formulation)} model, {traj.method}{stopped}")
    files.append(out / "checks.png")
    fig.savefig(files[-1], dpi=110)
    return files
