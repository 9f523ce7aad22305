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
The two-variable loops are ranked by the local connection's prediction of how far each moves
the robot toward the target (:mod:`.loop_ranking`): the best first, the ones predicted to move
it away after every other candidate but the ramps; the ranking runs when the first candidate past the leading
ones (path, fitted guess, warm start) is asked for (:class:`RankedOrder`).

Configurations q(t) and their rates q̇(t) (ramps included) are mapped to the model's state
by its ``state(q, q̇)`` map; the controls are zero. :func:`candidates` returns them in order;
the planner tries them (several at once when cores allow) and reports which one won.

Each candidate is checked along its whole length before it is handed out
(:class:`~.screening.Screen`: ż finite, the configurations off the singular set of the
equations) and repaired or skipped when it fails (:class:`Candidates`, :func:`~.waves.repairs`);
shape coordinates free at t = 0 whose centres lie on the singular set start off it in every
candidate. The waves, the ramps and the states of a candidate are :mod:`.waves`.
"""
from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from .loop_ranking import rank_loops
from .screening import RATIO, Check, Screen
from .waves import (
    FITTED_LABEL,
    PATH_LABEL,
    ShapeGuess,
    amplitude,
    ends,
    free_start,
    guess_from_shape,
    repairs,
)

__all__ = ["ShapeGuess", "shape_guesses", "rollout_guesses", "guess_from_shape", "candidates", "Candidates",
           "CandidateSetting", "RankedOrder", "Screened", "screened_dict", "RATIOS", "AMPLITUDES"]

RATIOS = ((1, 1), (2, 1), (1, 2), (3, 2), (2, 3))
#: (A, B) as fractions of the largest allowed amplitude of each variable (1 rad when unbounded)
AMPLITUDES = ((1.0, 0.9), (1.0, 0.6), (-1.0, 0.9), (0.6, 1.0))
SINGLE = ((1, 0.5), (1, 1.0), (2, 0.5), (1, -0.5))


def shape_guesses(problem, shape: tuple, start=()) -> list:
    """The shape-loop candidates (see the module docstring), in order of preference; ``start``:
    where the coordinates free at t = 0 start (:class:`ShapeGuess`)."""
    out = []
    start = tuple(start)
    fixed0 = {n for n in shape if problem.fixed_value(problem.initial, n) is not None}
    for a, b in combinations(shape, 2):
        amp_a, amp_b = amplitude(problem, a, start), amplitude(problem, b, start)
        # the variable fixed at t = 0 carries the sine (phase 0), the other the cosine
        if b in fixed0 and a not in fixed0:
            a, b, amp_a, amp_b = b, a, amp_b, amp_a
        phase_b = 0.0 if b in fixed0 else math.pi / 2
        for ka, kb in RATIOS:
            for fa, fb in AMPLITUDES:
                label = f"{a}:{b} {ka}:{kb} A={fa * amp_a:.2g} B={fb * amp_b:.2g}"
                out.append(ShapeGuess(label, ((a, fa * amp_a, ka, 0.0), (b, fb * amp_b, kb, phase_b)),
                                      start=start))
    if len(shape) == 1:
        (a,) = shape
        amp = amplitude(problem, a, start)
        phase = 0.0 if a in fixed0 else math.pi / 2
        for k, f in SINGLE:
            out.append(ShapeGuess(f"{a} k={k} A={f * amp:.2g}", ((a, f * amp, k, phase),), start=start))
    out.append(ShapeGuess("ramps only", (), start=start))
    return out


def rollout_guesses(problem, shape: tuple, rates: tuple, start=()) -> list:
    """Rollout candidates: each velocity state of ``rates`` paired with each shape variable."""
    start = tuple(start)
    T = float(problem.horizon)
    w = 2 * math.pi / T
    mean = _mean_speed(problem)
    out = []
    fixed0 = {n for n in shape if problem.fixed_value(problem.initial, n) is not None}
    for v in rates:
        reach = max(abs(mean) * T, _span(problem), 0.25)
        for b in shape or (None,):
            amp_b = amplitude(problem, b, start) if b else 0.0
            phase_b = 0.0 if b in fixed0 else math.pi / 2
            for kv, kb in RATIOS:
                for fa, fb in AMPLITUDES[:2] + ((-1.0, 0.6),):
                    A = fa * reach * w * kv / 2          # excursion 2A/(k ω) ≈ the task's reach
                    waves = ((b, fb * amp_b, kb, phase_b),) if b else ()
                    label = f"rollout {v}:{b} {kv}:{kb} A={A:.2g}" + (f" B={fb * amp_b:.2g}" if b else "")
                    out.append(ShapeGuess(label, waves, ((v, mean, A, kv, 0.0),), start))
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
    return [g for row in zip(*blocks, strict=False) for g in row] + rest


def _rate_states(model, shape: tuple) -> tuple:
    """Velocity states of a velocity-coordinate model that are not shape rates."""
    n = len(model.system.coordinates)
    velocities = tuple(getattr(model, "velocities", ()) or ())
    if not velocities:
        return ()
    return tuple(v for v in model.state_names[n:] if v not in {f"{c}_dot" for c in shape})


@dataclass(frozen=True)
class Screened:
    """What the screening did to one candidate before any solve: ``action`` "repaired" (tried as
    ``repair`` says) or "skipped" (never solved), and the :class:`~.screening.Check` of the
    candidate as generated (where it met the singular set or a non-finite ż)."""

    label: str
    action: str
    check: Check
    repair: str = ""


def screened_dict(record: Screened) -> dict:
    """A :class:`Screened` record as plain data (solution.json)."""
    c = record.check
    return {"label": record.label, "action": record.action, "repair": record.repair, "what": c.what,
            "t": c.t, "configuration": dict(zip(c.coordinates, c.q, strict=True)), "measure": c.measure}


@dataclass(frozen=True, eq=False)
class CandidateSetting:
    """What every candidate of one problem shares: the ``problem``, its ``coordinates``, the
    ``screen`` (:class:`~.screening.Screen`, None: unchecked), the ``start`` of the coordinates
    free at t = 0, the ``progress`` that hears about repairs and skips, and ``blocked``: the
    :class:`~.screening.Check` of an end every candidate shares on the singular set (None)."""

    problem: object
    coordinates: tuple
    screen: object = None
    start: tuple = ()
    progress: object = None
    blocked: object = None


class RankedOrder(Sequence):
    """The candidates' order (:func:`candidates`): ``head`` (a path guess, a leading fitted
    guess) and the rest, made by ``tail()`` — which ranks the shape loops
    (:func:`~.loop_ranking.rank_loops`) — only when an item past the head is first asked for,
    so a plan whose leading guesses converge never pays for the ranking. ``length`` is the
    tail's length (the ranking reorders, it does not remove)."""

    def __init__(self, head, tail, length: int):
        self._head, self._make, self._length, self._tail = tuple(head), tail, int(length), None

    def __len__(self) -> int:
        return len(self._head) + self._length

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = index + len(self) if index < 0 else index
        if not 0 <= i < len(self):
            raise IndexError(index)
        if i < len(self._head):
            return self._head[i]
        if self._tail is None:
            self._tail = list(self._make())
        return self._tail[i - len(self._head)]


