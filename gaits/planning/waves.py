"""A guess as data and the states it gives: sinusoids over ramps (:class:`ShapeGuess`), and the
repairs of one that meets the singular set.

A shape loop c(t) = c₀(t) + A sin(k ω t + φ) per shape coordinate, over the linear ramps c₀ of
every coordinate from its initial to its final value (a coordinate free at t = 0 starts at its
``start`` value: the candidates' common regular start, or :func:`centre`); a rollout
integrates the model's kinematics q̇ = q̇(q, y) with velocity states that are such waves
(:mod:`.guesses` says which candidates there are, in which order). :func:`guess_from_shape`
maps a :class:`ShapeGuess` to an :class:`~nhgait.ocp.InitialGuess` (z = state(q, q̇) at the
nodes, zero controls).

Repairs (:func:`repairs`), tried in this order, each a new :class:`ShapeGuess` whose label says
what changed — the least change first:

1. another relative phase of the loop's second wave (+π/2, +π: another ellipse through the
   same centre; only +π for a wave whose coordinate is fixed at t = 0, which keeps its start);
2. another centre: the coordinates free at t = 0 moved by half the room to their bounds, one
   or both, each way (amplitudes clipped to the bounds around the new centre);
3. amplitudes halved, then quartered, at each of those centres.

A rollout is repaired by halving its wave amplitudes (its path is an integral, so only a
smaller motion is predictably closer to the start, which is regular).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import product

import numpy as np

from nhgait.ocp import InitialGuess

__all__ = ["ShapeGuess", "centre", "ends", "free_start", "amplitude", "guess_from_shape", "repairs",
           "FITTED_LABEL", "PATH_LABEL"]

#: the fitted roll-out's label (:mod:`.fitted`; built by :func:`guess_from_shape` like the others)
FITTED_LABEL = "fitted roll-out"
#: the path through the places a task states between its ends (:mod:`.path_guess`)
PATH_LABEL = "path through the stated places"
#: amplitude factors of the repairs, after the phase and centre changes at full amplitude
SCALES = (1.0, 0.5, 0.25)
#: relative phases added to the second wave of a loop
PHASES = (0.0, math.pi / 2, math.pi)


@dataclass(frozen=True)
class ShapeGuess:
    """Sinusoids c(t) = amplitude · sin(k ω t + phase) per coordinate, over linear ramps.

    ``rates`` are waves of velocity states (w(t) = mean + amplitude · sin(k ω t + phase)); a
    guess with rates is a rollout of the model's kinematics (see the module docstring).
    ``start`` overrides where coordinates free at t = 0 start (their ramp's value; default
    :func:`centre`): the candidates' common regular start (:meth:`Candidates.start`) or a repair.
    """

    label: str
    waves: tuple            # ((coordinate, amplitude, k, phase), ...)
    rates: tuple = ()       # ((velocity state, mean, amplitude, k, phase), ...)
    start: tuple = ()       # ((coordinate, value), ...): start values of coordinates free at t = 0


def centre(problem, name) -> float:
    """Where a coordinate free at both ends sits: the middle of its bounds (0 when unbounded or
    when 0 is inside them)."""
    if name in problem.state_bounds:
        lo, hi = problem.bounds(problem.state_bounds, name)
        if math.isfinite(lo) and math.isfinite(hi) and not lo <= 0.0 <= hi:
            return (lo + hi) / 2
    return 0.0


def ends(problem, name, start=()):
    """(value at t = 0, value at t = T) of a coordinate's ramp; ``start`` ((name, value), ...)
    places a coordinate free at t = 0 (default: :func:`centre`)."""
    a = problem.fixed_value(problem.initial, name)
    b = problem.fixed_value(problem.final, name)
    if name in problem.periodic:
        b = a if b is None else b
        a = b if a is None else a
    a = dict(start).get(name, centre(problem, name)) if a is None else a
    return a, (a if b is None else b)


def amplitude(problem, name, start=()) -> float:
    """Largest amplitude of a wave around the ramp (90 % of the distance to a bound)."""
    if name in problem.state_bounds:
        lo, hi = problem.bounds(problem.state_bounds, name)
        a, b = ends(problem, name, start)
        room = min(min(a, b) - lo, hi - max(a, b))
        if math.isfinite(room):
            return max(0.0, min(1.0, room))
    return 1.0


def free_start(problem, coordinates) -> dict:
    """The coordinates free at t = 0 (no initial value, none implied by periodicity): name →
    (lo, hi), their bounds clipped to [−π, π]."""
    out = {}
    for name in coordinates:
        if problem.fixed_value(problem.initial, name) is not None:
            continue
        if name in problem.periodic and problem.fixed_value(problem.final, name) is not None:
            continue
        lo, hi = (problem.bounds(problem.state_bounds, name) if name in problem.state_bounds
                  else (-math.pi, math.pi))
        out[name] = (max(lo, -math.pi), min(hi, math.pi))
    return out


def guess_from_shape(problem, shape: ShapeGuess, coordinates: tuple) -> InitialGuess:
    """The state guess (nz × (N+1)) of one candidate; zero controls."""
    if shape.label == FITTED_LABEL:
        from .fitted import fitted_guess
        return fitted_guess(problem, coordinates, [ends(problem, c, shape.start)[0] for c in coordinates])
    if shape.label == PATH_LABEL:
        from .path_guess import path_guess
        return path_guess(problem, coordinates, lambda name: ends(problem, name, shape.start))
    if shape.rates:
        return _rollout(problem, shape, coordinates)
    t = problem.grid()
    T = float(problem.horizon)
    w = 2 * math.pi / T
    n = len(coordinates)
    q, qdot = np.zeros((n, t.size)), np.zeros((n, t.size))
    for i, name in enumerate(coordinates):
        a, b = ends(problem, name, shape.start)
        q[i] = a + (b - a) * t / T
        qdot[i] = (b - a) / T
    for name, amp, k, phase in shape.waves:
        i = coordinates.index(name)
        q[i] += amp * np.sin(k * w * t + phase)
        qdot[i] += amp * k * w * np.cos(k * w * t + phase)
    state = problem.model.numeric["state"]
    with np.errstate(all="ignore"):
        Z = np.asarray(state.map(t.size)(q, qdot, problem.model.numeric.params(problem.params)))
    return InitialGuess(Z, np.zeros((problem.n_controls, problem.intervals)), horizon=T, label=shape.label)


def _rollout(problem, shape: ShapeGuess, coordinates: tuple) -> InitialGuess:
    """Integrate q̇ = q̇(q, y) (RK4, 4 steps per interval) with y(t) from the waves and rates."""
    model = problem.model
    n, names = len(coordinates), tuple(model.state_names)
    T, N = float(problem.horizon), problem.intervals
    w = 2 * math.pi / T
    qdot = model.numeric["qdot"]

    def y_of(t):
        y = np.zeros(len(names) - n)
        for name, amp, k, phase in shape.waves:
            rate = f"{name}_dot"
            if rate in names:
                y[names.index(rate) - n] += amp * k * w * math.cos(k * w * t + phase)
        for name, mean, amp, k, phase in shape.rates:
            y[names.index(name) - n] += mean + amp * math.sin(k * w * t + phase)
        return y

    def f(t, q):
        return np.asarray(qdot(np.concatenate([q, y_of(t)]), problem.params)).ravel()

    q = np.array([ends(problem, c, shape.start)[0] for c in coordinates])
    for name, amp, _k, phase in shape.waves:
        q[coordinates.index(name)] += amp * math.sin(phase)
    h = T / N / 4
    Z = np.zeros((len(names), N + 1))
    Z[:, 0] = np.concatenate([q, y_of(0.0)])
    t = 0.0
    for j in range(N):
        for _ in range(4):
            k1 = f(t, q)
            k2 = f(t + h / 2, q + h / 2 * k1)
            k3 = f(t + h / 2, q + h / 2 * k2)
            k4 = f(t + h, q + h * k3)
            q, t = q + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h
        Z[:, j + 1] = np.concatenate([q, y_of(t)])
    return InitialGuess(Z, np.zeros((problem.n_controls, N)), horizon=T, label=shape.label)


def repairs(problem, shape: ShapeGuess, free: dict):
    """The repaired versions of ``shape`` in the order of the module docstring (a generator of
    (ShapeGuess, what changed)); ``free``: the coordinates free at t = 0 (:func:`free_start`)."""
    if shape.label == FITTED_LABEL:
        return
    if shape.rates:
        for f in (0.5, 0.25):
            yield (replace(shape, label=f"{shape.label} (amplitudes x{f:g})",
                           waves=tuple((c, a * f, k, p) for c, a, k, p in shape.waves),
                           rates=tuple((v, m, a * f, k, p) for v, m, a, k, p in shape.rates)),
                   f"amplitudes x{f:g}")
        return
    moved = [c for c, *_ in shape.waves if c in free]
    for scale, shift, phase in product(SCALES, _shifts(problem, shape, moved), PHASES):
        if scale == 1.0 and not shift and phase == 0.0:
            continue
        if phase and (len(shape.waves) < 2 or (shape.waves[1][0] not in free and phase != math.pi)):
            continue            # a wave fixed at t = 0 keeps sin(φ) = 0 there: only +π
        start = {**dict(shape.start), **shift}
        waves = []
        for i, (c, a, k, p) in enumerate(shape.waves):
            room = amplitude(problem, c, tuple(start.items())) if c in shift else abs(a)
            waves.append((c, math.copysign(min(abs(a) * scale, room), a), k, p + (phase if i == 1 else 0.0)))
        what = ", ".join(filter(None, [f"phase +{phase:.2f}" if phase else "",
                                      ", ".join(f"centre {c} = {v:.2g}" for c, v in shift.items()),
                                      f"amplitudes x{scale:g}" if scale != 1.0 else ""]))
        yield replace(shape, label=f"{shape.label} ({what})", waves=tuple(waves),
                      start=tuple(start.items())), what


def _shifts(problem, shape: ShapeGuess, moved: list) -> list:
    """Centres of the repairs: none, then each free waved coordinate moved by half its room to
    each bound, then both together (as {name: start value})."""
    out = [{}]
    steps = {}
    for c in moved:
        a = ends(problem, c, shape.start)[0]
        lo, hi = problem.bounds(problem.state_bounds, c) if c in problem.state_bounds else (a - 1.0, a + 1.0)
        lo, hi = (lo if math.isfinite(lo) else a - 1.0), (hi if math.isfinite(hi) else a + 1.0)
        steps[c] = (a + (hi - a) / 2, a - (a - lo) / 2)
    for c in moved:
        out += [{c: v} for v in steps[c]]
    if len(moved) == 2:
        a, b = moved
        out += [{a: va, b: vb} for va, vb in ((steps[a][0], steps[b][1]), (steps[a][1], steps[b][0]),
                                             (steps[a][0], steps[b][0]), (steps[a][1], steps[b][1]))]
    return out
