"""Numeric functions of each formulation: CasADi SX Functions (expanded, small) with numpy
wrappers. Compiled once per derived model and cached with it (see :mod:`.cache`).

Every function takes the parameter vector ``params`` in the order of
``System.param_symbols`` and the input vector ``u`` in the order of ``System.inputs``.

Reduced ODE (z = (q, P, P̃)):
    rhs(t, z, u, params) → ż;  jacobian(t, z, u, params) → (∂ż/∂z, ∂ż/∂u);
    qdot(z, params) → q̇;  qddot(t, z, u, params) → q̈;  state(q, q̇, params) → z;
    energy(z, params) → h;  power(t, z, u, params) → τ·q̇;  singular(q, params) → normalised
    measure of every matrix the reduction inverts (pivot block of ω, Gram of ω_s, basis N),
    in [0, 1], 0 exactly on the singular set;  basis(z, params) → X(q);
    structure(z, params) → J_z.
Lagrangian DAE (x = (q, q̇), λ):
    ode(t, x, u, params) → (ẋ, λ)  [index reduction: λ solved from ωq̈ + ω̇q̇ = 0];
    dae_f(t, x, λ, u, params) → ẋ;  dae_g(t, x, λ, u, params) → ωq̈ + ω̇q̇ (index-1 algebraic);
    energy(x, params);  power(t, x, u, params) → τ·q̇;  constraint(x, params) → ωq̇;  qdot(x, params);
    mass(x, params) → M(q).
Hamiltonian DAE (x = (q, p), λ): the same names, with the algebraic equation d/dt(ω∂H/∂p) = 0.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import casadi as ca
import numpy as np
import sympy as sp

from ..derivation.system import TIME as TIME_SYM
from .bridge import to_casadi


@dataclass(frozen=True, eq=False)
class NumericModel:
    """CasADi Functions of one formulation plus the orderings needed to call them."""

    formulation: str
    state_names: tuple
    input_names: tuple
    param_names: tuple
    param_defaults: tuple
    functions: dict = field(repr=False)
    n_coordinates: int = 0
    n_multipliers: int = 0

    def with_defaults(self, values) -> "NumericModel":
        """The same compiled functions with other default parameter values (a structure is
        compiled once; each system binds its own values)."""
        values = tuple(float(v) for v in values)
        if len(values) != len(self.param_names):
            from ..errors import ModelError
            raise ModelError([f"expected {len(self.param_names)} parameter values, got {len(values)}"])
        return replace(self, param_defaults=values)

    def params(self, values=None) -> np.ndarray:
        """Parameter vector: defaults overridden by a mapping ``values``."""
        vec = np.array(self.param_defaults, dtype=float)
        if values is None:
            return vec
        if isinstance(values, dict):
            for k, v in values.items():
                if k not in self.param_names:
                    from ..errors import ModelError
                    from nhgait.dynamics.suggestions import known_names
                    raise ModelError([f"unknown parameter {k!r}{known_names(k, self.param_names, label='parameters')}"])
                vec[self.param_names.index(k)] = float(v)
            return vec
        arr = np.asarray(values, dtype=float).ravel()
        if arr.size != vec.size:
            from ..errors import ModelError
            raise ModelError([f"expected {vec.size} parameter values, got {arr.size}"])
        return arr

    def __getitem__(self, name) -> ca.Function:
        return self.functions[name]

    def call(self, name, *args):
        """Evaluate function ``name`` with numpy arguments; returns numpy arrays."""
        out = self.functions[name](*args)
        if isinstance(out, (list, tuple)):
            return tuple(_to_numpy(o) for o in out)
        return _to_numpy(out)

    # pickling through CasADi's own serialisation
    def __getstate__(self):
        state = dict(self.__dict__)
        state["functions"] = {k: f.serialize() for k, f in self.functions.items()}
        return state

    def __setstate__(self, state):
        state = dict(state)
        state["functions"] = {k: ca.Function.deserialize(s) for k, s in state["functions"].items()}
        self.__dict__.update(state)


def _to_numpy(o):
    a = o.full() if hasattr(o, "full") else np.asarray(o, dtype=float)
    if a.shape == (1, 1):
        return a[0, 0]
    if a.ndim == 2 and a.shape[1] == 1:
        return a[:, 0]
    return a


def _time_inputs_params(system):
    """CasADi symbols of the time t, the inputs u and the parameters (``System.param_symbols``)."""
    t = ca.SX.sym("t")
    u = ca.SX.sym("u", len(system.input_symbols))
    params = ca.SX.sym("params", len(system.param_symbols))
    return t, u, params


def _conv(exprs, sym_list, sx_list):
    return to_casadi(list(exprs), sym_list, sx_list)


def _base(system, formulation, state_names, functions, n_mult=0):
    return NumericModel(formulation=formulation, state_names=tuple(state_names),
                        input_names=tuple(system.inputs),
                        param_names=tuple(s.name for s in system.param_symbols),
                        param_defaults=tuple(system.param_values), functions=functions,
                        n_coordinates=system.n, n_multipliers=n_mult)


def _absdet(A):
    """|det A| of a small square SX matrix (cofactors up to 3×3, else the QR factor)."""
    if A.shape[0] <= 3:
        return ca.fabs(ca.det(A))
    _, R = ca.qr(A)
    out = 1
    for i in range(A.shape[0]):
        out = out * ca.fabs(R[i, i])
    return out


def _normalised_det(B, rows):
    """|det B| / Π‖row of ``rows``‖ ∈ [0, 1] (Hadamard; B a block of ``rows``), 0 exactly
    where B is singular."""
    norm = 1
    for i in range(rows.shape[0]):
        norm = norm * ca.norm_2(rows[i, :].T)
    return _absdet(B) / (norm + 1e-300)


def singular_measure(layout, conv):
    """Normalised measure of every matrix the reduction inverts (thesis steps 3–6): the pivot
    block B of ω, the Gram matrix of ω_s (when the fiber takes every constraint) and the basis
    N of S_q (K_Ω = NᵀM_ssN is singular exactly where N loses rank). Their minimum: 0 exactly
    on the singular set, 1 for orthogonal rows. ``conv`` maps a sympy Matrix to SX."""
    k, si = layout.k, list(layout.si)
    parts = []
    if k:
        W = layout.W
        if layout.uses_pivot_block:
            Wb = conv(layout.Wb)
            parts.append(_normalised_det(Wb[:, list(layout.pivots)], Wb))
        if not layout.dependent:
            Ws = conv(W.extract(list(range(k)), si))
            G = ca.mtimes(Ws, Ws.T)
            norm = 1
            for i in range(k):
                norm = norm * G[i, i]
            parts.append(ca.fabs(ca.det(G) if k <= 3 else _absdet(G)) / (norm + 1e-300))
    if layout.d and layout.d < len(si):
        N = conv(layout.N)
        G = ca.mtimes(N.T, N)
        norm = 1
        for i in range(layout.d):
            norm = norm * G[i, i]
        parts.append(_absdet(G) / (norm + 1e-300))
    out = ca.SX(1)
    for part in parts:                  # a part that is not finite (0/0 of a factorisation at
        defined = ca.fabs(part) <= 1.0e300   # an exactly singular point) counts as singular:
        out = ca.fmin(out, ca.if_else(defined, part, 0.0))   # fmin alone would drop a NaN
    return out


def _matrix_converter(syms, sx):
    def conv(A):
        if A.shape[0] == 0 or A.shape[1] == 0:
            return ca.SX(A.shape[0], A.shape[1])
        return ca.reshape(ca.vertcat(*_conv(list(A.T), syms, sx)), A.shape[0], A.shape[1])
    return conv


def _reduced_functions(model, t, z, u, params, qv, qdv, rhs, qdot, h, P_of_v, X, J_z, sing, tau_z):
    """The Function table shared by both forms (names and signatures of the module docstring)."""
    system = model.system
    qddot = ca.jtimes(qdot, z, rhs)
    W = system.omega()
    map_syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    map_sx = [qv[i] for i in range(system.n)] + [qdv[i] for i in range(system.n)] + [params[i] for i in range(params.shape[0])]
    cons = ca.vertcat(*_conv(list(W * sp.Matrix(system.q_dot)), map_syms, map_sx)) if system.k else ca.SX(0, 1)
    return {
        "rhs": ca.Function("rhs", [t, z, u, params], [rhs], ["t", "z", "u", "params"], ["zdot"]),
        "jacobian": ca.Function("rhs_jacobian", [t, z, u, params], [ca.jacobian(rhs, z), ca.jacobian(rhs, u)],
                                ["t", "z", "u", "params"], ["dfdz", "dfdu"]),
        "qdot": ca.Function("qdot", [z, params], [qdot], ["z", "params"], ["qdot"]),
        "qddot": ca.Function("qddot", [t, z, u, params], [qddot], ["t", "z", "u", "params"], ["qddot"]),
        "energy": ca.Function("energy", [z, params], [h], ["z", "params"], ["h"]),
        "state": ca.Function("state", [qv, qdv, params], [ca.vertcat(qv, P_of_v)], ["q", "qdot", "params"], ["z"]),
        "constraint": ca.Function("constraint", [qv, qdv, params], [cons], ["q", "qdot", "params"], ["residual"]),
        "singular": ca.Function("singular", [qv, params], [sing], ["q", "params"], ["gram"]),
        "power": ca.Function("power", [t, z, u, params], [ca.dot(tau_z, qdot)], ["t", "z", "u", "params"], ["power"]),
        "basis": ca.Function("basis", [z, params], [X], ["z", "params"], ["X"]),
        "structure": ca.Function("structure", [z, params], [J_z], ["z", "params"], ["J_z"]),
    }


def compile_reduced(model, casadi_steps=None) -> NumericModel:
    """CasADi functions of a :class:`~nhgait.dynamics.derivation.reduction.ReducedODE` (either form).

    The explicit form is converted from its sympy expressions; the implicit form needs
    ``casadi_steps``, the outputs of steps 4–20 run on CasADi SX
    (:func:`~nhgait.dynamics.derivation.reduction.pipeline.run_steps`).
    Besides the functions of the module docstring: ``basis(z, params)`` → X(q) and
    ``structure(z, params)`` → J_z (used by :func:`~nhgait.dynamics.derivation.analysis.jacobi_test`)."""
    if model.form == "implicit":
        if casadi_steps is None:
            raise ValueError("the implicit form is compiled from the CasADi run of its steps (casadi_steps)")
        return _implicit_functions(model, casadi_steps)
    system = model.system
    n, nz = system.n, len(model.state)
    t, u, params = _time_inputs_params(system)
    z = ca.SX.sym("z", nz)
    base_syms = [TIME_SYM] + list(model.state) + list(system.input_symbols) + list(system.param_symbols)
    base_sx = [t] + [z[i] for i in range(nz)] + [u[i] for i in range(u.shape[0])] + [params[i] for i in range(params.shape[0])]
    conv_z = _matrix_converter(base_syms, base_sx)
    qv, qdv = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    map_syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    map_sx = [qv[i] for i in range(n)] + [qdv[i] for i in range(n)] + [params[i] for i in range(params.shape[0])]
    conv_q = _matrix_converter(map_syms, map_sx)
    tau_z = conv_z(system.force_vector().xreplace({v: model.qdot[i] for i, v in enumerate(system.q_dot)}))
    fns = _reduced_functions(model, t, z, u, params, qv, qdv, conv_z(model.rhs), conv_z(model.qdot),
                             conv_z(sp.Matrix([model.hamiltonian]))[0], conv_q(model.momenta_of_velocity),
                             conv_z(model.X), conv_z(model.structure), singular_measure(model.layout, conv_q), tau_z)
    return _base(system, "reduced", model.state_names, fns)


def _implicit_functions(model, out) -> NumericModel:
    """The implicit form's functions from the CasADi run of the steps (``out`` of
    :func:`~nhgait.dynamics.derivation.reduction.pipeline.run_steps` on :class:`CasadiArithmetic`)."""
    system, arithmetic = model.system, out.arithmetic
    sym_of = arithmetic.sym
    t = sym_of(TIME_SYM)
    q = ca.vertcat(*[sym_of(s) for s in system.q])
    P = ca.vertcat(*[sym_of(s) for s in model.momenta]) if model.momenta else ca.SX(0, 1)
    z = ca.vertcat(q, P)
    qd = ca.vertcat(*[sym_of(s) for s in system.q_dot])
    u = ca.vertcat(*[sym_of(s) for s in system.input_symbols]) if system.input_symbols else ca.SX(0, 1)
    params = ca.vertcat(*[sym_of(s) for s in system.param_symbols]) if system.param_symbols else ca.SX(0, 1)
    qdot = ca.vertcat(*out.qdot)
    rhs = ca.vertcat(qdot, *out.Pdot) if out.Pdot else qdot
    rhs, qdot = ca.cse(rhs), ca.cse(qdot)
    P_of_v = ca.vertcat(*out.momenta_of_velocity) if out.momenta_of_velocity else ca.SX(0, 1)
    tau = ca.vertcat(*[arithmetic.frac(e) for e in system.force_vector()])
    tau_z = ca.substitute(tau, qd, qdot)

    def conv(A):
        if A.shape[0] == 0 or A.shape[1] == 0:
            return ca.SX(A.shape[0], A.shape[1])
        return ca.reshape(ca.vertcat(*[arithmetic.frac(e) for e in A.T]), A.shape[0], A.shape[1])
    fns = _reduced_functions(model, t, z, u, params, q, qd, rhs, qdot, out.h, P_of_v, out.X, out.J_z,
                             singular_measure(model.layout, conv), tau_z)
    return _base(system, "reduced", model.state_names, fns)


@dataclass(frozen=True, eq=False)
class _DAEExpressions:
    """The CasADi expressions of a DAE form (Lagrange or Hamilton), in (t, x, λ, u, params):
    ẋ with λ solved (index reduction) and λ; ẋ with λ free and the index-1 algebraic equation g;
    the energy, the constraint residual, q̇, the mass matrix M(q) and the input power τ·q̇."""

    xdot: object
    lam: object
    xdot_dae: object
    g: object
    energy: object
    constraint: object
    qdot: object
    mass: object
    power: object


def _dae_functions(symbols, e: _DAEExpressions) -> dict:
    """The Function table of both DAE forms (names and signatures of the module docstring);
    ``symbols`` = (t, x, λ, u, params)."""
    t, x, lam, u, params = symbols
    return {
        "ode": ca.Function("ode", [t, x, u, params], [e.xdot, e.lam], ["t", "x", "u", "params"], ["xdot", "lam"]),
        "jacobian": ca.Function("rhs_jacobian", [t, x, u, params], [ca.jacobian(e.xdot, x), ca.jacobian(e.xdot, u)],
                                ["t", "x", "u", "params"], ["dfdx", "dfdu"]),
        "dae_f": ca.Function("dae_f", [t, x, lam, u, params], [e.xdot_dae], ["t", "x", "lam", "u", "params"], ["xdot"]),
        "dae_g": ca.Function("dae_g", [t, x, lam, u, params], [e.g], ["t", "x", "lam", "u", "params"], ["g"]),
        "energy": ca.Function("energy", [x, params], [e.energy], ["x", "params"], ["E"]),
        "constraint": ca.Function("constraint", [x, params], [e.constraint], ["x", "params"], ["residual"]),
        "qdot": ca.Function("qdot", [x, params], [e.qdot], ["x", "params"], ["qdot"]),
        "mass": ca.Function("mass", [x, params], [e.mass], ["x", "params"], ["M"]),
        "power": ca.Function("power", [t, x, u, params], [e.power], ["t", "x", "u", "params"], ["power"]),
    }


def _dae_symbols(model):
    """(t, x, λ, u, params, conv) of a DAE model: x = (q, q̇) or (q, p) (2n), λ (k), and
    ``conv`` mapping the model's sympy expressions (of t, its state, inputs, parameters) to SX."""
    system = model.system
    t, u, params = _time_inputs_params(system)
    x = ca.SX.sym("x", 2 * system.n)
    lam = ca.SX.sym("lam", system.k)
    syms = [TIME_SYM] + list(model.state) + list(system.input_symbols) + list(system.param_symbols)
    sx = [t] + [x[i] for i in range(x.shape[0])] + [u[i] for i in range(u.shape[0])] + [params[i] for i in range(params.shape[0])]
    return t, x, lam, u, params, lambda exprs: _conv(exprs, syms, sx)


