"""Animated GIF of a planned gait (matplotlib's Agg canvas + Pillow, no pyplot state).

Each frame shows the path so far, the body at that instant (the scene's ``[drawing]``, else
the frame point with a heading arrow), the time in seconds and a scale bar; the axes are in
metres and a legend explains the marks.

The frame fits the motion: the axes' box has the aspect of the whole motion (the path and
every drawn body, padded), within 0.4–1.25 (height over width) — a motion longer than that
gets room on its short side, so that scales stay equal —, and the figure is the box plus its
labels. Frames are drawn by blitting: the axes, grid, labels, legend and scale bar once, then
per frame only the path, the body and the time; the GIF shares one palette (taken from the
last frame, which holds every colour) instead of quantising each frame on its own.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .plots import body_segments, label, series, with_unit

__all__ = ["animate_solution", "FrameGeometry", "frame_geometry"]

#: height over width of the axes' box, at least and at most
ASPECT_RANGE = (0.4, 1.25)
#: the longer side of the axes' box (in) and the margins around it (in): left, right, bottom, top
BOX_INCHES = 5.2
MARGINS = (0.85, 0.25, 0.95, 0.45)
DPI = 100


def _nice(length: float) -> float:
    """A round scale-bar length (1, 2 or 5 × 10^k) about a quarter of ``length``."""
    target = max(length / 4, 1e-6)
    k = np.floor(np.log10(target))
    for m in (5, 2, 1):
        if m * 10 ** k <= target:
            return float(m * 10 ** k)
    return float(10 ** k)


@dataclass(frozen=True)
class FrameGeometry:
    """The axes' limits (equal scales) and the figure's size (in) of an animation."""

    xlim: tuple
    ylim: tuple
    box: tuple               # the axes' box, width and height (in)
    figsize: tuple
    span: float              # the motion's larger extent (for the scale bar)


def frame_geometry(allx, ally) -> FrameGeometry:
    """Limits that hold every point of ``allx``, ``ally`` (padded by 8 % of the larger extent)
    in a box of the motion's aspect, clipped to :data:`ASPECT_RANGE` by widening the short side."""
    lo_x, hi_x = float(np.min(allx)), float(np.max(allx))
    lo_y, hi_y = float(np.min(ally)), float(np.max(ally))
    span = max(hi_x - lo_x, hi_y - lo_y, 0.2)
    pad = 0.08 * span
    width, height = hi_x - lo_x + 2 * pad, hi_y - lo_y + 2 * pad
    ratio = float(np.clip(height / width, *ASPECT_RANGE))
    width, height = max(width, height / ratio), max(height, width * ratio)
    cx, cy = (lo_x + hi_x) / 2, (lo_y + hi_y) / 2
    box = (BOX_INCHES, BOX_INCHES * ratio) if ratio <= 1 else (BOX_INCHES / ratio, BOX_INCHES)
    left, right, bottom, top = MARGINS
    return FrameGeometry(xlim=(cx - width / 2, cx + width / 2), ylim=(cy - height / 2, cy + height / 2),
                         box=box, figsize=(box[0] + left + right, box[1] + bottom + top), span=span)


def animate_solution(solution, ctx, path, *, fps: int = 15, frames: int = 60) -> Path:
    """Write the motion to ``path`` as a GIF (the path so far, the body at each frame, a scale
    bar, the time in the title); returns the path."""
    if ctx.frame is None:   # no planar frame: animate the fiber path only
        fx, fy = (list(ctx.fiber) + list(solution.state_names))[:2]
    else:
        fx, fy = ctx.frame[:2]
    x, y = series(solution, fx), series(solution, fy)
    nodes = np.linspace(0, len(x) - 1, min(frames, len(x))).round().astype(int)
    segs = {k: body_segments(solution, ctx, k) if ctx.frame is not None else [] for k in range(len(x))}
    fig, artists = _animation_figure(ctx, (fx, fy), (x, y), segs)
    trace, lines, title = artists

    def update(k):
        trace.set_data(x[:k + 1], y[:k + 1])
        for line, (xs, ys) in zip(lines, segs[k], strict=True):
            line.set_data(xs, ys)
        title.set_text(f"t = {solution.t[k]:.2f} s of {solution.t[-1]:.2f} s")

    images = _frames(fig, update, nodes, (trace, *lines, title))
    path = Path(path)
    _save_gif(images, path, fps)
    return path


