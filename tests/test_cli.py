"""The `nhgait` command line: derive and simulate (issue 2's done-when)."""
import csv

import numpy as np
import pytest

from nhgait.gaits.cli import main


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
    assert "index-2 DAE" in out and "Hamilton's equations" in out


def test_derive_scene_file_with_error_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[system]\ncoordinates = ["x"]\nlagrangian = "x_dot**2*k"\nwheels = 3\n')
    assert main(["derive", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "unknown key(s) ['wheels']" in err and "Traceback" not in err


def test_derive_no_cache(capsys):
    assert main(["derive", "knife_edge_incline", "--no-cache"]) == 0
    assert "principally kinematic" in capsys.readouterr().out
