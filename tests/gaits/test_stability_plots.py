"""The eigenvalue chart figure (gaits/figures/stability.py), drawn from a chart written here: a
pair λ = a(v) ± i b(v) with a(v) = 1 − v (stable above v = 1) and one real λ = −2. The figure's
points are exactly the chart's values (real parts of all, |imaginary parts| of the pairs once),
the change is a vertical line at v = 1, the stable range [1, 3] is shaded; no global state
changes; the file is written."""
from __future__ import annotations

import matplotlib as mpl
import numpy as np
from matplotlib.figure import Figure

from nhgait.dynamics.linearisation.chart import StabilityChange, StabilityChart
from nhgait.dynamics.linearisation.linearised import STABLE, UNSTABLE
from nhgait.gaits.figures.stability import plot_eigenvalues, write_eigenvalue_figure


def _chart():
    v = np.linspace(0.0, 3.0, 7)
    lam = np.column_stack([np.full(v.size, -2.0 + 0j), (1 - v) - 2j, (1 - v) + 2j])
    verdicts = tuple(STABLE if s > 1 else UNSTABLE for s in v)
    change = StabilityChange(1.0, UNSTABLE, STABLE, np.array([-2.0, -2j, 2j]))
    return StabilityChart(v, lam, verdicts, (change,), ("a", "b", "c"))


def test_the_points_are_the_charts_values():
    chart = _chart()
    before = dict(mpl.rcParams)
    ax = plot_eigenvalues(chart, Figure().subplots(), reference={2.0: [-1 + 2j]})
    assert dict(mpl.rcParams) == before
    real, imag = ax.lines[0], ax.lines[1]
    ref_real, ref_imag = [line for line in ax.lines if line.get_marker() == "x"]
    np.testing.assert_array_equal(real.get_ydata(), chart.eigenvalues.real.ravel())
    np.testing.assert_array_equal(imag.get_ydata(), np.full(7, 2.0))          # one of each pair
    np.testing.assert_array_equal(imag.get_xdata(), chart.speeds)
    assert list(ref_real.get_ydata()) == [-1.0] and list(ref_imag.get_ydata()) == [2.0]
    vertical = [line for line in ax.lines if list(line.get_xdata()) == [1.0, 1.0]]
    assert len(vertical) == 1
    shaded = list(ax.patches)
    assert len(shaded) == 1 and (shaded[0].get_x(), shaded[0].get_x() + shaded[0].get_width()) == (1.0, 3.0)


def test_the_file_is_written(tmp_path):
    path = write_eigenvalue_figure(_chart(), tmp_path / "fig", title="a test chart")
    assert path == tmp_path / "fig" / "eigenvalues.png" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
