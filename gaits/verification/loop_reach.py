"""Whether shape loops within the task's bounds can move a robot toward its target, in one sentence.

By Stokes's theorem (:mod:`nhgait.dynamics.geometry.stokes`) a loop in the shape plane (r_a, r_b)
moves the body, to second order, by ∬ H_ab over the region it encloses (counter-clockwise
positive). Projected on the target direction d̂ (the task's fibre change, in the body frame at
the start), h = H_ab·d̂; a single loop inside the bounded box moves the body toward the target at
most about P = max(∬ max(h, 0), ∬ max(−h, 0)) (a counter-clockwise loop around where h > 0 or a
clockwise one around where h < 0; Hatton & Choset's optimal-gait principle). When P = 0 on every
bounded plane no loop within the bounds moves the robot that way; otherwise the target needs at
least |d|/P loops. For a mixed robot this is the loops' geometric part (momentum held at zero).

:func:`reach_sentence` says which, with the numbers a user can act on; :func:`reach_lines` is
the failure report's line (:mod:`.diagnosis`).
"""
from __future__ import annotations

import math
from itertools import combinations

import numpy as np

__all__ = ["reach_sentence", "reach_lines"]

#: grid points per axis of the bounded shape plane
POINTS = 25
#: grid cells where |h| exceeds this times its median are left out: they lie at the singular set
#: of A (the 3-link snake's α₁ = α₂), where H is unbounded and no loop's estimate means anything
SINGULAR_RATIO = 50.0


def _plane_reach(connection, pair, bounds, at, direction) -> tuple:
    """(P+, P−, cells left out) of one bounded plane (module docstring, :data:`SINGULAR_RATIO`)."""
    from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights_numeric
    grid = evaluate_heights_numeric(connection, *pair, HeightGrid(bounds=bounds, points=POINTS, at=at))
    with np.errstate(all="ignore"):
        h = np.tensordot(direction, grid.heights, axes=1)
        size = np.abs(h[np.isfinite(h)])
        typical = float(np.median(size)) if size.size else 0.0
        keep = np.isfinite(h) & (np.abs(h) <= SINGULAR_RATIO * max(typical, 1e-300))
    h = np.where(keep, h, 0.0)
    cell = np.ptp(grid.a_values) * np.ptp(grid.b_values) / (POINTS - 1) ** 2
    return (float(np.sum(np.maximum(h, 0.0)) * cell), float(np.sum(np.maximum(-h, 0.0)) * cell),
            int(h.size - keep.sum()))


def reach_sentence(problem) -> str:
    """The sentence of the module docstring for ``problem`` ('' when it does not apply: no local
    connection, no target direction, fewer than two bounded shape coordinates)."""
    from ..tasks.reachability import numeric_connection_of, target_of
    numeric = numeric_connection_of(problem)
    target = None if numeric is None else target_of(problem, numeric.fiber)
    bounded = {} if numeric is None else {c: problem.bounds(problem.state_bounds, c) for c in numeric.shape
                                          if c in problem.state_bounds}
    bounded = {c: b for c, b in bounded.items() if all(map(math.isfinite, b)) and b[0] < b[1]}
    if target is None or len(bounded) < 2:
        return ""
    names = numeric.names
    q0 = np.array([problem.fixed_value(problem.initial, c) or 0.0 for c in names])
    d = target.d
    body = np.linalg.solve(numeric.frame(q0), d)
    direction = body / np.linalg.norm(body)
    best, dropped = None, 0
    for pair in combinations(bounded, 2):
        plus, minus, out = _plane_reach(numeric, pair, bounded, dict(zip(names, q0, strict=True)), direction)
        dropped += out
        if best is None or max(plus, minus) > best[0]:
            best = (max(plus, minus), pair, "counter-clockwise" if plus >= minus else "clockwise")
    distance = float(np.linalg.norm(d))
    wanted = " and ".join(f"{c} by {v:+.3g}" for c, v in zip(numeric.fiber, d, strict=True) if v)
    boxes = ", ".join(f"{c} in [{lo:g}, {hi:g}]" for c, (lo, hi) in bounded.items())
    mixed = " (the shape loops' geometric part, momentum held at zero)" if numeric.n_momenta else ""
    mixed += " (away from the singular set of the connection)" if dropped else ""
    if best[0] <= 1e-9 * distance:
        return (f"not reachable by shape loops within the bounds{mixed}: the height function of the target "
                f"direction ({wanted}) is zero over {boxes}, so no loop there moves the robot toward it — "
                "widen the shape bounds, free another shape coordinate or change the target")
    P, (a, b), orientation = best
    loops = math.ceil(distance / P)
    return (f"reachable within the bounds{mixed}: one {orientation} loop in ({a}, {b}) within {boxes} "
            f"moves the robot at most about {P:.3g} toward the target ({wanted}), so it needs at least "
            f"{loops} loop{'s' if loops > 1 else ''} in T = {float(problem.horizon):g} s"
            + (" — if that is too many, widen the shape bounds or lengthen the horizon" if loops > 1 else ""))


def reach_lines(result) -> list:
    """The failure report's line for a failed plan's problem ([] when it does not apply)."""
    problem = getattr(getattr(result, "solution", None), "problem", None)
    if problem is None:
        return []
    sentence = reach_sentence(problem)
    return [f"target direction: {sentence}"] if sentence else []
