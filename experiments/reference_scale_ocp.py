#!/usr/bin/env python3
"""Hand-written reference NLP for the scaling benchmark of issue 19 (robots of 5–10 coordinates).

An independent check of nhgait's optimum and a fair speed baseline for the tasks of
``experiments/scale_tasks.py`` (snake_3 … snake_8, cart_trailers_1 … _6,
snakeboard_two_steering). Nothing here comes from ``nhgait``: the model is built from the
physical descriptions of ``tests/oracles.py`` (frames, bodies, loads and contact-point
constraints for ``sympy.physics.mechanics``), the tasks are read from ``scale_tasks``.

Model: a reduced ODE in z = (q, u_ind), 2n − k states
--------------------------------------------------------
Generalized speeds (chosen here, not the oracle's u = q̇): the body-frame velocity of the planar
frame point, v = ẋ cos θ + ẏ sin θ and w = −ẋ sin θ + ẏ cos θ, then u_c = ċ for every other
coordinate c (θ, the shape and wheel angles). ``KanesMethod`` of the *unconstrained* system in
these speeds gives M(q) u̇ = F(q, u, τ) (n × n); the constraints of the description, rewritten
in u, give A(q) u = 0 (k × n). All loads are internal or about the vertical, so M, F and A are
invariant under planar motions: x, y, θ are set to 0 in them (the check at random θ below
confirms it), and the parameter values of ``scaling_systems`` are substituted (floats).

* independent speeds u_ind (state), dependent u_dep = B u_ind with B = −A_dep⁻¹ A_ind:
    - snake_<N>:   u_ind = (α̇₁, α̇₂); u_dep = (v, w, θ̇, α̇₃ …). A_dep is block lower
      triangular (links 1–3 fix (v, w, θ̇), link j ≥ 4 fixes α̇_{j−1}); singular only where
      the first three axles meet in a point (α₁ = α₂), outside the task's zig-zag band.
    - cart_trailers_<k>: u_ind = (θ̇, φ̇); u_dep = (v, w, β̇₁ …): w = 0, v = ρφ̇, each trailer's
      axle fixes β̇ᵢ (coefficient −l_t, never singular).
    - snakeboard_two_steering: u_ind = (v, ψ̇, φ̇_f, φ̇_b); u_dep = (w, θ̇), determinant
      2r cos φ_f cos φ_b (regular for |φ| < π/2; the oracle's (θ̇, …) choice with (ẋ, ẏ)
      dependent is singular at φ_f = φ_b, which the forward gait crosses).
* Kane's equations with the nonholonomic partial velocities S = ∂u/∂u_ind (S = [I; B] in
  [ind; dep] order): u̇_dep = B u̇_ind + d with A_dep d = −Ȧu (Ȧu = Σ_j ∂(A u)/∂q_j q̇_j,
  sympy), and
      (Sᵀ M S) u̇_ind = Sᵀ (F − M_{:,dep} d).
* q̇ = (v cos θ − w sin θ, v sin θ + w cos θ, θ̇, shape rates …).

The linear systems (A_dep, k × k; Sᵀ M S, (n − k) × (n − k)) are solved either **symbolically**
(default, ``--linear symbolic``: sympy ``LUsolve`` without simplification, then ``sympy.cse``)
or **at evaluation time** (``--linear numeric``: ``casadi.solve`` in the SX graph, block-
triangular permutation + QR). The sympy expressions reach CasADi SX through ``sympy.cse`` and a
small printer (``_SXPrinter``). Measured (SX operations of ż; jit solve, median of 7, the two
variants interleaved): snake_5 794 vs 1379 ops, 696 vs 1325 ms; snakeboard 180 vs 280 ops,
79 vs 108 ms; cart_trailers_3 331 vs 314 ops, 61 vs 59 ms — symbolic is the default. Growth
of ż (symbolic / numeric ops): snake_3 … 8: 250/255, 485/836, 794/1379, 1173/2115, 1625/3066,
2159/4258; cart_trailers_6: 1152/1040. Trigonometric tidying of M, F, A (sin/cos products to
sums) did not reduce the SX count (snake_6: 1384 instead of 1173), nor did assembling Kane's
equations body by body without the n × n mass matrix (snake_8: 1933 + q̇ instead of 2159): the
cost is in B, d (≈ 1000 ops for snake_8) and the bodies' accelerations, all O(N²).

``--check`` / ``--check-only`` compare q̈ of this ODE (q̈ = ∂q̇/∂z · ż) at 50 random consistent
states (configurations inside the task's bounds, random heading) with the oracle's ``qddot``
(KanesMethod with dependent speeds u = q̇, numpy; its build takes 40 s for the 8-link snake)
*and* with a second formulation built here, the
unconstrained KanesMethod in the speeds u = q̇ with Lagrange multipliers (M_q q̈ = F_q + A_qᵀλ,
A_q q̈ = −Ȧ_q q̇, ``multiplier_dae``): max |Δq̈| / max(1, max |q̈|) must be below 1e-9.

Transcription and solver
------------------------
Direct multiple shooting, N intervals on the fixed horizon T, piecewise-constant τ, one function
per interval doing 4 RK4 sub-steps (h = T/(4N)) applied by ``Function.map(N, "serial")`` in an
MX graph; w = (z₀, τ₀, z₁, τ₁, …, z_N) interval-stacked (banded KKT for MUMPS); objective
Σ_k (T/N)|τ_k|² (the exact ∫|τ|² dt); boundary values and node bounds are bounds on w, gaps and
periodicity rows of g. Ipopt, exact Hessian, MUMPS, default options (``mu_strategy`` monotone;
``--mu-strategy adaptive`` took 4–2 fewer iterations and 7–12 % less time on snake_5, cart_3 and
the board, with objectives 1e-6 less accurate). Compiled (``jit=True``): CasADi's ``shell``
compiler, gcc -O1, every NLP function Ipopt uses, in a scratch directory removed after loading
(``c_bytes`` = size of the generated C). The interval function is an MX graph of 16 calls of the
SX ODE function (``--stage MX``), so the C holds the ODE kernel and its derivatives once,
independent of N. Measured alternatives: the ODE inlined in one SX interval function
(``--stage SX``) — snake_3: 6.3 MB of C, 149 s of gcc, 22 % less time per iteration; calls of
an SX RK4 step (``--stage step``) — snakeboard: 2.5 MB, 43 s, no faster. Interpreted
(``jit=False``): ``expand=True`` (SX virtual machine), or ``expand=False`` for a quick build.

Each optimum is re-simulated with scipy DOP853 (rtol 1e-10, atol 1e-12) on the multiplier DAE
in (q, q̇) above — a different model than the one optimised — restarted at every control switch
from the state it reached, and reported as the largest node error in z (``resim_error``) and the
largest violation of every condition of the task *as written* (``condition_error``: every
q̇ = 0 at rest, every αⱼ_dot periodic, the node bounds, …).

Tasks, translated without redundancy into z (values from ``scale_tasks``)
-------------------------------------------------------------------------
* conditions on coordinates are bounds on z at node 0 / N, path bounds are bounds at every
  node (intersected with the end values); periodic coordinates are rows z_N − z_0 = 0;
* a rate ``<c>_dot`` that is itself an independent speed (α̇₁, α̇₂ of the snake, θ̇, φ̇ of the
  cart, ψ̇, φ̇_f, φ̇_b of the board; ``forward_velocity`` = v of the board) is a bound or
  periodicity row on that state;
* the other rates are linear in u_ind, q̇_D = R_D(q) u_ind. Zero rates at one end:
  "R_D u_ind = 0" is the same set as "u_J = 0" when the columns of R_D outside J vanish and
  those in J have full column rank (checked numerically at 40 random configurations in the
  task's bounds, ``_zero_rate_subspace``). Cart at rest: every q̇ = 0 ⇔ (θ̇, φ̇) = 0 (q̇ = R
  u_ind with R of full column rank). Board fibre at rest: ẋ = ẏ = θ̇ = 0 ⇔ v = 0 (w and θ̇ are
  v times functions of φ_f, φ_b, with 2r cos φ_f cos φ_b ≠ 0; ψ̇, φ̇_f, φ̇_b do not move the
  axles);
* periodic rates that are not states: the snake's α̇ⱼ, j ≥ 3, are R_j(α) u_ind with R_j
  depending only on periodic coordinates and only on periodic u_ind (checked numerically,
  ``_periodic_implied``), so α̇ⱼ(T) = α̇ⱼ(0) follows from the other rows and is dropped;
* a periodic coordinate fixed at t = 0 (the board's ψ(0) = 0) is fixed at t = T instead of a
  row;
* ``control_bounds`` b: |τ_j| ≤ b on every interval; ``objective = "effort"``: Σ h|τ_k|².
Every dropped condition is checked on the re-simulated optimum (``condition_error``).

Guesses (torques 0; ω = 2π/T; chosen by a scan of 48 phase/offset/trailing-joint variants per
snake, all of which reach the same optimum — this one needed the fewest iterations for N = 3 … 6):
snake — head loop αⱼ = cⱼ + Aⱼ sin(ωt + 5π/4 + (j − 1)π/2), j = 1, 2, with cⱼ the centre and Aⱼ
0.8 of the half-width of the band, α̇ⱼ its derivative, trailing joints held at ±0.5
(alternating), x ramped to its target; cart — a kinematic rollout (RK4 of q̇ = R(q) u_ind) of a
lane change: forward speed a smooth bump, θ = a(1 − cos ωt)/2, (a, distance) fitted by Newton
so that x(T), y(T) hit the target, the trailers following through the constraints; board —
ψ = sin ωt, φ_f = −φ_b = 0.6 cos ωt with their rates, x ramped (the thesis snakeboard's P2 guess).

Measured (2026-11-23, 2-core machine shared with other jobs, CasADi 3.8.2, jit, median of 5
solves; ``out/reference_scale.json``; every member in its own process)
---------------------------------------------------------------------------------------------
member             n  k  nx  set-up s  C MB  solve ms  it  objective  re-sim err  peak RSS MB
snake_3            5  3   7     6.3    1.07     88.5   17  0.055029   3.9e-07     150
snake_4            6  4   8    12.9    1.83    402     25  0.044487   2.5e-07     155
snake_5            7  5   9    27.9    3.00    819     28  0.044801   2.8e-07     162
snake_6            8  6  10    56.8    4.87   1730     26  0.044114   2.7e-07     170
snake_7            9  7  11    69.7    7.19   2895     37  0.041730   5.2e-07     182
snake_8           10  8  12    81.5   10.22   6033     45  0.044300   8.6e-07     197
cart_trailers_1    5  3   7     6.7    0.69     20.9    6  0.061393   1.9e-09     149
cart_trailers_2    6  4   8     8.1    0.99     27.8    6  0.154731   1.5e-08     151
cart_trailers_3    7  5   9    13.5    1.44     62.9    6  0.325216   9.3e-08     154
cart_trailers_4    8  6  10    22.6    2.11     93.2    6  0.606452   3.4e-07     158
cart_trailers_5    9  7  11    26.6    2.98    156      7  1.038362   9.4e-07     164
cart_trailers_6   10  8  12    47.7    4.13    350      8  1.667326   2.2e-06     171
snakeboard_two_s.  6  2  10     9.1    1.56     97.5    9  0.023653   1.8e-09     153
Set-up = derivation (0.4–12 s) + compile (gcc -O1, 4.5–69 s). All 13 solves succeeded; the
re-simulated optima meet every condition of the task as written to ≤ 8.6e-7 (the cart's final
rates, the snake's periodic joints). Load-sensitive: an earlier run of the same code on a more
loaded machine gave snake_6 1241 ms, snake_8 4594 ms, cart_trailers_6 270 ms (function
evaluations are 80–98 % of the solve time; ms per iteration grow with ż's operations × (nx + nu)).
For comparison with the issue's reference (its task numbers): snake_3 with the brief's band
α ∈ [0.2, 1.0] takes 25 iterations, 135 ms, J = 0.108917 (issue: 16 it, 249 ms, 13 s set-up,
1.5 MB); the board, the same task, 9 it, 97 ms, 9 s, 1.6 MB (issue: 17 it, 254 ms, 14 s, 1.8 MB).
``--check-only``: the reduced ODEs agree with the oracle to ≤ 1.0e-13 and with the multiplier
DAE to ≤ 7.3e-13 (50 random states per member). ``nhgait plan`` on the scenes of
``scale_tasks.scene_with_task`` (FATROP, its own guesses) reached the reference's optima of
snake_3, cart_trailers_1 and the board to 1.3e-9, 2e-13 and 1.6e-7 relative.

API (called in-process by the issue-19 benchmark):
    ref = build("snake_3", N=None, jit=True); res = ref.solve()
    ref.setup_s, ref.compile_s, ref.c_bytes, ref.n_states
    res["objective"], res["iterations"], res["status"], res["success"], res["solve_s"],
    res["t_wall"], res["t"], res["q"], res["u"], res["coordinates"], res["inputs"]

Usage: python experiments/reference_scale_ocp.py [--members snake_3,snake_4] [--no-jit]
           [--repeats 5] [--N 50] [--check | --check-only] [--linear symbolic|numeric]
           [--stage MX|step|SX] [--mu-strategy monotone|adaptive] [--out out/reference_scale.json]
Every member runs in a fresh interpreter (its own peak RSS) unless ``--in-process``.
"""
from __future__ import annotations

