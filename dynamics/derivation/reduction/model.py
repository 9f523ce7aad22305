"""The result type of the reduction, :class:`ReducedODE`, and what it reports besides the
equations: the Table 2.1 class, the singular set and the implicit form's description."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import sympy as sp

from nhgait.dynamics.derivation.cse_text import cse_lines, wants_cse
from nhgait.dynamics.derivation.input.notation import symmetry_choice_lines
from nhgait.dynamics.reprs import ModelDisplay

from ...algebra.trig import TIDY_NODES, tidy, tree_size
from ..formulation_base import Formulation, LoopDynamics
from ..steps import DISPLAY_OPS, Steps, default_symbol_names, readable, text_of
from ..symmetry import SymmetryTest
from ..system import System

PURELY_MECHANICAL = "purely mechanical"
PRINCIPALLY_KINEMATIC = "principally kinematic"
PURELY_DYNAMIC = "purely dynamic"
MIXED = "mixed"

#: largest matrix whose determinant the singular set writes out (larger: unevaluated det)
SINGULAR_DET_MAX = 3
#: printed size of a CasADi expression in the implicit form's steps
CASADI_TEXT_MAX = 4000


@dataclass(frozen=True)
class CasadiText:
    """A CasADi expression of the implicit form, kept as its printed text (shared
    subexpressions as ``@1 = …``), its shape and its operation count."""

    text: str
    shape: tuple
    operations: int

    def __str__(self):
        return self.text

    def __repr__(self):
        return f"<CasADi {self.shape[0]}×{self.shape[1]} expression, {self.operations} operations>"


def casadi_text(obj):
    """Printable stand-in for an SX object (other objects unchanged)."""
    import casadi as ca
    if isinstance(obj, list):
        obj = ca.vertcat(*obj) if obj else ca.SX(0, 1)
    if not isinstance(obj, ca.SX):
        return obj
    ops = (ca.Function("f", [ca.vertcat(*ca.symvar(obj)) if ca.symvar(obj) else ca.SX(0, 1)], [obj])
           .n_instructions())
    text = str(obj)
    if len(text) > CASADI_TEXT_MAX:
        text = text[:CASADI_TEXT_MAX] + f" … ({len(text)} characters; evaluate through model.numeric)"
    return CasadiText(text=text, shape=obj.shape, operations=int(ops))


@dataclass(frozen=True)
class ImplicitForm:
    """What the implicit form solves at evaluation time (CasADi, ``model.numeric``).

    With B = ω_b[:, pivots] (k×k; ω_b = (ω_s g, ω_r), fiber velocities in the body frame),
    N the basis of S_q, K_Ω = NᵀM_ssN:

    1. X_α = e_α − (B⁻¹ω e_α on the pivot rows), made M-orthogonal to N: X = [N, X_α] (step 5);
    2. K = XᵀMX; v solves K v = P (steps 8–10);
    3. q̇ = Xv; Ṗ_a = −Σ_bc γ_abc v_b v_c + ½ Σ_i X_ia vᵀK_{,i}v − X_aᵀ∇V + X_aᵀτ with
       γ_abc = X_cᵀM[X_a, X_b] (steps 15–19).

    Attributes hold the sympy ingredients: ``B`` (pivot block), ``N``, ``M``, ``omega``.
    """

    B: sp.Matrix
    N: sp.Matrix
    M: sp.Matrix
    omega: sp.Matrix
    pivots: tuple

    @classmethod
    def of(cls, layout):
        B = layout.Wb.extract(list(range(layout.k)), list(layout.pivots)) if layout.k else sp.zeros(0, 0)
        return cls(B=B, N=layout.N, M=layout.M, omega=layout.W,
                   pivots=tuple(layout.system.coordinates[i] for i in layout.pivots))


def classify(layout, A_zero: bool) -> str:
    """Thesis Table 2.1 (``A_zero``: the local connection A(r) vanishes)."""
    if layout.k == 0:
        return PURELY_MECHANICAL
    if layout.d == 0:
        return PRINCIPALLY_KINEMATIC
    if A_zero:
        return PURELY_DYNAMIC
    return MIXED


def _det(A: sp.Matrix):
    """det A written out and factored for small matrices of small entries, else unevaluated."""
    if A.shape[0] <= SINGULAR_DET_MAX and sum(tree_size(e, TIDY_NODES) for e in A) <= TIDY_NODES:
        return sp.factor(tidy(A.det(method="berkowitz")))
    return sp.Determinant(sp.ImmutableMatrix(A))


def _positive_everywhere(f) -> bool:
    """True when the polynomial ``f`` is > 0 for every real value of its generators (symbols,
    sin, cos): a positive constant term and only positive terms of even degree in each
    generator (e.g. r² + 1, which the unicycle's Gram determinant carries)."""
    gens = f.free_symbols | f.atoms(sp.sin, sp.cos)
    try:
        poly = sp.Poly(f, *sorted(gens, key=sp.default_sort_key))
    except sp.PolynomialError:
        return False
    if any(not (g.is_Symbol or isinstance(g, (sp.sin, sp.cos))) for g in poly.gens):
        return False
    terms = poly.terms()
    return (any(not any(m) and c > 0 for m, c in terms)
            and all(c.is_real and c > 0 and all(d % 2 == 0 for d in m) for m, c in terms))


def _drop_positive_factors(e):
    """The square-free product of the factors of ``e`` that can vanish (the same zero set,
    shorter to read: the singular set is stated, the numerics use the layout's matrices). Of a
    quotient, its numerator's (a denominator of parameters, the 4 b² of a differential drive's
    (r²b² + 4b² + r²)/(4b²), does not vanish); ``e`` itself when sympy cannot factor it."""
    if isinstance(e, sp.Determinant) or e.is_Number:
        return e
    numerator, _ = sp.fraction(sp.together(e))
    try:
        _, factors = sp.factor_list(numerator)
    except sp.PolynomialError:
        return e
    kept = [f for f, _ in factors if not _positive_everywhere(f)]
    return sp.Mul(*kept) if kept else sp.Integer(1)


def set_text(e) -> str:
    """One expression of a singular set as text: as stored (factored and collected by
    :func:`~..steps.readable`), never with common subexpressions pulled out; an unevaluated
    determinant (too large to write out) by its size."""
    if isinstance(e, sp.Determinant):
        n = e.arg.shape[0]
        ops = sum(int(sp.count_ops(entry)) for entry in e.arg)
        return f"det of a {n}×{n} matrix ({ops} operations; model.singular_set holds it)"
    return sp.sstr(e)


def singular_set(layout) -> tuple:
    """Where a matrix the reduction inverts loses rank: the Gram determinant of ω_s (when
    rank ω_s = k), the pivot block B of ω (step 5) and K_Ω = NᵀM_ssN (the basis N, steps
    3/6). Each expression vanishes exactly there (constant ones are dropped)."""
    out = []
    k, si = layout.k, list(layout.si)
    if k:
        Ws = layout.W.extract(list(range(k)), si)
        if not layout.dependent and k <= SINGULAR_DET_MAX:
            out.append(_det(Ws * Ws.T))
        if layout.uses_pivot_block:
            out.append(_det(layout.Wb.extract(list(range(k)), list(layout.pivots))))
    if layout.d:
        Ms = layout.M.extract(si, si)
        out.append(_det(tidy(layout.N.T * Ms * layout.N)))
    seen, result = set(), []
    for e in out:
        e = _drop_positive_factors(e)
        if e.is_Number:
            continue
        e = sp.Mul(*[readable(f) for f in e.args]) if e.is_Mul else readable(e)   # once, stored
        key = sp.srepr(e)
        if key not in seen:
            seen.add(key)
            result.append(e)
    return tuple(result)


def symbol_names_for(layout) -> dict:
    """LaTeX names of every symbol that appears in the steps (q̇ as \\dot{q}, P̃ as \\tilde{p})."""
    symbols = layout.symbols()
    return default_symbol_names(list(layout.system.q_dot) + symbols.Pt + symbols.p)


@dataclass(frozen=True, eq=False)
class ReducedODE(ModelDisplay, Formulation):
    """Reduced constrained Hamiltonian equations ż = f(t, z, u), 2n − k first-order ODEs.

    State ordering (``state_names``): z = (q_1 … q_n in the system's coordinate order,
    P_1 … P_d nonholonomic momenta (named ``p`` or ``p1``, ``p2`` …), P̃ for each free shape
    coordinate (named ``pt_<shape coordinate>``)). No multipliers appear.

    The formulation's vocabulary (:class:`~..formulation_base.Formulation`): the singular-set
    measure is the engine's ``numeric["singular"]`` (0 where a matrix the reduction inverts
    loses rank), and the initial configuration is checked against it; the DAE options do not
    apply (projection only removes the drift of kept holonomic constraints).

    Attributes
    ----------
    system : System
    version : "A" or "B" — the choice of g in ξ = g⁻¹ṡ (identity, or SE(2)-type rotation).
    form : "explicit" or "implicit" (see :mod:`nhgait.dynamics.derivation.reduction`).
    fiber, shape : coordinate names s and r.
    state : tuple of Symbols z; momenta : (P…, P̃…) symbols.
    rhs : Matrix (2n−k)×1, ż in state order, in (t, z, u, parameters) — explicit form only;
        None in the implicit form, where ``implicit`` (:class:`ImplicitForm`) states the
        linear systems K(q)v = P (and Bᵀ-solves for the basis) that ``numeric`` solves.
    X : the constraint-adapted velocity basis, q̇ = X K⁻¹ P (n×(n−k)).
    K : the reduced kinetic metric XᵀMX (block-diagonal: nonholonomic, shape).
    hamiltonian : h(q, P) (step 11).  structure : J_z, ż = J_z∇h + (0, Xᵀτ) (step 17).
    qdot : q̇ as a function of z.  momenta_of_velocity : P = XᵀM(q)q̇ (Tables 3.2/3.3).
    (In the implicit form these five are CasADi expressions, :class:`CasadiText`.)
    classification : thesis Table 2.1 type.
    singular_set : expressions; the reduction is singular where any of them is 0.
    steps : the 20 steps by number and identifier (``steps[5].A``, ``steps[17].J``).
    symmetry : the symmetry test (Table 3.1 for this system).
    layout : the choices of steps 1–3 (fiber/shape indices, pivots, basis, g).
    compiled : the numeric functions when given at construction (the implicit form's, from
        its CasADi run; a bound or specialised copy's); None: ``numeric`` compiles them on first use.
    provenance : where a model from :func:`~nhgait.dynamics.derive` came from
        (:class:`~nhgait.dynamics.numerics.cache.Provenance`); None for a model derived directly.
    """

    system: System
    version: str
    fiber: tuple
    shape: tuple
    state: tuple
    state_names: tuple
    momenta: tuple
    rhs: object
    X: object
    K: object
    hamiltonian: object
    structure: object
    qdot: object
    momenta_of_velocity: object
    classification: str
    singular_set: tuple
    steps: Steps
    symmetry: SymmetryTest
    layout: object = field(default=None, repr=False)
    form: str = "explicit"
    implicit: ImplicitForm | None = field(default=None, repr=False)
    derive_time_s: float = 0.0
    symbol_names: dict = field(default_factory=dict, repr=False)
    compiled: object = field(default=None, repr=False)
    provenance: object = field(default=None, repr=False)

    formulation = "reduced"
    velocity_part = "momenta P = Xᵀ M(q) q̇ (nonholonomic P, shape P̃)"
    has_multipliers = False
    dae_options_apply = False
    has_constraint_gram = False
    specialised_for_integration = True

    def multiplier_count(self) -> int:
        return 0

    def initial_state(self, q, qdot, params):
        return self.numeric["state"](q, qdot, params)

    def constraint_residual(self, q, qdot, params):
        return self.numeric["constraint"](q, qdot, params)

    def configuration_measure(self, q, params):
        return self.numeric["singular"](q, params) if self.system.k else ca.SX(1)

    def loop_dynamics(self, point, stabilisation):
        num, n = self.numeric, self.system.n
        x, params = point.x, point.params
        q, qdot = x[:n], num["qdot"](x, params)
        return LoopDynamics(xdot=num["rhs"](point.t_c, x, point.u, params), lam=ca.SX(0, 1),
                            g=num["constraint"](q, qdot, params),
                            measure=self.configuration_measure(q, params), gram=ca.SX(0, 1))

    def singular_set_text(self) -> str:
        sset = self.singular_set
        if sset:
            return "singular set: " + " or ".join(f"{set_text(e)} = 0" for e in sset)
        return "the reduction is singular there"

    @classmethod
    def dae_option_problems(cls, idas, stabilisation, *, holonomic: bool = False) -> list:
        problems = []
        if idas:
            problems.append("dae='idas' applies to the DAE forms (lagrange, hamilton); the reduced "
                            "form is an ODE")
        if stabilisation.projects and holonomic:
            return problems           # q projected back onto the kept holonomic constraints h(q) = 0
        if stabilisation.kind is not None:
            problems.append("stabilization applies to the DAE forms; the reduced ODE satisfies the "
                            "constraints by construction (projection also applies to a reduced ODE "
                            "with kept holonomic constraints: it removes their drift)")
        return problems

    def __repr__(self) -> str:
        return (f"ReducedODE({self.system.name}, {self.form}, {self.dimension} ODEs in z = "
                f"({', '.join(self.state_names)}), fiber ({', '.join(self.fiber)}), {self.classification})")

    def equations(self) -> list:
        """ż = f as sympy Eq objects (``<z>_dot``); explicit form only."""
        if self.rhs is None:
            return []
        return [sp.Eq(sp.Symbol(f"{nm}_dot"), e) for nm, e in zip(self.state_names, self.rhs, strict=True)]

    def pretty_rhs(self) -> list:
        """ż for display: each coefficient of a momentum/input monomial factored when it is
        small, large ones left in normal form (printing stays within a budget)."""
        return [_pretty(e, list(self.momenta) + list(self.system.input_symbols)) for e in self.rhs]

    def to_text(self, pretty: bool = True, cse: bool | None = None) -> str:
        """The equations as text; ``cse``: name repeated sub-expressions once (None: when the
        plain text is long, :func:`~nhgait.dynamics.derivation.cse_text.wants_cse`)."""
        lines = [f"Reduced constrained Hamiltonian equations of {self.system.name} "
                 f"({self.dimension} = 2n − k first-order ODEs, {self.form} form, version {self.version}, "
                 f"{self.classification})",
                 *symmetry_choice_lines(self.symmetry, self.fiber, self.shape),
                 *self.system.holonomic_lines(),
                 f"  state z = ({', '.join(self.state_names)})"]
        if self.rhs is None:
            lines.append("  q̇ = X(q) v,  K(q) v = (" + ", ".join(map(str, self.momenta)) +
                         ") solved at evaluation time (model.numeric);  Ṗ_a = Σ_b {P_a, P_b} v_b "
                         "− X_aᵀ∂h/∂q + X_aᵀτ  (steps 15–19)")
            lines.append(f"  pivot velocities ({', '.join(self.implicit.pivots)}) from B = ω[:, pivots]; "
                         f"K: {self.K!r}; ż: {self.numeric['rhs'].n_instructions()} CasADi operations")
            return "\n".join(lines)
        rhs = self.pretty_rhs() if pretty else self.rhs
        plain = [f"  d{nm}/dt = {text_of(e)}" for nm, e in zip(self.state_names, rhs, strict=True)]
        if cse or (cse is None and wants_cse(plain)):
            return "\n".join(lines + [f"  {line}" for line in
                                       cse_lines([f"d{nm}/dt" for nm in self.state_names], rhs)])
        return "\n".join(lines + plain)

    def checks_text(self) -> str:
        """The ``nhgait derive --checks`` report: Jacobi/holonomy test, Table 2.1 class, the
        (q, q̇) → state map and the singular set."""
        from ..analysis import jacobi_test
        jacobi = jacobi_test(self)
        bracket = ("a Poisson bracket (the Jacobi identity holds" if jacobi.jacobi_holds else
                   "almost-Poisson (the Jacobi identity does not hold, as expected of a nonholonomic bracket")
        out = [f"reduced bracket: {bracket}; max relative Jacobiator {jacobi.jacobiator:.2g}); constraints "
               f"{'holonomic' if jacobi.holonomic else 'nonholonomic'} (max |ω[X_a, X_b]| "
               f"{jacobi.holonomy:.2g}); thesis §2.2.2 (Jacobi ⇔ holonomic): "
               f"{'consistent' if jacobi.consistent else 'INCONSISTENT'}",
               f"classification (thesis Table 2.1): {self.classification}",
               "initial-state map (Tables 3.2–3.3), P = Xᵀ M(q) q̇ on ω(q)q̇ = 0:"]
        if self.rhs is None:
            out.append("  P = X(q)ᵀ M(q) q̇, evaluated by model.numeric['state'] "
                       f"({self.momenta_of_velocity!r})")
        else:
            out += [f"  {s} = {text_of(e)}"
                    for s, e in zip(self.momenta, self.momenta_of_velocity, strict=True)]
        if self.singular_set:
            out.append("singular set: " + " or ".join(f"{set_text(e)} = 0" for e in self.singular_set))
        return "\n".join(out) + "\n"

    @cached_property
    def numeric(self):
        """CasADi/numpy functions of this model (see :mod:`nhgait.dynamics.numerics.numeric_model`);
        the implicit form's functions come from the CasADi run of steps 4–20."""
        if self.compiled is not None:
            return self.compiled
        from ...numerics.numeric_model import compile_reduced
        if self.form == "implicit":
            from .pipeline import arithmetic_for, run_steps
            return compile_reduced(self, run_steps(arithmetic_for("casadi", self.layout), self.layout))
        return compile_reduced(self)


#: coefficients with at most this many operations are factored for display
FACTOR_OPS = 300


def _pretty(e, gens):
    if sp.count_ops(e) > DISPLAY_OPS:
        return e
    try:
        poly = sp.Poly(sp.expand(e), *gens)
    except sp.PolynomialError:
        return e
    terms = []
    for mon, c in poly.terms():
        c = sp.factor(c) if sp.count_ops(c) <= FACTOR_OPS else c
        terms.append(c * sp.Mul(*[g ** k for g, k in zip(gens, mon, strict=True)]))
    return sp.Add(*terms)
