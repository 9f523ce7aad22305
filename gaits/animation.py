"""Animated GIF of a planned gait (matplotlib.animation + PillowWriter, no pyplot state).

Each frame shows the path so far, the body at that instant (the scene's ``[drawing]``, else
the frame point with a heading arrow), the time in seconds and a scale bar; the axes are in
metres and a legend explains the marks.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import body_segments, label, series, with_unit

__all__ = ["animate_solution"]


def _nice(length: float) -> float:
    """A round scale-bar length (1, 2 or 5 × 10^k) about a quarter of ``length``."""
    target = max(length / 4, 1e-6)
    k = np.floor(np.log10(target))
    for m in (5, 2, 1):
        if m * 10 ** k <= target:
            return float(m * 10 ** k)
    return float(10 ** k)


def animate_solution(solution, ctx, path, *, fps: int = 15, frames: int = 60) -> Path:
    """Write the motion to ``path`` as a GIF (the path so far, the body at each frame, a scale
    bar, the time in the title); returns the path."""
    if ctx.frame is None:   # no planar frame: animate the fiber path only
        fx, fy = (list(ctx.fiber) + list(solution.state_names))[:2]
    else:
        fx, fy = ctx.frame[:2]
    x, y = series(solution, fx), series(solution, fy)
    segs = [body_segments(solution, ctx, k) if ctx.frame is not None else [] for k in range(len(x))]
    fig, artists = _animation_figure(ctx, (fx, fy), (x, y), segs)
    trace, lines, title = artists

    def update(k):
        trace.set_data(x[:k + 1], y[:k + 1])
        for line, (xs, ys) in zip(lines, segs[k], strict=True):
            line.set_data(xs, ys)
        title.set_text(f"t = {solution.t[k]:.2f} s of {solution.t[-1]:.2f} s")

    nodes = np.linspace(0, len(x) - 1, min(frames, len(x))).round().astype(int)
    images = _frames(fig, update, nodes)
    path = Path(path)
    images[0].save(path, save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0)
    return path


def _animation_figure(ctx, names: tuple, path_xy: tuple, segs: list) -> tuple:
    """(figure, (path line, body lines, title)): axes fitted to the whole motion with equal
    scales, named axes with units, a legend and a scale bar."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    (fx, fy), (x, y) = names, path_xy
    allx = np.concatenate([x] + [np.ravel(s[0]) for ss in segs for s in ss])
    ally = np.concatenate([y] + [np.ravel(s[1]) for ss in segs for s in ss])
    span = max(np.ptp(allx), np.ptp(ally), 0.2)
    pad = 0.12 * span
    ratio = (np.ptp(ally) + 2 * pad) / (np.ptp(allx) + 2 * pad)
    fig = Figure(figsize=(6.0, float(np.clip(6.0 * ratio, 2.2, 6.0)) + 1.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.set_xlim(allx.min() - pad, allx.max() + pad)
    ax.set_ylim(ally.min() - pad, ally.max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel(with_unit(ctx, fx))
    ax.set_ylabel(with_unit(ctx, fy))
    ax.grid(True, alpha=0.3)
    trace, = ax.plot([], [], "-", color="C0", lw=1.5, label="path so far")
    n_seg = len(segs[0])
    widths = ctx.drawing.widths if ctx.drawing is not None else (2.0,) * n_seg
    body_label = "body" if ctx.drawing is not None else f"heading {label(ctx.frame[2]) if ctx.frame else ''}"
    lines = [ax.plot([], [], "-", color="C1", lw=widths[i], label=body_label if i == 0 else None)[0]
             for i in range(n_seg)]
    bar = _nice(span)
    x0, y0 = allx.min() - 0.6 * pad, ally.min() - 0.6 * pad
    ax.plot([x0, x0 + bar], [y0, y0], "-", color="k", lw=3, label=f"scale bar {bar:g} m")
    fig.legend(loc="outside lower center", ncol=3, fontsize="small", frameon=False)
    return fig, (trace, lines, ax.set_title(""))


def _frames(fig, update, nodes) -> list:
    """One RGB image per node. One draw per frame: the layout is computed once (constrained
    layout per frame and matplotlib's animation writer drew every frame three times; the
    timings are in docs/benchmarks.md, "Measured numbers behind design choices")."""
    from PIL import Image
    canvas = fig.canvas
    update(nodes[0])
    canvas.draw()
    fig.set_layout_engine("none")
    images = []
    for k in nodes:
        update(k)
        canvas.draw()
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy()))
    return images
