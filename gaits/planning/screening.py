"""Checking a guess before a solver sees it: the equations along the whole guess.

A guess that meets the singular set of the equations the solver is given — where the velocity
states stop determining the motion (det A = 0, A = [ω_b; Y_b] of
:mod:`nhgait.dynamics.numerics.velocity_coordinates`), or where a route through the reduction's
chart divides by its pivot block — gives NaN or huge values in the transcription's first
evaluation: Ipopt refuses the point (``Invalid_Initial_Point``) or spends hundreds of iterations
in restoration. :class:`Screen` finds that before the solve, for the cost of two vectorised
evaluations:

* ż = f(z, u) at every node and at every midpoint between two nodes (the states averaged, the
  interval's control): every entry finite;
* the measure of the singular set at the same 2N + 1 configurations: with the velocity map,
  det A keeps the sign it has at t = 0 (a sign change is a crossing between two points) and
  |det A| / Π‖rows‖ stays above :data:`RATIO` of its typical value in the task's region; for a
  route through the chart also the chart's measure (``singular``) above that fraction.

:meth:`Screen.check` returns a :class:`Check`: ``ok``, and otherwise where the guess met the
set — the time and the posture in the user's coordinate names (:meth:`Check.posture`).
:meth:`Screen.regular_start` moves the free initial values of the shape off the singular set.
Measured (N = 50–60, one process, a 2-core machine shared by several jobs): a check takes
1.4 ms for the 3-link snake and the two-steering snakeboard, 4.8 ms for the cart with six
trailers, 11–14 ms for the 5- and 8-link snakes (the 2N + 1 evaluations of ż dominate);
building the :class:`Screen` 6–22 ms — against 0.1–3 s for one solve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from nhgait.ocp.solution import node_arrays

__all__ = ["Screen", "Check", "RATIO", "START_RATIO"]

#: a configuration whose normalised |det A| (or chart measure) is below this fraction of the
#: measure's median over the task's region counts as on the singular set
RATIO = 1e-3
#: a free start is moved until its measure is at least this fraction of that median
START_RATIO = 0.1


def _median_size(values) -> float:
    """The median of |values| over the finite ones (0 without any)."""
    if values is None or not np.isfinite(values).any():
        return 0.0
    return float(np.median(np.abs(values[np.isfinite(values)])))


@dataclass(frozen=True)
class Check:
    """The verdict on one guess: ``ok``; else ``what`` went wrong ("singular", "not finite"),
    at time ``t`` (s) and configuration ``q`` (values in ``coordinates`` order), with the
    ``measure`` there."""

    ok: bool
    what: str = ""
    t: float = math.nan
    q: tuple = ()
    coordinates: tuple = ()
    measure: float = math.nan

    def posture(self, names=None) -> str:
        """"alpha1 = 0.31, alpha2 = 0.31": the values of ``names`` (default: every coordinate)."""
        pairs = [(c, v) for c, v in zip(self.coordinates, self.q, strict=True) if names is None or c in names]
        return ", ".join(f"{c} = {v:.3g}" for c, v in pairs)

    def reason(self, shape=None) -> str:
        """One line: what the guess met, where and when."""
        if self.ok:
            return "regular"
        where = f"{self.posture(shape)} (t = {self.t:.2f} s)"
        if self.what == "not finite":
            return f"the equations are not finite at {where}"
        return f"it meets the singular set at {where}"


class SamplePoints(NamedTuple):
    """What :meth:`Screen.points` returns."""

    t: np.ndarray   #: (2N+1,) the nodes and the midpoints in time order
    Z: np.ndarray   #: nz × (2N+1) the model's states
    U: np.ndarray   #: nu × (2N+1)


class Screen:
    """The checks of one problem (module docstring), built once: the vectorised ż and measures,
    the measure's typical value over the task's region."""

    def __init__(self, problem):
        from nhgait.dynamics.numerics.velocity_coordinates import region_samples
        self.problem = problem
        model = problem.model
        self.coordinates = tuple(model.system.coordinates)
        self.n = len(self.coordinates)
        numeric = model.numeric
        self.params = numeric.params(problem.params)
        N = problem.intervals
        self._rhs = numeric["rhs"].map(2 * N + 1)
        self._map = numeric.functions.get("velocity_map")
        self._singular = numeric.functions.get("singular")
        bounds = {c: problem.bounds(problem.state_bounds, c) for c in self.coordinates
                  if c in problem.state_bounds}
        samples = region_samples(self.coordinates, bounds, count=64)
        self._typical = self._typical_values(samples)

    # ------------------------------------------------------------------ measures
    def _determinants(self, q: np.ndarray) -> np.ndarray | None:
        """Signed det A / Π‖rows‖ at the columns of ``q`` (None without a velocity map)."""
        if self._map is None:
            return None
        K = q.shape[1]
        with np.errstate(all="ignore"):
            A = np.asarray(self._map.map(K)(q, self.params)).reshape(self.n, K, self.n).transpose(1, 0, 2)
            return np.linalg.det(A) / np.prod(np.linalg.norm(A, axis=2), axis=1)

    def _chart(self, q: np.ndarray) -> np.ndarray | None:
        if self._singular is None:
            return None
        with np.errstate(all="ignore"):
            return np.asarray(self._singular.map(q.shape[1])(q, self.params)).ravel()

    def _typical_values(self, samples: np.ndarray) -> tuple:
        q = samples.T
        det, chart = self._determinants(q), self._chart(q)
        return _median_size(det), _median_size(chart)

    def measure(self, q: np.ndarray) -> np.ndarray:
        """Per column of ``q`` (n × K): the smaller of |det A| and the chart's measure, each as a
        fraction of its typical value (≥ 1 is ordinary; below :data:`RATIO` singular)."""
        out = np.full(q.shape[1], np.inf)
        for values, typical in ((self._determinants(q), self._typical[0]),
                                (self._chart(q), self._typical[1])):
            if values is not None and typical > 0:
                out = np.minimum(out, np.where(np.isfinite(values), np.abs(values) / typical, 0.0))
        return out

    # ------------------------------------------------------------------ checks
    def points(self, guess) -> SamplePoints:
        """(t (2N+1,), Z (nz × (2N+1)), U (nu × (2N+1))): the nodes and the midpoints, in time order
        (Z the model's states: a task's integral states, which follow them, are left out)."""
        nz = len(self.problem.model_state_names)
        Z, U = node_arrays(guess)
        Z = Z[:nz]
        T = float(guess.horizon if guess.horizon is not None else self.problem.horizon)
        N = Z.shape[1] - 1
        t = np.linspace(0.0, T, 2 * N + 1)
        pts = np.empty((Z.shape[0], 2 * N + 1))
        pts[:, 0::2], pts[:, 1::2] = Z, (Z[:, :-1] + Z[:, 1:]) / 2
        Uk = np.empty((U.shape[0], 2 * N + 1))
        Uk[:, 0::2], Uk[:, 1::2] = U[:, np.minimum(np.arange(N + 1), N - 1)], U
        return SamplePoints(t, pts, Uk)

    def check(self, guess) -> Check:
        """The verdict on ``guess`` (an InitialGuess on the problem's grid; module docstring)."""
        t, Z, U = self.points(guess)
        if Z.shape[1] != 2 * self.problem.intervals + 1:
            return Check(True)
        with np.errstate(all="ignore"):
            zdot = np.asarray(self._rhs(t, Z, U, self.params))
        bad = ~np.all(np.isfinite(zdot), axis=0) | ~np.all(np.isfinite(Z), axis=0)
        if bad.any():
            return self._at(int(np.argmax(bad)), "not finite", t, Z, np.nan)
        q = Z[:self.n]
        det = self._determinants(q)
        if det is not None and np.all(np.isfinite(det)) and det[0] != 0:
            crossed = np.sign(det) != np.sign(det[0])
            if crossed.any():
                j = int(np.argmax(crossed))
                j = j - 1 if abs(det[j - 1]) < abs(det[j]) else j
                return self._at(j, "singular", t, Z, abs(det[j]) / max(self._typical[0], 1e-300))
        m = self.measure(q)
        j = int(np.argmin(m))
        if m[j] < RATIO:
            return self._at(j, "singular", t, Z, float(m[j]))
        return Check(True, measure=float(m[j]))

    def _at(self, j, what, t, Z, measure) -> Check:
        return Check(False, what, float(t[j]), tuple(float(v) for v in Z[:self.n, j]), self.coordinates,
                     float(measure))

    # ------------------------------------------------------------------ the start
    def regular_start(self, q0: np.ndarray, free: dict, count: int = 128) -> dict:
        """Values for the coordinates ``free`` (name → (lo, hi) within which the start may move)
        that put the start configuration ``q0`` (n,) at least :data:`START_RATIO` of the typical
        measure away from the singular set, nearest to ``q0`` (a grid of 5 values per coordinate,
        or ``count`` seeded samples for more than three): {name: value}, empty when ``q0`` is
        already regular or nothing better is found."""
        q0 = np.asarray(q0, float)
        if not free or self.measure(q0[:, None])[0] >= START_RATIO:
            return {}
        names = list(free)
        idx = [self.coordinates.index(c) for c in names]
        lo = np.array([free[c][0] for c in names])
        hi = np.array([free[c][1] for c in names])
        if len(names) <= 3:
            axes = [np.linspace(a, b, 5) for a, b in zip(lo, hi, strict=True)]
            trial = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(names), -1).T
        else:
            trial = np.random.default_rng(3).uniform(lo, hi, (count, len(names)))
        Q = np.repeat(q0[:, None], trial.shape[0], axis=1)
        Q[idx] = trial.T
        m = self.measure(Q)
        ok = np.flatnonzero(m >= START_RATIO)
        if ok.size == 0:
            return {}
        best = ok[np.argmin(np.linalg.norm(trial[ok] - q0[idx], axis=1))]
        return {c: float(v) for c, v in zip(names, trial[best], strict=True)}
