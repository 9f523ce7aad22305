"""A reduced model prepared for planning: parameter values bound, optionally in velocity
coordinates. The symbolic work the planner needs lives here, in the dynamics layer.

:func:`specialise` is the one entry point::

    fast = specialise(model, velocities=("forward_velocity", "psi_dot", "phi_dot"))
    fast.numeric["rhs"](t, z, u, params)        # params ignored: the values are bound

Parameter binding
-----------------
The derived reduced ODE keeps its parameters symbolic. For planning they are fixed, so their
values are bound into the functions. Two routes, chosen by the model's form:

* **symbolic** (``model.form == "explicit"``, the default when ``form`` is absent): the values,
  as exact rationals, are substituted into the sympy rhs and q̇(z); every component is brought
  to the one trig normal form of the package (:func:`nhgait.dynamics.algebra.trig.trig_normal`: a
  fraction of polynomials in sin/cos of each angle with sin² = 1 − cos²); coefficients below
  1e-13 of the largest of their polynomial are dropped (the round-off left by identities that
  hold for the values only up to float precision, e.g. m r² = J + J_r + 2J_w with r = √2.4),
  the remaining ones are rationalised and the normal form is taken again, which cancels the
  factors the round-off had hidden. The snakeboard's ż then costs 46 SX operations instead
  of 313.
* **numeric** (``model.form == "implicit"``, where ``model.rhs`` is None and ż is solved
  numerically inside ``model.numeric["rhs"]``, or when the symbolic result fails its check):
  the values are substituted into the CasADi functions (constants folded by CasADi), and —
  when the check confirms the model is invariant under its symmetry group, forces included —
  evaluated at the group's identity and moved back (:func:`_at_identity`: ṡ = g(s)ṡ|_{s=0}),
  which folds every trigonometric function of the heading.

Every symbolic result is checked against the numeric route at 50 random states, inputs and
times (relative error ≤ 1e-10; the forces may depend on t); a result that fails is replaced
by the numeric one.

Velocity coordinates
--------------------
``velocities`` names n − k velocity quantities y = Y(q) q̇ that replace the momenta as states,
z = (q, y): ``<coordinate>_dot``, the planar body velocities (:func:`body_velocity`) and
named quantities of a scene that are linear in q̇ (``quantities``: name → sympy expression).
With q̇ = Q(q) P (Q = X K⁻¹, X the constraint-adapted basis, K the reduced metric) and
B = Y Q, the momenta are P = B⁻¹ y and

    q̇ = Q B⁻¹ y,    ẏ = d/dt [Y(q) q̇(q, P)]  along  ż_P = f(z_P, u),  z_P = (q, B⁻¹ y).

Symbolically (explicit models): with v = K⁻¹P and B_v = Y X, y = B_v v and
ẏ = Ḃ_v v + B_v K⁻¹(Ṗ − K̇ v), each component in the normal form above. Numerically: B by
automatic differentiation of q̇ in P, ẏ by a directional derivative (``casadi.jtimes``).
Conditions such as "at rest" or "shape motion periodic" are then bounds on states or linear
rows, which is what makes Ipopt take the iteration counts of a hand-written model.

Cache
-----
Results are cached (:mod:`.cache`) under :func:`cache.make_key` of the model's structural
key, the exact parameter values (``float.hex``), the velocity names and the quantity
expressions; ``make_key`` covers the source of every dynamics module (this one included), so
a change of the code that specialises invalidates the entries without a hand-bumped tag.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction
from typing import Any

import casadi as ca
import numpy as np

from ..errors import ModelError
from .velocity_coordinates import (  # noqa: F401
    BODY_VELOCITIES,
    body_velocity,
    choose_velocities,
    group_matrix,
    row_function,
    velocity_map,
    velocity_measure,
    velocity_problems,
    velocity_rows,
)

__all__ = ["specialise", "SpecialisedModel", "body_velocity", "BODY_VELOCITIES", "velocity_rows",
           "choose_velocities", "model_form"]

_CHECK_SAMPLES = 50
_MIN_SAMPLES = 10       # states at which a route must be compared before it counts as agreeing
_CHOP = 1e-13            # coefficients below this fraction of the largest are round-off
_RATIONAL = 1e-14        # relative distance within which a coefficient is snapped to p/q


def model_form(model) -> str:
    """``"explicit"`` (sympy rhs available) or ``"implicit"`` (numeric rhs only)."""
    form = getattr(model, "form", "explicit")
    if form == "explicit" and getattr(model, "rhs", None) is None:
        return "implicit"
    return form


@dataclass(frozen=True, eq=False)
class SpecialisedModel:
    """A reduced model with its parameter values bound (see the module docstring).

    Same interface as :class:`~nhgait.dynamics.derivation.reduction.ReducedODE` for the OCP layer:
    ``numeric`` (``rhs(t, z, u, params)``, ``qdot(z, params)``, ``state(q, q̇, params)``; the
    ``params`` argument is ignored), ``state_names``, ``system``, ``fiber``, ``shape``. In
    velocity coordinates ``numeric`` also has ``momentum_state(z, params) → (q, P)``.

    Attributes
    ----------
    base : the reduced model (momentum coordinates z = (q, P)).
    numeric : NumericModel with the bound functions; ``numeric.params()`` gives the values.
    route : "symbolic" or "numeric" (see the module docstring).
    velocities : names of the velocity states (empty: the momenta are the states).
    """

    base: Any
    numeric: Any
    route: str
    velocities: tuple = ()

    @property
    def system(self):
        return self.base.system

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.numeric.state_names)

    @property
    def fiber(self) -> tuple[str, ...]:
        return tuple(self.base.fiber)

    @property
    def shape(self) -> tuple[str, ...]:
        """The shape coordinates a planner may move freely: the reduced model's shape without
        the dependent coordinates of kept holonomic constraints (the bicycle's pitch follows
        lean and steer)."""
        dependent = set(self.system.dependent or ())
        return tuple(c for c in self.base.shape if c not in dependent)


@dataclass(frozen=True)
class _Entry:
    """What is cached: the bound functions and the route that made them."""

    numeric: Any
    route: str


# ----------------------------------------------------------------------------- velocity rows
def _momentum_basis(model, params) -> ca.Function:
    """Q(q) with q̇ = Q(q) P (q̇ is linear in the momenta), by automatic differentiation."""
    n, nz = model.system.n, len(model.state_names)
    q, P = ca.SX.sym("q", n), ca.SX.sym("P", nz - n)
    qdot = model.numeric["qdot"](ca.vertcat(q, P), params)
    Q = ca.substitute(ca.jacobian(qdot, P), P, ca.DM.zeros(nz - n))
    return ca.Function("Q", [q], [Q])


# ----------------------------------------------------------------------------- numeric route
def _bind(f: ca.Function, params) -> ca.Function:
    """``f`` with its ``params`` input replaced by constants (same signature, input ignored)."""
    sym = ca.SX if f.is_a("SXFunction") else ca.MX
    ins = [sym.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    args = list(ins)
    if "params" in f.name_in():
        args[f.index_in("params")] = ca.DM(params)
    outs = f.call(args)
    return ca.Function(f.name(), ins, outs, f.name_in(), f.name_out())


def _numeric_bound(model, params) -> dict:
    return {name: _bind(f, params) for name, f in model.numeric.functions.items()}


def _numeric_velocity(model, params, names, quantities) -> dict:
    """Functions of z = (q, y) by automatic differentiation (no sympy; any model form)."""
    n, nz = model.system.n, len(model.state_names)
    nu = len(model.numeric.input_names)
    Yf = row_function(model, names, quantities)
    Qf = _momentum_basis(model, params)
    t, z, u, params_sx = (ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu),
                          ca.SX.sym("params", len(params)))
    q, y = z[:n], z[n:]
    P = ca.solve(ca.mtimes(Yf(q, params), Qf(q)), y)
    zP = ca.vertcat(q, P)
    zs = ca.SX.sym("zP", nz)
    y_of_zP = ca.mtimes(Yf(zs[:n], params), model.numeric["qdot"](zs, params))
    ydot = ca.jtimes(y_of_zP, zs, model.numeric["rhs"](t, zs, u, params))
    ydot = ca.substitute(ydot, zs, zP)
    qdot = model.numeric["qdot"](zP, params)
    qs, qd = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    return {
        "rhs": ca.Function("rhs", [t, z, u, params_sx], [ca.vertcat(qdot, ydot)],
                           ["t", "z", "u", "params"], ["zdot"]),
        "qdot": ca.Function("qdot", [z, params_sx], [qdot], ["z", "params"], ["qdot"]),
        "state": ca.Function("state", [qs, qd, params_sx], [ca.vertcat(qs, ca.mtimes(Yf(qs, params), qd))],
                             ["q", "qdot", "params"], ["z"]),
        "momentum_state": ca.Function("momentum_state", [z, params_sx], [zP], ["z", "params"],
                                      ["z_momentum"]),
    }


# ----------------------------------------------------------------------------- Maggi route
def _maggi_velocity(model, params, names, quantities, basis: str = "chart") -> dict:
    """Functions of z = (q, y) from Maggi's form of the same reduced equations (any model form).

    With X(q) a basis of the allowed velocities (q̇ = X v, v the quasi-velocities; ``basis``
    "chart": the reduction's own, :func:`_body_basis`; "velocities": the basis dual to the
    velocity states, :func:`_velocity_basis`, with v = y),
    p(q, v) = ∂L/∂q̇ at q̇ = X v, the Lagrange–d'Alembert principle projected on X reads

        K v̇ = Xᵀ (τ + ∂L/∂q − (∂p/∂q) q̇),   K = Xᵀ ∂p/∂v = XᵀMX,

    the equations of steps 18–19 in the quasi-velocities v = K⁻¹P (the thesis: the reduced
    constrained Hamiltonian equations equal the Hamel/Maggi equations). Every derivative is
    automatic differentiation of the scalar L — no symbolic inverse, no brackets, no ∂h/∂q
    through K⁻¹ — so the expression is several times smaller than the 20 steps' graph
    (the velocity states y = B_v v, B_v = Y X: ẏ = (∂(B_v v)/∂q) q̇ + B_v v̇). The result is used
    only when it agrees with the 20-step functions at random states (:func:`_build`).
    """
    from ..algebra.symbols import TIME
    from .bridge import to_casadi
    from .linsolve import solve_general, solve_spd
    system = model.system
    n, nz = system.n, len(model.state_names)
    nu = len(model.numeric.input_names)
    t, z, u, params_sx = (ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu),
                          ca.SX.sym("params", len(params)))
    qs, qds = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    subs = {s: float(v) for s, v in zip(system.param_symbols, params, strict=True)}
    syms = [TIME] + list(system.q) + list(system.q_dot) + list(system.input_symbols)
    sx = [t] + [qs[i] for i in range(n)] + [qds[i] for i in range(n)] + [u[i] for i in range(nu)]
    L = to_casadi([system.L.xreplace(subs)], syms, sx)[0]
    tau = ca.vertcat(*to_casadi(list(system.force_vector().xreplace(subs)), syms, sx)) if n else ca.SX(0, 1)
    Yf = row_function(model, names, quantities)
    q, y = z[:n], z[n:]
    if basis == "velocities":
        X = _velocity_basis(model, params, q, names, quantities)
        Bv, v = ca.SX.eye(nz - n), y                                # Y X = I
    else:
        X = _body_basis(model, params, q)
        Bv = ca.mtimes(Yf(q, params), X)
        v = solve_general(Bv, y)
    qdot = ca.mtimes(X, v)
    vs = ca.SX.sym("v", nz - n)
    qdot_v = ca.densify(ca.mtimes(X, vs))        # dense: a row of X may be structurally zero
    at = lambda e: ca.substitute(ca.substitute(e, qs, q), qds, qdot_v)  # noqa: E731  (q̇ = X v)
    mom = at(ca.gradient(L, qds))                                   # p(q, v)
    K = ca.mtimes(X.T, ca.jacobian(mom, vs))
    force = ca.mtimes(X.T, at(tau) + at(ca.gradient(L, qs)) - ca.jtimes(mom, q, ca.mtimes(X, vs)))
    vdot = ca.substitute(solve_spd(K, force), vs, v)                  # K = XᵀMX: LDLᵀ
    ydot = ca.substitute(ca.jtimes(ca.mtimes(Bv, vs), q, ca.mtimes(X, vs)), vs, v) + ca.mtimes(Bv, vdot)
    rhs = ca.cse(ca.vertcat(qdot, ydot))
    fns = _numeric_velocity(model, params, names, quantities)   # state and momentum_state maps
    fns["rhs"] = ca.Function("rhs", [t, z, u, params_sx], [rhs], ["t", "z", "u", "params"], ["zdot"])
    fns["qdot"] = ca.Function("qdot", [z, params_sx], [ca.cse(qdot)], ["z", "params"], ["qdot"])
    return fns


def _velocity_basis(model, params, q, names, quantities):
    """X(q) = diag(g, I) A⁻¹ [0; I] (A = :func:`~.velocity_coordinates.velocity_map`): the basis
    of ker ω with Y X = I, so that the quasi-velocities are the velocity states themselves.
    Regular wherever the velocity states determine the allowed velocities, whatever the
    reduction's pivots (the 3-link snake's chart is singular where the three axles' lines
    meet, α₁ = α₂; with y = (forward_velocity, α̇₁) this basis is regular for |α₁| < π).
    :func:`~nhgait.dynamics.numerics.linsolve.solve_general` eliminates the constant rows of A
    first (a shape rate or, in body velocities, θ̇ and forward_velocity are unit rows)."""
    from .bridge import to_casadi
    from .linsolve import solve_general
    system = model.system
    n, k = system.n, system.k
    A = velocity_map(model, params, names, quantities)(q)
    Xb = solve_general(A, ca.vertcat(ca.SX(k, n - k), ca.SX.eye(n - k)))
    subs = {s: float(v) for s, v in zip(system.param_symbols, params, strict=True)}
    G = group_matrix(model.layout).xreplace(subs)
    G = ca.reshape(ca.vertcat(*to_casadi(list(G.T), list(system.q), [q[i] for i in range(n)])), n, n)
    return ca.mtimes(G, Xb)


def _body_basis(model, params, q):
    """X(q) = diag(g(s), I) X_b(r): a basis of ker ω(q) from the body-frame constraints
    ω_b = (ω_s g, ω_r) of step 5 (``layout.Wb``, a function of the shape alone for a symmetric
    system), with the reduction's pivots: X_b[free] = I, X_b[pivots] = −ω_b,piv⁻¹ ω_b,free
    (:func:`~nhgait.dynamics.numerics.linsolve.solve_general`: constant pivots first). Built from the
    k×n matrix ω_b instead of the 20 steps' graph, it stays small for chains of many links."""
    from .bridge import to_casadi
    from .linsolve import solve_general
    layout, system = model.layout, model.system
    n, k = system.n, system.k
    subs = {s: float(v) for s, v in zip(system.param_symbols, params, strict=True)}
    qs = [q[i] for i in range(n)]
    pivots = list(layout.pivots)
    free = [i for i in range(n) if i not in pivots]
    Xb = ca.SX(n, n - k)
    for j, i in enumerate(free):
        Xb[i, j] = 1
    if k:
        Wb = ca.reshape(ca.vertcat(*to_casadi(list(layout.Wb.xreplace(subs).T), list(system.q), qs)), k, n)
        Xb[pivots, :] = -solve_general(Wb[:, pivots], Wb[:, free])
    G = ca.SX.eye(n)
    if layout.version == "B":
        g = ca.reshape(ca.vertcat(*to_casadi(list(layout.g.T), list(system.q), qs)), len(layout.si),
                       len(layout.si))
        G[list(layout.si), list(layout.si)] = g
    return ca.mtimes(G, Xb)


