"""Numeric functions of each formulation: CasADi SX Functions (expanded, small) with numpy
wrappers. Compiled once per derived model and cached with it (see :mod:`.cache`).

Every function takes the parameter vector ``params`` in the order of
``System.param_symbols`` and the input vector ``u`` in the order of ``System.inputs``.

Every form, for a system with kept holonomic constraints: holonomic(q, params) → h(q).

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

from ..algebra.symbols import TIME as TIME_SYM
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

    def with_defaults(self, values) -> NumericModel:
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
                    from nhgait.dynamics.suggestions import known_names

                    from ..errors import ModelError
                    raise ModelError(["unknown parameter "
                                      f"{k!r}{known_names(k, self.param_names, label='parameters')}"])
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


def _holonomic_function(system) -> ca.Function:
    """``holonomic(q, params)`` → h(q) of the kept holonomic constraints (c×1)."""
    q, params = ca.SX.sym("q", system.n), ca.SX.sym("params", len(system.param_symbols))
    h = to_casadi(list(system.holonomic), list(system.q) + list(system.param_symbols),
                  [q[i] for i in range(system.n)] + [params[i] for i in range(params.shape[0])])
    return ca.Function("holonomic", [q, params], [ca.vertcat(*h)], ["q", "params"], ["h"])


def _base(system, formulation, state_names, functions, n_mult=0):
    if system.holonomic:
        functions = {**functions, "holonomic": _holonomic_function(system)}
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
        return ca.reshape(ca.vertcat(*to_casadi(list(A.T), syms, sx)), A.shape[0], A.shape[1])
    return conv


@dataclass(frozen=True, eq=False)
class _ReducedSymbols:
    """The CasADi symbols of the reduced functions: time ``t``, state ``z`` = (q, P), inputs
    ``u``, parameters ``params``, and ``q``, ``q_dot`` of the maps from (q, q̇)."""

    t: ca.SX
    z: ca.SX
    u: ca.SX
    params: ca.SX
    q: ca.SX
    q_dot: ca.SX


@dataclass(frozen=True, eq=False)
class _ReducedExpressions:
    """The CasADi expressions of the reduced form: in (t, z, u, params) ż (``rhs``), q̇, the
    Hamiltonian h, the basis X, the structure J_z and the forces τ (velocities replaced by q̇);
    in (q, q̇, params) the momenta P = XᵀMq̇; in (q, params) the singular measure."""

    rhs: ca.SX
    qdot: ca.SX
    hamiltonian: ca.SX
    momenta_of_velocity: ca.SX
    basis: ca.SX
    structure: ca.SX
    singular: ca.SX
    tau: ca.SX


def _reduced_functions(system, symbols: _ReducedSymbols, e: _ReducedExpressions) -> dict:
    """The Function table shared by both forms (names and signatures of the module docstring)."""
    t, z, u, params, q, q_dot = symbols.t, symbols.z, symbols.u, symbols.params, symbols.q, symbols.q_dot
    qddot = ca.jtimes(e.qdot, z, e.rhs)
    W = system.omega()
    map_syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    map_sx = ([q[i] for i in range(system.n)] + [q_dot[i] for i in range(system.n)]
              + [params[i] for i in range(params.shape[0])])
    constraint = (ca.vertcat(*to_casadi(list(W * sp.Matrix(system.q_dot)), map_syms, map_sx)) if system.k
                  else ca.SX(0, 1))
    return {
        "rhs": ca.Function("rhs", [t, z, u, params], [e.rhs], ["t", "z", "u", "params"], ["zdot"]),
        "jacobian": ca.Function("rhs_jacobian", [t, z, u, params],
                                [ca.jacobian(e.rhs, z), ca.jacobian(e.rhs, u)],
                                ["t", "z", "u", "params"], ["dfdz", "dfdu"]),
        "qdot": ca.Function("qdot", [z, params], [e.qdot], ["z", "params"], ["qdot"]),
        "qddot": ca.Function("qddot", [t, z, u, params], [qddot], ["t", "z", "u", "params"], ["qddot"]),
        "energy": ca.Function("energy", [z, params], [e.hamiltonian], ["z", "params"], ["h"]),
        "state": ca.Function("state", [q, q_dot, params], [ca.vertcat(q, e.momenta_of_velocity)],
                             ["q", "qdot", "params"], ["z"]),
        "constraint": ca.Function("constraint", [q, q_dot, params], [constraint], ["q", "qdot", "params"],
                                  ["residual"]),
        "singular": ca.Function("singular", [q, params], [e.singular], ["q", "params"], ["gram"]),
        "power": ca.Function("power", [t, z, u, params], [ca.dot(e.tau, e.qdot)],
                             ["t", "z", "u", "params"], ["power"]),
        "basis": ca.Function("basis", [z, params], [e.basis], ["z", "params"], ["X"]),
        "structure": ca.Function("structure", [z, params], [e.structure], ["z", "params"], ["J_z"]),
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
    state_syms = [TIME_SYM] + list(model.state) + list(system.input_symbols) + list(system.param_symbols)
    state_sx = ([t] + [z[i] for i in range(nz)] + [u[i] for i in range(u.shape[0])]
                + [params[i] for i in range(params.shape[0])])
    of_state = _matrix_converter(state_syms, state_sx)
    q, q_dot = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    map_syms = list(system.q) + list(system.q_dot) + list(system.param_symbols)
    map_sx = ([q[i] for i in range(n)] + [q_dot[i] for i in range(n)]
              + [params[i] for i in range(params.shape[0])])
    of_velocity = _matrix_converter(map_syms, map_sx)
    tau = of_state(system.force_vector().xreplace({v: model.qdot[i] for i, v in enumerate(system.q_dot)}))
    expressions = _ReducedExpressions(
        rhs=of_state(model.rhs), qdot=of_state(model.qdot),
        hamiltonian=of_state(sp.Matrix([model.hamiltonian]))[0],
        momenta_of_velocity=of_velocity(model.momenta_of_velocity), basis=of_state(model.X),
        structure=of_state(model.structure), singular=singular_measure(model.layout, of_velocity), tau=tau)
    functions = _reduced_functions(system, _ReducedSymbols(t, z, u, params, q, q_dot), expressions)
    return _base(system, "reduced", model.state_names, functions)


def _implicit_functions(model, run) -> NumericModel:
    """The implicit form's functions from the CasADi run of the steps (``run`` of
    :func:`~nhgait.dynamics.derivation.reduction.pipeline.run_steps` on :class:`CasadiArithmetic`)."""
    system, arithmetic = model.system, run.arithmetic
    sym_of = arithmetic.sym
    t = sym_of(TIME_SYM)
    q = ca.vertcat(*[sym_of(s) for s in system.q])
    P = ca.vertcat(*[sym_of(s) for s in model.momenta]) if model.momenta else ca.SX(0, 1)
    z = ca.vertcat(q, P)
    q_dot = ca.vertcat(*[sym_of(s) for s in system.q_dot])
    u = ca.vertcat(*[sym_of(s) for s in system.input_symbols]) if system.input_symbols else ca.SX(0, 1)
    params = ca.vertcat(*[sym_of(s) for s in system.param_symbols]) if system.param_symbols else ca.SX(0, 1)
    qdot = ca.vertcat(*run.qdot)
    rhs = ca.vertcat(qdot, *run.Pdot) if run.Pdot else qdot
    rhs, qdot = ca.cse(rhs), ca.cse(qdot)
    P_of_v = ca.vertcat(*run.momenta_of_velocity) if run.momenta_of_velocity else ca.SX(0, 1)
    tau = ca.vertcat(*[arithmetic.frac(e) for e in system.force_vector()])

    def of_variables(A):
        if A.shape[0] == 0 or A.shape[1] == 0:
            return ca.SX(A.shape[0], A.shape[1])
        return ca.reshape(ca.vertcat(*[arithmetic.frac(e) for e in A.T]), A.shape[0], A.shape[1])
    expressions = _ReducedExpressions(
        rhs=rhs, qdot=qdot, hamiltonian=run.h, momenta_of_velocity=P_of_v, basis=run.X, structure=run.J_z,
        singular=singular_measure(model.layout, of_variables), tau=ca.substitute(tau, q_dot, qdot))
    functions = _reduced_functions(system, _ReducedSymbols(t, z, u, params, q, q_dot), expressions)
    return _base(system, "reduced", model.state_names, functions)


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
        "ode": ca.Function("ode", [t, x, u, params], [e.xdot, e.lam], ["t", "x", "u", "params"],
                           ["xdot", "lam"]),
        "jacobian": ca.Function("rhs_jacobian", [t, x, u, params],
                                [ca.jacobian(e.xdot, x), ca.jacobian(e.xdot, u)],
                                ["t", "x", "u", "params"], ["dfdx", "dfdu"]),
        "dae_f": ca.Function("dae_f", [t, x, lam, u, params], [e.xdot_dae],
                             ["t", "x", "lam", "u", "params"], ["xdot"]),
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
    sx = ([t] + [x[i] for i in range(x.shape[0])] + [u[i] for i in range(u.shape[0])]
          + [params[i] for i in range(params.shape[0])])
    return t, x, lam, u, params, lambda exprs: to_casadi(list(exprs), syms, sx)


def compile_lagrange(model) -> NumericModel:
    """CasADi functions of a :class:`~nhgait.dynamics.derivation.lagrange.LagrangianDAE`."""
    system = model.system
    n, k = system.n, system.k
    t, x, lam, u, params, conv = _dae_symbols(model)
    M = ca.reshape(ca.vertcat(*conv(list(model.M.T))), n, n)
    forces = ca.vertcat(*conv(model.F))         # F = ∂L/∂q − (∂²L/∂q̇∂q)q̇ (eq. 2.8)
    tau = ca.vertcat(*conv(model.tau))
    energy = conv([model.energy])[0]
    qd = x[n:]
    if k:
        W = ca.reshape(ca.vertcat(*conv(list(model.omega.T))), k, n)
        Wdq = ca.vertcat(*conv(model.omega_dot_qdot))
        Minv_f = ca.solve(M, forces + tau)
        Minv_Wt = ca.solve(M, W.T)
        S = ca.mtimes(W, Minv_Wt)
        lam_sol = -ca.solve(S, ca.mtimes(W, Minv_f) + Wdq)
        qdd = Minv_f + ca.mtimes(Minv_Wt, lam_sol)
        qdd_dae = ca.solve(M, forces + tau + ca.mtimes(W.T, lam))
        g_alg = ca.mtimes(W, qdd_dae) + Wdq
        cons = ca.mtimes(W, qd)
    else:
        qdd = qdd_dae = ca.solve(M, forces + tau)
        lam_sol = g_alg = cons = ca.SX(0, 1)
    functions = _dae_functions((t, x, lam, u, params), _DAEExpressions(
        xdot=ca.vertcat(qd, qdd), lam=lam_sol, xdot_dae=ca.vertcat(qd, qdd_dae), g=g_alg, energy=energy,
        constraint=cons, qdot=qd, mass=M, power=ca.dot(tau, qd)))
    return _base(system, "lagrange", model.state_names, functions, k)


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
        pdot = pdot_dae = -dHdq + tau
        lam_sol = g_alg = cons = ca.SX(0, 1)
    functions = _dae_functions((t, x, lam, u, params), _DAEExpressions(
        xdot=ca.vertcat(dHdp, pdot), lam=lam_sol, xdot_dae=ca.vertcat(dHdp, pdot_dae), g=g_alg, energy=H,
        constraint=cons, qdot=dHdp, power=ca.dot(tau, dHdp),
        mass=ca.reshape(ca.vertcat(*conv(list(system.mass_matrix().T))), n, n)))
    return _base(system, "hamilton", model.state_names, functions, k)


