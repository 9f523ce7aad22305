"""Model only what a scene needs (issue 9 item 4): the dependency closure of a run's outputs.

Independent references: a dependency graph worked out by hand for ``closure``; the KanesMethod
oracle (tests/oracles.py) for the shape trajectory of a shape-only run; the structure of the
snakeboard's reduced equations (its shape and momentum equations read neither x, y nor θ,
thesis eqs. 3.86–3.90) for the state count.
"""
from __future__ import annotations

import csv

import numpy as np
import pytest

from nhgait.dynamics import simulate  # the function (lazy export), before any submodule import
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.simulation.closure import closure, resolve_outputs
from nhgait.dynamics.simulation.controllers import snakeboard_pd

SNAKE_Q0, SNAKE_QDOT0 = np.array([0, 0, 0, 0, 1.0]), np.array([0, 0, 0, 1.0, 0])


def test_closure_of_a_hand_made_graph():
    """0 reads 1, 1 reads 2, 3 reads 0 and 4, 5 reads nothing:
    closure{0} = {0, 1, 2}; closure{3} = {0, 1, 2, 3, 4}; closure{5} = {5}."""
    dep = np.zeros((6, 6), dtype=bool)
    for i, j in ((0, 1), (1, 2), (3, 0), (3, 4), (2, 2)):
        dep[i, j] = True
    assert closure(dep, [0]) == (0, 1, 2)
    assert closure(dep, [3]) == (0, 1, 2, 3, 4)
    assert closure(dep, [5]) == (5,)
    assert closure(dep, []) == ()


def test_output_names_resolve_to_states(models):
    model = models["snakeboard"]["reduced"]
    names = model.state_names
    assert resolve_outputs(model, ["shape"]).seeds == (names.index("psi"), names.index("phi"))
    momenta = resolve_outputs(model, ["momenta"]).seeds
    assert [names[i] for i in momenta] == ["p", "pt_psi", "pt_phi"]
    with pytest.raises(ModelError, match="unknown output 'speed'") as err:
        resolve_outputs(model, ["speed", "psi", "torque"])
    assert len(err.value.problems) == 2
    assert "velocities (<coordinate>_dot)" in str(err.value)


def test_shape_only_run_integrates_five_of_eight_states(models):
    """The snakeboard's shape and momentum equations do not read the fiber (x, y, θ): a run
    that asks for shape and momenta integrates 5 of 8 states, and its shape trajectory equals
    the KanesMethod solution."""
    from oracles import oracle
    from scipy.integrate import solve_ivp
    model = models["snakeboard"]["reduced"]
    ctl = snakeboard_pd()
    t_eval = np.linspace(0.0, 3.0, 31)
    traj = simulate(model, (0.0, 3.0), SNAKE_Q0, SNAKE_QDOT0, controller=ctl, method="compiled",
                    rtol=1e-12, atol=1e-13, t_eval=t_eval, outputs=("shape", "momenta"))
    assert traj.success, traj.message
    assert traj.diagnostics["state_count"] == (5, 8)
    assert traj.state_names == ("psi", "phi", "p", "pt_psi", "pt_phi")
    assert list(traj.outputs) == ["psi", "phi", "p", "pt_psi", "pt_phi"]
    assert np.all(np.isnan(traj.q[:, :3]))                     # x, y, θ not modelled
    o = oracle("snakeboard")
    pv = model.numeric.params(None)
    ref = solve_ivp(lambda t, y: np.r_[y[5:], o.qddot(y[:5], y[5:], ctl(t, y[:5], y[5:]), pv)],
                    (0.0, 3.0), np.r_[SNAKE_Q0, SNAKE_QDOT0], method="DOP853", rtol=1e-12,
                    atol=1e-12, t_eval=t_eval)
    assert np.max(np.abs(traj.outputs["psi"] - ref.y[3])) < 1e-9
    assert np.max(np.abs(traj.outputs["phi"] - ref.y[4])) < 1e-9
    assert np.max(np.abs(traj.qdot[:, 3:] - ref.y[8:].T)) < 1e-9
    assert np.max(np.abs(traj.energy_balance)) < 1e-10         # the work quadrature is kept
    assert traj.settings["outputs"] == ("shape", "momenta")


