"""Steps 18–20 (thesis §3.2.5, Fig. 3.7): the gradient of h, the reduced constrained
Hamiltonian equations and the reconstruction of the fiber velocities.

Momentum equations (Hamel form, what ż = J_z∇h + (0, Xᵀτ) says row by row):

    Ṗ_a = Σ_b {P_a, P_b}|_M̄ v_b − X_aᵀ ∂h/∂q + X_aᵀτ,   v = K⁻¹P,
    ∂h/∂q_i = ½ Pᵀ(∂K⁻¹/∂q_i)P + ∂V/∂q_i = −½ vᵀ(∂K/∂q_i)v + ∂V/∂q_i,

(``arith.diff_inverse``: the exact back ends differentiate K⁻¹ entry by entry, the CasADi back
end uses −K⁻¹K_qK⁻¹, so no inverse is differentiated),

zero along the fiber by symmetry. Each Ṗ_a is assembled as a quadratic form in P with normal
coefficients, plus −X_aᵀ∂V/∂q and the forces.
"""
from __future__ import annotations

from dataclasses import dataclass

from ...errors import ModelError
from ..steps import Step, Stepped


@dataclass(frozen=True, eq=False)
class HamiltonianGradient:
    """Step 18's elements: ``quad[i]`` = ∂K⁻¹/∂q_i for the shape coordinates i where it is not
    zero, ``dV[i]`` = ∂V/∂q_i for every shape coordinate i (∂h/∂q_i = ½Pᵀ quad[i] P + dV[i])."""

    quad: dict
    dV: dict


@dataclass(frozen=True, eq=False)
class MomentumEquations:
    """Step 19's elements: ``Pdot`` (nP display values Ṗ_a), ``qdot`` (n values q̇ = XK⁻¹P) and
    ``xi_coef`` (l×nP: ξ = xi_coef·P)."""

    Pdot: list
    qdot: list
    xi_coef: list


def gradient(arith, layout, symbols, connection, Kinv) -> Stepped:
    """Step 18 (eqs. 3.32, 3.49, 3.92): ∇h = (0, ∂h/∂P, ∂h/∂r, ∂h/∂P̃); ∂h/∂s = 0 by symmetry
    (checked exactly by the explicit back ends)."""
    q, nP = layout.system.q, len(symbols.P)
    V = arith.frac(layout.V)
    if arith.symbolic:
        for i in layout.si:
            if any(not arith.is_zero(arith.normal(arith.diff(e, q[i]))) for r in connection.K for e in r) or \
                    not arith.is_zero(arith.normal(arith.diff(V, q[i]))):
                raise ModelError(["h depends on the fiber coordinates: the chosen group is not a symmetry"])
    quad = {}                      # i -> ∂K⁻¹/∂q_i (i ∈ r): ∂h/∂q_i = ½Pᵀ(∂K⁻¹/∂q_i)P + ∂V/∂q_i
    dV = {}
    for i in layout.ri:
        dKinv = arith.diff_inverse(Kinv, connection.K, q[i])
        if any(not arith.is_zero(e) for r in dKinv for e in r):
            quad[i] = dKinv
        dV[i] = arith.normal(arith.diff(V, q[i]))
    shown = [arith.quadratic(quad[i], symbols.P, half=True) + arith.expr(dV[i]) if i in quad
             else arith.expr(dV[i])
             for i in layout.ri]
    dh_dP = [arith.form([(Kinv[a][b], [symbols.P[b]]) for b in range(nP)]) for a in range(nP)]
    step = Step(18, "Gradient of h", "§3.2.5, eqs. 3.32, 3.49, 3.92",
                {"dh_dP": arith.column(dh_dP), "dh_dr": arith.column(shown)}, "∂h/∂s = 0 by symmetry.",
                labels={"dh_dP": "dh/d(" + ", ".join(map(str, symbols.P)) + ")",
                        "dh_dr": "dh/d(" + ", ".join(layout.shape) + ")"})
    return Stepped(step, HamiltonianGradient(quad=quad, dV=dV))


@dataclass(frozen=True, eq=False)
class MomentumInputs:
    """What step 19 reads from the earlier steps: the :class:`~.connection.Connection`
    (steps 5–8), K⁻¹ (step 10), the restricted brackets (step 16) and the gradient of h
    (step 18)."""

    connection: object
    Kinv: list
    brackets: object
    gradient: HamiltonianGradient


def _bracket_products(arith, inputs: MomentumInputs, a):
    """The bracket part Σ_b {P_a, P_b}|_M̄ v_b of Ṗ_a as a table ``products[j][l]`` of the
    coefficient terms of P_j P_l (before they are summed)."""
    Kinv, nP = inputs.Kinv, len(inputs.Kinv)
    products = [[[] for _ in range(nP)] for _ in range(nP)]
    for b in range(nP):
        cab = inputs.brackets.coef.get((a, b))
        if cab is None:
            continue
        for j in range(nP):
            if not arith.is_zero(cab[j]):
                for l_ in range(nP):
                    if not arith.is_zero(Kinv[b][l_]):
                        products[j][l_].append(arith.mul(cab[j], Kinv[b][l_]))
    return products


