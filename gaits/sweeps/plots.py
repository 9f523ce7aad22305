"""Plots of a sweep: cost and feasibility landscapes over two grid axes, shape loops of a row.

Every function takes a :class:`~nhgait.gaits.sweeps.driver.SweepResult` (``load_sweep(DIR)``), an
optional ``ax`` (or ``axes``) and returns what it drew on; none calls ``plt.show()`` or
changes global matplotlib state. Axis labels carry units: the scene's ``[units]`` table
(``x = "m"``, ``J_r = "kg*m^2"``), ``s`` for the horizon, else "SI units".

Grids with more than two axes are sliced: ``fixed`` maps each other axis to a value (the
nearest grid value is used) and defaults to the axis's middle value.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nhgait.dynamics.units import pretty, unit_of

__all__ = ["plot_landscape", "LandscapeView", "plot_feasibility", "plot_shape_loops", "axis_label",
           "grid_slice"]


def axis_label(name: str, units=None) -> str:
    """``final.x [m]``, ``horizon [s]``, ``params.J_r [kg*m^2]``."""
    units = dict(units or {})
    key = name.partition(".")[2] or name
    if name == "horizon":
        unit = "s"
    elif name == "intervals":
        return "intervals N"
    elif name.startswith("objective."):
        return f"weight {key}"
    else:
        unit = unit_of(key, units) or "SI units"      # the one inference (nhgait.dynamics.units)
    return f"{name} [{unit}]"


def objective_label(inputs=(), units=None) -> str:
    """``J = ∫|u|² dt`` with its unit when every input has the same unit in ``units``."""
    units = dict(units or {})
    found = {units.get(u) for u in inputs}
    if inputs and len(found) == 1 and None not in found:
        return f"optimal cost J = ∫|u|² dt [({pretty(found.pop())})²·s]"
    return "optimal cost J = ∫|u|² dt [SI units]"


def _coordinate_label(name: str, units) -> str:
    """``θ [rad]``: the planner's readable name and the unit."""
    from ..figures.plots import label
    return f"{label(name)} [{unit_of(name, units) or 'SI units'}]"


