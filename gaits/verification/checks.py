"""Three checks of a planned gait, and which one decides (docs/verification.md).

A plan is (t_k, z_k, u_k), k = 0 … N, with ż = f(t, z, u) and u = u_k on [t_k, t_{k+1}). Each
check re-integrates with an integrator independent of the transcription (scipy DOP853,
rtol 1e-10, atol 1e-12) and judges the node errors relative to each state's scale
s_i = max(1, range of z_i over the nodes) (:func:`~nhgait.ocp.solution.scales`):

1. **interval** — the transcription's own error. Each interval from its own node::

       e_int = max_k max_i |φ_{t_k→t_{k+1}}(z_k; u_k) − z_{k+1}|_i / s_i,

   which holds for unstable robots too: no error is carried from one interval to the next.
2. **closed loop** — usability: the whole gait re-simulated from z_0 with the plan's own
   discrete time-varying LQR (:func:`~nhgait.ocp.feedback.riccati` on the stage Jacobians
   [A_k B_k] = ∂F/∂(z, u) of the shooting map, CasADi AD), applied sample-and-hold as in its
   design: u = sat(u_k − K_k (z(t_k) − z_k)) on [t_k, t_{k+1}). Its node error e_cl and the
   conditions (ends, periodicity) met by the re-simulated nodes.
3. **open loop** — :meth:`~nhgait.ocp.Solution.verify`: the inputs u_k alone from z_0.

Stability along the gait (reported whatever decides):

* the *growth rate* λ_max = max_k max Re eig ∂f/∂z (t_k, z_k, u_k) [1/s] — the largest rate at
  which a deviation grows at a node (for an upright coin at rest, the inverted pendulum's √(g/l));
* the *amplification* over the horizon, ln σ_max(A_{N−1} ⋯ A_0) — the factor by which the open
  loop multiplies an error (ln: in e-folds; exp(λ T) for a constant λ).

Which decides: the open loop when the gait is *stable* for verification, i.e. its amplification
is at most :data:`STABLE_AMPLIFICATION` (an error grows at most that factor: the open loop can
then show what the transcription's error does to the whole gait); otherwise the interval and
closed-loop checks together — an open-loop re-simulation of an unstable gait multiplies the
integrator's own 1e-10 by e^{λT} and can never verify it, however fine the transcription
(a coin upright: λ ≈ 6.3 /s over 6 s, e^{38} ≈ 10¹⁶); one that passes all the same (a mildly
unstable gait, an accurate transcription) verifies the gait too.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["GaitChecks", "gait_checks", "checks_of", "STABLE_AMPLIFICATION", "check_lines",
           "solution_check_lines", "open_loop_label"]

#: an open loop that multiplies errors by at most this factor over the horizon decides
STABLE_AMPLIFICATION = 1e3
_RTOL, _ATOL = 1e-10, 1e-12


@dataclass(frozen=True, kw_only=True)
class GaitChecks:
    """The three checks of the module docstring (errors scaled by each state's scale).

    interval_error, interval_state : e_int and the state where it is largest;
    closed_loop_error, closed_loop_state : e_cl and its state; closed_loop_conditions : condition
    name → how far the closed loop's nodes miss it (scaled); closed_loop_ran : the closed-loop
    re-simulation ran through; open_loop_error : the open loop's largest scaled error (nodes and
    conditions; inf when it stopped); growth_rate : λ_max [1/s]; amplification : ln σ_max of the
    open loop's transition over the horizon; horizon : T [s]; tolerance; decided_by : "open loop"
    or "interval and closed loop"; passed : whether the deciding checks pass.
    """

    interval_error: float
    interval_state: str
    closed_loop_error: float
    closed_loop_state: str
    closed_loop_ran: bool
    open_loop_error: float
    open_loop_passed: bool
    growth_rate: float
    amplification: float
    horizon: float
    tolerance: float
    closed_loop_conditions: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        """Whether the open loop amplifies errors by at most :data:`STABLE_AMPLIFICATION` (also when
        the amplification is unknown: Jacobians not finite along the gait, the open loop decides)."""
        return not bool(self.amplification > math.log(STABLE_AMPLIFICATION))

    @property
    def decided_by(self) -> str:
        return "open loop" if self.stable else "interval and closed loop"

    @property
    def interval_passed(self) -> bool:
        return bool(self.interval_error <= self.tolerance)

    @property
    def closed_loop_passed(self) -> bool:
        worst = max(self.closed_loop_conditions.values(), default=0.0)
        return bool(self.closed_loop_ran and max(self.closed_loop_error, worst) <= self.tolerance)

    @property
    def passed(self) -> bool:
        """The deciding checks pass — or the open loop passes even so (the strongest evidence:
        the planned inputs alone reproduce the gait)."""
        return self.open_loop_passed or (not self.stable and self.interval_passed and self.closed_loop_passed)

    def failures(self) -> list:
        """One sentence per deciding check that fails (empty when :attr:`passed`)."""
        if self.stable or self.passed:
            return []
        out = []
        if not self.interval_passed:
            out.append(f"the interval check misses by {self.interval_error:.3g} ({self.interval_state}; "
                       f"tolerance {self.tolerance:g}): the transcription is too coarse")
        if not self.closed_loop_ran:
            out.append("the closed-loop re-simulation stopped early")
        elif not self.closed_loop_passed:
            worst = max([self.closed_loop_error, *self.closed_loop_conditions.values()])
            out.append(f"the closed loop (the plan's TVLQR) misses by {worst:.3g} "
                       f"(tolerance {self.tolerance:g})")
        return out

    def to_dict(self) -> dict:
        finite = lambda v: float(v) if math.isfinite(v) else None  # noqa: E731
        return {"decided_by": self.decided_by, "passed": self.passed, "tolerance": self.tolerance,
                "interval": {"error": finite(self.interval_error), "state": self.interval_state,
                             "passed": self.interval_passed},
                "closed_loop": {"error": finite(self.closed_loop_error), "state": self.closed_loop_state,
                                "ran": self.closed_loop_ran, "passed": self.closed_loop_passed,
                                "conditions": {k: finite(v) for k, v in self.closed_loop_conditions.items()}},
                "open_loop": {"error": finite(self.open_loop_error), "passed": self.open_loop_passed},
                "stability": {"growth_rate_per_s": finite(self.growth_rate),
                              "amplification_efolds": finite(self.amplification),
                              "amplification": finite(math.exp(min(self.amplification, 700.0))),
                              "horizon_s": self.horizon, "stable": self.stable}}

    @classmethod
    def from_dict(cls, data: dict) -> GaitChecks:
        num = lambda v: math.inf if v is None else float(v)  # noqa: E731
        c, st = data["closed_loop"], data["stability"]
        return cls(interval_error=num(data["interval"]["error"]), interval_state=data["interval"]["state"],
                   closed_loop_error=num(c["error"]), closed_loop_state=c["state"], closed_loop_ran=c["ran"],
                   open_loop_error=num(data["open_loop"]["error"]),
                   open_loop_passed=data["open_loop"]["passed"],
                   growth_rate=num(st["growth_rate_per_s"]), amplification=num(st["amplification_efolds"]),
                   horizon=float(st["horizon_s"]), tolerance=float(data["tolerance"]),
                   closed_loop_conditions={k: num(v) for k, v in c["conditions"].items()})


def checks_of(solution) -> GaitChecks | None:
    """The :class:`GaitChecks` a verified ``solution`` carries (``settings["checks"]``), else None."""
    data = (getattr(solution, "settings", None) or {}).get("checks")
    return GaitChecks.from_dict(data) if data else None


# ----------------------------------------------------------------------------- the checks
def _flow(ode, t0: float, t1: float, z, u):
    """z(t1) from z(t0) = ``z`` with the input ``u`` (DOP853, rtol 1e-10); None when it fails
    or leaves the finite numbers."""
    from scipy.integrate import solve_ivp
    def rhs(t, x):
        out = np.asarray(ode(t, x, u)).ravel()
        if not np.all(np.isfinite(out)):
            raise ArithmeticError("not finite")
        return out
    try:
        sol = solve_ivp(rhs, (t0, t1), np.asarray(z, float), method="DOP853", rtol=_RTOL, atol=_ATOL)
    except ArithmeticError:
        return None
    return sol.y[:, -1] if sol.success else None


def interval_errors(ode, t, states, controls) -> np.ndarray:
    """(nz × N) |φ_{t_k→t_{k+1}}(z_k; u_k) − z_{k+1}| of every interval (inf where it failed)."""
    N = controls.shape[1]
    err = np.full((states.shape[0], N), np.inf)
    for k in range(N):
        end = _flow(ode, t[k], t[k + 1], states[:, k], controls[:, k])
        if end is not None:
            err[:, k] = np.abs(end - states[:, k + 1])
    return err


def closed_loop(ode, t, states, controls, gains, bounds) -> tuple:
    """(nodes nz × (N+1), ran): the closed loop of the module docstring from z_0; ``bounds`` =
    (lower, upper) of the inputs (the saturation)."""
    lower, upper = bounds
    N = controls.shape[1]
    out = np.full(states.shape, np.nan)
    out[:, 0] = z = states[:, 0]
    for k in range(N):
        u = np.clip(controls[:, k] - gains[k] @ (z - states[:, k]), lower, upper)
        z = _flow(ode, t[k], t[k + 1], z, u)
        if z is None:
            return out, False
        out[:, k + 1] = z
    return out, True


def growth_rate(ode, t, states, controls) -> float:
    """λ_max = max_k max Re eig ∂f/∂z (t_k, z_k, u_k) [1/s] (the last node with the last input)."""
    import casadi as ca
    tz, z, u = ca.SX.sym("t"), ca.SX.sym("z", states.shape[0]), ca.SX.sym("u", controls.shape[0])
    jac = ca.Function("fz", [tz, z, u], [ca.jacobian(ode(tz, z, u), z)])
    rates = []
    for k in range(states.shape[1]):
        J = np.asarray(jac(t[k], states[:, k], controls[:, min(k, controls.shape[1] - 1)]))
        if np.all(np.isfinite(J)):
            rates.append(float(np.linalg.eigvals(J).real.max()))
    return max(rates, default=math.nan)


def log_amplification(A) -> float:
    """ln σ_max(A_{N−1} ⋯ A_0), the product normalised at each step (no overflow); NaN when a
    Jacobian is not finite."""
    if not np.all(np.isfinite(A)):
        return math.nan
    M, log_scale = np.eye(A.shape[1]), 0.0
    for a in A:
        M = a @ M
        s = np.linalg.norm(M, 2)
        if not (np.isfinite(s) and s > 0):
            return math.inf if not np.isfinite(s) else -math.inf
        M, log_scale = M / s, log_scale + math.log(s)
    return log_scale + math.log(np.linalg.norm(M, 2))


def _worst(errors: np.ndarray, names, scale: np.ndarray) -> tuple:
    """(largest scaled error, its state) of ``errors`` (nz × K)."""
    scaled = np.max(np.where(np.isnan(errors), np.inf, errors), axis=1) / scale
    i = int(np.argmax(scaled))
    return float(scaled[i]), names[i]


def gait_checks(opened, tolerance: float, *, steps: int = 4) -> GaitChecks:
    """The checks of the module docstring of ``opened`` (a solution carrying its open-loop
    :class:`~nhgait.ocp.solution.Verification`), on its own problem's ODE; the stage Jacobians use
    the plan's ``steps`` RK4 sub-steps per interval."""
    from nhgait.dynamics.numerics.buffered_call import BufferedCall
    from nhgait.ocp.feedback import default_weights, riccati, stage_jacobians
    from nhgait.ocp.solution import condition_errors, condition_scales, scales
    problem, v = opened.problem, opened.verification
    t, states, controls = np.asarray(opened.t, float), opened.z.T.astype(float), opened.u.T.astype(float)
    ode, names, scale = problem.ode(), tuple(opened.state_names), scales(states)
    fast = BufferedCall(ode)              # the same ż, without the per-call conversions
    e_int, s_int = _worst(interval_errors(fast, t, states, controls), names, scale)
    A, B, _ = stage_jacobians(problem, states, controls, float(opened.horizon), steps)
    sim, ran = np.full(states.shape, np.nan), False
    if np.all(np.isfinite(A)) and np.all(np.isfinite(B)):
        w = default_weights(problem, states, controls)
        try:
            K, _ = riccati(A, B, w.state, w.control, w.final, weight=1.0 / problem.intervals)
        except np.linalg.LinAlgError:
            K = np.full((problem.intervals, controls.shape[0], states.shape[0]), np.nan)
        if np.all(np.isfinite(K)):
            sim, ran = closed_loop(fast, t, states, controls, K, problem.control_bound_vectors())
    e_cl, s_cl = _worst(np.abs(sim - states), names, scale)
    cond, cscale = (condition_errors(problem, sim, controls, t) if ran else {},
                    condition_scales(problem, states, controls, t))
    open_error = (max(v.max_scaled_error, v.max_scaled_condition_error) if v is not None and v.success
                  else math.inf)
    return GaitChecks(interval_error=e_int, interval_state=s_int, closed_loop_error=e_cl,
                      closed_loop_state=s_cl,
                      closed_loop_ran=ran, open_loop_error=open_error,
                      open_loop_passed=bool(v is not None and v.passed),
                      growth_rate=growth_rate(ode, t, states, controls), amplification=log_amplification(A),
                      horizon=float(opened.horizon), tolerance=float(tolerance),
                      closed_loop_conditions={k: float(e) / cscale.get(k, 1.0) for k, e in cond.items()})


