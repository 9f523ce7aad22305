"""``--set KEY=VALUE`` on a scene's ``[simulation]`` (dynamics/derivation/input/assignments.py): values
land where the file would have them (numbers as numbers, words and input laws as text, one
entry of a list in coordinate order), and every malformed or unknown key is named in one
ModelError, with the close matches."""
from __future__ import annotations

import pytest

from nhgait.dynamics.derivation.input.assignments import apply_simulation_overrides, parse_assignment
from nhgait.dynamics.errors import ModelError

DOCUMENT = {"system": {"coordinates": ["x", "y", "theta"], "inputs": ["tau"], "parameters": {"m": 1.0}},
            "simulation": {"t_final": 5, "q0": [0.0, 0.0, 0.0], "method": "DOP853"}}


def test_parse_splits_at_the_first_equals_sign():
    problems = []
    a = parse_assignment("final.x= 2*pi=1 ", problems)
    assert (a.key, a.parts, a.value) == ("final.x", ("final", "x"), "2*pi=1") and not problems
    assert parse_assignment("final.x", problems) is None and parse_assignment("=3", problems) is None
    assert len(problems) == 2 and all("expected key=value" in p for p in problems)


def test_values_land_where_the_file_has_them():
    out = apply_simulation_overrides(DOCUMENT, ["t_final=20", "rtol=1e-10", "q0.theta=0.3",
                                                "qdot0.x_dot=1.5", "inputs.tau=0.2*sin(t)", "params.m=2",
                                                "method=compiled"])
    sim = out["simulation"]
    assert sim["t_final"] == 20 and isinstance(sim["t_final"], int) and sim["rtol"] == 1e-10
    assert sim["q0"] == [0.0, 0.0, 0.3] and sim["qdot0"] == {"x_dot": 1.5}
    assert sim["inputs"] == {"tau": "0.2*sin(t)"} and sim["parameters"] == {"m": 2}
    assert sim["method"] == "compiled"
    assert DOCUMENT["simulation"]["t_final"] == 5                   # the document itself unchanged
    assert apply_simulation_overrides(DOCUMENT, []) is DOCUMENT


def test_every_bad_key_in_one_error():
    with pytest.raises(ModelError) as caught:
        apply_simulation_overrides(DOCUMENT, ["t_finl=3", "q0.z=1", "params.mass=2", "q0=1", "rtol.x=1",
                                              "nothing"])
    text = str(caught.value)
    assert "6 problem" in text
    assert "did you mean 't_final'" in text and "'z' is not a coordinate" in text
    assert "unknown parameter 'mass'" in text and "q0 needs a name" in text and "rtol takes no" in text
