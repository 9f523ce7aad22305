"""Distinct styles for many series (gaits/figures/style.py): no two of up to 40 series share
colour, marker and line style together; the first ten are tab10's plain lines; nothing global
(matplotlib's rcParams) changes."""
from __future__ import annotations

import pytest

from nhgait.gaits.figures.style import COLORS, series_styles


@pytest.mark.parametrize("markers", [False, True])
def test_styles_are_pairwise_distinct(markers):
    styles = series_styles(40, markers=markers)
    keys = [(s["color"], s.get("marker"), s["linestyle"]) for s in styles]
    assert len(styles) == 40 and len(set(keys)) == 40
    assert all(("marker" in s) == markers for s in styles[:10])
    assert [s["color"] for s in styles[:10]] == list(COLORS)


def test_no_global_state_changes():
    import matplotlib as mpl
    before = dict(mpl.rcParams)
    series_styles(25)
    assert dict(mpl.rcParams) == before