class Candidates(Sequence):
    """The planner's initial guesses in order of preference, each built and screened when first
    used (a rollout integrates the kinematics, so building all of them up front would delay the
    first solve); ``with_first(guess)`` puts a ready guess (a warm start) in front.

    Every candidate is checked along its whole length (:class:`~.screening.Screen`) before it is
    handed out; one that meets the singular set or a non-finite ż is repaired
    (:func:`~.waves.repairs`) or, when no repair avoids it, skipped: item i is the i-th
    candidate that passed. ``len()`` counts the candidates not known to be skipped (it shrinks
    as skips are found); ``screened`` lists what was repaired or skipped, ``screen_seconds`` the
    time the checks and repairs took, ``first_skipped`` the first skipped guess (as generated).
    ``start`` is where the coordinates free at t = 0 start in every candidate (off the singular
    set; empty when their centres are regular)."""

    def __init__(self, setting: CandidateSetting, shapes, first=()):
        self._setting, self._shapes, self._first = setting, shapes, tuple(first)
        self._problem, self._coordinates = setting.problem, setting.coordinates
        self._screen, self.start, self._blocked = setting.screen, setting.start, setting.blocked
        self._progress = setting.progress
        self._accepted: list = []
        self._next = 0
        self.screened: list = []
        self.screen_seconds = 0.0
        self.first_skipped = None

    def __len__(self) -> int:
        return len(self._accepted) + len(self._first) + len(self._shapes) - self._next

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = index + len(self) if index < 0 else index
        while i >= len(self._accepted) and self._advance():
            i = index + len(self) if index < 0 else index
        if not 0 <= i < len(self._accepted):
            raise IndexError(index)
        return self._accepted[i]

    def _advance(self) -> bool:
        """Build and screen the next candidate; False when none is left."""
        if self._next >= len(self._first) + len(self._shapes):
            return False
        j, self._next = self._next, self._next + 1
        if self._blocked is not None and j >= len(self._first):
            label = self._shapes[j - len(self._first)].label
            self.screened.append(Screened(label, "skipped", self._blocked))
            if j == len(self._first):
                names = tuple(getattr(self._problem.model, "shape", ())) or None
                self._progress.note("  every candidate skipped, not solved: "
                                    f"{self._blocked.reason(names)}, where "
                                    "every guess starts or ends (fixed by the task)")
            return True
        if j < len(self._first):
            shape, guess = None, self._first[j]
        else:
            shape = self._shapes[j - len(self._first)]
            guess = guess_from_shape(self._problem, shape, self._coordinates)
        if self._screen is None:
            self._accepted.append(guess)
            return True
        t0 = time.perf_counter()
        accepted = self._screened(guess, shape)
        self.screen_seconds += time.perf_counter() - t0
        if accepted is not None:
            self._accepted.append(accepted)
        return True

    def _screened(self, guess, shape):
        """``guess`` when it passes, else its first repair that passes, else None (recorded)."""
        check = self._screen.check(guess)
        if check.ok:
            return guess
        names = tuple(getattr(self._problem.model, "shape", ())) or None
        free = free_start(self._problem, self._coordinates)
        tried = 0
        for variant, what in (repairs(self._problem, shape, free) if shape is not None else ()):
            tried += 1
            repaired = guess_from_shape(self._problem, variant, self._coordinates)
            if self._screen.check(repaired).ok:
                self.screened.append(Screened(guess.label, "repaired", check, what))
                self._progress.note(f"  guess {guess.label!r}: {check.reason(names)}; repaired ({what})")
                return repaired
        self.screened.append(Screened(guess.label, "skipped", check))
        self.first_skipped = self.first_skipped or guess
        self._progress.note(f"  guess {guess.label!r} skipped, not solved: {check.reason(names)}"
                            + (f"; none of {tried} repairs (phase, centre, amplitude) avoids it"
                               if tried else ""))
        return None

    def check(self, guess):
        """The :class:`~.screening.Check` of any guess or solution on this problem's grid (None
        when the candidates are not screened)."""
        return None if self._screen is None else self._screen.check(guess)

    @property
    def given_first(self) -> bool:
        """Whether a given guess (a warm start, :meth:`with_first`) leads the candidates."""
        return bool(self._first)

    def with_first(self, guess) -> Candidates:
        return Candidates(self._setting, self._shapes, (guess, *self._first))


