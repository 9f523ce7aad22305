"""Steps 9–11 (thesis §3.2.3, Fig. 3.6): Legendre transform, velocities from momenta and the
reduced constrained Hamiltonian h = ½PᵀK⁻¹P + V."""
from __future__ import annotations

from ..steps import Step, Stepped


def legendre_transform(arith, layout, symbols, connection) -> Step:
    """Step 9 (eqs. 3.18, 3.76–3.77): P = ∂l_c/∂v = Kv, v = (Ω, ṙ)."""
    nP = len(symbols.P)
    Kv = [arith.form([(connection.K[a][b], [symbols.v[b]]) for b in range(nP)]) for a in range(nP)]
    return Step(9, "Legendre transformation", "§3.2.3, eqs. 3.18, 3.76–3.77",
                {"P": arith.column(Kv)}, "P = ∂l_c/∂v = Kv.",
                labels={"P": "(" + ", ".join(map(str, symbols.P)) + ") = dl_c/d("
                        + ", ".join(map(str, symbols.v)) + ")"})


def velocities(arith, layout, symbols, connection) -> Stepped:
    """Step 10 (eqs. 3.19, 3.78–3.79): v = K⁻¹P, with K⁻¹ = blockdiag(K_Ω⁻¹, K_r⁻¹); returns
    (step, K⁻¹). The implicit back end's inverse is a linear solve at evaluation time."""
    d, nP = layout.d, len(symbols.P)
    m = nP - d
    K_r = [[connection.K[d + i][d + j] for j in range(m)] for i in range(m)]
    K_r_inv = arith.inv(K_r, "shape metric K_r = X_rᵀMX_r") if m else []
    Kinv = arith.block_diag(connection.K_nh_inv, K_r_inv)
    v = [arith.form([(Kinv[a][b], [symbols.P[b]]) for b in range(nP)]) for a in range(nP)]
    step = Step(10, "Velocities from momenta", "§3.2.3, eqs. 3.19, 3.78–3.79",
                {"v": arith.column(v)}, "v = K⁻¹P.",
                labels={"v": "(" + ", ".join(map(str, symbols.v)) + ")"})
    return Stepped(step, Kinv)


def hamiltonian(arith, layout, symbols, Kinv) -> Stepped:
    """Step 11 (eqs. 3.20, 3.80): h = P·v − l_c = ½PᵀK⁻¹P + V."""
    h = arith.quadratic(Kinv, symbols.P, half=True) + arith.value(layout.V)
    step = Step(11, "Reduced constrained Hamiltonian", "§3.2.3, eqs. 3.20, 3.80",
                {"h": h}, "h = P·v − l_c = ½PᵀK⁻¹P + V.")
    return Stepped(step, h)