def compile_lagrange(model) -> NumericModel:
    """CasADi functions of a :class:`~nhgait.dynamics.derivation.lagrange.LagrangianDAE`."""
    system = model.system
    n, k = system.n, system.k
    t, x, lam, u, params, conv = _dae_symbols(model)
    M = ca.reshape(ca.vertcat(*conv(list(model.M.T))), n, n)
    F = ca.vertcat(*conv(model.F))
    tau = ca.vertcat(*conv(model.tau))
    E = conv([model.energy])[0]
    qd = x[n:]
    if k:
        W = ca.reshape(ca.vertcat(*conv(list(model.omega.T))), k, n)
        Wdq = ca.vertcat(*conv(model.omega_dot_qdot))
        Minv_f = ca.solve(M, F + tau)
        Minv_Wt = ca.solve(M, W.T)
        S = ca.mtimes(W, Minv_Wt)
        lam_sol = -ca.solve(S, ca.mtimes(W, Minv_f) + Wdq)
        qdd = Minv_f + ca.mtimes(Minv_Wt, lam_sol)
        qdd_dae = ca.solve(M, F + tau + ca.mtimes(W.T, lam))
        g_alg = ca.mtimes(W, qdd_dae) + Wdq
        cons = ca.mtimes(W, qd)
    else:
        lam_sol = ca.SX(0, 1)
        qdd = ca.solve(M, F + tau)
        qdd_dae = qdd
        g_alg = ca.SX(0, 1)
        cons = ca.SX(0, 1)
    xdot = ca.vertcat(qd, qdd)
    fns = _dae_functions((t, x, lam, u, params), _DAEExpressions(
        xdot=xdot, lam=lam_sol, xdot_dae=ca.vertcat(qd, qdd_dae), g=g_alg, energy=E, constraint=cons,
        qdot=qd, mass=M, power=ca.dot(tau, qd)))
    return _base(system, "lagrange", model.state_names, fns, k)


