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

from ..symbolic import NotRational, WorkBudgetExceeded
from ..system import System
from .model import ImplicitForm, ReducedODE, casadi_text, classify, singular_set
from .pipeline import arithmetic_for, run_steps
from .setup import Layout, layout

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
    lay, first = layout(system, version, form)
    if lay.form == "explicit":
        try:
            F = arithmetic_for("ring", lay)
            F.budget = None if form == "explicit" else EXPLICIT_WORK_BUDGET
            steps, out = run_steps(F, lay)
            return _explicit_model(lay, first, steps, out, t0)
        except NotRational:
            steps, out = run_steps(arithmetic_for("sympy", lay), lay)
            return _explicit_model(lay, first, steps, out, t0)
        except WorkBudgetExceeded:
            lay = dataclasses.replace(lay, form="implicit")
    steps, out = run_steps(arithmetic_for("casadi", lay), lay)
    return _implicit_model(lay, first, steps, out, t0)


def _common(lay, out):
    s, sy = lay.system, out["symbols"]
    state = tuple(s.q) + tuple(sy.P)
    return dict(system=s, version=lay.version, fiber=lay.fiber, shape=lay.shape, state=state,
                state_names=tuple(s.coordinates) + tuple(str(p) for p in sy.P), momenta=tuple(sy.P),
                singular_set=singular_set(lay), symmetry=lay.symmetry, layout=lay, form=lay.form)


def _explicit_model(lay, first, steps, out, t0) -> ReducedODE:
    import sympy as sp
    from .model import symbol_names_for
    qdot = sp.Matrix(out["qdot"])
    rhs = sp.Matrix.vstack(qdot, sp.Matrix(out["Pdot"])) if out["Pdot"] else qdot
    names = symbol_names_for(lay)
    return ReducedODE(**_common(lay, out), rhs=rhs, X=out["X"], K=out["K"], hamiltonian=out["h"],
                      structure=out["J_z"], qdot=qdot,
                      momenta_of_velocity=sp.Matrix(out["momenta_of_velocity"]) if out["momenta_of_velocity"] else sp.zeros(0, 1),
                      classification=classify(lay, out["A_zero"]),
                      steps=_steps(first, steps, names), implicit=None,
                      derive_time_s=time.perf_counter() - t0, symbol_names=names)


def _implicit_model(lay, first, steps, out, t0) -> ReducedODE:
    from ..steps import Step
    from .model import symbol_names_for
    shown = [Step(s.number, s.title, s.thesis, {k: casadi_text(v) for k, v in s.items.items()},
                  s.note, s.labels) for s in steps]
    names = symbol_names_for(lay)
    model = ReducedODE(**_common(lay, out), rhs=None, X=casadi_text(out["X"]), K=casadi_text(out["K"]),
                       hamiltonian=casadi_text(out["h"]), structure=casadi_text(out["J_z"]),
                       qdot=casadi_text(out["qdot"]),
                       momenta_of_velocity=casadi_text(out["momenta_of_velocity"]),
                       classification=classify(lay, out["A_zero"]),
                       steps=_steps(first, shown, names), implicit=ImplicitForm.of(lay),
                       derive_time_s=0.0, symbol_names=names)
    from ...numerics.numeric_model import compile_reduced
    model.__dict__["numeric"] = compile_reduced(model, out)
    object.__setattr__(model, "derive_time_s", time.perf_counter() - t0)
    return model


def _steps(first, later, names):
    from ..steps import Steps
    return Steps(list(first) + list(later), names)