# ----------------------------------------------------------------------------- symbolic route
def _exact(value: float):
    """A float as an exact rational: p/q with q ≤ 10⁶ when that is within 1e-14, else its
    binary value."""
    import sympy as sp
    f = Fraction(value).limit_denominator(10**6)
    if abs(float(f) - value) > _RATIONAL * abs(value):
        f = Fraction(value)
    return sp.Rational(f.numerator, f.denominator)


def _clean_polynomial(poly):
    """``poly`` with round-off removed: terms below ``_CHOP`` of the largest dropped, and in
    each group of terms sharing one monomial of the non-trig symbols (states, inputs) the
    coefficients snapped to p/q relative to the group's largest, which is kept as a factor.

    A factor such as (cos²φ + 5/2) that the exact values would share between numerator and
    denominator is then exact in every group, so the next normal form cancels it.
    """
    import sympy as sp
    terms = [t.as_coeff_Mul() for t in sp.Add.make_args(sp.expand(poly))]
    big = max((abs(float(c)) for c, _ in terms), default=0.0)
    if big == 0.0:
        return sp.S.Zero
    groups: dict = {}
    for c, mono in terms:
        if abs(float(c)) <= _CHOP * big:
            continue
        factors = sp.Mul.make_args(mono)
        key = sp.Mul(*[f for f in factors if not f.has(sp.sin, sp.cos)])
        groups.setdefault(key, []).append((c, mono))
    out = []
    for members in groups.values():
        scale = max(members, key=lambda cm: abs(float(cm[0])))[0]
        out.append(scale * sp.Add(*[_exact(float(c / scale)) * m for c, m in members]))
    return sp.Add(*out)