import argparse
import contextlib
import functools
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np
import sibling  # experiments/sibling.py: the other scripts, loaded by file path

ROOT = Path(__file__).resolve().parents[1]


def _oracles():
    return sibling.oracles()


def _scale_tasks():
    return sibling.load("scale_tasks")


def _progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# --------------------------------------------------------------------------- #
# members
# --------------------------------------------------------------------------- #
def _family(member: str) -> str:
    if member.startswith("snake_") and member[6:].isdigit():
        return "snake"
    if member.startswith("cart_trailers_") and member[14:].isdigit():
        return "cart_trailers"
    if member == "snakeboard_two_steering":
        return "snakeboard_two_steering"
    raise KeyError(f"unknown member {member!r}")


def _parameter_values(member: str) -> dict:
    """The scene's parameter values (``scaling_systems``: the same robots as the scenes)."""
    ss = _scale_tasks()._scaling_systems()
    fam = _family(member)
    if fam == "snake":
        return dict(ss.SNAKE)
    if fam == "cart_trailers":
        return {**ss.CART, **ss.TRAILER}
    return dict(ss.BOARD)


def _independent_speeds(member: str) -> tuple[str, ...]:
    """Names (of the speeds ``v``, ``w`` or coordinates) of the independent speeds."""
    fam = _family(member)
    if fam == "snake":
        return ("alpha1", "alpha2")
    if fam == "cart_trailers":
        return ("theta", "phi")
    return ("v", "psi", "phi_f", "phi_b")


