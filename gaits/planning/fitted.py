"""An initial guess fitted to the task through the robot's own kinematics.

For a model in velocity coordinates z = (q, y) the configuration follows from the velocity
states: q̇ = q̇(q, y) (the model's ``qdot``). The guess chooses y(t) from a small basis,

    y_i(t) = a_i + (b_i − a_i) t/T + Σ_k c_ik φ_k(t),
    φ_1 = 30 t²(T − t)²/T⁴ (a bump of unit mean),  φ_2 = sin ωt,  φ_3 = sin 2ωt,  ω = 2π/T,

(a_i, b_i the task's fixed end values of y_i, else 0; every φ_k vanishes at both ends), rolls
the kinematics out from the task's initial configuration (RK4, 4 steps per interval, as the
transcription) and fits the coefficients c by least squares so that the rolled-out motion
meets the task: the fixed final coordinates, the periodic coordinates (q(T) = q(0)), the path
bounds at the nodes (as penalties) and a small weight on c (the gentlest motion that does it;
the targets are then met to about 1e-3, and the solver starts closer to its optimum than from
an exact fit: the cart with two trailers takes 6 iterations from this fit, 10 from an exact one).
The result moves only in allowed directions and ends where the task ends — what the
hand-written reference does by hand for its cart (a speed bump and a heading wave fitted by
Newton), here for any robot. The roll-out and its Jacobian are one CasADi function
(``mapaccum`` over the sub-steps), compiled by the fast compiler when there is one
(:func:`~nhgait.dynamics.numerics.fast_compiler.compiled_fast`), so a fit takes milliseconds to
a few seconds.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from nhgait.ocp import InitialGuess

__all__ = ["fitted_guess", "applies", "leads", "LABEL"]

LABEL = "fitted roll-out"
#: basis functions per velocity state, least-squares starts, weights of bounds and of c
BASIS, STARTS, BOUND_WEIGHT, SMALL_WEIGHT = 3, 4, 10.0, 1e-2
STEPS = 4
#: a start whose targets' part of the least-squares cost (without the small weight on c) is
#: below this meets them to about 1e-2: the further starts are not tried (each costs roll-outs
#: and their Jacobians — 6 to 28 s for the Whipple bicycle's 480 implicit sub-steps)
GOOD_ENOUGH = 1e-4
#: a fit stops when an iteration lowers its cost by less than this fraction: a guess needs the
#: shape of the fit, not its last digits (opty's garage at N = 300: 162 evaluations to reach the
#: cost 1.1658e-4 that 20 reach to 30 %, 10 s instead of 1 s)
FIT_FTOL = 1e-3


def applies(problem) -> bool:
    """A velocity-coordinate model (``qdot`` of z = (q, y)) and a task that fixes a final
    coordinate or asks for a periodic one."""
    model = problem.model
    coords = tuple(model.system.coordinates)
    if not getattr(model, "velocities", None) or "qdot" not in model.numeric.functions:
        return False
    return bool(_targets(problem, coords)) or any(c in problem.periodic for c in coords)


def leads(problem, shape: tuple) -> bool:
    """Whether the fitted roll-out goes before the shape loops: when the velocity states are
    driven by the inputs directly (∂ẏ/∂u has full row rank at a sample state) and some of them
    are not shape rates (a cart's heading rate and wheel speed). Then y(t) can be followed
    as fitted and the roll-out is close to a solution (cart with two trailers: 6 iterations, as
    the hand-written reference's fitted guess, instead of 25–38 from a shape loop). Where the
    motion comes from shape loops through the dynamics (snakes, snakeboards) the loops are
    better starts (3-link snake: 28 iterations from a loop, 46 from the fit) and the fit comes
    second — unless the task starts in motion (a velocity state that is not a shape rate fixed
    to a value other than 0 at t = 0, as a bicycle's forward speed): then the motion is there
    to be steered, not to be made by shape loops, and the roll-out of it goes first (the Whipple
    bicycle's lane change: 18 iterations from the fit; its first loop fails after 297)."""
    model = problem.model
    n = len(model.system.coordinates)
    rates = tuple(model.state_names[n:])
    shape_rates = {f"{c}_dot" for c in shape}
    if not rates or all(r in shape_rates for r in rates):
        return False
    if any(problem.fixed_value(problem.initial, r) not in (None, 0.0) for r in rates if r not in shape_rates):
        return True
    t, z, u = ca.SX.sym("t"), ca.SX.sym("z", len(model.state_names)), ca.SX.sym("u", problem.n_controls)
    rhs = model.numeric["rhs"](t, z, u, problem.params)
    B = ca.Function("B", [t, z, u], [ca.jacobian(rhs[n:], u)])
    sample = np.random.default_rng(1).uniform(-0.5, 0.5, len(model.state_names))
    with np.errstate(all="ignore"):
        Bv = np.asarray(B(0.3, sample, np.zeros(problem.n_controls)))
    return bool(np.all(np.isfinite(Bv)) and np.linalg.matrix_rank(Bv, tol=1e-8) == len(rates))


def _targets(problem, coords) -> list:
    return [(i, v) for i, c in enumerate(coords) if (v := problem.fixed_value(problem.final, c)) is not None]


def _basis(t: np.ndarray, T: float) -> np.ndarray:
    """(BASIS × len(t)): φ_1 bump, φ_2 sin ωt, φ_3 sin 2ωt."""
    w = 2 * math.pi / T
    return np.vstack([30 * t**2 * (T - t) ** 2 / T**4, np.sin(w * t), np.sin(2 * w * t)])[:BASIS]


def _rollout_function(problem, n: int, nv: int):
    """(c → node configurations n × (N+1)) as a CasADi Function, and the fine-grid y(c)."""
    T, N = float(problem.horizon), problem.intervals
    h = T / (N * STEPS)
    fine = np.linspace(0.0, T, 2 * N * STEPS + 1)                 # t, t + h/2, t + h of every sub-step
    names = tuple(problem.model.state_names)
    ends = [(problem.fixed_value(problem.initial, v) or 0.0, problem.fixed_value(problem.final, v) or 0.0)
            for v in names[n:]]
    Y0 = np.array([a + (b - a) * fine / T for a, b in ends]).reshape(nv, -1)
    Phi = _basis(fine, T)
    c = ca.MX.sym("c", nv * BASIS)
    Y = ca.DM(Y0) + ca.mtimes(ca.reshape(c, nv, BASIS), ca.DM(Phi))
    q, ya, ym, yb = (ca.SX.sym(s, k) for s, k in (("q", n), ("ya", nv), ("ym", nv), ("yb", nv)))
    qdot = problem.model.numeric["qdot"]
    f = lambda qq, yy: qdot(ca.vertcat(qq, yy), problem.params)  # noqa: E731
    k1 = f(q, ya)
    k2 = f(q + h / 2 * k1, ym)
    k3 = f(q + h / 2 * k2, ym)
    k4 = f(q + h * k3, yb)
    step = ca.Function("step", [q, ya, ym, yb], [q + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    q0 = ca.MX.sym("q0", n)
    path = step.mapaccum(N * STEPS)(q0, Y[:, 0:-1:2], Y[:, 1::2], Y[:, 2::2])
    nodes = ca.horzcat(q0, path[:, STEPS - 1::STEPS])
    return ca.Function("rollout", [q0, c], [nodes]), Y0, Phi, fine


def _residual_function(problem, coords, rollout):
    """r(q0, c, weight) → (final targets, periodicity, bound penalties, weight · c) and its
    Jacobian in c, as two functions (the fit evaluates r far more often than its Jacobian)."""
    n = len(coords)
    q0, c, weight = ca.MX.sym("q0", n), ca.MX.sym("c", rollout.size1_in(1)), ca.MX.sym("weight")
    Q = rollout(q0, c)
    parts = [Q[i, -1] - v for i, v in _targets(problem, coords)]
    parts += [Q[i, -1] - Q[i, 0] for i, name in enumerate(coords) if name in problem.periodic]
    for i, name in enumerate(coords):
        if name in problem.state_bounds:
            lo, hi = problem.bounds(problem.state_bounds, name)
            if math.isfinite(hi):
                parts.append(BOUND_WEIGHT * ca.fmax(0, Q[i, :] - hi).T)
            if math.isfinite(lo):
                parts.append(BOUND_WEIGHT * ca.fmax(0, lo - Q[i, :]).T)
    parts.append(weight * c)
    r = ca.vertcat(*parts)
    return ca.Function("r", [q0, c, weight], [r]), ca.Function("J", [q0, c, weight], [ca.jacobian(r, c)])


def fitted_guess(problem, coordinates: tuple, initial_configuration) -> InitialGuess:
    """The fitted roll-out of ``problem`` (module docstring) from ``initial_configuration``
    (the task's initial coordinates, free ones at the centre of their bounds)."""
    from scipy.optimize import least_squares

    from nhgait.dynamics.numerics.fast_compiler import compiled_fast
    n = len(coordinates)
    nv = len(problem.model.state_names) - n
    rollout, Y0, Phi, fine = _rollout_function(problem, n, nv)
    residual, jacobian = (compiled_fast(f, salt=f"fitted roll-out {f.name()}")
                          for f in _residual_function(problem, coordinates, rollout))
    q0 = np.asarray(initial_configuration, float)
    T = float(problem.horizon)
    rng = np.random.default_rng(0)
    scale = 2.0 / T

    def fit(c0, weight):
        with np.errstate(all="ignore"):
            return least_squares(lambda c: np.asarray(residual(q0, c, weight)).ravel(), c0,
                                 jac=lambda c: np.asarray(jacobian(q0, c, weight)), method="trf",
                                 max_nfev=200, ftol=FIT_FTOL)

    best = None
    for start in range(STARTS):
        c0 = np.zeros(nv * BASIS) if start == 0 else rng.normal(0.0, scale, nv * BASIS)
        try:
            trial = fit(c0, SMALL_WEIGHT)
        except ValueError:                       # a start whose roll-out crosses the singular set
            continue
        if np.isfinite(trial.cost) and (best is None or trial.cost < best.cost):
            best = trial
        if best is not None and 0.5 * float(np.sum(best.fun[:-c0.size] ** 2)) <= GOOD_ENOUGH:
            break
    c = best.x if best is not None else np.zeros(nv * BASIS)
    Q = np.asarray(rollout(q0, c))
    Y = Y0 + np.reshape(c, (nv, BASIS), order="F") @ Phi          # as ca.reshape (column-major)
    Yn = Y[:, :: 2 * STEPS]
    Z = np.vstack([Q, Yn])
    return InitialGuess(Z, np.zeros((problem.n_controls, problem.intervals)), horizon=T, label=LABEL)
