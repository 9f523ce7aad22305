"""A time-varying linear feedback along a reference trajectory: :class:`GainSchedule`.

On the grid t_0 < t_1 < … < t_N, with s = (t − t_k)/h_k on [t_k, t_{k+1}), h_k = t_{k+1} − t_k::

    u(t, q, q̇) = sat( u_k − K_k (σ(q, q̇) − z_ref(t)) ),
    z_ref(t)   = H₀₀(s) z_k + H₁₀(s) h_k ż_k⁺ + H₀₁(s) z_{k+1} + H₁₁(s) h_k ż_{k+1}⁻,

with σ the *state map* (q, q̇) ↦ z of the coordinates the gains were designed in (e.g. a planner's
velocity coordinates z = (q, y(q, q̇)); any parameters of σ are the designer's, bound in the
CasADi Function), z_ref the cubic Hermite interpolant of the reference nodes z_k and of the
reference's rates at both ends of each interval (H₀₀ = 2s³ − 3s² + 1, H₁₀ = s³ − 2s² + s,
H₀₁ = −2s³ + 3s², H₁₁ = s³ − s²: exact for cubics, error O(h⁴) on a smooth trajectory), u_k
the reference input (piecewise constant), K_k (m × nz) the gain of interval k and sat the clip
to [lower, upper] (the actuators' limits; ±inf: none).

The law is one of :mod:`.controllers`' laws *by segments*: on the segment starting at a the
closed loop reads the numbers ``segment_data(a)`` = (u_k, K_k row by row, z_k, z_{k+1},
h_k ż_k⁺, h_k ż_{k+1}⁻, t_k, h_k) as data, so one compiled closed loop (``simulate(...,
method="compiled")``) serves every gain, reference and input perturbation of the same sizes —
a sample of a tracking study with its own input noise costs no compilation.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from ..errors import ModelError
from .controllers import KnotSchedule

__all__ = ["GainSchedule", "hermite"]


def hermite(s, z0, z1, d0, d1):
    """The cubic Hermite interpolant at s ∈ [0, 1] of the values z0, z1 and the scaled rates
    d0 = h ż(0), d1 = h ż(1) (numpy or CasADi)."""
    return ((2 * s ** 3 - 3 * s ** 2 + 1) * z0 + (s ** 3 - 2 * s ** 2 + s) * d0
            + (-2 * s ** 3 + 3 * s ** 2) * z1 + (s ** 3 - s ** 2) * d1)


def _frozen(array) -> np.ndarray:
    a = np.array(array, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(kw_only=True, frozen=True, eq=False)
class GainSchedule(KnotSchedule):
    """u = sat(u_k − K_k (σ(q, q̇) − z_ref(t))) on [t_k, t_{k+1}) (module docstring).

    Parameters
    ----------
    times : (N+1,) strictly increasing knots t_k.
    controls : (N, m) reference inputs u_k (any perturbation added by the caller).
    gains : (N, m, nz) K_k.
    reference : (N+1, nz) reference states z_k at the knots.
    rates : (N, 2, nz) the reference's ż at the start (ż_k⁺) and end (ż_{k+1}⁻) of each interval.
    state_map : casadi Function (q (n,), q̇ (n,)) → z (nz,).
    lower, upper : (m,) saturation limits (±inf where none).
    inputs, system_coordinates : names checked by :func:`~.driver.simulate`.
    """

    times: np.ndarray
    controls: np.ndarray
    gains: np.ndarray
    reference: np.ndarray
    rates: np.ndarray
    state_map: ca.Function
    lower: np.ndarray
    upper: np.ndarray
    inputs: tuple | None = None
    system_coordinates: tuple | None = None

    def __post_init__(self):
        for name in ("times", "controls", "gains", "reference", "rates", "lower", "upper"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        problems = self._problems()
        if problems:
            raise ModelError(problems, title="invalid controller")
        for name in ("inputs", "system_coordinates"):
            value = getattr(self, name)
            object.__setattr__(self, name, None if value is None else tuple(value))

    def _problems(self) -> list:
        t, u, K, z, r = self.times, self.controls, self.gains, self.reference, self.rates
        N = t.size - 1
        m = u.shape[1] if u.ndim == 2 else -1
        nz = z.shape[1] if z.ndim == 2 else -1
        problems = []
        if t.ndim != 1 or N < 1 or not np.all(np.diff(t) > 0):
            problems.append("times must hold at least two strictly increasing knots")
        expected = {"controls": (u, (N, m)), "gains": (K, (N, m, nz)), "reference": (z, (N + 1, nz)),
                    "rates": (r, (N, 2, nz)), "lower": (self.lower, (m,)), "upper": (self.upper, (m,))}
        for name, (value, shape) in expected.items():
            if value.shape != shape:
                problems.append(f"{name} has shape {value.shape}, expected {shape} (N = {N}, m = "
                                f"{m}, nz = {nz})")
        for name in ("times", "controls", "gains", "reference", "rates"):
            if not np.all(np.isfinite(getattr(self, name))):
                problems.append(f"{name} must be finite")
        if self.state_map.n_in() != 2 or self.state_map.size1_out(0) != nz:
            problems.append(f"state_map must map (q, q̇) to z with {nz} entries")
        if np.any(self.lower > self.upper):
            problems.append("lower must not exceed upper")
        return problems

    # ---------------------------------------------------------------- the protocol of .controllers
    @property
    def n_controls(self) -> int:
        return self.controls.shape[1]

    @property
    def n_states(self) -> int:
        return self.reference.shape[1]

    @property
    def segment_size(self) -> int:
        """m + m·nz + 4 nz + 2 numbers per interval (module docstring)."""
        m, nz = self.n_controls, self.n_states
        return m + m * nz + 4 * nz + 2

    def segment_data(self, a: float) -> np.ndarray:
        """The numbers of the interval containing ``a`` (module docstring)."""
        k = self.interval(a)
        h = self.times[k + 1] - self.times[k]
        return np.r_[self.controls[k], self.gains[k].ravel(), self.reference[k], self.reference[k + 1],
                     h * self.rates[k, 0], h * self.rates[k, 1], self.times[k], h]

    def casadi_segment(self, t, q, q_dot, data):
        """The law (module docstring) as a CasADi expression of t, q, q̇ and a segment's data."""
        m, nz = self.n_controls, self.n_states
        u_k, at = data[:m], m
        K = ca.reshape(data[at:at + m * nz], nz, m).T          # rows of K_k were stored one after another
        at += m * nz
        z0, z1, d0, d1 = (data[at + i * nz:at + (i + 1) * nz] for i in range(4))
        t_k, h = data[at + 4 * nz], data[at + 4 * nz + 1]
        z_ref = hermite((t - t_k) / h, z0, z1, d0, d1)
        u = u_k - ca.mtimes(K, self.state_map(q, q_dot) - z_ref)
        return ca.vertcat(*[self._clip(u[j], j) for j in range(m)])

    def _clip(self, value, j):
        lo, hi = float(self.lower[j]), float(self.upper[j])
        if np.isfinite(hi):
            value = ca.fmin(value, hi)
        if np.isfinite(lo):
            value = ca.fmax(value, lo)
        return value

    def __call__(self, t, q, q_dot) -> np.ndarray:
        """u (m,) at time t for q (n,), q̇ (n,) (the same law, evaluated numerically)."""
        law = self._law()
        return np.asarray(law(float(t), np.asarray(q, float), np.asarray(q_dot, float),
                              self.segment_data(t)), dtype=float).ravel()

    def _law(self) -> ca.Function:
        law = self.__dict__.get("_law_function")
        if law is None:
            n = int(self.state_map.size1_in(0))
            t, q, qd = ca.SX.sym("t"), ca.SX.sym("q", n), ca.SX.sym("qdot", n)
            d = ca.SX.sym("d", self.segment_size)
            law = ca.Function("law", [t, q, qd, d], [self.casadi_segment(t, q, qd, d)])
            object.__setattr__(self, "_law_function", law)
        return law

    # ---------------------------------------------------------------- variants
    def reference_state(self, t) -> np.ndarray:
        """z_ref(t) (nz,) of the Hermite interpolant."""
        k = self.interval(t)
        h = self.times[k + 1] - self.times[k]
        return hermite((float(t) - self.times[k]) / h, self.reference[k], self.reference[k + 1],
                       h * self.rates[k, 0], h * self.rates[k, 1])

    def with_controls(self, controls) -> GainSchedule:
        """The same schedule with other inputs u_k (N, m), e.g. perturbed by input noise."""
        return replace(self, controls=controls)

    def open_loop(self) -> GainSchedule:
        """The same reference inputs and saturation with every gain zero (the open loop; same
        compiled closed loop as the schedule itself)."""
        return replace(self, gains=np.zeros_like(self.gains))

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_law_function", None)
        return state
