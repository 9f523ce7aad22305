"""Steps 4–8 (thesis §3.2.2, Fig. 3.5): nonholonomic momentum, reconstruction equation,
body-fixed basis, reduced Lagrangian and reduced constrained Lagrangian.

Every function takes the arithmetic back end ``F`` (see :mod:`.arithmetic`), the
:class:`~.setup.Layout` and the symbols, and returns its :class:`~nhgait.dynamics.derivation.steps.Step`
together with the elements later steps need.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..steps import Step


@dataclass
class Connection:
    """Elements of steps 4–8 used later (matrices are lists of rows of F-elements).

    X : n×(d+m) constraint-adapted basis, columns (ξ_Q^1 … ξ_Q^d, X_α for free shape α).
    K_nh, K_nh_inv : K_Ω = NᵀM_ssN and its inverse (d×d); K : blockdiag(K_Ω, K_r).
    A, e : A(r) (l×m) and the body basis e = g⁻¹N (l×d); l_red : the reduced Lagrangian.
    """

    X: list
    K_nh: list
    K_nh_inv: list
    A: list
    e: list
    K: list = None
    l_red: object = None
    xi_c: list = None


def momentum(F, lay, sy) -> Step:
    """Step 4 (eqs. 3.9, 3.69): p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ = Σ_s (∂L/∂ṡ) N_si."""
    qd = lay.system.q_dot
    M = F.mat(lay.M)
    p = []
    for j in range(lay.d):
        terms = [(F.normal(F.add_many([F.mul(F.frac(lay.N[a, j]), M[i][c]) for a, i in enumerate(lay.si)
                                       if not F.is_zero(M[i][c])])), [qd[c]]) for c in range(lay.n)]
        p.append(F.form(terms))
    items = {"p": F.column(p)}
    return Step(4, "Nonholonomic momentum", "§3.2.2 (3), eqs. 3.9, 3.69", items,
                "p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ (none when d = 0).",
                labels={"p": "p (nonholonomic momenta " + ", ".join(map(str, sy.P_nh)) + ")"})


def _shape_column(F, lay, M, N, NT, K_nh_inv, wp, ja, g):
    """The horizontal lift X_α of ∂/∂r_α (eq. 2.47): 1 at r_α, the pivot velocities from
    ω X_α = 0 (fiber pivots in body velocities ξ, ṡ = gξ), then made M-orthogonal to every
    ξ_Q^i (so K is block-diagonal)."""
    n = lay.n
    w = [F.ZERO] * n
    w[ja] = F.ONE
    if wp is not None:              # B⁻¹ω_b e_α (a k-vector), or None when ω_b e_α = 0
        xi = [F.ZERO] * len(lay.si)
        for i, pv in enumerate(lay.pivots):
            if pv in lay.si:
                xi[lay.si.index(pv)] = F.neg(wp[i][0])
            else:
                w[pv] = F.neg(wp[i][0])
        sdot = F.matmul(g, [[x] for x in xi], normal=False)
        for a, i in enumerate(lay.si):
            w[i] = sdot[a][0]
    if lay.d:
        inner = F.matmul([M[i] for i in lay.si], [[x] for x in w], normal=False)
        beta = F.mneg(F.matmul(K_nh_inv, F.matmul(NT, inner)))
        Nb = F.matmul(N, beta, normal=False)
        for a, i in enumerate(lay.si):
            w[i] = F.add_many([w[i], Nb[a][0]])
    return [F.normal(x) for x in w]


def reconstruction(F, lay, sy) -> tuple[Step, Connection]:
    """Step 5 (eqs. 2.47, 3.10–3.13, 3.36, 3.71): solve ω_s ṡ + ω_r ṙ = 0 with the momentum
    definition for ṡ = −A_q ṙ + Γ_q p; A = g⁻¹A_q, Γ = g⁻¹Γ_q = g⁻¹N K_Ω⁻¹. The pivot block B
    of ω_b is solved against the free shape columns (``F.solve``: a linear solve in the
    implicit form)."""
    n, k, d, l = lay.n, lay.k, lay.d, len(lay.si)
    M, N = F.mat(lay.M), F.mat(lay.N)
    NT = F.T(N) if d else []
    K_nh = F.matmul(F.matmul(NT, [[M[i][j] for j in lay.si] for i in lay.si], normal=False), N) if d else []
    K_nh_inv = F.inv(K_nh, "kinetic metric K_Ω = NᵀM_ssN") if d else []
    W = F.mat(lay.Wb) if k else []
    needs_B = k and any(not F.is_zero(W[i][j]) for i in range(k) for j in lay.free)
    rhs = [ja for ja in lay.free if k and any(not F.is_zero(W[i][ja]) for i in range(k))]
    sol = F.solve([[W[i][p] for p in lay.pivots] for i in range(k)], [[W[i][ja] for ja in rhs] for i in range(k)],
                  "pivot block of ω") if needs_B and rhs else []
    g = F.mat(lay.g)
    cols = [_shape_column(F, lay, M, N, NT, K_nh_inv,
                          [[sol[i][rhs.index(ja)]] for i in range(k)] if ja in rhs else None, ja, g)
            for ja in lay.free]
    X = [[F.ZERO] * (d + len(cols)) for _ in range(n)]
    for j in range(d):
        for a, i in enumerate(lay.si):
            X[i][j] = N[a][j]
    for b, col in enumerate(cols):
        for i in range(n):
            X[i][d + b] = col[i]
    ginv = F.mat(lay.ginv)
    A = F.matmul(ginv, [[F.neg(X[i][d + b]) for b in range(len(cols))] for i in lay.si]) if cols else [[] for _ in range(l)]
    Gamma = F.matmul(ginv, F.matmul(N, K_nh_inv)) if d else [[] for _ in range(l)]
    con = Connection(X=X, K_nh=K_nh, K_nh_inv=K_nh_inv, A=A, e=F.matmul(ginv, N) if d else [[] for _ in range(l)])
    rdot = F.vec([lay.system.q_dot[i] for i in lay.free])
    sdot = F.vec([lay.system.q_dot[i] for i in lay.si])
    xi = F.madd(F.mneg(F.matmul(A, rdot, normal=False)) if cols else F.zeros(l, 1),
                F.matmul(Gamma, F.vec(sy.P_nh), normal=False) if d else F.zeros(l, 1))
    step = Step(5, "Reconstruction equation", "§3.2.2 (4), eqs. 2.47, 3.10–3.13, 3.36, 3.71", {
        "g": lay.g, "xi_body": F.show(F.matmul(ginv, sdot), l, 1), "A": F.show(A, l, len(cols)),
        "Gamma": F.show(Gamma, l, d), "xi": F.show(xi, l, 1)},
        "Solve ω_s ṡ + ω_r ṙ = 0 with the momentum definition for ṡ; ξ = g⁻¹ṡ.",
        labels={"xi_body": "g^-1 s_dot", "A": "A(r)", "Gamma": "Gamma(r)", "xi": "xi = -A r_dot + Gamma p"})
    return step, con


def body_basis(F, lay, sy, con: Connection) -> Step:
    """Step 6 (eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73): e = g⁻¹N, Ω = K_Ω⁻¹p, so Γp = eΩ and
    ξ = −Aṙ + eΩ on the constraints."""
    l, d, m = len(lay.si), lay.d, len(lay.free)
    rdot = F.vec([lay.system.q_dot[i] for i in lay.free])
    con.xi_c = F.madd(F.mneg(F.matmul(con.A, rdot, normal=False)) if m else F.zeros(l, 1),
                      F.matmul(con.e, F.vec(sy.Om), normal=False) if d else F.zeros(l, 1))
    Omega = F.matmul(con.K_nh_inv, F.vec(sy.P_nh)) if d else []
    return Step(6, "Body-fixed basis e and Ω", "§3.2.2 (5), eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73", {
        "e": F.show(con.e, l, d), "Omega": F.show(Omega, d, 1), "xi": F.show(con.xi_c, l, 1)}, "Γ(r)p = eΩ.",
        labels={"e": "e = g^-1 xi_Q", "Omega": "Omega = K_Omega^-1 p", "xi": "xi = -A r_dot + e Omega"})


def reduced_lagrangian(F, lay, sy, con: Connection) -> Step:
    """Step 7 (eqs. 3.16, 3.74): l(r, ṙ, ξ) = L with ṡ = gξ."""
    qd = lay.system.q_dot
    sdot = F.matmul(F.mat(lay.g), F.vec(sy.xi), normal=False)
    con.l_red = F.normal(F.subs(F.frac(lay.system.L), {F.sub_key(qd[i]): sdot[a][0] for a, i in enumerate(lay.si)}))
    return Step(7, "Reduced Lagrangian l(r, ṙ, ξ)", "§3.2.2 (6), eqs. 3.16, 3.74",
                {"l": F.expr(con.l_red)}, "L with ṡ = gξ.")


def constrained_lagrangian(F, lay, sy, con: Connection) -> Step:
    """Step 8 (eqs. 3.17, 3.75): l_c(r, ṙ, Ω) = ½vᵀKv − V with v = (Ω, ṙ) and K = XᵀMX,
    block-diagonal (K_Ω, K_r): no Ω–ṙ cross terms."""
    d, m = lay.d, len(lay.free)
    M = F.mat(lay.M)
    Xr = [[row[d + b] for b in range(m)] for row in con.X]
    K_r = F.matmul(F.matmul(F.T(Xr), M, normal=False), Xr) if m else []
    con.K = K = F.block_diag(con.K_nh, K_r)
    l_c = F.quadratic(K, sy.v, half=True) - F.value(lay.V)
    return Step(8, "Reduced constrained Lagrangian l_c(r, ṙ, Ω)", "§3.2.2 (7), eqs. 3.17, 3.75",
                {"l_c": l_c, "K": F.show(K, d + m, d + m)}, "l with ξ = −Aṙ + eΩ; no Ω–ṙ cross terms.",
                labels={"K": "K = X^T M X"})