# --------------------------------------------------------------------------- #
# sympy -> CasADi SX
# --------------------------------------------------------------------------- #
class _SXPrinter:
    """Turns sympy expressions (after ``sympy.cse``) into CasADi SX, memoised per node."""

    def __init__(self, env: dict):
        self.env = dict(env)   # sympy Symbol -> SX

    def __call__(self, e):
        import sympy as sp
        hit = self.env.get(e)
        if hit is not None:
            return hit
        if e.is_Number:
            out = ca.SX(float(e))
        elif e.is_Add:
            args = [self(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out + a
        elif e.is_Mul:
            args = [self(a) for a in e.args]
            out = args[0]
            for a in args[1:]:
                out = out * a
        elif e.is_Pow:
            base, expo = e.args
            b = self(base)
            if expo.is_Integer:
                k = int(expo)
                if k == 2:
                    out = b * b
                elif k == -1:
                    out = 1 / b
                elif k == -2:
                    out = 1 / (b * b)
                else:
                    out = ca.constpow(b, k)
            elif expo == sp.Rational(1, 2):
                out = ca.sqrt(b)
            else:
                out = ca.power(b, self(expo))
        elif isinstance(e, sp.sin):
            out = ca.sin(self(e.args[0]))
        elif isinstance(e, sp.cos):
            out = ca.cos(self(e.args[0]))
        elif isinstance(e, sp.tan):
            out = ca.tan(self(e.args[0]))
        else:
            raise TypeError(f"cannot print {type(e).__name__}: {e}")
        self.env[e] = out
        return out

    def matrix(self, exprs, shape):
        """Print a list of sympy expressions (row-major ``shape``) with one common ``cse``."""
        import sympy as sp
        repl, reduced = sp.cse(list(exprs), order="none")
        for sym, sub in repl:
            self.env[sym] = self(sub)
        flat = [self(r) for r in reduced]
        rows, cols = shape
        return ca.vertcat(*[ca.horzcat(*flat[i * cols:(i + 1) * cols]) for i in range(rows)]) \
            if flat else ca.SX(rows, cols)


# --------------------------------------------------------------------------- #
# Kane's equations in body-frame speeds (sympy)
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class KaneBody:
    """M(s) u̇ = F(s, u, τ), A(s) u = 0 and Ȧu = h(s, u) in the body-frame speeds
    u = (v, w, θ̇, u_c …) with x = y = θ = 0 and the parameter values substituted; plain sympy
    symbols ``q_<c>``, ``u_<speed>``, inputs by name."""
    member: str
    coordinates: tuple[str, ...]
    speeds: tuple[str, ...]           # v, w, theta, <c> ...
    inputs: tuple[str, ...]
    q_syms: tuple
    u_syms: tuple
    tau_syms: tuple
    M: object                         # sympy Matrix n x n
    F: object                         # sympy Matrix n x 1
    A: object                         # sympy Matrix k x n
    h: object                         # sympy Matrix k x 1
    derive_s: float


@functools.cache
def kane_body(member: str) -> KaneBody:
    """Kane's equations of ``member`` (``tests/oracles.py`` description) in body-frame speeds."""
    import sympy as sp
    from sympy.physics.mechanics import KanesMethod, dynamicsymbols, msubs

    t0 = time.perf_counter()
    mdl = _oracles().model_description(member)
    q = list(mdl["q"])
    n = len(q)
    names = tuple(qi.func.__name__ for qi in q)
    if names[:3] != ("x", "y", "theta"):
        raise ValueError(f"{member}: expected the planar frame (x, y, theta) first, got {names[:3]}")
    t = dynamicsymbols._t
    speeds = ("v", "w") + names[2:]
    u = [dynamicsymbols(f"ub_{s}") for s in speeds]
    qd = [qi.diff(t) for qi in q]
    x, y, th = q[:3]
    c, s = sp.cos(th), sp.sin(th)
    kd = [u[0] - (qd[0] * c + qd[1] * s), u[1] - (-qd[0] * s + qd[1] * c)]
    kd += [u[i] - qd[i] for i in range(2, n)]
    km = KanesMethod(mdl["N"], q_ind=q, u_ind=u, kd_eqs=kd)
    km.kanes_equations(mdl["bodies"], mdl["loads"])
    qd_of_u = {qd[0]: u[0] * c - u[1] * s, qd[1]: u[0] * s + u[1] * c}
    qd_of_u.update({qd[i]: u[i] for i in range(2, n)})
    cons = sp.Matrix([msubs(ci, qd_of_u) for ci in mdl["constraints"]])
    A = cons.jacobian(u)

    values = _parameter_values(member)
    q_syms = tuple(sp.Symbol(f"q_{nm}", real=True) for nm in names)
    u_syms = tuple(sp.Symbol(f"u_{sp_}", real=True) for sp_ in speeds)
    tau_syms = tuple(sp.Symbol(str(i), real=True) for i in mdl["inputs"])
    plain = {**dict(zip(q, q_syms, strict=True)), **dict(zip(u, u_syms, strict=True))}
    plain.update({p: sp.Float(values[str(p)]) for p in mdl["params"]})
    plain.update({i: ts for i, ts in zip(mdl["inputs"], tau_syms, strict=True)})
    frame0 = {q_syms[0]: 0, q_syms[1]: 0, q_syms[2]: 0}

    def to_plain(mat):
        out = sp.Matrix(mat).xreplace(plain).xreplace(frame0)
        left = {a for a in out.atoms(sp.Function, sp.Derivative) if a.has(t)}
        if left:
            raise RuntimeError(f"{member}: unresolved time functions {left}")
        return out

    M = to_plain(km.mass_matrix)
    F = to_plain(km.forcing)
    A = to_plain(A)
    Au = A * sp.Matrix(u_syms)
    shape_rates = {q_syms[i]: u_syms[i] for i in range(3, n)}   # speeds[i] is the rate of q_i, i >= 2
    h = sp.zeros(A.shape[0], 1)
    for qs_, rate in shape_rates.items():
        h += Au.diff(qs_) * rate
    # (x, y, θ set to 0 is exact by the planar symmetry; ``check_model`` confirms it at random θ)
    return KaneBody(member, names, speeds, tuple(str(i) for i in mdl["inputs"]), q_syms, u_syms,
                    tau_syms, M, F, A, h, time.perf_counter() - t0)


# --------------------------------------------------------------------------- #
# the reduced ODE (CasADi)
# --------------------------------------------------------------------------- #
@dataclass(frozen=True)
class ReducedODE:
    """ż = f(z, τ), z = (q, u_ind) of size 2n − k, in nhgait's coordinate order.

    ``f``: (z, τ) -> ż; ``qdot``: z -> q̇ (n); ``qddot``: (z, τ) -> q̈ (n);
    ``velocity_matrix``: q -> R (n × (n − k)) with q̇ = R(q) u_ind."""
    member: str
    coordinates: tuple[str, ...]
    independent: tuple[str, ...]       # speed names of u_ind (v or coordinate names)
    inputs: tuple[str, ...]
    n: int
    k: int
    f: ca.Function
    qdot: ca.Function
    qddot: ca.Function
    velocity_matrix: ca.Function
    derive_s: float
    linear: str

    @property
    def nx(self) -> int:
        return self.n + len(self.independent)

    @property
    def nu(self) -> int:
        return len(self.inputs)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.coordinates + tuple(f"u_{s}" for s in self.independent)


def _speeds_numeric(kb: KaneBody, ind, dep, z, tau) -> tuple:
    """(u, u̇_ind) with the linear solves in the SX graph (``linear="numeric"``)."""
    n = len(kb.coordinates)
    q_env = {s: z[i] for i, s in enumerate(kb.q_syms)}
    tau_env = {s: tau[i] for i, s in enumerate(kb.tau_syms)}
    u_ind = z[n:]
    pr = _SXPrinter({**q_env, **tau_env})
    A = pr.matrix(list(kb.A), kb.A.shape)
    A_dep, A_ind = A[:, dep], A[:, ind]
    B = ca.solve(A_dep, -A_ind)                       # k x (n-k)
    u_full = ca.SX.zeros(n)
    u_full[ind] = u_ind
    u_full[dep] = ca.mtimes(B, u_ind)
    pr2 = _SXPrinter({**q_env, **tau_env, **{s: u_full[i] for i, s in enumerate(kb.u_syms)}})
    rows = list(kb.M) + list(kb.F) + list(kb.h)
    allm = pr2.matrix(rows, (len(rows), 1))
    Mm = ca.reshape(allm[:n * n], n, n).T
    Fv = allm[n * n:n * n + n]
    hv = allm[n * n + n:]
    d = ca.solve(A_dep, -hv)
    S = ca.SX.zeros(n, len(ind))
    S[ind, :] = ca.SX.eye(len(ind))
    S[dep, :] = B
    Mr = ca.mtimes([S.T, Mm, S])
    rhs = ca.mtimes(S.T, Fv - ca.mtimes(Mm[:, dep], d))
    return u_full, ca.solve(Mr, rhs)


def _speeds_symbolic(kb: KaneBody, ind, dep, z, tau) -> tuple:
    """(u, u̇_ind) with the linear solves eliminated in sympy (``linear="symbolic"``)."""
    import sympy as sp
    n = len(kb.coordinates)
    q_env = {s: z[i] for i, s in enumerate(kb.q_syms)}
    tau_env = {s: tau[i] for i, s in enumerate(kb.tau_syms)}
    u_ind = z[n:]
    M, F, A, h = kb.M, kb.F, kb.A, kb.h
    A_dep, A_ind = A[:, dep], A[:, ind]
    B = A_dep.LUsolve(-A_ind)
    ui = sp.Matrix([kb.u_syms[i] for i in ind])
    sub = {kb.u_syms[i]: (B[j, :] * ui)[0] for j, i in enumerate(dep)}
    d = A_dep.LUsolve(-h.xreplace(sub))
    S = sp.zeros(n, len(ind))
    for j, i in enumerate(ind):
        S[i, j] = 1
    for j, i in enumerate(dep):
        S[i, :] = B[j, :]
    Mr = S.T * M * S
    rhs = S.T * (F.xreplace(sub) - M[:, dep] * d)
    acc = Mr.LUsolve(rhs)
    pr = _SXPrinter({**q_env, **tau_env, **{s: u_ind[j] for j, s in enumerate(ui)}})
    allm = pr.matrix(list(acc) + list(B), (len(acc) + B.shape[0] * B.shape[1], 1))
    Bsx = ca.reshape(allm[len(acc):], B.shape[1], B.shape[0]).T
    u_full = ca.SX.zeros(n)
    u_full[ind] = u_ind
    u_full[dep] = ca.mtimes(Bsx, u_ind)
    return u_full, allm[:len(acc)]


_SPEEDS = {"numeric": _speeds_numeric, "symbolic": _speeds_symbolic}


@functools.cache
def reduced_ode(member: str, linear: str = "symbolic") -> ReducedODE:
    """The reduced ODE of ``member`` (see the module docstring); ``linear`` = "numeric" (solves
    in the SX graph) or "symbolic" (eliminated in sympy before printing)."""
    if linear not in _SPEEDS:
        raise ValueError(f"linear must be 'numeric' or 'symbolic', got {linear!r}")
    kb = kane_body(member)
    t0 = time.perf_counter()
    n, k = len(kb.coordinates), kb.A.shape[0]
    ind_names = _independent_speeds(member)
    ind = [kb.speeds.index(s) for s in ind_names]
    dep = [i for i in range(n) if i not in ind]
    if len(ind) != n - k:
        raise RuntimeError(f"{member}: {len(ind)} independent speeds for n - k = {n - k}")
    z = ca.SX.sym("z", n + len(ind))
    tau = ca.SX.sym("tau", len(kb.inputs))
    u_full, u_ind_dot = _SPEEDS[linear](kb, ind, dep, z, tau)
    th = z[2]
    qdot = ca.vertcat(u_full[0] * ca.cos(th) - u_full[1] * ca.sin(th),
                      u_full[0] * ca.sin(th) + u_full[1] * ca.cos(th),
                      u_full[2:])
    zdot = ca.vertcat(qdot, u_ind_dot)
    f = ca.Function(f"f_{member}", [z, tau], [zdot], ["z", "tau"], ["zdot"])
    fq = ca.Function(f"qdot_{member}", [z], [qdot], ["z"], ["qdot"])
    qdd = ca.jtimes(qdot, z, zdot)
    fqdd = ca.Function(f"qddot_{member}", [z, tau], [qdd], ["z", "tau"], ["qddot"])
    R = ca.jacobian(qdot, z[n:])
    fR = ca.Function(f"R_{member}", [z[:n]], [ca.substitute(R, z[n:], ca.DM.zeros(len(ind)))],
                     ["q"], ["R"])
    return ReducedODE(member, kb.coordinates, ind_names, kb.inputs, n, k, f, fq, fqdd, fR,
                      kb.derive_s + time.perf_counter() - t0, linear)


# --------------------------------------------------------------------------- #
# the task, without redundancy in z
# --------------------------------------------------------------------------- #
_INF = math.inf


@dataclass
class Transcribed:
    """The task of ``scale_tasks`` in z: node bounds, periodicity rows, control bounds."""
    T: float
    N: int
    lbz0: np.ndarray
    ubz0: np.ndarray
    lbzN: np.ndarray
    ubzN: np.ndarray
    lbz: np.ndarray          # path bounds at every node
    ubz: np.ndarray
    periodic: list           # state indices with z_N[i] = z_0[i] as rows of g
    lbu: np.ndarray
    ubu: np.ndarray
    notes: list = field(default_factory=list)


def _rate_rows(ode: ReducedODE, q: np.ndarray) -> dict:
    """Rows r(q) with  rate = r(q) · u_ind  for every ``<c>_dot`` and ``forward_velocity``."""
    R = np.asarray(ode.velocity_matrix(q))
    rows = {f"{c}_dot": R[i] for i, c in enumerate(ode.coordinates)}
    rows["forward_velocity"] = math.cos(q[2]) * R[0] + math.sin(q[2]) * R[1]
    return rows


def _sample_configurations(ode: ReducedODE, lo: np.ndarray, hi: np.ndarray, count: int, seed: int):
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(lo), lo, -1.5)
    hi = np.where(np.isfinite(hi), hi, 1.5)
    return rng.uniform(lo, hi, (count, ode.n))


def _range(value) -> tuple:
    """(lo, hi) of a task value: a number (lo = hi) or a [lo, hi] pair."""
    if isinstance(value, (list, tuple)):
        return float(value[0]), float(value[1])
    return float(value), float(value)


@dataclass(frozen=True)
class _StateIndex:
    """Where a task name sits in z = (q, u_ind): the coordinates, and the state rates (``<s>_dot``
    of an independent speed, ``forward_velocity`` for v)."""

    coord: dict
    state_rate: dict

    @classmethod
    def of(cls, ode: ReducedODE) -> _StateIndex:
        return cls({c: i for i, c in enumerate(ode.coordinates)},
                   {f"{s}_dot" if s != "v"
                    else "forward_velocity": ode.n + j for j, s in enumerate(ode.independent)})

    def get(self, name):
        """The index of ``name`` in z, None when it is not a state."""
        return self.coord.get(name, self.state_rate.get(name))


def _end_bounds(ode: ReducedODE, task: dict, index: _StateIndex, path: tuple, notes: list) -> tuple:
    """The node bounds ((lb, ub) at t = 0, (lb, ub) at t = T): the path bounds
    narrowed by the task's values; rates that are not states may only be held at 0, through
    the independent speeds that carry them (a note says which)."""
    lbz, ubz = path
    ends = []
    for end in ("initial", "final"):
        lb, ub = lbz.copy(), ubz.copy()
        rates = {}
        for name, value in task.get(end, {}).items():
            lo, hi = _range(value)
            i = index.get(name)
            if i is not None:
                lb[i], ub[i] = max(lb[i], lo), min(ub[i], hi)
            else:
                rates[name] = (lo, hi)
        if rates:
            if any(v != (0.0, 0.0) for v in rates.values()):
                raise ValueError(f"{end}: nonzero values of rates that are not states: {rates}")
            J = _zero_rate_subspace(ode, list(rates), lbz, ubz)
            for j in J:
                lb[ode.n + j] = ub[ode.n + j] = 0.0
            notes.append(f"{end}: {', '.join(sorted(rates))} = 0  <=>  "
                         f"{', '.join('u_' + ode.independent[j] for j in J)} = 0")
        ends.append((lb, ub))
    return tuple(ends)


def _periodic_rows(ode: ReducedODE, task: dict, index: _StateIndex, path: tuple, ends: tuple,
                   notes: list) -> list:
    """The periodic states kept as rows z_N[i] = z_0[i]; a periodic state fixed at one end is
    fixed at the other instead (``ends`` narrowed), a periodic rate that is not a state must be
    implied by the periodic states (checked, dropped)."""
    per = list(task.get("periodic", []))
    per_states = [index.get(p) for p in per if index.get(p) is not None]
    others = [p for p in per if index.get(p) is None]
    if others:
        _periodic_implied(ode, others, per_states, *path)
        notes.append(f"periodic {', '.join(others)}: implied by the periodic states (dropped)")
    (lb0, ub0), (lbN, ubN) = ends
    periodic = []
    for i in per_states:
        if lb0[i] == ub0[i] and lbN[i] == -_INF and ubN[i] == _INF or \
                (lb0[i] == ub0[i] and lbN[i] <= lb0[i] <= ubN[i]):
            lbN[i] = ubN[i] = lb0[i]
            notes.append(f"periodic {ode.state_names[i]}: fixed at t = 0, so fixed at t = T")
        elif lbN[i] == ubN[i] and lb0[i] <= lbN[i] <= ub0[i]:
            lb0[i] = ub0[i] = lbN[i]
            notes.append(f"periodic {ode.state_names[i]}: fixed at t = T, so fixed at t = 0")
        else:
            periodic.append(i)
    return periodic


def _control_bounds(ode: ReducedODE, task: dict) -> tuple:
    """(lbu, ubu) of ``control_bounds``: none, one bound for every input, or per input."""
    cb = task.get("control_bounds")
    if cb is None:
        return np.full(ode.nu, -_INF), np.full(ode.nu, _INF)
    if isinstance(cb, (int, float)):
        return np.full(ode.nu, -float(cb)), np.full(ode.nu, float(cb))
    lbu, ubu = np.full(ode.nu, -_INF), np.full(ode.nu, _INF)
    for name, value in cb.items():
        j = ode.inputs.index(name)
        lbu[j], ubu[j] = ((-float(value), float(value)) if not isinstance(value, (list, tuple))
                          else _range(value))
    return lbu, ubu


def transcribe(ode: ReducedODE, task: dict, N: int | None = None) -> Transcribed:
    """The task (a ``[task]`` dict) as bounds and rows in z = (q, u_ind) (module docstring)."""
    allowed = {"name", "description", "horizon", "intervals", "initial", "final", "periodic",
               "bounds", "control_bounds", "objective"}
    unknown = set(task) - allowed
    if unknown:
        raise ValueError(f"task keys not handled by the reference: {sorted(unknown)}")
    if task.get("objective", "effort") != "effort":
        raise ValueError("the reference solves the effort objective only")
    T = _scale_tasks().horizon(task)
    N = int(N if N is not None else task.get("intervals", 50))
    index = _StateIndex.of(ode)
    notes = []
    lbz, ubz = np.full(ode.nx, -_INF), np.full(ode.nx, _INF)
    for name, value in task.get("bounds", {}).items():
        i = index.get(name)
        if i is None:
            raise ValueError(f"path bound on {name!r}: only coordinates and state rates")
        lbz[i], ubz[i] = _range(value)
    ends = _end_bounds(ode, task, index, (lbz, ubz), notes)
    periodic = _periodic_rows(ode, task, index, (lbz, ubz), ends, notes)
    (lb0, ub0), (lbN, ubN) = ends
    lbu, ubu = _control_bounds(ode, task)
    return Transcribed(T, N, lb0, ub0, lbN, ubN, lbz, ubz, periodic, lbu, ubu, notes)


def _zero_rate_subspace(ode: ReducedODE, names: list, lbz, ubz, count: int = 40) -> list:
    """J with {R_D(q) u_ind = 0} = {u_J = 0} at random configurations within the bounds
    (columns of R_D outside J zero, those in J of full column rank); else ValueError."""
    J = None
    for q in _sample_configurations(ode, lbz[:ode.n], ubz[:ode.n], count, seed=7):
        rows = _rate_rows(ode, q)
        try:
            RD = np.array([rows[nm] for nm in names])
        except KeyError as exc:
            raise ValueError(f"unknown rate {exc}") from None
        scale = max(1.0, float(np.max(np.abs(RD))))
        cols = [j for j in range(RD.shape[1]) if np.max(np.abs(RD[:, j])) > 1e-12 * scale]
        if J is None:
            J = cols
        if cols != J or np.linalg.matrix_rank(RD[:, cols], tol=1e-9 * scale) != len(cols):
            raise ValueError(f"zero rates {names} are not a set of zero independent speeds")
    return J


def _periodic_implied(ode: ReducedODE, names: list, per_states: list, lbz, ubz, count: int = 20):
    """Check that every rate in ``names`` is R(q) u_ind with R depending only on periodic
    coordinates and only on periodic u_ind (so it is periodic when they are)."""
    n = ode.n
    per_q = [i for i in per_states if i < n]
    per_u = {i - n for i in per_states if i >= n}
    rng = np.random.default_rng(11)
    for q in _sample_configurations(ode, lbz[:n], ubz[:n], count, seed=13):
        q2 = q.copy()
        free = [i for i in range(n) if i not in per_q]
        q2[free] = rng.uniform(-1.5, 1.5, len(free))
        r1, r2 = _rate_rows(ode, q), _rate_rows(ode, q2)
        for nm in names:
            if nm not in r1:
                raise ValueError(f"periodic {nm!r}: unknown name")
            if np.max(np.abs(r1[nm] - r2[nm])) > 1e-10 * max(1.0, np.max(np.abs(r1[nm]))):
                raise ValueError(f"periodic {nm!r} depends on a non-periodic coordinate")
            if any(abs(r1[nm][j]) > 1e-12 for j in range(len(ode.independent)) if j not in per_u):
                raise ValueError(f"periodic {nm!r} depends on a non-periodic speed")


# --------------------------------------------------------------------------- #
# initial guesses
# --------------------------------------------------------------------------- #
def _rk4_rollout(ode: ReducedODE, q0: np.ndarray, u_of_t, t: np.ndarray, sub: int = 10):
    """Kinematic rollout q̇ = R(q) u_ind(t) (RK4, ``sub`` steps per node interval)."""
    qs = [np.asarray(q0, float)]
    R = ode.velocity_matrix
    for a, b in zip(t[:-1], t[1:], strict=True):
        q = qs[-1].copy()
        h = (b - a) / sub
        for i in range(sub):
            s = a + i * h
            f = lambda tt, qq: np.asarray(R(qq)).dot(u_of_t(tt))   # noqa: E731
            k1 = f(s, q)
            k2 = f(s + h / 2, q + h / 2 * k1)
            k3 = f(s + h / 2, q + h / 2 * k2)
            k4 = f(s + h, q + h * k3)
            q = q + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        qs.append(q)
    return np.array(qs)


def initial_guess(ode: ReducedODE, tr: Transcribed, task: dict) -> tuple[np.ndarray, np.ndarray]:
    """Z0 (nx × N+1) and U0 = 0 (nu × N): see the module docstring."""
    fam = _family(ode.member)
    T, N, n = tr.T, tr.N, ode.n
    t = np.linspace(0.0, T, N + 1)
    w = 2 * math.pi / T
    Z = np.zeros((ode.nx, N + 1))
    U = np.zeros((ode.nu, N))
    final = task.get("final", {})
    if fam == "snake":
        # head loop: alpha_j = c_j + A_j sin(wt + 5pi/4 + (j - 1) pi/2), j = 1, 2, (c_j, A_j) the
        # centre and 0.8 of the half-width of the band; trailing joints held at +-0.5
        for j in range(1, n - 2):
            i = ode.coordinates.index(f"alpha{j}")
            if j <= 2:
                lo, hi = tr.lbz[i], tr.ubz[i]
                c, amp = (lo + hi) / 2, 0.8 * (hi - lo) / 2
                phase = 5 * math.pi / 4 + (j - 1) * math.pi / 2
                Z[i] = c + amp * np.sin(w * t + phase)
                Z[n + j - 1] = amp * w * np.cos(w * t + phase)
            else:
                Z[i] = np.clip(0.5 if j % 2 else -0.5, tr.lbz[i], tr.ubz[i])
        Z[0] = float(final.get("x", 0.0)) * t / T
    elif fam == "cart_trailers":
        xT, yT = float(final["x"]), float(final["y"])
        rho = _parameter_values(ode.member)["rho"]

        def rollout(a, dist):
            def u_of(tt):
                speed = dist * 30 * tt**2 * (T - tt)**2 / T**5
                return np.array([a * w * math.sin(w * tt) / 2, speed / rho])   # theta_dot, phi_dot
            return _rk4_rollout(ode, np.zeros(n), u_of, t), u_of
        a, dist = 0.3, xT
        for _ in range(20):                                   # Newton on (a, dist) -> (x, y)(T)
            base = rollout(a, dist)[0][-1, :2]
            da = rollout(a + 1e-6, dist)[0][-1, :2]
            dd = rollout(a, dist + 1e-6)[0][-1, :2]
            Jm = np.column_stack([(da - base) / 1e-6, (dd - base) / 1e-6])
            step = np.linalg.solve(Jm, np.array([xT, yT]) - base)
            a, dist = a + step[0], dist + step[1]
            if np.max(np.abs(step)) < 1e-10:
                break
        qs, u_of = rollout(a, dist)
        Z[:n] = qs.T
        Z[n:] = np.array([u_of(tt) for tt in t]).T
    else:
        i_psi, i_f, i_b = (ode.coordinates.index(c) for c in ("psi", "phi_f", "phi_b"))
        Z[i_psi] = np.sin(w * t)
        Z[i_f] = 0.6 * np.cos(w * t)
        Z[i_b] = -0.6 * np.cos(w * t)
        Z[n + ode.independent.index("psi")] = w * np.cos(w * t)
        Z[n + ode.independent.index("phi_f")] = -0.6 * w * np.sin(w * t)
        Z[n + ode.independent.index("phi_b")] = 0.6 * w * np.sin(w * t)
        Z[0] = float(final.get("x", 0.0)) * t / T
    return Z, U


# --------------------------------------------------------------------------- #
# the NLP
# --------------------------------------------------------------------------- #
def rk4_stage(ode: ReducedODE, dt: float, steps: int = 4, kind: str = "MX") -> ca.Function:
    """One shooting interval: ``steps`` RK4 steps of size dt/steps. ``kind`` "MX": an MX
    graph of calls of the SX ODE function (compact C: one ODE kernel and its derivatives);
    "step": an MX graph of calls of one SX RK4 step; "SX": everything inlined in SX."""
    h = dt / steps

    def rk4(zz, tau, f):
        k1 = f(zz, tau)
        k2 = f(zz + h / 2 * k1, tau)
        k3 = f(zz + h / 2 * k2, tau)
        k4 = f(zz + h * k3, tau)
        return zz + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    if kind == "step":
        zs, ts = ca.SX.sym("z", ode.nx), ca.SX.sym("tau", ode.nu)
        step = ca.Function(f"step_{ode.member}", [zs, ts], [rk4(zs, ts, ode.f)])
        sym = ca.MX.sym
    elif kind in ("MX", "SX"):
        step, sym = None, (ca.MX.sym if kind == "MX" else ca.SX.sym)
    else:
        raise ValueError(f"stage kind must be 'MX', 'step' or 'SX', got {kind!r}")
    z0, tau = sym("z0", ode.nx), sym("tau", ode.nu)
    zz = z0
    for _ in range(steps):
        zz = step(zz, tau) if step is not None else rk4(zz, tau, ode.f)
    return ca.Function(f"F_{ode.member}", [z0, tau], [zz], ["z0", "tau"], ["zf"])


@contextlib.contextmanager
def scratch_cwd():
    """Run inside a temporary directory (CasADi's shell compiler writes jit_tmp* files into
    the working directory); yields its path; removed afterwards (libraries already loaded).
    Also used by ``experiments/reference_dae_ocp.py``."""
    old = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="reference-scale-jit-") as tmp:
        os.chdir(tmp)
        try:
            yield Path(tmp)
        finally:
            os.chdir(old)


