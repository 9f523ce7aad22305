"""Figures of the thesis's simulations (Figs. 3.8–3.11 unicycle, 3.13–3.17 snakeboard).

Every function draws several runs of one case on one axes: ``runs`` maps a label to a
trajectory (anything with ``t`` (N,), ``q`` (N, n), ``lam`` (N, k) or None and ``coordinates``).
The run named ``reference`` is drawn as a thick light line underneath, every other run as a thin
dashed/dotted line with sparse, staggered markers, so overlapping curves stay visible.

Functions take an optional ``ax``; without one they create a bare :class:`matplotlib.figure.Figure`
(no pyplot, no global state, no backend selection). They never call ``show`` and never change
``rcParams``.
"""
from __future__ import annotations

from matplotlib.figure import Figure

_STYLES = (("--", "o"), (":", "s"), ("-.", "^"), ((0, (5, 2, 1, 2)), "D"), ((0, (1, 3)), "v"),
           ((0, (8, 3)), "x"))
_MARKERS_PER_LINE = 14


def _axes(ax):
    if ax is not None:
        return ax
    return Figure(figsize=(6.4, 4.4)).add_subplot()


def _draw(ax, runs, reference, xy):
    """Draw every run; ``xy(run)`` → (x values, y values) or None to skip the run."""
    others = [label for label in runs if label != reference]
    if reference in runs:
        data = xy(runs[reference])
        if data is not None:
            ax.plot(*data, color="0.55", lw=6, alpha=0.45, solid_capstyle="round",
                    label=f"{reference} (reference)", zorder=1)
    for i, label in enumerate(others):
        data = xy(runs[label])
        if data is None:
            continue
        n = len(data[0])
        every = max(1, n // _MARKERS_PER_LINE)
        style, marker = _STYLES[i % len(_STYLES)]
        ax.plot(*data, ls=style, lw=1.3, marker=marker, ms=4.5, mfc="none",
                markevery=(min(n - 1, (i * every) // max(1, len(others))), every),
                label=label, zorder=2 + i)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    return ax


def plot_path(runs, *, reference=None, ax=None, title=None):
    """x–y path of the contact point / board centre (Figs. 3.8, 3.13)."""
    ax = _axes(ax)

    def xy(run):
        i, j = run.coordinates.index("x"), run.coordinates.index("y")
        return run.q[:, i], run.q[:, j]

    _draw(ax, runs, reference, xy)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title)
    return ax


def plot_coordinate(runs, coordinate, *, reference=None, ax=None, title=None, unit="rad"):
    """One coordinate against time (Figs. 3.9, 3.10, 3.14–3.16)."""
    ax = _axes(ax)
    _draw(ax, runs, reference, lambda run: (run.t, run.q[:, run.coordinates.index(coordinate)]))
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{_greek(coordinate)} [{unit}]")
    if title:
        ax.set_title(title)
    return ax


def plot_multiplier(runs, index, *, reference=None, ax=None, title=None, unit="N"):
    """Lagrange multiplier λ_{index+1} against time from the DAE runs (Figs. 3.11, 3.17)."""
    ax = _axes(ax)

    def xy(run):
        return None if run.lam is None else (run.t, run.lam[:, index])

    _draw(ax, runs, reference, xy)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"λ{_subscript(index + 1)} [{unit}]")
    if title:
        ax.set_title(title)
    return ax


def multiplier_figure(runs, *, reference=None, title=None):
    """λ₁ and λ₂ one above the other, sharing the time axis; returns the Figure."""
    fig = Figure(figsize=(6.4, 6.4))
    top, bottom = fig.subplots(2, 1, sharex=True)
    plot_multiplier(runs, 0, reference=reference, ax=top)
    plot_multiplier(runs, 1, reference=reference, ax=bottom)
    top.set_xlabel("")
    bottom.get_legend().remove()
    top.legend(loc="lower center", bbox_to_anchor=(0.5, 1.02), ncol=2, fontsize="small")
    if title:
        fig.suptitle(title)
    return fig


def save(fig_or_ax, path, *, dpi=150):
    """Tight layout and write a PNG; accepts a Figure or an Axes."""
    fig = getattr(fig_or_ax, "figure", None) or fig_or_ax
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    return path


_GREEK = {"theta": "θ", "phi": "φ", "psi": "ψ"}


def _greek(name):
    return _GREEK.get(name, name)


def _subscript(i):
    return str(i).translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))
