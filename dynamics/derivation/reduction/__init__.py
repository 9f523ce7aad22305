"""The reduced constrained Hamiltonian: the 20-step method of thesis §3.2, for any system.

Math (what every step computes; notation of the thesis)
-------------------------------------------------------
Split q = (s, r) with s the fiber coordinates chosen by the symmetry test (steps 2–3) and r the
shape coordinates; l = dim s, m = number of free shape velocities, d nonholonomic momenta.

* N(q) (l×d): basis of S_q in the s-components, ξ_Q^q = (N, 0) (step 3, eq. 3.7/3.67).
* Nonholonomic momenta p_i = ⟨∂L/∂q̇, ξ_Q^i⟩ (step 4, eq. 3.9/3.69).
* Reconstruction (step 5, eq. 2.47): the constraints together with the momentum definition
  solve for ṡ = −A_q ṙ + Γ_q p; with ξ = g⁻¹ṡ, ξ = −A(r)ṙ + Γ(r)p. The columns
  X_α = (−A_q e_α, e_α) are the M-orthogonal horizontal lifts of ∂/∂r_α.
* Body basis e = g⁻¹N and Ω = K_Ω⁻¹p with K_Ω = NᵀM_ssN, so Γp = eΩ (step 6, eq. 3.72).
* Reduced Lagrangian l(r, ṙ, ξ) = L|_{ṡ=gξ} (step 7); reduced constrained Lagrangian
  l_c = ½ vᵀKv − V, v = (Ω, ṙ), K = XᵀMX block-diagonal (step 8).
* Legendre transform P = Kv (steps 9–10); h = ½ PᵀK⁻¹P + V (step 11).
* P = Xᵀp (step 12), μ = ∂l/∂ξ (steps 13–14); brackets {P_a, P_b} = −pᵀ[X_a, X_b] (step 15),
  restricted to M̄ with γ_abc = X_cᵀM[X_a, X_b] (step 16); the structure J (step 17).
* Equations (steps 18–19): ż = J_z∇h + (0, Xᵀτ) in z = (q, P, P̃); ṡ = gξ (step 20).

The result, 2n − k first-order ODEs, equals the Hamel/Maggi equations of Lagrange–d'Alembert
mechanics, which is why it can be checked against KanesMethod.

Modules: :mod:`.setup` (steps 1–3 and the layout), :mod:`.connection` (4–8),
:mod:`.legendre` (9–11), :mod:`.poisson` (12–17), :mod:`.equations` (18–20), written once
against :mod:`.arithmetic` and run in order by :mod:`.pipeline`; :mod:`.model` holds the result
type :class:`ReducedODE`.

Two forms (``model.form``):

* ``"explicit"`` — every step is a sympy object in canonical trigonometric normal form and
  ``model.rhs`` is ż as a sympy Matrix. Chosen when every matrix the steps invert is at most
  2×2 (``setup.EXPLICIT_MAX_INVERSE``), the shape velocities are free and the exact
  arithmetic stays within ``EXPLICIT_WORK_BUDGET``.
* ``"implicit"`` — the same steps run on CasADi SX (inverses are linear solves, derivatives are
  AD, common subexpressions shared), so the cost grows gently with the system. ``model.rhs`` is
  None; ``model.implicit`` states the linear systems solved at evaluation time; the step
  objects are CasADi expressions printed with shared subexpressions.
"""
from __future__ import annotations

import dataclasses
import time

from ...algebra.ring import NotRational, WorkBudgetExceeded
from ..system import System
from .model import ImplicitForm, ReducedODE, casadi_text, classify, singular_set
from .pipeline import StepsRun, arithmetic_for, run_steps
from .setup import Layout, choose_layout

__all__ = ["ReducedODE", "derive_reduced", "Layout"]

