"""Steps 4–8 (thesis §3.2.2, Fig. 3.5): nonholonomic momentum, reconstruction equation,
body-fixed basis, reduced Lagrangian and reduced constrained Lagrangian.

Every function takes the arithmetic back end ``arith`` (see :mod:`.arithmetic`), the
:class:`~.setup.Layout` and the symbols, and returns its :class:`~nhgait.dynamics.derivation.steps.Step`
together with the elements later steps need, as values: step 5 a frozen
:class:`Reconstruction`, steps 6–8 one element each; :class:`Connection` holds them all.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

from ..steps import Step, Stepped


@dataclass(frozen=True, eq=False)
class Reconstruction:
    """What step 5 gives the later steps (matrices are lists of rows of back-end elements).

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
    def of(cls, reconstruction: Reconstruction, *, xi_c, l_red, K) -> Connection:
        parts = {f.name: getattr(reconstruction, f.name) for f in fields(Reconstruction)}
        return cls(**parts, xi_c=xi_c, l_red=l_red, K=K)


def momentum(arith, layout, symbols) -> Step:
    """Step 4 (eqs. 3.9, 3.69): p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ = Σ_s (∂L/∂ṡ) N_si."""
    qd = layout.system.q_dot
    M = arith.mat(layout.M)
    p = []
    for j in range(layout.d):
        terms = [(arith.normal(arith.add_many([arith.mul(arith.frac(layout.N[a, j]), M[i][c])
                                               for a, i in enumerate(layout.si)
                                       if not arith.is_zero(M[i][c])])), [qd[c]]) for c in range(layout.n)]
        p.append(arith.form(terms))
    items = {"p": arith.column(p)}
    return Step(4, "Nonholonomic momentum", "§3.2.2 (3), eqs. 3.9, 3.69", items,
                "p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ (none when d = 0).",
                labels={"p": "p (nonholonomic momenta " + ", ".join(map(str, symbols.P_nh)) + ")"})


@dataclass(frozen=True, eq=False)
class _LiftMatrices:
    """What every horizontal lift of step 5 reads, as back-end elements (lists of rows):
    M (n×n), the basis N of S_q (l×d) and Nᵀ, K_Ω⁻¹ (d×d) and g (l×l)."""

    M: list
    N: list
    NT: list
    K_nh_inv: list
    g: list


def _shape_column(arith, layout, lift: _LiftMatrices, pivot_solution, alpha):
    """The horizontal lift X_α of ∂/∂r_α (eq. 2.47; ``alpha`` the index of r_α in q): 1 at r_α,
    the pivot velocities from ω X_α = 0 (fiber pivots in body velocities ξ, ṡ = gξ), then made
    M-orthogonal to every ξ_Q^i (so K is block-diagonal). ``pivot_solution`` is B⁻¹ω_b e_α
    (k×1), or None when ω_b e_α = 0."""
    n = layout.n
    column = [arith.ZERO] * n
    column[alpha] = arith.ONE
    if pivot_solution is not None:
        xi = [arith.ZERO] * len(layout.si)
        for i, pivot in enumerate(layout.pivots):
            if pivot in layout.si:
                xi[layout.si.index(pivot)] = arith.neg(pivot_solution[i][0])
            else:
                column[pivot] = arith.neg(pivot_solution[i][0])
        sdot = arith.matmul(lift.g, [[x] for x in xi], normal=False)
        for a, i in enumerate(layout.si):
            column[i] = sdot[a][0]
    if layout.d:
        inner = arith.matmul([lift.M[i] for i in layout.si], [[x] for x in column], normal=False)
        beta = arith.mneg(arith.matmul(lift.K_nh_inv, arith.matmul(lift.NT, inner)))
        Nb = arith.matmul(lift.N, beta, normal=False)
        for a, i in enumerate(layout.si):
            column[i] = arith.add_many([column[i], Nb[a][0]])
    return [arith.normal(x) for x in column]


