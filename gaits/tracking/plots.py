"""Figures of a tracking study (:func:`~nhgait.gaits.tracking.study.track`). Every function takes its
axes, returns what it drew on, never calls ``plt.show()`` and never changes ``rcParams``.

* :func:`plot_tracking_paths` — the planar frame's path of every sample, open loop beside
  closed loop, over the plan's (the noise-free runs drawn apart);
* :func:`plot_final_positions` — where each sample ends relative to the plan's end, both
  loops on one scale;
* :func:`plot_tracking_errors` — the position error ‖p(t) − p_ref(t)‖ over time and the error
  of each configuration coordinate, every sample, open and closed loop;
* :func:`write_tracking_figures` — tracking_paths.png and tracking_errors.png.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .runs import LOOPS

__all__ = ["plot_tracking_paths", "plot_final_positions", "plot_tracking_errors", "write_tracking_figures"]

_COLOR = {"open_loop": "tab:red", "closed_loop": "tab:blue"}
_TITLE = {"open_loop": "open loop", "closed_loop": "closed loop (the plan's LQR)"}


def _position_label(report, axis: int, names, prefix: str = "") -> str:
    from ..figures.plots import label
    return f"{prefix}{label(names[axis])} [{report['position_unit']}]"


def plot_tracking_paths(result, axes, names=("x", "y")):
    """Two axes: each loop's sample paths (thin), its noise-free run (dashed) and the plan's
    reference path (black)."""
    report = result.report
    reference = (np.asarray(result.samples[0]["reference_position"])
                 if "reference_position" in result.samples[0] else None)
    for ax, loop in zip(axes, LOOPS, strict=False):
        for answer in result.samples[1:]:
            p = np.asarray(answer[loop]["position"])
            if p.size:
                ax.plot(p[:, 0], p[:, 1], color=_COLOR[loop], lw=0.7, alpha=0.45)
        free = np.asarray(result.samples[0][loop]["position"])
        if free.size:
            ax.plot(free[:, 0], free[:, 1], color="k", ls="--", lw=1.0, label="noise-free (mismatch only)")
        if reference is not None:
            ax.plot(reference[:, 0], reference[:, 1], color="k", lw=1.6, label="plan")
        f = report[loop]["final_position_error"]
        ax.set_title(f"{_TITLE[loop]}\nfinal error median {f['median']:.3g}, max {f['max']:.3g} "
                     f"{report['position_unit']}", fontsize="medium")
        ax.set_xlabel(_position_label(report, 0, names))
        ax.set_ylabel(_position_label(report, 1, names))
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    return axes


def plot_final_positions(result, ax, names=("x", "y")):
    """Each sample's final position minus the plan's, open loop and closed loop on one axes
    (equal scales), the noise-free runs as crosses."""
    report = result.report
    end = np.asarray(result.samples[0]["reference_position"])[-1]
    for loop in LOOPS:
        ends = np.array([answer[loop]["position"][-1] for answer in result.samples[1:]
                         if answer[loop]["position"]])
        if ends.size:
            ax.scatter(ends[:, 0] - end[0], ends[:, 1] - end[1], s=14, color=_COLOR[loop], alpha=0.7,
                       label=_TITLE[loop])
        free = result.samples[0][loop]["position"]
        if free:
            ax.scatter([free[-1][0] - end[0]], [free[-1][1] - end[1]], marker="x", s=60, color=_COLOR[loop])
    ax.scatter([0.0], [0.0], marker="+", s=120, color="k", label="the plan's end (×: noise-free runs)")
    ax.set_xlabel(_position_label(report, 0, names, "Δ"))
    ax.set_ylabel(_position_label(report, 1, names, "Δ"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="best")
    ax.set_title("final positions relative to the plan's end", fontsize="medium")
    return ax


def plot_tracking_errors(result, axes, coordinates, units):
    """Row 0: the position error over time; then one row per configuration coordinate (its
    error z_i − z_ref,i in its unit); every sample, open loop in red, closed loop in blue."""
    report = result.report
    for loop in LOOPS:
        for j, answer in enumerate(result.samples[1:]):
            run = answer[loop]
            t = np.asarray(run["t"])
            if not t.size:
                continue
            kw = {"color": _COLOR[loop], "lw": 0.6, "alpha": 0.5, "label": _TITLE[loop] if j == 0 else None}
            axes[0].plot(t, run["position_error"], **kw)
            errors = np.asarray(run["coordinate_errors"])
            for i, ax in enumerate(axes[1:]):
                ax.plot(t, errors[:, i], **{**kw, "label": None})
    axes[0].set_ylabel(f"position error [{report['position_unit']}]")
    axes[0].set_yscale("log")
    axes[0].legend(fontsize="small", loc="best")
    from ..figures.plots import label
    for ax, name in zip(axes[1:], coordinates, strict=False):
        ax.set_ylabel(f"{label(name)} error [{units.get(name, '')}]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return axes


def write_tracking_figures(result, out: Path, *, units=None) -> list:
    """tracking_paths.png and tracking_errors.png in ``out``; returns the paths."""
    from matplotlib.figure import Figure
    report = result.report
    names = [n for n in report["closed_loop"]["state_errors"]]
    coordinates = names[:len(result.samples[0]["closed_loop"]["coordinate_errors"][0])]
    units = {name: report["closed_loop"]["state_errors"][name]["unit"] for name in names}
    frame = result.samples[0].get("position_names", coordinates[:2])
    fig = Figure(figsize=(11, 9), layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=(1, 1.15))
    plot_tracking_paths(result, [fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1])], names=frame)
    plot_final_positions(result, fig.add_subplot(grid[1, :]), names=frame)
    fig.suptitle(_title(report), fontsize="medium")
    fig.savefig(out / "tracking_paths.png", dpi=110, bbox_inches="tight")
    fig = Figure(figsize=(8, 1.9 * (1 + len(coordinates))), layout="constrained")
    axes = fig.subplots(1 + len(coordinates), 1, sharex=True, squeeze=False)[:, 0]
    plot_tracking_errors(result, axes, coordinates, units)
    fig.suptitle(_title(report), fontsize="medium")
    fig.savefig(out / "tracking_errors.png", dpi=110, bbox_inches="tight")
    return [out / "tracking_paths.png", out / "tracking_errors.png"]


def _title(report) -> str:
    mism = ", ".join(f"{k} ×{v:g}" for k, v in report["mismatch"].items()) or "no mismatch"
    return (f"{report['system']}: {report['samples']} samples, {mism}, noise {report['noise']['state']:g} "
            f"(state) / {report['noise']['input']:g} (input) of scale")
