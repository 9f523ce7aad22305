"""Suggestions for misspelt names (dynamics/suggestions.py): close names by difflib's ratio, and
also names equal up to underscores, hyphens and case; the error message's tail lists the known
names, cut after KNOWN_MAX."""
from __future__ import annotations

from nhgait.dynamics.suggestions import KNOWN_MAX, close_matches, did_you_mean, known_names


def test_close_matches_find_typos_and_spelling_variants():
    known = ["theta", "phi_dot", "tau_psi", "x"]
    assert close_matches("thetta", known)[0] == "theta"
    assert close_matches("PhiDot", known) == ["phi_dot"]         # underscores and case ignored
    assert close_matches("zzz", known) == []


def test_did_you_mean_phrases_one_or_several_or_nothing():
    assert did_you_mean("mas", ["mass", "inertia"]) == "did you mean 'mass'?"
    two = did_you_mean("m1", ["m1a", "m1b"])             # equally close: both, in either order
    assert two in ("did you mean 'm1a' or 'm1b'?", "did you mean 'm1b' or 'm1a'?")
    assert did_you_mean("qqq", ["mass"]) == ""


def test_known_names_lists_them_and_cuts_long_lists():
    assert known_names("mas", ["mass", "I"], label="parameters") == \
        ": did you mean 'mass'? (parameters: mass, I)"
    assert known_names("zzz", [], label="inputs") == " (inputs: none)"
    many = [f"p{i}" for i in range(KNOWN_MAX + 5)]
    tail = known_names("zzz", many)
    assert tail.endswith(", … and 5 more)") and f"p{KNOWN_MAX - 1}," in tail and f"p{KNOWN_MAX}," not in tail
