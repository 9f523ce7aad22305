"""Steps 4–8 (thesis §3.2.2, Fig. 3.5): nonholonomic momentum, reconstruction equation,
body-fixed basis, reduced Lagrangian and reduced constrained Lagrangian.

Every function takes the arithmetic back end ``F`` (see :mod:`.arithmetic`), the
:class:`~.setup.Layout` and the symbols, and returns its :class:`~nhgait.dynamics.derivation.steps.Step`
together with the elements later steps need, as values: step 5 a frozen
:class:`Reconstruction`, steps 6–8 one element each; :class:`Connection` holds them all.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

from ..steps import Step


@dataclass(frozen=True, eq=False)
class Reconstruction:
    """What step 5 gives the later steps (matrices are lists of rows of F-elements).

    X : n×(d+m) constraint-adapted basis, columns (ξ_Q^1 … ξ_Q^d, X_α for free shape α).
    K_nh, K_nh_inv : K_Ω = NᵀM_ssN and its inverse (d×d).
    A, e : A(r) (l×m) and the body basis e = g⁻¹N (l×d).
    """

    X: list
    K_nh: list
    K_nh_inv: list
    A: list
    e: list


@dataclass(frozen=True, eq=False)
class Connection(Reconstruction):
    """Everything steps 5–8 give the later steps: the :class:`Reconstruction` and

    xi_c : ξ = −Aṙ + eΩ on the constraints (l×1, step 6); l_red : the reduced Lagrangian
    l(r, ṙ, ξ) (step 7); K : K = XᵀMX = blockdiag(K_Ω, K_r) ((d+m)×(d+m), step 8).
    """

    xi_c: list
    l_red: object
    K: list

    @classmethod
    def of(cls, reconstruction: Reconstruction, *, xi_c, l_red, K) -> "Connection":
        parts = {f.name: getattr(reconstruction, f.name) for f in fields(Reconstruction)}
        return cls(**parts, xi_c=xi_c, l_red=l_red, K=K)


def momentum(F, layout, symbols) -> Step:
    """Step 4 (eqs. 3.9, 3.69): p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ = Σ_s (∂L/∂ṡ) N_si."""
    qd = layout.system.q_dot
    M = F.mat(layout.M)
    p = []
    for j in range(layout.d):
        terms = [(F.normal(F.add_many([F.mul(F.frac(layout.N[a, j]), M[i][c]) for a, i in enumerate(layout.si)
                                       if not F.is_zero(M[i][c])])), [qd[c]]) for c in range(layout.n)]
        p.append(F.form(terms))
    items = {"p": F.column(p)}
    return Step(4, "Nonholonomic momentum", "§3.2.2 (3), eqs. 3.9, 3.69", items,
                "p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ (none when d = 0).",
                labels={"p": "p (nonholonomic momenta " + ", ".join(map(str, symbols.P_nh)) + ")"})


def _shape_column(F, layout, M, N, NT, K_nh_inv, wp, ja, g):
    """The horizontal lift X_α of ∂/∂r_α (eq. 2.47): 1 at r_α, the pivot velocities from
    ω X_α = 0 (fiber pivots in body velocities ξ, ṡ = gξ), then made M-orthogonal to every
    ξ_Q^i (so K is block-diagonal)."""
    n = layout.n
    w = [F.ZERO] * n
    w[ja] = F.ONE
    if wp is not None:              # B⁻¹ω_b e_α (a k-vector), or None when ω_b e_α = 0
        xi = [F.ZERO] * len(layout.si)
        for i, pv in enumerate(layout.pivots):
            if pv in layout.si:
                xi[layout.si.index(pv)] = F.neg(wp[i][0])
            else:
                w[pv] = F.neg(wp[i][0])
        sdot = F.matmul(g, [[x] for x in xi], normal=False)
        for a, i in enumerate(layout.si):
            w[i] = sdot[a][0]
    if layout.d:
        inner = F.matmul([M[i] for i in layout.si], [[x] for x in w], normal=False)
        beta = F.mneg(F.matmul(K_nh_inv, F.matmul(NT, inner)))
        Nb = F.matmul(N, beta, normal=False)
        for a, i in enumerate(layout.si):
            w[i] = F.add_many([w[i], Nb[a][0]])
    return [F.normal(x) for x in w]


def reconstruction(F, layout, symbols) -> tuple[Step, Reconstruction]:
    """Step 5 (eqs. 2.47, 3.10–3.13, 3.36, 3.71): solve ω_s ṡ + ω_r ṙ = 0 with the momentum
    definition for ṡ = −A_q ṙ + Γ_q p; A = g⁻¹A_q, Γ = g⁻¹Γ_q = g⁻¹N K_Ω⁻¹. The pivot block B
    of ω_b is solved against the free shape columns (``F.solve``: a linear solve in the
    implicit form)."""
    n, k, d, l = layout.n, layout.k, layout.d, len(layout.si)
    M, N = F.mat(layout.M), F.mat(layout.N)
    NT = F.T(N) if d else []
    K_nh = F.matmul(F.matmul(NT, [[M[i][j] for j in layout.si] for i in layout.si], normal=False), N) if d else []
    K_nh_inv = F.inv(K_nh, "kinetic metric K_Ω = NᵀM_ssN") if d else []
    W = F.mat(layout.Wb) if k else []
    needs_B = k and any(not F.is_zero(W[i][j]) for i in range(k) for j in layout.free)
    rhs = [ja for ja in layout.free if k and any(not F.is_zero(W[i][ja]) for i in range(k))]
    sol = F.solve([[W[i][p] for p in layout.pivots] for i in range(k)], [[W[i][ja] for ja in rhs] for i in range(k)],
                  "pivot block of ω") if needs_B and rhs else []
    g = F.mat(layout.g)
    cols = [_shape_column(F, layout, M, N, NT, K_nh_inv,
                          [[sol[i][rhs.index(ja)]] for i in range(k)] if ja in rhs else None, ja, g)
            for ja in layout.free]
    X = [[F.ZERO] * (d + len(cols)) for _ in range(n)]
    for j in range(d):
        for a, i in enumerate(layout.si):
            X[i][j] = N[a][j]
    for b, col in enumerate(cols):
        for i in range(n):
            X[i][d + b] = col[i]
    ginv = F.mat(layout.ginv)
    A = F.matmul(ginv, [[F.neg(X[i][d + b]) for b in range(len(cols))] for i in layout.si]) if cols else [[] for _ in range(l)]
    Gamma = F.matmul(ginv, F.matmul(N, K_nh_inv)) if d else [[] for _ in range(l)]
    result = Reconstruction(X=X, K_nh=K_nh, K_nh_inv=K_nh_inv, A=A, e=F.matmul(ginv, N) if d else [[] for _ in range(l)])
    rdot = F.vec([layout.system.q_dot[i] for i in layout.free])
    sdot = F.vec([layout.system.q_dot[i] for i in layout.si])
    xi = F.madd(F.mneg(F.matmul(A, rdot, normal=False)) if cols else F.zeros(l, 1),
                F.matmul(Gamma, F.vec(symbols.P_nh), normal=False) if d else F.zeros(l, 1))
    step = Step(5, "Reconstruction equation", "§3.2.2 (4), eqs. 2.47, 3.10–3.13, 3.36, 3.71", {
        "g": layout.g, "xi_body": F.show(F.matmul(ginv, sdot), l, 1), "A": F.show(A, l, len(cols)),
        "Gamma": F.show(Gamma, l, d), "xi": F.show(xi, l, 1)},
        "Solve ω_s ṡ + ω_r ṙ = 0 with the momentum definition for ṡ; ξ = g⁻¹ṡ.",
        labels={"xi_body": "g^-1 s_dot", "A": "A(r)", "Gamma": "Gamma(r)", "xi": "xi = -A r_dot + Gamma p"})
    return step, result


def body_basis(F, layout, symbols, reconstruction: Reconstruction) -> tuple[Step, list]:
    """Step 6 (eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73): e = g⁻¹N, Ω = K_Ω⁻¹p, so Γp = eΩ and
    ξ = −Aṙ + eΩ on the constraints."""
    l, d, m = len(layout.si), layout.d, len(layout.free)
    rdot = F.vec([layout.system.q_dot[i] for i in layout.free])
    xi_c = F.madd(F.mneg(F.matmul(reconstruction.A, rdot, normal=False)) if m else F.zeros(l, 1),
                  F.matmul(reconstruction.e, F.vec(symbols.Om), normal=False) if d else F.zeros(l, 1))
    Omega = F.matmul(reconstruction.K_nh_inv, F.vec(symbols.P_nh)) if d else []
    return Step(6, "Body-fixed basis e and Ω", "§3.2.2 (5), eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73", {
        "e": F.show(reconstruction.e, l, d), "Omega": F.show(Omega, d, 1), "xi": F.show(xi_c, l, 1)}, "Γ(r)p = eΩ.",
        labels={"e": "e = g^-1 xi_Q", "Omega": "Omega = K_Omega^-1 p", "xi": "xi = -A r_dot + e Omega"}), xi_c


def reduced_lagrangian(F, layout, symbols) -> tuple[Step, object]:
    """Step 7 (eqs. 3.16, 3.74): l(r, ṙ, ξ) = L with ṡ = gξ."""
    qd = layout.system.q_dot
    sdot = F.matmul(F.mat(layout.g), F.vec(symbols.xi), normal=False)
    l_red = F.normal(F.subs(F.frac(layout.system.L), {F.sub_key(qd[i]): sdot[a][0] for a, i in enumerate(layout.si)}))
    return Step(7, "Reduced Lagrangian l(r, ṙ, ξ)", "§3.2.2 (6), eqs. 3.16, 3.74",
                {"l": F.expr(l_red)}, "L with ṡ = gξ."), l_red


def constrained_lagrangian(F, layout, symbols, reconstruction: Reconstruction) -> tuple[Step, list]:
    """Step 8 (eqs. 3.17, 3.75): l_c(r, ṙ, Ω) = ½vᵀKv − V with v = (Ω, ṙ) and K = XᵀMX,
    block-diagonal (K_Ω, K_r): no Ω–ṙ cross terms."""
    d, m = layout.d, len(layout.free)
    M = F.mat(layout.M)
    Xr = [[row[d + b] for b in range(m)] for row in reconstruction.X]
    K_r = F.matmul(F.matmul(F.T(Xr), M, normal=False), Xr) if m else []
    K = F.block_diag(reconstruction.K_nh, K_r)
    l_c = F.quadratic(K, symbols.v, half=True) - F.value(layout.V)
    return Step(8, "Reduced constrained Lagrangian l_c(r, ṙ, Ω)", "§3.2.2 (7), eqs. 3.17, 3.75",
                {"l_c": l_c, "K": F.show(K, d + m, d + m)}, "l with ξ = −Aṙ + eΩ; no Ω–ṙ cross terms.",
                labels={"K": "K = X^T M X"}), K
