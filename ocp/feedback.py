"""Feedback along a planned trajectory: a time-varying LQR on the plan's own stage Jacobians.

Linearisation. The stage function F of multiple shooting (:mod:`.stage`: one interval of
length h = T/N, M RK4 sub-steps of the problem's ODE) at the plan's nodes (z_k, u_k) gives the
deviations δz = z − z_k, δu = u − u_k their discrete dynamics::

    δz_{k+1} = A_k δz_k + B_k δu_k,      [A_k  B_k] = ∂F/∂(z, u) (z_k, u_k),   k = 0 … N−1.

Cost (the path time-averaged, so that the gains do not depend on N)::

    J = Σ_k (h/T) (δz_kᵀ Q δz_k + δu_kᵀ R δu_k) + δz_Nᵀ Q_N δz_N.

Riccati recursion (backward, P_N = Q_N)::

    S_k = (h/T) R + B_kᵀ P_{k+1} B_k,      K_k = S_k⁻¹ B_kᵀ P_{k+1} A_k,
    P_k = (h/T) Q + A_kᵀ P_{k+1} (A_k − B_k K_k),

and the law δu_k = −K_k δz_k, applied as u = u_k − K_k (z − z_ref(t)) on [t_k, t_{k+1})
(:class:`~nhgait.dynamics.simulation.gain_schedule.GainSchedule`).

Default weights (Bryson's rule, :func:`default_weights`): each state and input is divided by
the deviation one accepts of it::

    Q = diag 1/(0.1 s_i)²,   Q_N = diag 1/(0.02 s_i)² = 25 Q,   R = diag 1/ū_j²,

with s_i the *scale* of state i — the width of its bound in the task when both ends are
finite, else the range the plan spans (max − min over the nodes); a state the plan barely
moves (range below 1 % of the largest of its kind: configuration coordinates, velocity states)
takes the largest of its kind, so the lateral position of a forward gait is weighted like the
forward one — and ū_j the largest |u_j| the plan uses (no larger than its bound), else the
bound's half-width, else 1. In words: a path deviation of 10 % of a state's scale costs as much
as a correction of the size of the plan's own inputs, and at the end only 2 % is accepted (a
gait is planned to arrive). The end's weight was chosen on the snakeboard's forward gait with
m +10 % and J_r −10 % (docs/tracking.md: with Q_N = 3, 10, 25, 100, 300 Q the closed
loop's worst final error was 0.34, 0.12, 0.035, 0.07, 0.09 of the open loop's median; a larger
end weight makes the linear law overreact in the last intervals).

Everything is in the problem's own state (for the planner: the velocity coordinates
z = (q, y) of the specialised model) and nothing here imports sympy.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .problem import OptimalControlProblem, model_coordinates
from .stage import stage_functions
from .transcription import ode_function

__all__ = ["Weights", "Feedback", "default_weights", "design_feedback", "riccati", "stage_jacobians",
           "node_rates", "state_scales", "PATH_FRACTION", "FINAL_FRACTION"]

#: accepted path deviation, as a fraction of each state's scale (Bryson's rule)
PATH_FRACTION = 0.1
#: accepted deviation of the final state, as a fraction of each state's scale (Q_N = 25 Q)
FINAL_FRACTION = 0.02
#: a state whose range is below this fraction of the largest of its kind takes that largest
_FLAT = 0.01


@dataclass(frozen=True)
class Weights:
    """Diagonal LQR weights: ``state`` Q (nz,), ``control`` R (nu,), ``final`` Q_N (nz,), and the
    scales they came from (``state_scale`` s_i, ``control_scale`` ū_j) with the ``rule`` in words."""

    state: np.ndarray
    control: np.ndarray
    final: np.ndarray
    state_scale: np.ndarray
    control_scale: np.ndarray
    rule: str = ""

    def to_dict(self, state_names, control_names) -> dict:
        return {"rule": self.rule,
                "state": dict(zip(state_names, map(float, self.state), strict=True)),
                "final": dict(zip(state_names, map(float, self.final), strict=True)),
                "control": dict(zip(control_names, map(float, self.control), strict=True)),
                "state_scale": dict(zip(state_names, map(float, self.state_scale), strict=True)),
                "control_scale": dict(zip(control_names, map(float, self.control_scale), strict=True))}


def state_scales(problem: OptimalControlProblem, states: np.ndarray) -> np.ndarray:
    """s_i of each state (module docstring): bound width, else the plan's range, flat states
    raised to the largest of their kind (configuration coordinates, then velocity states)."""
    n = len(model_coordinates(problem.model))
    scale = np.ptp(states, axis=1).astype(float)
    for i, name in enumerate(problem.state_names):
        if name in problem.state_bounds:
            lo, hi = problem.bounds(problem.state_bounds, name)
            if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
                scale[i] = hi - lo
    for part in (slice(0, n), slice(n, None)):
        block = scale[part]
        if block.size:
            top = block.max() if block.max() > 0 else 1.0
            block[block < _FLAT * top] = top
    return scale


def _control_scales(problem: OptimalControlProblem, controls: np.ndarray) -> np.ndarray:
    lo, hi = problem.control_bound_vectors()
    half = np.where(np.isfinite(lo) & np.isfinite(hi), (hi - lo) / 2, np.inf)
    peak = np.abs(controls).max(axis=1) if controls.size else np.zeros(len(lo))
    scale = np.minimum(peak, half)
    scale = np.where(scale > 0, scale, np.where(np.isfinite(half) & (half > 0), half, 1.0))
    return scale


def default_weights(problem: OptimalControlProblem, states: np.ndarray, controls: np.ndarray, *,
                    path_fraction: float = PATH_FRACTION, final_fraction: float = FINAL_FRACTION) -> Weights:
    """Bryson's weights of the module docstring from the task's bounds and the plan
    (``states`` nz × (N+1), ``controls`` nu × N)."""
    s = state_scales(problem, states)
    ubar = _control_scales(problem, controls)
    rule = (f"Bryson: Q = 1/({path_fraction:g} s)², Q_N = 1/({final_fraction:g} s)², R = 1/ū²; s = "
            "bound width or "
            "the plan's range (flat states: the largest of their kind), ū = the plan's peak input "
            "(≤ its bound)")
    return Weights(1.0 / (path_fraction * s) ** 2, 1.0 / ubar ** 2, 1.0 / (final_fraction * s) ** 2,
                   s, ubar, rule)


def stage_jacobians(problem: OptimalControlProblem, states, controls, horizon: float,
                    steps: int = 4) -> tuple:
    """(A (N, nz, nz), B (N, nz, nu), gap (N,)): the stage Jacobians at the nodes and how far
    F(z_k, u_k) is from z_{k+1} (the plan's own defects, ~0 for a converged plan)."""
    N, nz = problem.intervals, problem.n_states
    st = stage_functions(ode_function(problem), N, steps=steps)
    phase = ca.DM([1.0 / N, 0.0])                                 # (ν, t0): one phase from t = 0
    F, J = st.jacobian.map(N)(states[:, :N], controls, float(horizon), ca.DM(np.arange(N)).T, phase)
    blocks = np.stack(np.hsplit(np.asarray(J), N))                # (N, nz, nz + nu)
    gap = np.abs(np.asarray(F) - states[:, 1:]).max(axis=0)
    return blocks[:, :, :nz], blocks[:, :, nz:], gap


def riccati(A, B, Q, R, Q_final, weight: float = 1.0) -> tuple:
    """(K (N, nu, nz), P_0): the backward recursion of the module docstring with the stage
    weights multiplied by ``weight`` (= h/T)."""
    N, nz, nu = B.shape
    P = np.diag(Q_final).astype(float)
    Qs, Rs = weight * np.diag(Q), weight * np.diag(R)
    K = np.zeros((N, nu, nz))
    for k in reversed(range(N)):
        a, b = A[k], B[k]
        K[k] = np.linalg.solve(Rs + b.T @ P @ b, b.T @ P @ a)
        P = Qs + a.T @ P @ (a - b @ K[k])
        P = (P + P.T) / 2
    return K, P


def node_rates(problem: OptimalControlProblem, t, states, controls) -> np.ndarray:
    """(N, 2, nz): ż at the start and at the end of each interval with that interval's input
    (the reference's rates for a Hermite interpolation, :class:`Feedback`)."""
    f = ode_function(problem)
    N = controls.shape[1]
    start = np.asarray(f.map(N)(t[:-1], states[:, :-1], controls)).T
    end = np.asarray(f.map(N)(t[1:], states[:, 1:], controls)).T
    return np.stack([start, end], axis=1)


@dataclass(kw_only=True, frozen=True, eq=False)
class Feedback:
    """The LQR of a plan, in the problem's state.

    Attributes
    ----------
    t : (N+1,) node times; states : (nz, N+1) reference z_k; controls : (nu, N) reference u_k;
    gains : (N, nu, nz) K_k; rates : (N, 2, nz) ż at both ends of each interval;
    state_names, control_names : orderings of z and u; weights : :class:`Weights`;
    lower, upper : (nu,) input bounds of the task (±inf: none); defect : largest
    |F(z_k, u_k) − z_{k+1}| of the plan (how far the linearisation's nodes are from a trajectory).
    """

    t: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    gains: np.ndarray
    rates: np.ndarray
    state_names: tuple
    control_names: tuple
    weights: Weights
    lower: np.ndarray
    upper: np.ndarray
    defect: float = 0.0

    @property
    def horizon(self) -> float:
        return float(self.t[-1] - self.t[0])

    def to_dict(self) -> dict:
        """JSON-ready: the gains as nested lists [k][input][state], the weights, the orderings."""
        finite = lambda a: [float(v) if np.isfinite(v) else None for v in a]  # noqa: E731
        return {"law": "u = sat(u_k - K_k (z(q, qdot) - z_ref(t))) on [t_k, t_k+1); z_ref cubic Hermite",
                "state_names": list(self.state_names), "control_names": list(self.control_names),
                "t": self.t.tolist(), "reference": self.states.tolist(), "controls": self.controls.tolist(),
                "gains": self.gains.tolist(), "rates": self.rates.tolist(),
                "weights": self.weights.to_dict(self.state_names, self.control_names),
                "lower": finite(self.lower), "upper": finite(self.upper), "defect": float(self.defect)}

    @classmethod
    def from_dict(cls, data: dict) -> Feedback:
        """The feedback written by :meth:`to_dict` (``solution.json["feedback"]``)."""
        names, cnames = tuple(data["state_names"]), tuple(data["control_names"])
        w = data["weights"]
        vec = lambda d, keys: np.array([float(d[k]) for k in keys])  # noqa: E731
        weights = Weights(vec(w["state"], names), vec(w["control"], cnames), vec(w["final"], names),
                          vec(w["state_scale"], names), vec(w["control_scale"], cnames), w.get("rule", ""))
        bound = lambda v, inf: np.array([inf if b is None else float(b) for b in v])  # noqa: E731
        return cls(t=np.asarray(data["t"], float), states=np.asarray(data["reference"], float),
                   controls=np.asarray(data["controls"], float), gains=np.asarray(data["gains"], float),
                   rates=np.asarray(data["rates"], float), state_names=names, control_names=cnames,
                   weights=weights, lower=bound(data["lower"], -np.inf), upper=bound(data["upper"], np.inf),
                   defect=float(data.get("defect", 0.0)))


def design_feedback(problem: OptimalControlProblem, t, states, controls, *, weights: Weights | None = None,
                    steps: int = 4) -> Feedback:
    """The time-varying LQR (module docstring) of the plan (``t`` (N+1,), ``states`` nz × (N+1),
    ``controls`` nu × N, in the problem's state) with ``weights`` (default: :func:`default_weights`)."""
    t, states, controls = (np.asarray(a, dtype=float) for a in (t, states, controls))
    weights = weights or default_weights(problem, states, controls)
    horizon = float(t[-1] - t[0])
    A, B, gap = stage_jacobians(problem, states, controls, horizon, steps)
    K, _ = riccati(A, B, weights.state, weights.control, weights.final, weight=1.0 / problem.intervals)
    lo, hi = problem.control_bound_vectors()
    return Feedback(t=t, states=states, controls=controls, gains=K,
                    rates=node_rates(problem, t, states, controls), state_names=tuple(problem.state_names),
                    control_names=tuple(problem.control_names), weights=weights, lower=lo, upper=hi,
                    defect=float(gap.max(initial=0.0)))