def _normal(expr):
    """The trig normal form, round-off coefficients removed, and the normal form again."""
    import sympy as sp

    from ..algebra.trig import trig_normal
    e = trig_normal(expr)
    if e == 0:
        return e
    num, den = sp.fraction(e)
    num, den = _clean_polynomial(num), _clean_polynomial(den)
    if num == 0:
        return sp.S.Zero
    return trig_normal(num / den)


def _symbolic_momentum(model, params) -> dict:
    """rhs and q̇ of z = (q, P) with the values substituted, in normal form."""
    from ..algebra.symbols import TIME
    from .bridge import to_casadi
    system = model.system
    subs = {s: _exact(float(v)) for s, v in zip(system.param_symbols, params, strict=True)}
    rhs = [_normal(e.xreplace(subs)) for e in model.rhs]
    qdot = [_normal(e.xreplace(subs)) for e in model.qdot]
    nz, nu, npar = len(model.state), len(system.input_symbols), len(system.param_symbols)
    t, z, u, params_sx = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("params", npar)
    syms = [TIME] + list(model.state) + list(system.input_symbols)
    sx = [t] + [z[i] for i in range(nz)] + [u[i] for i in range(nu)]
    fns = _numeric_bound(model, params)
    fns["rhs"] = ca.Function("rhs", [t, z, u, params_sx], [ca.vertcat(*to_casadi(rhs, syms, sx))],
                             ["t", "z", "u", "params"], ["zdot"])
    fns["qdot"] = ca.Function("qdot", [z, params_sx], [ca.vertcat(*to_casadi(qdot, syms, sx))],
                              ["z", "params"], ["qdot"])
    return fns


