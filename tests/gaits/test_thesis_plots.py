"""The thesis reproduction's figures (gaits/bench/thesis_plots.py) draw the data they are given —
a circle x = cos t, y = sin t and its multipliers λ = (sin t, cos t) written here — on the
axes they are given, the reference underneath, without pyplot's global figures."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from nhgait.gaits.bench import thesis_plots

T = np.linspace(0.0, 2 * np.pi, 50)


def _run(shift=0.0, lam=True):
    q = np.column_stack([np.cos(T) + shift, np.sin(T), T])
    return SimpleNamespace(t=T, q=q, coordinates=("x", "y", "theta"),
                           lam=np.column_stack([np.sin(T), np.cos(T)]) if lam else None)


def test_the_path_is_the_runs_x_and_y_with_the_reference_underneath():
    import matplotlib.pyplot as plt
    figures = plt.get_fignums()
    runs = {"kane": _run(), "reduced": _run(1e-3), "lagrange": _run(2e-3)}
    ax = thesis_plots.plot_path(runs, reference="kane", title="circle")
    assert plt.get_fignums() == figures                 # a bare Figure: no pyplot state
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == ["kane (reference)", "reduced", "lagrange"]
    assert lines[0].get_linewidth() > lines[1].get_linewidth()      # thick, underneath
    assert lines[0].get_zorder() < min(line.get_zorder() for line in lines[1:])
    for line, run in zip(lines, runs.values(), strict=True):
        np.testing.assert_array_equal(line.get_xdata(), run.q[:, 0])
        np.testing.assert_array_equal(line.get_ydata(), run.q[:, 1])
    assert ax.get_title() == "circle" and ax.get_xlabel() == "x [m]"


def test_a_coordinate_against_time_on_a_given_axes():
    from matplotlib.figure import Figure
    ax = Figure().add_subplot()
    same = thesis_plots.plot_coordinate({"reduced": _run()}, "theta", ax=ax)
    assert same is ax
    (line,) = ax.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), T)
    np.testing.assert_array_equal(line.get_ydata(), T)
    assert ax.get_ylabel() == "θ [rad]"


def test_the_multipliers_skip_the_runs_without_them_and_the_png_is_written(tmp_path):
    runs = {"lagrange": _run(), "reduced": _run(lam=False), "hamilton": _run(1e-3)}
    fig = thesis_plots.multiplier_figure(runs, reference="lagrange", title="λ")
    top, bottom = fig.axes
    assert [line.get_label() for line in top.get_lines()] == ["lagrange (reference)", "hamilton"]
    np.testing.assert_array_equal(top.get_lines()[0].get_ydata(), np.sin(T))
    np.testing.assert_array_equal(bottom.get_lines()[0].get_ydata(), np.cos(T))
    assert top.get_ylabel() == "λ₁ [N]" and bottom.get_ylabel() == "λ₂ [N]"
    path = thesis_plots.save(fig, tmp_path / "lambda.png", dpi=40)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
