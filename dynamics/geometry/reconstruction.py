"""The reconstruction equation as data (thesis §2.3, Table 2.1, eqs. 2.47–2.50).

For the fibre s (a Lie group G, ξ = g⁻¹ṡ) and the free shape coordinates r chosen by steps 2–3
of the reduction, every reduced model moves its fibre by

    ξ = −A(r) ṙ + Γ(r) pᵀ                                   (eq. 2.47, mixed)

with A (l×m) the local form of the connection and Γ (l×d) the map from the d nonholonomic
momenta p = ⟨∂L/∂q̇, ξ_Q⟩ (step 4). Table 2.1 names four types:

* mixed (0 < k < l, A ≠ 0): eq. 2.47 and the momentum equation
  ṗ = ṙᵀσ_rr ṙ + ṙᵀσ_rp p + pᵀσ_pp p (one σ triple per momentum; plus the forces along
  ξ_Q, when there are any);
* principally kinematic (d = 0): ξ = −𝔸(r)ṙ (eq. 2.48), the principal connection;
* purely mechanical (k = 0): ξ = −A(r)ṙ at zero momentum (eq. 2.49), the mechanical
  connection; the general form keeps Γ(r)pᵀ;
* purely dynamic (A = 0): ξ = Γ(r)pᵀ.

A, Γ and the body basis are those of steps 5–6 of :mod:`nhgait.dynamics.derivation.reduction`
(reused, never re-derived); σ is read off the reduced equations Ṗ of step 19 with the shape
momenta written in shape velocities, P̃ = K_r(r)ṙ (K = XᵀMX is block-diagonal, step 8).
In the explicit form every matrix is a sympy Matrix; in the implicit form a CasADi SX
expression of (q, params). :meth:`ReconstructionEquation.evaluate` gives numbers in either.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import sympy as sp

from ..derivation.reduction import connection as steps_4_8
from ..derivation.reduction.model import MIXED, PRINCIPALLY_KINEMATIC, PURELY_DYNAMIC, PURELY_MECHANICAL
from ..derivation.reduction.pipeline import arithmetic_for
from ..derivation.steps import text_of
from ..numerics.bridge import to_casadi

__all__ = ["ReconstructionEquation", "ReconstructionValues", "reconstruction"]

#: the thesis's equation of each Table 2.1 type
EQUATION_OF_TYPE = {MIXED: "2.47", PRINCIPALLY_KINEMATIC: "2.48", PURELY_MECHANICAL: "2.49",
                    PURELY_DYNAMIC: "2.47 with A = 0"}


@dataclass(frozen=True)
class ReconstructionValues:
    """The matrices of a :class:`ReconstructionEquation` at one configuration (numpy).

    A : (l, m); Gamma : (l, d); sigma_rr : (d, m, m); sigma_rp : (d, m, d); sigma_pp : (d, d, d).
    """

    A: np.ndarray
    Gamma: np.ndarray
    sigma_rr: np.ndarray
    sigma_rp: np.ndarray
    sigma_pp: np.ndarray


@dataclass(frozen=True, kw_only=True, eq=False)
class ReconstructionEquation:
    """ξ = −A(r)ṙ + Γ(r)pᵀ and ṗ = ṙᵀσ_rr ṙ + ṙᵀσ_rp p + pᵀσ_pp p of one reduced model.

    Attributes
    ----------
    system : the system's name.
    classification : thesis Table 2.1 type ("mixed", "principally kinematic", "purely
        mechanical", "purely dynamic").
    version : "A" (g = identity) or "B" (SE(2)-type g: ξ in the body frame).
    fiber : names of s (l); shape : names of the free shape coordinates r (m), the ṙ of the
        equation; dependent : shape coordinates whose velocities the constraints fix.
    momenta : names of the nonholonomic momenta p (d).
    g : l×l, ṡ = gξ.  xi_of_velocity : g⁻¹ṡ (l×1, what ξ is in the user's velocities).
    A : l×m local connection.  Gamma : l×d.
    sigma_rr, sigma_rp, sigma_pp : one matrix per momentum (m×m, m×d, d×d; symmetric σ_rr,
        σ_pp); empty tuples when d = 0.
    forcing : d×1, what ṗ has besides the quadratic form (forces along ξ_Q), zeros mostly.
    symbolic : True when the matrices are sympy (explicit form), False for CasADi SX.
    """

    system: str
    classification: str
    version: str
    fiber: tuple
    shape: tuple
    dependent: tuple
    momenta: tuple
    g: object
    xi_of_velocity: object
    A: object
    Gamma: object
    sigma_rr: tuple
    sigma_rp: tuple
    sigma_pp: tuple
    forcing: object
    symbolic: bool
    function: ca.Function = field(repr=False)
    param_names: tuple = ()
    param_defaults: tuple = ()

    @property
    def equation(self) -> str:
        """The thesis equation number of this Table 2.1 type."""
        return EQUATION_OF_TYPE[self.classification]

    def evaluate(self, q, params=None) -> ReconstructionValues:
        """A, Γ and σ at the configuration ``q`` (n values in the system's coordinate order);
        ``params``: a parameter vector or a mapping name → value (defaults otherwise)."""
        vec = np.array(self.param_defaults, dtype=float)
        if isinstance(params, dict):
            for k, v in params.items():
                vec[self.param_names.index(k)] = float(v)
        elif params is not None:
            vec = np.asarray(params, dtype=float).ravel()
        out = [np.array(o.full()) for o in self.function(np.asarray(q, dtype=float), vec)]
        l, m, d = len(self.fiber), len(self.shape), len(self.momenta)

        def stack(flat, rows, cols):
            return flat.reshape(d, cols, rows).transpose(0, 2, 1) if d else np.zeros((0, rows, cols))
        return ReconstructionValues(A=out[0].reshape(l, m, order="F"), Gamma=out[1].reshape(l, d, order="F"),
                                    sigma_rr=stack(out[2], m, m), sigma_rp=stack(out[3], m, d),
                                    sigma_pp=stack(out[4], d, d))

    def _numeric_lines(self) -> list:
        """A and Γ at q = 0, when they are finite there (the implicit form's display)."""
        n = len(self.fiber) + len(self.shape) + len(self.dependent)
        values = self.evaluate(np.zeros(n))
        if not (np.all(np.isfinite(values.A)) and np.all(np.isfinite(values.Gamma))):
            return []
        xi = _xi_names(len(self.fiber))
        return (["  at q = 0:"] + _numeric_entries("A", values.A, xi, [f"{r}_dot" for r in self.shape])
                + _numeric_entries("Γ", values.Gamma, xi, list(self.momenta)))

    def to_text(self) -> str:
        """The equation in the user's names (``nhgait derive SCENE --reconstruction``)."""
        lines = [f"Reconstruction equation of {self.system} (thesis Table 2.1: {self.classification}, "
                 f"eq. {self.equation})",
                 f"  fibre s = ({', '.join(self.fiber)}), ṡ = g ξ (version {self.version}); shape r = "
                 f"({', '.join(self.shape)})"
                 + (f"; constrained shape velocities: {', '.join(self.dependent)}" if self.dependent else "")
                 + (f"; nonholonomic momenta p = ({', '.join(self.momenta)})" if self.momenta else "")]
        lines.append("  " + _form_line(self.classification))
        if not self.symbolic:
            lines.append("  (implicit form: A, Γ and σ are CasADi expressions; evaluate them with "
                         "ReconstructionEquation.evaluate(q))")
            return "\n".join(lines + self._numeric_lines())
        lines.append("  where ξ = g⁻¹ṡ in your velocities:")
        for i, name in enumerate(_xi_names(len(self.fiber))):
            lines.append(f"    {name} = {text_of(self.xi_of_velocity[i])}")
        xi = _xi_names(len(self.fiber))
        rdot, p = [f"{r}_dot" for r in self.shape], list(self.momenta)
        lines += _entries("A(r)", self.A, xi, rdot) if self.shape else ["  A(r): no free shape velocities"]
        if self.momenta:
            lines += _entries("Γ(r)", self.Gamma, xi, p)
            lines.append("  momentum equation ṗ = ṙᵀσ_rr ṙ + ṙᵀσ_rp p + pᵀσ_pp p (zero entries omitted):")
            for a, name in enumerate(self.momenta):
                lines.append(f"    d{name}/dt:")
                lines += _entries("σ_rr", self.sigma_rr[a], rdot, rdot, indent=6)
                lines += _entries("σ_rp", self.sigma_rp[a], rdot, p, indent=6)
                lines += _entries("σ_pp", self.sigma_pp[a], p, p, indent=6)
                if self.forcing[a] != 0:
                    lines.append(f"      + forces along ξ_Q: {text_of(self.forcing[a])}")
        return "\n".join(lines)


def _numeric_entries(label, matrix, rows, cols) -> list:
    """The entries of a numeric ``matrix`` above 1e-12 of its largest (rounding left out)."""
    small = 1e-12 * max(1.0, float(np.abs(matrix).max(initial=0.0)))
    return [f"    {label}[{r}, {c}] = {matrix[i, j]:.6g}"
            for i, r in enumerate(rows) for j, c in enumerate(cols) if abs(matrix[i, j]) > small]


def _entries(label, matrix, rows, cols, indent=2) -> list:
    """The nonzero entries of a sympy ``matrix`` as ``label[row, col] = …`` lines."""
    out = [f"{' ' * indent}{label}[{r}, {c}] = {text_of(_factored(matrix[i, j]))}"
           for i, r in enumerate(rows) for j, c in enumerate(cols) if matrix[i, j] != 0]
    return out or [f"{' ' * indent}{label} = 0"]


#: entries with at most this many operations are factored for display
FACTOR_OPS = 300


def _factored(e):
    return sp.factor(e) if sp.count_ops(e) <= FACTOR_OPS else e


def _xi_names(l) -> list:
    return ["ξ"] if l == 1 else [f"ξ{i + 1}" for i in range(l)]


def _form_line(classification) -> str:
    return {MIXED: "ξ = g⁻¹ṡ = −A(r)ṙ + Γ(r)pᵀ",
            PRINCIPALLY_KINEMATIC: "ξ = g⁻¹ṡ = −𝔸(r)ṙ (principal connection)",
            PURELY_MECHANICAL: "ξ = g⁻¹ṡ = −A(r)ṙ + Γ(r)pᵀ (mechanical connection; −A(r)ṙ at zero "
                               "momentum)",
            PURELY_DYNAMIC: "ξ = g⁻¹ṡ = Γ(r)pᵀ (A = 0)",
            }[classification]


def reconstruction(model) -> ReconstructionEquation:
    """The reconstruction equation (and momentum equation) of a derived reduced model.

    Parameters
    ----------
    model : :class:`~nhgait.dynamics.derivation.reduction.ReducedODE`

    Examples
    --------
    >>> from nhgait.dynamics import derive, chaplygin_sleigh
    >>> eq = reconstruction(derive(chaplygin_sleigh(), "reduced"))
    >>> eq.classification, eq.momenta
    ('purely dynamic', ('p1', 'p2'))
    """
    layout, system = model.layout, model.system
    d = layout.d
    names = dict(system=system.name, classification=model.classification, version=model.version,
                 fiber=tuple(model.fiber), shape=tuple(system.coordinates[i] for i in layout.free),
                 dependent=tuple(system.coordinates[i] for i in layout.dependent),
                 momenta=tuple(str(p) for p in model.momenta[:d]),
                 param_names=tuple(s.name for s in system.param_symbols),
                 param_defaults=tuple(float(v) for v in system.param_vector()))
    if model.form == "explicit":
        return ReconstructionEquation(**names, **_symbolic_parts(model), symbolic=True)
    return ReconstructionEquation(**names, **_casadi_parts(model), symbolic=False)


def _symbolic_parts(model) -> dict:
    """Explicit form: A, Γ, g⁻¹ṡ from step 5; σ from the rows Ṗ_nh of the reduced equations
    with P̃ = K_r ṙ, the inputs at zero (what remains is ``forcing``)."""
    from ..algebra.trig import tidy
    layout, system, step5 = model.layout, model.system, model.steps[5]
    n, d = system.n, layout.d
    rdot = [system.q_dot[i] for i in layout.free]
    p = list(model.momenta[:d])
    K_r = model.K[d:, d:]
    P_tilde = K_r * sp.Matrix(rdot) if rdot else sp.zeros(0, 1)
    sub = {P: e for P, e in zip(model.momenta[d:], P_tilde, strict=True)}
    rr, rp, pp, forcing = [], [], [], []
    for a in range(d):
        e = model.rhs[n + a].xreplace(sub)
        zero = {v: 0 for v in rdot + p}
        rr.append(tidy(sp.hessian(e, rdot).xreplace(zero) / 2) if rdot else sp.zeros(0, 0))
        rp.append(tidy(sp.Matrix([[sp.diff(e, x, y).xreplace(zero) for y in p] for x in rdot])))
        pp.append(tidy(sp.hessian(e, p).xreplace(zero) / 2))
        quad = (sp.Matrix(rdot).T * rr[a] * sp.Matrix(rdot) if rdot else sp.zeros(1, 1))[0] + \
               (sp.Matrix(rdot).T * rp[a] * sp.Matrix(p) if rdot else sp.zeros(1, 1))[0] + \
               (sp.Matrix(p).T * pp[a] * sp.Matrix(p))[0]
        forcing.append(tidy(sp.expand(e - quad)))      # forces along ξ_Q (need not be quadratic)
    parts = dict(g=layout.g, xi_of_velocity=step5.xi_body, A=step5.A, Gamma=step5.Gamma,
                 sigma_rr=tuple(rr), sigma_rp=tuple(rp), sigma_pp=tuple(pp), forcing=sp.Matrix(forcing))
    q, params = ca.SX.sym("q", n), ca.SX.sym("params", len(system.param_symbols))

    def conv(A):
        return ca.reshape(_of_configuration(system, q, params, sp.Matrix(A)), -1, 1)
    outs = [conv(parts["A"]), conv(parts["Gamma"]), _stacked([conv(s) for s in rr]),
            _stacked([conv(s) for s in rp]), _stacked([conv(s) for s in pp])]
    parts["function"] = ca.Function("reconstruction", [q, params], outs, ["q", "params"],
                                    ["A", "Gamma", "sigma_rr", "sigma_rp", "sigma_pp"])
    return parts


def _of_configuration(system, q, params, A: sp.Matrix) -> ca.SX:
    """The sympy matrix ``A`` of (q, parameters) as CasADi SX of the symbols ``q``, ``params``."""
    if A.shape[0] == 0 or A.shape[1] == 0:
        return ca.SX(A.shape[0], A.shape[1])
    sx = [q[i] for i in range(q.shape[0])] + [params[i] for i in range(params.shape[0])]
    return ca.reshape(ca.vertcat(*to_casadi(list(A.T), list(system.q) + list(system.param_symbols), sx)),
                      A.shape[0], A.shape[1])


def _stacked(blocks) -> ca.SX:
    return ca.vertcat(*blocks) if blocks else ca.SX(0, 1)


def _sx(rows) -> ca.SX:
    """A matrix given as a list of rows of SX scalars."""
    return ca.vertcat(*[ca.horzcat(*row) for row in rows])


def _casadi_parts(model) -> dict:
    """Implicit form: A and Γ from step 5 run on CasADi SX; σ by AD of the model's Ṗ_nh with
    P̃ = K_r ṙ (K_r = X_rᵀ M X_r from the model's basis)."""
    layout, system = model.layout, model.system
    n, d, m = system.n, layout.d, len(layout.free)
    arith = arithmetic_for("casadi", layout)
    _, rec = steps_4_8.reconstruction(arith, layout, layout.symbols())
    q = ca.vertcat(*[arith.sym(s) for s in system.q])
    params = (ca.vertcat(*[arith.sym(s) for s in system.param_symbols]) if system.param_symbols
              else ca.SX(0, 1))
    l = len(layout.si)
    A = _sx(rec.A) if m else ca.SX(l, 0)
    Gamma = (ca.mtimes(_sx(arith.mat(layout.ginv)), ca.mtimes(_sx(arith.mat(layout.N)), _sx(rec.K_nh_inv)))
             if d else ca.SX(l, 0))
    rdot, p = ca.SX.sym("rdot", m), ca.SX.sym("p", d)
    X = model.numeric["basis"](ca.vertcat(q, ca.SX(len(model.momenta), 1)), params)
    M = _of_configuration(system, q, params, system.mass_matrix())
    Xr = X[:, d:]
    P = ca.vertcat(p, ca.mtimes(ca.mtimes(Xr.T, ca.mtimes(M, Xr)), rdot))
    f = model.numeric["rhs"](0, ca.vertcat(q, P), ca.SX(len(system.input_symbols), 1), params)
    rr, rp, pp, forcing = [], [], [], []
    for a in range(d):
        e = f[n + a]
        rr.append(ca.reshape(ca.hessian(e, rdot)[0] / 2, -1, 1))
        rp.append(ca.reshape(ca.jacobian(ca.gradient(e, rdot), p), -1, 1))
        pp.append(ca.reshape(ca.hessian(e, p)[0] / 2, -1, 1))
        forcing.append(ca.substitute(e, ca.vertcat(rdot, p), ca.SX(ca.DM.zeros(m + d, 1))))
    outs = [ca.reshape(A, -1, 1), ca.reshape(Gamma, -1, 1)] + [
        ca.substitute(_stacked(s), ca.vertcat(rdot, p), ca.SX(ca.DM.zeros(m + d, 1))) for s in (rr, rp, pp)]
    function = ca.Function("reconstruction", [q, params], outs, ["q", "params"],
                           ["A", "Gamma", "sigma_rr", "sigma_rp", "sigma_pp"])
    return dict(g=layout.g, xi_of_velocity=None, A=A, Gamma=Gamma, sigma_rr=tuple(rr), sigma_rp=tuple(rp),
                sigma_pp=tuple(pp), forcing=ca.vertcat(*forcing) if forcing else ca.SX(0, 1),
                function=function)