def _ipopt_options(jit: bool, expand: bool | None = None, mu_strategy: str = "monotone") -> dict:
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "record_time": True,
            "ipopt.hessian_approximation": "exact", "ipopt.linear_solver": "mumps",
            "ipopt.max_iter": 500, "ipopt.mu_strategy": mu_strategy}
    if jit:
        opts.update({"expand": False, "jit": True, "compiler": "shell", "jit_cleanup": False,
                     "jit_options": {"flags": ["-O1"], "cleanup": False, "verbose": False}})
    else:
        opts["expand"] = True if expand is None else expand
    return opts


@dataclass(frozen=True)
class Options:
    """How the reference NLP is built: ``N`` intervals (None: the task's), compiled (``jit``),
    RK4 sub-``steps`` per interval, the ODE's ``linear`` solves ("symbolic" or "numeric"), the RK4
    ``stage`` ("MX", "step", "SX"), ``expand`` (None: Ipopt options' default) and Ipopt's
    ``mu_strategy``."""

    N: int | None = None
    jit: bool = True
    steps: int = 4
    linear: str = "symbolic"
    stage: str = "MX"
    expand: bool | None = None
    mu_strategy: str = "monotone"


class Reference:
    """The hand-written multiple-shooting NLP of one member (built once, solved many times)."""

    def __init__(self, member: str, options: Options = Options(), task: dict | None = None):
        t0 = time.perf_counter()
        jit, expand, mu_strategy = options.jit, options.expand, options.mu_strategy
        self.member = member
        self.task = dict(task if task is not None else _scale_tasks().task(member))
        self.ode = ode = reduced_ode(member, options.linear)
        self.derive_s = ode.derive_s
        self.tr = tr = transcribe(ode, self.task, options.N)
        self.N, self.T, self.jit, self.steps = tr.N, tr.T, jit, options.steps
        nx, nu, N = ode.nx, ode.nu, tr.N
        self.n_states = nx
        self.stage = step = rk4_stage(ode, tr.T / N, options.steps, options.stage)
        step_map = step.map(N, "serial")
        V = ca.MX.sym("V", nx + nu, N)
        zN = ca.MX.sym("zN", nx)
        w = ca.vertcat(ca.vec(V), zN)
        Zs, Us = V[:nx, :], V[nx:, :]
        gaps = step_map(Zs, Us) - ca.horzcat(Zs[:, 1:], zN)
        g = ca.vertcat(ca.vec(gaps), *[zN[i] - Zs[i, 0] for i in tr.periodic])
        J = (tr.T / N) * ca.sumsqr(Us)
        t1 = time.perf_counter()
        self.c_bytes = 0
        if jit:
            with scratch_cwd() as tmp:
                self.solver = ca.nlpsol("reference", "ipopt", {"x": w, "f": J, "g": g},
                                        _ipopt_options(True, mu_strategy=mu_strategy))
                self.c_bytes = sum(p.stat().st_size for p in tmp.glob("*.c"))
        else:
            self.solver = ca.nlpsol("reference", "ipopt", {"x": w, "f": J, "g": g},
                                    _ipopt_options(False, expand, mu_strategy))
        self.compile_s = time.perf_counter() - t1 if jit else 0.0
        self.lbg = np.zeros(g.shape[0])
        self.ubg = np.zeros(g.shape[0])
        self._set_bounds(tr)
        self.build_s = t1 - t0          # transcription (derivation included)
        self.setup_s = time.perf_counter() - t0

    def set_task(self, task: dict) -> None:
        """Change the task's numbers (targets, bounds, control bounds) without rebuilding; the
        horizon, N and the periodic rows must stay the same."""
        tr = transcribe(self.ode, task, self.N)
        if tr.periodic != self.tr.periodic or tr.T != self.T:
            raise ValueError("set_task: horizon or periodic rows differ; build a new Reference")
        self.task, self.tr = dict(task), tr
        self._set_bounds(tr)

    def _set_bounds(self, tr: Transcribed) -> None:
        nx, nu, N = self.ode.nx, self.ode.nu, self.N
        lbV = np.empty((nx + nu, N))
        ubV = np.empty((nx + nu, N))
        lbV[:nx, :], ubV[:nx, :] = tr.lbz[:, None], tr.ubz[:, None]
        lbV[:nx, 0], ubV[:nx, 0] = tr.lbz0, tr.ubz0
        lbV[nx:, :], ubV[nx:, :] = tr.lbu[:, None], tr.ubu[:, None]
        self.lbx = np.concatenate([lbV.ravel(order="F"), tr.lbzN])
        self.ubx = np.concatenate([ubV.ravel(order="F"), tr.ubzN])
        Z0, U0 = initial_guess(self.ode, tr, self.task)
        self.w0 = self.pack(Z0, U0)

    def pack(self, Z: np.ndarray, U: np.ndarray) -> np.ndarray:
        """w from node states Z (nx × N+1) and controls U (nu × N)."""
        N = self.N
        return np.concatenate([np.vstack([Z[:, :N], U]).ravel(order="F"), Z[:, N]])

    def _unpack(self, wopt):
        nx, nu, N = self.ode.nx, self.ode.nu, self.N
        V = wopt[:(nx + nu) * N].reshape((nx + nu, N), order="F")
        Z = np.column_stack([V[:nx, :], wopt[(nx + nu) * N:]])
        return Z, V[nx:, :]

    def solve(self, w0: np.ndarray | None = None) -> dict:
        """Solve from the reference's own guess (or ``w0``); a dict (see the module docstring)."""
        t0 = time.perf_counter()
        sol = self.solver(x0=self.w0 if w0 is None else w0, lbx=self.lbx, ubx=self.ubx,
                          lbg=self.lbg, ubg=self.ubg)
        wall = time.perf_counter() - t0
        st = self.solver.stats()
        wopt = np.asarray(sol["x"]).ravel()
        Z, U = self._unpack(wopt)
        n = self.ode.n
        t_wall = {k[len("t_wall_"):]: float(v) for k, v in st.items() if k.startswith("t_wall_")}
        return {
            "member": self.member, "N": self.N, "T": self.T,
            "objective": float(sol["f"]), "iterations": int(st["iter_count"]),
            "status": str(st["return_status"]), "success": bool(st["success"]),
            "solve_s": wall, "t_wall": t_wall,
            "t": np.linspace(0.0, self.T, self.N + 1), "z": Z, "q": Z[:n].T.copy(), "u": U.T.copy(),
            "coordinates": list(self.ode.coordinates), "inputs": list(self.ode.inputs),
            "state_names": list(self.ode.state_names),
        }


