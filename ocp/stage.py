"""The stage function of multiple shooting and its exact derivatives, built once per problem.

One shooting interval k of a phase with N intervals on [t0, t0 + T] (a problem without
phases: one phase, t0 = 0): the model's ODE ż = f(t, z, u) is integrated in *scaled time*
s ∈ [0, 1] per interval,

    dz/ds = g(z, u, T, τ, ν, t0) = h f(t0 + τ h, z, u),      h = ν T,  ν = 1 / N,  τ = k + s,

by RK4 with M equal sub-steps (Butcher tableau a, b, c; ds = 1/M)::

    y_ij = z_i + ds Σ_l a_jl κ_il,   κ_ij = g(y_ij, u, T, k + (i + c_j)/M),
    z_{i+1} = z_i + ds Σ_j b_j κ_ij,   i = 0 … M−1,   F = z_M.

The scaling makes every relation but the g-evaluations linear with constant coefficients, so
with the stage variables x = (z, u) — and T when the horizon is free — the exact derivatives
are (forward sensitivities and second-order adjoints, as in acados' explicit integrators):

    J = ∂F/∂x = Σ_ij ds b_j ∂κ_ij/∂x + ∂z_0/∂x,   ∂κ_ij/∂x = G_ij L_ij,
    L_ij = ∂(y_ij, u, T)/∂x,  G_ij = ∂g/∂(y, u, T) at point ij,
    ∇²_x (λᵀF) = Σ_ij L_ijᵀ ∇²_(y,u,T)(ν_ijᵀ g)(point ij) L_ij,

with ν_ij = ∂(λᵀF)/∂κ_ij the adjoint of each evaluation (one backward sweep through the
tableau with the stored G_ij). Only g, its Jacobian and its weighted Hessian are nonlinear.

Two realisations of the same three functions ``step``, ``jacobian``, ``hessian``:

* ``"inline"``: the M sub-steps written out in one SX expression and differentiated by
  CasADi (the fastest evaluation for small ODEs; its code grows like 4M · nx · ops(f));
* ``"structured"``: MX glue that calls three small SX functions — ``g``, ``g_jac`` (value and
  Jacobian) and ``g_hess`` (weighted Hessian) — at every RK point. The generated code is
  those three functions plus O(M) calls: independent of N and of M, about
  (1 + 6 + 19) · ops(f) for the velocity-coordinate models measured in
  ``experiments/bench_ocp.py``.

:func:`stage_functions` chooses by an estimate of the inline code (``mode="auto"``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np

__all__ = ["StageFunctions", "stage_functions", "stage_mode", "phase_size", "INLINE_LIMIT", "RK4"]

#: RK4 tableau (a lower triangular, b weights, c nodes)
RK4 = (((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)), (1 / 6, 1 / 3, 1 / 3, 1 / 6), (0.0, 0.5, 0.5, 1.0))
#: the inline realisation is used while 4 M · nx · ops(f) stays below this. Measured (warm
#: Ipopt solves, same guess, both compiled): the thesis snakeboard (8 states, 54 operations:
#: 6 912) is fastest inline; the two-steering snakeboard (27 840) took 435 ms inline (5.1 MB
#: of C, compiled at -O0 by the budget) against 250 ms structured (0.9 MB), the 3-link
#: snake (39 760) 539 ms against 149 ms (7.5 against 0.7 MB); the cart with one trailer
#: (18 432; issue 25) 0.96–1.02× the hand-written reference inline with Ipopt (1.9 MB of C)
#: and 0.68–0.70× with FATROP, against 1.45–1.64× structured with Ipopt; with two trailers
#: (40 960) the inline C needs 1.5 GB of gcc -O1.
INLINE_LIMIT = 20_000


@dataclass(kw_only=True, frozen=True, eq=False)
class StageFunctions:
    """F, ∂F/∂x and ∇²_x(λᵀF) of one shooting interval (see the module docstring).

    Every function takes ``(z, u, T, k, phase)``: node state (nz), control (nu), the phase's
    horizon (scalar; a constant for a fixed horizon), the interval's index k in its phase and
    ``phase`` = (ν, t0) = (1 / N of the phase, its start time) (constants; followed by θ for an
    ODE with a parameter argument, :func:`phase_size`); ``hessian`` also
    ``lam`` (nz). ``jacobian`` returns (F, J) with J of shape nz × nx; ``hessian`` returns
    the dense symmetric nx × nx matrix. x = (z, u) or (z, u, T) when ``free_horizon``.
    """

    step: ca.Function
    jacobian: ca.Function
    hessian: ca.Function
    mode: str
    n_states: int
    n_controls: int
    free_horizon: bool
    steps: int
    ode_operations: int
    code_operations: int

    @property
    def n_variables(self) -> int:
        return self.n_states + self.n_controls + (1 if self.free_horizon else 0)

    @property
    def n_outputs(self) -> int:
        return self.n_states

    @property
    def value(self) -> ca.Function:
        """F (the name every mapped term of :mod:`.transcription` gives its value function)."""
        return self.step

    def describe(self) -> dict:
        """Sizes for reports: operations of f and of the SX code the stage functions hold."""
        return {"stage": self.mode, "rk4_steps": self.steps, "ode_operations": self.ode_operations,
                "stage_code_operations": self.code_operations}


def stage_mode(ode: ca.Function, *, steps: int = 4, free_horizon: bool = False) -> str:
    """"inline" while 4 M · nx · ops(f) ≤ :data:`INLINE_LIMIT`, else "structured"."""
    nx = int(ode.size1_in(1)) + int(ode.size1_in(2)) + (1 if free_horizon else 0)
    return "inline" if 4 * steps * nx * int(ode.n_instructions()) <= INLINE_LIMIT else "structured"


def stage_functions(ode: ca.Function, intervals: int | None = None, *, steps: int = 4,
                    free_horizon: bool = False, mode: str = "auto") -> StageFunctions:
    """The stage functions of ``ode`` (an SX Function ``(t, z, u) -> ż`` with the parameter
    values bound, or ``(t, z, u, θ) -> ż`` whose θ then follows (ν, t0) in ``phase``),
    ``steps`` = M RK4 sub-steps per interval; the number of intervals enters as the argument
    ν = 1/N (``intervals`` is not needed: the same functions serve every N).

    ``mode``: "inline", "structured" or "auto" (inline while 4 M · nx · ops(f) ≤
    :data:`INLINE_LIMIT`).
    """
    nz, nu = int(ode.size1_in(1)), int(ode.size1_in(2))
    ops = int(ode.n_instructions())
    if mode == "auto":
        mode = stage_mode(ode, steps=steps, free_horizon=free_horizon)
    g = _scaled_ode(ode)
    build = {"inline": _inline, "structured": _structured}[mode]
    step, jac, hess, code = build(g, nz, nu, steps, free_horizon)
    return StageFunctions(step=step, jacobian=jac, hessian=hess, mode=mode, n_states=nz, n_controls=nu,
                          free_horizon=free_horizon, steps=steps, ode_operations=ops, code_operations=code)


def phase_size(ode: ca.Function) -> int:
    """The entries of the stage's constant argument ``phase``: (ν, t0), followed by the
    parameter vector θ of an ODE ``(t, z, u, θ) -> ż`` that takes one (:mod:`.scenarios`)."""
    return 2 + (int(ode.size1_in(3)) if ode.n_in() > 3 else 0)


def _scaled_ode(ode: ca.Function) -> ca.Function:
    """g(z, u, T, τ, phase) = h f(t0 + τ h, z, u[, θ]), h = ν T, phase = (ν, t0[, θ]) (module
    docstring): an ODE with a parameter argument θ gets it from the constant ``phase``."""
    nz, nu = int(ode.size1_in(1)), int(ode.size1_in(2))
    z, u, T, tau = ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("T"), ca.SX.sym("tau")
    phase = ca.SX.sym("phase", phase_size(ode))
    h = phase[0] * T
    args = [phase[1] + tau * h, z, u] + ([phase[2:]] if ode.n_in() > 3 else [])
    return ca.Function("g", [z, u, T, tau, phase], [h * ode(*args)],
                       ["z", "u", "T", "tau", "phase"], ["dzds"])


def _symbols(sym, nz, nu, n_phase=2):
    return (sym.sym("z", nz), sym.sym("u", nu), sym.sym("T"), sym.sym("k"), sym.sym("lam", nz),
            sym.sym("phase", n_phase))


def _inline(g, nz, nu, steps, free):
    """One SX expression of the M sub-steps, differentiated by CasADi."""
    z, u, T, k, lam, phase = _symbols(ca.SX, nz, nu, int(g.size1_in(4)))
    zi = _value(g, z, _Held(u, T, k, phase), steps)
    x = ca.vertcat(z, u, T) if free else ca.vertcat(z, u)
    ins, names = [z, u, T, k, phase], ["z", "u", "T", "k", "phase"]
    step = ca.Function("stage", ins, [zi], names, ["z_end"])
    jac = ca.Function("stage_jac", ins, [zi, ca.jacobian(zi, x)], names, ["z_end", "J"])
    hess = ca.Function("stage_hess", ins + [lam], [ca.hessian(ca.dot(lam, zi), x)[0]], names + ["lam"], ["H"])
    return step, jac, hess, sum(int(f.n_instructions()) for f in (step, jac, hess))


def _structured(g, nz, nu, steps, free):
    """MX glue over g, g_jac, g_hess (module docstring): code independent of N and M."""
    zs, us, Ts, taus, nus = (ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("T"), ca.SX.sym("tau"),
                             ca.SX.sym("nu", nz))
    phs = ca.SX.sym("phase", int(g.size1_in(4)))
    val = g(zs, us, Ts, taus, phs)
    local = ca.vertcat(zs, us, Ts) if free else ca.vertcat(zs, us)
    g_jac = ca.Function("g_jac", [zs, us, Ts, taus, phs], [val, ca.jacobian(val, local)])
    g_hess = ca.Function("g_hess", [zs, us, Ts, taus, phs, nus], [ca.hessian(ca.dot(nus, val), local)[0]])
    z, u, T, k, lam, phase = _symbols(ca.MX, nz, nu, int(g.size1_in(4)))
    nx = nz + nu + (1 if free else 0)
    # ∂(u[, T])/∂x: constant rows below the sensitivity of y
    E = ca.DM(np.hstack([np.zeros((nx - nz, nz)), np.eye(nx - nz)]))
    a, b, _ = RK4
    ds = 1.0 / steps
    zi, Zi = z, ca.DM(np.hstack([np.eye(nz), np.zeros((nz, nx - nz))]))
    record = []                       # per sub-step: (points (y, L), G of each point)
    for i in range(steps):
        kap, K, pts, Gs = [], [], [], []
        for j in range(4):
            y = zi + ds * sum((a[j][l] * kap[l] for l in range(j)), ca.MX.zeros(nz))
            Y = Zi + ds * sum((a[j][l] * K[l] for l in range(j)), ca.MX.zeros(nz, nx))
            L = ca.vertcat(Y, E)
            kj, G = g_jac(y, u, T, k + (i + RK4[2][j]) / steps, phase)
            kap.append(kj)
            K.append(ca.mtimes(G, L))
            pts.append((y, L))
            Gs.append(G)
        zi = zi + ds * sum(b[j] * kap[j] for j in range(4))
        Zi = Zi + ds * sum(b[j] * K[j] for j in range(4))
        record.append((pts, Gs))
    ins, names = [z, u, T, k, phase], ["z", "u", "T", "k", "phase"]
    held = _Held(u, T, k, phase)
    step = ca.Function("stage", ins, [_value(g, z, held, steps)], names, ["z_end"])
    jac = ca.Function("stage_jac", ins, [zi, Zi], names, ["z_end", "J"])
    H = _second_order_adjoint(record, g_hess, lam, held)
    hess = ca.Function("stage_hess", ins + [lam], [H], names + ["lam"], ["H"])
    return step, jac, hess, sum(int(f.n_instructions()) for f in (g, g_jac, g_hess))


class _Held(NamedTuple):
    """The stage's arguments held over its sub-steps: u, T, the interval's k and phase row."""

    u: object
    T: object
    k: object
    phase: object


def _value(g, z, held: _Held, steps):
    """F = z_M: the M RK4 sub-steps from calls of g alone (SX symbols: the inline stage; MX: the
    structured stage's value function — through g_jac it cost 6 ops(f) per RK point instead of 1,
    and its reverse derivative was a second-order function as large as g_hess)."""
    a, b, c = RK4
    ds = 1.0 / steps
    zi = z
    for i in range(steps):
        kap = []
        for j in range(4):
            y = zi + ds * sum((a[j][l] * kap[l] for l in range(j)), type(z).zeros(z.shape[0]))
            kap.append(g(y, held.u, held.T, held.k + (i + c[j]) / steps, held.phase))
        zi = zi + ds * sum(b[j] * kap[j] for j in range(4))
    return zi


def _second_order_adjoint(record, g_hess, lam, held: _Held):
    """Σ L_ijᵀ ∇²(ν_ijᵀ g) L_ij with the adjoints ν_ij of a backward sweep (module docstring);
    ``record`` holds one entry per sub-step, each point's L is nx × nx, λ has the nz entries of z."""
    a, b, _ = RK4
    steps, nz, nx = len(record), int(lam.shape[0]), int(record[0][0][0][1].shape[1])
    ds = 1.0 / steps
    lz = lam                                        # adjoint of z_{i+1}
    H = ca.MX.zeros(nx, nx)
    for i in reversed(range(steps)):
        pts, Gs = record[i]
        nus, ybar = [None] * 4, [None] * 4
        for j in reversed(range(4)):
            v = ds * b[j] * lz
            for jj in range(j + 1, 4):
                if a[jj][j]:
                    v = v + ds * a[jj][j] * ybar[jj]
            nus[j] = v
            ybar[j] = ca.mtimes(Gs[j][:, :nz].T, v)  # adjoint of y_ij
        lz = lz + sum(ybar)
        for j in range(4):
            y, L = pts[j]
            Hj = g_hess(y, held.u, held.T, held.k + (i + RK4[2][j]) / steps, held.phase, nus[j])
            H = H + ca.mtimes([L.T, Hj, L])
    return H
