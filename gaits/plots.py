"""Plots of a planned gait. Every function takes an optional ``ax`` (or ``axes``), returns the
axes it drew on, never calls ``plt.show()`` and never changes ``rcParams``.

* :func:`plot_path` — x–y path with the body (snakeboard: board and wheels; unicycle: wheel)
  drawn at intervals;
* :func:`plot_shape_loop` — the shape loop φ vs ψ (snakeboard) or θ vs φ (unicycle);
* :func:`plot_histories` — shape coordinates and controls over time;
* :func:`plot_momentum` — the momenta (p, p̃) over time.
"""
from __future__ import annotations

import numpy as np

__all__ = ["plot_path", "plot_shape_loop", "plot_histories", "plot_momentum", "body_outline"]


def _axes(ax, **kw):
    if ax is None:
        import matplotlib.pyplot as plt
        _, ax = plt.subplots(**kw)
    return ax


def _half_length(solution) -> float:
    problem = solution.problem
    names = getattr(problem.model.numeric, "param_names", ()) if problem is not None else ()
    if "r" in names:
        return float(problem.params[list(names).index("r")])
    return 0.1


def body_outline(solution, k: int, system: str | None = None):
    """Line segments [(xs, ys), ...] of the body at node k."""
    names = solution.state_names
    x, y, th = (solution.states[names.index(n), k] for n in ("x", "y", "theta"))
    r = _half_length(solution)
    c, s = np.cos(th), np.sin(th)
    if "psi" in names:  # snakeboard: board of length 2r, wheels at ±r steered by ∓phi / ±phi
        phi = solution.states[names.index("phi"), k]
        segs = [([x - r * c, x + r * c], [y - r * s, y + r * s])]
        w = 0.25 * r
        for sign in (1.0, -1.0):
            cx, cy = x + sign * r * c, y + sign * r * s
            a = th + sign * phi
            segs.append(([cx - w * np.cos(a), cx + w * np.cos(a)], [cy - w * np.sin(a), cy + w * np.sin(a)]))
        return segs
    w = max(r, 0.05)   # unicycle: the wheel seen from above, a segment along the heading
    return [([x - w * c, x + w * c], [y - w * s, y + w * s])]


def plot_path(solution, ax=None, *, system=None, bodies: int = 9):
    """x–y path with the body drawn at ``bodies`` evenly spaced nodes."""
    ax = _axes(ax)
    names = solution.state_names
    x, y = solution.states[names.index("x")], solution.states[names.index("y")]
    ax.plot(x, y, "-", color="C0", lw=1.5, label="path")
    for k in np.linspace(0, len(x) - 1, bodies).round().astype(int):
        for i, (xs, ys) in enumerate(body_outline(solution, k, system)):
            ax.plot(xs, ys, "-", color="C1" if i == 0 else "C3", lw=2.5 if i == 0 else 1.5, alpha=0.8)
    ax.plot(x[0], y[0], "o", color="C2", label="start")
    ax.plot(x[-1], y[-1], "s", color="C3", label="end")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax.set_title("path")
    return ax


def plot_shape_loop(solution, ax=None, *, system=None):
    """The closed curve traced in shape space."""
    ax = _axes(ax)
    names = solution.state_names
    a, b = ("psi", "phi") if "psi" in names else ("phi", "theta")
    ax.plot(solution.states[names.index(a)], solution.states[names.index(b)], "-o", ms=2)
    ax.set_xlabel(a)
    ax.set_ylabel(b)
    ax.set_title("shape loop")
    return ax


def plot_histories(solution, axes=None, *, system=None):
    """Shape coordinates (top) and piecewise-constant controls (bottom) over time."""
    if axes is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(2, 1, sharex=True, figsize=(6, 5))
    names = solution.state_names
    for n in ("psi", "phi", "theta"):
        if n in names and not (n == "theta" and "psi" in names):
            axes[0].plot(solution.t, solution.states[names.index(n)], label=n)
    axes[0].set_ylabel("shape")
    axes[0].legend(fontsize="small")
    for i, n in enumerate(solution.control_names):
        axes[1].step(solution.t, np.append(solution.controls[i], solution.controls[i, -1]), where="post", label=n)
    axes[1].set_ylabel("control")
    axes[1].set_xlabel("t")
    axes[1].legend(fontsize="small")
    return axes[0]


def plot_momentum(solution, ax=None, *, system=None):
    """The momenta (nonholonomic p and shape p̃) over time."""
    ax = _axes(ax)
    n_q = len(solution.problem.model.system.coordinates) if solution.problem is not None else 0
    for i, n in enumerate(solution.state_names[n_q:], start=n_q):
        ax.plot(solution.t, solution.states[i], label=n)
    ax.set_xlabel("t")
    ax.set_ylabel("momentum")
    ax.legend(fontsize="small")
    ax.set_title("momenta")
    return ax
