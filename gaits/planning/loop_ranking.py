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

:func:`rank_loops` puts the two-variable loops that move toward the target first, in order of
decreasing score, then those it cannot tell apart (in their order), in the slots the loops held;
every other candidate keeps its place. The loops predicted to move the robot *away* from the
target (progress below −:data:`SIGNIFICANT` |d|: about half of them, the mirror images of the
good ones) are set apart (:class:`RankedLoops`), tried after every other candidate but the ramps
alone (for a robot with roll-outs, beyond the planner's limit of guesses per solver). Nothing
changes when the model has no local connection or the task no target direction.

The prediction is numeric only (:class:`Predictor`: the compiled basis X(q) and the fibre
integrator's one CasADi ``mapaccum`` per loop), so ranking the snakeboard's 21 loops costs
tens of milliseconds, and :mod:`.guesses` ranks only when a guess beyond the leading ones (a
warm start, the path through the task's places, the fitted guess) is first asked for.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..tasks.reachability import target_of
from .waves import ends

__all__ = ["LoopScore", "Predictor", "RankedLoops", "loop_scores", "predictor_of", "rank_loops"]

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


@dataclass(frozen=True, eq=False)
class Predictor:
    """What the ranking needs of a model: the ``fiber`` and ``shape`` names, the shape's rows in q
    (``shape_index``), ``lift_sizes(q)`` → ‖gA‖ at each column of q (n×K) and ``motion(t, q)`` →
    the fibre path (l×K) from rest along q(t)."""

    fiber: tuple
    shape: tuple
    shape_index: tuple
    lift_sizes: Callable
    motion: Callable


def predictor_of(problem) -> Predictor | None:
    """The :class:`Predictor` of the problem's reduced model (None without one: no layout, no
    shape): the compiled basis X(q) and :class:`~nhgait.dynamics.geometry.prescribed.FibreIntegrator`,
    nothing symbolic (the connection's bracket, simplified symbolically in about a second, is not
    needed)."""
    from nhgait.dynamics.geometry.prescribed import FibreIntegrator
    base = getattr(problem.model, "base", problem.model)
    layout = getattr(base, "layout", None)
    if layout is None or not getattr(base, "shape", ()):
        return None
    values = np.asarray(problem.model.numeric.params(problem.params), float)
    names = tuple(base.system.coordinates)
    si, free = list(layout.si), list(layout.free)
    m, extra = len(free), len(base.momenta)
    basis = base.numeric["basis"]

    def lift_sizes(q):
        K = q.shape[1]
        X = np.asarray(basis.map(K)(np.vstack([q, np.zeros((extra, K))]), values))
        cols = X.shape[1] // K
        blocks = X[si].reshape(len(si), K, cols)[:, :, cols - m:]
        return np.sqrt(np.sum(blocks ** 2, axis=(0, 2)))

    integrate = FibreIntegrator(base, values)
    return Predictor(fiber=tuple(layout.fiber), shape=tuple(names[i] for i in free), shape_index=tuple(free),
                     lift_sizes=lift_sizes, motion=lambda t, q: integrate(t, q).fiber)


def _predicted(predictor, t, q):
    """(Δs, ‖ṙ‖, trusted) of the path q(t) (module docstring); ``trusted`` as there."""
    r = q[list(predictor.shape_index)]
    sizes = predictor.lift_sizes(q)
    rate = np.diff(r, axis=1) / np.diff(t)
    effort = math.sqrt(float(np.sum(rate ** 2 * np.diff(t))))
    trusted = bool(np.all(np.isfinite(sizes)) and max(sizes) <= TRUSTED_PEAK * max(np.median(sizes), 1e-12))
    if not trusted:
        return None, effort, False
    s = predictor.motion(t, q)
    return s[:, -1] - s[:, 0], effort, bool(np.all(np.isfinite(s)))


def loop_scores(problem, guesses, predictor=None) -> list:
    """:class:`LoopScore` of every two-variable loop in ``guesses`` (others: None); [] when the
    model has no connection or the task no target direction. ``predictor``: a :class:`Predictor`
    (default :func:`predictor_of` the problem)."""
    predictor = predictor or predictor_of(problem)
    if predictor is None:
        return []
    target = target_of(problem, predictor.fiber)
    if target is None:
        return []
    d, mask = target.d, target.mask
    coordinates = tuple(problem.model.system.coordinates)
    out = []
    scored = 0
    for g in guesses:
        if (len(g.waves) != 2 or g.rates or any(w[0] not in predictor.shape for w in g.waves)
                or scored >= MAX_SCORED):
            out.append(None)
            continue
        scored += 1
        t, q = _path(problem, g, coordinates)
        with np.errstate(all="ignore"):
            moved, effort, trusted = _predicted(predictor, t, q)
        if not trusted:
            out.append(None)
            continue
        progress = float(np.linalg.norm(d) - np.linalg.norm(d - np.where(mask, moved, 0.0)))
        ok = math.isfinite(progress) and effort > 0
        significant = abs(progress) > SIGNIFICANT * np.linalg.norm(d)
        score = (progress if significant else 0.0) / effort if ok else -math.inf
        out.append(LoopScore(g.label, tuple(moved), progress, effort, score))
    return out


@dataclass(frozen=True)
class RankedLoops:
    """The guesses of :func:`rank_loops`: ``front`` (the loops toward the target by decreasing
    score, then those the prediction cannot tell, in the slots the loops held; the other guesses
    in their places) and ``away`` (the loops predicted to move the robot away from the target,
    least far first: :mod:`.guesses` tries them after every other candidate but the ramps alone)."""

    front: tuple
    away: tuple = ()


def rank_loops(problem, guesses: list, progress=None, predictor=None) -> RankedLoops:
    """``guesses`` with the two-variable loops reordered by decreasing score (module docstring):
    the loops that move toward the target first, in the slots the loops held, those predicted to
    move away from it (progress below −:data:`SIGNIFICANT` |d|) set apart; ``progress`` hears the
    best prediction."""
    scores = loop_scores(problem, guesses, predictor)
    slots = [i for i, s in enumerate(scores) if s is not None]
    if not slots:
        return RankedLoops(tuple(guesses))
    toward = sorted((i for i in slots if scores[i].score > 0), key=lambda i: -scores[i].score)
    away = sorted((i for i in slots if scores[i].score < 0), key=lambda i: -scores[i].score)
    unknown = [i for i in slots if scores[i].score == 0]
    filled, in_slots = iter(toward + unknown), set(slots)
    front = []
    for i, g in enumerate(guesses):
        if i not in in_slots:
            front.append(g)
            continue
        j = next(filled, None)
        if j is not None:
            front.append(guesses[j])
    if progress is not None and (toward + unknown + away) != slots:
        best = scores[toward[0]] if toward else None
        progress.note("  shape loops ranked by the connection's prediction: "
                      + (f"{best.label!r} first ({best.progress:.3g} toward the target per {best.effort:.3g} "
                         "of ‖ṙ‖)" if best else "none moves toward the target")
                      + (f"; {len(away)} predicted to move away from it tried last" if away else ""))
    return RankedLoops(tuple(front), tuple(guesses[i] for i in away))
