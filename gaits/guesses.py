"""Initial guesses for any system, from the task and the system's own shape variables.

A zero guess does not work for these systems: at rest the linearisation cannot move the body
and Ipopt reports local infeasibility. The guesses are therefore shape loops, as in the
classical gaits (snakeboard rotor:wheel frequency ratios 1:1 drive, 2:1 rotate, 3:2 park):

* for every pair (a, b) of shape variables (``model.shape``) and every frequency ratio
  k_a:k_b in 1:1, 2:1, 1:2, 3:2, 2:3, and a few amplitudes and signs,
  a(t) = a₀(t) + A sin(k_a ω t),  b(t) = b₀(t) + B sin(k_b ω t + π/2),  ω = 2π/T,
  where a₀(t), b₀(t) run linearly from the task's initial to its final value (when free: 0,
  or the middle of the variable's bounds when they exclude 0);
  a variable fixed at t = 0 takes the phase 0 (the sine), so that it starts at its value;
* a single shape variable oscillates alone (k = 1, 2);
* the fiber coordinates (``model.fiber``) ramp linearly from their initial to their final
  values;
* **rollouts**, for a model in velocity coordinates with velocity states that are not shape
  rates (a car's or a sleigh's forward velocity w): w(t) = w̄ + A sin(k_w ω t) paired with a
  shape variable as above, w̄ the mean speed that covers the task's displacement along the
  initial heading; the configuration is then integrated from the initial one through the
  model's own kinematics q̇ = q̇(q, y) (RK4, 4 steps per interval), so the guess moves the body
  only in allowed directions (a car parallel-parks by v = A sin ωt, φ = B sin 2ωt);
  rollouts are interleaved with the loops;
* the last candidate is the ramps alone (no shape motion);
* first of all, for a task that states places between its ends (waypoints, phase ends), the
  path through them (:mod:`.path_guess`).

Amplitudes respect the task's bounds (at most 90 % of the distance to the nearer bound).
Configurations q(t) and their rates q̇(t) (ramps included) are mapped to the model's state
by its ``state(q, q̇)`` map; the controls are zero. :func:`candidates` returns them in order;
the planner tries them (several at once when cores allow) and reports which one won.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from nhgait.ocp import InitialGuess

__all__ = ["ShapeGuess", "shape_guesses", "rollout_guesses", "guess_from_shape", "candidates", "Candidates",
           "RATIOS", "AMPLITUDES"]

RATIOS = ((1, 1), (2, 1), (1, 2), (3, 2), (2, 3))
#: (A, B) as fractions of the largest allowed amplitude of each variable (1 rad when unbounded)
AMPLITUDES = ((1.0, 0.9), (1.0, 0.6), (-1.0, 0.9), (0.6, 1.0))
SINGLE = ((1, 0.5), (1, 1.0), (2, 0.5), (1, -0.5))


@dataclass(frozen=True)
class ShapeGuess:
    """Sinusoids c(t) = amplitude · sin(k ω t + phase) per coordinate, over linear ramps.

    ``rates`` are waves of velocity states (w(t) = mean + amplitude · sin(k ω t + phase)); a
    guess with rates is a rollout of the model's kinematics (see the module docstring).
    """

    label: str
    waves: tuple            # ((coordinate, amplitude, k, phase), ...)
    rates: tuple = ()       # ((velocity state, mean, amplitude, k, phase), ...)


def _centre(problem, name) -> float:
    """Where a coordinate free at both ends sits: the middle of its bounds (0 when unbounded or
    when 0 is inside them)."""
    if name in problem.state_bounds:
        lo, hi = problem.bounds(problem.state_bounds, name)
        if math.isfinite(lo) and math.isfinite(hi) and not lo <= 0.0 <= hi:
            return (lo + hi) / 2
    return 0.0


def _ends(problem, name):
    """(value at t = 0, value at t = T) of a coordinate's ramp."""
    a = problem.fixed_value(problem.initial, name)
    b = problem.fixed_value(problem.final, name)
    if name in problem.periodic:
        b = a if b is None else b
        a = b if a is None else a
    a = _centre(problem, name) if a is None else a
    return a, (a if b is None else b)


