"""Targets no admissible input can reach, refused before the solver looks for them.

A plan to move the car 10 km in 6 s at |F| ≤ 5 N has no solution, and FATROP searched for one
for minutes. :func:`unreachable_targets` compares each coordinate's required displacement
(from a fixed initial value to the final value or range) with the bound of
:func:`nhgait.dynamics.derivation.reach.displacement_bounds` — an upper bound over every input
within the task's control bounds, starting at rest, judged only when it is exact and cheap
(constant kinetic metric, no potential, forces linear in the inputs). A target beyond it is
impossible, not merely hard; anything nearer goes to the solver (and its time limit).

A robot with one bounded shape coordinate and nothing pushing along its fibre moves only by
the reconstruction equation (:func:`shape_reach`): a two-link sleigh whose every hinge motion
from rest moves it toward its trailing link cannot go forward, and says so before any solve
(issue 42: 18 attempts and 247 s before).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ShapeReach", "Target", "numeric_connection_of", "shape_reach", "target_of", "unreachable_targets"]


def unreachable_targets(problem, system, params=None) -> list:
    """One sentence per coordinate whose final value lies beyond what any admissible input can
    reach in the horizon (for a free horizon, its longest); [] when none does or when the
    bound cannot be judged (the motion does not start at rest, an input is unbounded, …); then,
    for a robot with one bounded shape coordinate, the verdict of :func:`shape_reach` when it
    finds the target out of reach."""
    from nhgait.dynamics.derivation.reach import displacement_bounds
    n = system.n
    if any(problem.fixed_value(problem.initial, v) != 0.0 for v in problem.state_names[n:]):
        return []
    lo, hi = problem.control_bound_vectors()
    bounds = {u: (a, b) for u, a, b in zip(problem.control_names, lo, hi, strict=True)}
    horizon = problem.free_horizon[1] if problem.free_horizon is not None else problem.horizon
    reach = displacement_bounds(system, bounds, float(horizon), params)
    if reach is None:
        return _shape_verdict(problem)
    limits = ", ".join(f"|{u}| ≤ {max(abs(a), abs(b)):g}" for u, (a, b) in bounds.items())
    problems = []
    for name in system.coordinates:
        start = problem.fixed_value(problem.initial, name)
        if start is None or name not in problem.final:
            continue
        low, high = problem.bounds(problem.final, name)
        distance = max(low - start, start - high, 0.0)
        if distance > reach[name] * (1 + 1e-9) and math.isfinite(distance):
            problems.append(f"final {name} is {distance:.6g} from initial {name} = {start:g}, but "
                            "starting at rest "
                            f"with {limits} no input moves {name} more than {reach[name]:.4g} in T = "
                            f"{horizon:g} s (a bound from the kinetic energy the inputs can supply): "
                            "lengthen the horizon, widen the control bounds or move the target")
    return problems or _shape_verdict(problem)


def _shape_verdict(problem) -> list:
    """[the sentence of :func:`shape_reach`] when it finds the target out of reach, else []."""
    try:
        verdict = shape_reach(problem)
    except (RuntimeError, np.linalg.LinAlgError):     # CasADi's evaluation errors: the solver decides
        return []
    return [] if verdict is None or verdict.reachable else [verdict.sentence]


# ----------------------------------------------------------------------------- the target direction
def numeric_connection_of(problem):
    """The :class:`~nhgait.dynamics.geometry.connection_fields.NumericConnection` of the problem's
    model, or None when it has none (no reduced model, no shape, a fibre that is no group)."""
    from nhgait.dynamics.errors import ModelError
    from nhgait.dynamics.geometry.connection_fields import numeric_connection
    base = getattr(problem.model, "base", problem.model)
    if getattr(base, "layout", None) is None or not getattr(base, "shape", ()):
        return None
    try:
        return numeric_connection(base, problem.model.numeric.params(problem.params))
    except ModelError:
        return None


@dataclass(frozen=True, eq=False)
class Target:
    """The task's target direction ``d`` (fibre order) and the fibre components it concerns
    (``mask``)."""

    d: np.ndarray
    mask: np.ndarray


def target_of(problem, fiber: tuple) -> Target | None:
    """The :class:`Target`: the planar position's change when the task fixes both ends of it and
    it changes (mask: x, y), else the change of every fibre coordinate fixed at both ends (mask:
    those); None when d = 0."""
    d, mask = np.zeros(len(fiber)), np.zeros(len(fiber), bool)
    for i, name in enumerate(fiber):
        a, b = problem.fixed_value(problem.initial, name), problem.fixed_value(problem.final, name)
        if a is not None and b is not None:
            d[i], mask[i] = b - a, True
    frame = getattr(problem.model.system, "planar_frame", None) or ()
    planar = np.isin(np.arange(d.size), [fiber.index(c) for c in frame[:2] if c in fiber]) & mask
    if planar.any() and np.linalg.norm(d[planar]) > 0:
        d, mask = np.where(planar, d, 0.0), planar
    return Target(d, mask) if np.linalg.norm(d) > 0 else None


# ----------------------------------------------------------------------------- one shape coordinate
#: shape motions sampled per bounded shape interval: end offsets (fractions of the way to each
#: bound), stroke amplitudes (fractions of the half-width, either sign) and strokes per horizon
SAMPLE_ENDS = (-0.9, -0.45, 0.0, 0.45, 0.9)
SAMPLE_STROKES = (0.0, 0.3, 0.6, 0.95)
SAMPLE_CYCLES = (1, 2, 3, 4)
#: nodes per horizon of a sampled motion (midpoint rule)
SAMPLE_NODES = 160
#: the verdict "not reachable" needs every sampled motion to end short of this fraction of |d|
REACH_FRACTION = 0.02
#: a sampled motion counts when the input it needs stays within this factor of the task's bounds
INPUT_SLACK = 1.1


@dataclass(frozen=True)
class ShapeReach:
    """What the one-shape-coordinate check found (:func:`shape_reach`): the ``shape`` coordinate
    and its ``interval``, whether the momentum equation keeps the momentum pushing away from the
    target over the interval (``momentum_away``), how many sampled motions stayed within the
    input bounds (``samples`` of ``tried``), the best displacement toward the target any of them
    reached (``best``, in the target's units) and the target's distance (``distance``); ``reachable``
    is False when the target is out of reach, with ``sentence`` saying so."""

    shape: str
    interval: tuple
    momentum_away: bool
    samples: int
    tried: int
    best: float
    distance: float
    reachable: bool
    sentence: str


def shape_reach(problem) -> ShapeReach | None:
    """Whether a robot with ONE bounded shape coordinate r, started at rest, can move toward its
    target within the bounds (None when the check does not apply: no local connection, another
    number of shape coordinates, r unbounded, a start not at rest, forces along the fibre, no
    target direction, a task in phases).

    With one shape coordinate there is no height function (no loop encloses an area); what moves
    the fibre is the reconstruction equation ξ = −A(r)ṙ + Γ(r)p with, for one nonholonomic
    momentum, ṗ = σ_rr(r)ṙ² + σ_rp(r)ṙp + σ_pp(r)p² (thesis Table 2.1, mixed). From rest (p = 0),
    at p = 0 the rate is σ_rr ṙ², of the sign of σ_rr whatever r(t) does, so p never changes sign:
    when σ_rr·(Γ·d̂) < 0 over the whole interval (d̂ the target direction in the body frame at the
    start) the momentum pushes the body away from the target for every shape motion
    (``momentum_away``; σ_rr(r) is ṗ at p = 0, ṙ = 1 and Γ(r)·d̂ the fibre velocity of p = 1 at
    ṙ = 0 along d̂, both from the reduced equations at the start's fibre values — numbers only, no
    symbolic work). A principally kinematic robot (d = 0) moves along one curve s(r). The
    remaining geometric part −A(r)ṙ and the turning of the body are sampled: smooth shape
    motions from rest within the interval (an end offset, strokes of several amplitudes and
    frequencies) over the horizon, each followed through the reconstruction and momentum
    equations (:class:`~nhgait.dynamics.geometry.prescribed.FibreIntegrator`), kept when the
    input it needs (from the reduced equations, least squares) stays within the task's bounds;
    the best displacement toward the target at any time is ``best``. Not reachable:
    ``momentum_away`` (or d = 0) and ``best`` < :data:`REACH_FRACTION` |d|.
    """
    case = _one_shape_case(problem)
    if case is None:
        return None
    model = getattr(problem.model, "base", problem.model)
    values = np.asarray(problem.model.numeric.params(problem.params), float)
    distance = float(np.linalg.norm(case.target.d))
    away = _momentum_away(model, values, case)
    best, kept, tried = _sampled_reach(problem, model, values, case)
    reachable = not ((away or model.layout.d == 0) and kept > 0 and best < REACH_FRACTION * distance)
    sentence = "" if reachable else _unreachable_sentence(problem, case, best, kept, away)
    return ShapeReach(shape=case.name, interval=case.interval, momentum_away=away, samples=kept, tried=tried,
                      best=best, distance=distance, reachable=reachable, sentence=sentence)


@dataclass(frozen=True, eq=False)
class _OneShape:
    """The robot and task :func:`shape_reach` judges: the coordinates ``names`` and the start
    ``q0``, the fibre (``fiber``, its rows ``si``), the shape coordinate ``name`` (row ``index``)
    and its ``interval``, the :class:`Target`."""

    names: tuple
    q0: np.ndarray
    fiber: tuple
    si: tuple
    name: str
    index: int
    interval: tuple
    target: Target


def _one_shape_case(problem) -> _OneShape | None:
    """The :class:`_OneShape` when :func:`shape_reach` applies, else None."""
    model = getattr(problem.model, "base", problem.model)
    layout = getattr(model, "layout", None)
    if layout is None or len(layout.free) != 1 or layout.d > 1 or not layout.si:
        return None
    if getattr(problem, "phases", ()):                     # horizons and bounds per phase: not judged
        return None
    names = tuple(model.system.coordinates)
    n = len(names)
    if any(problem.fixed_value(problem.initial, v) != 0.0 for v in problem.state_names[n:]):
        return None                                        # not from rest
    tau = model.system.tau
    if any(not tau[i].is_zero for i in layout.si):
        return None                                        # something pushes along the fibre
    index = layout.free[0]
    name = names[index]
    if name not in problem.state_bounds:
        return None
    lo, hi = problem.bounds(problem.state_bounds, name)
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        return None
    target = target_of(problem, tuple(layout.fiber))
    if target is None:
        return None
    q0 = np.array([problem.fixed_value(problem.initial, c) or 0.0 for c in names])
    return _OneShape(names=names, q0=q0, fiber=tuple(layout.fiber), si=tuple(layout.si), name=name,
                     index=index, interval=(lo, hi), target=target)


def _shape_momenta(model, values):
    """(q, ṙ) → the shape momenta P_r = K_r(q)ṙ of the horizontal lift X_r ṙ (thesis step 8), CasADi."""
    import casadi as ca
    layout, numeric = model.layout, model.numeric
    n, d, m = len(model.system.coordinates), layout.d, len(layout.free)
    q, r_dot = ca.MX.sym("q", n), ca.MX.sym("rd", m)
    X = numeric["basis"](ca.vertcat(q, ca.DM.zeros(len(model.momenta))), values)
    P_r = numeric["state"](q, ca.mtimes(X[:, d:], r_dot), values)[n + d:]
    return q, r_dot, P_r


def _momentum_away(model, values, case: _OneShape) -> bool:
    """Whether σ_rr(r)·(Γ(r)·d̂) < 0 on a grid of the interval (one momentum; False otherwise)."""
    if model.layout.d != 1:
        return False
    import casadi as ca
    n = len(case.names)
    q, r_dot, P_r = _shape_momenta(model, values)
    u0 = ca.DM.zeros(len(model.system.inputs))
    p_rate = model.numeric["rhs"](0.0, ca.vertcat(q, 0.0, P_r), u0, values)[n]       # σ_rr at ṙ = 1
    pushed = model.numeric["qdot"](ca.vertcat(q, 1.0, ca.DM.zeros(P_r.shape[0])), values)
    along = ca.dot(pushed[list(case.si)], ca.DM(case.target.d / np.linalg.norm(case.target.d)))
    grid = np.linspace(*case.interval, 41)
    Q = np.repeat(case.q0[:, None], grid.size, axis=1)
    Q[case.index] = grid
    f = ca.Function("momentum_sign", [q, r_dot], [p_rate * along]).map(grid.size)
    signs = np.asarray(f(Q, np.ones((1, grid.size)))).ravel()
    return bool(np.all(signs < 0.0))


def _shape_paths(case: _OneShape, t) -> np.ndarray:
    """The sampled shape motions r(t) (S×K, module constants), each from the start at rest:
    r0 + Δ(1 − cos πt/T)/2 + a(1 − cos 2πkt/T)/2, clipped to the interval."""
    lo, hi = case.interval
    r0 = float(np.clip(case.q0[case.index], lo, hi))
    T = float(t[-1])
    half = (hi - lo) / 2
    out = []
    for e in SAMPLE_ENDS:
        delta = e * ((hi - r0) if e > 0 else (r0 - lo))
        for a in SAMPLE_STROKES:
            for sign in ((1.0, -1.0) if a else (1.0,)):
                for k in (SAMPLE_CYCLES if a else (1,)):
                    r = (r0 + delta * (1 - np.cos(np.pi * t / T)) / 2
                         + sign * a * half * (1 - np.cos(2 * np.pi * k * t / T)) / 2)
                    out.append(np.clip(r, lo, hi))
    return np.array(out)


def _input_function(model, values):
    """(q, ṙ, r̈, p) → what the inputs must do along a shape path: Ṗ_r wanted − Ṗ_r(u = 0) and
    ∂Ṗ_r/∂u (the reduced equations are affine in u), as one CasADi Function."""
    import casadi as ca
    layout = model.layout
    n, d, nu = len(model.system.coordinates), layout.d, len(model.system.inputs)
    q, r_dot, P_r = _shape_momenta(model, values)
    r_ddot, p, u = ca.MX.sym("rdd", r_dot.shape[0]), ca.MX.sym("p", d), ca.MX.sym("u", nu)
    # Ṗ_r along the path: ∂P_r/∂q q̇_r + ∂P_r/∂ṙ r̈ (the fibre does not enter K_r, thesis step 8)
    q_dot = ca.MX.zeros(n)
    for j, k in enumerate(layout.free):
        q_dot[k] = r_dot[j]
    wanted = ca.jtimes(P_r, q, q_dot) + ca.jtimes(P_r, r_dot, r_ddot)
    zdot = model.numeric["rhs"](0.0, ca.vertcat(q, p, P_r), u, values)[n + d:]
    zero = ca.DM.zeros(nu)
    return ca.Function("shape_inputs", [q, r_dot, r_ddot, p],
                       [wanted - ca.substitute(zdot, u, zero), ca.substitute(ca.jacobian(zdot, u), u, zero)])


def _sampled_reach(problem, model, values, case: _OneShape) -> tuple:
    """(best displacement toward the target, motions within the input bounds, motions tried)
    over :func:`_shape_paths` (:func:`shape_reach`)."""
    from nhgait.dynamics.geometry.prescribed import FibreIntegrator
    horizon = problem.free_horizon[1] if problem.free_horizon is not None else problem.horizon
    t = np.linspace(0.0, float(horizon), SAMPLE_NODES + 1)
    paths = _shape_paths(case, t)
    integrate = FibreIntegrator(model, values)
    lo, hi = problem.control_bound_vectors()
    bounded = np.isfinite(lo).any() or np.isfinite(hi).any()
    inputs = _input_function(model, values).map(t.size) if bounded else None
    mask, d = case.target.mask, case.target.d
    distance = float(np.linalg.norm(d))
    best, kept = -math.inf, 0
    for r in paths:
        q = np.repeat(case.q0[:, None], t.size, axis=1)
        q[case.index] = r
        motion = integrate(t, q)
        if not np.all(np.isfinite(motion.fiber)):
            continue
        if inputs is not None and not _within_inputs(inputs, q, r, t, motion.momentum, (lo, hi)):
            continue
        kept += 1
        moved = motion.fiber - motion.fiber[:, :1]
        progress = distance - np.linalg.norm(np.where(mask[:, None], moved, 0.0) - d[:, None], axis=0)
        best = max(best, float(np.max(progress)))
    return best, kept, len(paths)


def _within_inputs(inputs, q, r, t, momentum, bounds) -> bool:
    """Whether the least-squares inputs of the path q(t) (shape r(t)) stay within ``bounds``
    (lo, hi) widened by :data:`INPUT_SLACK`; ``inputs`` is :func:`_input_function` mapped over t."""
    lo, hi = bounds
    r_dot = np.gradient(r, t)
    residual, G = inputs(q, r_dot[None, :], np.gradient(r_dot, t)[None, :], momentum)
    residual, G = np.asarray(residual), np.asarray(G)                     # m×K, m×(K·nu)
    m, K = residual.shape
    stacked = G.reshape(m, K, lo.size).transpose(1, 0, 2)                 # K×m×nu
    u = np.einsum("kij,kj->ki", np.linalg.pinv(stacked), residual.T)       # K×nu
    low, high = INPUT_SLACK * np.minimum(lo, 0) - 1e-9, INPUT_SLACK * np.maximum(hi, 0) + 1e-9
    return bool(np.all(u >= low) and np.all(u <= high))


def _unreachable_sentence(problem, case: _OneShape, best, kept, away) -> str:
    """The verdict of :func:`shape_reach` in one sentence a user can act on."""
    target, name = case.target, case.name
    wanted = " and ".join(f"{c} by {v:+.3g}"
                          for c, v, on in zip(case.fiber, target.d, target.mask, strict=True) if on and v)
    lo, hi = case.interval
    lo_u, hi_u = problem.control_bound_vectors()
    limits = ", ".join(f"{u} in [{a:g}, {b:g}]"
                       for u, a, b in zip(problem.control_names, lo_u, hi_u, strict=True)
                       if math.isfinite(a) or math.isfinite(b))
    why = ("from rest the momentum equation keeps the nonholonomic momentum pushing the robot away "
           f"from that direction for every motion of {name} in [{lo:g}, {hi:g}] (σ_rr·Γ of one sign there)"
           if away else f"with d = 0 the fibre follows one curve of {name}")
    horizon = problem.free_horizon[1] if problem.free_horizon is not None else problem.horizon
    return (f"not reachable within the bounds: the target ({wanted}) needs motion toward it, but {why}, "
            f"and none of {kept} sampled motions of {name} within [{lo:g}, {hi:g}]"
            + (f" and {limits}" if limits else "")
            + f" gets it nearer in T = {float(horizon):g} s (the best: {max(best, 0.0):.2g} of the "
            f"{float(np.linalg.norm(target.d)):.3g} needed) — widen the bounds of {name}, add an input "
            "that pushes along the fibre, or move the target the other way")
