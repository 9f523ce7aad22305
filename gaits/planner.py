"""The gait planner: derive → specialise → task → guess → solve → verify → write.

:func:`plan` is the one entry point used by ``nhgait plan``::

    result = plan("snakeboard", "forward", distance=1.0, out_dir="out/demo")
    result.solution.objective, result.solution.verification_error, result.files

Specialisation
--------------
The derived reduced ODE keeps its parameters symbolic, so its CasADi expressions carry
every parameter combination (the snakeboard's ż costs ~310 SX operations). For planning the
parameters are fixed, so :func:`specialise` substitutes their values into the sympy rhs and
q̇(z), brings each component to one fraction with sin/cos of each angle as symbols reduced
by sin² = 1 − cos², drops coefficients below 1e-13 of the largest one (round-off of
cancelled terms such as J + J_r + 2J_w − m r²), cancels denominator factors that divide a
numerator up to round-off, and rationalises the remaining coefficients. The result
(snakeboard 65 operations) is checked against the original functions at random states
(relative error ≤ 1e-12, else the original is kept) and cached on disk by the model's
content hash and the exact parameter values, so a second process pays neither the
derivation nor the simplification.

Velocity coordinates
--------------------
``specialise(model, velocities=names)`` also changes the state from the momenta to n − k
velocity quantities y = Y(q) q̇ (``<coordinate>_dot``, ``forward_velocity``): with the
reduced velocities v = K⁻¹P = B⁻¹y (B = Y X), q̇ = X v and ẏ = Ḃ v + B K⁻¹(Ṗ − K̇ v),
simplified as above and checked against the momentum ODE (ẏ by automatic differentiation
of Y(q) q̇(z) along ż). Each gait task names its velocities; the snakeboard's (v, ψ̇, φ̇), v the
forward body velocity, give a 46-operation ODE in which the tasks' rest and periodicity
conditions are bounds or linear rows, and Ipopt takes the reference's iteration counts
(P3: 13–17 instead of 24–36 in momenta). :func:`plan` reports its solution in the momentum
coordinates (:func:`to_momentum_coordinates`) and verifies it there.
"""
from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["plan", "PlanResult", "specialise", "SpecialisedModel", "solve_task", "to_momentum_coordinates"]


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
        return tuple(self.numeric.state_names)

    @property
    def velocities(self) -> tuple:
        """The velocity quantities of the state (empty: momentum coordinates)."""
        if self.numeric.formulation != "reduced-velocity":
            return ()
        return tuple(self.numeric.state_names[self.numeric.n_coordinates:])

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


def _trig_symbols(expr):
    """``expr`` with sin(a), cos(a) (after ``expand_trig``) replaced by symbols S_a, C_a.

    Returns (expr, pairs [(S_a, C_a), ...], back-substitution dict).
    """
    import sympy as sp
    expr = sp.expand_trig(expr.replace(sp.tan, lambda a: sp.sin(a) / sp.cos(a)))
    args = sorted({f.args[0] for f in expr.atoms(sp.sin, sp.cos)}, key=sp.default_sort_key)
    pairs, fwd, back = [], {}, {}
    for k, a in enumerate(args):
        S, C = sp.Dummy(f"S{k}"), sp.Dummy(f"C{k}")
        fwd[sp.sin(a)], fwd[sp.cos(a)] = S, C
        back[S], back[C] = sp.sin(a), sp.cos(a)
        pairs.append((S, C))
    return expr.xreplace(fwd), pairs, back


def _pythagoras(poly, pairs):
    """``poly`` reduced modulo S² + C² − 1 for each pair (at most linear in every S)."""
    import sympy as sp
    for S, C in pairs:
        poly = sp.expand(sp.rem(sp.expand(poly), S**2 + C**2 - 1, S))
    return poly


