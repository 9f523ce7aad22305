"""An independent transcription for planning tests: the Lagrange DAE with multipliers.

Nothing here comes from nhgait: the caller writes L(q, q̇), the constraint rows ω(q) q̇ and the
generalized forces τ(q, u) directly as CasADi expressions. The state is z = (q, q̇) (2n); the
multipliers are eliminated by the index-1 form (thesis eq. 2.8 differentiated once)

    [M  ωᵀ] [q̈]   [τ + ∂L/∂q − (∂²L/∂q̇∂q) q̇]
    [ω  0 ] [λ] = [−ω̇ q̇                    ],     M = ∂²L/∂q̇²,

which is regular wherever ω has full rank — it has no chart and no velocity coordinates, so
none of the planner's singular sets. ω q̇ = 0 is an invariant of this ODE; it is imposed by the
initial state (at rest) and kept by continuity. Direct multiple shooting: N intervals on the
fixed horizon T, piecewise-constant u, 4 RK4 steps per interval (as nhgait's transcription),
objective Σ_k (T/N) |u_k|², Ipopt with the exact Hessian.
"""
from __future__ import annotations

import casadi as ca
import numpy as np


def index1_ode(L, constraints, forces, q, qd, u) -> ca.Function:
    """f(z, u) = (q̇, q̈) of the index-1 DAE above (z = (q, q̇))."""
    n, k = q.shape[0], constraints.shape[0]
    W = ca.jacobian(constraints, qd)
    M = ca.hessian(L, qd)[0]
    p = ca.gradient(L, qd)
    rhs = forces + ca.gradient(L, q) - ca.jtimes(p, q, qd)
    KKT = ca.blockcat([[M, W.T], [W, ca.SX.zeros(k, k)]])
    acc = ca.solve(KKT, ca.vertcat(rhs, -ca.jtimes(ca.mtimes(W, qd), q, qd)))[:n]
    return ca.Function("f", [ca.vertcat(q, qd), u], [ca.vertcat(qd, acc)])


def solve(f, *, n_u, T, N, fixed0, fixedT, periodic=(), bounds=None, u_bound, guess, max_iter=300) -> dict:
    """Minimise Σ (T/N)|u_k|² subject to the shooting gaps of ``f``.

    ``fixed0`` / ``fixedT``: {state index: value} at t = 0 / T; ``periodic``: state indices with
    z(T) = z(0); ``bounds``: {state index: (lo, hi)} at every node; ``u_bound``: (lo, hi) arrays
    or a number b for |u| ≤ b; ``guess``: (Z (2n × N+1), U (n_u × N)). Returns the objective,
    Ipopt's status and iterations, Z and U."""
    nz = f.size1_in(0)
    h = T / N / 4
    z, u = ca.SX.sym("z", nz), ca.SX.sym("u", n_u)
    zz = z
    for _ in range(4):
        k1 = f(zz, u)
        k2 = f(zz + h / 2 * k1, u)
        k3 = f(zz + h / 2 * k2, u)
        k4 = f(zz + h * k3, u)
        zz = zz + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    step = ca.Function("step", [z, u], [zz]).map(N)
    Z, U = ca.MX.sym("Z", nz, N + 1), ca.MX.sym("U", n_u, N)
    g = [ca.vec(step(Z[:, :-1], U) - Z[:, 1:])] + [Z[i, -1] - Z[i, 0] for i in periodic]
    lbz, ubz = np.full((nz, N + 1), -np.inf), np.full((nz, N + 1), np.inf)
    for i, (lo, hi) in (bounds or {}).items():
        lbz[i], ubz[i] = lo, hi
    for col, fixed in ((0, fixed0), (-1, fixedT)):
        for i, v in fixed.items():
            lbz[i, col] = ubz[i, col] = v
    lo, hi = (-u_bound, u_bound) if np.isscalar(u_bound) else u_bound
    lbu, ubu = (np.broadcast_to(np.reshape(lo, (-1, 1)), (n_u, N)),
                np.broadcast_to(np.reshape(hi, (-1, 1)), (n_u, N)))
    w = ca.vertcat(ca.vec(Z), ca.vec(U))
    nlp = {"x": w, "f": T / N * ca.sumsqr(U), "g": ca.vertcat(*g)}
    solver = ca.nlpsol("reference", "ipopt", nlp, {"ipopt.print_level": 0, "print_time": 0,
                                                   "ipopt.max_iter": max_iter, "ipopt.tol": 1e-10})
    Z0, U0 = guess
    r = solver(x0=np.concatenate([np.ravel(Z0, order="F"), np.ravel(U0, order="F")]),
               lbx=np.concatenate([lbz.ravel(order="F"), np.ravel(lbu, order="F")]),
               ubx=np.concatenate([ubz.ravel(order="F"), np.ravel(ubu, order="F")]), lbg=0, ubg=0)
    stats = solver.stats()
    x = np.asarray(r["x"]).ravel()
    return {"objective": float(r["f"]), "status": stats["return_status"], "iterations": stats["iter_count"],
            "Z": x[:nz * (N + 1)].reshape(nz, N + 1, order="F"),
            "U": x[nz * (N + 1):].reshape(n_u, N, order="F")}


def car_ode() -> ca.Function:
    """examples/car.toml written again by hand: m = 1, I_z = 0.1, I_s = 0.01, l = 0.5; q = (x, y,
    θ, φ), inputs (F, τ_φ): the driving force along the heading and the steering torque."""
    q, qd, u = ca.SX.sym("q", 4), ca.SX.sym("qd", 4), ca.SX.sym("u", 2)
    th, ph = q[2], q[3]
    L = (qd[0] ** 2 + qd[1] ** 2) / 2 + 0.1 * qd[2] ** 2 / 2 + 0.01 * qd[3] ** 2 / 2
    rows = ca.vertcat(-ca.sin(th) * qd[0] + ca.cos(th) * qd[1],
                      -ca.sin(th + ph) * qd[0] + ca.cos(th + ph) * qd[1] + 0.5 * ca.cos(ph) * qd[2])
    forces = ca.vertcat(u[0] * ca.cos(th), u[0] * ca.sin(th), 0, u[1])
    return index1_ode(L, rows, forces, q, qd, u)
