"""Targets no admissible input can reach, refused before the solver looks for them.

A plan to move the car 10 km in 6 s at |F| ≤ 5 N has no solution, and FATROP searched for one
for minutes. :func:`unreachable_targets` compares each coordinate's required displacement
(from a fixed initial value to the final value or range) with the bound of
:func:`nhgait.dynamics.derivation.reach.displacement_bounds` — an upper bound over every input
within the task's control bounds, starting at rest, judged only when it is exact and cheap
(constant kinetic metric, no potential, forces linear in the inputs). A target beyond it is
impossible, not merely hard; anything nearer goes to the solver (and its time limit).
"""
from __future__ import annotations

import math

__all__ = ["unreachable_targets"]


def unreachable_targets(problem, system, params=None) -> list:
    """One sentence per coordinate whose final value lies beyond what any admissible input can
    reach in the horizon (for a free horizon, its longest); [] when none does or when the
    bound cannot be judged (the motion does not start at rest, an input is unbounded, …)."""
    from nhgait.dynamics.derivation.reach import displacement_bounds
    n = system.n
    if any(problem.fixed_value(problem.initial, v) != 0.0 for v in problem.state_names[n:]):
        return []
    lo, hi = problem.control_bound_vectors()
    bounds = {u: (a, b) for u, a, b in zip(problem.control_names, lo, hi, strict=True)}
    horizon = problem.free_horizon[1] if problem.free_horizon is not None else problem.horizon
    reach = displacement_bounds(system, bounds, float(horizon), params)
    if reach is None:
        return []
    limits = ", ".join(f"|{u}| ≤ {max(abs(a), abs(b)):g}" for u, (a, b) in bounds.items())
    problems = []
    for name in system.coordinates:
        start = problem.fixed_value(problem.initial, name)
        if start is None or name not in problem.final:
            continue
        low, high = problem.bounds(problem.final, name)
        distance = max(low - start, start - high, 0.0)
        if distance > reach[name] * (1 + 1e-9) and math.isfinite(distance):
            problems.append(f"final {name} is {distance:.6g} from initial {name} = {start:g}, but "
                            "starting at rest "
                            f"with {limits} no input moves {name} more than {reach[name]:.4g} in T = "
                            f"{horizon:g} s (a bound from the kinetic energy the inputs can supply): "
                            "lengthen the horizon, widen the control bounds or move the target")
    return problems
