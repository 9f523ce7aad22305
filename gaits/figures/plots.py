"""Plots of a planned gait for any system. Every function takes an optional ``ax`` (or
``axes``), returns what it drew on, never calls ``plt.show()`` and never changes ``rcParams``.

* :func:`plot_path` — the fiber path: the planar frame's point in the x–y plane with the body
  drawn at a few instants (from the scene's ``[drawing]``, else the point and an arrow along
  the heading); without a planar frame, the first two fiber coordinates;
* :func:`plot_shape_loop` — the loop in shape space: one shape variable r against ṙ, two
  against each other, more as parallel coordinates;
* :func:`plot_histories` — shape coordinates and the inputs (one panel per input unit);
* :func:`plot_momentum` — the reduced momenta, one panel each, named with their meaning.

Names and units come from the system and the scene's ``[units]`` (``tau = "N*m"``);
coordinates default to rad when they appear inside a trigonometric function of the model,
else m, and the planar frame's position is in m.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nhgait.dynamics.units import coordinate_unit, unit_of

from .geometry import LoopOnPlane, draw_height_under_loop

__all__ = ["plot_path", "plot_shape_loop", "plot_histories", "plot_momentum", "write_figures",
           "figure_jobs", "FigureContext", "figure_context", "FigureLayout", "figure_layouts", "gait_figure",
           "label", "unit", "strobe_nodes", "path_figure_size", "TIME_COLORMAP", "drawing_modules"]

_GREEK = {g: c for g, c in zip(
    ("alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa", "lambda",
     "mu", "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi", "omega"),
    "αβγδεζηθικλμνξπρστυφχψω", strict=True)}


def label(name: str) -> str:
    """A readable label: Greek letter names as letters, ``pt_x`` as p̃_x, ``x_dot`` as ẋ."""
    if name.startswith("pt_"):
        return "p̃_" + label(name[3:])
    if name.endswith("_dot"):
        return label(name[:-4]) + "\u0307"
    parts = name.split("_")
    return "_".join(_GREEK.get(p, p) for p in parts)


@dataclass(frozen=True, eq=False)
class FigureContext:
    """What the plots need to know about the system beyond the solution."""

    system: object
    units: dict
    drawing: object          # Drawing or None
    frame: tuple | None
    fiber: tuple
    shape: tuple
    model: object = None

    def unit(self, name: str) -> str:
        return unit(self, name)


def unit(ctx: FigureContext, name: str) -> str:
    """The unit of a coordinate, velocity, input or quantity: the one inference of
    :func:`nhgait.dynamics.units.unit_of` (the CSV files say the same)."""
    return unit_of(name, ctx.units, ctx.system)


def with_unit(ctx, name) -> str:
    """The axis label of ``name``: its readable label and unit in brackets."""
    u = unit(ctx, name)
    return f"{label(name)} [{u}]" if u else label(name)


def figure_context(solution, model, units=None, drawing=None) -> FigureContext:
    """What the plots need beyond ``solution``: the system of ``model``, the scene's ``[units]``
    (a mapping name → unit) and its parsed ``[drawing]`` (a table, or None: a heading arrow)."""
    from .drawing import default_frame, parse_drawing
    system = model.system
    parsed = parse_drawing(drawing, system) if drawing is not None else None
    frame = parsed.frame if parsed is not None else default_frame(system)
    return FigureContext(system=system, units=dict(units or {}), drawing=parsed, frame=frame,
                         fiber=tuple(getattr(model, "fiber", ())), shape=tuple(getattr(model, "shape", ())),
                         model=model)


def _axes(ax, **kw):
    if ax is None:
        import matplotlib.pyplot as plt
        _, ax = plt.subplots(**kw)
    return ax


def series(solution, name):
    """The history of state ``name`` at the nodes."""
    return solution.z[:, list(solution.state_names).index(name)]


def _q(solution, k):
    n = len(solution.problem.model.system.coordinates)
    return solution.z[k, :n]


# ----------------------------------------------------------------------------- path
def body_segments(solution, ctx, k) -> list:
    """Segments [(xs, ys), …] of the body at node k (drawing, or point + heading arrow)."""
    if ctx.drawing is not None:
        return ctx.drawing.segments(_q(solution, k), solution.problem.params)
    x, y, th = (series(solution, c)[k] for c in ctx.frame)
    th = th + float(getattr(solution.problem.model.system, "forward_angle", 0.0))    # the forward axis
    size = _scale(solution, ctx)
    return [([x, x + 0.15 * size * np.cos(th)], [y, y + 0.15 * size * np.sin(th)])]


def _scale(solution, ctx) -> float:
    x, y = series(solution, ctx.frame[0]), series(solution, ctx.frame[1])
    return max(float(np.ptp(x)), float(np.ptp(y)), 0.2)


#: the colour map of time in the path strobe and its colour bar
TIME_COLORMAP = "viridis"


def strobe_nodes(count: int, bodies: int) -> np.ndarray:
    """The ``bodies`` node indices (first and last included) at which the strobe draws the body."""
    return np.unique(np.linspace(0, count - 1, max(2, min(bodies, count))).round().astype(int))


def plot_path(solution, ctx: FigureContext, ax=None, *, bodies: int = 5):
    """The fiber path as a strobe, true to scale: the body drawn at ``bodies`` instants coloured
    by time (a colour bar in s beside the axes), the frame point's path, the start (an open
    circle) and the end (a filled square, visible inside the circle when the gait returns to
    its start), and a legend below the axes, clear of the drawing."""
    ax = _axes(ax, figsize=(7, 5.2))
    if ctx.frame is None:
        return _plot_fiber(solution, ctx, ax)
    import matplotlib as mpl
    fx, fy, fh = ctx.frame
    x, y, t = series(solution, fx), series(solution, fy), np.asarray(solution.t)
    cmap = mpl.colormaps[TIME_COLORMAP]
    norm = mpl.colors.Normalize(float(t[0]), float(max(t[-1], t[0] + 1e-12)))
    nodes = strobe_nodes(len(x), bodies)
    for j, k in enumerate(nodes):
        for i, (xs, ys) in enumerate(body_segments(solution, ctx, k)):
            lw = ctx.drawing.widths[i] if ctx.drawing is not None else 2.0
            ax.plot(xs, ys, "-", color=cmap(norm(t[k])), lw=lw, alpha=0.9, solid_capstyle="round", zorder=1,
                    label=_strobe_label(ctx, fh, len(nodes)) if j == 0 and i == 0 else None)
    ax.plot(x, y, "-", color="0.15", lw=1.6, label=f"path of the frame point ({label(fx)}, {label(fy)})",
            zorder=3)
    _start_and_end(ax, (x[0], y[0]), (x[-1], y[-1]), (t[0], t[-1]))
    bar = ax.figure.colorbar(mpl.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.85, pad=0.02,
                             label="time of the drawn body t [s]")
    for k in nodes:                                     # the drawn instants marked on the bar
        bar.ax.axhline(t[k], color="w", lw=1.2)
    ax.set_xlabel(with_unit(ctx, fx))
    ax.set_ylabel(with_unit(ctx, fy))
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    _legend_below(ax)
    ax.set_title("path in the plane (to scale)")
    return ax


def _start_and_end(ax, start, end, times) -> None:
    """The start as an open circle, the end as a small filled square: both visible when they
    coincide (a periodic gait, a turn on the spot)."""
    ax.plot(*start, "o", mfc="none", mec="C3", mew=2.0, ms=13, label=f"start (t = {times[0]:.3g} s)",
            zorder=5)
    ax.plot(*end, "s", color="k", ms=6, label=f"end (t = {times[1]:.3g} s)", zorder=6)


def _strobe_label(ctx, heading, count) -> str:
    what = "body" if ctx.drawing is not None else f"heading {label(heading)}"
    return f"{what} at {count} instants (colour: time)"


def _legend_below(ax, ncol: int = 2) -> None:
    """The legend under the axes (outside: it never hides the drawing)."""
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=ncol, fontsize="small", frameon=False)


def _plot_fiber(solution, ctx, ax):
    fiber = [c for c in ctx.fiber if c in solution.state_names] or list(solution.state_names[:1])
    if len(fiber) >= 2:
        a, b = series(solution, fiber[0]), series(solution, fiber[1])
        ax.plot(a, b, "-", color="C0", lw=2, label="fiber path")
        _start_and_end(ax, (a[0], b[0]), (a[-1], b[-1]), (solution.t[0], solution.t[-1]))
        ax.set_xlabel(with_unit(ctx, fiber[0]))
        ax.set_ylabel(with_unit(ctx, fiber[1]))
    else:
        ax.plot(solution.t, series(solution, fiber[0]), "-", color="C0", lw=2, label=label(fiber[0]))
        ax.set_xlabel("t [s]")
        ax.set_ylabel(with_unit(ctx, fiber[0]))
    ax.grid(True, alpha=0.3)
    _legend_below(ax, ncol=3)
    ax.set_title("fiber path")
    return ax


# ----------------------------------------------------------------------------- shape
def plot_shape_loop(solution, ctx: FigureContext, ax=None):
    """The closed curve in shape space, with its start and direction of motion."""
    ax = _axes(ax, figsize=(5.2, 4.6))
    shape = [c for c in ctx.shape if c in solution.state_names]
    if len(shape) >= 3:
        return _parallel_coordinates(solution, ctx, shape, ax)
    if len(shape) == 2:
        a, b = shape
        u, v = series(solution, a), series(solution, b)
        xl, yl = with_unit(ctx, a), with_unit(ctx, b)
        title = "shape loop"
        q = np.vstack([series(solution, c) for c in ctx.system.coordinates])
        if draw_height_under_loop(ax, ctx.model or solution.problem.model,
                                  LoopOnPlane(q[:, 0], q[:, -1], (u, v), (a, b)), units=ctx.units,
                                  params=getattr(solution.problem, "params", None),
                                  draw_loop=False):
            title = "shape loop over the height function"
    else:
        a = shape[0] if shape else solution.state_names[0]
        u = series(solution, a)
        v = np.asarray(solution.velocities())[list(ctx.system.coordinates).index(a)]
        xl, yl = with_unit(ctx, a), with_unit(ctx, f"{a}_dot")
        title = f"shape motion: {label(a)} against its rate"
    ax.plot(u, v, "-", color="C0", lw=2, label="shape trajectory")
    ax.plot(u[0], v[0], "o", color="C2", ms=7, label="start (t = 0)")
    k = max(1, len(u) // 8)
    if k + 1 < len(u):
        ax.annotate("", xy=(u[k + 1], v[k + 1]), xytext=(u[k], v[k]),
                    arrowprops=dict(arrowstyle="->", color="C0", lw=2))
        ax.plot([], [], marker=r"$\rightarrow$", ls="", color="C0", label="direction of motion")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(title)
    return ax


def _parallel_coordinates(solution, ctx, shape, ax):
    """One vertical axis per shape variable; each node a polyline coloured by time."""
    import matplotlib.cm as cm
    data = np.vstack([series(solution, c) for c in shape])
    lo, hi = data.min(axis=1, keepdims=True), data.max(axis=1, keepdims=True)
    scaled = (data - lo) / np.where(hi > lo, hi - lo, 1.0)
    colors = cm.viridis(np.linspace(0, 1, data.shape[1]))
    for k in range(data.shape[1]):
        ax.plot(range(len(shape)), scaled[:, k], "-", color=colors[k], lw=0.8, alpha=0.7)
    ax.set_xticks(range(len(shape)))
    ax.set_xticklabels([f"{with_unit(ctx, c)}\n[{lo[i, 0]:.2g}, {hi[i, 0]:.2g}]"
                        for i, c in enumerate(shape)])
    ax.set_ylabel("value scaled to its range [min, max] (1 = max)")
    ax.plot([], [], color=colors[0], label="t = 0")
    ax.plot([], [], color=colors[-1], label=f"t = {solution.t[-1]:.3g} s")
    ax.legend(fontsize="small")
    ax.set_title("shape motion (parallel coordinates)")
    return ax


# ----------------------------------------------------------------------------- histories
def plot_histories(solution, ctx: FigureContext, axes=None):
    """Shape coordinates (top) and the inputs, one panel per input unit; returns the axes."""
    units = []
    for n in solution.control_names:
        u = unit(ctx, n)
        if u not in units:
            units.append(u)
    if axes is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(1 + len(units), 1, sharex=True, figsize=(7, 2.4 * (1 + len(units))))
    axes = list(np.atleast_1d(axes))
    shape = [c for c in ctx.shape if c in solution.state_names] or list(ctx.system.coordinates)
    shape_units = list(dict.fromkeys(unit(ctx, c) for c in shape))      # in the order of the names
    for c in shape:
        axes[0].plot(solution.t, series(solution, c), lw=2, label=with_unit(ctx, c))
    axes[0].set_ylabel(f"shape {', '.join(label(c) for c in shape)} "
                       f"[{', '.join(u for u in shape_units if u)}]")
    axes[0].legend(fontsize="small")
    axes[0].set_title("shape coordinates and inputs (inputs constant on each interval)")
    for ax, u in zip(axes[1:], units, strict=False):
        for i, n in enumerate(solution.control_names):
            if unit(ctx, n) == u:
                ax.step(solution.t, np.append(solution.u[:, i], solution.u[-1, i]), where="post",
                        lw=1.5, label=with_unit(ctx, n))
        ax.set_ylabel(f"input [{u}]" if u else "input")
        ax.legend(fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return axes


def plot_momentum(solution, ctx: FigureContext, axes=None):
    """The reduced momenta over time, one panel each, with their meaning and unit."""
    n = len(ctx.system.coordinates)
    model_states = (solution.problem.model_state_names if solution.problem is not None
                    else solution.state_names)
    names = list(model_states[n:])                       # the integral states (a task's) are not momenta
    if axes is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(len(names), 1, sharex=True, figsize=(7, 1.9 * max(1, len(names))))
    axes = list(np.atleast_1d(axes))
    for ax, name in zip(axes, names, strict=False):
        ax.plot(solution.t, series(solution, name), lw=2, color="C0")
        if name.startswith("pt_"):
            ax.set_ylabel(f"{label(name)} [{unit(ctx, name)}]")
            ax.set_title(f"{label(name)}: shape momentum conjugate to {label(name[3:])}", fontsize="small")
        elif name.endswith("_dot") and name[:-4] in ctx.system.coordinates:     # a gait verified in (q, q̇)
            ax.set_ylabel(f"{label(name)}")
            ax.set_title(f"{label(name)}: generalised velocity", fontsize="small")
        else:
            u = _basis_momentum_unit(ctx, names.index(name))
            ax.set_ylabel(f"{label(name)} [{u}]" if u else f"{label(name)} [unit of XᵀMq̇]")
            ax.set_title(f"{label(name)}: nonholonomic momentum P = XᵀM q̇ along the constraint-adapted "
                         "basis X", fontsize="small")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return axes


def _basis_momentum_unit(ctx, j) -> str:
    """Unit of the j-th momentum P_j = Σ_i X_ij (∂L/∂q̇_i): the unit of the momentum conjugate to a
    coordinate q_i whose basis entry X_ij is a pure number (no parameter in it); "" if none is."""
    X = getattr(ctx.model, "X", None)
    if X is None or not hasattr(X, "free_symbols"):     # the implicit form holds X as CasADi text
        return ""
    params = set(ctx.system.param_symbols)
    coords = tuple(ctx.system.coordinates)
    for i, c in enumerate(coords):
        entry = X[i, j]
        if entry != 0 and not (entry.free_symbols & params):
            return "N·m·s" if coordinate_unit(ctx.system, c, ctx.units) == "rad" else "N·s"
    return ""


# ----------------------------------------------------------------------------- files
def failed_banner(reason: str, width_in: float) -> str:
    """"FAILED — not a verified gait" and the reason in at most two lines that fit a figure
    ``width_in`` inches wide (about 8 characters an inch of the banner's bold font)."""
    import textwrap
    chars = max(30, int(8 * width_in))
    lines = textwrap.wrap(reason, width=chars)
    if len(lines) > 2:
        lines = [lines[0], textwrap.shorten(" ".join(lines[1:]), width=chars, placeholder=" …")]
    return "\n".join(["FAILED — not a verified gait", *lines])


@dataclass(frozen=True)
class FigureLayout:
    """One figure file of a plan: its name, the plot function, its size (in) and its rows."""

    name: str
    draw: object             # plot function (solution, ctx, ax or axes)
    size: tuple
    rows: int = 1


def figure_layouts(solution, ctx: FigureContext) -> tuple[FigureLayout, ...]:
    """The four figures of a plan: path.png, shape.png, histories.png, momentum.png."""
    n_units = len({unit(ctx, c) for c in solution.control_names})
    n_mom = max(1, len(solution.state_names) - len(ctx.system.coordinates))
    return (FigureLayout("path.png", plot_path, path_figure_size(solution, ctx)),
            # shape.png: the place of a background over the shape plane (a height function,
            # drawn under the loop by the function that draws it on ``ax``) when there is one
            FigureLayout("shape.png", plot_shape_loop, (5.4, 5.0)),
            FigureLayout("histories.png", plot_histories, (7, 2.4 * (1 + n_units)), 1 + n_units),
            FigureLayout("momentum.png", plot_momentum, (7, 1.9 * n_mom + 0.4), n_mom))


def path_figure_size(solution, ctx: FigureContext, width: float = 7.4) -> tuple[float, float]:
    """(width, height) in inches of the path strobe: the axes' height follows the aspect of the
    path and the drawn bodies (equal scales), within 0.35–1.1 of the axes' width, plus the
    title and the legend below."""
    if ctx.frame is None:
        return (width, 5.6)
    xs, ys = [series(solution, ctx.frame[0])], [series(solution, ctx.frame[1])]
    for k in strobe_nodes(len(xs[0]), 5):
        for sx, sy in body_segments(solution, ctx, k):
            xs.append(np.ravel(sx))
            ys.append(np.ravel(sy))
    x, y = np.concatenate(xs), np.concatenate(ys)
    ratio = float(np.clip((np.ptp(y) + 0.1) / max(float(np.ptp(x)) + 0.1, 1e-9), 0.35, 1.1))
    return (width, round(0.78 * width * ratio + 1.9, 2))


def gait_figure(solution, ctx: FigureContext, layout: FigureLayout, failed: str | None = None):
    """The :class:`~matplotlib.figure.Figure` of ``layout`` (no pyplot state). With ``failed``
    (the reason) the figure carries a red banner "FAILED — not a verified gait" above the
    axes' titles: constrained layout gives the banner (the figure's suptitle) its own room."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=layout.size, layout="constrained")
    axes = fig.subplots(layout.rows, 1, sharex=layout.rows > 1, squeeze=False)[:, 0]
    layout.draw(solution, ctx, axes[0] if layout.rows == 1 else axes)
    if failed:
        fig.suptitle(failed_banner(failed, layout.size[0]), color="tab:red", fontsize="medium",
                     fontweight="bold")
    return fig


def write_figures(solution, out: Path, *, units=None, drawing=None, model=None,
                  failed: str | None = None) -> list:
    """path.png, shape.png, histories.png, momentum.png in ``out``; with ``failed`` (the reason)
    every figure is titled "FAILED — not a verified gait". Each figure in a supervised child,
    two at a time (:func:`figure_jobs`, :func:`nhgait.ocp.supervision.supervise`: two cores,
    stopped with the plan; one after the other in this process where there is no fork). The
    animation is :func:`nhgait.gaits.figures.animation.animate_solution`."""
    from nhgait.ocp.supervision import supervise
    jobs = figure_jobs(solution, out, units=units, drawing=drawing, model=model, failed=failed)
    return [path for paths in supervise(jobs, workers=2) for path in paths]


def figure_jobs(solution, out: Path, *, units=None, drawing=None, model=None,
                failed: str | None = None) -> list:
    """One :class:`~nhgait.ocp.supervision.Job` per figure of :func:`write_figures` (each draws its
    figure into ``out`` and gives its path in a list), the costliest first — shape.png, whose
    background is a height function — so that two workers finish together; to run with other
    jobs or while the parent works (``supervise``'s ``meanwhile``); the drawing modules
    imported here first (:func:`drawing_modules`)."""
    from functools import partial

    from nhgait.ocp.supervision import Job
    drawing_modules()
    model = model if model is not None else solution.problem.model
    ctx = figure_context(solution, model, units, drawing)
    layouts = sorted(figure_layouts(solution, ctx), key=lambda layout: layout.name != "shape.png")
    return [Job(partial(_drawn, solution, ctx, out, [layout], failed), None, _not_drawn)
            for layout in layouts]


def drawing_modules() -> None:
    """Import what every figure's process uses — matplotlib's Figure, the Agg canvas, the PNG
    writer — in this process, before :func:`figure_jobs`' children are forked: each child
    has them then, instead of importing them itself (about 0.4 s of CPU a child, five
    children a plan; a no-op when the planner imported them while its attempts ran)."""
    import matplotlib.figure  # noqa: F401
    from matplotlib.backends import backend_agg  # noqa: F401
    from PIL import Image
    Image.preinit()                  # the image plugins a first save imports (PNG, GIF, BMP, ...)


def _drawn(solution, ctx, out: Path, layouts, failed) -> list:
    """The figures of ``layouts`` (:class:`FigureLayout`) written to ``out``."""
    files = []
    for layout in layouts:
        gait_figure(solution, ctx, layout, failed).savefig(out / layout.name, dpi=110)
        files.append(out / layout.name)
    return files


def _not_drawn(status: str, message: str, seconds: float):
    """A figures' child that died (killed, out of memory): the figures were not written — an
    OSError, which a plan's writer reports as such (solution.json then goes to its fallback)."""
    raise OSError(f"the figures' process ended without an answer ({status}: {message})")
