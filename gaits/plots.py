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


_GREEK = {"psi": "ψ", "phi": "φ", "theta": "θ", "tau_psi": "τ_ψ", "tau_phi": "τ_φ",
          "tau_theta": "τ_θ", "p": "p", "pt_psi": "p̃_ψ", "pt_phi": "p̃_φ", "pt_theta": "p̃_θ"}


def _label(name: str) -> str:
    return _GREEK.get(name, name)


def plot_path(solution, ax=None, *, system=None, bodies: int = 7):
    """x–y path of the body's reference point with the body drawn at ``bodies`` evenly spaced
    nodes (earlier poses lighter), true to scale."""
    ax = _axes(ax, figsize=(7, 4.5))
    names = solution.state_names
    x, y = solution.states[names.index("x")], solution.states[names.index("y")]
    nodes = np.linspace(0, len(x) - 1, bodies).round().astype(int)
    for j, k in enumerate(nodes):
        alpha = 0.25 + 0.6 * j / max(1, len(nodes) - 1)
        for i, (xs, ys) in enumerate(body_outline(solution, k, system)):
            if i == 0:
                ax.plot(xs, ys, "-", color="0.45", lw=3.0, alpha=alpha, solid_capstyle="round", zorder=1)
            else:
                ax.plot(xs, ys, "-", color="k", lw=2.0, alpha=alpha, zorder=2)
    ax.plot(x, y, "-", color="C0", lw=2.5, label="path of the centre", zorder=3)
    ax.plot(x[0], y[0], "o", color="C2", ms=8, label="start", zorder=4)
    ax.plot(x[-1], y[-1], "s", color="C3", ms=8, label="end", zorder=4)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title(f"x–y path (body drawn at {bodies} instants, to scale)")
    return ax


def plot_shape_loop(solution, ax=None, *, system=None):
    """The closed curve traced in shape space, with its start and direction."""
    ax = _axes(ax, figsize=(5, 4.5))
    names = solution.state_names
    a, b = ("psi", "phi") if "psi" in names else ("phi", "theta")
    u, v = solution.states[names.index(a)], solution.states[names.index(b)]
    ax.plot(u, v, "-", color="C0", lw=2)
    ax.plot(u[0], v[0], "o", color="C2", ms=7, label="start")
    k = len(u) // 8
    if k > 0:
        ax.annotate("", xy=(u[k + 1], v[k + 1]), xytext=(u[k], v[k]),
                    arrowprops=dict(arrowstyle="->", color="C0", lw=2))
    ax.set_xlabel(f"{_label(a)} [rad]")
    ax.set_ylabel(f"{_label(b)} [rad]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("shape loop")
    return ax


def plot_histories(solution, axes=None, *, system=None):
    """Shape coordinates (top) and piecewise-constant controls (bottom) over time."""
    if axes is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    names = solution.state_names
    for n in ("psi", "phi", "theta"):
        if n in names and not (n == "theta" and "psi" in names):
            axes[0].plot(solution.t, solution.states[names.index(n)], lw=2, label=_label(n))
    axes[0].set_ylabel("shape angle [rad]")
    axes[0].grid(True, alpha=0.3)
    axes[0].legend(fontsize="small")
    for i, n in enumerate(solution.control_names):
        axes[1].step(solution.t, np.append(solution.controls[i], solution.controls[i, -1]), where="post",
                     lw=1.5, label=_label(n))
    axes[1].set_ylabel("torque [N·m]")
    axes[1].set_xlabel("t [s]")
    axes[1].grid(True, alpha=0.3)
    axes[1].legend(fontsize="small")
    axes[0].set_title("shape and controls (piecewise constant)")
    return axes[0]


def plot_momentum(solution, ax=None, *, system=None):
    """The momenta (nonholonomic p and shape p̃) over time."""
    ax = _axes(ax, figsize=(7, 3.5))
    n_q = len(solution.problem.model.system.coordinates) if solution.problem is not None else 0
    for i, n in enumerate(solution.state_names[n_q:], start=n_q):
        ax.plot(solution.t, solution.states[i], lw=2, label=_label(n))
    ax.set_xlabel("t [s]")
    ax.set_ylabel("momentum [SI]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("reduced momenta")
    return ax