def build(member: str, N: int | None = None, jit: bool = True, task: dict | None = None,
          **options) -> Reference:
    """The reference NLP of ``member`` (compiled when ``jit``); ``N`` overrides the task's;
    ``options``: the other fields of :class:`Options`."""
    return Reference(member, Options(N=N, jit=jit, **options), task)


# --------------------------------------------------------------------------- #
# a second model: the multiplier DAE in (q, q̇) (check and re-simulation)
# --------------------------------------------------------------------------- #
@functools.cache
def multiplier_dae(member: str) -> ca.Function:
    """q̈(q, q̇, τ) of M_q q̈ = F_q + A_qᵀλ, A_q q̈ = −Ȧ_q q̇, from the *unconstrained*
    ``KanesMethod`` in the speeds u = q̇ (no body-frame speeds, no symmetry, no reduction)."""
    import sympy as sp
    from sympy.physics.mechanics import KanesMethod, dynamicsymbols
    mdl = _oracles().model_description(member)
    q = list(mdl["q"])
    n = len(q)
    t = dynamicsymbols._t
    names = [qi.func.__name__ for qi in q]
    u = [dynamicsymbols(f"ud_{c}") for c in names]
    qd = [qi.diff(t) for qi in q]
    km = KanesMethod(mdl["N"], q_ind=q, u_ind=u, kd_eqs=[a - b for a, b in zip(u, qd, strict=True)])
    km.kanes_equations(mdl["bodies"], mdl["loads"])
    cons = sp.Matrix(mdl["constraints"]).xreplace(dict(zip(qd, u, strict=True)))
    values = _parameter_values(member)
    qs = sp.symbols([f"q{i}" for i in range(n)], real=True)
    us = sp.symbols([f"qd{i}" for i in range(n)], real=True)
    taus = sp.symbols([str(i) for i in mdl["inputs"]], real=True)
    plain = {**dict(zip(q, qs, strict=True)), **dict(zip(u, us, strict=True)),
             **dict(zip(mdl["inputs"], taus, strict=True))}
    plain.update({p: sp.Float(values[str(p)]) for p in mdl["params"]})
    M = sp.Matrix(km.mass_matrix).xreplace(plain)
    F = sp.Matrix(km.forcing).xreplace(plain)
    A = cons.jacobian(u).xreplace(plain)
    Aqd = A * sp.Matrix(us)
    bias = sp.zeros(A.shape[0], 1)
    for qi, ui in zip(qs, us, strict=True):
        bias += Aqd.diff(qi) * ui
    Q, QD, TAU = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("tau", len(taus))
    env = {**{s: Q[i] for i, s in enumerate(qs)}, **{s: QD[i] for i, s in enumerate(us)},
           **{s: TAU[i] for i, s in enumerate(taus)}}
    rows = list(M) + list(F) + list(A) + list(bias)
    allm = _SXPrinter(env).matrix(rows, (len(rows), 1))
    k = A.shape[0]
    Mm = ca.reshape(allm[:n * n], n, n).T
    Fv = allm[n * n:n * n + n]
    Am = ca.reshape(allm[n * n + n:n * n + n + k * n], n, k).T
    bv = allm[n * n + n + k * n:]
    K = ca.vertcat(ca.horzcat(Mm, -Am.T), ca.horzcat(Am, ca.SX.zeros(k, k)))
    sol = ca.solve(K, ca.vertcat(Fv, -bv))
    return ca.Function(f"dae_{member}", [Q, QD, TAU], [sol[:n]], ["q", "qd", "tau"], ["qdd"])


