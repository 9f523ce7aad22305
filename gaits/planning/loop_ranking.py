"""Shape loops ranked before any solve, by the displacement the local connection predicts.

For a reduced model with a local connection (ξ = −A(r)ṙ + Γ(r)p, thesis step 5), a shape-loop
candidate r(t) (:mod:`.waves`: sines around the ramps) moves the fibre by the reconstruction
equation with its momentum equation, from the task's initial fibre values and p = 0
(:func:`~nhgait.dynamics.geometry.prescribed.fibre_motion`: the exact fibre motion when the
shape follows r(t), for principally kinematic and mixed robots alike). The target
direction d is the change of the fibre coordinates the task fixes at both ends (the planar
position alone when it changes, else every fixed fibre coordinate); a candidate's score is how
much nearer the target it ends (Δs restricted to the components of d), per unit effort
‖ṙ‖ = (∫|ṙ|² dt)^½:

    score = (|d| − |d − Δs|) / ‖ṙ‖

(a loop that overshoots or moves sideways scores low; one whose progress is below
:data:`SIGNIFICANT` |d| keeps its place). A loop along which ‖A‖ peaks above
:data:`TRUSTED_PEAK` times its median (it passes near the singular set of A, where the
prediction means nothing: the 3-link snake's α₁ = α₂) gets no score and keeps its place.

:func:`rank_loops` puts the two-variable loops in order of decreasing score (ties and loops
that move away from the target keep their order, after the others); every other candidate
keeps its place. Nothing changes when the model has no connection or no target direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..tasks.reachability import numeric_connection_of, target_of
from .waves import ends

__all__ = ["LoopScore", "loop_scores", "rank_loops", "model_motion"]

#: samples per horizon of a predicted loop (midpoint rule)
SAMPLES = 240
#: a prediction is trusted when max ‖A‖ along the loop ≤ this times its median
TRUSTED_PEAK = 10.0
#: at most this many loops are scored (in their generated order; the rest keep their places),
#: so a robot with many shape pairs does not spend seconds before its first solve
MAX_SCORED = 80
#: a loop counts as moving toward the target when its progress exceeds this fraction of |d|
#: (below it the prediction is rounding: a 4-link chain's loops of 1e-12 m)
SIGNIFICANT = 1e-3


@dataclass(frozen=True)
class LoopScore:
    """A candidate's predicted fibre change ``moved`` (fibre order), its ``progress`` toward the
    target (|d| − |d − Δs|), its ``effort`` ‖ṙ‖ and ``score`` (module docstring)."""

    label: str
    moved: tuple
    progress: float
    effort: float
    score: float


def _path(problem, guess, coordinates):
    """q(t) (n×SAMPLES+1) of a loop candidate: the ramps plus its waves."""
    T = float(problem.horizon)
    t = np.linspace(0.0, T, SAMPLES + 1)
    w = 2 * math.pi / T
    q = np.zeros((len(coordinates), t.size))
    for i, name in enumerate(coordinates):
        a, b = ends(problem, name, guess.start)
        q[i] = a + (b - a) * t / T
    for name, amp, k, phase in guess.waves:
        q[coordinates.index(name)] += amp * np.sin(k * w * t + phase)
    return t, q


def model_motion(problem):
    """The fibre path (l×K) along configurations q (n×K) at times t, by the problem's model
    (:func:`~nhgait.dynamics.geometry.prescribed.fibre_motion`, from rest)."""
    from nhgait.dynamics.geometry.prescribed import FibreIntegrator
    integrate = FibreIntegrator(getattr(problem.model, "base", problem.model),
                                problem.model.numeric.params(problem.params))
    return lambda t, q: integrate(t, q).fiber


def _predicted(motion, connection, t, q):
    """(Δs, ‖ṙ‖, trusted) of the path q(t) (module docstring); ``trusted`` as there."""
    r = q[list(connection.shape_index)]
    sizes = connection.lift_sizes(q)
    rate = np.diff(r, axis=1) / np.diff(t)
    effort = math.sqrt(float(np.sum(rate ** 2 * np.diff(t))))
    trusted = bool(np.all(np.isfinite(sizes)) and max(sizes) <= TRUSTED_PEAK * max(np.median(sizes), 1e-12))
    if not trusted:
        return None, effort, False
    s = motion(t, q)
    return s[:, -1] - s[:, 0], effort, bool(np.all(np.isfinite(s)))


def loop_scores(problem, guesses, motion=None) -> list:
    """:class:`LoopScore` of every two-variable loop in ``guesses`` (others: None); [] when the
    model has no connection or the task no target direction. ``motion(t, q)`` → the fibre path
    (default :func:`model_motion`)."""
    connection = numeric_connection_of(problem)
    if connection is None:
        return []
    target = target_of(problem, connection.fiber)
    if target is None:
        return []
    d, mask = target.d, target.mask
    coordinates = tuple(problem.model.system.coordinates)
    motion = motion or model_motion(problem)
    out = []
    scored = 0
    for g in guesses:
        if (len(g.waves) != 2 or g.rates or any(w[0] not in connection.shape for w in g.waves)
                or scored >= MAX_SCORED):
            out.append(None)
            continue
        scored += 1
        t, q = _path(problem, g, coordinates)
        with np.errstate(all="ignore"):
            moved, effort, trusted = _predicted(motion, connection, t, q)
        if not trusted:
            out.append(None)
            continue
        progress = float(np.linalg.norm(d) - np.linalg.norm(d - np.where(mask, moved, 0.0)))
        ok = math.isfinite(progress) and effort > 0
        significant = abs(progress) > SIGNIFICANT * np.linalg.norm(d)
        score = (progress if significant else 0.0) / effort if ok else -math.inf
        out.append(LoopScore(g.label, tuple(moved), progress, effort, score))
    return out


def rank_loops(problem, guesses: list, progress=None, motion=None) -> list:
    """``guesses`` with the two-variable loops reordered by decreasing score (module
    docstring), in the slots the loops held; ``progress`` hears the best prediction."""
    scores = loop_scores(problem, guesses, motion)
    slots = [i for i, s in enumerate(scores) if s is not None]
    if not slots:
        return list(guesses)
    order = sorted(slots, key=lambda i: (-scores[i].score if scores[i].score > 0 else math.inf, i))
    out = list(guesses)
    for slot, i in zip(slots, order, strict=True):
        out[slot] = guesses[i]
    if progress is not None and order != slots:
        best = scores[order[0]]
        progress.note(f"  shape loops ranked by the connection's prediction: {best.label!r} first "
                      f"({best.progress:.3g} toward the target per {best.effort:.3g} of ‖ṙ‖)")
    return out