def compile_hamilton(model) -> NumericModel:
    """CasADi functions of a :class:`~nhgait.dynamics.derivation.hamilton.HamiltonianDAE`."""
    system = model.system
    n, k = system.n, system.k
    t, x, lam, u, params, conv = _dae_symbols(model)
    dHdp = ca.vertcat(*conv(model.dH_dp))
    dHdq = ca.vertcat(*conv(model.dH_dq))
    tau = ca.vertcat(*conv(model.tau))
    H = conv([model.H])[0]
    Minv = ca.reshape(ca.vertcat(*conv(list(model.Minv.T))), n, n)
    q_sx = x[:n]
    if k:
        W = ca.reshape(ca.vertcat(*conv(list(model.omega.T))), k, n)
        G = ca.mtimes(W, dHdp)                         # constraint ω ∂H/∂p
        dG_dq = ca.jacobian(G, q_sx)
        WMinv = ca.mtimes(W, Minv)                     # ∂G/∂p
        base = -dHdq + tau
        lam_sol = -ca.solve(ca.mtimes(WMinv, W.T), ca.mtimes(dG_dq, dHdp) + ca.mtimes(WMinv, base))
        pdot = base + ca.mtimes(W.T, lam_sol)
        pdot_dae = base + ca.mtimes(W.T, lam)
        g_alg = ca.mtimes(dG_dq, dHdp) + ca.mtimes(WMinv, pdot_dae)
        cons = G
    else:
        lam_sol = ca.SX(0, 1)
        pdot = -dHdq + tau
        pdot_dae = pdot
        g_alg = ca.SX(0, 1)
        cons = ca.SX(0, 1)
    xdot = ca.vertcat(dHdp, pdot)
    fns = _dae_functions((t, x, lam, u, params), _DAEExpressions(
        xdot=xdot, lam=lam_sol, xdot_dae=ca.vertcat(dHdp, pdot_dae), g=g_alg, energy=H, constraint=cons,
        qdot=dHdp, power=ca.dot(tau, dHdp),
        mass=ca.reshape(ca.vertcat(*conv(list(system.mass_matrix().T))), n, n)))
    return _base(system, "hamilton", model.state_names, fns, k)