def _animation_figure(ctx, names: tuple, path_xy: tuple, segs: dict) -> tuple:
    """(figure, (path line, body lines, title)): axes fitted to the whole motion with equal
    scales (:func:`frame_geometry`), named axes with units, a legend and a scale bar."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    (fx, fy), (x, y) = names, path_xy
    allx = np.concatenate([x] + [np.ravel(s[0]) for ss in segs.values() for s in ss])
    ally = np.concatenate([y] + [np.ravel(s[1]) for ss in segs.values() for s in ss])
    geometry = frame_geometry(allx, ally)
    fig = Figure(figsize=geometry.figsize, dpi=DPI)
    FigureCanvasAgg(fig)
    left, _, bottom, _ = MARGINS
    w, h = geometry.figsize
    ax = fig.add_axes((left / w, bottom / h, geometry.box[0] / w, geometry.box[1] / h))
    ax.set_xlim(*geometry.xlim)
    ax.set_ylim(*geometry.ylim)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(with_unit(ctx, fx))
    ax.set_ylabel(with_unit(ctx, fy))
    ax.grid(True, alpha=0.3)
    trace, = ax.plot([], [], "-", color="C0", lw=1.5, label="path so far", animated=True)
    n_seg = len(next(iter(segs.values())))
    widths = ctx.drawing.widths if ctx.drawing is not None else (2.0,) * n_seg
    body_label = "body" if ctx.drawing is not None else f"heading {label(ctx.frame[2]) if ctx.frame else ''}"
    lines = [ax.plot([], [], "-", color="C1", lw=widths[i], label=body_label if i == 0 else None,
                     animated=True)[0] for i in range(n_seg)]
    bar = _nice(geometry.span)
    x0 = geometry.xlim[0] + 0.04 * (geometry.xlim[1] - geometry.xlim[0])
    y0 = geometry.ylim[0] + 0.05 * (geometry.ylim[1] - geometry.ylim[0])
    ax.plot([x0, x0 + bar], [y0, y0], "-", color="k", lw=3, label=f"scale bar {bar:g} m")
    fig.legend(loc="lower center", ncol=3, fontsize="small", frameon=False)
    title = ax.set_title("")
    title.set_animated(True)
    return fig, (trace, lines, title)


def _frames(fig, update, nodes, animated) -> list:
    """One RGB image per node, blitted: the static part of the figure is drawn once and copied,
    and each frame restores it and draws only the ``animated`` artists (a full draw per frame
    cost about 3× more; the timings are in docs/benchmarks.md, "Measured numbers behind design
    choices")."""
    from PIL import Image
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for k in nodes:
        update(k)
        canvas.restore_region(background)
        for artist in animated:
            fig.draw_artist(artist)
        images.append(Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3].copy()))
    return images


def _save_gif(images, path: Path, fps: int) -> None:
    """The frames as one GIF with one palette (from the last frame: the whole path, the body,
    the axes), so that Pillow does not quantise each frame on its own; the palette entry the
    figure's white background falls on is made pure white."""
    from PIL import Image
    palette = images[-1].quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    frames = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    entries = np.asarray(frames[-1].getpalette(), dtype=int).reshape(-1, 3)
    entries[frames[-1].getpixel((0, 0))] = 255                      # a corner: the background
    for frame in frames:
        frame.putpalette(entries.astype(np.uint8).ravel().tolist())
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=round(1000 / fps), loop=0,
                   optimize=False)