def reconstruction(arith, layout, symbols) -> Stepped:
    """Step 5 (eqs. 2.47, 3.10–3.13, 3.36, 3.71): solve ω_s ṡ + ω_r ṙ = 0 with the momentum
    definition for ṡ = −A_q ṙ + Γ_q p; A = g⁻¹A_q, Γ = g⁻¹Γ_q = g⁻¹N K_Ω⁻¹. The pivot block B
    of ω_b is solved against the free shape columns (``arith.solve``: a linear solve in the
    implicit form)."""
    n, k, d, l = layout.n, layout.k, layout.d, len(layout.si)
    M, N = arith.mat(layout.M), arith.mat(layout.N)
    NT = arith.T(N) if d else []
    K_nh = (arith.matmul(arith.matmul(NT, [[M[i][j] for j in layout.si] for i in layout.si], normal=False), N)
            if d else [])
    K_nh_inv = arith.inv(K_nh, "kinetic metric K_Ω = NᵀM_ssN") if d else []
    W = arith.mat(layout.Wb) if k else []
    needs_B = k and any(not arith.is_zero(W[i][j]) for i in range(k) for j in layout.free)
    rhs = [alpha for alpha in layout.free if k and any(not arith.is_zero(W[i][alpha]) for i in range(k))]
    sol = arith.solve([[W[i][pivot] for pivot in layout.pivots] for i in range(k)],
                      [[W[i][alpha] for alpha in rhs] for i in range(k)],
                  "pivot block of ω") if needs_B and rhs else []
    lift = _LiftMatrices(M=M, N=N, NT=NT, K_nh_inv=K_nh_inv, g=arith.mat(layout.g))
    cols = [_shape_column(arith, layout, lift,
                          [[sol[i][rhs.index(alpha)]] for i in range(k)] if alpha in rhs else None, alpha)
            for alpha in layout.free]
    X = [[arith.ZERO] * (d + len(cols)) for _ in range(n)]
    for j in range(d):
        for a, i in enumerate(layout.si):
            X[i][j] = N[a][j]
    for b, col in enumerate(cols):
        for i in range(n):
            X[i][d + b] = col[i]
    ginv = arith.mat(layout.ginv)
    A = (arith.matmul(ginv, [[arith.neg(X[i][d + b]) for b in range(len(cols))] for i in layout.si]) if cols
         else [[] for _ in range(l)])
    Gamma = arith.matmul(ginv, arith.matmul(N, K_nh_inv)) if d else [[] for _ in range(l)]
    result = Reconstruction(X=X, K_nh=K_nh, K_nh_inv=K_nh_inv, A=A,
                            e=arith.matmul(ginv, N) if d else [[] for _ in range(l)])
    rdot = arith.vec([layout.system.q_dot[i] for i in layout.free])
    sdot = arith.vec([layout.system.q_dot[i] for i in layout.si])
    xi = arith.madd(arith.mneg(arith.matmul(A, rdot, normal=False)) if cols else arith.zeros(l, 1),
                arith.matmul(Gamma, arith.vec(symbols.P_nh), normal=False) if d else arith.zeros(l, 1))
    step = Step(5, "Reconstruction equation", "§3.2.2 (4), eqs. 2.47, 3.10–3.13, 3.36, 3.71", {
        "g": layout.g, "xi_body": arith.show(arith.matmul(ginv, sdot), l, 1),
        "A": arith.show(A, l, len(cols)), "Gamma": arith.show(Gamma, l, d), "xi": arith.show(xi, l, 1)},
        "Solve ω_s ṡ + ω_r ṙ = 0 with the momentum definition for ṡ; ξ = g⁻¹ṡ.",
        labels={"xi_body": "g^-1 s_dot", "A": "A(r)", "Gamma": "Gamma(r)", "xi": "xi = -A r_dot + Gamma p"})
    return Stepped(step, result)


def body_basis(arith, layout, symbols, reconstruction: Reconstruction) -> Stepped:
    """Step 6 (eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73): e = g⁻¹N, Ω = K_Ω⁻¹p, so Γp = eΩ and
    ξ = −Aṙ + eΩ on the constraints."""
    l, d, m = len(layout.si), layout.d, len(layout.free)
    rdot = arith.vec([layout.system.q_dot[i] for i in layout.free])
    xi_c = arith.madd(arith.mneg(arith.matmul(reconstruction.A, rdot, normal=False)) if m
                      else arith.zeros(l, 1),
                  arith.matmul(reconstruction.e, arith.vec(symbols.Om), normal=False) if d
                      else arith.zeros(l, 1))
    Omega = arith.matmul(reconstruction.K_nh_inv, arith.vec(symbols.P_nh)) if d else []
    step = Step(6, "Body-fixed basis e and Ω", "§3.2.2 (5), eqs. 3.14–3.15, 3.37–3.38, 3.72–3.73", {
        "e": arith.show(reconstruction.e, l, d), "Omega": arith.show(Omega, d, 1),
        "xi": arith.show(xi_c, l, 1)}, "Γ(r)p = eΩ.",
        labels={"e": "e = g^-1 xi_Q", "Omega": "Omega = K_Omega^-1 p", "xi": "xi = -A r_dot + e Omega"})
    return Stepped(step, xi_c)


def reduced_lagrangian(arith, layout, symbols) -> Stepped:
    """Step 7 (eqs. 3.16, 3.74): l(r, ṙ, ξ) = L with ṡ = gξ."""
    qd = layout.system.q_dot
    sdot = arith.matmul(arith.mat(layout.g), arith.vec(symbols.xi), normal=False)
    l_red = arith.normal(arith.subs(arith.frac(layout.system.L),
                                    {arith.sub_key(qd[i]): sdot[a][0] for a, i in enumerate(layout.si)}))
    step = Step(7, "Reduced Lagrangian l(r, ṙ, ξ)", "§3.2.2 (6), eqs. 3.16, 3.74",
                {"l": arith.expr(l_red)}, "L with ṡ = gξ.")
    return Stepped(step, l_red)


def constrained_lagrangian(arith, layout, symbols, reconstruction: Reconstruction) -> Stepped:
    """Step 8 (eqs. 3.17, 3.75): l_c(r, ṙ, Ω) = ½vᵀKv − V with v = (Ω, ṙ) and K = XᵀMX,
    block-diagonal (K_Ω, K_r): no Ω–ṙ cross terms."""
    d, m = layout.d, len(layout.free)
    M = arith.mat(layout.M)
    Xr = [[row[d + b] for b in range(m)] for row in reconstruction.X]
    K_r = arith.matmul(arith.matmul(arith.T(Xr), M, normal=False), Xr) if m else []
    K = arith.block_diag(reconstruction.K_nh, K_r)
    l_c = arith.quadratic(K, symbols.v, half=True) - arith.value(layout.V)
    step = Step(8, "Reduced constrained Lagrangian l_c(r, ṙ, Ω)", "§3.2.2 (7), eqs. 3.17, 3.75",
                {"l_c": l_c, "K": arith.show(K, d + m, d + m)}, "l with ξ = −Aṙ + eΩ; no Ω–ṙ cross terms.",
                labels={"K": "K = X^T M X"})
    return Stepped(step, K)
