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

import numpy as np

__all__ = ["FibreMotion", "fibre_motion"]


@dataclass(frozen=True)
class FibreMotion:
    """The fibre coordinates s (l×K) and nonholonomic momenta p (d×K) along the times t (K,)."""

    t: np.ndarray
    fiber: np.ndarray
    momentum: np.ndarray


def fibre_motion(model, t, q_path, *, params=None, p0=None) -> FibreMotion:
    """Integrate the fibre and momentum of ``model`` (a ReducedODE) along the configurations
    ``q_path`` (n×K at times ``t``; the fibre rows give only the start values) from ``p0``."""
    layout = model.layout
    numeric = model.numeric
    values = np.asarray(numeric.params(params), float)
    si, ri, d = list(layout.si), list(layout.free), layout.d
    n = len(model.system.coordinates)
    basis, state, rhs = numeric["basis"], numeric["state"], numeric["rhs"]
    u0 = np.zeros(len(model.system.inputs))
    nP = len(model.momenta)
    t = np.asarray(t, float)
    q_path = np.asarray(q_path, float)

    def derivative(tk, q, r_dot, p):
        X = np.asarray(basis(np.concatenate([q, np.zeros(nP)]), values))
        P_r = np.asarray(state(q, X[:, d:] @ r_dot, values)).ravel()[n + d:]
        z = np.concatenate([q, p, P_r])
        zdot = np.asarray(rhs(tk, z, u0, values)).ravel()
        return zdot[si], zdot[n:n + d]

    s = q_path[si, 0].copy()
    p = np.zeros(d) if p0 is None else np.asarray(p0, float)
    S, Pm = [s.copy()], [p.copy()]
    for k in range(t.size - 1):
        h = t[k + 1] - t[k]
        r_dot = (q_path[ri, k + 1] - q_path[ri, k]) / h
        q = q_path[:, k].copy()
        q[si] = s
        ds, dp = derivative(t[k], q, r_dot, p)
        qm = 0.5 * (q_path[:, k] + q_path[:, k + 1])
        qm[si] = s + 0.5 * h * ds
        ds, dp = derivative(t[k] + 0.5 * h, qm, r_dot, p + 0.5 * h * dp)
        s, p = s + h * ds, p + h * dp
        S.append(s.copy())
        Pm.append(p.copy())
    return FibreMotion(t, np.array(S).T, np.array(Pm).T)