def _symbolic_velocity(model, params, names, quantities) -> dict:
    """The velocity-coordinate ODE in normal form (see the module docstring)."""
    import sympy as sp

    from ..algebra.symbols import TIME
    from .bridge import to_casadi
    system = model.system
    n, nv = system.n, len(model.state) - system.n
    subs = {s: _exact(float(v)) for s, v in zip(system.param_symbols, params, strict=True)}
    norm = lambda M: M.applyfunc(_normal)  # noqa: E731
    q, P = list(model.state[:n]), list(model.state[n:])
    K, X = norm(model.K.xreplace(subs)), norm(model.X.xreplace(subs))
    Y = velocity_rows(system, names, quantities).xreplace(dict(zip(system.q, q, strict=True))).xreplace(subs)
    ys, vs = sp.Matrix(sp.symbols(f"_y0:{nv}")), sp.Matrix(sp.symbols(f"_v0:{nv}"))
    B = norm(Y * X)                                                   # y = B v, v = K⁻¹P
    Binv, Kinv = norm(B.inv(method="LU")), norm(K.inv(method="LU"))
    qdot_v = list(X * vs)
    Pdot = sp.Matrix([_normal(e.xreplace(subs)).xreplace(dict(zip(P, K * vs, strict=True)))
                      for e in model.rhs[n:]])
    Kdot, Bdot = sp.zeros(nv, nv), sp.zeros(nv, nv)
    for i, qi in enumerate(q):
        Kdot += K.diff(qi) * qdot_v[i]
        Bdot += B.diff(qi) * qdot_v[i]
    ydot = Bdot * vs + B * (Kinv * (Pdot - Kdot * vs))
    back = dict(zip(vs, Binv * ys, strict=True))
    qdot = [_normal(e.xreplace(back)) for e in qdot_v]
    ydot = [_normal(e.xreplace(back)) for e in ydot]
    nz, nu, npar = n + nv, len(system.input_symbols), len(system.param_symbols)
    t, z, u, params_sx = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("params", npar)
    sx = [t] + [z[i] for i in range(nz)] + [u[i] for i in range(nu)]
    out = to_casadi(qdot + ydot, [TIME] + q + list(ys) + list(system.input_symbols), sx)
    fns = _numeric_velocity(model, params, names, quantities)   # state and momentum_state maps
    fns["rhs"] = ca.Function("rhs", [t, z, u, params_sx], [ca.vertcat(*out)],
                             ["t", "z", "u", "params"], ["zdot"])
    fns["qdot"] = ca.Function("qdot", [z, params_sx], [ca.vertcat(*out[:n])], ["z", "params"], ["qdot"])
    return fns