def candidates(problem, *, shape=None, screen=True, progress=None) -> Candidates:
    """Initial guesses for ``problem`` in order of preference (see the module docstring),
    built and screened lazily (:class:`Candidates`). ``shape`` defaults to the model's shape
    variables (``problem.model.shape``); ``screen`` False hands them out unchecked; ``progress``
    hears about repaired and skipped candidates and a moved start."""
    model = problem.model
    coords = tuple(model.system.coordinates)
    shape = tuple(shape if shape is not None else getattr(model, "shape", ()))
    checks = Screen(problem) if screen else None
    start, moved = (_regular_start(problem, checks, coords, shape, progress) if checks is not None
                    else ((), None))
    n_pairs = len(shape) * (len(shape) - 1) // 2
    loops = _order(shape_guesses(problem, shape, start), n_pairs)
    rollouts = rollout_guesses(problem, shape, _rate_states(model, shape), start)
    from . import path_guess
    from .fitted import applies, leads
    head, fitted = [], None
    if path_guess.applies(problem):        # a task that says where to pass: along there first
        head.append(ShapeGuess(PATH_LABEL, (), start=start))
    if applies(problem):                   # the fitted guess first, or second after the best loop
        fitted = ShapeGuess(FITTED_LABEL, (), start=start)
        head, fitted = (head + [fitted], None) if leads(problem, shape) else (head, fitted)

    def tail() -> list:
        ranked = rank_loops(problem, loops, progress)
        out = _interleave(list(ranked.front[:-1]), rollouts) + list(ranked.away) + list(ranked.front[-1:])
        return out[:1] + [fitted] + out[1:] if fitted is not None else out

    order = RankedOrder(head, tail, len(loops) + len(rollouts) + (fitted is not None))
    blocked = _blocked_end(problem, checks, coords, start) if checks is not None else None
    setting = CandidateSetting(problem, coords, screen=checks, start=start, progress=progress or _silent(),
                               blocked=blocked)
    out = Candidates(setting, order)
    if moved is not None:
        out.screened.append(moved)
    return out


def _silent():
    from nhgait.dynamics.progress import Progress
    return Progress.silent()


def _blocked_end(problem, checks, coords, start):
    """The :class:`~.screening.Check` of an end configuration every candidate shares (the start,
    or the end of the ramps) when it lies on the singular set — no repair can move it — else None."""
    T = float(problem.horizon)
    for j, t in ((0, 0.0), (1, T)):
        q = np.array([ends(problem, c, start)[j] for c in coords])
        m = float(checks.measure(q[:, None])[0])
        if m < RATIO:
            return Check(False, "singular", t, tuple(float(v) for v in q), coords, m)
    return None


def _regular_start(problem, checks, coords, shape, progress) -> tuple:
    """(start, record): start values, off the singular set, for the shape coordinates free at
    t = 0 whose centres (:func:`~.waves.centre`) are on it — ((name, value), ...), empty when
    the centres are regular — and the :class:`Screened` record of the move (or None)."""
    free = {c: r for c, r in free_start(problem, coords).items() if c in shape}
    q0 = np.array([ends(problem, c)[0] for c in coords])
    moved = checks.regular_start(q0, free)
    if not moved:
        return (), None
    was = ", ".join(f"{c} = {q0[coords.index(c)]:.3g}" for c in moved)
    now = ", ".join(f"{c} = {v:.3g}" for c, v in moved.items())
    if progress is not None:
        progress.note(f"  the free start {was} is on the singular set of the equations: every guess "
                      f"starts at {now}")
    at = Check(False, "singular", 0.0, tuple(float(v) for v in q0), coords,
               float(checks.measure(q0[:, None])[0]))
    return tuple(moved.items()), Screened("free start", "moved", at, now)
