"""The `nhgait` command line: derive and simulate (issue 2's done-when)."""
import csv

import numpy as np
import pytest

from nhgait.gaits.cli.main import main


def test_derive_builtin_prints_reduced_equations(capsys):
    assert main(["derive", "unicycle"]) == 0
    out = capsys.readouterr().out
    assert "6 = 2n − k first-order ODEs" in out
    assert "dx/dt = p*r*cos(theta)/(J_phi + m*r**2)" in out
    assert "dp/dt = tau_phi" in out


def test_derive_steps_markdown_and_latex(capsys):
    assert main(["derive", "snakeboard", "--steps", "markdown"]) == 0
    md = capsys.readouterr().out
    assert all(f"### Step {i}:" in md for i in range(1, 21))
    assert main(["derive", "snakeboard", "--steps", "latex"]) == 0
    assert "\\paragraph{Step 17: Reduced Poisson structure matrix}" in capsys.readouterr().out


def test_derive_table_and_all_formulations(capsys):
    assert main(["derive", "unicycle", "--formulation", "all", "--table"]) == 0
    out = capsys.readouterr().out
    assert "full **(chosen)**" in out
    assert "index-2 DAE" in out
    assert "Hamilton's equations" in out


def test_derive_scene_file_with_error_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[system]\ncoordinates = ["x"]\nlagrangian = "x_dot**2*k"\nwheels = 3\n')
    assert main(["derive", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "unknown key(s) ['wheels']" in err
    assert "Traceback" not in err


def test_derive_no_cache(capsys):
    assert main(["derive", "knife_edge_incline", "--no-cache"]) == 0
    assert "principally kinematic" in capsys.readouterr().out


@pytest.mark.parametrize("formulation", ["reduced", "lagrange", "hamilton"])
def test_simulate_snakeboard_scene_writes_csv(tmp_path, formulation, capsys):
    out = tmp_path / "traj.csv"
    assert main(["simulate", "snakeboard", "--formulation", formulation, "--rtol", "1e-10",
                 "--out", str(out)]) == 0
    with out.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t [s]", "x [m]", "y [m]", "theta [rad]", "psi [rad]", "phi [rad]"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (501, 6)                         # `samples` uniform times
    np.testing.assert_allclose(data[:, 0], np.linspace(0, 10 * np.pi, 501), rtol=0, atol=1e-12)
    # independent KanesMethod + DOP853 at 1e-12: x(10π) = 2.2990248, y(10π) = −0.00906814
    assert data[-1, 1] == pytest.approx(2.2990248, abs=2e-7)
    assert data[-1, 2] == pytest.approx(-0.00906814, abs=2e-8)


def test_simulate_inconsistent_initial_state_exits_2(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    text = open(__import__("nhgait.dynamics.derivation", fromlist=["x"]).__path__[0]
                + "/scenes/unicycle.toml").read()
    scene.write_text(text.replace("qdot0 = [0.1, 0.0, 1.0, 1.0]", "qdot0 = [0.5, 0.0, 1.0, 1.0]"))
    assert main(["simulate", str(scene), "--out", str(tmp_path / "t.csv")]) == 2
    assert "violates the constraints" in capsys.readouterr().err


def test_derive_checks(capsys):
    assert main(["derive", "unicycle", "--checks"]) == 0
    out = capsys.readouterr().out
    assert "reduced bracket: almost-Poisson (the Jacobi identity does not hold" in out
    assert "(Jacobi ⇔ holonomic): consistent" in out
    assert "p = J_phi*phi_dot + m*r*x_dot*cos(theta) + m*r*y_dot*sin(theta)" in out


def test_a_long_simulation_says_it_is_still_integrating(capsys):
    """A run whose first steps do not foresee its cost (a force with the sign of a velocity
    chatters across it: a user's unicycle said nothing for 150 s before max_steps stopped it)
    says every HEARTBEAT_S that it goes on, and nothing once it has ended: the block waits for
    four lines (polled; 120 s is a hang guard), and once it is left the heartbeat thread is gone."""
    import threading
    import time

    from nhgait.gaits.cli.simulate import _still_integrating
    said, deadline = [], time.monotonic() + 120.0
    with _still_integrating("unicycle with DOP853 to t = 6.28 s", every=0.05):
        while len(said) < 4:
            said += capsys.readouterr().err.splitlines()
            assert time.monotonic() < deadline, said
            time.sleep(0.01)
    said += capsys.readouterr().err.splitlines()
    assert len(said) >= 4
    assert said[0].startswith("nhgait simulate: still integrating unicycle with DOP853 to t = 6.28 s (0 s;")
    assert all(line.startswith("nhgait simulate: still integrating") for line in said)
    assert "simulate-heartbeat" not in {t.name for t in threading.enumerate()}
    assert capsys.readouterr().err == ""
