"""Figures of a simulated trajectory (gaits/figures/trajectory.py), for the thesis's unicycle
under constant torques: the time series panels draw the run's own coordinates and inputs (the
same numbers, one panel per unit: m, rad, N·m), the checks panel the run's residual |ω(q) q̇| of
each row and its energy balance, and the three files are written."""
from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure

from nhgait.dynamics import load_scene, simulate
from nhgait.gaits.figures.plots import figure_context, with_unit
from nhgait.gaits.figures.trajectory import (
    RESIDUAL_FLOOR,
    TrajectoryView,
    plot_checks,
    plot_time_series,
    time_series_rows,
    write_trajectory_figures,
)


class _Torques:
    def __call__(self, t, q, qdot):
        return [0.2, 0.1]


@pytest.fixture(scope="module")
def run(models):
    model = models["unicycle"]["reduced"]
    qdot0 = [0.5 * 0.1 * np.cos(0.3), 0.5 * 0.1 * np.sin(0.3), 2.0, 0.5]       # rolling: ẋ = r cos θ φ̇
    traj = simulate(model, (0.0, 1.0), [0.0, 0.0, 0.3, 0.0], qdot0,
                    controller=_Torques(), t_eval=np.linspace(0.0, 1.0, 11), rtol=1e-10, atol=1e-12)
    assert traj.success, traj.message
    scene = load_scene("unicycle")
    return traj, model, scene.units


def test_the_panels_draw_the_runs_numbers(run):
    traj, model, units = run
    ctx = figure_context(TrajectoryView.of(traj, model), model, units, None)
    rows = time_series_rows(traj, ctx)
    assert rows == 3                                   # m (x, y), rad (θ, φ), N·m (the torques)
    axes = plot_time_series(traj, ctx, Figure().subplots(rows, 1, squeeze=False)[:, 0])
    drawn = {line.get_label(): line.get_ydata() for ax in axes for line in ax.get_lines()}
    for i, name in enumerate(model.system.coordinates):
        np.testing.assert_array_equal(drawn[with_unit(ctx, name)], traj.q[:, i])
    assert [ax.get_ylabel() for ax in axes] == ["coordinates [m]", "coordinates [rad]", "inputs [N·m]"]
    res, energy = plot_checks(traj, ctx, Figure().subplots(2, 1))
    residual = np.abs(np.asarray(traj.constraint_residual)).reshape(len(traj.t), -1)
    for i, line in enumerate(res.get_lines()):
        np.testing.assert_array_equal(line.get_ydata(), np.maximum(residual[:, i], RESIDUAL_FLOOR))
    np.testing.assert_array_equal(energy.get_lines()[0].get_ydata(), np.asarray(traj.energy_balance))


def test_the_three_files(run, tmp_path):
    traj, model, units = run
    files = write_trajectory_figures(traj, model, tmp_path / "figs", units=units)
    assert [f.name for f in files] == ["time_series.png", "path.png", "checks.png"]
    assert all(f.read_bytes()[:4] == b"\x89PNG" for f in files)