def _simplify_numeric(expr, linear_symbols, tol=1e-13):
    """expr (floats for the parameters) as Σ monomial(linear symbols) · cancelled coefficient.

    sin/cos of each angle are treated as symbols S, C with S² = 1 − C² (so terms that vanish
    only through the Pythagorean identity, e.g. a velocity basis written with sin 2φ and
    cos²φ, cancel), coefficients below ``tol`` of the largest are dropped (round-off of
    cancelled parameter combinations) and the rest rationalised.
    """
    import sympy as sp
    expr, pairs, back = _trig_symbols(expr)
    num, den = sp.fraction(sp.cancel(sp.together(expr)))
    num, den = _pythagoras(num, pairs), _pythagoras(den, pairs)
    if num == 0:
        return sp.S.Zero

    def chop(poly):
        terms = sp.Add.make_args(sp.expand(poly))
        coeffs = [float(t.as_coeff_Mul()[0]) for t in terms]
        big = max(abs(c) for c in coeffs)
        return sp.Add(*[_rational(c / big, 1e-14) * t.as_coeff_Mul()[1]
                        for c, t in zip(coeffs, terms) if abs(c) > tol * big]), big

    (n2, nb), (d2, db) = chop(num), chop(den)
    if n2 == 0:
        return sp.S.Zero
    scale = _rational(nb / db, 1e-14)
    groups = sp.collect(sp.expand(n2), list(linear_symbols), evaluate=False)
    out = sp.S.Zero
    for mono, coeff in groups.items():
        out += mono * _cancel_numeric(scale * coeff, d2, tol)
    return sp.N(out.xreplace(back), 17)


def _cancel_numeric(num, den, tol):
    """num/den with the factors of den that divide num up to round-off (remainder ≤ tol) cancelled.

    Exact ``cancel`` misses factors when irrational parameter values (r = √2.4) leave
    rationalised coefficients that agree with a product only to ~1e-16.
    """
    import sympy as sp
    exact = sp.cancel(num / den)
    n0, d0 = sp.fraction(exact)
    if not d0.free_symbols:
        return sp.factor(exact)
    const, factors = sp.factor_list(d0)
    num, den = sp.expand(n0), const
    for f, k in factors:
        for _ in range(k):
            gens = sorted(num.free_symbols | f.free_symbols, key=sp.default_sort_key)
            pn = sp.Poly(num, *gens, domain="RR")
            qt, rm = pn.div(sp.Poly(f, *gens, domain="RR"))
            size = max(abs(float(c)) for c in pn.coeffs())
            if rm.is_zero or max(abs(float(c)) for c in rm.coeffs()) <= 1e3 * tol * size:
                num = qt.as_expr()
            else:
                den = den * f
    terms = sp.Add.make_args(sp.expand(num))
    big = max(abs(float(t.as_coeff_Mul()[0])) for t in terms)
    num = sp.Add(*[_rational(float(t.as_coeff_Mul()[0]), 1e-14) * t.as_coeff_Mul()[1] for t in terms
                   if abs(float(t.as_coeff_Mul()[0])) > tol * big])
    return sp.factor(num / den)


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


def _velocity_rows(names, coordinates, q):
    """Rows Y(q) (sympy, one per name) of velocity quantities y = Y(q) q̇.

    ``<coordinate>_dot`` is q̇_i; for planar bodies (coordinates x, y, theta)
    ``forward_velocity`` = ẋ cos θ + ẏ sin θ and ``lateral_velocity`` = −ẋ sin θ + ẏ cos θ
    (the same quantities :mod:`nhgait.ocp.problem` offers on every model).
    """
    import sympy as sp
    from nhgait.ocp import ProblemError

    n = len(coordinates)
    rows, problems = [], []
    for name in names:
        row = [sp.S.Zero] * n
        if name.endswith("_dot") and name[:-4] in coordinates:
            row[coordinates.index(name[:-4])] = sp.S.One
        elif name in ("forward_velocity", "lateral_velocity") and {"x", "y", "theta"} <= set(coordinates):
            th = q[coordinates.index("theta")]
            c, s_ = sp.cos(th), sp.sin(th)
            ix, iy = coordinates.index("x"), coordinates.index("y")
            row[ix], row[iy] = (c, s_) if name == "forward_velocity" else (-s_, c)
        else:
            problems.append(f"velocities: {name!r} is not a velocity quantity (use <coordinate>_dot"
                            f" for {', '.join(coordinates)}, forward_velocity or lateral_velocity)")
        rows.append(row)
    if len(set(names)) != len(names):
        problems.append(f"velocities: repeated names in {tuple(names)}")
    if problems:
        raise ProblemError(problems, title="invalid velocity coordinates")
    return sp.Matrix(rows)