def _amplitude(problem, name) -> float:
    """Largest amplitude of a wave around the ramp (90 % of the distance to a bound)."""
    if name in problem.state_bounds:
        lo, hi = problem.bounds(problem.state_bounds, name)
        a, b = _ends(problem, name)
        room = min(min(a, b) - lo, hi - max(a, b))
        if math.isfinite(room):
            return max(0.0, min(1.0, room))
    return 1.0


def shape_guesses(problem, shape: tuple) -> list:
    """The shape-loop candidates (see the module docstring), in order of preference."""
    out = []
    fixed0 = {n for n in shape if problem.fixed_value(problem.initial, n) is not None}
    for a, b in combinations(shape, 2):
        amp_a, amp_b = _amplitude(problem, a), _amplitude(problem, b)
        # the variable fixed at t = 0 carries the sine (phase 0), the other the cosine
        if b in fixed0 and a not in fixed0:
            a, b, amp_a, amp_b = b, a, amp_b, amp_a
        phase_b = 0.0 if b in fixed0 else math.pi / 2
        for ka, kb in RATIOS:
            for fa, fb in AMPLITUDES:
                label = f"{a}:{b} {ka}:{kb} A={fa * amp_a:.2g} B={fb * amp_b:.2g}"
                out.append(ShapeGuess(label, ((a, fa * amp_a, ka, 0.0), (b, fb * amp_b, kb, phase_b))))
    if len(shape) == 1:
        (a,) = shape
        amp = _amplitude(problem, a)
        phase = 0.0 if a in fixed0 else math.pi / 2
        for k, f in SINGLE:
            out.append(ShapeGuess(f"{a} k={k} A={f * amp:.2g}", ((a, f * amp, k, phase),)))
    out.append(ShapeGuess("ramps only", ()))
    return out


def rollout_guesses(problem, shape: tuple, rates: tuple) -> list:
    """Rollout candidates: each velocity state of ``rates`` paired with each shape variable."""
    T = float(problem.horizon)
    w = 2 * math.pi / T
    mean = _mean_speed(problem)
    out = []
    fixed0 = {n for n in shape if problem.fixed_value(problem.initial, n) is not None}
    for v in rates:
        reach = max(abs(mean) * T, _span(problem), 0.25)
        for b in shape or (None,):
            amp_b = _amplitude(problem, b) if b else 0.0
            phase_b = 0.0 if b in fixed0 else math.pi / 2
            for kv, kb in RATIOS:
                for fa, fb in AMPLITUDES[:2] + ((-1.0, 0.6),):
                    A = fa * reach * w * kv / 2          # excursion 2A/(k ω) ≈ the task's reach
                    waves = ((b, fb * amp_b, kb, phase_b),) if b else ()
                    label = f"rollout {v}:{b} {kv}:{kb} A={A:.2g}" + (f" B={fb * amp_b:.2g}" if b else "")
                    out.append(ShapeGuess(label, waves, ((v, mean, A, kv, 0.0),)))
    return out


def _span(problem) -> float:
    """Largest change of a coordinate fixed at both ends."""
    d = 0.0
    for name in problem.final:
        a, b = problem.fixed_value(problem.initial, name), problem.fixed_value(problem.final, name)
        if a is not None and b is not None and name in problem.model.system.coordinates:
            d = max(d, abs(b - a))
    return d


def _mean_speed(problem) -> float:
    """Displacement of the planar frame along its initial heading, divided by T (0 without one)."""
    frame = getattr(problem.model.system, "planar_frame", None)
    if not frame:
        return 0.0
    x0, y0 = (problem.fixed_value(problem.initial, c) or 0.0 for c in frame[:2])
    x1, y1 = (problem.fixed_value(problem.final, c) for c in frame[:2])
    h0 = problem.fixed_value(problem.initial, frame[2]) or 0.0
    x1, y1 = (x0 if x1 is None else x1), (y0 if y1 is None else y1)
    return ((x1 - x0) * math.cos(h0) + (y1 - y0) * math.sin(h0)) / float(problem.horizon)


def _interleave(a: list, b: list) -> list:
    out = []
    for i in range(max(len(a), len(b))):
        out += ([a[i]] if i < len(a) else []) + ([b[i]] if i < len(b) else [])
    return out