def _at_identity(model, fns: dict) -> dict | None:
    """rhs and q̇ evaluated at the identity of the symmetry group (fiber coordinates s = 0) and
    moved back by it: ṡ = g(s) ṡ|_{s=0}, everything else as at s = 0.

    For a model whose L, ω and forces are invariant under the group acting on the fiber (the
    reduction's symmetry, thesis §3.2.1; version A translations, version B the planar
    rotation g(θ) of eqs. 3.34/3.70), the reduced dynamics depend on the shape r and the
    momenta only, and ξ = g⁻¹ṡ does too. Setting s = 0 before evaluating lets CasADi fold every
    sin θ, cos θ of the heading (snake_3: 1931 → ~1050 operations). Forces that break the
    symmetry (a world-frame force) make the result differ: :func:`_agrees` then keeps the
    general functions. None when the model has no group layout.
    """
    from .bridge import to_casadi
    layout = getattr(model, "layout", None)
    if layout is None or not layout.fiber:
        return None
    system = model.system
    n, nz = system.n, len(model.state_names)
    si = [system.coordinates.index(c) for c in layout.fiber]
    rhs, qdot = fns["rhs"], fns["qdot"]
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", rhs.size1_in(2))
    params_sx = ca.SX.sym("params", rhs.size1_in(3))
    at_e = ca.vertcat(*[0 if i in si else z[i] for i in range(nz)])
    G = ca.reshape(ca.vertcat(*to_casadi(list(layout.g.T), list(system.q), [z[i] for i in range(n)])),
                   len(si), len(si)) if layout.version == "B" else ca.SX.eye(len(si))

    def moved(v):
        out = [v[i] for i in range(v.shape[0])]
        s_rates = ca.mtimes(G, ca.vertcat(*[v[i] for i in si]))
        for j, i in enumerate(si):
            out[i] = s_rates[j]
        return ca.cse(ca.vertcat(*out))
    out = dict(fns)
    out["rhs"] = ca.Function("rhs", [t, z, u, params_sx], [moved(rhs(t, at_e, u, params_sx))],
                             ["t", "z", "u", "params"], ["zdot"])
    out["qdot"] = ca.Function("qdot", [z, params_sx], [moved(qdot(at_e, params_sx))],
                              ["z", "params"], ["qdot"])
    return out