def _build_velocity(model, params, velocities):
    """The reduced ODE in velocity coordinates z = (q, y), y = Y(q) q̇ (see :func:`specialise`)."""
    import casadi as ca
    import sympy as sp
    from nhgait.dynamics.bridge import to_casadi
    from nhgait.dynamics.numeric import NumericModel
    from nhgait.ocp import ProblemError

    system = model.system
    coords = tuple(system.coordinates)
    n, nv = len(coords), len(model.state) - len(coords)
    if len(velocities) != nv:
        raise ProblemError([f"velocities: {system.name if hasattr(system, 'name') else 'the model'} needs "
                            f"{nv} velocity quantities (one per reduced momentum), got {len(velocities)}"],
                           title="invalid velocity coordinates")
    subs = {s: sp.Float(float(v), 17) for s, v in zip(system.param_symbols, params)}
    q, P = list(model.state[:n]), list(model.state[n:])
    ys = sp.Matrix(sp.symbols(f"y0:{nv}"))
    vs = sp.Matrix(sp.symbols(f"v0:{nv}"))
    K = model.K.xreplace(subs)
    X = model.X.xreplace(subs)
    Y = _velocity_rows(velocities, coords, q)
    B = (Y * X).applyfunc(lambda e: _simplify_numeric(e, []))        # y = B(q) v, v = K⁻¹P
    rng = np.random.default_rng(0)
    probe = {qi: float(rng.uniform(-0.7, 0.7)) for qi in q}
    if abs(float(B.xreplace(probe).det())) < 1e-9:
        raise ProblemError([f"velocities {tuple(velocities)} do not parametrise the allowed velocities "
                            "(Y X is singular)"], title="invalid velocity coordinates")
    Binv = B.inv()
    v_of_y = Binv * ys
    rhs = model.rhs.xreplace(subs)
    qdot_v = list(X * vs)                                             # q̇ = X v
    Pdot = sp.Matrix([e.xreplace(dict(zip(P, K * vs))) for e in rhs[n:]])
    Kdot, Bdot = sp.zeros(nv, nv), sp.zeros(nv, nv)
    for i, qi in enumerate(q):
        Kdot += K.diff(qi) * qdot_v[i]
        Bdot += B.diff(qi) * qdot_v[i]
    vdot = K.inv() * (Pdot - Kdot * vs)                               # P = K v
    ydot = Bdot * vs + B * vdot
    back = dict(zip(vs, v_of_y))
    inputs = list(system.input_symbols)
    linear = list(ys) + inputs
    qdot = [_simplify_numeric(e.xreplace(back), linear) for e in qdot_v]
    ydot = [_simplify_numeric(e.xreplace(back), linear) for e in ydot]
    nz, nu, npar = n + nv, len(inputs), len(system.param_symbols)
    t, z, u, p = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", nu), ca.SX.sym("params", npar)
    sx = [z[i] for i in range(nz)] + [u[i] for i in range(nu)]
    out = to_casadi(qdot + ydot, q + list(ys) + inputs, sx)
    qs, qd = ca.SX.sym("q", n), ca.SX.sym("qdot", n)
    # list(M.T) is M column-major, as ca.reshape expects
    Ysx = ca.reshape(ca.vertcat(*to_casadi(list(Y.T), q, [qs[i] for i in range(n)])), nv, n)
    KBinv = ca.reshape(ca.vertcat(*to_casadi(list((K * Binv).T), q, [z[i] for i in range(n)])), nv, nv)
    fns = {
        "rhs": ca.Function("rhs", [t, z, u, p], [ca.vertcat(*out)], ["t", "z", "u", "params"], ["zdot"]),
        "qdot": ca.Function("qdot", [z, p], [ca.vertcat(*out[:n])], ["z", "params"], ["qdot"]),
        "state": ca.Function("state", [qs, qd, p], [ca.vertcat(qs, ca.mtimes(Ysx, qd))],
                             ["q", "qdot", "params"], ["z"]),
        "momentum_state": ca.Function("momentum_state", [z, p], [ca.vertcat(z[:n], ca.mtimes(KBinv, z[n:]))],
                                      ["z", "params"], ["z_momentum"]),
    }
    # check against the momentum model: z_P = (q, K B⁻¹ y); q̇ must agree and
    # ẏ = d/dt [Y(q) q̇(z_P)] along ż_P = rhs_P (automatic differentiation).
    zp, up = ca.SX.sym("zp", nz), ca.SX.sym("up", nu)
    y_of_zp = ca.substitute(ca.mtimes(Ysx, model.numeric["qdot"](zp, params)), qs, zp[:n])
    ydot_ref = ca.Function("ydot_ref", [zp, up], [ca.jtimes(y_of_zp, zp, model.numeric["rhs"](0, zp, up, params))])
    worst = 0.0
    for _ in range(50):
        zz, uu = rng.uniform(-1.2, 1.2, nz), rng.normal(size=nu)
        zP = np.asarray(fns["momentum_state"](zz, params)).ravel()
        a = np.asarray(fns["rhs"](0.0, zz, uu, params)).ravel()
        b = np.concatenate([np.asarray(model.numeric["qdot"](zP, params)).ravel(),
                            np.asarray(ydot_ref(zP, uu)).ravel()])
        c = np.asarray(fns["state"](zz[:n], a[:n], params)).ravel()
        worst = max(worst, float(np.max(np.abs(a - b) / (1.0 + np.abs(b)))),
                    float(np.max(np.abs(c - zz) / (1.0 + np.abs(zz)))))
    if not worst <= 1e-10:
        raise RuntimeError(f"velocity-coordinate ODE disagrees with the momentum ODE (relative error {worst:.1e})")
    old = model.numeric
    return NumericModel(formulation="reduced-velocity", state_names=coords + tuple(velocities),
                        input_names=old.input_names, param_names=old.param_names,
                        param_defaults=tuple(float(v) for v in params), functions=fns, n_coordinates=n)


