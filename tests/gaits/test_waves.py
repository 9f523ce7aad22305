"""A guess as data (gaits/planning/waves.py) on a particle of mass m in the plane, whose reduced state is
(x, y, p = m ẋ, pt_y = m ẏ): the ramps and waves written out by hand, c(t) = a + (b − a) t/T +
A sin(k 2π t/T + φ), and the rules for where a free coordinate sits and how far a wave may swing."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nhgait.gaits.planning.waves import ShapeGuess, amplitude, centre, ends, free_start, guess_from_shape
from nhgait.ocp import OptimalControlProblem

MASS = 2.0


def _problem(particle, **extra):
    return OptimalControlProblem(particle, 2.0, 8, **{"initial": {"x": 0.0, "p": 0.0, "pt_y": 0.0},
                                                      "final": {"x": 1.0}, **extra})


def test_where_a_coordinate_sits_and_how_far_it_may_swing(particle):
    free = _problem(particle)
    assert ends(free, "x") == (0.0, 1.0) and ends(free, "y") == (0.0, 0.0)    # y free: at its centre, 0
    assert ends(free, "y", start=(("y", 0.4),)) == (0.4, 0.4)
    bounded = _problem(particle, state_bounds={"y": (0.5, 1.5), "x": (-0.3, 1.2)})
    assert centre(bounded, "y") == 1.0 and centre(bounded, "x") == 0.0         # 0 inside: stays
    assert amplitude(bounded, "x") == pytest.approx(0.2)                        # min(0 + 0.3, 1.2 − 1)
    assert amplitude(bounded, "y") == pytest.approx(0.5) and amplitude(free, "x") == 1.0
    assert free_start(free, ("x", "y")) == {"y": (-math.pi, math.pi)}
    assert free_start(bounded, ("x", "y")) == {"y": (0.5, 1.5)}


def test_a_shape_guess_is_its_ramps_and_waves(particle):
    problem = _problem(particle, state_bounds={"y": (-1.0, 1.0)})
    shape = ShapeGuess("loop", waves=(("x", 0.3, 1, 0.0), ("y", 0.2, 2, math.pi / 2)))
    guess = guess_from_shape(problem, shape, ("x", "y"))
    t, T, w = problem.grid(), 2.0, math.pi
    x = t / T + 0.3 * np.sin(w * t)
    y = 0.2 * np.sin(2 * w * t + math.pi / 2)
    xdot = 1 / T + 0.3 * w * np.cos(w * t)
    ydot = 0.2 * 2 * w * np.cos(2 * w * t + math.pi / 2)
    Z = np.asarray(guess.states)
    np.testing.assert_allclose(Z, np.vstack([x, y, MASS * xdot, MASS * ydot]), rtol=1e-13, atol=1e-13)
    assert guess.label == "loop" and np.asarray(guess.controls).shape == (2, 8) and guess.horizon == T