def _independent_of(ode: ReducedODE, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """u_ind from (q, q̇)."""
    out = []
    for s in ode.independent:
        if s == "v":
            out.append(qd[0] * math.cos(q[2]) + qd[1] * math.sin(q[2]))
        else:
            out.append(qd[ode.coordinates.index(s)])
    return np.array(out)


def _random_states(ode: ReducedODE, count: int, seed: int):
    """Random consistent states: configurations within the task's node bounds (x, y, θ and
    unbounded coordinates in [−1.2, 1.2]), u_ind in [−1, 1], τ in [−2, 2]."""
    tr = transcribe(ode, _scale_tasks().task(ode.member))
    rng = np.random.default_rng(seed)
    qs = _sample_configurations(ode, tr.lbz[:ode.n], tr.ubz[:ode.n], count, seed)
    qs[:, :3] = rng.uniform(-1.2, 1.2, (count, 3))
    lo = np.where(np.isfinite(tr.lbz[:ode.n]), tr.lbz[:ode.n], -1.2)
    hi = np.where(np.isfinite(tr.ubz[:ode.n]), tr.ubz[:ode.n], 1.2)
    qs[:, 3:] = rng.uniform(lo[3:], hi[3:], (count, ode.n - 3))
    for q in qs:
        yield q, rng.uniform(-1.0, 1.0, ode.nx - ode.n), rng.uniform(-2.0, 2.0, ode.nu)


def check_model(member: str, count: int = 50, oracle: bool = True, seed: int = 3,
                linear: str = "symbolic") -> dict:
    """Worst relative q̈ error of the reduced ODE against the oracle's ``qddot`` (when
    ``oracle``) and against the multiplier DAE, at ``count`` random consistent states
    (max |Δq̈| / max(1, max |q̈|)); also the constraint residual of q̇(z)."""
    ode = reduced_ode(member, linear)
    dae = multiplier_dae(member)
    orc = params = None
    t0 = time.perf_counter()
    if oracle:
        orc = _oracles().oracle(member)
        values = _parameter_values(member)
        params = np.array([values[p] for p in orc.parameters])
    oracle_build_s = time.perf_counter() - t0
    worst_oracle = worst_dae = worst_res = 0.0
    for q, ui, tau in _random_states(ode, count, seed):
        z = np.concatenate([q, ui])
        qd = np.asarray(ode.qdot(z)).ravel()
        got = np.asarray(ode.qddot(z, tau)).ravel()
        ref = np.asarray(dae(q, qd, tau)).ravel()
        worst_dae = max(worst_dae, float(np.max(np.abs(got - ref)) / max(1.0, np.max(np.abs(ref)))))
        if orc is not None:
            tau_o = np.array([tau[ode.inputs.index(i)] for i in orc.inputs])
            ref = orc.qddot(q, qd, tau_o, params)
            worst_oracle = max(worst_oracle,
                               float(np.max(np.abs(got - ref)) / max(1.0, np.max(np.abs(ref)))))
            worst_res = max(worst_res, float(np.max(np.abs(orc.constraint_residual(q, qd, params)))))
    return {"member": member, "states": count, "vs_oracle": worst_oracle if orc else None,
            "vs_multiplier_dae": worst_dae, "constraint_residual": worst_res if orc else None,
            "oracle_build_s": oracle_build_s if orc else None}


# --------------------------------------------------------------------------- #
# re-simulation of an optimum (scipy DOP853 on the multiplier DAE)
# --------------------------------------------------------------------------- #
def _condition_values(ode: ReducedODE, q: np.ndarray, qd: np.ndarray) -> dict:
    vals = {c: q[i] for i, c in enumerate(ode.coordinates)}
    vals.update({f"{c}_dot": qd[i] for i, c in enumerate(ode.coordinates)})
    vals["forward_velocity"] = qd[0] * math.cos(q[2]) + qd[1] * math.sin(q[2])
    return vals


def resimulate(ref: Reference, res: dict, rtol: float = 1e-10, atol: float = 1e-12) -> dict:
    """Re-simulate the optimum's controls from its initial state on the multiplier DAE in
    (q, q̇) (DOP853, restarted at every control switch from the state reached); the largest
    node error in z and the largest violation of the task's conditions as written."""
    from scipy.integrate import solve_ivp
    ode = ref.ode
    dae = multiplier_dae(ref.member)
    n = ode.n
    Z, U, t = res["z"], res["u"], res["t"]
    y = np.concatenate([Z[:n, 0], np.asarray(ode.qdot(Z[:, 0])).ravel()])
    states = [y]
    nfev = 0
    for kk in range(ref.N):
        tau = U[kk]
        sol = solve_ivp(lambda _t, s, tau=tau: np.concatenate([s[n:],
                                                               np.asarray(dae(s[:n], s[n:], tau)).ravel()]),
                        (t[kk], t[kk + 1]), states[-1], method="DOP853", rtol=rtol, atol=atol)
        if not sol.success:
            return {"success": False, "message": sol.message, "node_error": math.inf}
        nfev += sol.nfev
        states.append(sol.y[:, -1])
    S = np.array(states)
    Zs = np.array([np.concatenate([s[:n], _independent_of(ode, s[:n], s[n:])]) for s in S]).T
    node_error = float(np.max(np.abs(Zs - Z)))
    first, last = (_condition_values(ode, S[0, :n], S[0, n:]),
                   _condition_values(ode, S[-1, :n], S[-1, n:]))
    task = ref.task
    viol = {}

    def dist(v, target):
        lo, hi = (target if isinstance(target, (list, tuple)) else (target, target))
        return max(0.0, float(lo) - v, v - float(hi))
    for end, vals in (("initial", first), ("final", last)):
        for name, target in task.get(end, {}).items():
            viol[f"{end}.{name}"] = dist(vals[name], target)
    for name in task.get("periodic", []):
        viol[f"periodic.{name}"] = abs(last[name] - first[name])
    for name, rng_ in task.get("bounds", {}).items():
        i = ode.coordinates.index(name)
        viol[f"bounds.{name}"] = max(dist(v, rng_) for v in S[:, i])
    worst = max(viol, key=viol.get) if viol else None
    return {"success": True, "node_error": node_error, "nfev": nfev,
            "condition_error": viol[worst] if worst else 0.0, "worst_condition": worst,
            "condition_errors": viol}


# --------------------------------------------------------------------------- #
# command line
# --------------------------------------------------------------------------- #
def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0   # Linux: kB


def run_member(member: str, options: Options, *, repeats=5, check=False, verify=True) -> dict:
    """Build, solve ``repeats`` times (median), re-simulate and (optionally) check one member."""
    jit, linear, stage, mu_strategy = options.jit, options.linear, options.stage, options.mu_strategy
    _progress(f"[{member}] building (jit={jit}, linear={linear}, stage={stage}) ...")
    ref = Reference(member, options)
    _progress(f"[{member}] set-up {ref.setup_s:.1f} s (derivation {ref.derive_s:.1f} s, "
              f"compile {ref.compile_s:.1f} s, C {ref.c_bytes / 1e6:.2f} MB); solving ...")
    runs = [ref.solve() for _ in range(max(1, repeats))]
    last = runs[-1]
    row = {
        "member": member, "n": ref.ode.n, "k": ref.ode.k, "states": ref.n_states,
        "inputs": ref.ode.nu, "N": ref.N, "T": ref.T, "jit": jit, "linear": linear, "stage": stage,
        "mu_strategy": mu_strategy,
        "setup_s": ref.setup_s, "derive_s": ref.derive_s, "compile_s": ref.compile_s,
        "c_bytes": ref.c_bytes, "ode_instructions": ref.ode.f.n_instructions(),
        "solve_ms": statistics.median(r["solve_s"] for r in runs) * 1e3,
        "solve_ms_all": [r["solve_s"] * 1e3 for r in runs],
        "t_wall_ms": {k: statistics.median(r["t_wall"].get(k, 0.0) for r in runs) * 1e3
                      for k in last["t_wall"]},
        "iterations": last["iterations"], "objective": last["objective"],
        "status": last["status"], "success": all(r["success"] for r in runs),
        "translation": ref.tr.notes, "task": ref.task,
        "trajectory": {"t": last["t"].tolist(), "coordinates": last["coordinates"],
                       "q": last["q"].tolist(), "inputs": last["inputs"], "u": last["u"].tolist(),
                       "state_names": last["state_names"], "z": last["z"].T.tolist()},
    }
    if verify:
        _progress(f"[{member}] J = {row['objective']:.6g}, {row['iterations']} it, "
                  f"{row['solve_ms']:.0f} ms; re-simulating ...")
        ver = resimulate(ref, last)
        row["resim_error"] = ver["node_error"]
        row["condition_error"] = ver.get("condition_error")
        row["worst_condition"] = ver.get("worst_condition")
    if check:
        _progress(f"[{member}] checking the model against the oracle ...")
        row["check"] = check_model(member, linear=linear)
    row["peak_rss_mb"] = _peak_rss_mb()
    return row


def _run_isolated(member: str, args) -> dict:
    """``run_member`` in a fresh interpreter (own peak RSS); returns its row."""
    with tempfile.TemporaryDirectory(prefix="reference-scale-") as tmp:
        out = Path(tmp) / "row.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--members", member,
               "--repeats", str(args.repeats), "--linear", args.linear, "--stage", args.stage,
               "--mu-strategy", args.mu_strategy, "--timeout", str(args.timeout),
               "--out", str(out), "--in-process", "--quiet"]
        if args.N:
            cmd += ["--N", str(args.N)]
        if args.no_jit:
            cmd.append("--no-jit")
        if args.check:
            cmd.append("--check")
        try:
            proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, timeout=args.timeout)
        except subprocess.TimeoutExpired:
            return {"member": member, "status": f"not finished in {args.timeout:.0f} s",
                    "success": False}
        if proc.returncode not in (0, 1) or not out.exists():
            return {"member": member, "status": f"child exited with {proc.returncode}",
                    "success": False}
        return json.loads(out.read_text())["rows"][0]