def _gap(a, b) -> float:
    """max |a − b| / (1 + |b|); entries non-finite in both count as equal, in one only as ∞."""
    a, b = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    fa, fb = np.isfinite(a), np.isfinite(b)
    if np.any(fa != fb):
        return np.inf
    return float(np.max(np.abs(a[fb] - b[fb]) / (1.0 + np.abs(b[fb])), initial=0.0))


@dataclass(frozen=True, eq=False)
class _Reference:
    """What every specialisation must reproduce: ``functions`` (rhs and qdot with the values
    bound, the 20-step graph), the sizes of the state and the inputs, the parameter values and
    the model's measure of its singular set (a function of (q, params) in [0, 1]; None when the
    model has none)."""

    functions: dict
    n_state: int
    n_inputs: int
    params: np.ndarray
    singular: object = None


def _agrees(fns: dict, reference: _Reference, tol: float = 1e-10) -> bool:
    """Whether :func:`_compare` finds ``fns`` within ``tol`` of the reference at no fewer than
    :data:`_MIN_SAMPLES` states (no usable state is no evidence: a reduction whose chart is
    singular everywhere once let every candidate through, a wrong one among them)."""
    worst, used = _compare(fns, reference)
    return bool(used >= _MIN_SAMPLES and worst <= tol)


