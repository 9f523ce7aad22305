"""The gait planner: derive → specialise → task → guess → solve → verify → write.

:func:`plan` is the one entry point used by ``nhgait plan``::

    result = plan("snakeboard", "forward", distance=1.0, out_dir="out/demo")
    result.solution.objective, result.solution.verification_error, result.files

Specialisation
--------------
The derived reduced ODE keeps its parameters symbolic, so its CasADi expressions carry
every parameter combination (the snakeboard's ż costs ~250 SX operations). For planning the
parameters are fixed, so :func:`specialise` substitutes their values into the sympy rhs and
q̇(z), brings each component to one fraction, drops coefficients below 1e-13 of the largest
one (round-off of cancelled terms such as J + J_r + 2J_w − m r²), rationalises the remaining
coefficients and cancels each monomial of the momenta/inputs against the denominator. The
result (snakeboard ~70 operations, a 3–5× cheaper RK4 Hessian) is checked against the
original functions at random states (relative error ≤ 1e-12, else the original is kept) and
cached on disk by the model's content hash and the exact parameter values, so a second
process pays neither the derivation nor the simplification.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plan", "PlanResult", "specialise", "SpecialisedModel", "solve_task"]


# ------------------------------------------------------------------ specialisation
@dataclass(frozen=True, eq=False)
class SpecialisedModel:
    """A reduced model with its parameter values substituted into the numeric functions.

    Same interface as :class:`~nhgait.dynamics.reduction.ReducedODE` for the OCP layer
    (``numeric``, ``state_names``, ``system``); ``numeric.params()`` returns the baked values
    and the functions ignore their ``params`` argument.
    """

    base: Any
    numeric: Any
    simplified: bool

    @property
    def system(self):
        return self.base.system

    @property
    def state_names(self):
        return self.base.state_names

    @property
    def momenta(self):
        return self.base.momenta


def _rational(c: float, tol: float) -> "Any":
    import sympy as sp
    f = Fraction(c).limit_denominator(10**6)
    if abs(float(f) - c) <= tol * abs(c):
        return sp.Rational(f.numerator, f.denominator)
    f = Fraction(c)
    return sp.Rational(f.numerator, f.denominator)


def _simplify_numeric(expr, linear_symbols, tol=1e-13):
    """expr (floats for the parameters) as Σ monomial(linear symbols) · cancelled coefficient."""
    import sympy as sp
    num, den = sp.fraction(sp.cancel(sp.together(expr)))
    if num == 0:
        return sp.S.Zero

    def chop(poly):
        terms = sp.Add.make_args(sp.expand(poly))
        coeffs = [float(t.as_coeff_Mul()[0]) for t in terms]
        big = max(abs(c) for c in coeffs)
        return sp.Add(*[_rational(c / big, 1e-14) * t.as_coeff_Mul()[1]
                        for c, t in zip(coeffs, terms) if abs(c) > tol * big]), big

    (n2, nb), (d2, db) = chop(num), chop(den)
    scale = _rational(nb / db, 1e-14)
    groups = sp.collect(sp.expand(n2), list(linear_symbols), evaluate=False)
    out = sp.S.Zero
    for mono, coeff in groups.items():
        out += mono * sp.factor(sp.cancel(scale * coeff / d2))
    return sp.N(out, 17)


def _build_specialised(model, params):
    import casadi as ca
    import sympy as sp
    from nhgait.dynamics.bridge import to_casadi
    from nhgait.dynamics.numeric import NumericModel
    from nhgait.dynamics.system import TIME

    system = model.system
    subs = {s: sp.Float(float(v), 17) for s, v in zip(system.param_symbols, params)}
    linear = list(model.momenta) + list(system.input_symbols)
    rhs = [_simplify_numeric(e.xreplace(subs), linear) for e in model.rhs]
    qdot = [_simplify_numeric(e.xreplace(subs), linear) for e in model.qdot]
    nz, nu, npar = len(model.state), len(system.input_symbols), len(system.param_symbols)
    t, z, u, p = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("params", npar)
    syms = [TIME] + list(model.state) + list(system.input_symbols)
    sx = [t] + [z[i] for i in range(nz)] + [u[i] for i in range(nu)]
    rhs_sx = ca.vertcat(*to_casadi(rhs, syms, sx))
    qdot_sx = ca.vertcat(*to_casadi(qdot, syms, sx))
    fns = dict(model.numeric.functions)
    fns["rhs"] = ca.Function("rhs", [t, z, u, p], [rhs_sx], ["t", "z", "u", "params"], ["zdot"])
    fns["qdot"] = ca.Function("qdot", [z, p], [qdot_sx], ["z", "params"], ["qdot"])
    # numeric check against the general functions at random states away from singular sets
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(50):
        zz, uu = rng.uniform(-1.2, 1.2, nz), rng.normal(size=nu)
        for name, args in (("rhs", (0.3, zz, uu)), ("qdot", (zz,))):
            a = np.asarray(fns[name](*args, params)).ravel()
            b = np.asarray(model.numeric[name](*args, params)).ravel()
            worst = max(worst, float(np.max(np.abs(a - b) / (1.0 + np.abs(b)))))
    if not worst <= 1e-12:
        return None
    old = model.numeric
    return NumericModel(formulation=old.formulation, state_names=old.state_names,
                        input_names=old.input_names, param_names=old.param_names,
                        param_defaults=tuple(float(v) for v in params), functions=fns,
                        n_coordinates=old.n_coordinates, n_multipliers=old.n_multipliers)


def specialise(model, params=None) -> SpecialisedModel:
    """``model`` with parameter values substituted and simplified (cached on disk)."""
    from nhgait.dynamics import cache

    params = np.asarray(model.numeric.params(params), dtype=float)
    key = cache.cache_key(model.system, "reduced-specialised",
                          "params=" + ",".join(float(v).hex() for v in params) + ";v1")
    hit = cache.load(key)
    if hit is None:
        numeric = _build_specialised(model, params)
        hit = {"numeric": numeric}
        cache.store(key, hit)
    numeric = hit["numeric"]
    if numeric is None:  # simplification did not pass its check: keep the general functions
        return SpecialisedModel(model, model.numeric, False)
    return SpecialisedModel(model, numeric, True)


# ------------------------------------------------------------------ planning
@dataclass(frozen=True, eq=False)
class PlanResult:
    """What :func:`plan` produced: the verified solution, the guesses tried and the files."""

    system: str
    gait: str
    solution: Any
    attempts: tuple                  # ((guess label, status), ...)
    files: tuple = ()
    derive_time_s: float = 0.0
    timings: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return bool(self.solution.success)


def solve_task(problem, family: str, *, transcription="multiple-shooting", jit=False, options=None):
    """Solve ``problem`` from the guesses of ``family`` until Ipopt succeeds.

    Returns (solution, attempts, solver). The transcription/NLP is built once and reused for
    every candidate guess.
    """
    from nhgait.ocp import OCPSolver, SolverOptions
    from .guesses import candidates

    solver = OCPSolver(problem, transcription, options or SolverOptions(jit=jit))
    attempts = []
    solution = None
    for guess in candidates(problem, family):
        solution = solver.solve(guess)
        attempts.append((guess.label, solution.status))
        if solution.success:
            break
    return solution, tuple(attempts), solver


def plan(system_name: str, gait: str, *, distance=None, angle=None, period=None, intervals=None,
         transcription="multiple-shooting", jit=False, out_dir=None, animate=True,
         verify=True) -> PlanResult:
    """Plan a gait: derive → specialise → task → guess → solve → verify → write files.

    Files in ``out_dir`` (when given): ``solution.json``, ``path.png``, ``shape.png``,
    ``histories.png``, ``momentum.png`` and ``motion.gif`` (``animate=False`` skips the GIF).
    """
    from nhgait.dynamics import builtin, derive
    from .tasks import get_task

    task = get_task(system_name, gait)
    timings = {}
    t0 = time.perf_counter()
    model = derive(builtin(system_name), "reduced")
    timings["derive_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fast = specialise(model)
    timings["specialise_s"] = time.perf_counter() - t0
    problem = task.problem(fast, distance=distance, angle=angle, period=period,
                           intervals=100 if intervals is None else int(intervals))
    solution, attempts, solver = solve_task(problem, task.guess_family, transcription=transcription, jit=jit)
    timings["setup_s"] = solver.setup_time_s
    timings["jit_cached"] = solver.jit_cached
    if verify:
        solution = solution.verified()
    solution = _with_settings(solution, {"system": system_name, "gait": gait, "attempts": [list(a) for a in attempts],
                                         "specialised_model": fast.simplified, **timings})
    files = []
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        files.append(solution.to_json(out / "solution.json"))
        files.extend(_write_figures(solution, out, system_name, animate))
    return PlanResult(system_name, gait, solution, attempts, tuple(files), timings["derive_s"], timings)


def _with_settings(solution, extra):
    from dataclasses import replace
    return replace(solution, settings={**solution.settings, **extra})


def _write_figures(solution, out: Path, system_name: str, animate: bool) -> list:
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from . import plots

    files = []
    for name, fn in (("path.png", plots.plot_path), ("shape.png", plots.plot_shape_loop),
                     ("histories.png", plots.plot_histories), ("momentum.png", plots.plot_momentum)):
        fig = fn(solution, system=system_name).figure
        path = out / name
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        files.append(path)
    if animate:
        from .animation import animate_solution
        files.append(animate_solution(solution, out / "motion.gif", system=system_name))
    return files