def _table(rows) -> str:
    hdr = (f"{'member':24s} {'n':>2s} {'k':>2s} {'nx':>3s} {'setup s':>8s} {'C MB':>5s} "
           f"{'solve ms':>9s} {'it':>4s} {'objective':>11s} {'resim err':>9s} {'cond err':>9s} "
           f"{'RSS MB':>7s}  status")
    lines = [hdr, "-" * len(hdr)]
    for r in rows:
        if "objective" not in r:
            lines.append(f"{r['member']:24s} {r.get('status', 'failed')}")
            continue
        lines.append(
            f"{r['member']:24s} {r['n']:2d} {r['k']:2d} {r['states']:3d} {r['setup_s']:8.1f} "
            f"{r['c_bytes'] / 1e6:5.2f} {r['solve_ms']:9.1f} {r['iterations']:4d} "
            f"{r['objective']:11.6f} {r.get('resim_error', float('nan')):9.1e} "
            f"{r.get('condition_error', float('nan')):9.1e} {r.get('peak_rss_mb', 0):7.0f}  {r['status']}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", default=",".join(_scale_tasks().MEMBERS),
                    help="comma-separated members (default: all)")
    ap.add_argument("--N", type=int, default=None, help="intervals (default: the task's)")
    ap.add_argument("--no-jit", action="store_true", help="interpreted (expand=True) NLP")
    ap.add_argument("--repeats", type=int, default=5, help="solves per member (median)")
    ap.add_argument("--linear", choices=["numeric", "symbolic"], default="symbolic",
                    help="linear solves of the ODE in the SX graph or eliminated in sympy")
    ap.add_argument("--stage", choices=["MX", "step", "SX"], default="MX",
                    help="RK4 stage: MX calls of the SX ODE (default), of an SX RK4 step, or "
                         "the ODE inlined in SX")
    ap.add_argument("--mu-strategy", choices=["monotone", "adaptive"], default="monotone",
                    help="Ipopt's barrier update (default: Ipopt's own, monotone)")
    ap.add_argument("--check", action="store_true",
                    help="compare the reduced ODE with the oracle and the multiplier DAE")
    ap.add_argument("--check-only", action="store_true",
                    help="only compare the reduced ODE with the oracle and the DAE (no NLP)")
    ap.add_argument("--no-verify", action="store_true", help="skip the DOP853 re-simulation")
    ap.add_argument("--timeout", type=float, default=3600.0,
                    help="seconds per member when run in a child process")
    ap.add_argument("--in-process", action="store_true",
                    help="run every member in this process (peak RSS is then cumulative)")
    ap.add_argument("--quiet", action="store_true", help="no table on stdout")
    ap.add_argument("--out", default=str(ROOT / "out" / "reference_scale.json"))
    args = ap.parse_args(argv)
    members = [m.strip() for m in args.members.split(",") if m.strip()]
    for m in members:
        _family(m)
    if args.check_only:
        return _check_only(members, args.linear)
    options = Options(N=args.N, jit=not args.no_jit, linear=args.linear, stage=args.stage,
                      mu_strategy=args.mu_strategy)
    rows = []
    for m in members:
        if args.in_process or len(members) == 1:
            rows.append(run_member(m, options, repeats=args.repeats, check=args.check,
                                   verify=not args.no_verify))
        else:
            rows.append(_run_isolated(m, args))
        r = rows[-1]
        if not args.quiet:
            _progress(f"[{m}] done: {r.get('status')}, J = {r.get('objective')}, "
                      f"{r.get('solve_ms', float('nan')):.1f} ms, resim {r.get('resim_error')}")
    _write_and_print(args, rows)
    ok = all(r.get("success") for r in rows)
    if args.check:
        ok &= all(r["check"]["vs_multiplier_dae"] < 1e-9 and
                  (r["check"]["vs_oracle"] is None or r["check"]["vs_oracle"] < 1e-9) for r in rows)
    return 0 if ok else 1


