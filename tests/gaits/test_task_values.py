"""The values of a ``[task]`` table (gaits/tasks/values.py): numbers and constant expressions
(pi/2 = 1.5707963267948966, math.pi's own value), ranges, tables, lists and horizons, each
parser recording what is wrong in the table's words and returning a usable value."""
from __future__ import annotations

import math

import pytest

from nhgait.gaits.tasks.values import control_bounds, horizon, names_list, number, table, value


def test_numbers_expressions_and_ranges():
    problems = []
    assert number("pi/2", "[task].final.theta", problems) == pytest.approx(math.pi / 2, rel=1e-15)
    assert number(3, "[task].x", problems) == 3.0
    assert value(["-inf", 2], "[task].bounds.x", problems) == (-math.inf, 2.0)
    assert not problems
    assert math.isnan(number("__import__('os')", "[task].x", problems)) and "[task].x" in problems[0]
    assert value([1, 2, 3], "[task].bounds.y", problems) == (-math.inf, math.inf)
    assert "a range is [lo, hi], got 3 entries" in problems[-1]


def test_tables_and_lists():
    problems = []
    assert table({"bounds": {"x": [0, "pi"]}}, "bounds", problems) == {"x": (0.0, pytest.approx(math.pi))}
    assert table({"bounds": {"x": 1.0}}, "bounds", problems) == {}
    assert table({"final": 3}, "final", problems) == {}
    assert names_list({"periodic": ["psi", "psi"]}, "periodic", problems) == ("psi", "psi")
    assert names_list({"periodic": "psi"}, "periodic", problems) == ()
    assert [p.split(":")[0].split(" ")[0] for p in problems] == [
        "[task].bounds.x", "[task].final", "[task].periodic", "[task].periodic"]


@pytest.mark.parametrize("item, expected", [(4.0, (4.0, None)), ([2, 6], (4.0, (2.0, 6.0))),
                                            ({"initial": 3, "min": 2, "max": 6}, (3.0, (2.0, 6.0)))])
def test_horizons(item, expected):
    problems = []
    assert horizon({"horizon": item}, problems) == expected and not problems


def test_bad_horizons_and_bounds_are_reported():
    problems = []
    assert horizon({}, problems) == (None, None) and "missing key 'horizon'" in problems[-1]
    horizon({"horizon": {"initial": 9, "min": 2, "max": 6}}, problems)
    assert "initial 9 outside [2, 6]" in problems[-1]
    assert horizon({"horizon": {"min": 2}}, problems) == (None, None)
    problems.clear()
    assert control_bounds({"control_bounds": {"tau": 2, "F": [-1, 3]}}, problems) == {
        "tau": (-2.0, 2.0), "F": (-1.0, 3.0)}
    assert control_bounds({"control_bounds": 5}, problems) == 5.0 and not problems
    control_bounds({"control_bounds": -1}, problems)
    assert "must be a positive number or a table" in problems[-1]
