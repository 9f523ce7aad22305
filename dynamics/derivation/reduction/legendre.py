"""Steps 9–11 (thesis §3.2.3, Fig. 3.6): Legendre transform, velocities from momenta and the
reduced constrained Hamiltonian h = ½PᵀK⁻¹P + V."""
from __future__ import annotations

from ..steps import Step


def legendre_transform(F, lay, sy, con) -> Step:
    """Step 9 (eqs. 3.18, 3.76–3.77): P = ∂l_c/∂v = Kv, v = (Ω, ṙ)."""
    nP = len(sy.P)
    Kv = [F.form([(con.K[a][b], [sy.v[b]]) for b in range(nP)]) for a in range(nP)]
    return Step(9, "Legendre transformation", "§3.2.3, eqs. 3.18, 3.76–3.77",
                {"P": F.column(Kv)}, "P = ∂l_c/∂v = Kv.",
                labels={"P": "(" + ", ".join(map(str, sy.P)) + ") = dl_c/d(" + ", ".join(map(str, sy.v)) + ")"})


def velocities(F, lay, sy, con) -> tuple[Step, list]:
    """Step 10 (eqs. 3.19, 3.78–3.79): v = K⁻¹P, with K⁻¹ = blockdiag(K_Ω⁻¹, K_r⁻¹); returns
    (step, K⁻¹). The implicit back end's inverse is a linear solve at evaluation time."""
    d, nP = lay.d, len(sy.P)
    m = nP - d
    K_r = [[con.K[d + i][d + j] for j in range(m)] for i in range(m)]
    K_r_inv = F.inv(K_r, "shape metric K_r = X_rᵀMX_r") if m else []
    Kinv = F.block_diag(con.K_nh_inv, K_r_inv)
    v = [F.form([(Kinv[a][b], [sy.P[b]]) for b in range(nP)]) for a in range(nP)]
    return Step(10, "Velocities from momenta", "§3.2.3, eqs. 3.19, 3.78–3.79",
                {"v": F.column(v)}, "v = K⁻¹P.",
                labels={"v": "(" + ", ".join(map(str, sy.v)) + ")"}), Kinv


def hamiltonian(F, lay, sy, Kinv) -> tuple[Step, object]:
    """Step 11 (eqs. 3.20, 3.80): h = P·v − l_c = ½PᵀK⁻¹P + V."""
    h = F.quadratic(Kinv, sy.P, half=True) + F.value(lay.V)
    return Step(11, "Reduced constrained Hamiltonian", "§3.2.3, eqs. 3.20, 3.80",
                {"h": h}, "h = P·v − l_c = ½PᵀK⁻¹P + V."), h
