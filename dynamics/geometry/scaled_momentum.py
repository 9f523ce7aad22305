"""Shammas's scaled momentum: the height functions of a mixed system (one nonholonomic momentum).

For a mixed reduced model (thesis Table 2.1, eq. 2.47; :mod:`.reconstruction`) with one
nonholonomic momentum p, over a plane of two shape coordinates r = (r_a, r_b) (the others
fixed),

    ξ = −A(r)ṙ + Γ(r)p,        ṗ = ṙᵀσ_rr(r)ṙ + σ_rp(r)·ṙ p + σ_pp(r)p²        (1)

(Shammas, Choset & Rizzi, IJRR 2007: the "mixed" class; the snakeboard is its example).

**Exact: the scaled momentum.** When σ_pp = 0, nothing else drives p (no forces along ξ_Q) and
the 1-form σ_rp·dr is closed on the plane (∂σ_a/∂r_b = ∂σ_b/∂r_a), its potential

    F(r) = ∫_{r⁰}^{r} σ_rp·dr       (path-independent; r⁰ the plane's base point, ``at``)

is an integrating factor of (1): the scaled momentum p̄ = e^{−F(r)}p obeys

    dp̄/dt = ṙᵀσ̄_rr ṙ,   σ̄_rr = e^{−F}σ_rr,      ξ = −Aṙ + Γ̄ p̄,   Γ̄ = e^{F}Γ          (2)

exactly (differentiate e^{−F}p along r(t)). So from rest, p̄(t) = ∫₀ᵗ ṙᵀσ̄_rr ṙ dτ: the momentum
at any instant is a functional of the shape path alone, with no p-feedback.

**Approximate: the height function of the momentum.** For a closed loop of size ε from rest,
the fibre moves by exp(Ω) with

    Ω = ∬ H_ab dr_a dr_b + ∫₀ᵀ Γ̄(r(t)) p̄(t) dt + O(ε³)                               (3)

(H_ab the connection's height, :mod:`.heights`; p̄ = O(ε²), so its brackets with ξ are O(ε³)).
The second term is not an area integral for every timing: it is Γ̄(c)∫₀ᵀ(T − t)ṙᵀσ̄_rr(c)ṙ dt
+ O(ε³) (c the loop's centre), and a rectangle traced side by side builds no momentum at all.
It is one for the elliptical gait r = c + (α cos ωt, β sin ωt) traced at a constant rate from
rest, when σ̄_aa = σ̄_bb = 0 on the plane (else ṙᵀσ̄ṙ has a sign and the momentum does not
return to zero): then ṙ_a = −(αω/β)(r_b − c_b), so p̄ = −(αω/β)σ̄_ab(c)(r_b − c_b)² + O(ε³ω) —
zero at the start and at the end — and p̄ dt = σ̄_ab(c)(r_b − c_b) dr_a, whence by Stokes

    ∫₀ᵀ Γ̄ p̄ dt = ∮ Γ̄σ̄_ab(r_b − c_b) dr_a = −∬ σ̄_ab Γ̄ dr_a dr_b + O(ε³):

the momentum part is the curvature of the scaled momentum distribution Γ̄ carried by the form
σ̄_ab(r_b − c_b)dr_a. The height function of the scaled-momentum form is therefore

    H̄_ab = H_ab − σ̄_ab Γ̄ = H_ab − σ_ab Γ          (σ̄_ab Γ̄ = σ_ab Γ: the factors e^{∓F} cancel)

(l×1; σ_ab the off-diagonal entry of σ_rr, ṙᵀσ_rr ṙ ∋ 2σ_ab ṙ_a ṙ_b), and ∬H̄ estimates the
loop's displacement with a relative error O(ε), independent of ω. Conventions: the loop is
counter-clockwise in (r_a, r_b) (clockwise: both parts change sign) and starts on the line
r_b = c_b (moving along r_b); starting at the phase θ₀, r = c + (α cos(ωt + θ₀), β sin(ωt + θ₀)),
multiplies the momentum part by cos 2θ₀ (the momentum builds from where the loop starts; the
mean of p̄ over the loop changes). Both orders are checked against the full reduced ODE in
``tests/dynamics/test_scaled_momentum.py``.

:func:`scaled_momentum` returns the pieces (:class:`ScaledMomentum`): σ_rr, σ_rp, Γ on the
plane (sympy), F by quadrature, p̄, σ̄, Γ̄ as numbers, and :meth:`ScaledMomentum.height` the
momentum part −σ_abΓ; :func:`~.heights.height_function` and :func:`~.heights.evaluate_heights`
take it as ``momentum=`` to give H̄.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..derivation.reduction.model import MIXED
from ..errors import ModelError
from .reconstruction import reconstruction

__all__ = ["ScaledMomentum", "scaled_momentum"]

#: Gauss–Legendre nodes of the quadrature of F along each leg of the path from the base point
QUADRATURE_NODES = 24


def _is_zero(e) -> bool:
    return e == 0 or sp.simplify(e) == 0


@dataclass(frozen=True, kw_only=True, eq=False)
class ScaledMomentum:
    """The scaled-momentum form (2) of a mixed model over one shape plane (module docstring).

    Attributes
    ----------
    pair : (a, b), the shape coordinates of the plane; fiber : the l fibre names;
    momentum : the name of p.
    sigma_rr : sympy 2×2, σ_rr on (ṙ_a, ṙ_b); sigma_rp : sympy 2×1, (σ_a, σ_b) of σ_rp·dr;
    Gamma : sympy l×1, Γ(r).  All of (q, parameters).
    at : coordinate values held fixed (the base point r⁰ of F is (at[a], at[b]), default 0).
    returns_to_zero : σ_aa ≡ σ_bb ≡ 0, the condition of the height function.
    system : the model's System; params : the parameter vector used for numbers.
    """

    pair: tuple
    fiber: tuple
    momentum: str
    sigma_rr: sp.Matrix
    sigma_rp: sp.Matrix
    Gamma: sp.Matrix
    at: dict
    returns_to_zero: bool
    system: Any
    params: np.ndarray
    _numbers: Any = field(repr=False)

    def height(self) -> sp.Matrix:
        """The momentum part of the height function, −σ̄_abΓ̄ = −σ_abΓ (l×1 sympy); a ModelError
        when σ_aa or σ_bb is not zero (a loop's momentum would not return to zero)."""
        if not self.returns_to_zero:
            a, b = self.pair
            raise ModelError([f"σ_rr has diagonal entries on ({a}, {b}) "
                              f"(σ_aa = {self.sigma_rr[0, 0]}, σ_bb = {self.sigma_rr[1, 1]}): ṙᵀσ_rr ṙ "
                              "does not average out over a loop, the momentum does not return to zero, "
                              "and no height function describes the momentum's part"],
                             title="no scaled-momentum height function")
        return (-self.sigma_rr[0, 1] * self.Gamma).applyfunc(sp.cancel)

    def factor(self, ra, rb) -> np.ndarray:
        """F(r) = ∫_{r⁰}^{r} σ_rp·dr at the points (``ra``, ``rb``) (arrays of one shape):
        along r_a at r_b⁰, then along r_b, by Gauss–Legendre quadrature
        (:data:`QUADRATURE_NODES` nodes a leg; exact for closed σ_rp up to the rule's error)."""
        ra, rb = np.broadcast_arrays(np.asarray(ra, float), np.asarray(rb, float))
        a0, b0 = (float(self.at.get(n, 0.0)) for n in self.pair)
        x, w = np.polynomial.legendre.leggauss(QUADRATURE_NODES)
        sa, sb = self._numbers["sigma_a"], self._numbers["sigma_b"]
        half_a, half_b = (ra - a0) / 2, (rb - b0) / 2
        leg_a = sum(wk * sa(a0 + half_a * (1 + xk), np.full_like(ra, b0))
                    for xk, wk in zip(x, w, strict=True))
        leg_b = sum(wk * sb(ra, b0 + half_b * (1 + xk)) for xk, wk in zip(x, w, strict=True))
        return half_a * leg_a + half_b * leg_b

    def scaled(self, p, ra, rb) -> np.ndarray:
        """p̄ = e^{−F(r)} p."""
        return np.exp(-self.factor(ra, rb)) * np.asarray(p, float)

    def sigma_bar(self, ra, rb) -> np.ndarray:
        """σ̄_rr = e^{−F}σ_rr at one point (2×2)."""
        return np.exp(-float(self.factor(ra, rb))) * np.asarray(self._numbers["sigma_rr"](ra, rb), float)

    def Gamma_bar(self, ra, rb) -> np.ndarray:
        """Γ̄ = e^{F}Γ at one point (l,)."""
        return np.exp(float(self.factor(ra, rb))) * np.asarray(self._numbers["Gamma"](ra, rb), float).ravel()


def _problems(model, equation, a, b) -> list:
    shape = equation.shape
    problems = [f"{n!r} is not a shape coordinate (shape: {', '.join(shape) or 'none'})"
                for n in (a, b) if n not in shape]
    problems += [f"the pair needs two different shape coordinates, got {a!r} twice"] if a == b else []
    if model.classification != MIXED or len(equation.momenta) != 1:
        problems.append(f"the scaled momentum is for a mixed system with one nonholonomic momentum; "
                        f"{equation.system} is {model.classification} with {len(equation.momenta)} momenta "
                        f"({', '.join(equation.momenta) or 'none'})")
    elif not equation.symbolic:
        problems.append("the model is in the implicit form (CasADi): derive it in the explicit form, or "
                        "use heights.evaluate_heights_numeric(..., equation=reconstruction(model))")
    return problems


def scaled_momentum(model, a: str, b: str, *, at=None, params=None) -> ScaledMomentum:
    """The scaled-momentum form of a mixed ``model`` (a ReducedODE, explicit form) over the plane
    of shape coordinates (``a``, ``b``), the other coordinates at ``at`` (default 0), the
    parameters ``params`` (mapping or vector; default the system's).

    Every problem in one ModelError: not a shape pair, not mixed with one momentum, σ_pp ≠ 0,
    forces along ξ_Q, σ_rp not closed on the plane (then F depends on the path and (2) is not
    exact).

    Examples
    --------
    >>> import numpy as np
    >>> from nhgait.dynamics import derive, snakeboard
    >>> momentum = scaled_momentum(derive(snakeboard(), "reduced"), "psi", "phi")
    >>> momentum.momentum, momentum.returns_to_zero
    ('p', True)
    >>> bool(np.isclose(momentum.factor(0.0, 0.5), np.log(np.cos(0.5))))      # F = ln cos φ
    True
    """
    equation = reconstruction(model)
    problems = _problems(model, equation, a, b)
    if problems:
        raise ModelError(problems, title="invalid scaled-momentum request")
    system = model.system
    ja, jb = equation.shape.index(a), equation.shape.index(b)
    qa, qb = (next(s for s in system.q if str(s) == n) for n in (a, b))
    rr, rp = equation.sigma_rr[0], equation.sigma_rp[0]
    sigma_rr = sp.Matrix([[rr[ja, ja], rr[ja, jb]], [rr[jb, ja], rr[jb, jb]]])
    sigma_rp = sp.Matrix([rp[ja, 0], rp[jb, 0]])
    if not _is_zero(equation.sigma_pp[0][0, 0]):
        problems.append(f"σ_pp = {equation.sigma_pp[0][0, 0]} ≠ 0: p² drives the momentum and no "
                        "integrating factor removes it")
    if not _is_zero(equation.forcing[0]):
        problems.append(f"forces along ξ_Q drive the momentum ({equation.forcing[0]})")
    if not _is_zero(sigma_rp[0].diff(qb) - sigma_rp[1].diff(qa)):
        problems.append(f"σ_rp·dr is not closed on ({a}, {b}): the integrating factor depends on the path")
    if problems:
        raise ModelError(problems, title="no exact scaled momentum")
    at = {k: float(v) for k, v in dict(at or {}).items()}
    vector = (system.param_vector(params) if params is None or isinstance(params, dict)
              else np.asarray(params, float))
    sub = dict(zip(system.param_symbols, vector, strict=True))
    sub.update({s: at.get(str(s), 0.0) for s in system.q if s not in (qa, qb)})

    def numeric(expr):
        return sp.lambdify((qa, qb), expr.subs(sub), "numpy")
    numbers = {"sigma_a": numeric(sigma_rp[0]), "sigma_b": numeric(sigma_rp[1]),
               "sigma_rr": numeric(sigma_rr), "Gamma": numeric(equation.Gamma)}
    return ScaledMomentum(pair=(a, b), fiber=tuple(equation.fiber), momentum=equation.momenta[0],
                          sigma_rr=sigma_rr, sigma_rp=sigma_rp, Gamma=sp.Matrix(equation.Gamma), at=at,
                          returns_to_zero=_is_zero(sigma_rr[0, 0]) and _is_zero(sigma_rr[1, 1]),
                          system=system, params=np.asarray(vector, float), _numbers=numbers)
