"""Figures of the local connection: height functions with contours and the connection's fields.

The arrays come from :func:`nhgait.dynamics.geometry.heights.evaluate_heights`
(:class:`~nhgait.dynamics.geometry.heights.HeightFunctions`): H_ab = −(∂A_b/∂r_a − ∂A_a/∂r_b) +
[A_a, A_b], the body displacement of fibre k per unit area of a counter-clockwise loop in the
(r_a, r_b) plane, and the rows of −A (the shape velocity that moves fibre k forward fastest).

* :func:`plot_height_function` — filled contours of H_k (a diverging colour map centred on 0,
  the zero contour drawn), its colour bar with name and units, the field of −A_k as arrows and,
  optionally, a loop with its direction;
* :func:`heights_figure` — one panel per fibre component;
* :func:`height_parts_figure` — a mixed system's scaled-momentum heights H̄ = H − σ̄Γ̄ in their
  parts (connection, momentum, sum), one row per fibre component;
* :func:`draw_height_under_loop` — what a plan's ``shape.png`` draws under a two-variable loop:
  the height function of the direction the gait moves.

Every function takes an optional ``ax``; none calls ``plt.show()`` or changes ``rcParams``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["plot_height_function", "heights_figure", "height_parts_figure", "LoopOnPlane",
           "draw_height_under_loop", "moved_component"]

#: how a colour bar names each :attr:`HeightFunctions.form` (and the parts of
#: :func:`height_parts_figure`)
_FORM_WORDS = {"connection": "height", "scaled momentum": "scaled-momentum height H̄",
               "connection part": "connection's height H", "momentum part": "momentum part −σ̄Γ̄"}

#: colours saturate at this percentile of |H| (near the singular set of A, H is unbounded)
CLIP_PERCENTILE = 95.0


def _capped(U, V):
    """Arrows no longer than the 90th percentile of their lengths (directions kept; non-finite
    arrows dropped), so the singular set does not shrink every other arrow to a dot."""
    length = np.hypot(U, V)
    finite = np.isfinite(length)
    cap = float(np.percentile(length[finite], 90)) if finite.any() else 1.0
    scale = np.where(finite & (length > cap), cap / np.where(length > 0, length, 1.0), 1.0)
    return np.where(finite, U * scale, np.nan), np.where(finite, V * scale, np.nan)


def _label(heights, name: str) -> str:
    unit = heights.units.get(name, "")
    return f"{name} [{unit}]" if unit else name


def _height_unit(heights, k: int) -> str:
    a, b = heights.pair
    top = heights.units.get(heights.fiber[k], "")
    units = [u for u in (heights.units.get(a, ""), heights.units.get(b, "")) if u]
    bottom = f"{units[0]}²" if len(units) == 2 and units[0] == units[1] else "·".join(units)
    return f"{top or '1'}/{bottom}" if bottom else top


def plot_height_function(heights, component: str, ax=None, *, loop=None, arrows: bool = True, colorbar=True):
    """Filled contours of the height function of fibre ``component`` over the shape plane, the
    field of −A_k as arrows, and ``loop`` ((a samples, b samples)) when given. Returns ``ax``."""
    from matplotlib.colors import TwoSlopeNorm
    if ax is None:
        from matplotlib.figure import Figure
        ax = Figure(figsize=(5.6, 4.8), layout="constrained").subplots()
    k = heights.component(component)
    H = heights.heights[k]
    finite = np.abs(H[np.isfinite(H)])
    peak = float(np.max(finite)) if finite.size else 0.0
    top = float(np.percentile(finite, CLIP_PERCENTILE)) if finite.size else 1.0
    top = top if top > 0 else (peak if peak > 0 else 1.0)
    clipped = peak > 1.5 * top
    A, B = np.meshgrid(heights.a_values, heights.b_values)
    filled = ax.contourf(A, B, np.clip(H, -top, top), levels=21, cmap="RdBu_r",
                         norm=TwoSlopeNorm(0.0, -top, top))
    if peak > 0:
        ax.contour(A, B, H, levels=[0.0], colors="k", linewidths=1.0)
    else:
        ax.text(0.5, 0.5, f"H = 0 over this plane:\nno loop here moves {component}", transform=ax.transAxes,
                ha="center", va="center")
    what = _FORM_WORDS.get(heights.form, "height")
    if colorbar:
        unit = _height_unit(heights, k)
        text = (f"{what} of {component}" + (f" [{unit}]" if unit else "")
                + "\nper unit area of a counter-clockwise loop"
                + (" from rest" if heights.form in ("scaled momentum", "momentum part") else "")
                + (f"\n(colours clipped at the {CLIP_PERCENTILE:g}th percentile)" if clipped else ""))
        ax.figure.colorbar(filled, ax=ax, label=text)
    if arrows and np.any(np.hypot(*heights.fields[k]) > 0):
        step = max(1, len(heights.a_values) // 12)
        U, V = _capped(heights.fields[k, 0], heights.fields[k, 1])
        ax.quiver(A[::step, ::step], B[::step, ::step], U[::step, ::step], V[::step, ::step],
                  color="0.25", alpha=0.8, angles="xy")
    if loop is not None:
        u, v = (np.asarray(x, float) for x in loop)
        ax.plot(u, v, "-", color="C2", lw=2.2, label="gait's shape loop")
        i = max(1, len(u) // 8)
        if i + 1 < len(u):
            ax.annotate("", xy=(u[i + 1], v[i + 1]), xytext=(u[i], v[i]),
                        arrowprops=dict(arrowstyle="->", color="C2", lw=2.2))
        ax.plot(u[0], v[0], "o", color="C2", ms=6)
        ax.legend(fontsize="small", loc="upper right")
    ax.set_xlabel(_label(heights, heights.pair[0]))
    ax.set_ylabel(_label(heights, heights.pair[1]))
    ax.set_title(f"{what} of {component}; arrows: −A row of {component}", fontsize="medium")
    return ax


def heights_figure(heights, *, loop=None):
    """A :class:`~matplotlib.figure.Figure` with one :func:`plot_height_function` panel per fibre
    component (no pyplot state)."""
    from matplotlib.figure import Figure
    l = len(heights.fiber)
    fig = Figure(figsize=(5.2 * l, 4.8), layout="constrained")
    for ax, name in zip(np.atleast_1d(fig.subplots(1, l)), heights.fiber, strict=True):
        plot_height_function(heights, name, ax, loop=loop)
    return fig


def height_parts_figure(heights, *, loop=None, components=None):
    """The scaled-momentum heights (:attr:`HeightFunctions.form` ``"scaled momentum"``) in their
    parts, one row per fibre component (``components``, default all): the connection's height
    H, the momentum part −σ̄Γ̄ and their sum H̄ (:mod:`nhgait.dynamics.geometry.scaled_momentum`)."""
    from dataclasses import replace

    from matplotlib.figure import Figure
    if heights.momentum_part is None:
        raise ValueError("height_parts_figure needs scaled-momentum heights "
                         "(evaluate_heights(..., momentum=...))")
    names = list(components or heights.fiber)
    parts = [replace(heights, heights=heights.heights - heights.momentum_part, form="connection part"),
             replace(heights, heights=heights.momentum_part, form="momentum part"), heights]
    fig = Figure(figsize=(5.2 * 3, 4.6 * len(names)), layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(names), 3))
    for row, name in zip(axes, names, strict=True):
        for ax, part in zip(row, parts, strict=True):
            plot_height_function(part, name, ax, loop=loop)
    return fig


def moved_component(fiber: tuple, moved_body) -> str:
    """The fibre component a gait moved most (``moved_body``: its net change in the body frame
    at its start, fibre order)."""
    return fiber[int(np.argmax(np.abs(np.asarray(moved_body, float))))]


@dataclass(frozen=True)
class LoopOnPlane:
    """A gait's two-variable shape loop: the configurations ``q_start`` and ``q_end`` (n, the
    system's order) at its ends, its ``samples`` ((a values, b values)) and the shape ``pair``
    (a, b) of the plane."""

    q_start: np.ndarray
    q_end: np.ndarray
    samples: tuple
    pair: tuple


def draw_height_under_loop(ax, model, loop: LoopOnPlane, *, units=None, params=None,
                           draw_loop: bool = True) -> bool:
    """Draw, on ``ax``, the height function of the direction a gait moved (its net fibre change
    from ``loop.q_start`` to ``loop.q_end``, in the body frame at the start) over the box around
    the loop's samples, the other coordinates at ``q_start``, with the connection's arrows (and
    the loop, with ``draw_loop``). False (nothing drawn) when ``model`` has no local connection."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.geometry.connection_fields import numeric_connection
    from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights_numeric
    base = getattr(model, "base", model)
    if getattr(base, "layout", None) is None:
        return False
    try:
        connection = numeric_connection(base, params)
    except ModelError:
        return False
    names = tuple(base.system.coordinates)
    pair = tuple(loop.pair)
    if any(p not in connection.shape for p in pair):
        return False
    idx = [names.index(c) for c in connection.fiber]
    q0, q1 = np.asarray(loop.q_start, float), np.asarray(loop.q_end, float)
    g0 = connection.frame(q0)
    moved = np.linalg.solve(g0, q1[idx] - q0[idx])
    u, v = (np.asarray(x, float) for x in loop.samples)
    pad_u, pad_v = 0.25 * max(np.ptp(u), 1e-3), 0.25 * max(np.ptp(v), 1e-3)
    bounds = {pair[0]: (u.min() - pad_u, u.max() + pad_u), pair[1]: (v.min() - pad_v, v.max() + pad_v)}
    heights = evaluate_heights_numeric(connection, *pair, HeightGrid(bounds=bounds, points=31,
                                                                     at=dict(zip(names, q0, strict=True)),
                                                                     units=dict(units or {})))
    plot_height_function(heights, moved_component(connection.fiber, moved), ax,
                         loop=(u, v) if draw_loop else None)
    return True
