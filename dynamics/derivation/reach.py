"""How far bounded inputs can move a system in a given time, when that can be judged cheaply.

A task whose target no admissible input can reach sent FATROP spinning for minutes
(``plan examples/car.toml --set final.y=1e4``). For the systems where the kinetic energy alone
bounds the motion, :func:`displacement_bounds` gives an upper bound on |q_i(T) − q_i(0)| that
holds for *every* input within its bounds, so a target beyond it is refused at once.

The bound (an energy argument). Constraint forces do no work and the potential is constant,
so the kinetic energy T = ½ q̇ᵀ M q̇ changes only by the inputs' power:

    dT/dt = τ(q, u) · q̇ ≤ ‖τ‖_{M⁻¹} ‖q̇‖_M = ‖τ‖_{M⁻¹} √(2T)   (Cauchy–Schwarz in the metric M),

hence d√(2T)/dt ≤ ‖τ‖_{M⁻¹} ≤ P := Σ_j ū_j · sup_q ‖B_j(q)‖_{M⁻¹} (τ = B(q) u, |u_j| ≤ ū_j), and
from rest √(2T(t)) ≤ P t. Each velocity obeys |q̇_i| ≤ √((M⁻¹)_ii) √(2T) (Cauchy–Schwarz
again), so

    |q_i(T) − q_i(0)| ≤ √((M⁻¹)_ii) · P · T² / 2.

It is judged only when every step is exact and cheap: M constant (no coordinate in it), V
constant, τ linear in the inputs with coefficients B(q) whose M⁻¹-norm is bounded by interval
arithmetic (sin, cos ∈ [−1, 1]; a coordinate outside a sine or cosine makes it unbounded), every
input bounded, the motion starting at rest. Otherwise None: nothing is claimed. The bound is
not tight (the car: 201 m of y in 6 s at |F| ≤ 5 N, |τ_φ| ≤ 1 N·m, where about 45 m is
reachable) — it refuses only the impossible.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import sympy as sp

from ..algebra.trig import trig_normal

__all__ = ["displacement_bounds"]


def displacement_bounds(system, input_bounds: Mapping, horizon: float,
                        params: Mapping | None = None) -> dict | None:
    """Coordinate name → an upper bound on |q_i(T) − q_i(0)| over every input with
    |u_j| ≤ max(|lo_j|, |hi_j|) (``input_bounds``: input name → (lo, hi)), starting at rest,
    for the horizon T; None when it cannot be judged cheaply (see the module docstring)."""
    if not (math.isfinite(horizon) and horizon > 0):
        return None
    limits = [_limit(input_bounds.get(name)) for name in system.inputs]
    if not system.inputs or any(v is None for v in limits):
        return None
    subs = system.param_subs(params)
    M = system.mass_matrix().xreplace(subs)
    qs = set(system.q)
    if M.free_symbols or system.potential().xreplace(subs).free_symbols & qs:
        return None
    B = _input_matrix(system, subs)
    if B is None:
        return None
    Minv = sp.Matrix(np.linalg.inv(np.array(M, dtype=float)).tolist())
    power = 0.0
    for j, u_max in enumerate(limits):
        column = B[:, j]
        norm2 = _sup(trig_normal(sp.expand((column.T * Minv * column)[0, 0])), qs)
        if norm2 is None:
            return None
        power += u_max * math.sqrt(max(norm2, 0.0))
    diagonal = np.diag(np.array(Minv, dtype=float))
    return {name: float(math.sqrt(max(d, 0.0)) * power * horizon ** 2 / 2)
            for name, d in zip(system.coordinates, diagonal, strict=True)}


def _limit(bounds) -> float | None:
    if bounds is None:
        return None
    lo, hi = bounds
    value = max(abs(float(lo)), abs(float(hi)))
    return value if math.isfinite(value) else None


def _input_matrix(system, subs) -> sp.Matrix | None:
    """B(q) with τ = B(q) u exactly (no term without an input, none in t or the velocities),
    or None."""
    u = list(system.input_symbols)
    tau = sp.Matrix(system.tau).xreplace(subs)
    B = tau.jacobian(u)
    if B.free_symbols & (set(u) | set(system.q_dot) | {sp.Symbol("t")}):
        return None
    if any(sp.expand(e) != 0 for e in tau - B * sp.Matrix(u)):
        return None
    return B


def _sup(expr, qs: set) -> float | None:
    """An upper bound on expr over all q (interval arithmetic), or None when unbounded."""
    interval = _interval(expr, qs)
    return None if interval is None else interval[1]


def _interval(e, qs: set):
    """(lo, hi) enclosing ``e`` for every q, or None (a coordinate outside sin/cos, an unknown
    function, a division)."""
    if e.is_Number:
        return (float(e), float(e))
    if isinstance(e, (sp.sin, sp.cos)):
        return (-1.0, 1.0)
    if e in qs or e.is_Symbol:
        return None
    parts = [_interval(a, qs) for a in e.args]
    if any(p is None for p in parts):
        return None
    if e.is_Add:
        return (sum(p[0] for p in parts), sum(p[1] for p in parts))
    if e.is_Mul:
        out = (1.0, 1.0)
        for lo, hi in parts:
            corners = [out[0] * lo, out[0] * hi, out[1] * lo, out[1] * hi]
            out = (min(corners), max(corners))
        return out
    if e.is_Pow and e.exp.is_Integer and e.exp > 0:
        lo, hi = parts[0]
        n = int(e.exp)
        values = [lo ** n, hi ** n]
        low = 0.0 if (n % 2 == 0 and lo <= 0 <= hi) else min(values)
        return (low, max(values))
    return None