def _momentum_rate(arith, layout, symbols, inputs: MomentumInputs, forces, a):
    """Ṗ_a as Σ_{j≤l} c_jl P_j P_l − X_aᵀ∂V/∂q + (Xᵀτ)_a (−X_aᵀ∂h/∂q through the derivative
    of K⁻¹ along X_a)."""
    nP = len(symbols.P)
    connection, grad = inputs.connection, inputs.gradient
    products = _bracket_products(arith, inputs, a)
    Xa = [connection.X[i][a] for i in range(layout.n)]
    Q = arith.directional_inverse(inputs.Kinv, connection.K, layout.system.q, Xa, grad.quad)
    for j in range(nP):                    # −X_aᵀ∂h/∂q = −½ Pᵀ(D_{X_a}K⁻¹)P − X_aᵀ∇V
        for l_ in range(nP):
            if not arith.is_zero(Q[j][l_]):
                products[j][l_].append(arith.neg(arith.scale(Q[j][l_], 1, 2)))
    potential = [arith.neg(arith.mul(connection.X[i][a], dv)) for i, dv in grad.dV.items()
                 if not arith.is_zero(dv) and not arith.is_zero(connection.X[i][a])]
    terms = []
    for j in range(nP):
        for l_ in range(j, nP):
            raw = products[j][j] if j == l_ else products[j][l_] + products[l_][j]
            if raw:
                terms.append((arith.normal(arith.add_many(raw)), [symbols.P[j], symbols.P[l_]]))
    if potential:
        terms.append((arith.normal(arith.add_many(potential)), []))
    return arith.form(terms) + forces[a]


def _forces(arith, layout, symbols, connection, XKinv):
    """Xᵀτ(t, q, q̇ = XK⁻¹P, u): coefficients of the affine part in P normalised, and any
    remainder (forces nonlinear in the velocities) as one more term."""
    nP = len(symbols.P)
    qd = layout.system.q_dot
    qdot = arith.matmul(XKinv, arith.vec(symbols.P), normal=False)
    tau = [[arith.subs(arith.frac(e), {arith.sub_key(v): qdot[j][0] for j, v in enumerate(qd)})]
           for e in layout.system.force_vector()]
    XtT = arith.matmul(arith.T(connection.X), tau, normal=False) if nP else []
    out = []
    for a in range(nP):
        total = XtT[a][0]
        c0, cs = arith.linear_split(total, symbols.P)
        terms = [(c0, [])] + [(c, [v]) for c, v in zip(cs, symbols.P, strict=True)]
        # a force need not be affine in the momenta (drag −c q̇², friction sign(q̇)): what the
        # affine split does not hold is kept as its own term, never dropped
        affine = arith.add_many([c0] + [arith.mul(c, arith.sym(v))
                                        for c, v in zip(cs, symbols.P, strict=True)])
        rest = arith.normal(arith.add_many([total, arith.neg(affine)]))
        if not arith.is_zero(rest):
            terms.append((rest, []))
        out.append(arith.form(terms))
    return out


def equations(arith, layout, symbols, inputs: MomentumInputs) -> Stepped:
    """Step 19 (eqs. 3.33, 3.50, 3.93): (ξ, Ṗ, ṙ, dP̃/dt) = J∇h + (0, Xᵀτ); the forces enter
    through the constraint-adapted basis X, never by hand."""
    nP, d, l = len(symbols.P), layout.d, len(layout.si)
    m = nP - d
    connection, Kinv, XKinv = inputs.connection, inputs.Kinv, inputs.brackets.XKinv
    forces = _forces(arith, layout, symbols, connection, XKinv)
    Pdot = [_momentum_rate(arith, layout, symbols, inputs, forces, a) for a in range(nP)]
    eA = [list(r1) + list(r2) for r1, r2 in zip(connection.e or [[] for _ in range(l)],
                                                arith.mneg(connection.A) if m
                                                else [[] for _ in range(l)], strict=True)]
    xi_coef = arith.matmul(eA, Kinv) if l and nP else arith.zeros(l, nP)
    xi = [arith.form([(xi_coef[i][j], [symbols.P[j]]) for j in range(nP)]) for i in range(l)]
    qdot = [arith.form([(XKinv[i][j], [symbols.P[j]]) for j in range(nP)]) for i in range(layout.n)]
    step = Step(19, "Reduced constrained Hamiltonian equations", "§3.2.5, eqs. 3.33, 3.50, 3.93", {
        "xi": arith.column(xi), "P_dot": arith.column(Pdot[:d]),
        "r_dot": arith.column([qdot[i] for i in layout.ri]),
        "Pt_dot": arith.column(Pdot[d:]), "F": arith.column(forces)},
        "(ξ, Ṗ, ṙ, dP̃/dt) = J∇h + (0, Xᵀτ).", labels={"F": "forces X^T tau"})
    return Stepped(step, MomentumEquations(Pdot=Pdot, qdot=qdot, xi_coef=xi_coef))


def fiber_velocities(arith, layout, symbols, eqs) -> Step:
    """Step 20 (eqs. 3.51, 3.94): ṡ = gξ."""
    nP = len(symbols.P)
    coef = (arith.matmul(arith.mat(layout.g), eqs.xi_coef) if layout.si and nP
            else arith.zeros(len(layout.si), nP))
    sdot = [arith.form([(coef[i][j], [symbols.P[j]]) for j in range(nP)]) for i in range(len(layout.si))]
    return Step(20, "Reconstruction of the fiber velocities", "§3.2.5, eqs. 3.51, 3.94",
                {"s_dot": arith.column(sdot)}, "ṡ = gξ.", labels={"s_dot": "s_dot = g xi"})


def momenta_of_velocity(arith, layout, symbols, connection) -> list:
    """P = XᵀM(q)q̇ (Tables 3.2–3.3), linear in q̇ with normal coefficients."""
    qd = layout.system.q_dot
    nP = len(symbols.P)
    XTMq = (arith.matmul(arith.matmul(arith.T(connection.X), arith.mat(layout.M), normal=False),
                         arith.vec(qd), normal=False) if nP else [])
    out = []
    for a in range(nP):
        c0, cs = arith.linear_split(XTMq[a][0], list(qd))
        out.append(arith.form([(c, [v]) for c, v in zip(cs, qd, strict=True)]))
    return out