def _order(guesses: list, n_pairs: int) -> list:
    """Interleave the pairs: the first candidate of every pair, then the second, … (so a
    system with several shape pairs tries each pair early)."""
    if n_pairs <= 1:
        return guesses
    per = len(RATIOS) * len(AMPLITUDES)
    blocks = [guesses[i * per:(i + 1) * per] for i in range(n_pairs)]
    rest = guesses[n_pairs * per:]
    return [g for row in zip(*blocks) for g in row] + rest


def guess_from_shape(problem, shape: ShapeGuess, coordinates: tuple) -> InitialGuess:
    """The state guess (nz × (N+1)) of one candidate; zero controls."""
    if shape.label == FITTED.label:
        from .fitted import fitted_guess
        return fitted_guess(problem, coordinates, [_ends(problem, c)[0] for c in coordinates])
    if shape.label == PATH.label:
        from .path_guess import path_guess
        return path_guess(problem, coordinates, lambda name: _ends(problem, name))
    if shape.rates:
        return _rollout(problem, shape, coordinates)
    t = problem.grid()
    T = float(problem.horizon)
    w = 2 * math.pi / T
    n = len(coordinates)
    q, qdot = np.zeros((n, t.size)), np.zeros((n, t.size))
    for i, name in enumerate(coordinates):
        a, b = _ends(problem, name)
        q[i] = a + (b - a) * t / T
        qdot[i] = (b - a) / T
    for name, amp, k, phase in shape.waves:
        i = coordinates.index(name)
        q[i] += amp * np.sin(k * w * t + phase)
        qdot[i] += amp * k * w * np.cos(k * w * t + phase)
    state = problem.model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q[:, j], qdot[:, j], problem.params)).ravel() for j in range(t.size)])
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

    q = np.array([_ends(problem, c)[0] for c in coordinates])
    for name, amp, k, phase in shape.waves:
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


def _rate_states(model, shape: tuple) -> tuple:
    """Velocity states of a velocity-coordinate model that are not shape rates."""
    n = len(model.system.coordinates)
    velocities = tuple(getattr(model, "velocities", ()) or ())
    if not velocities:
        return ()
    return tuple(v for v in model.state_names[n:] if v not in {f"{c}_dot" for c in shape})


#: the fitted roll-out (:mod:`.fitted`), built by :func:`guess_from_shape` like the others
FITTED = ShapeGuess("fitted roll-out", ())
#: the path through the places a task states between its ends (:mod:`.path_guess`)
PATH = ShapeGuess("path through the stated places", ())


class Candidates(Sequence):
    """The planner's initial guesses in order of preference, each built when first used (a
    rollout integrates the kinematics, so building all of them up front would delay the
    first solve); ``with_first(guess)`` puts a ready guess (a warm start) in front."""

    def __init__(self, problem, shapes, coordinates, first=()):
        self._problem, self._shapes, self._coordinates = problem, tuple(shapes), tuple(coordinates)
        self._first = tuple(first)
        self._built: dict = {}

    def __len__(self) -> int:
        return len(self._first) + len(self._shapes)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = index + len(self) if index < 0 else index
        if not 0 <= i < len(self):
            raise IndexError(index)
        if i < len(self._first):
            return self._first[i]
        j = i - len(self._first)
        if j not in self._built:
            self._built[j] = guess_from_shape(self._problem, self._shapes[j], self._coordinates)
        return self._built[j]

    def with_first(self, guess) -> "Candidates":
        return Candidates(self._problem, self._shapes, self._coordinates, (guess, *self._first))


def candidates(problem, *, shape=None) -> Candidates:
    """Initial guesses for ``problem`` in order of preference (see the module docstring),
    built lazily. ``shape`` defaults to the model's shape variables (``problem.model.shape``).
    """
    model = problem.model
    coords = tuple(model.system.coordinates)
    shape = tuple(shape if shape is not None else getattr(model, "shape", ()))
    n_pairs = len(shape) * (len(shape) - 1) // 2
    loops = _order(shape_guesses(problem, shape), n_pairs)
    rollouts = rollout_guesses(problem, shape, _rate_states(model, shape))
    from .fitted import applies, leads
    ordered = _interleave(loops[:-1], rollouts) + loops[-1:]
    if applies(problem):
        at = 0 if leads(problem, shape) else 1
        ordered = ordered[:at] + [FITTED] + ordered[at:]
    from . import path_guess
    if path_guess.applies(problem):        # a task that says where to pass: along there first
        ordered = [PATH] + ordered
    return Candidates(problem, ordered, coords)
