"""The speeds of a stability chart (dynamics/linearisation/chart.py ``parse_speeds``): a range
as numpy's linspace, a list as written, anything else one clear ModelError."""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.linearisation.chart import parse_speeds


def test_a_range_and_a_list():
    np.testing.assert_array_equal(parse_speeds("0:10:101"), np.linspace(0.0, 10.0, 101))
    assert parse_speeds("0:10:101")[1] == pytest.approx(0.1, rel=1e-15)
    np.testing.assert_array_equal(parse_speeds("0.5,1,2.5"), [0.5, 1.0, 2.5])


@pytest.mark.parametrize("text, says", [("3:1:10", "start < stop"), ("0:1:1", "count"),
                                        ("1", "at least two increasing"), ("2,1", "increasing"),
                                        ("a:b:c", "expected start:stop:count"), ("1,nan", "increasing")])
def test_bad_speeds_raise_one_clear_error(text, says):
    with pytest.raises(ModelError, match=says):
        parse_speeds(text)
