"""Animated GIF of a planned gait (matplotlib.animation + PillowWriter)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["animate_solution"]


def animate_solution(solution, path, *, system=None, fps: int = 15, frames: int = 60) -> Path:
    """Write the motion (path so far + body) to ``path`` as a GIF; returns the path."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    from .plots import _half_length, body_outline

    names = solution.state_names
    x, y = solution.states[names.index("x")], solution.states[names.index("y")]
    r = _half_length(solution)
    fig, ax = plt.subplots(figsize=(5, 5))
    pad = 1.3 * r
    ax.set_xlim(x.min() - pad, x.max() + pad)
    ax.set_ylim(y.min() - pad, y.max() + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    trace, = ax.plot([], [], "-", color="C0", lw=1)
    n_seg = len(body_outline(solution, 0, system))
    lines = [ax.plot([], [], "-", color="C1" if i == 0 else "C3", lw=3 if i == 0 else 2)[0] for i in range(n_seg)]
    title = ax.set_title("")
    nodes = np.linspace(0, len(x) - 1, min(frames, len(x))).round().astype(int)

    def update(k):
        trace.set_data(x[:k + 1], y[:k + 1])
        for line, (xs, ys) in zip(lines, body_outline(solution, k, system)):
            line.set_data(xs, ys)
        title.set_text(f"t = {solution.t[k]:.2f}")
        return [trace, *lines, title]

    anim = FuncAnimation(fig, update, frames=nodes, blit=False)
    path = Path(path)
    anim.save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path
