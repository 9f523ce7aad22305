"""Taking a gait out (issue 43): trajectory.csv and Solution.to_numpy()/to_csv(), the time-first
arrays and the deprecation of the former ones, one unit inference for CSV and figures.

References: numpy's own CSV reader (np.loadtxt) against the Solution's arrays; the units a
physicist gives the snakeboard's columns (x in m, θ in rad, τ_ψ in N·m)."""
from __future__ import annotations

import csv
import warnings

import numpy as np
import pytest

from nhgait.gaits import plan


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("plan")
    with warnings.catch_warnings():            # no internal use of the deprecated attributes
        warnings.filterwarnings("error", message=r"Solution\.", category=DeprecationWarning)
        result = plan("unicycle", "parallel-park", jit=False, out_dir=out)
    assert result.success
    return result, out


def _header(path):
    with open(path, newline="", encoding="utf-8") as fh:
        return next(csv.reader(fh))


def test_plan_writes_trajectory_csv_beside_solution_json(planned):
    result, out = planned
    sol = result.solution
    path = out / "trajectory.csv"
    assert (out / "solution.json").is_file() and path in result.files
    header = _header(path)
    n = len(sol.coordinates)
    names = [h.split(" [")[0] for h in header]
    assert names == ["t", *sol.coordinates, *(f"{c}_dot" for c in sol.coordinates),
                     *sol.state_names[n:], *sol.control_names]
    assert header[:3] == ["t [s]", "x [m]", "y [m]"] and "theta [rad]" in header
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert table.shape == (len(sol.t), len(header))
    np.testing.assert_array_equal(table[:, 0], sol.t)                       # time first
    np.testing.assert_array_equal(table[:, 1:1 + n], sol.z[:, :n])
    np.testing.assert_array_equal(table[:, 1 + 2 * n:1 + n + len(sol.state_names)], sol.z[:, n:])
    np.testing.assert_array_equal(table[:-1, -len(sol.control_names):], sol.u)
    np.testing.assert_array_equal(table[-1, -len(sol.control_names):], sol.u[-1])   # held at t_N
    np.testing.assert_array_equal(table, sol.to_numpy())


def test_velocity_columns_are_the_derivative_of_the_coordinates(planned):
    """q̇ in the table against a finite difference of q over the nodes (second order)."""
    sol = planned[0].solution
    n = len(sol.coordinates)
    table = sol.to_numpy()
    q, qd, t = table[:, 1:1 + n], table[:, 1 + n:1 + 2 * n], table[:, 0]
    fd = np.gradient(q, t, axis=0, edge_order=2)
    h = t[1] - t[0]
    scale = max(1.0, float(np.abs(qd).max()))
    assert np.abs(fd[1:-1] - qd[1:-1]).max() < 50 * h ** 2 * scale


def test_to_csv_round_trip(planned, tmp_path):
    sol = planned[0].solution
    path = sol.to_csv(tmp_path / "sub" / "gait.csv", units={"tau_phi": "N*m"})
    assert "tau_phi [N·m]" in _header(path)
    np.testing.assert_array_equal(np.loadtxt(path, delimiter=",", skiprows=1), sol.to_numpy())


def test_arrays_are_time_first_and_the_former_warn(planned):
    sol = planned[0].solution
    N = len(sol.t) - 1
    assert sol.z.shape == (N + 1, len(sol.state_names)) and sol.u.shape == (N, len(sol.control_names))
    assert sol.q.shape == sol.qdot.shape == (N + 1, len(sol.coordinates))
    with pytest.warns(DeprecationWarning, match=r"Solution\.states .* use Solution\.z, time first"):
        states = sol.states
    with pytest.warns(DeprecationWarning, match=r"Solution\.controls .* use Solution\.u, time first"):
        controls = sol.controls
    np.testing.assert_array_equal(states, sol.z.T)
    np.testing.assert_array_equal(controls, sol.u.T)
    np.testing.assert_array_equal(sol.state("y"), sol.z[:, sol.state_names.index("y")])


def test_csv_and_figures_say_the_same_units(tmp_path):
    """nhgait simulate's CSV header and the figures' axis labels: one inference. The snakeboard
    scene names no unit for x, θ, φ̇ (only for the inputs): x in m, θ in rad, φ̇ in rad/s."""
    from nhgait.dynamics import derive, load_scene, simulate
    from nhgait.gaits.figures.plots import figure_context, with_unit
    scene = load_scene("snakeboard")
    units = {k: v for k, v in dict(scene.units or {}).items() if k in scene.system.inputs}
    model = derive(scene.system, "reduced")
    traj = simulate(model, (0.0, 0.2), [0, 0, 0, 0, 0.3], [0, 0, 0, 0.5, 0.1], t_eval=[0.0, 0.1, 0.2])
    traj.to_csv(tmp_path / "run.csv", columns="qdot", units=units, system=scene.system)
    header = dict(h.split(" [", 1) for h in _header(tmp_path / "run.csv"))
    assert header["x"] == "m]" and header["theta"] == "rad]" and header["phi_dot"] == "rad/s]"
    ctx = figure_context(None, model, units)
    for name in ("x", "theta", "phi_dot"):
        assert with_unit(ctx, name).endswith(f"[{header[name]}")
