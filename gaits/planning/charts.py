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

The planner solves in velocity coordinates whose equations do not go through the chart
(:func:`~nhgait.dynamics.numerics.specialisation.specialise`: the velocity basis), so a gait may
cross the chart's singular set — the 3-link snake's optimum does, its joint angles cross
α₁ = α₂ twice. The verification re-simulates the gait in momentum coordinates z = (q, P), which
are singular there. :func:`verification_chart` therefore measures the chart along the gait
(:func:`singular_along`: the chart's measure at the nodes and between them) and, when the gait
comes close to its singular set, derives the other admissible charts (the fibers ``nhgait
derive`` lists) and verifies in the first one that stays regular along it (the snake: fiber
(y), singular only where cos θ (1 + cos α₂) = 0). When none does (a car with two off-axle
trailers turning by π/2 meets the singular sets of (x, y, θ), (x) and (y)), the gait is
verified on the Euler–Lagrange equations in their index-1 form (:func:`lagrange_ode`), which
have no chart.
"""
from __future__ import annotations

from dataclasses import replace
from itertools import combinations
from typing import NamedTuple

import numpy as np

__all__ = ["derive_for_task", "fixed_configurations", "verification_chart", "lagrange_ode", "singular_along",
           "CHART_MARGIN"]

#: a chart whose measure along a gait falls below this fraction of its median along it counts as
#: meeting its singular set there (:func:`verification_chart`)
CHART_MARGIN = 0.05
#: points per interval at which :func:`singular_along` measures between the nodes
POINTS_PER_INTERVAL = 8
#: other charts derived at most when the default one is singular along a gait
MAX_CHARTS = 4


def fixed_configurations(task, coordinates) -> list:
    """(end, q) for each end of ``task`` at which every coordinate has a fixed value."""
    out = []
    for end in ("initial", "final"):
        given = getattr(task, end)
        values = [given.get(c) for c in coordinates]
        if all(isinstance(v, (int, float)) for v in values):
            out.append((end, [float(v) for v in values]))
    return out


def end_postures(task, coordinates) -> list:
    """A configuration q for each end of ``task`` that fixes at least one coordinate: the fixed
    values, every other coordinate at the centre of its bound (0 when unbounded) — where the
    guesses start or end (a heading fixed at π/2 decides whether ẋ can be a velocity state
    whatever the shape)."""
    out = []
    for end in ("initial", "final"):
        given = getattr(task, end)
        if not any(isinstance(given.get(c), (int, float)) for c in coordinates):
            continue
        q = []
        for c in coordinates:
            value, bound = given.get(c), task.bounds.get(c)
            if isinstance(value, (int, float)):
                q.append(float(value))
            elif isinstance(bound, tuple) and all(map(np.isfinite, bound)):
                q.append(float(sum(bound)) / 2)
            else:
                q.append(0.0)
        out.append(q)
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
            other = derive(system.with_fiber(candidate), "reduced")
        if not _singular_ends(other, ends, params):
            progress.note(f"  using fiber ({', '.join(candidate)}), shape "
                          f"({', '.join(c for c in system.coordinates if c not in candidate)})")
            return other
    return model


def singular_along(model, q_nodes, params, points: int = POINTS_PER_INTERVAL) -> np.ndarray:
    """The singular-set measure of ``model`` (``numeric["singular"]``) along the path through the
    configurations ``q_nodes`` (n × (N+1)), linear between the nodes, ``points`` per interval:
    an array of N·points + 1 values (non-finite values count as 0)."""
    q_nodes = np.asarray(q_nodes, float)
    s = np.linspace(0.0, q_nodes.shape[1] - 1, (q_nodes.shape[1] - 1) * points + 1)
    q = np.vstack([np.interp(s, np.arange(q_nodes.shape[1]), row) for row in q_nodes])
    f = model.numeric["singular"]
    with np.errstate(all="ignore"):
        m = np.asarray(f.map(q.shape[1])(q, model.numeric.params(params))).ravel()
    return np.where(np.isfinite(m), m, 0.0)


def _regularity(model, q_nodes, params) -> float:
    """min / median of the chart's measure along the path (1 without a singular set)."""
    if "singular" not in model.numeric.functions:
        return 1.0
    m = singular_along(model, q_nodes, params)
    median = float(np.median(m))
    return float(m.min() / median) if median > 0 else 0.0


class VerificationChart(NamedTuple):
    """What :func:`verification_chart` returns."""

    model: object   #: the reduced model to verify in
    regular: bool   #: whether it stays regular along the gait


def verification_chart(system, model, q_nodes, params, progress) -> VerificationChart:
    """(model, regular): the chart of the same system to verify a gait through ``q_nodes`` in —
    ``model`` unless its measure along the gait falls below :data:`CHART_MARGIN` of its median
    there; then the first other admissible chart (at most :data:`MAX_CHARTS` derived) that stays
    above it — and whether it does; when none does, the most regular one tried and False (verify
    on :func:`lagrange_ode` then; module docstring)."""
    from nhgait.dynamics import derive
    best, score = model, _regularity(model, q_nodes, params)
    if score >= CHART_MARGIN:
        return VerificationChart(model, True)
    symmetry = getattr(model, "symmetry", None)
    others = [c for c in (symmetry.candidates if symmetry is not None else ())
              if c.admissible and tuple(c.fiber) != tuple(model.fiber)][:MAX_CHARTS]
    fiber = ", ".join(model.fiber)
    for candidate in others:
        with progress.phase(f"the gait meets the singular set of fiber ({fiber}): deriving fiber "
                            f"({', '.join(candidate.fiber)}) to verify it in"):
            other = derive(system.with_fiber(candidate.fiber), "reduced")
        mine = _regularity(other, q_nodes, params)
        if mine > score:
            best, score = other, mine
        if score >= CHART_MARGIN:
            break
    if score >= CHART_MARGIN:
        progress.note(f"  verifying in the chart with fiber ({', '.join(best.fiber)}), shape "
                      f"({', '.join(best.shape)}): regular along the gait")
        return VerificationChart(best, True)
    progress.note("  no chart of the reduction is regular along the gait: verifying on the Euler–Lagrange "
                  "equations (index-1 form, x = (q, q̇)), which have none")
    return VerificationChart(best, False)


def lagrange_ode(system):
    """The Euler–Lagrange equations with multipliers of ``system`` (thesis eq. 2.8) in their
    index-1 form as an ODE model x = (q, q̇) for the verification: ``numeric["rhs"](t, x, u,
    params)`` (the multipliers solved), ``qdot`` and ``state(q, q̇, params) = (q, q̇)`` — regular
    wherever ω has full rank, so a gait that crosses the singular set of every chart of the
    reduction can still be re-simulated. The LagrangianDAE with these functions added."""
    import casadi as ca

    from nhgait.dynamics import derive
    dae = derive(system, "lagrange")
    numeric = dae.numeric
    n = len(system.coordinates)
    t, x = ca.SX.sym("t"), ca.SX.sym("x", 2 * n)
    u, params = ca.SX.sym("u", len(numeric.input_names)), ca.SX.sym("params", len(numeric.param_names))
    q, qd = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    functions = {**numeric.functions,
                 "rhs": ca.Function("rhs", [t, x, u, params], [numeric["ode"](t, x, u, params)[0]],
                                    ["t", "z", "u", "params"], ["zdot"]),
                 "state": ca.Function("state", [q, qd, params], [ca.vertcat(q, qd)],
                                      ["q", "qdot", "params"], ["z"])}
    return replace(dae, compiled=replace(numeric, functions=functions))