def check_lines(checks: GaitChecks) -> list:
    """The summary's lines: the three checks, which decides, the gait's stability."""
    mark = lambda ok: "passed" if ok else "FAILED"  # noqa: E731
    amp = checks.amplification
    return [f"interval check     {mark(checks.interval_passed)}: each interval from its own node meets "
            "the next "
            f"to {checks.interval_error:.2e} ({checks.interval_state})",
            f"closed loop        {mark(checks.closed_loop_passed)}: the plan's TVLQR re-simulated meets the "
            "nodes "
            f"to {checks.closed_loop_error:.2e}",
            f"open loop          {mark(checks.open_loop_passed)}: error {checks.open_loop_error:.2e}",
            f"stability          largest growth rate {checks.growth_rate:.3g} /s; the open loop amplifies "
            f"errors by e^{amp:.1f} = {math.exp(min(amp, 700.0)):.2g} over T = {checks.horizon:g} s "
            f"({'stable' if checks.stable else 'unstable'} for verification)",
            f"decided by         the {checks.decided_by} check{'s' if not checks.stable else ''}"
            + ("" if checks.stable else " (an open-loop re-simulation of an unstable gait cannot verify it "
               "at any step size: reported; no refinement aims at it)")]


def solution_check_lines(solution) -> list:
    """:func:`check_lines` of the checks ``solution`` carries (none: [])."""
    checks = checks_of(solution)
    return [] if checks is None else check_lines(checks)


def open_loop_label(solution) -> str:
    """The summary's label of the open-loop line: "verification", or for a gait whose interval and
    closed-loop checks decide, the open loop named as reported."""
    checks = checks_of(solution)
    return "verification       " if checks is None or checks.stable else "open loop, reported "
