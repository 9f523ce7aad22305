"""The reduced constrained Hamiltonian: the 20-step method of thesis §3.2, for any system.

Math (what every step computes; notation of the thesis)
-------------------------------------------------------
Split q = (s, r) with s the fiber coordinates chosen by the symmetry test (steps 2–3) and r the
shape coordinates; l = dim s, m = dim r, d = l − k nonholonomic momenta.

* N(q) (l×d): basis of S_q in the s-components, ξ_Q^q = (N, 0) (step 3, eq. 3.7/3.67).
* Nonholonomic momenta p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ (step 4, eq. 3.9/3.69).
* Reconstruction (step 5, eq. 2.47): the constraints ω_s ṡ + ω_r ṙ = 0 together with the momentum
  definition solve for ṡ = −A_q ṙ + Γ_q p; with ξ = g⁻¹ṡ, ξ = −A(r)ṙ + Γ(r)p, A = g⁻¹A_q,
  Γ = g⁻¹Γ_q. The columns X_α = (−A_q e_α, e_α) are the M-orthogonal (mixed-connection)
  horizontal lifts of ∂/∂r_α.
* Body basis e = g⁻¹N and Ω = K_Ω⁻¹p with K_Ω = NᵀM_ssN, so Γp = eΩ (step 6, eq. 3.72).
* Reduced Lagrangian l(r, ṙ, ξ) = L|_{ṡ=gξ} (step 7) and reduced constrained Lagrangian
  l_c(r, ṙ, Ω) = l|_{ξ=−Aṙ+eΩ} = ½ vᵀKv − V, v = (Ω, ṙ), K = XᵀMX block-diagonal (step 8).
* Legendre transform P = ∂l_c/∂v = Kv (steps 9–10); h = ½ PᵀK⁻¹P + V (step 11).
* P in canonical momenta: P_a = X_aᵀp (steps 12–13); body momentum μ = ∂l/∂ξ = gᵀp_s (step 14).
* Brackets {P_a, P_b} = −pᵀ[X_a, X_b] written in μ (step 15), then restricted to the constraint
  submanifold by μ|_M̄ = gᵀ(M X K⁻¹P)_s (step 16).
* The reduced Poisson-like structure (step 17, Fig. 3.7), with rows (ξ, P, r, P̃):
  [[0, e, 0, −A], [−eᵀ, {P,P}, 0, {P,P̃}], [0, 0, 0, I], [Aᵀ, {P̃,P}, −I, {P̃,P̃}]].
* Equations (steps 18–19): (ξ, Ṗ, ṙ, dP̃/dt) = J_M̄ ∇h + (0, Xᵀτ), with ∇h = (0, ∂h/∂P, ∂h/∂r,
  ∂h/∂P̃); the forces enter through the constraint-adapted basis X, never by hand.
* Reconstruction of the fiber velocities ṡ = gξ (step 20).

The result, 2n − k first-order ODEs in z = (q, P, P̃), equals the Hamel/Maggi equations of
Lagrange–d'Alembert mechanics, which is why it can be checked against KanesMethod.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import sympy as sp

from .errors import ModelError
from .steps import Step, Steps
from .symbolic import FracField, _NotRational, numeric_pivots, strip_factors, tidy
from .symmetry import SymmetryTest, group_transform, omega_samples, symmetry_test
from .system import TIME, System

PURELY_MECHANICAL = "purely mechanical"
PRINCIPALLY_KINEMATIC = "principally kinematic"
PURELY_DYNAMIC = "purely dynamic"
MIXED = "mixed"


@dataclass(frozen=True, eq=False)
class ReducedODE:
    """Reduced constrained Hamiltonian equations ż = f(t, z, u), 2n − k first-order ODEs.

    State ordering (``state_names``): z = (q_1 … q_n in the system's coordinate order,
    P_1 … P_d nonholonomic momenta (named ``p`` or ``p1``, ``p2`` …), P̃_1 … P̃_m shape momenta
    (named ``pt_<shape coordinate>``)). No multipliers appear.

    Attributes
    ----------
    system : System
    version : "A" or "B" — the choice of g in ξ = g⁻¹ṡ (identity, or SE(2)-type rotation).
    fiber, shape : coordinate names s and r.
    state : tuple of Symbols z; momenta : (P…, P̃…) symbols.
    rhs : Matrix (2n−k)×1, ż in state order, in (t, z, u, parameters).
    X : Matrix n×(n−k), the constraint-adapted velocity basis: q̇ = X K⁻¹ P.
    K : Matrix, the reduced kinetic metric XᵀMX (block-diagonal: nonholonomic, shape).
    hamiltonian : h(q, P) (step 11).
    structure : Matrix, the Poisson-like structure J in z-coordinates, ż = J∇h + (0, Xᵀτ).
    qdot : Matrix n×1, q̇ as a function of z (reconstruction).
    momenta_of_velocity : Matrix (n−k)×1, P = XᵀM(q)q̇ (the thesis's Table 3.2/3.3 map).
    classification : thesis Table 2.1 type.
    singular_set : tuple of expressions; the reduction is singular where any of them is 0.
    steps : the 20 steps, each inspectable (``steps.get(17)['J']``).
    symmetry : the symmetry test (Table 3.1 for this system).
    """

    system: System
    version: str
    fiber: tuple
    shape: tuple
    state: tuple
    state_names: tuple
    momenta: tuple
    rhs: sp.Matrix
    X: sp.Matrix
    K: sp.Matrix
    hamiltonian: sp.Expr
    structure: sp.Matrix
    qdot: sp.Matrix
    momenta_of_velocity: sp.Matrix
    classification: str
    singular_set: tuple
    steps: Steps
    symmetry: SymmetryTest
    derive_time_s: float = 0.0
    symbol_names: dict = field(default_factory=dict, repr=False)

    formulation = "reduced"

    @property
    def dimension(self) -> int:
        return len(self.state)

    def equations(self) -> list:
        """The equations ż = f as sympy Eq objects (time derivatives written as ``<z>_dot``)."""
        return [sp.Eq(sp.Symbol(f"{nm}_dot"), e) for nm, e in zip(self.state_names, self.rhs)]

    def pretty_rhs(self) -> list:
        """ż with every coefficient of the momentum/input monomials factored (for display)."""
        gens = list(self.momenta) + list(self.system.input_symbols)
        out = []
        for e in self.rhs:
            e = sp.expand(e)
            try:
                poly = sp.Poly(e, *gens)
                terms = [sp.factor(c) * sp.Mul(*[g ** k for g, k in zip(gens, mon)]) for mon, c in poly.terms()]
                out.append(sp.Add(*terms))
            except sp.PolynomialError:
                out.append(e)
        return out

    def to_text(self, pretty: bool = True) -> str:
        lines = [f"Reduced constrained Hamiltonian equations of {self.system.name} "
                 f"({self.dimension} = 2n − k first-order ODEs, version {self.version}, "
                 f"fiber s = ({', '.join(self.fiber)}), shape r = ({', '.join(self.shape)}), "
                 f"{self.classification})",
                 f"  state z = ({', '.join(self.state_names)})"]
        for nm, e in zip(self.state_names, self.pretty_rhs() if pretty else self.rhs):
            lines.append(f"  d{nm}/dt = {sp.sstr(e)}")
        return "\n".join(lines)

    @cached_property
    def numeric(self):
        """CasADi/numpy functions of this model (see :mod:`nhgait.dynamics.numeric`)."""
        from .numeric import compile_reduced
        return compile_reduced(self)


def _sym(name):
    return sp.Symbol(name, real=True)


def _embed(N, si, n):
    out = sp.zeros(n, N.shape[1])
    for a, i in enumerate(si):
        out[i, :] = N[a, :]
    return out


def _col(symbols):
    return sp.Matrix(symbols) if len(symbols) else sp.zeros(0, 1)


def _linear_tidy(expr, variables):
    """Tidy an expression linear in ``variables`` coefficient by coefficient."""
    expr = sp.expand(expr)
    out = tidy(expr.xreplace({v: 0 for v in variables}))
    for v in variables:
        c = expr.coeff(v)
        if c != 0:
            out += tidy(c) * v
    return out


def _quadratic(Q, variables):
    """vᵀQv for a symmetric coefficient matrix Q, as a sum of tidy coefficients × monomials."""
    out = sp.Integer(0)
    nv = len(variables)
    for i in range(nv):
        for j in range(i, nv):
            c = Q[i, j] if i == j else Q[i, j] + Q[j, i]
            if c != 0:
                out += tidy(c) * variables[i] * variables[j]
    return out


def derive_reduced(system: System, version: str | None = None) -> ReducedODE:
    """Run the 20 steps for ``system`` and return the :class:`ReducedODE`.

    Parameters
    ----------
    version : "A", "B" or None
        g = identity (A) or the SE(2)-type rotation (B, needs a planar frame with x, y in the
        fiber). None: B when available, else A.

    The intermediate quantities are kept as fractions of one polynomial ring per derivation
    (:class:`~nhgait.dynamics.symbolic.FracField`) and normalised exactly as :func:`tidy` would;
    systems with expressions outside that field use the plain sympy version.
    """
    try:
        return _derive_reduced_field(system, version)
    except _NotRational:
        return _derive_reduced_plain(system, version)


def _set_up(system: System, version):
    """Steps 1–3 (set-up, D_q, the full symmetry group) and the choice of g; shared by both
    derivation paths."""
    t0 = time.perf_counter()
    n, k = system.n, system.k
    q, qd = list(system.q), list(system.q_dot)
    names = system.coordinates
    M = tidy(system.mass_matrix())
    V = system.potential()
    W = system.omega()
    L = system.L
    tau_raw = system.force_vector()
    steps: list[Step] = []

    # ---- step 1: set-up -----------------------------------------------------------------
    steps.append(Step(1, "Set-up", "§3.2.1, Fig. 3.3", {
        "q": sp.Matrix(q).T, "L": L, "omega": W, "tau": tau_raw.T, "M": M, "V": V,
        "parameters": ", ".join(f"{k_}={v}" for k_, v in system.parameters.items())},
        "Coordinates, Lagrangian, Pfaffian constraints ω(q)q̇ = 0, forces and parameters."))

    # ---- steps 2–3: distribution and full symmetry group ------------------------------------
    sym = symmetry_test(system)
    cand = sym.chosen
    fiber = cand.fiber
    si = [names.index(c) for c in fiber]
    ri = [i for i in range(n) if i not in si]
    shape = tuple(names[i] for i in ri)
    l, m = len(si), len(ri)
    N = strip_factors(cand.xi, [q[i] for i in si])  # l×d, no vanishing factor in the group variables
    d = N.shape[1]
    steps.append(Step(2, "Constraint distribution D_q = null ω(q)", "§3.2.2, eqs. 3.3–3.4, 3.62–3.64",
                      {"D_q (columns)": sym.distribution},
                      "Basis vectors are k×k minors of ω, so they vanish only where rank ω < k."))
    steps.append(Step(3, "Full symmetry group", "§3.2.2, Table 3.1, eqs. 3.5–3.8, 3.65–3.68", {
        "table": sym, "s (fiber)": ", ".join(fiber), "r (shape)": ", ".join(shape),
        "G": cand.group, "xi_Q^q (columns)": _embed(N, si, n), "xi (Lie algebra element)": N,
        "chosen by": sym.chosen_by},
        "Candidates T_q Orb = span{∂/∂s}; S_q = D_q ∩ T_q Orb; the full candidate of smallest l."))

    if version is None:
        pf = system.planar_frame
        version = "B" if pf is not None and pf[0] in fiber and pf[1] in fiber else "A"
    g = group_transform(system, fiber, version)
    ginv = tidy(g.T) if version == "B" else sp.eye(l)
    return (t0, n, k, q, qd, names, M, V, W, L, tau_raw, steps, sym, cand, fiber, si, ri, shape, l, m, N, d, version, g, ginv)


def _assemble(system, version, sym, steps, t0, *, q, names, si, ri, fiber, shape, k, d, P_all, Pt,
              sdot, rdot, Pdot, Ptdot, A_body, Ws, K_nh, X, K, h, J_z, qdot_of_P,
              momenta_of_velocity) -> ReducedODE:
    """The ODE in state order, the Table 2.1 class, the singular set and the result object
    (shared by both derivation paths)."""
    n = len(q)
    qdot_rhs = sp.zeros(n, 1)
    for a, i in enumerate(si):
        qdot_rhs[i] = sdot[a]
    for b, i in enumerate(ri):
        qdot_rhs[i] = rdot[b]
    rhs = sp.Matrix.vstack(qdot_rhs, Pdot, Ptdot)
    state = tuple(q) + tuple(P_all)
    state_names = tuple(names) + tuple(str(s) for s in P_all)

    # classification (thesis Table 2.1)
    if k == 0:
        cls = PURELY_MECHANICAL
    elif d == 0:
        cls = PRINCIPALLY_KINEMATIC
    elif all(e == 0 for e in A_body):
        cls = PURELY_DYNAMIC
    else:
        cls = MIXED

    # singular set: where the constraints on the fiber lose rank or K degenerates
    sing = []
    if k:
        gram = sp.factor(tidy((Ws * Ws.T).det(method="berkowitz")))
        sing.append(gram)
    if d:
        sing.append(sp.factor(tidy(K_nh.det(method="berkowitz"))))
    singular = tuple(e for e in sing if not e.is_Number)
    symbol_names = {s: f"\\tilde{{p}}_{{{sp.latex(q[i])}}}" for s, i in zip(Pt, ri)}
    return ReducedODE(
        system=system, version=version, fiber=fiber, shape=shape, state=state,
        state_names=state_names, momenta=tuple(P_all), rhs=rhs, X=X, K=K, hamiltonian=h,
        structure=J_z, qdot=qdot_of_P, momenta_of_velocity=momenta_of_velocity,
        classification=cls, singular_set=singular, steps=Steps(steps), symmetry=sym,
        derive_time_s=time.perf_counter() - t0, symbol_names=symbol_names)


def _derive_reduced_field(system: System, version: str | None = None) -> ReducedODE:
    (t0, n, k, q, qd, names, M, V, W, L, tau_raw, steps, sym, cand, fiber, si, ri, shape,
     l, m, N, d, version, g, ginv) = \
        _set_up(system, version)

    p_canon = [_sym(f"p_{c}") for c in names]
    nh_names = ["p"] if d == 1 else [f"p{i + 1}" for i in range(d)]
    P_nh = [_sym(nm) for nm in nh_names]
    xi_syms = [_sym(f"xi{i + 1}") for i in range(l)]
    Om = [_sym("Omega") if d == 1 else _sym(f"Omega{i + 1}") for i in range(d)]
    Pt = [_sym(f"pt_{names[i]}") for i in ri]
    mu_syms = [_sym(f"mu{i + 1}") for i in range(l)]
    P_all = P_nh + Pt
    nP = d + m
    Fd = FracField([M, W, L, V, tau_raw, N, g], symbols=list(q) + list(qd) + p_canon + P_all + xi_syms + Om
                   + mu_syms + list(system.input_symbols), angles=q)
    fM = Fd.mat(M)
    fN = Fd.mat(N)
    fg = Fd.mat(g)
    fginv = Fd.mat(ginv)

    def ext(A, rows, cols):
        return [[A[i][j] for j in cols] for i in rows]

    def vec(symbols):
        return [[Fd.table[s_]] for s_ in symbols]

    # ---- step 4: nonholonomic momenta ---------------------------------------------------------
    dLdqd = sp.Matrix([sp.diff(L, v) for v in qd])
    Ms, Msr = M.extract(si, si), M.extract(si, ri) if m else sp.zeros(l, 0)
    fMs, fMsr = ext(fM, si, si), ext(fM, si, ri)
    p_nh_expr = [tidy(sum((dLdqd[i] * N[a, j] for a, i in enumerate(si)), sp.Integer(0))) for j in range(d)]
    steps.append(Step(4, "Nonholonomic momentum", "§3.2.2 (3), eqs. 3.9, 3.69",
                      {nm: e for nm, e in zip(nh_names, p_nh_expr)} if d else {"(none)": "l = k: no momentum"},
                      "p_i = ⟨∂L/∂q̇, ξ_Q^i⟩."))

    # ---- step 5: reconstruction equation ------------------------------------------------------
    fNT = Fd.T(fN) if d else []
    fK_nh = Fd.matmul(Fd.matmul(fNT, fMs, normal=False), fN) if d else []
    fK_nh_inv = Fd.inv(fK_nh) if d else []
    K_nh = Fd.matrix(fK_nh, d, d)
    K_nh_inv = Fd.matrix(fK_nh_inv, d, d)
    Ws = W.extract(list(range(k)), si) if k else sp.zeros(0, l)
    Wr = W.extract(list(range(k)), ri) if k and m else sp.zeros(k, m)
    fW = Fd.mat(W) if k else []
    piv = numeric_pivots(omega_samples(system, 1, seed=13)[0][:, si]) if k else []
    zero = (Fd.zero, Fd.one)
    fXs = [[zero] * m for _ in range(l)]   # s-part of the horizontal lifts X_alpha
    if k and any(e != 0 for e in Wr):
        fBinv = Fd.inv(ext(fW, range(k), [si[p] for p in piv]))
    for a in range(m):
        w = [[zero] for _ in range(l)]
        col = Wr[:, a] if k else sp.zeros(0, 1)
        if k and any(e != 0 for e in col):
            fcol = [[fW[i][ri[a]]] for i in range(k)]
            wp = Fd.matmul(fBinv, fcol)
            for i, pv in enumerate(piv):
                w[pv] = [Fd.neg(wp[i][0])]
        if d:
            inner = Fd.madd(Fd.matmul(fMs, w, normal=False), [[fMsr[i][a]] for i in range(l)], normal=False)
            beta = Fd.mneg(Fd.matmul(fK_nh_inv, Fd.matmul(fNT, inner)))
            w = Fd.madd(w, Fd.matmul(fN, beta, normal=False), normal=False)
        for i in range(l):
            fXs[i][a] = Fd.normal(w[i][0])
    Xs_shape = Fd.matrix(fXs, l, m)
    fA_q = Fd.mneg(fXs)
    fGamma_q = Fd.matmul(fN, fK_nh_inv) if d else [[] for _ in range(l)]
    fA_body = Fd.matmul(fginv, fA_q) if m else [[] for _ in range(l)]
    fGamma_body = Fd.matmul(fginv, fGamma_q) if d else [[] for _ in range(l)]
    A_body = Fd.matrix(fA_body, l, m)
    Gamma_body = Fd.matrix(fGamma_body, l, d)
    s_dot = _col([qd[i] for i in si])
    r_dot = _col([qd[i] for i in ri])
    f_rdot = vec([qd[i] for i in ri])
    f_sdot = vec([qd[i] for i in si])
    if l:
        xi_rec = Fd.madd(Fd.mneg(Fd.matmul(fA_body, f_rdot, normal=False)) if m else [[zero] for _ in range(l)],
                         Fd.matmul(fGamma_body, vec(P_nh), normal=False) if d else [[zero] for _ in range(l)])
        xi_rec = Fd.matrix(xi_rec, l, 1)
    steps.append(Step(5, "Reconstruction equation", "§3.2.2 (4), eqs. 2.47, 3.10–3.13, 3.36, 3.71", {
        "g": g, "g^-1 s_dot": Fd.matrix(Fd.matmul(fginv, f_sdot), l, 1), "A(r)": A_body, "Gamma(r)": Gamma_body,
        "xi = -A r_dot + Gamma p": xi_rec if l else sp.Matrix([])},
        "Solve ω_s ṡ + ω_r ṙ = 0 with the momentum definition for ṡ; ξ = g⁻¹ṡ."))

    # ---- step 6: body basis and Omega ---------------------------------------------------------
    fe_body = Fd.matmul(fginv, fN) if d else [[] for _ in range(l)]
    e_body = Fd.matrix(fe_body, l, d)
    if l:
        f_xic = Fd.madd(Fd.mneg(Fd.matmul(fA_body, f_rdot, normal=False)) if m else [[zero] for _ in range(l)],
                        Fd.matmul(fe_body, vec(Om), normal=False) if d else [[zero] for _ in range(l)])
        xi_constrained = Fd.matrix(f_xic, l, 1)
    else:
        xi_constrained = sp.Matrix([])
    steps.append(Step(6, "Body-fixed basis e and Ω", "§3.2.2 (5), eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73", {
        "e = g^-1 xi_Q": e_body, "Omega = K_Omega^-1 p": K_nh_inv * _col(P_nh),
        "xi = -A r_dot + e Omega": xi_constrained}, "Γ(r)p = eΩ."))

    # ---- step 7: reduced Lagrangian -----------------------------------------------------------
    sdot_of_xi = g * sp.Matrix(xi_syms)
    sub_xi = {qd[i]: sdot_of_xi[a] for a, i in enumerate(si)}
    fL = Fd.frac(L)
    f_sdot_xi = Fd.matmul(fg, vec(xi_syms), normal=False)
    fl_red = Fd.normal(Fd.subs(fL, {Fd.index[qd[i]]: f_sdot_xi[a][0] for a, i in enumerate(si)}))
    l_red = Fd.expr(fl_red)
    steps.append(Step(7, "Reduced Lagrangian l(r, ṙ, ξ)", "§3.2.2 (6), eqs. 3.16, 3.74",
                      {"l": l_red}, "L with ṡ = gξ."))

    # ---- step 8: reduced constrained Lagrangian -----------------------------------------------
    X = sp.zeros(n, d + m)   # columns: nonholonomic (d), then shape (m)
    fX = [[zero] * nP for _ in range(n)]
    one = (Fd.one, Fd.one)
    for j in range(d):
        for a, i in enumerate(si):
            X[i, j] = N[a, j]
            fX[i][j] = fN[a][j]
    for b in range(m):
        for a, i in enumerate(si):
            X[i, d + b] = Xs_shape[a, b]
            fX[i][d + b] = fXs[a][b]
        X[ri[b], d + b] = 1
        fX[ri[b]][d + b] = one
    if m:
        fXsT = Fd.T(fXs)
        terms = [Fd.matmul(Fd.matmul(fXsT, fMs, normal=False), fXs, normal=False),
                 Fd.matmul(fXsT, fMsr, normal=False), Fd.T(Fd.matmul(fXsT, fMsr, normal=False)),
                 ext(fM, ri, ri)]
        fK_rr = [[Fd.normal(Fd.add_many([t[i][j] for t in terms])) for j in range(m)] for i in range(m)]
    else:
        fK_rr = []
    K_rr = Fd.matrix(fK_rr, m, m)
    K = sp.diag(K_nh, K_rr) if d and m else (K_nh if d else K_rr)
    fK = [[zero] * nP for _ in range(nP)]
    for i in range(d):
        for j in range(d):
            fK[i][j] = fK_nh[i][j]
    for i in range(m):
        for j in range(m):
            fK[d + i][d + j] = fK_rr[i][j]
    v_syms = Om + [qd[i] for i in ri]
    l_c = Fd.quadratic(fK, v_syms, half=True) - V
    steps.append(Step(8, "Reduced constrained Lagrangian l_c(r, ṙ, Ω)", "§3.2.2 (7), eqs. 3.17, 3.75",
                      {"l_c": l_c, "K = X^T M X": K}, "l with ξ = −Aṙ + eΩ; no Ω–ṙ cross terms."))

    # ---- steps 9–11: Legendre transform and reduced Hamiltonian --------------------------------
    f_v = vec(v_syms)
    fKv = Fd.matmul(fK, f_v) if nP else []
    legendre = {str(s_): Fd.expr(fKv[j][0]) for j, s_ in enumerate(P_all)}
    steps.append(Step(9, "Legendre transformation", "§3.2.3, eqs. 3.18, 3.76–3.77",
                      {f"{s} = dl_c/d{v}": e for (s, e), v in zip(legendre.items(), v_syms)}, "P = ∂l_c/∂v = Kv."))
    fK_rr_inv = Fd.inv(fK_rr) if m else []
    K_rr_inv = Fd.matrix(fK_rr_inv, m, m)
    Kinv = sp.diag(K_nh_inv, K_rr_inv) if d and m else (K_nh_inv if d else K_rr_inv)
    fKinv = [[zero] * nP for _ in range(nP)]
    for i in range(d):
        for j in range(d):
            fKinv[i][j] = fK_nh_inv[i][j]
    for i in range(m):
        for j in range(m):
            fKinv[d + i][d + j] = fK_rr_inv[i][j]
    v_of_P = Kinv * sp.Matrix(P_all)
    steps.append(Step(10, "Velocities from momenta", "§3.2.3, eqs. 3.19, 3.78–3.79",
                      {f"{v}": e for v, e in zip(v_syms, v_of_P)}, "v = K⁻¹P."))
    h = Fd.quadratic(fKinv, P_all, half=True) + V
    steps.append(Step(11, "Reduced constrained Hamiltonian", "§3.2.3, eqs. 3.20, 3.80",
                      {"h": h}, "h = P·v − l_c = ½PᵀK⁻¹P + V."))

    # ---- steps 12–14: momenta in canonical momenta and in mu ------------------------------------
    p_vec = sp.Matrix(p_canon)
    P_of_p = X.T * p_vec
    steps.append(Step(12, "Nonholonomic momenta in canonical momenta", "§3.2.4, eqs. 3.21–3.22, 3.81",
                      {f"{s}": P_of_p[j] for j, s in enumerate(P_nh)} or {"(none)": "d = 0"},
                      "p_i = ξ_Q^iᵀ p, p = ∂L/∂q̇."))
    if l:
        sub_c = {Fd.index[x]: f_xic[j][0] for j, x in enumerate(xi_syms)}
        mu_rows = []
        for x in xi_syms:
            fd_ = Fd.subs(Fd.diff(fl_red, x), sub_c)
            c0, cs = Fd.linear_split(fd_, v_syms)
            e = Fd.expr(c0)
            for c, v in zip(cs, v_syms):
                if c[0]:
                    e += Fd.expr(c) * v
            mu_rows.append(e)
        mu_of_v = sp.Matrix(mu_rows)
    else:
        mu_of_v = sp.Matrix([])
    steps.append(Step(13, "Shape momenta in canonical momenta", "§3.2.4, eqs. 3.24, 3.83",
                      {**{f"{s}": P_of_p[d + b] for b, s in enumerate(Pt)}, "mu = dl/dxi (on xi = -A r_dot + e Omega)": mu_of_v},
                      "P̃_α = p_α + μ·∂ξ/∂ṙ_α = p_α − μ·A_α."))
    ps_vec = sp.Matrix([p_canon[i] for i in si])
    mu_of_p = tidy(g.T * ps_vec)
    ps_of_mu = tidy(ginv.T * sp.Matrix(mu_syms))  # p_s = g^-T mu
    P_of_mu = sp.Matrix([_linear_tidy(P_of_p[a].xreplace({p_canon[i]: ps_of_mu[j] for j, i in enumerate(si)}),
                                      mu_syms + [p_canon[i] for i in ri]) for a in range(nP)])
    steps.append(Step(14, "Momenta in terms of μ", "§3.2.4, eqs. 3.25–3.27, 3.84–3.87",
                      {"mu = g^T p_s": mu_of_p, "P(mu)": P_of_mu}, "P_i = e_iᵀμ, P̃_α = p_α − A_αᵀμ."))

    # ---- step 15: brackets in mu ------------------------------------------------------------
    # {P_a, P_b} = {X_aᵀp, X_bᵀp} = −pᵀ[X_a, X_b], [X_a, X_b] = DX_b·X_a − DX_a·X_b. Its shape
    # components vanish (X_r is constant), so the bracket is linear in μ: −μᵀ g⁻¹[X_a, X_b]_s.
    JX = [[[Fd.diff(fX[i][a], q[j]) for j in range(n)] for i in range(n)] for a in range(nP)]
    lie_brackets = {}
    C_mu = sp.zeros(nP, nP)
    for a in range(nP):
        for b in range(a + 1, nP):
            lie = []
            for i in range(n):
                terms = [Fd.mul(JX[b][i][j], fX[j][a]) for j in range(n) if JX[b][i][j][0] and fX[j][a][0]]
                terms += [Fd.neg(Fd.mul(JX[a][i][j], fX[j][b])) for j in range(n) if JX[a][i][j][0] and fX[j][b][0]]
                lie.append([Fd.normal(Fd.add_many(terms))])
            lie_brackets[a, b] = lie
            if any(lie[i][0][0] for i in ri):  # pragma: no cover - X_r is constant by construction
                raise ModelError(["internal: Lie bracket has shape components"])
            if l:
                c = Fd.mneg(Fd.matmul(fginv, [lie[i] for i in si]))
                C_mu[a, b] = sum((Fd.expr(c[i][0]) * mu_syms[i] for i in range(l)), sp.Integer(0))
            C_mu[b, a] = -C_mu[a, b]
    steps.append(Step(15, "Brackets of the momenta in μ", "§3.2.4, eqs. 3.28, 3.45, 3.88",
                      {"{P_a, P_b}(mu)": C_mu}, "{P_a, P_b} = −pᵀ[X_a, X_b] = −μᵀg⁻¹[X_a, X_b]_s."))

    # ---- step 16: restriction to the constraint submanifold ------------------------------------
    fXKinv = Fd.matmul(fX, fKinv)
    XKinv = Fd.matrix(fXKinv, n, nP)              # q̇ = (X K⁻¹) P
    if l:
        fMXKinv_s = Fd.matmul(ext(fM, si, range(n)), fXKinv, normal=False)
        mu_M_coef = Fd.matrix(Fd.matmul(Fd.T(fg), fMXKinv_s), l, nP)   # μ|_M = coef·P
        mu_on_M = mu_M_coef * sp.Matrix(P_all)
    else:
        mu_on_M = sp.Matrix([])
    # {P_a, P_b}|_M = μ|_Mᵀ·c_ab = −Σ_c γ_abc (K⁻¹P)_c with γ_abc = X_cᵀ M [X_a, X_b].
    fXTM = Fd.matmul(Fd.T(fX), fM, normal=False)
    C_coef = {}                                  # (a, b) -> nP-vector (fractions): {P_a,P_b}|_M = coef·P
    C = sp.zeros(nP, nP)
    for (a, b), lie in lie_brackets.items():
        gam = Fd.matmul(fXTM, lie)               # nP×1
        coef = [Fd.normal(Fd.neg(Fd.add_many([Fd.mul(gam[c][0], fKinv[c][j]) for c in range(nP)
                                               if fKinv[c][j][0] and gam[c][0]])))
                for j in range(nP)]
        C_coef[a, b] = coef
        C_coef[b, a] = [Fd.neg(x) for x in coef]
        C[a, b] = sum((Fd.expr(coef[j]) * P_all[j] for j in range(nP)), sp.Integer(0))
        C[b, a] = -C[a, b]
    steps.append(Step(16, "Brackets restricted to M̄", "§3.2.4, eqs. 3.29–3.30, 3.46–3.47, 3.89–3.90",
                      {"mu|M": mu_on_M, "{P_a, P_b}|M": C}, "μ|_M̄ = gᵀ(M X K⁻¹P)_s."))

    # ---- step 17: reduced Poisson structure ---------------------------------------------------
    Cnn, Cnr = C.extract(list(range(d)), list(range(d))), C.extract(list(range(d)), list(range(d, nP)))
    Crn, Crr = C.extract(list(range(d, nP)), list(range(d))), C.extract(list(range(d, nP)), list(range(d, nP)))
    J_thesis = sp.BlockMatrix([
        [sp.zeros(l, l), e_body, sp.zeros(l, m), -A_body],
        [-e_body.T, Cnn, sp.zeros(d, m), Cnr],
        [sp.zeros(m, l), sp.zeros(m, d), sp.zeros(m, m), sp.eye(m)],
        [A_body.T, Crn, -sp.eye(m), Crr]]).as_explicit()
    J_z = sp.BlockMatrix([[sp.zeros(n, n), X], [-X.T, C]]).as_explicit()
    steps.append(Step(17, "Reduced Poisson structure matrix", "§3.2.4, Fig. 3.7, eqs. 3.31, 3.48, 3.91",
                      {"J (rows xi, P, r, Pt)": J_thesis, "J_z (rows q, P)": J_z},
                      "Skew-symmetric; rows (ξ, P, r, P̃) as in the thesis, and in z = (q, P) coordinates."))

    # ---- step 18: gradient of h -------------------------------------------------------------
    s_syms = [q[i] for i in si]
    fV = Fd.frac(V)
    for x in s_syms:
        if any(Fd.normal(Fd.diff(e, x))[0] for r_ in fKinv for e in r_) or Fd.normal(Fd.diff(fV, x))[0]:
            raise ModelError(["h depends on the fiber coordinates: the chosen group is not a symmetry"])
    v_of_P_lin = Kinv * sp.Matrix(P_all)
    dh_dP = _col([v_of_P_lin[j] for j in range(d)])
    dh_dPt = _col([v_of_P_lin[d + b] for b in range(m)])
    fdKinv_dr = [[[Fd.normal(Fd.diff(e, q[i])) for e in r_] for r_ in fKinv] for i in ri]
    dV_dr = [Fd.expr(Fd.normal(Fd.diff(fV, q[i]))) for i in ri]
    dh_dr = _col([Fd.quadratic(fdKinv_dr[b], P_all, half=True) + dV_dr[b] for b in range(m)])
    grad = sp.Matrix.vstack(sp.zeros(l, 1), dh_dP, dh_dr, dh_dPt)
    steps.append(Step(18, "Gradient of h", "§3.2.5, eqs. 3.32, 3.49, 3.92",
                      {"(0, dh/dP, dh/dr, dh/dPt)": grad}, "∂h/∂s = 0 by symmetry."))

    # ---- step 19: equations -------------------------------------------------------------------
    # ξ rows: e ∂h/∂P − A ∂h/∂P̃ (linear in P); momentum rows: C K⁻¹P (quadratic) − ∂h/∂r + Xᵀτ
    fP = vec(P_all)
    fqdot = Fd.matmul(fXKinv, fP, normal=False)
    ftau = [[Fd.subs(Fd.frac(tau_raw[i]), {Fd.index[v]: fqdot[j][0] for j, v in enumerate(qd)})] for i in range(n)]
    fF = Fd.matmul(Fd.T(fX), ftau, normal=False) if nP else []
    F_rows = []
    for a in range(nP):
        c0, cs = Fd.linear_split(fF[a][0], P_all)
        e = Fd.expr(c0)
        for c, v in zip(cs, P_all):
            if c[0]:
                e += Fd.expr(c) * v
        F_rows.append(e)
    F = sp.Matrix(F_rows) if nP else sp.zeros(0, 1)
    if l:
        fxi_coef = Fd.matmul([list(r1) + list(r2) for r1, r2 in zip(fe_body, Fd.mneg(fA_body))], fKinv)
        xi_coef = Fd.matrix(fxi_coef, l, nP)
        xi_eq = xi_coef * sp.Matrix(P_all)
    else:
        xi_coef, xi_eq = sp.zeros(0, nP), sp.Matrix([])
    mom_dot = []
    for a in range(nP):
        T = [[[] for _ in range(nP)] for _ in range(nP)]   # raw coefficients of P_j P_l
        for b in range(nP):
            if b != a:
                cab = C_coef[a, b]
                for j in range(nP):
                    if cab[j][0]:
                        for l_ in range(nP):
                            if fKinv[b][l_][0]:
                                T[j][l_].append(Fd.mul(cab[j], fKinv[b][l_]))
        if a >= d:                                # shape momentum: − ∂h/∂r_α
            D_ = fdKinv_dr[a - d]
            for j in range(nP):
                for l_ in range(nP):
                    if D_[j][l_][0]:
                        T[j][l_].append(Fd.neg(Fd.scale(D_[j][l_], 1, 2)))
        quad = sp.Integer(0)
        for j in range(nP):
            for l_ in range(j, nP):
                raw = T[j][j] if j == l_ else T[j][l_] + T[l_][j]
                if raw:
                    c = Fd.normal(Fd.add_many(raw))
                    if c[0]:
                        quad += Fd.expr(c) * P_all[j] * P_all[l_]
        extra = -dV_dr[a - d] if a >= d else sp.Integer(0)
        mom_dot.append(quad + extra + F[a])
    Pdot = sp.Matrix(mom_dot[:d]) if d else sp.zeros(0, 1)
    Ptdot = sp.Matrix(mom_dot[d:]) if m else sp.zeros(0, 1)
    rdot = dh_dPt
    steps.append(Step(19, "Reduced constrained Hamiltonian equations", "§3.2.5, eqs. 3.33, 3.50, 3.93", {
        "xi": xi_eq, "P_dot": Pdot, "r_dot": rdot, "Pt_dot": Ptdot, "forces X^T tau": F},
        "(ξ, Ṗ, ṙ, dP̃/dt) = J∇h + (0, Xᵀτ)."))

    # ---- step 20: fiber velocities ------------------------------------------------------------
    sdot = (Fd.matrix(Fd.matmul(fg, fxi_coef), l, nP) * sp.Matrix(P_all)) if l else sp.Matrix([])
    steps.append(Step(20, "Reconstruction of the fiber velocities", "§3.2.5, eqs. 3.51, 3.94",
                      {"s_dot = g xi": sdot}, "ṡ = gξ."))
    qdot_of_P = XKinv * sp.Matrix(P_all)


    fMqd = Fd.matmul(fXTM, vec(qd), normal=False)
    mov = []
    for a in range(nP):
        c0, cs = Fd.linear_split(fMqd[a][0], qd)
        e = Fd.expr(c0)
        for c, v in zip(cs, qd):
            if c[0]:
                e += Fd.expr(c) * v
        mov.append(e)
    momenta_of_velocity = sp.Matrix(mov) if nP else sp.zeros(0, 1)
    return _assemble(system, version, sym, steps, t0, q=q, names=names, si=si, ri=ri, fiber=fiber,
                     shape=shape, k=k, d=d, P_all=P_all, Pt=Pt, sdot=sdot, rdot=rdot, Pdot=Pdot,
                     Ptdot=Ptdot, A_body=A_body, Ws=Ws, K_nh=K_nh, X=X, K=K, h=h, J_z=J_z,
                     qdot_of_P=qdot_of_P, momenta_of_velocity=momenta_of_velocity)


def _derive_reduced_plain(system: System, version: str | None = None) -> ReducedODE:
    """Plain sympy version of :func:`derive_reduced` (fallback when an expression is not a
    rational function of the generators of :class:`FracField`).

    Parameters
    ----------
    version : "A", "B" or None
        g = identity (A) or the SE(2)-type rotation (B, needs a planar frame with x, y in the
        fiber). None: B when available, else A.
    """
    (t0, n, k, q, qd, names, M, V, W, L, tau_raw, steps, sym, cand, fiber, si, ri, shape,
     l, m, N, d, version, g, ginv) = \
        _set_up(system, version)

    # ---- step 4: nonholonomic momenta ---------------------------------------------------------
    p_canon = [_sym(f"p_{c}") for c in names]
    dLdqd = sp.Matrix([sp.diff(L, v) for v in qd])
    Ms, Msr = M.extract(si, si), M.extract(si, ri) if m else sp.zeros(l, 0)
    nh_names = ["p"] if d == 1 else [f"p{i + 1}" for i in range(d)]
    P_nh = [_sym(nm) for nm in nh_names]
    p_nh_expr = [tidy(sum((dLdqd[i] * N[a, j] for a, i in enumerate(si)), sp.Integer(0))) for j in range(d)]
    steps.append(Step(4, "Nonholonomic momentum", "§3.2.2 (3), eqs. 3.9, 3.69",
                      {nm: e for nm, e in zip(nh_names, p_nh_expr)} if d else {"(none)": "l = k: no momentum"},
                      "p_i = ⟨∂L/∂q̇, ξ_Q^i⟩."))

    # ---- step 5: reconstruction equation ------------------------------------------------------
    K_nh = tidy(N.T * Ms * N) if d else sp.zeros(0, 0)
    K_nh_inv = tidy(K_nh.inv()) if d else sp.zeros(0, 0)
    Ws = W.extract(list(range(k)), si) if k else sp.zeros(0, l)
    Wr = W.extract(list(range(k)), ri) if k and m else sp.zeros(k, m)
    piv = numeric_pivots(omega_samples(system, 1, seed=13)[0][:, si]) if k else []
    Xs_shape = sp.zeros(l, m)   # s-part of the horizontal lifts X_alpha
    if k and any(e != 0 for e in Wr):
        B = Ws.extract(list(range(k)), piv)
        Binv = tidy(B.inv())
    for a in range(m):
        w = sp.zeros(l, 1)
        col = Wr[:, a] if k else sp.zeros(0, 1)
        if k and any(e != 0 for e in col):
            wp = -Binv * col
            for i, pv in enumerate(piv):
                w[pv] = wp[i]
        if d:
            beta = -K_nh_inv * (N.T * (Ms * w + Msr[:, a]))
            w = w + N * beta
        Xs_shape[:, a] = tidy(w)
    A_q = -Xs_shape
    Gamma_q = tidy(N * K_nh_inv) if d else sp.zeros(l, 0)
    A_body = tidy(ginv * A_q)
    Gamma_body = tidy(ginv * Gamma_q)
    s_dot = _col([qd[i] for i in si])
    r_dot = _col([qd[i] for i in ri])
    xi_syms = [_sym(f"xi{i + 1}") for i in range(l)]
    steps.append(Step(5, "Reconstruction equation", "§3.2.2 (4), eqs. 2.47, 3.10–3.13, 3.36, 3.71", {
        "g": g, "g^-1 s_dot": tidy(ginv * s_dot), "A(r)": A_body, "Gamma(r)": Gamma_body,
        "xi = -A r_dot + Gamma p": tidy(-A_body * r_dot + Gamma_body * _col(P_nh)) if l else sp.Matrix([])},
        "Solve ω_s ṡ + ω_r ṙ = 0 with the momentum definition for ṡ; ξ = g⁻¹ṡ."))

    # ---- step 6: body basis and Omega ---------------------------------------------------------
    e_body = tidy(ginv * N) if d else sp.zeros(l, 0)
    Om = [_sym("Omega") if d == 1 else _sym(f"Omega{i + 1}") for i in range(d)]
    xi_constrained = tidy(-A_body * r_dot + e_body * _col(Om)) if l else sp.Matrix([])
    steps.append(Step(6, "Body-fixed basis e and Ω", "§3.2.2 (5), eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73", {
        "e = g^-1 xi_Q": e_body, "Omega = K_Omega^-1 p": K_nh_inv * _col(P_nh),
        "xi = -A r_dot + e Omega": xi_constrained}, "Γ(r)p = eΩ."))

    # ---- step 7: reduced Lagrangian -----------------------------------------------------------
    sdot_of_xi = g * sp.Matrix(xi_syms)
    sub_xi = {qd[i]: sdot_of_xi[a] for a, i in enumerate(si)}
    l_red = tidy(sp.expand(L.xreplace(sub_xi)))
    steps.append(Step(7, "Reduced Lagrangian l(r, ṙ, ξ)", "§3.2.2 (6), eqs. 3.16, 3.74",
                      {"l": l_red}, "L with ṡ = gξ."))

    # ---- step 8: reduced constrained Lagrangian -----------------------------------------------
    X = sp.zeros(n, d + m)   # columns: nonholonomic (d), then shape (m)
    for j in range(d):
        for a, i in enumerate(si):
            X[i, j] = N[a, j]
    for b in range(m):
        for a, i in enumerate(si):
            X[i, d + b] = Xs_shape[a, b]
        X[ri[b], d + b] = 1
    K_rr = tidy(Xs_shape.T * Ms * Xs_shape + Xs_shape.T * Msr + Msr.T * Xs_shape + M.extract(ri, ri)) if m else sp.zeros(0, 0)
    K = sp.diag(K_nh, K_rr) if d and m else (K_nh if d else K_rr)
    v_syms = Om + [qd[i] for i in ri]
    l_c = _quadratic(K / 2, v_syms) - V
    steps.append(Step(8, "Reduced constrained Lagrangian l_c(r, ṙ, Ω)", "§3.2.2 (7), eqs. 3.17, 3.75",
                      {"l_c": l_c, "K = X^T M X": K}, "l with ξ = −Aṙ + eΩ; no Ω–ṙ cross terms."))

    # ---- steps 9–11: Legendre transform and reduced Hamiltonian --------------------------------
    Pt = [_sym(f"pt_{names[i]}") for i in ri]
    P_all = P_nh + Pt
    legendre = {str(s): tidy(sp.diff(l_c, v)) for s, v in zip(P_all, v_syms)}
    steps.append(Step(9, "Legendre transformation", "§3.2.3, eqs. 3.18, 3.76–3.77",
                      {f"{s} = dl_c/d{v}": e for (s, e), v in zip(legendre.items(), v_syms)}, "P = ∂l_c/∂v = Kv."))
    K_rr_inv = tidy(K_rr.inv()) if m else sp.zeros(0, 0)
    Kinv = sp.diag(K_nh_inv, K_rr_inv) if d and m else (K_nh_inv if d else K_rr_inv)
    v_of_P = Kinv * sp.Matrix(P_all)
    steps.append(Step(10, "Velocities from momenta", "§3.2.3, eqs. 3.19, 3.78–3.79",
                      {f"{v}": e for v, e in zip(v_syms, v_of_P)}, "v = K⁻¹P."))
    h = _quadratic(Kinv / 2, P_all) + V
    steps.append(Step(11, "Reduced constrained Hamiltonian", "§3.2.3, eqs. 3.20, 3.80",
                      {"h": h}, "h = P·v − l_c = ½PᵀK⁻¹P + V."))

    # ---- steps 12–14: momenta in canonical momenta and in mu ------------------------------------
    nP = d + m
    p_vec = sp.Matrix(p_canon)
    P_of_p = X.T * p_vec
    steps.append(Step(12, "Nonholonomic momenta in canonical momenta", "§3.2.4, eqs. 3.21–3.22, 3.81",
                      {f"{s}": P_of_p[j] for j, s in enumerate(P_nh)} or {"(none)": "d = 0"},
                      "p_i = ξ_Q^iᵀ p, p = ∂L/∂q̇."))
    dl_dxi = sp.Matrix([sp.diff(l_red, x) for x in xi_syms])
    mu_of_v = sp.Matrix([_linear_tidy(dl_dxi[i].xreplace({x: xi_constrained[j] for j, x in enumerate(xi_syms)}),
                                      v_syms) for i in range(l)]) if l else sp.Matrix([])
    steps.append(Step(13, "Shape momenta in canonical momenta", "§3.2.4, eqs. 3.24, 3.83",
                      {**{f"{s}": P_of_p[d + b] for b, s in enumerate(Pt)}, "mu = dl/dxi (on xi = -A r_dot + e Omega)": mu_of_v},
                      "P̃_α = p_α + μ·∂ξ/∂ṙ_α = p_α − μ·A_α."))
    mu_syms = [_sym(f"mu{i + 1}") for i in range(l)]
    ps_vec = sp.Matrix([p_canon[i] for i in si])
    mu_of_p = tidy(g.T * ps_vec)
    ps_of_mu = tidy(ginv.T * sp.Matrix(mu_syms))  # p_s = g^-T mu
    P_of_mu = sp.Matrix([_linear_tidy(P_of_p[a].xreplace({p_canon[i]: ps_of_mu[j] for j, i in enumerate(si)}),
                                      mu_syms + [p_canon[i] for i in ri]) for a in range(nP)])
    steps.append(Step(14, "Momenta in terms of μ", "§3.2.4, eqs. 3.25–3.27, 3.84–3.87",
                      {"mu = g^T p_s": mu_of_p, "P(mu)": P_of_mu}, "P_i = e_iᵀμ, P̃_α = p_α − A_αᵀμ."))

    # ---- step 15: brackets in mu ------------------------------------------------------------
    # {P_a, P_b} = {X_aᵀp, X_bᵀp} = −pᵀ[X_a, X_b], [X_a, X_b] = DX_b·X_a − DX_a·X_b. Its shape
    # components vanish (X_r is constant), so the bracket is linear in μ: −μᵀ g⁻¹[X_a, X_b]_s.
    JX = [X[:, a].jacobian(q) for a in range(nP)]
    bracket_mu_coef = {}      # (a, b) -> l-vector c with {P_a, P_b} = c·mu
    lie_brackets = {}
    C_mu = sp.zeros(nP, nP)
    for a in range(nP):
        for b in range(a + 1, nP):
            lie = JX[b] * X[:, a] - JX[a] * X[:, b]
            lie_brackets[a, b] = lie
            lie_s = sp.Matrix([lie[i] for i in si])
            lie_r = [tidy(lie[i]) for i in ri]
            if any(e != 0 for e in lie_r):  # pragma: no cover - X_r is constant by construction
                raise ModelError(["internal: Lie bracket has shape components"])
            c = tidy(-(ginv * lie_s)) if l else sp.zeros(0, 1)
            bracket_mu_coef[a, b] = c
            C_mu[a, b] = sum((c[i] * mu_syms[i] for i in range(l)), sp.Integer(0))
            C_mu[b, a] = -C_mu[a, b]
    steps.append(Step(15, "Brackets of the momenta in μ", "§3.2.4, eqs. 3.28, 3.45, 3.88",
                      {"{P_a, P_b}(mu)": C_mu}, "{P_a, P_b} = −pᵀ[X_a, X_b] = −μᵀg⁻¹[X_a, X_b]_s."))

    # ---- step 16: restriction to the constraint submanifold ------------------------------------
    XKinv = tidy(X * Kinv)                       # q̇ = (X K⁻¹) P
    MXKinv = M * XKinv                           # p|_M = (M X K⁻¹) P
    mu_M_coef = tidy(g.T * MXKinv.extract(si, list(range(nP)))) if l else sp.zeros(0, nP)  # μ|_M = coef·P
    mu_on_M = mu_M_coef * sp.Matrix(P_all) if l else sp.Matrix([])
    # {P_a, P_b}|_M = μ|_Mᵀ·c_ab = −Σ_c γ_abc (K⁻¹P)_c with γ_abc = X_cᵀ M [X_a, X_b]: the same
    # number, assembled from the small factors γ (no K⁻¹ inside) before multiplying by K⁻¹.
    C_coef = {}                                  # (a, b) -> nP-vector: {P_a,P_b}|_M = coef·P
    C = sp.zeros(nP, nP)
    for (a, b), lie in lie_brackets.items():
        gam = [tidy((X[:, c].T * M * lie)[0, 0]) for c in range(nP)]
        coef = sp.Matrix([tidy(-sum((gam[c] * Kinv[c, j] for c in range(nP) if Kinv[c, j] != 0), sp.Integer(0)))
                          for j in range(nP)])
        C_coef[a, b] = coef
        C_coef[b, a] = -coef
        C[a, b] = sum((coef[j] * P_all[j] for j in range(nP)), sp.Integer(0))
        C[b, a] = -C[a, b]
    steps.append(Step(16, "Brackets restricted to M̄", "§3.2.4, eqs. 3.29–3.30, 3.46–3.47, 3.89–3.90",
                      {"mu|M": mu_on_M, "{P_a, P_b}|M": C}, "μ|_M̄ = gᵀ(M X K⁻¹P)_s."))

    # ---- step 17: reduced Poisson structure ---------------------------------------------------
    Cnn, Cnr = C.extract(list(range(d)), list(range(d))), C.extract(list(range(d)), list(range(d, nP)))
    Crn, Crr = C.extract(list(range(d, nP)), list(range(d))), C.extract(list(range(d, nP)), list(range(d, nP)))
    J_thesis = sp.BlockMatrix([
        [sp.zeros(l, l), e_body, sp.zeros(l, m), -A_body],
        [-e_body.T, Cnn, sp.zeros(d, m), Cnr],
        [sp.zeros(m, l), sp.zeros(m, d), sp.zeros(m, m), sp.eye(m)],
        [A_body.T, Crn, -sp.eye(m), Crr]]).as_explicit()
    J_z = sp.BlockMatrix([[sp.zeros(n, n), X], [-X.T, C]]).as_explicit()
    steps.append(Step(17, "Reduced Poisson structure matrix", "§3.2.4, Fig. 3.7, eqs. 3.31, 3.48, 3.91",
                      {"J (rows xi, P, r, Pt)": J_thesis, "J_z (rows q, P)": J_z},
                      "Skew-symmetric; rows (ξ, P, r, P̃) as in the thesis, and in z = (q, P) coordinates."))

    # ---- step 18: gradient of h -------------------------------------------------------------
    s_syms = [q[i] for i in si]
    dKinv_ds = [tidy(sp.diff(Kinv, x)) for x in s_syms]
    dV_ds = [tidy(sp.diff(V, x)) for x in s_syms]
    if any(any(e != 0 for e in D_) for D_ in dKinv_ds) or any(e != 0 for e in dV_ds):
        raise ModelError(["h depends on the fiber coordinates: the chosen group is not a symmetry"])
    v_of_P_lin = Kinv * sp.Matrix(P_all)
    dh_dP = _col([v_of_P_lin[j] for j in range(d)])
    dh_dPt = _col([v_of_P_lin[d + b] for b in range(m)])
    dKinv_dr = [tidy(sp.diff(Kinv, q[i])) for i in ri]
    dV_dr = [tidy(sp.diff(V, q[i])) for i in ri]
    dh_dr = _col([_quadratic(dKinv_dr[b] / 2, P_all) + dV_dr[b] for b in range(m)])
    grad = sp.Matrix.vstack(sp.zeros(l, 1), dh_dP, dh_dr, dh_dPt)
    steps.append(Step(18, "Gradient of h", "§3.2.5, eqs. 3.32, 3.49, 3.92",
                      {"(0, dh/dP, dh/dr, dh/dPt)": grad}, "∂h/∂s = 0 by symmetry."))

    # ---- step 19: equations -------------------------------------------------------------------
    # ξ rows: e ∂h/∂P − A ∂h/∂P̃ (linear in P); momentum rows: C K⁻¹P (quadratic) − ∂h/∂r + Xᵀτ
    tau = system.force_vector().xreplace({v: (XKinv * sp.Matrix(P_all))[i] for i, v in enumerate(qd)})
    F = sp.Matrix([_linear_tidy(e, list(P_all)) for e in (X.T * tau)]) if nP else sp.zeros(0, 1)
    xi_coef = tidy(sp.Matrix.hstack(e_body, -A_body) * Kinv) if l else sp.zeros(0, nP)
    xi_eq = xi_coef * sp.Matrix(P_all) if l else sp.Matrix([])
    mom_dot = []
    for a in range(nP):
        T = sp.zeros(nP, nP)                      # raw coefficients of P_j P_l (not yet symmetric)
        for b in range(nP):
            if b != a:
                T += C_coef[a, b] * Kinv[b, :]   # C_coef[a,b][j] * Kinv[b, l]
        if a >= d:                                # shape momentum: − ∂h/∂r_α
            T -= dKinv_dr[a - d] / 2
        quad = sp.Integer(0)
        for j in range(nP):
            for l_ in range(j, nP):
                raw = T[j, j] if j == l_ else T[j, l_] + T[l_, j]
                if raw != 0:
                    c = tidy(raw)
                    if c != 0:
                        quad += c * P_all[j] * P_all[l_]
        extra = -dV_dr[a - d] if a >= d else sp.Integer(0)
        mom_dot.append(quad + extra + F[a])
    Pdot = sp.Matrix(mom_dot[:d]) if d else sp.zeros(0, 1)
    Ptdot = sp.Matrix(mom_dot[d:]) if m else sp.zeros(0, 1)
    rdot = dh_dPt
    steps.append(Step(19, "Reduced constrained Hamiltonian equations", "§3.2.5, eqs. 3.33, 3.50, 3.93", {
        "xi": xi_eq, "P_dot": Pdot, "r_dot": rdot, "Pt_dot": Ptdot, "forces X^T tau": F},
        "(ξ, Ṗ, ṙ, dP̃/dt) = J∇h + (0, Xᵀτ)."))

    # ---- step 20: fiber velocities ------------------------------------------------------------
    sdot = (tidy(g * xi_coef) * sp.Matrix(P_all)) if l else sp.Matrix([])
    steps.append(Step(20, "Reconstruction of the fiber velocities", "§3.2.5, eqs. 3.51, 3.94",
                      {"s_dot = g xi": sdot}, "ṡ = gξ."))
    qdot_of_P = XKinv * sp.Matrix(P_all)


    momenta_of_velocity = sp.Matrix([_linear_tidy(e, qd) for e in X.T * M * sp.Matrix(qd)])
    return _assemble(system, version, sym, steps, t0, q=q, names=names, si=si, ri=ri, fiber=fiber,
                     shape=shape, k=k, d=d, P_all=P_all, Pt=Pt, sdot=sdot, rdot=rdot, Pdot=Pdot,
                     Ptdot=Ptdot, A_body=A_body, Ws=Ws, K_nh=K_nh, X=X, K=K, h=h, J_z=J_z,
                     qdot_of_P=qdot_of_P, momenta_of_velocity=momenta_of_velocity)