def grid_slice(result, keep: tuple, fixed=None) -> tuple[int | slice, ...]:
    """Indices selecting the 2-D (or 1-D) slice of the axes ``keep`` (other axes at ``fixed``)."""
    fixed = dict(fixed or {})
    grid = result.grid
    unknown = [n for n in (*keep, *fixed) if n not in grid.names]
    if unknown:
        from nhgait.ocp import ProblemError
        raise ProblemError([f"no grid axis {n!r} (axes: {', '.join(grid.names)})" for n in unknown],
                           title="invalid plot axes")
    index = []
    for axis in grid.axes:
        if axis.name in keep:
            index.append(slice(None))
        elif axis.name in fixed:
            index.append(int(np.argmin(np.abs(np.asarray(axis.values) - float(fixed[axis.name])))))
        else:
            index.append((len(axis) - 1) // 2)
    return tuple(index)


def _plane(result, x: str, y: str, values: np.ndarray, fixed):
    """(x values, y values, 2-D array indexed [y, x]) of a grid-shaped array."""
    grid = result.grid
    sub = values[grid_slice(result, (x, y), fixed)]
    ix, iy = grid.names.index(x), grid.names.index(y)
    if ix > iy:                               # the slice keeps axis order: (y, x) already
        return np.asarray(grid.axis(x).values), np.asarray(grid.axis(y).values), sub
    return np.asarray(grid.axis(x).values), np.asarray(grid.axis(y).values), sub.T


def _edges(v: np.ndarray) -> np.ndarray:
    """Cell edges around the points ``v`` (midpoints, ends extended by half a step)."""
    if v.size == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _new_ax(ax, size=(5.5, 4.2)):
    if ax is not None:
        return ax
    from matplotlib.figure import Figure
    return Figure(figsize=size).add_subplot()


def _slice_title(result, keep, fixed) -> str:
    index = grid_slice(result, keep, fixed)
    rest = [f"{a.name} = {a.values[i]:g}" for a, i in zip(result.grid.axes, index, strict=True)
            if not isinstance(i, slice)]
    return f" ({', '.join(rest)})" if rest else ""


@dataclass(frozen=True)
class LandscapeView:
    """What :func:`plot_landscape` shows and how: the record ``column``, ``contours`` lines,
    the colour map ``cmap``, a logarithmic colour scale ``log`` (None: when the values are
    positive and span more than 20×)."""

    column: str = "objective"
    contours: bool = True
    cmap: str = "viridis"
    log: bool | None = None


def plot_landscape(result, x: str, y: str, *, fixed=None, ax=None, view: LandscapeView = LandscapeView()):
    """Heat map of ``view.column`` (solved points) over axes ``x`` and ``y`` (the other axes
    at ``fixed``), with contour lines; failed points crossed out (red ×), points not yet
    solved left blank."""
    from matplotlib.colors import LogNorm
    column, contours, cmap, log = view.column, view.contours, view.cmap, view.log
    ax = _new_ax(ax)
    units = result.units
    xs, ys, Z = _plane(result, x, y, result.values(column), fixed)
    _, _, ok = _plane(result, x, y, result.success_mask(), fixed)
    finite = Z[np.isfinite(Z)]
    if log is None:
        log = finite.size > 1 and finite.min() > 0 and finite.max() > 20 * finite.min()
    norm = LogNorm(finite.min(), finite.max()) if log and finite.size and finite.min() > 0 else None
    mesh = ax.pcolormesh(_edges(xs), _edges(ys), np.ma.masked_invalid(Z), cmap=cmap,
                         shading="flat", norm=norm)
    label = objective_label(result.case.get("inputs") or (), units) if column == "objective" else column
    ax.figure.colorbar(mesh, ax=ax, label=label)
    if contours and np.isfinite(Z).sum() >= 4 and min(Z.shape) >= 2:
        Zc = np.ma.masked_invalid(Z)
        levels = np.geomspace(finite.min(), finite.max(), 8)[1:-1] if norm is not None else 6
        cs = ax.contour(xs, ys, Zc, levels=levels, colors="white", linewidths=0.8)
        ax.clabel(cs, fontsize=7, fmt="%.3g")
    fy, fx = np.nonzero(ok == 0)
    if fx.size:
        ax.plot(xs[fx], ys[fy], "x", color="red", ms=9, mew=2, label="failed", linestyle="none")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel(axis_label(x, units))
    ax.set_ylabel(axis_label(y, units))
    ax.set_title(f"{result.case.get('label', '')} {column}{_slice_title(result, (x, y), fixed)}", fontsize=9)
    return ax


def plot_feasibility(result, x: str, y: str, *, fixed=None, ax=None):
    """Which points were solved and verified (green), failed (red) or not yet solved (grey)."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch
    ax = _new_ax(ax)
    xs, ys, ok = _plane(result, x, y, result.success_mask(), fixed)
    codes = np.where(np.isnan(ok), 0, np.where(ok == 1, 2, 1))
    ax.pcolormesh(_edges(xs), _edges(ys), codes, cmap=ListedColormap(["0.85", "tab:red", "tab:green"]),
                  vmin=0, vmax=2, shading="flat", edgecolors="white", linewidth=0.5)
    ax.legend(handles=[Patch(color="tab:green", label="solved, verified"),
                       Patch(color="tab:red", label="failed"),
                       Patch(color="0.85", label="not solved")], loc="upper right", fontsize=7)
    ax.set_xlabel(axis_label(x, result.units))
    ax.set_ylabel(axis_label(y, result.units))
    ax.set_title(f"{result.case.get('label', '')} "
                 f"feasibility{_slice_title(result, (x, y), fixed)}", fontsize=9)
    return ax


def _load_trajectory(result, record):
    import json
    if not record or not record.solution_path:
        return None
    try:
        data = json.loads((Path(result.directory) / record.solution_path).read_text())
    except (OSError, ValueError):
        return None
    return data.get("trajectory")


def plot_shape_loops(result, axis: str, *, shape=None, fixed=None, axes=None):
    """The optimal shape loops (shape variable a against b over one period) of every point
    along ``axis``, side by side; ``shape`` defaults to the case's first two shape variables."""
    shape = tuple(shape or (result.case.get("shape") or ())[:2])
    if len(shape) != 2:
        from nhgait.ocp import ProblemError
        raise ProblemError([f"shape loops need two shape variables, got {shape!r} (pass shape=(a, b))"],
                           title="invalid plot")
    grid = result.grid
    index = list(grid_slice(result, (axis,), fixed))
    k = grid.names.index(axis)
    values = grid.axis(axis).values
    if axes is None:
        from matplotlib.figure import Figure
        fig = Figure(figsize=(2.4 * len(values) + 0.6, 3.0), layout="constrained")   # room for the suptitle
        axes = fig.subplots(1, len(values), sharex=True, sharey=True, squeeze=False)[0]
    units = result.units
    for i, (value, ax) in enumerate(zip(values, axes, strict=False)):
        index[k] = i
        record = result.record(tuple(index))
        traj = _load_trajectory(result, record)
        if record is not None and record.success and traj is not None:
            a, b = (np.asarray(traj["states"][s]) for s in shape)
            ax.plot(a, b, lw=1.5)
            ax.plot(a[:1], b[:1], "o", ms=4, color="black")
        else:
            ax.text(0.5, 0.5, "failed" if record is not None else "not solved", transform=ax.transAxes,
                    ha="center", va="center", color="tab:red")
        ax.set_title(f"{axis} = {value:g}", fontsize=8)
        ax.set_xlabel(_coordinate_label(shape[0], units), fontsize=8)
        if i == 0:
            ax.set_ylabel(_coordinate_label(shape[1], units), fontsize=8)
    axes[0].figure.suptitle(f"{result.case.get('label', '')}: shape loops along {axis}"
                            f"{_slice_title(result, (axis,), fixed)}", fontsize=9)
    return axes