def test_pose_output_pulls_in_the_reconstruction(models):
    """Asking for x needs the reconstruction ẋ(θ, shape, momenta): x, θ join, y does not."""
    traj = simulate(models["snakeboard"]["reduced"], (0.0, 1.0), SNAKE_Q0, SNAKE_QDOT0,
                    controller=snakeboard_pd(), method="compiled", outputs=("x",))
    assert traj.state_names == ("x", "theta", "psi", "phi", "p", "pt_psi", "pt_phi")
    full = simulate(models["snakeboard"]["reduced"], (0.0, 1.0), SNAKE_Q0, SNAKE_QDOT0,
                    controller=snakeboard_pd(), method="compiled", t_eval=traj.t)
    assert np.max(np.abs(traj.outputs["x"] - full.q[:, 0])) < 1e-8


def test_python_controller_reads_everything(models):
    """A controller without a CasADi form may read any state: nothing can be dropped."""
    ctl = snakeboard_pd()
    traj = simulate(models["snakeboard"]["reduced"], (0.0, 0.5), SNAKE_Q0, SNAKE_QDOT0,
                    controller=lambda t, q, qd: ctl(t, q, qd), outputs=("shape",))
    assert traj.diagnostics["state_count"] == (8, 8)


def test_cli_prints_the_state_count_and_writes_the_outputs(tmp_path, capsys):
    from importlib import resources

    from nhgait.gaits.cli.main import main
    text = resources.files("nhgait.dynamics.derivation").joinpath("scenes", "snakeboard.toml").read_text()
    scene = tmp_path / "shape.toml"
    scene.write_text(text.replace("samples = 501", 'samples = 51\noutputs = ["shape", "momenta"]'))
    out = tmp_path / "out" / "shape.csv"
    assert main(["simulate", str(scene), "--method", "compiled", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "5 of 8 states integrated (psi, phi, p, pt_psi, pt_phi)" in printed
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t [s]", "psi [rad]", "phi [rad]", "p [SI]",      # units as the figures'
                       "pt_psi [N·m·s]", "pt_phi [N·m·s]"]
    assert len(rows) == 52
    assert main(["simulate", str(scene), "--all-states", "--columns", "qdot", "--out", str(out)]) == 0
    assert "8 of 8 states" in capsys.readouterr().out
    header = next(csv.reader(out.open()))
    assert header[:3] == ["t [s]", "x [m]", "y [m]"]
    assert header[-1] == "phi_dot [rad/s]"


def test_named_quantities_as_outputs_match_their_formula(models):
    """Two named quantities requested together are both reported, each equal to its formula
    evaluated with numpy on the run's own q and q̇ columns (tolerance 1e-12: the same numbers
    through CasADi and through numpy)."""
    import sympy as sp
    model = models["snakeboard"]["reduced"]
    system = model.system
    x_dot, y_dot, psi = (sp.Symbol(n, real=True) for n in ("x_dot", "y_dot", "psi"))
    quantities = {"speed_sq": x_dot ** 2 + y_dot ** 2, "rotor_cos": sp.cos(psi)}
    traj = simulate(model, (0.0, 2.0), SNAKE_Q0, SNAKE_QDOT0, controller=snakeboard_pd(),
                    outputs=("speed_sq", "rotor_cos"), quantities=quantities, rtol=1e-9, atol=1e-11)
    assert traj.success, traj.message
    assert set(traj.outputs) == {"speed_sq", "rotor_cos"}
    coords = list(system.coordinates)
    qdot_x, qdot_y = traj.qdot[:, coords.index("x")], traj.qdot[:, coords.index("y")]
    np.testing.assert_allclose(traj.outputs["speed_sq"], qdot_x ** 2 + qdot_y ** 2, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(traj.outputs["rotor_cos"], np.cos(traj.q[:, coords.index("psi")]),
                               rtol=1e-12, atol=1e-12)
