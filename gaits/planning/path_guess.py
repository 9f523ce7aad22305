"""A guess along the positions a task states between its ends (waypoints and phase ends).

For a system with a planar frame (x, y, θ) whose task fixes positions between the ends (a
waypoint or a phase that ends at a place, exactly or within a range), the guess drives the
frame along straight legs through those places: with knots (t_j, x_j, y_j) at the start, at
each such event (its node time on the problem's grid, the middle of a range) and at the end,

    x(t), y(t)  piecewise linear through the knots,
    θ(t)        the heading of each leg, atan2(Δy, Δx) − α (α: the forward axis's angle from
                the heading, ``[system] forward``), unwrapped along the path (angles are never
                wrapped), interpolated linearly from the stated start (and end) heading to the
                legs' directions at their middles,

the other coordinates on their ramps (:func:`~nhgait.gaits.planning.guesses.guess_from_shape`'s), the
rates q̇ by differences over the grid, mapped to the model's state by ``state(q, q̇)``; the
controls are zero. The path is kinematically consistent along each leg (the frame moves along
its forward axis); at the knots the heading turns in place, which the solver smooths.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from nhgait.ocp import InitialGuess

__all__ = ["applies", "path_guess", "LABEL"]

LABEL = "path through the stated places"


def _frame(problem):
    frame = getattr(problem.model.system, "planar_frame", None)
    return tuple(frame) if frame else None


def _place(problem, conditions, name):
    """The value (or the middle of the range) a condition table gives ``name``, else None."""
    if name not in conditions:
        return None
    lo, hi = problem.bounds(conditions, name)
    if math.isfinite(lo) and math.isfinite(hi):
        return (lo + hi) / 2
    return lo if math.isfinite(lo) else (hi if math.isfinite(hi) else None)


def _knots(problem) -> list:
    """(node, x, y) of the events that state a position (x or y), in node order; a coordinate
    an event leaves open is filled in by interpolation (None here)."""
    from nhgait.ocp.schedule import schedule
    frame = _frame(problem)
    out = []
    for event in schedule(problem).events:
        x, y = (_place(problem, event.conditions, c) for c in frame[:2])
        if x is not None or y is not None or event.label in ("initial", "final"):
            out.append((event.node, x, y))
    return out


def applies(problem) -> bool:
    """A planar frame and a position stated at an event between the ends."""
    if _frame(problem) is None:
        return False
    N = problem.intervals
    return any(0 < node < N and (x is not None or y is not None) for node, x, y in _knots(problem))


def _filled(t_knots, values, default) -> np.ndarray:
    """The knot values with the missing ones interpolated (the start's default when none)."""
    values = np.array([np.nan if v is None else v for v in values], float)
    known = np.isfinite(values)
    if not known.any():
        return np.full(values.size, default)
    return np.interp(t_knots, t_knots[known], values[known])


class _Knots(NamedTuple):
    """The path's knots: their times (on the problem's grid) and positions, each (K,)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray


def _headings(t, knots: _Knots, ends: tuple, alpha: float) -> np.ndarray:
    """θ(t): the legs' directions at their middles, the stated start and end headings
    (``ends``: (start, end), each None when the task leaves it open)."""
    (t_knots, x, y), (start, end) = knots, ends
    legs = [(0.5 * (t_knots[j] + t_knots[j + 1]), math.atan2(y[j + 1] - y[j], x[j + 1] - x[j]) - alpha)
            for j in range(len(x) - 1) if math.hypot(x[j + 1] - x[j], y[j + 1] - y[j]) > 0]
    times, angles = [t[0]], [start if start is not None else (legs[0][1] if legs else 0.0)]
    for time, angle in legs:                      # unwrapped: the nearest turn from the previous heading
        angles.append(angle + 2 * math.pi * round((angles[-1] - angle) / (2 * math.pi)))
        times.append(time)
    if end is not None:                           # a stated heading is that angle, not one a turn away
        times.append(t[-1])
        angles.append(end)
    return np.interp(t, times, angles)


def path_guess(problem, coordinates: tuple, ramps) -> InitialGuess:
    """The guess of the module docstring; ``ramps(name)`` gives (value at 0, value at T) of
    any other coordinate (the shape loops' ramps)."""
    fx, fy, fh = _frame(problem)
    t = problem.grid()
    knots = _knots(problem)
    t_knots = t[[node for node, _, _ in knots]]
    x = _filled(t_knots, [k[1] for k in knots], ramps(fx)[0])
    y = _filled(t_knots, [k[2] for k in knots], ramps(fy)[0])
    q = np.zeros((len(coordinates), t.size))
    for i, name in enumerate(coordinates):
        a, b = ramps(name)
        q[i] = a + (b - a) * (t - t[0]) / (t[-1] - t[0])
    q[coordinates.index(fx)] = np.interp(t, t_knots, x)
    q[coordinates.index(fy)] = np.interp(t, t_knots, y)
    alpha = float(getattr(problem.model.system, "forward_angle", 0.0))
    start, end = problem.fixed_value(problem.initial, fh), problem.fixed_value(problem.final, fh)
    q[coordinates.index(fh)] = _headings(t, _Knots(t_knots, x, y), (start, end), alpha)
    qdot = np.gradient(q, t, axis=1)
    state = problem.model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q[:, j], qdot[:, j], problem.params)).ravel()
                         for j in range(t.size)])
    return InitialGuess(Z, np.zeros((problem.n_controls, problem.intervals)), horizon=float(problem.horizon),
                        label=LABEL)
