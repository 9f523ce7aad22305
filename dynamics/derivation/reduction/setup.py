"""Steps 1–3 (thesis §3.2.1–3.2.2, Figs. 3.3–3.5): set-up, the constraint distribution and the
full symmetry group, and the choices every later step relies on (the :class:`Layout`).

Beyond the thesis: when the constraints restricted to the fiber have rank k_s < k (more
constraints than the fiber can absorb, e.g. a snake with more than three wheeled links), the
remaining k − k_s constraints restrict the shape velocities. The reconstruction then solves
the constraints for k pivot velocities (k_s fiber ones, k − k_s *dependent* shape ones) and
keeps the other shape velocities free; with k_s = k this is exactly the thesis's method.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import sympy as sp

from nhgait.dynamics.derivation.input.notation import method_name, system_names

from ...algebra.matrices import numeric_pivots, strip_factors
from ...algebra.trig import TIDY_NODES, tidy, tree_size
from ..steps import Step, readable
from ..symmetry import SymmetryTest, distribution_pivots, group_transform, symmetry_test
from ..system import System

#: largest matrix the explicit form inverts symbolically (pivot block, K_Ω, K_r); larger
#: systems use the implicit form (linear solves by CasADi at evaluation time)
EXPLICIT_MAX_INVERSE = 2


def _sym(name):
    return sp.Symbol(name, real=True)


@dataclass(frozen=True, eq=False)
class Layout:
    """What steps 1–3 decide: coordinates split, pivots, basis, g and the form.

    Attributes
    ----------
    si, ri : indices of the fiber s and shape r coordinates in q.
    pivots : k indices of q whose velocities the constraints determine (fiber pivots first,
        then dependent shape coordinates; empty when k = 0).
    free : indices of the free shape coordinates (their momenta are the P̃).
    N : sympy l×d basis of S_q in the s-components (step 3).
    g, ginv : the reconstruction's g (l×l) and its inverse.
    W, Wb : ω and ω with its fiber columns in body velocities (ω_s g).
    form : "explicit" (every step a sympy object) or "implicit" (linear solves at evaluation).
    """

    system: System
    version: str
    fiber: tuple
    shape: tuple
    si: tuple
    ri: tuple
    pivots: tuple
    free: tuple
    N: sp.Matrix
    g: sp.Matrix
    ginv: sp.Matrix
    M: sp.Matrix
    V: sp.Expr
    W: sp.Matrix
    Wb: sp.Matrix
    form: str
    symmetry: SymmetryTest = field(repr=False, default=None)

    @property
    def n(self):
        return self.system.n

    @property
    def k(self):
        return self.system.k

    @property
    def d(self):
        return self.N.shape[1]

    @property
    def uses_pivot_block(self) -> bool:
        """Step 5 inverts B = ω_b[:, pivots] (some free shape velocity enters ω)."""
        return bool(self.k) and any(self.Wb[i, j] != 0 for i in range(self.k) for j in self.free)

    @property
    def dependent(self):
        """Shape coordinates whose velocities the constraints determine."""
        return tuple(i for i in self.pivots if i in self.ri)

    def symbols(self):
        """The symbols of the later steps: canonical momenta p_q, P (nonholonomic), P̃ (free
        shape), ξ, Ω, μ, and v = (Ω, ṙ_free)."""
        names, q_dot = self.system.coordinates, self.system.q_dot
        d, l = self.d, len(self.si)
        taken = system_names(self.system)      # a user's p, Omega, xi1 … never meets the method's

        def sym(name):
            return _sym(method_name(name, taken))
        P_nh = [sym("p")] if d == 1 else [sym(f"p{i + 1}") for i in range(d)]
        Om = [sym("Omega")] if d == 1 else [sym(f"Omega{i + 1}") for i in range(d)]
        Pt = [sym(f"pt_{names[i]}") for i in self.free]
        return _Symbols(p=[sym(f"p_{c}") for c in names], P_nh=P_nh, Pt=Pt, P=P_nh + Pt,
                        xi=[sym(f"xi{i + 1}") for i in range(l)], Om=Om,
                        mu=[sym(f"mu{i + 1}") for i in range(l)],
                        v=Om + [q_dot[i] for i in self.free])


@dataclass(frozen=True)
class _Symbols:
    p: list
    P_nh: list
    Pt: list
    P: list
    xi: list
    Om: list
    mu: list
    v: list


def set_up(system: System, M: sp.Matrix) -> Step:
    """Step 1 (§3.2.1, Fig. 3.3): q, L, ω, τ, M = ∂²L/∂q̇² (eq. 2.5), V and the parameters."""
    return Step(1, "Set-up", "§3.2.1, Fig. 3.3", {
        "q": sp.Matrix(system.q).T, "L": system.L, "omega": system.omega(),
        "tau": system.force_vector().T, "M": readable(M), "V": system.potential(),
        "parameters": ", ".join(f"{k_}={v}" for k_, v in system.parameters.items())},
        "Coordinates, Lagrangian, Pfaffian constraints ω(q)q̇ = 0, forces and parameters.",
        labels={"omega": "omega (k x n)", "tau": "tau"})


def distribution_sentence(system: System) -> str:
    """What step 2's columns are and where they span D_q: built from the pivot block
    B = ω[:, pivots] without divisions, column j = det B·e_j − adj(B)ω_j, they span D_q where
    det B ≠ 0 — and may vanish where det B = 0 even though rank ω = k there (the sleigh's
    (0, 0, sin θ, 0) at θ = 0): a chart of D_q, not a basis everywhere."""
    if not system.k:
        return "No constraints: D_q is the whole tangent space (the unit columns)."
    pivots = distribution_pivots(system)
    B = system.omega().extract(list(range(system.k)), pivots)
    names = ", ".join(system.coordinates[i] for i in pivots)
    head = (f"Each column is det B·e_j − adj(B)·ω_j for a free coordinate j, with B = ω[:, ({names})] "
            "(entries k×k minors of ω, no divisions).")
    if system.k > 3 or sum(tree_size(e, TIDY_NODES) for e in B) > TIDY_NODES:   # det B: too costly to state
        return (f"{head} The columns span D_q where det B ≠ 0; where det B = 0 some may vanish although "
                "rank ω = k.")
    det = sp.factor(tidy(B.det(method="berkowitz")))
    if det.is_Number:
        return f"{head} det B = {sp.sstr(det)} is constant: the columns span D_q at every q."
    return (f"{head} The columns span D_q where det B ≠ 0; where det B = {sp.sstr(det)} = 0 some may "
            "vanish although rank ω = k there.")


def distribution_and_group(system: System, symmetry: SymmetryTest, N: sp.Matrix, si, ri) -> tuple[Step, Step]:
    """Steps 2–3 (§3.2.2, eqs. 3.3–3.8, 3.62–3.68, Table 3.1): D_q = null ω and the chosen
    full symmetry group with its Lie algebra element ξ (N, no spurious factor in s)."""
    n, chosen = system.n, symmetry.chosen
    xi_Q = sp.zeros(n, N.shape[1])
    for a, i in enumerate(si):
        xi_Q[i, :] = N[a, :]
    names = system.coordinates
    step2 = Step(2, "Constraint distribution D_q = null ω(q)", "§3.2.2, eqs. 3.3–3.4, 3.62–3.64",
                 {"D": symmetry.distribution}, distribution_sentence(system),
                 labels={"D": "D_q (columns)"})
    step3 = Step(3, "Full symmetry group", "§3.2.2, Table 3.1, eqs. 3.5–3.8, 3.65–3.68", {
        "table": symmetry, "s": ", ".join(chosen.fiber), "r": ", ".join(names[i] for i in ri),
        "G": chosen.group, "xi_Q": xi_Q, "xi": N, "chosen_by": symmetry.chosen_by},
        "Candidates: every set of fibre coordinates, T_q Orb = their span; S_q = D_q ∩ T_q Orb; chosen "
        "by the selection rule of docs/reduction.md.",
        labels={"s": "fibre coordinates (step.s)", "r": "shape coordinates (step.r)",
                "xi_Q": "xi_Q^q (columns)", "xi": "xi (Lie algebra element)", "chosen_by": "chosen by"})
    return step2, step3


def body_omega(W: sp.Matrix, g: sp.Matrix, si) -> sp.Matrix:
    """ω with its fiber columns in body velocities, ω_s g (so ω_s ṡ = (ω_s g)ξ): for an SE(2)
    symmetry its pivot blocks do not depend on the heading."""
    Wb = sp.Matrix(W)
    if W.shape[0]:
        body = tidy(W[:, list(si)] * g)
        for a, i in enumerate(si):
            Wb[:, i] = body[:, a]
    return Wb


#: most pivot sets compared by their worst conditioning (else the greedy choice)
PIVOT_CANDIDATES = 120


def _pivots(system: System, Wb: sp.Matrix, si, ri) -> tuple:
    """k pivot columns of ω_b = (ω_s g, ω_r): as many fiber columns as rank ω_s, then shape
    columns. Among the admissible sets the one whose normalised |det| is largest in the worst
    of a few configurations (q = 0 and random ones) is chosen, so the basis avoids singular
    points of its own making where it can."""
    import itertools
    k = system.k
    if not k:
        return ()
    f = sp.lambdify([system.q, system.param_symbols], Wb, "numpy")
    pv = system.param_vector()
    samples = [np.zeros(system.n)] + list(system.sample_configurations(4, seed=17))
    mats = [np.array(f(qv, pv), dtype=float).reshape(k, system.n) for qv in samples]
    greedy = numeric_pivots(mats[1], list(si) + list(reversed(ri)))
    k_s = sum(1 for i in greedy if i in si)

    def score(cols):       # |det B| / Π‖row of ω_b‖: how well the pivots carry each row
        worst = np.inf
        for A in mats:
            norm = np.prod(np.linalg.norm(A, axis=1)) or 1.0
            worst = min(worst, abs(np.linalg.det(A[:, list(cols)])) / norm)
        return worst
    fiber_sets = list(itertools.combinations(si, k_s))
    shape_sets = list(itertools.combinations(list(reversed(ri)), k - k_s))
    if len(fiber_sets) * len(shape_sets) > PIVOT_CANDIDATES:
        return tuple(i for i in list(si) + list(reversed(ri)) if i in greedy)
    best = max(((a + b) for a in fiber_sets for b in shape_sets), key=score)
    return tuple(best)


def choose_form(k: int, d: int, m: int, dependent: int) -> str:
    """Explicit when every symbolic inverse is at most EXPLICIT_MAX_INVERSE square and the
    shape velocities are free; implicit otherwise."""
    if dependent or max(k, d, m) > EXPLICIT_MAX_INVERSE:
        return "implicit"
    return "explicit"


class LayoutChoice(NamedTuple):
    """The choices of steps 1–3 (``layout``) and the displayed ``steps`` 1, 2, 3."""

    layout: Layout
    steps: list


def choose_layout(system: System, version: str | None = None, form: str | None = None) -> LayoutChoice:
    """Steps 1–3 and the choices of the reconstruction."""
    names = system.coordinates
    M = system.mass_matrix()
    symmetry = symmetry_test(system, M)
    fiber = symmetry.chosen.fiber
    si = tuple(names.index(c) for c in fiber)
    ri = tuple(i for i in range(system.n) if i not in si)
    N = strip_factors(symmetry.chosen.xi, [system.q[i] for i in si])
    steps = [set_up(system, M), *distribution_and_group(system, symmetry, N, si, ri)]
    if version is None:
        pf = system.planar_frame
        version = "B" if pf is not None and pf[0] in fiber and pf[1] in fiber else "A"
    g = group_transform(system, fiber, version)
    ginv = tidy(g.T) if version == "B" else sp.eye(len(si))
    W = system.omega()
    Wb = body_omega(W, g, si)
    pivots = _pivots(system, Wb, si, ri)
    free = tuple(i for i in ri if i not in pivots)
    dependent = [i for i in pivots if i in ri]
    if form is None:
        form = choose_form(system.k, N.shape[1], len(free), len(dependent))
    layout = Layout(system=system, version=version, fiber=fiber, shape=tuple(names[i] for i in ri),
                    si=si, ri=ri, pivots=pivots, free=free, N=N, g=g, ginv=ginv,
                    M=M, V=system.potential(), W=W, Wb=Wb, form=form, symmetry=symmetry)
    return LayoutChoice(layout, steps)