def _check_only(members, linear) -> int:
    """``--check-only``: each member's reduced ODE against the oracle and the multiplier DAE."""
    ok = True
    for m in members:
        _progress(f"[{m}] checking the reduced ODE ({linear}) ...")
        c = check_model(m, linear=linear)
        ok &= c["vs_oracle"] < 1e-9 and c["vs_multiplier_dae"] < 1e-9
        print(f"{m:24s} vs oracle {c['vs_oracle']:.1e}  vs multiplier DAE "
              f"{c['vs_multiplier_dae']:.1e}  constraint residual {c['constraint_residual']:.1e}"
              f"  (oracle build {c['oracle_build_s']:.1f} s, {c['states']} states)", flush=True)
    return 0 if ok else 1


def _write_and_print(args, rows) -> None:
    """The JSON file of the run (``--out``) and, unless ``--quiet``, its table and checks."""
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = {"casadi": ca.__version__, "python": sys.version.split()[0], "cpus": os.cpu_count(),
            "repeats": args.repeats, "jit": not args.no_jit, "linear": args.linear,
            "stage": args.stage, "mu_strategy": args.mu_strategy,
            "transcription": "multiple shooting, RK4 x4, Ipopt exact Hessian, MUMPS"}
    out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1, default=float))
    if not args.quiet:
        print(f"# {meta['transcription']}; CasADi {ca.__version__}; jit={meta['jit']}; "
              f"median of {args.repeats} solves")
        print(_table(rows))
        for r in rows:
            if "check" in r:
                c = r["check"]
                print(f"check {r['member']}: vs oracle {c['vs_oracle']}, vs multiplier DAE "
                      f"{c['vs_multiplier_dae']:.1e}, constraint residual {c['constraint_residual']}")


if __name__ == "__main__":
    sys.exit(main())
