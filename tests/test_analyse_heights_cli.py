"""``nhgait analyse --heights a,b [--figure F]``: the height functions at the point against the
snakeboard's hand-derived closed forms (docs/geometry.md: with the default r, c = J + J_r + 2J_w,
H_x = J_r r cos 2φ/c, H̄_x = J_r r (cos 2φ − ½cos²φ)/c, H_θ = J_r sin 2φ/c, H̄_θ = ¾ J_r sin 2φ/c),
the figure written, and bad pairs named in the one error message."""
from __future__ import annotations

import json
import math
from pathlib import Path

from nhgait.gaits.cli.main import main

SCENES = Path(__file__).resolve().parent / "scenes"


def test_snakeboard_heights_at_a_point_and_their_figure(capsys, tmp_path):
    figure = tmp_path / "heights.png"
    assert main(["analyse", "snakeboard", "--at", "phi=0.4", "--heights", "psi,phi", "--figure", str(figure),
                 "--json"]) == 0
    heights = json.loads(capsys.readouterr().out)["heights"]
    J_r, J, J_w, m = 0.2, 0.3, 0.1, 0.5
    c = J + J_r + 2 * J_w
    r, phi = math.sqrt(c / m), 0.4
    # central differences of step 1e-5 over a 2e-3 box: ~1e-9 relative
    tol = dict(rel_tol=1e-7, abs_tol=1e-9)
    assert math.isclose(heights["connection"]["x"], J_r * r * math.cos(2 * phi) / c, **tol)
    assert math.isclose(heights["connection"]["theta"], J_r * math.sin(2 * phi) / c, **tol)
    assert math.isclose(heights["scaled_momentum"]["x"],
                        J_r * r * (math.cos(2 * phi) - 0.5 * math.cos(phi) ** 2) / c, **tol)
    assert math.isclose(heights["scaled_momentum"]["theta"], 0.75 * J_r * math.sin(2 * phi) / c, **tol)
    assert heights["units"]["x"] == "m/rad²" and heights["units"]["theta"] == "rad/rad²"
    assert figure.stat().st_size > 20_000


def test_a_kinematic_robot_has_no_momentum_part(capsys):
    assert main(["analyse", str(SCENES / "snake3.toml"), "--at", "alpha1=0.5", "alpha2=-0.3",
                 "--heights", "alpha1,alpha2", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "height functions over (alpha1, alpha2)" in text and "scaled momentum" not in text


def test_bad_pairs_are_named_in_one_message(capsys):
    status = main(["analyse", "snakeboard", "--heights", "psi,phii", "--outputs", "xx"])
    err = capsys.readouterr().err
    assert status == 2 and "'phii' is not a shape coordinate" in err and "xx" in err
    assert main(["analyse", "snakeboard", "--figure", "f.png"]) == 2
    assert "give --heights a,b too" in capsys.readouterr().err