def specialise(model, params=None, *, velocities=None) -> SpecialisedModel:
    """``model`` with parameter values substituted and simplified (cached on disk).

    With ``velocities`` (names of n − k velocity quantities, e.g. ``("forward_velocity",
    "psi_dot", "phi_dot")``) the state becomes z = (q, y), y = Y(q) q̇, instead of the
    momenta: with v = K⁻¹P = B⁻¹y (B = Y X), q̇ = X v and ẏ = Ḃ v + B K⁻¹(Ṗ − K̇ v).
    """
    from nhgait.dynamics import cache

    params = np.asarray(model.numeric.params(params), dtype=float)
    velocities = tuple(velocities or ())
    code = hashlib.sha256(Path(__file__).read_bytes()).hexdigest()   # the code that specialises
    key = cache.cache_key(model.system, "reduced-specialised",
                          "params=" + ",".join(float(v).hex() for v in params)
                          + ";velocities=" + ",".join(velocities) + ";code=" + code)
    hit = cache.load(key, dict)
    if hit is None:
        if velocities:
            numeric = _build_velocity(model, params, velocities)
        else:
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
    fast = specialise(model, velocities=task.velocities)
    timings["specialise_s"] = time.perf_counter() - t0
    problem = task.problem(fast, distance=distance, angle=angle, period=period,
                           intervals=100 if intervals is None else int(intervals))
    solution, attempts, solver = solve_task(problem, task.guess_family, transcription=transcription, jit=jit)
    timings["setup_s"] = solver.setup_time_s
    timings["jit_cached"] = solver.jit_cached
    if fast.velocities:  # report (and verify) in the momentum coordinates z = (q, P)
        momentum_problem = task.problem(specialise(model), distance=distance, angle=angle, period=period,
                                        intervals=problem.intervals)
        solution = to_momentum_coordinates(solution, momentum_problem)
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


def to_momentum_coordinates(solution, momentum_problem):
    """A velocity-coordinate solution re-expressed on ``momentum_problem`` (z = (q, P), P = K B⁻¹y).

    The statement is the same (tasks are coordinate-free); only the states change. Any
    verification is dropped: verify the returned solution in momentum coordinates.
    """
    from dataclasses import replace
    model = solution.problem.model
    to_p = model.numeric["momentum_state"]
    params = solution.problem.params
    states = np.column_stack([np.asarray(to_p(solution.states[:, k], params)).ravel()
                              for k in range(solution.states.shape[1])])
    settings = {**solution.settings, "transcribed_in": list(solution.state_names)}
    return replace(solution, states=states, state_names=momentum_problem.state_names,
                   problem=momentum_problem, verification=None, settings=settings)


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