def _compare(fns: dict, reference: _Reference) -> tuple:
    """(largest gap, states used) between ``fns`` and the reference (rhs and q̇) at random states,
    inputs and times t ∈ [0, 10] (the forces may depend on t), relative to 1 + |reference|. With the
    singular-set measure, states within 1e-3 of that set are not used, and within 0.1 the tolerance
    grows as 0.1/measure: both sides solve the same ill-conditioned systems there, and their round-off
    grows with the condition number (snake_4: gaps of 6e-10 at measure 1.5e-3 between two
    correct evaluations, against O(1) for a wrong formula)."""
    ref, nz, nu = reference.functions, reference.n_state, reference.n_inputs
    params, singular = reference.params, reference.singular
    rng = np.random.default_rng(0)
    worst, used = 0.0, 0
    n = singular.size1_in(0) if singular is not None else nz
    # first the configuration q = 0 (where tasks start: straight chains, zero angles), at which a
    # symbolic QR may divide 0 by 0 although the matrix it factorises is regular
    special = [np.zeros(nz), np.concatenate([np.zeros(n), rng.uniform(-1.2, 1.2, nz - n)])]
    for k in range(4 * _CHECK_SAMPLES):
        t, z, u = rng.uniform(0.0, 10.0), rng.uniform(-1.2, 1.2, nz), rng.normal(size=nu)
        z = special[k] if k < len(special) else z
        measure = 1.0 if singular is None else float(singular(z[:n], params))
        if not measure > 1e-3:
            continue
        scale = max(1.0, 0.1 / measure)
        with np.errstate(all="ignore"):
            if k < len(special) and not np.all(np.isfinite(np.asarray(ref["rhs"](t, z, u, params)))):
                continue                          # q = 0 is singular for the reference itself
        for name, args in (("rhs", (t, z, u)), ("qdot", (z,))):
            worst = max(worst, _gap(fns[name](*args, params), ref[name](*args, params)) / scale)
        used += 1
        if used == _CHECK_SAMPLES:
            break
    return worst, used


# ----------------------------------------------------------------------------- entry point
def _build(model, params, velocities, quantities) -> _Entry:
    n = model.system.n
    graph = (_numeric_velocity(model, params, velocities, quantities) if velocities
             else _numeric_bound(model, params))
    reference = _Reference(graph, len(model.state_names), len(model.numeric.input_names), params,
                           model.numeric.functions.get("singular"))
    route, fns = "numeric", graph
    if model_form(model) == "explicit":
        try:
            candidate = (_symbolic_velocity(model, params, velocities, quantities) if velocities
                         else _symbolic_momentum(model, params))
        except (ZeroDivisionError, ArithmeticError, ValueError):
            candidate = None
        if candidate is not None and _agrees(candidate, reference):
            route, fns = "symbolic", candidate
    if route == "numeric":
        route, fns = _cheapest(model, velocities, quantities, reference)
    if velocities:
        fns = {**fns, **_measures(model, params, velocities, quantities, chart="velocity basis" not in route)}
    from .numeric_model import NumericModel
    old = model.numeric
    if "holonomic" in old.functions:                # h(q): the same in every route
        fns = {**fns, "holonomic": _bind(old["holonomic"], params)}
    state_names = ((tuple(model.system.coordinates) + tuple(velocities)) if velocities
                   else tuple(old.state_names))
    numeric = NumericModel(formulation="reduced-velocity" if velocities else old.formulation,
                           state_names=state_names, input_names=old.input_names,
                           param_names=old.param_names, param_defaults=tuple(float(v) for v in params),
                           functions=fns, n_coordinates=n)
    return _Entry(numeric, route)


def _measures(model, params, velocities, quantities, chart: bool) -> dict:
    """The regularity functions of a velocity-coordinate route, of (q, params):

    * ``velocity_map`` — A(q) = [ω_b; Y_b] (n × n; :func:`~.velocity_coordinates.velocity_map`):
      the velocity states determine q̇ where det A ≠ 0 (its sign tells the two sides apart);
    * ``singular`` ∈ [0, 1], 0 exactly where ż is singular: the normalised |det A|, and for a
      route through the reduction's basis (``chart``) also the chart's own measure.
    """
    n = model.system.n
    q, params_sx = ca.SX.sym("q", n), ca.SX.sym("params", len(params))
    A = velocity_map(model, params, velocities, quantities)(q)
    measure = velocity_measure(A)
    base = model.numeric.functions.get("singular")
    if chart and base is not None:
        measure = ca.fmin(measure, base(q, ca.DM(params)))
    return {"velocity_map": ca.Function("velocity_map", [q, params_sx], [A], ["q", "params"], ["A"]),
            "singular": ca.Function("singular", [q, params_sx], [measure], ["q", "params"], ["measure"])}


def _operations(fns: dict) -> int:
    return int(fns["rhs"].n_instructions())


