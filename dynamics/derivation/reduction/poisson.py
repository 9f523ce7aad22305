"""Steps 12–17 (thesis §3.2.4, Fig. 3.7): the momenta in canonical momenta and in μ, their
brackets, the restriction to the constraint submanifold M̄ and the reduced Poisson-like
structure J.

The brackets are {P_a, P_b} = {X_aᵀp, X_bᵀp} = −pᵀ[X_a, X_b] with the Lie bracket
[X_a, X_b] = DX_b·X_a − DX_a·X_b; on M̄, p = MXK⁻¹P, so {P_a, P_b}|_M̄ = −Σ_c γ_abc (K⁻¹P)_c with
γ_abc = X_cᵀM[X_a, X_b] (no inverse inside γ).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..steps import Step, Stepped


def canonical_momenta(arith, layout, symbols, connection) -> Stepped:
    """Step 12 (eqs. 3.21–3.22, 3.81): P_a = X_aᵀp, p = ∂L/∂q̇."""
    nP = len(symbols.P)
    P_of_p = [arith.form([(connection.X[i][a], [symbols.p[i]]) for i in range(layout.n)]) for a in range(nP)]
    step = Step(12, "Momenta in canonical momenta", "§3.2.4, eqs. 3.21–3.22, 3.81",
                {"P": arith.column(P_of_p)}, "P_a = X_aᵀp (nonholonomic: p_i = ξ_Q^iᵀp).",
                labels={"P": "(" + ", ".join(map(str, symbols.P)) + ") in p"})
    return Stepped(step, P_of_p)


def body_momentum(arith, layout, symbols, connection) -> Step:
    """Step 13 (eqs. 3.24, 3.83): μ = ∂l/∂ξ on ξ = −Aṙ + eΩ, and P̃_α = p_α − μ·A_α."""
    l = len(layout.si)
    sub = {arith.sub_key(x): connection.xi_c[j][0] for j, x in enumerate(symbols.xi)}
    mu = []
    for x in symbols.xi:
        c0, cs = arith.linear_split(arith.subs(arith.diff(connection.l_red, x), sub), symbols.v)
        mu.append(arith.form([(c0, [])] + [(c, [v]) for c, v in zip(cs, symbols.v, strict=True)]))
    return Step(13, "Body momentum on the constraints", "§3.2.4, eqs. 3.24, 3.83",
                {"mu": arith.column(mu) if l else arith.column([])}, "μ = ∂l/∂ξ; P̃_α = p_α − μ·A_α.",
                labels={"mu": "mu = dl/dxi (on xi = -A r_dot + e Omega)"})


def momenta_in_mu(arith, layout, symbols, connection) -> Step:
    """Step 14 (eqs. 3.25–3.27, 3.84–3.87): μ = gᵀp_s, so p_s = g⁻ᵀμ and P = Xᵀp in μ."""
    l, nP = len(layout.si), len(symbols.P)
    gT, ginvT = arith.T(arith.mat(layout.g)), arith.T(arith.mat(layout.ginv))
    mu_of_p = arith.matmul(gT, arith.vec([symbols.p[i] for i in layout.si]))
    P_mu = []
    for a in range(nP):
        terms = [arith.normal(arith.add_many([arith.mul(connection.X[i][a], ginvT[j][b])
                                              for j, i in enumerate(layout.si)]))
                 for b in range(l)]
        P_mu.append(arith.form([(c, [symbols.mu[b]]) for b, c in enumerate(terms)]
                           + [(connection.X[i][a], [symbols.p[i]]) for i in layout.ri]))
    return Step(14, "Momenta in terms of μ", "§3.2.4, eqs. 3.25–3.27, 3.84–3.87",
                {"mu": arith.show(mu_of_p, l, 1), "P": arith.column(P_mu)},
                "P_i = e_iᵀμ, P̃_α = p_α − A_αᵀμ.", labels={"mu": "mu = g^T p_s", "P": "P(mu)"})


def lie_brackets(arith, layout, connection) -> dict:
    """[X_a, X_b] = DX_b·X_a − DX_a·X_b for a < b (n-vectors of elements): derivatives of the
    columns along each other (``arith.jvp``; forward AD in the implicit form)."""
    n, q = layout.n, layout.system.q
    nP = len(connection.X[0]) if connection.X else 0
    cols = [[connection.X[i][a] for i in range(n)] for a in range(nP)]
    out = {}
    for a in range(nP):
        for b in range(a + 1, nP):
            d_b = arith.jvp(cols[b], q, cols[a])
            d_a = arith.jvp(cols[a], q, cols[b])
            out[a, b] = [[arith.normal(arith.add_many([x, arith.neg(y)]))]
                         for x, y in zip(d_b, d_a, strict=True)]
    return out


def brackets_in_mu(arith, layout, symbols, lie) -> Step:
    """Step 15 (eqs. 3.28, 3.45, 3.88): {P_a, P_b} = −pᵀ[X_a, X_b] = −μᵀg⁻¹[X_a, X_b]_s
    (− p_rᵀ[X_a, X_b]_r when constraints restrict the shape velocities)."""
    nP = len(symbols.P)
    ginv = arith.mat(layout.ginv)
    C_mu = [[arith.value(sp.Integer(0))] * nP for _ in range(nP)]
    for (a, b), v in lie.items():
        c = arith.mneg(arith.matmul(ginv, [v[i] for i in layout.si])) if layout.si else []
        val = arith.form([(c[i][0], [symbols.mu[i]]) for i in range(len(layout.si))]
                     + [(arith.neg(v[i][0]), [symbols.p[i]]) for i in layout.ri])
        C_mu[a][b], C_mu[b][a] = val, -val
    return Step(15, "Brackets of the momenta in μ", "§3.2.4, eqs. 3.28, 3.45, 3.88",
                {"C_mu": arith.square(C_mu)}, "{P_a, P_b} = −pᵀ[X_a, X_b] = −μᵀg⁻¹[X_a, X_b]_s.",
                labels={"C_mu": "{P_a, P_b}(mu)"})


@dataclass(frozen=True, eq=False)
class RestrictedBrackets:
    """Step 16's elements for the later steps: ``coef[a, b]`` the coefficients c with
    {P_a, P_b}|_M̄ = c·P, ``C`` the bracket matrix (nP×nP, rows of back-end elements), ``XKinv`` = XK⁻¹
    (n×nP)."""

    coef: dict
    C: list
    XKinv: list


def restricted_brackets(arith, layout, symbols, connection, Kinv, lie) -> Stepped:
    """Step 16 (eqs. 3.29–3.30, 3.46–3.47, 3.89–3.90): μ|_M̄ = gᵀ(MXK⁻¹P)_s and
    {P_a, P_b}|_M̄ = coef_ab·P with coef_ab = −Σ_c γ_abc K⁻¹_c· (γ_abc = X_cᵀM[X_a, X_b])."""
    nP, n = len(symbols.P), layout.n
    M = arith.mat(layout.M)
    XKinv = arith.matmul(connection.X, Kinv)
    l = len(layout.si)
    mu_coef = (arith.matmul(arith.T(arith.mat(layout.g)), arith.matmul([M[i] for i in layout.si], XKinv,
                                                                        normal=False)) if l else [])
    mu_M = [arith.form([(mu_coef[i][j], [symbols.P[j]]) for j in range(nP)]) for i in range(l)]
    XTM = arith.matmul(arith.T(connection.X), M, normal=False) if n else []
    coef, C = {}, [[arith.value(sp.Integer(0))] * nP for _ in range(nP)]
    for (a, b), v in lie.items():
        gam = arith.matmul(XTM, v)
        c = [arith.normal(arith.neg(arith.add_many([arith.mul(gam[c_][0], Kinv[c_][j]) for c_ in range(nP)
                                         if not arith.is_zero(Kinv[c_][j])
                                                    and not arith.is_zero(gam[c_][0])])))
             for j in range(nP)]
        coef[a, b], coef[b, a] = c, [arith.neg(x) for x in c]
        val = arith.form([(c[j], [symbols.P[j]]) for j in range(nP)])
        C[a][b], C[b][a] = val, -val
    step = Step(16, "Brackets restricted to M̄", "§3.2.4, eqs. 3.29–3.30, 3.46–3.47, 3.89–3.90",
                {"mu": arith.column(mu_M), "C": arith.square(C)}, "μ|_M̄ = gᵀ(M X K⁻¹P)_s.",
                labels={"mu": "mu|M", "C": "{P_a, P_b}|M"})
    return Stepped(step, RestrictedBrackets(coef=coef, C=C, XKinv=XKinv))


def structure(arith, layout, symbols, connection, C) -> Stepped:
    """Step 17 (eqs. 3.31, 3.48, 3.91, Fig. 3.7): J in rows (ξ, P, r, P̃) as in the thesis (when
    the shape velocities are free) and J_z = [[0, X], [−Xᵀ, C]] in z = (q, P)."""
    n, d, nP, l = layout.n, layout.d, len(symbols.P), len(layout.si)
    m = nP - d
    X = arith.show(connection.X, n, nP)
    Cm = arith.square(C)
    J_z = arith.blocks([[arith.zero_block(n, n), X], [-X.T, Cm]])
    if not arith.symbolic:        # the implicit form shows J_z alone (CasADi)
        step = Step(17, "Reduced Poisson structure matrix", "§3.2.4, Fig. 3.7, eqs. 3.31, 3.48, 3.91",
                    {"J_z": J_z}, "Skew-symmetric, in z = (q, P) coordinates.",
                    labels={"J_z": "J_z (rows q, P)"})
        return Stepped(step, J_z)
    items, labels = {}, {"J": "J (rows xi, P, r, Pt)", "J_z": "J_z (rows q, P)"}
    if not layout.dependent:
        e, A = arith.show(connection.e, l, d), arith.show(connection.A, l, m)
        items["J"] = sp.BlockMatrix([
            [sp.zeros(l, l), e, sp.zeros(l, m), -A],
            [-e.T, Cm[:d, :d], sp.zeros(d, m), Cm[:d, d:]],
            [sp.zeros(m, l), sp.zeros(m, d), sp.zeros(m, m), sp.eye(m)],
            [A.T, Cm[d:, :d], -sp.eye(m), Cm[d:, d:]]]).as_explicit()
    items["J_z"] = J_z
    step = Step(17, "Reduced Poisson structure matrix", "§3.2.4, Fig. 3.7, eqs. 3.31, 3.48, 3.91", items,
                "Skew-symmetric; rows (ξ, P, r, P̃) as in the thesis, and in z = (q, P) coordinates.",
                labels=labels)
    return Stepped(step, J_z)
