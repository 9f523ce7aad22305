"""The outcome of one solve: data, never an exception.

A :class:`Solution` holds Ipopt's verdict (``success``, ``status``, ``message``), counters and
timings, and the trajectory on the grid: ``t`` (N+1,), ``states`` (nz × (N+1)) at the nodes,
``controls`` (nu × N), piecewise constant on [t_k, t_{k+1}). :meth:`Solution.verify`
re-simulates the optimal controls with an integrator independent of the transcription
(scipy ``solve_ivp``, DOP853, restarted at every control switch) and returns a
:class:`Verification` with the largest state error over the nodes;
:meth:`Solution.verified` returns a copy carrying it (shown in :meth:`to_json`).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["Solution", "Verification", "Integrator", "simulate_piecewise_constant", "condition_errors"]


@dataclass(frozen=True)
class Verification:
    """Re-simulation of the optimal controls.

    Attributes
    ----------
    max_error : float
        max over nodes k and states i of |z_i^sim(t_k) − z_i(t_k)|.
    condition_errors : dict "initial.<name>" / "final.<name>" / "periodic.<name>" → how far the
        re-simulated trajectory is from meeting that condition of the problem (0 when met).
    state_errors : dict name → max over nodes of the error of that state.
    states : ndarray (nz × (N+1)), the re-simulated node states.
    method, rtol, atol : the integrator settings.
    success : bool, whether every integration interval succeeded.
    """

    max_error: float
    state_errors: dict
    states: np.ndarray = field(repr=False)
    method: str = "DOP853"
    rtol: float = 1e-10
    atol: float = 1e-12
    success: bool = True
    time_s: float = 0.0
    condition_errors: dict = field(default_factory=dict)
    tolerance: float = 1e-6

    @property
    def max_condition_error(self) -> float:
        """Largest violation of a boundary or periodicity condition by the re-simulation."""
        return max(self.condition_errors.values(), default=0.0)

    @property
    def passed(self) -> bool:
        """The re-simulation ran through and meets the solution's nodes and every condition to
        ``tolerance`` (absolute, in the units of each quantity)."""
        return bool(self.success and self.max_error <= self.tolerance
                    and self.max_condition_error <= self.tolerance)

    def failures(self) -> list:
        """One sentence per miss (empty when :attr:`passed`), worst first."""
        out = [] if self.success else ["the re-simulation stopped early (the integrator failed)"]
        if self.max_error > self.tolerance:
            worst = max(self.state_errors, key=self.state_errors.get)
            out.append(f"the re-simulated states leave the planned ones by up to {self.max_error:.3g} "
                       f"({worst}; tolerance {self.tolerance:g})")
        for name, err in sorted(self.condition_errors.items(), key=lambda kv: -kv[1]):
            if err > self.tolerance:
                out.append(f"{name} missed by {err:.3g} (tolerance {self.tolerance:g})")
        return out


@dataclass(frozen=True)
class Integrator:
    """The settings of scipy's ``solve_ivp`` for a re-simulation: ``method``, ``rtol``, ``atol``."""

    method: str = "DOP853"
    rtol: float = 1e-10
    atol: float = 1e-12


def simulate_piecewise_constant(model, params, t, z0, controls, integrator: Integrator = Integrator()):
    """Integrate ż = rhs(t, z, u_k, params) interval by interval with scipy ``solve_ivp``.

    Returns the states at the grid ``t`` (nz × len(t)) and whether all intervals succeeded.
    """
    from scipy.integrate import solve_ivp

    method, rtol, atol = integrator.method, integrator.rtol, integrator.atol
    rhs = model.numeric["rhs"]
    nz = len(z0)
    ts, zs, us = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", controls.shape[0])
    f = ca.Function("f", [ts, zs, us], [rhs(ts, zs, us, params)])
    jac = ca.Function("J", [ts, zs, us], [ca.jacobian(rhs(ts, zs, us, params), zs)])
    out = np.empty((nz, len(t)))
    out[:, 0] = z0
    z = np.asarray(z0, dtype=float)
    ok = True
    for k in range(len(t) - 1):
        u = controls[:, k]
        sol = solve_ivp(lambda tt, zz: np.asarray(f(tt, zz, u)).ravel(), (t[k], t[k + 1]), z,
                        method=method, rtol=rtol, atol=atol,
                        **({"jac": lambda tt, zz: np.asarray(jac(tt, zz, u))} if method in ("Radau", "BDF", "LSODA") else {}))
        ok &= bool(sol.success)
        z = sol.y[:, -1]
        out[:, k + 1] = z
    return out, ok


