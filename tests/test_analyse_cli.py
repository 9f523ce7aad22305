"""``nhgait analyse`` end to end: the JSON object's published values, the text, and bad input
as one message with "did you mean …?" (exit status 2)."""
from __future__ import annotations

import json
from pathlib import Path

from nhgait.gaits.cli.main import main

SCENES = Path(__file__).resolve().parent / "scenes"


def test_json_of_the_snakeboard(capsys):
    assert main(["analyse", "snakeboard", "--at", "phi=0.7", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["growth_vector"] == [3, 4, 5] and out["degree_of_nonholonomy"] == 3
    assert out["accessibility"]["rank"] == out["accessibility"]["dimension"] == 8
    assert out["accessibility"]["depth"] >= 2 and out["classification"] == "mixed"
    assert "observability" not in out


def test_json_with_outputs(capsys):
    scene = str(SCENES / "knife_edge.toml")
    assert main(["analyse", scene, "--at", "x_dot=1", "theta_dot=0.5", "--outputs", "theta", "--json"]) == 0
    obs = json.loads(capsys.readouterr().out)["observability"]
    assert obs["rank"] < obs["dimension"] == 5 and {"x", "y"} <= set(obs["unobservable"])


def test_text_names_brackets_and_confinement(capsys):
    assert main(["analyse", str(SCENES / "free_two_link.toml"), "--at", "alpha=0.5", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "purely mechanical" in text and "confined" in text and "conserved" in text
    assert main(["analyse", str(SCENES / "knife_edge.toml"), "--quiet"]) == 0
    assert "depth 2: [X_p, X_theta]" in capsys.readouterr().out


def test_bad_names_in_one_message(capsys):
    status = main(["analyse", "unicycle", "--at", "thetaa=1", "phi=oops", "--outputs", "x,yy"])
    err = capsys.readouterr().err
    assert status == 2
    assert "did you mean 'theta'" in err and "did you mean 'y'" in err and "phi" in err
    assert "Traceback" not in err
