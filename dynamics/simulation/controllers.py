"""Controllers for :func:`~nhgait.dynamics.simulation.driver.simulate`: u = controller(t, q, q̇).

Protocol (duck-typed; every controller here implements it)
---------------------------------------------------------
``__call__(t, q, q_dot) -> u``
    numpy: t float, q (n,), q_dot (n,) → u (m,) in the order of ``System.inputs``.
``casadi(t, q, q_dot) -> SX`` (optional)
    The same law as a CasADi expression (t SX scalar, q and q_dot SX (n, 1)) → SX (m, 1).
    Required by ``simulate(..., dae="idas")``; with it the scipy path also runs the closed
    loop as one compiled CasADi function.
``system_coordinates`` (optional)
    The system coordinate order the law indexes q with; :func:`simulate` checks it.
``inputs`` (optional)
    The input names u is ordered by; :func:`simulate` checks them against ``System.inputs``.
``breakpoints`` (optional)
    Times at which u may jump; the integrator restarts there and, inside each interval
    [a, b), sees the controller with t clamped to [a, b) so a switch is exact.
``domain`` (optional)
    (t_first, t_last) on which the law is defined; :func:`simulate` checks the time span.
``segment_size``, ``segment_data(a) -> d``, ``casadi_segment(t, q, q_dot, d) -> SX`` (optional)
    A law that reads, on the integration segment starting at a, a vector d (``segment_size``,)
    of numbers known at that breakpoint (an open-loop input's value and slope, a gain schedule's
    gains and reference). d enters the compiled closed loop as data, not as code: one compiled
    loop serves every d (:mod:`.closed_loop`). :class:`OpenLoop` and
    :class:`~.gain_schedule.GainSchedule` are such laws.

Thesis laws
-----------
Unicycle (eqs. 3.52–3.53): θ_d = sin t, φ_d = t, τ = k_p(q_d − q) + k_d(q̇_d − q̇),
k_p = 20, k_d = 5. Snakeboard (eqs. 3.95–3.96): ψ_d = sin t, φ_d = sin(t + π/2),
τ = q̈_d + k_p(q_d − q) + k_d(q̇_d − q̇), k_p = 10, k_d = 5 (the feed-forward q̈_d is added to
the torque as printed, without an inertia factor).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..errors import ModelError

UNICYCLE_COORDINATES = ("x", "y", "theta", "phi")
SNAKEBOARD_COORDINATES = ("x", "y", "theta", "psi", "phi")


def _is_symbolic(t) -> bool:
    return isinstance(t, (ca.SX, ca.MX))


@dataclass(frozen=True)
class Sinusoid:
    """Reference q_d(t) = offset + rate·t + amplitude·sin(frequency·t + phase).

    Evaluates on floats (numpy) and on CasADi SX alike, so one object feeds both the numeric
    and the symbolic controller.
    """

    amplitude: float = 1.0
    frequency: float = 1.0
    phase: float = 0.0
    offset: float = 0.0
    rate: float = 0.0

    def position(self, t):
        sin = ca.sin if _is_symbolic(t) else np.sin
        return self.offset + self.rate * t + self.amplitude * sin(self.frequency * t + self.phase)

    def velocity(self, t):
        cos = ca.cos if _is_symbolic(t) else np.cos
        return self.rate + self.amplitude * self.frequency * cos(self.frequency * t + self.phase)

    def acceleration(self, t):
        sin = ca.sin if _is_symbolic(t) else np.sin
        return -self.amplitude * self.frequency ** 2 * sin(self.frequency * t + self.phase)


@dataclass(frozen=True)
class _Callables:
    """A reference given as three callables (q_d, q̇_d, q̈_d)."""

    position: object
    velocity: object
    acceleration: object


def _reference(desired, name):
    if all(hasattr(desired, a) for a in ("position", "velocity", "acceleration")):
        return desired
    if isinstance(desired, (tuple, list)) and len(desired) == 3 and all(map(callable, desired)):
        return _Callables(*desired)
    raise ModelError([f"reference for {name!r} must be a Sinusoid-like object (position, velocity, "
                      "acceleration) or a tuple of three callables (q_d, qd_d, qdd_d)"],
                     title="invalid controller")


@dataclass(frozen=True, eq=False)
class PDTracking:
    """PD tracking law on actuated coordinates, one input per tracked coordinate.

    u_i = [q̈_d,i(t)] + k_p (q_d,i(t) − q_c(i)) + k_d (q̇_d,i(t) − q̇_c(i)),

    where c(i) is the index of ``coordinates[i]`` in ``system_coordinates``; the bracketed
    feed-forward term is present when ``feedforward`` is true.

    Parameters
    ----------
    coordinates : sequence of str, length m
        Tracked coordinate names; u[i] acts on ``coordinates[i]``.
    desired : mapping name → reference
        Each reference a :class:`Sinusoid` (or any object with ``position``, ``velocity``,
        ``acceleration``) or a tuple of callables (q_d, q̇_d, q̈_d) of t.
    kp, kd : float
        Proportional and derivative gains.
    feedforward : bool
        Add q̈_d to the torque (thesis eq. 3.96).
    system_coordinates : sequence of str, length n
        The system's coordinate order (q is indexed with it).
    inputs : sequence of str, length m, optional
        Names of the inputs, checked by :func:`simulate` against ``System.inputs``.
    """

    coordinates: tuple
    desired: dict
    kp: float
    kd: float
    feedforward: bool
    system_coordinates: tuple
    inputs: tuple | None = None

    def __post_init__(self):
        problems = []
        coordinates, system_coordinates = tuple(self.coordinates), tuple(self.system_coordinates)
        missing = [c for c in coordinates if c not in system_coordinates]
        if missing:
            problems.append(f"tracked coordinates {missing} are not in {system_coordinates}")
        if set(self.desired) != set(coordinates):
            problems.append(f"references given for {sorted(self.desired)}, tracked {list(coordinates)}")
        if self.inputs is not None and len(self.inputs) != len(coordinates):
            problems.append(f"{len(self.inputs)} input names for {len(coordinates)} tracked coordinates")
        for gain in ("kp", "kd"):
            if not math.isfinite(float(getattr(self, gain))):
                problems.append(f"{gain} must be finite")
        if problems:
            raise ModelError(problems, title="invalid controller")
        refs = {c: _reference(self.desired[c], c) for c in coordinates}
        object.__setattr__(self, "coordinates", coordinates)
        object.__setattr__(self, "system_coordinates", system_coordinates)
        object.__setattr__(self, "inputs", None if self.inputs is None else tuple(self.inputs))
        object.__setattr__(self, "desired", refs)
        object.__setattr__(self, "_index", tuple(system_coordinates.index(c) for c in coordinates))

    def _law(self, t, q, q_dot):
        out = []
        for name, i in zip(self.coordinates, self._index, strict=True):
            ref = self.desired[name]
            u = self.kp * (ref.position(t) - q[i]) + self.kd * (ref.velocity(t) - q_dot[i])
            if self.feedforward:
                u = u + ref.acceleration(t)
            out.append(u)
        return out

    def __call__(self, t, q, q_dot) -> np.ndarray:
        """u (m,) at time t for q (n,), q_dot (n,)."""
        return np.array([float(v) for v in self._law(float(t), np.asarray(q, float),
                                                       np.asarray(q_dot, float))])

    def casadi(self, t, q, q_dot) -> ca.SX:
        """The same law as a CasADi SX (m, 1)."""
        return ca.vertcat(*self._law(t, q, q_dot))

    def initial_state(self, t0: float = 0.0):
        """(q_d(t0), q̇_d(t0)) of the tracked coordinates, each (m,) — thesis Tables 3.2–3.3."""
        refs = [self.desired[c] for c in self.coordinates]
        return (np.array([float(r.position(t0)) for r in refs]),
                np.array([float(r.velocity(t0)) for r in refs]))


def unicycle_pd(system_coordinates=UNICYCLE_COORDINATES) -> PDTracking:
    """Thesis eqs. 3.52–3.53: θ_d = sin t, φ_d = t; k_p = 20, k_d = 5; no feed-forward."""
    return PDTracking(coordinates=("theta", "phi"),
                      desired={"theta": Sinusoid(), "phi": Sinusoid(amplitude=0.0, rate=1.0)},
                      kp=20.0, kd=5.0, feedforward=False, system_coordinates=system_coordinates,
                      inputs=("tau_theta", "tau_phi"))


def snakeboard_pd(system_coordinates=SNAKEBOARD_COORDINATES) -> PDTracking:
    """Thesis eqs. 3.95–3.96: ψ_d = sin t, φ_d = sin(t + π/2); k_p = 10, k_d = 5; with q̈_d."""
    return PDTracking(coordinates=("psi", "phi"),
                      desired={"psi": Sinusoid(), "phi": Sinusoid(phase=math.pi / 2)},
                      kp=10.0, kd=5.0, feedforward=True, system_coordinates=system_coordinates,
                      inputs=("tau_psi", "tau_phi"))


class KnotSchedule:
    """What a law on knots ``times`` (t_0 < … < t_N, an attribute of the class) has: the
    integrator restarts at the interior knots (``breakpoints``), the law is defined on
    [t_0, t_N] (``domain``) and :meth:`interval` finds the knot interval of a time."""

    @property
    def breakpoints(self) -> np.ndarray:
        """Interior knots (N−1,)."""
        return self.times[1:-1]

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.times[0]), float(self.times[-1])

    def interval(self, t: float) -> int:
        """k with t in [t_k, t_{k+1}) (right-continuous at the knots), clamped to 0 … N−1."""
        return int(np.clip(np.searchsorted(self.times, float(t), side="right") - 1, 0, self.times.size - 2))


@dataclass(frozen=True, eq=False)
class OpenLoop(KnotSchedule):
    """Open-loop input on a time grid: zero-order hold or piecewise linear.

    Parameters
    ----------
    times : array (N+1,)
        Strictly increasing knots t_0 < … < t_N.
    values : array (N, m) for ``kind="zoh"`` (value on [t_j, t_{j+1})) or (N+1, m) for
        ``kind="linear"`` (values at the knots, linear in between).
    kind : {"zoh", "linear"}
    inputs : sequence of str, optional — input names, checked by :func:`simulate`.

    Outside [t_0, t_N] the first/last value is held; :func:`simulate` refuses a time span
    outside ``domain``. ``breakpoints`` are the interior knots, where :func:`simulate` restarts
    the integrator so each switch is exact.
    """

    times: np.ndarray
    values: np.ndarray
    kind: str = "zoh"
    inputs: tuple | None = None

    def __post_init__(self):
        times = np.asarray(self.times, dtype=float).ravel()
        values = np.asarray(self.values, dtype=float)
        if values.ndim == 1:
            values = values[:, None]
        problems = []
        if self.kind not in ("zoh", "linear"):
            problems.append(f"unknown kind {self.kind!r} (zoh or linear)")
        if times.size < 2 or not np.all(np.diff(times) > 0):
            problems.append("times must hold at least two strictly increasing knots")
        expected = times.size - 1 if self.kind == "zoh" else times.size
        if values.ndim != 2 or values.shape[0] != expected:
            problems.append(f"values must have shape ({expected}, m) for kind={self.kind!r} and "
                            f"{times.size} knots, got {values.shape}")
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values))):
            problems.append("times and values must be finite")
        if self.inputs is not None and values.ndim == 2 and len(self.inputs) != values.shape[1]:
            problems.append(f"{len(self.inputs)} input names for {values.shape[1]} value columns")
        if problems:
            raise ModelError(problems, title="invalid controller")
        times.setflags(write=False)
        values.setflags(write=False)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "inputs", None if self.inputs is None else tuple(self.inputs))

    @property
    def segment_size(self) -> int:
        """Length of :meth:`segment_data`: (u₀, u₁, t_a) with m entries each for u₀ and u₁."""
        return 2 * self.values.shape[1] + 1

    def segment_data(self, a: float) -> np.ndarray:
        """(u₀, u₁, a) on the segment starting at ``a``: u = u₀ + u₁ (t − a) there (u₁ = 0 for
        ``kind="zoh"``)."""
        times, values = self.times, self.values
        j = self.interval(a)
        if self.kind == "zoh":
            u0, u1 = values[j], np.zeros(values.shape[1])
        else:
            u1 = (values[j + 1] - values[j]) / (times[j + 1] - times[j])
            u0 = values[j] + u1 * (a - times[j])
        return np.r_[u0, u1, a]

    def casadi_segment(self, t, q, q_dot, data) -> ca.SX:
        """u = u₀ + u₁ (t − t_a) with d = (u₀, u₁, t_a) from :meth:`segment_data`."""
        m = self.values.shape[1]
        return data[:m] + data[m:2 * m] * (t - data[2 * m])

    def __call__(self, t, q=None, q_dot=None) -> np.ndarray:
        """u (m,) at time t (right-continuous at the knots); q, q_dot are ignored."""
        t = float(t)
        if self.kind == "zoh":
            return self.values[self.interval(t)].copy()
        tc = min(max(t, self.times[0]), self.times[-1])
        return np.array([np.interp(tc, self.times, col) for col in self.values.T])

    def casadi(self, t, q=None, q_dot=None) -> ca.SX:
        """The same input as a CasADi expression of t, (m, 1)."""
        if self.kind == "zoh":
            inner = ca.DM(self.times[1:-1])
            return ca.vertcat(*[ca.pw_const(t, inner, ca.DM(col)) for col in self.values.T])
        tc = ca.fmin(ca.fmax(t, self.times[0]), self.times[-1])
        return ca.vertcat(*[ca.pw_lin(tc, ca.DM(self.times), ca.DM(col)) for col in self.values.T])