FORMS = ("explicit", "implicit")
#: work budget of the explicit form's exact arithmetic (Σ terms(num)·terms(den) over all
#: normalisations; snakeboard ≈ 1.2e4, a 2-link snake with a rotor ≈ 1.9e6): beyond it the
#: implicit form is used (deterministic, unlike a time limit)
EXPLICIT_WORK_BUDGET = 60_000


def derive_reduced(system: System, version: str | None = None, form: str | None = None) -> ReducedODE:
    """Run the 20 steps for ``system`` and return the :class:`ReducedODE`.

    Parameters
    ----------
    version : "A", "B" or None
        g = identity (A) or the SE(2)-type rotation (B, needs a planar frame with x, y in the
        fiber). None: B when available, else A.
    form : "explicit", "implicit" or None
        None chooses automatically (see the module docstring); a test may force either.
    """
    t0 = time.perf_counter()
    if form not in (None, *FORMS):
        from ...errors import ModelError
        raise ModelError([f"unknown form {form!r} (explicit or implicit)"], title="invalid request")
    layout, first = choose_layout(system, version, form)
    if layout.form == "explicit":
        try:
            ring = arithmetic_for("ring", layout, budget=None if form == "explicit" else EXPLICIT_WORK_BUDGET)
            return _model(layout, first, run_steps(ring, layout), t0)
        except NotRational:
            return _model(layout, first, run_steps(arithmetic_for("sympy", layout), layout), t0)
        except WorkBudgetExceeded:
            layout = dataclasses.replace(layout, form="implicit")
    return _model(layout, first, run_steps(arithmetic_for("casadi", layout), layout), t0)


def _model(layout, first, run: StepsRun, t0) -> ReducedODE:
    """The one constructor of a :class:`ReducedODE` from the steps 1–3 (``first``) and a run of
    steps 4–20: the explicit form holds sympy matrices; the implicit form holds CasADi text
    and the functions compiled from the run."""
    import sympy as sp

    from ..steps import Step, Steps
    from .model import symbol_names_for
    system, symbols = layout.system, run.symbols
    names = symbol_names_for(layout)
    if layout.form == "explicit":
        qdot = sp.Matrix(run.qdot)
        equations = dict(rhs=sp.Matrix.vstack(qdot, sp.Matrix(run.Pdot)) if run.Pdot else qdot,
                         X=run.X, K=run.K, hamiltonian=run.h, structure=run.J_z, qdot=qdot,
                         momenta_of_velocity=(sp.Matrix(run.momenta_of_velocity) if run.momenta_of_velocity
                                              else sp.zeros(0, 1)))
        later, implicit = run.steps, None
    else:
        equations = dict(rhs=None, X=casadi_text(run.X), K=casadi_text(run.K), hamiltonian=casadi_text(run.h),
                         structure=casadi_text(run.J_z), qdot=casadi_text(run.qdot),
                         momenta_of_velocity=casadi_text(run.momenta_of_velocity))
        later = [Step(s.number, s.title, s.thesis, {k: casadi_text(v) for k, v in s.items.items()},
                      s.note, s.labels)
                 for s in run.steps]
        implicit = ImplicitForm.of(layout)
    model = ReducedODE(system=system, version=layout.version, fiber=layout.fiber, shape=layout.shape,
                       state=tuple(system.q) + tuple(symbols.P),
                       state_names=tuple(system.coordinates) + tuple(str(p) for p in symbols.P),
                       momenta=tuple(symbols.P), singular_set=singular_set(layout), symmetry=layout.symmetry,
                       layout=layout, form=layout.form, **equations,
                       classification=classify(layout, run.A_zero),
                       steps=Steps(list(first) + list(later), names),
                       implicit=implicit, derive_time_s=time.perf_counter() - t0, symbol_names=names)
    if layout.form == "implicit":
        from ...numerics.numeric_model import compile_reduced
        model = dataclasses.replace(model, compiled=compile_reduced(model, run),
                                    derive_time_s=time.perf_counter() - t0)
    return model
