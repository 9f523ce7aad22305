"""The fibre motion a prescribed shape path gives: the reconstruction equation with its momentum.

For a reduced model (thesis §3.2, steps 5–20) and a shape path r(t), the state z = (q, P) with
P = (p, P_r) is known from (s, r, ṙ, p): the shape momenta P_r = K_r(q)ṙ (K = XᵀMX is block
diagonal, step 8), read from the model's map ``state(q, X_r ṙ)`` (the horizontal lift: Ω = 0).
Then

    ṡ = q̇_s(z)   (= g(−A(r)ṙ + Γ(r)p), step 20),     ṗ = Ṗ_p(z, u = 0)   (step 19)

integrated by the explicit midpoint rule from s(0) and p(0) (default 0: the robot at rest).
The inputs act on the shape only, so they drop out of the momentum rows (ṗ = ṙᵀσ_rr ṙ +
ṙᵀσ_rp p + pᵀσ_pp p, Table 2.1's mixed form); this is the exact motion of the fibre when the
shape follows r(t), for every Table 2.1 class (d = 0: ξ = −A(r)ṙ alone), the numeric
counterpart of Shammas's scaled-momentum reconstruction.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["FibreMotion", "FibreIntegrator", "fibre_motion"]


@dataclass(frozen=True)
class FibreMotion:
    """The fibre coordinates s (l×K) and nonholonomic momenta p (d×K) along the times t (K,)."""

    t: np.ndarray
    fiber: np.ndarray
    momentum: np.ndarray


def _step(model, values):
    """The midpoint step (s, p) → (s, p) over [t, t + h] with the shape from q_a to q_b, as a
    CasADi Function of ((s, p), (q_a, q_b, t, h)) (one graph: the integration is one
    ``mapaccum`` call)."""
    layout, numeric = model.layout, model.numeric
    si, ri, d = list(layout.si), list(layout.free), layout.d
    n, l, nP = len(model.system.coordinates), len(si), len(model.momenta)
    basis, state, rhs = numeric["basis"], numeric["state"], numeric["rhs"]
    u0 = ca.DM.zeros(len(model.system.inputs))
    x, w = ca.MX.sym("x", l + d), ca.MX.sym("w", 2 * n + 2)
    qa, qb, t, h = w[:n], w[n:2 * n], w[2 * n], w[2 * n + 1]
    r_dot = (qb[ri] - qa[ri]) / h

    def derivative(tk, q_shape, s, p):
        q = ca.vertcat(*[s[si.index(i)] if i in si else q_shape[i] for i in range(n)])
        X = basis(ca.vertcat(q, ca.DM.zeros(nP)), values)
        P_r = state(q, ca.mtimes(X[:, d:], r_dot), values)[n + d:]
        zdot = rhs(tk, ca.vertcat(q, p, P_r), u0, values)
        return zdot[si], zdot[n:n + d]

    s, p = x[:l], x[l:]
    ds, dp = derivative(t, qa, s, p)
    ds, dp = derivative(t + h / 2, (qa + qb) / 2, s + h / 2 * ds, p + h / 2 * dp)
    return ca.Function("midpoint_step", [x, w], [ca.vertcat(s + h * ds, p + h * dp)])


class FibreIntegrator:
    """:func:`fibre_motion` for one model and parameter values, its CasADi step built once
    (and its ``mapaccum`` once per number of intervals): call it with (t, q_path[, p0])."""

    def __init__(self, model, params=None):
        self._l, self._d, self._si = len(model.layout.si), model.layout.d, list(model.layout.si)
        self._step = _step(model, ca.DM(np.asarray(model.numeric.params(params), float)))
        self._accumulated: dict = {}

    def __call__(self, t, q_path, p0=None) -> FibreMotion:
        t = np.asarray(t, float)
        q_path = np.asarray(q_path, float)
        p = np.zeros(self._d) if p0 is None else np.asarray(p0, float)
        x0 = np.concatenate([q_path[self._si, 0], p])
        w = np.vstack([q_path[:, :-1], q_path[:, 1:], t[:-1], np.diff(t)])
        K = t.size - 1
        if K not in self._accumulated:
            self._accumulated[K] = self._step.mapaccum(K)
        X = np.hstack([x0[:, None], np.asarray(self._accumulated[K](x0, w))])
        return FibreMotion(t, X[:self._l], X[self._l:])


def fibre_motion(model, t, q_path, *, params=None, p0=None) -> FibreMotion:
    """Integrate the fibre and momentum of ``model`` (a ReducedODE) along the configurations
    ``q_path`` (n×K at times ``t``; the fibre rows give only the start values) from ``p0``
    (default 0), by the explicit midpoint rule on the intervals of ``t``."""
    return FibreIntegrator(model, params)(t, q_path, p0)