def condition_errors(problem, states) -> dict:
    """How far ``states`` (nz × (N+1)) are from meeting each boundary and periodicity condition
    of ``problem``: distance of y(t_0) / y(t_N) to its value or range, |y(t_N) − y(t_0)|."""
    zs = ca.SX.sym("z", problem.n_states)
    out = {}

    def value(name, col):
        f = ca.Function("y", [zs], [problem.quantity(name, zs)])
        return float(f(states[:, col]))

    for where, mapping, col in (("initial", problem.initial, 0), ("final", problem.final, -1)):
        for name in mapping:
            lo, hi = problem.bounds(mapping, name)
            y = value(name, col)
            out[f"{where}.{name}"] = float(max(lo - y, y - hi, 0.0))
    for name in problem.periodic:
        out[f"periodic.{name}"] = abs(value(name, -1) - value(name, 0))
    return out


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    return obj


@dataclass(frozen=True, eq=False)
class Solution:
    """Result of :func:`nhgait.ocp.solve` (see the module docstring for array shapes)."""

    success: bool
    status: str
    message: str
    iterations: int
    objective: float
    t: np.ndarray
    states: np.ndarray
    controls: np.ndarray
    state_names: tuple
    control_names: tuple
    horizon: float
    solve_time_s: float
    setup_time_s: float
    function_time_s: float
    solver_time_s: float
    stats: dict = field(default_factory=dict, repr=False)
    settings: dict = field(default_factory=dict)
    problem: Any = field(default=None, repr=False)
    constraint_violation: float = math.nan
    verification: Verification | None = None
    violations: dict = field(default_factory=dict)
    #: the time-varying LQR along the plan (:class:`~nhgait.ocp.feedback.Feedback`), or None
    feedback: Any = field(default=None, repr=False)
    #: Floquet multipliers of a periodic plan (:class:`~nhgait.ocp.floquet.Stability`), or None
    stability: Any = field(default=None, repr=False)

    def __repr__(self) -> str:
        from nhgait.dynamics.reprs import solution_repr
        return solution_repr(self)

    def _repr_markdown_(self) -> str:
        from nhgait.dynamics.reprs import solution_markdown
        return solution_markdown(self)

    def saturation(self, tol: float = 1e-6) -> dict:
        """Input name → fraction of the intervals where it sits at a bound of the problem."""
        if self.problem is None:
            return {}
        lo, hi = self.problem.control_bound_vectors()
        out = {}
        for i, name in enumerate(self.control_names):
            u = self.controls[i]
            at = np.zeros(u.shape, dtype=bool)
            for b in (lo[i], hi[i]):
                if np.isfinite(b):
                    at |= np.abs(u - b) <= tol * max(1.0, abs(b))
            out[name] = float(at.mean()) if u.size else 0.0
        return out

    # ---------------------------------------------------------------- access
    def state(self, name: str) -> np.ndarray:
        """Node values (N+1,) of state ``name``."""
        return self.states[self.state_names.index(name)]

    def control(self, name: str) -> np.ndarray:
        """Interval values (N,) of control ``name``."""
        return self.controls[self.control_names.index(name)]

    @property
    def verification_error(self) -> float:
        return self.verification.max_error if self.verification is not None else math.nan

    def velocities(self) -> np.ndarray:
        """Generalised velocities q̇ at the nodes (n × (N+1)) through the model's qdot(z)."""
        qdot = self.problem.model.numeric["qdot"]
        return np.column_stack([np.asarray(qdot(self.states[:, k], self.problem.params)).ravel()
                                for k in range(self.states.shape[1])])

    # ---------------------------------------------------------------- checks
    def verify(self, rtol: float = 1e-10, atol: float = 1e-12, method: str = "DOP853",
               tolerance: float = 1e-6) -> Verification:
        """Re-simulate the optimal controls from z(0) with an independent integrator; the
        verification passes when nodes and conditions are met to ``tolerance``."""
        import time
        if self.problem is None:
            raise ValueError("this solution has no problem attached; cannot re-simulate")
        t0 = time.perf_counter()
        sim, ok = simulate_piecewise_constant(self.problem.model, self.problem.params, self.t,
                                              self.states[:, 0], self.controls, Integrator(method, rtol, atol))
        err = np.abs(sim - self.states)
        return Verification(max_error=float(err.max()),
                            state_errors={n: float(e) for n, e in zip(self.state_names, err.max(axis=1))},
                            states=sim, method=method, rtol=rtol, atol=atol, success=ok,
                            time_s=time.perf_counter() - t0, condition_errors=condition_errors(self.problem, sim),
                            tolerance=float(tolerance))

    def verified(self, **kwargs) -> "Solution":
        """A copy of this solution carrying :meth:`verify`'s result. Success means verified: a
        converged solution whose verification fails has ``success`` False, status
        ``Verification_Failed`` and a message listing the misses (the solver's own status is
        kept in ``stats["solver_status"]``)."""
        v = self.verify(**kwargs)
        if not self.success or v.passed:
            return replace(self, verification=v)
        return replace(self, verification=v, success=False, status="Verification_Failed",
                       message=f"{self.status}, but the verification failed: " + "; ".join(v.failures()))

    # ---------------------------------------------------------------- output
    def to_dict(self) -> dict:
        v = self.verification
        return _jsonable({
            "success": bool(self.success), "status": self.status, "message": self.message,
            "objective": self.objective, "iterations": int(self.iterations),
            "solve_time_s": self.solve_time_s, "setup_time_s": self.setup_time_s,
            "function_time_s": self.function_time_s, "solver_time_s": self.solver_time_s,
            "constraint_violation": self.constraint_violation, "violations": self.violations,
            "verification_error": v.max_error if v is not None else None,
            "verification": None if v is None else {
                "max_error": v.max_error, "state_errors": v.state_errors, "method": v.method,
                "rtol": v.rtol, "atol": v.atol, "success": v.success, "tolerance": v.tolerance,
                "passed": v.passed, "failures": v.failures(),
                "condition_errors": v.condition_errors, "max_condition_error": v.max_condition_error},
            "settings": self.settings,
            "feedback": None if self.feedback is None else self.feedback.to_dict(),
            "stability": None if self.stability is None else self.stability.to_dict(),
            "problem": self.problem.describe() if self.problem is not None else None,
            "trajectory": self._trajectory(),
        })

    def _trajectory(self) -> dict:
        """t (N+1), q (N+1 × n) in ``coordinates`` order, q̇ (N+1 × n), u (N × m, constant on
        [t_k, t_k+1)) in ``inputs`` order, and the states and controls by name."""
        out = {"t": self.t, "horizon": self.horizon,
               "state_names": list(self.state_names), "control_names": list(self.control_names),
               "states": {n: self.states[i] for i, n in enumerate(self.state_names)},
               "controls": {n: self.controls[i] for i, n in enumerate(self.control_names)},
               "inputs": list(self.control_names), "u": self.controls.T}
        if self.problem is not None:
            coords = tuple(getattr(self.problem.model.system, "coordinates", ()))
            n = len(coords)
            out.update({"coordinates": list(coords), "q": self.states[:n].T, "qdot": self.velocities().T})
        return out

    def to_json(self, path, extra: dict | None = None) -> Path:
        """Write :meth:`to_dict` (plus ``extra`` top-level keys) to ``path`` (parents created)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = self.to_dict()
        data.update(_jsonable(dict(extra or {})))
        path.write_text(json.dumps(data, indent=1))
        return path

    def summary(self) -> str:
        v = self.verification_error
        return (f"{'success' if self.success else 'FAILED'} ({self.status}): J = {self.objective:.6g}, "
                f"{self.iterations} iterations, solve {self.solve_time_s * 1e3:.1f} ms "
                f"(functions {self.function_time_s * 1e3:.1f} ms, solver {self.solver_time_s * 1e3:.1f} ms), "
                f"setup {self.setup_time_s * 1e3:.1f} ms"
                + ("" if math.isnan(v) else f", verification error {v:.2e}"))
