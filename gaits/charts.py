"""The reduced model whose chart covers the task's ends.

The 20-step reduction splits q = (s, r) into fiber and shape and inverts the constraints'
block on the pivots (steps 4–5); its *singular set* is where that block, or the momentum
basis, loses rank. That set belongs to the chart, not to the robot: a cart with two on-axle
trailers reduced with fiber (x, y, θ, φ) is singular wherever the trailers are straight
(β₁ = β₂ = 0: three of the four constraints then act on (y, θ) alone), which is exactly where
a lane change starts and ends; with fiber (x, y, θ) the pivot block takes the last hitch
angle and is regular there.

:func:`derive_for_task` derives the default chart and, when a configuration the task fixes
completely (every coordinate given at an end) lies on its singular set, tries smaller fibers —
the default one with fiber coordinates outside the planar frame dropped, one at a time, then
more — and keeps the first whose singular set misses every such configuration. The choice and
its reason are said on the progress stream; a task no chart covers gets the default model (the
error that follows names the singular set).
"""
from __future__ import annotations

from dataclasses import replace
from itertools import combinations

__all__ = ["derive_for_task", "fixed_configurations"]


def fixed_configurations(task, coordinates) -> list:
    """(end, q) for each end of ``task`` at which every coordinate has a fixed value."""
    out = []
    for end in ("initial", "final"):
        given = getattr(task, end)
        values = [given.get(c) for c in coordinates]
        if all(isinstance(v, (int, float)) for v in values):
            out.append((end, [float(v) for v in values]))
    return out


def _singular_ends(model, ends, params) -> list:
    """The ends whose configuration is on ``model``'s singular set (its measure, which counts a
    factorisation that gives 0/0 there as singular)."""
    from nhgait.dynamics.derivation.states import check_configuration
    from nhgait.dynamics.errors import SingularConfigurationError
    bad = []
    for end, q in ends:
        try:
            check_configuration(model, q, params)
        except SingularConfigurationError:
            bad.append(end)
    return bad


def _smaller_fibers(model) -> list:
    """Proper subsets of the model's fiber that keep its planar frame, largest first."""
    fiber = tuple(getattr(model.layout, "fiber", ()) or ())
    frame = set(getattr(model.system, "planar_frame", None) or ())
    optional = [c for c in fiber if c not in frame]
    subsets = []
    for drop in range(1, len(optional) + 1):
        for removed in combinations(optional, drop):
            kept = tuple(c for c in fiber if c not in removed)
            if kept:
                subsets.append(kept)
    return subsets


def derive_for_task(system, task, params, progress):
    """``derive(system, "reduced")``, in a chart whose singular set misses the task's fully
    fixed end configurations when the default chart's does not (module docstring)."""
    from nhgait.dynamics import derive
    with progress.phase(f"derive the reduced equations of {system.name}"):
        model = derive(system, "reduced")
    ends = fixed_configurations(task, tuple(system.coordinates))
    bad = _singular_ends(model, ends, params) if ends else []
    if not bad:
        return model
    fiber = ", ".join(model.layout.fiber)
    for candidate in _smaller_fibers(model):
        with progress.phase(f"fiber ({fiber}) is singular at the {' and '.join(bad)} configuration: "
                            f"trying fiber ({', '.join(candidate)})"):
            other = derive(replace(system, fiber=candidate), "reduced")
        if not _singular_ends(other, ends, params):
            progress.note(f"  using fiber ({', '.join(candidate)}), shape "
                          f"({', '.join(c for c in system.coordinates if c not in candidate)})")
            return other
    return model
