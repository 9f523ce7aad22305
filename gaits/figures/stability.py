"""The eigenvalues of a straight steady motion against forward speed (the Whipple benchmark's
Fig. 3): real parts as solid dots, imaginary parts (|Im λ| of each complex pair) as open
circles, the speeds where stability changes as vertical lines, the stable range shaded, and
optionally published values on top as crosses. Functions take an optional ``ax`` and never
change global settings."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_eigenvalues", "write_eigenvalue_figure"]


def plot_eigenvalues(chart, ax=None, *, reference=None, reference_label: str = "published"):
    """Draw ``chart`` (a :class:`~nhgait.dynamics.linearisation.chart.StabilityChart`) into
    ``ax``. ``reference``: optional mapping speed → eigenvalues drawn as crosses (real parts
    black, |imaginary parts| grey)."""
    if ax is None:
        from matplotlib.figure import Figure
        ax = Figure(figsize=(7.5, 4.8), layout="constrained").subplots()
    v = np.repeat(chart.speeds[:, None], chart.eigenvalues.shape[1], axis=1)
    lam = chart.eigenvalues
    ax.plot(v.ravel(), lam.real.ravel(), ".", color="C0", markersize=3, label="Re λ")
    imag = lam.imag > 0
    ax.plot(v[imag], lam.imag[imag], "o", mfc="none", color="C1", markersize=3, label="Im λ (> 0)")
    for a, b in chart.stable_ranges():
        ax.axvspan(a, b, color="C2", alpha=0.12, lw=0)
    for change in chart.changes:
        ax.axvline(change.speed, color="0.3", lw=0.8, ls="--")
        ax.annotate(f"{change.speed:.4f}", (change.speed, 1), xycoords=("data", "axes fraction"),
                    xytext=(2, -12), textcoords="offset points", fontsize=8, color="0.3")
    if reference:
        speeds = [s for s, values in reference.items() for _ in values]
        values = np.array([complex(x) for values in reference.values() for x in values])
        ax.plot(speeds, values.real, "x", color="k", markersize=7, label=f"Re λ, {reference_label}")
        positive = values.imag > 0
        ax.plot(np.array(speeds)[positive], values.imag[positive], "x", color="0.45", markersize=7,
                label=f"Im λ, {reference_label}")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("forward speed v [m/s]")
    ax.set_ylabel("eigenvalue λ [1/s]")
    ax.legend(loc="lower left", fontsize=8)
    return ax


def write_eigenvalue_figure(chart, out, *, title: str, reference=None,
                            reference_label: str = "published") -> Path:
    """``eigenvalues.png`` in the folder ``out``; returns its path."""
    from matplotlib.figure import Figure
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    ax = fig.subplots()
    plot_eigenvalues(chart, ax, reference=reference, reference_label=reference_label)
    ax.set_title(title)
    path = out / "eigenvalues.png"
    fig.savefig(path, dpi=110)
    return path