def _cheapest(model, velocities, quantities, reference: _Reference) -> tuple:
    """(route, functions): the cheapest evaluation of the reference's equations among the
    20-step graph with values bound, Maggi's form (velocity states only) and either evaluated
    at the group identity — each checked against the reference at random states."""
    options = [("numeric", reference.functions)]
    if velocities and "basis" in model.numeric.functions:
        basis = _maggi_velocity(model, reference.params, velocities, quantities, basis="velocities")
        if _compare(basis, reference)[1] < _MIN_SAMPLES:
            # the 20-step graph is singular almost everywhere (its chart's pivot block is; the
            # velocity states are regular): Maggi in the velocity basis, from L and ω alone, is
            # the reference its variants must reproduce
            reference = replace(reference, functions=basis, singular=None)
            options = []
        options.append(("Maggi", _maggi_velocity(model, reference.params, velocities, quantities)))
        options.append(("Maggi in the velocity basis", basis))
    for name, fns in list(options):
        reduced = _at_identity(model, fns)
        if reduced is not None:
            options.append((f"{name} at the group identity", reduced))
    # the velocity basis first: its singular set is the velocity states' own (where they stop
    # determining q̇), a subset of every other route's (which adds the chart's)
    options.sort(key=lambda item: ("velocity basis" not in item[0], _operations(item[1])))
    for name, fns in options:
        if fns is reference.functions or _agrees(fns, reference):
            return name, fns
    return "numeric", reference.functions


def _key(model, params, velocities, quantities) -> str:
    import sympy as sp

    from . import cache
    structure = cache.cache_key(model.system, "reduced", f"version={getattr(model, 'version', None)}")
    qtext = ";".join(f"{k}={sp.srepr(v)}" for k, v in sorted((quantities or {}).items()) if k in velocities)
    return cache.make_key("specialised", structure, f"form={model_form(model)}",
                          "params=" + ",".join(float(v).hex() for v in params),
                          "velocities=" + ",".join(velocities), "quantities=" + qtext)


def specialise(model, params=None, *, velocities=(), quantities=None,
               use_cache: bool = True) -> SpecialisedModel:
    """``model`` (a reduced ODE) with its parameter values bound, optionally in velocity
    coordinates ``velocities`` (n − k names; see the module docstring).

    Parameters
    ----------
    model : ReducedODE (explicit or implicit form)
    params : mapping or vector of parameter values (default: the model's values)
    velocities : sequence of names, empty for the momentum coordinates z = (q, P)
    quantities : mapping name → sympy expression of (q, q̇, parameters), the scene's
        ``[quantities]``, usable as velocity names when linear in q̇
    use_cache : read and write the on-disk cache
    """
    from . import cache
    params = np.asarray(model.numeric.params(params), dtype=float)
    velocities = tuple(velocities or ())
    quantities = dict(quantities or {})
    nv = len(model.state_names) - model.system.n
    if velocities:
        problems = velocity_problems(model.system, velocities, quantities)
        if len(velocities) != nv:
            problems.append(f"velocities: {model.system.name} needs {nv} velocity quantities (one per "
                            f"reduced momentum), got {len(velocities)}")
        if problems:
            raise ModelError(problems, title="invalid velocity coordinates")
        _check_rank(model, params, velocities, quantities)
    key = _key(model, params, velocities, quantities)
    entry = cache.load(key, _Entry) if use_cache else None
    if entry is None:
        entry = _build(model, params, velocities, quantities)
        if use_cache:
            cache.store(key, entry)
    return SpecialisedModel(model, entry.numeric, entry.route, velocities)


def _check_rank(model, params, velocities, quantities):
    """ModelError unless ``velocities`` determine the allowed velocities at generic
    configurations: A(q) = [ω_b; Y_b] (:func:`~.velocity_coordinates.velocity_map`, n × n,
    finite everywhere) regular at three seeded random q. Tested on A and not on Y X, whose
    basis X of the reduction's chart is not finite on the chart's singular set (a random q of a
    5-link chain landed there: a non-finite Y X, and numpy's SVD raised LinAlgError)."""
    A = velocity_map(model, params, velocities, quantities)
    rng = np.random.default_rng(0)
    for _ in range(3):
        qq = rng.uniform(-0.7, 0.7, model.system.n)
        s = np.linalg.svd(np.asarray(A(qq), float), compute_uv=False)
        if not s[-1] > 1e-8 * max(s[0], 1.0):
            raise ModelError([f"velocities {tuple(velocities)} do not parametrise the allowed velocities "
                              "([ω; Y] is singular)"], title="invalid velocity coordinates")
