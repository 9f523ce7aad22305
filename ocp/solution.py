"""The outcome of one solve: data, never an exception.

A :class:`Solution` holds Ipopt's verdict (``success``, ``status``, ``message``), counters and
timings, and the trajectory on the grid, time first as in every public result of nhgait:
``t`` (N+1,), ``z`` ((N+1) × nz) the states at the nodes, ``u`` (N × nu) the controls,
piecewise constant on [t_k, t_{k+1}), and ``q``, ``qdot`` ((N+1) × n). ``states`` (nz × (N+1))
and ``controls`` (nu × N), the former orientation, are kept for one release and warn
(:class:`DeprecationWarning`). :meth:`Solution.to_numpy` and :meth:`Solution.to_csv` give the
table of ``trajectory.csv``. :meth:`Solution.verify`
re-simulates the optimal controls with an integrator independent of the transcription
(scipy ``solve_ivp``, DOP853, restarted at every control switch) and returns a
:class:`Verification` with the largest state error over the nodes;
:meth:`Solution.verified` returns a copy carrying it (shown in :meth:`to_json`).
"""
from __future__ import annotations

import csv
import json
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

__all__ = ["Solution", "Verification", "Integrator", "simulate_piecewise_constant", "condition_errors",
           "condition_scales", "scales", "NodeArrays", "node_arrays", "Table"]


@dataclass(frozen=True)
class Verification:
    """Re-simulation of the optimal controls.

    Attributes
    ----------
    max_error : float
        max over nodes k and states i of ``|z_i^sim(t_k) − z_i(t_k)|``.
    condition_errors : dict "initial.<name>" / "final.<name>" / "periodic.<name>" → how far the
        re-simulated trajectory is from meeting that condition of the problem (0 when met).
    state_errors : dict name → max over nodes of the error of that state.
    state_scales, condition_scales : dict name → the scale s ≥ 1 each error is judged against:
        max(1, the range max_k y(t_k) − min_k y(t_k) of that state or quantity over the plan's
        nodes), so that a 1200 kg car's momentum (range ~10³) is judged relative to its range and
        a position in metres absolutely (:func:`scales`).
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
    state_scales: dict = field(default_factory=dict)
    condition_scales: dict = field(default_factory=dict)

    @property
    def max_condition_error(self) -> float:
        """Largest violation of a boundary or periodicity condition by the re-simulation (absolute)."""
        return max(self.condition_errors.values(), default=0.0)

    @property
    def scaled_state_errors(self) -> dict:
        """State name → its error divided by its scale (``state_scales``, 1 when absent)."""
        return {n: e / self.state_scales.get(n, 1.0) for n, e in self.state_errors.items()}

    @property
    def scaled_condition_errors(self) -> dict:
        return {n: e / self.condition_scales.get(n, 1.0) for n, e in self.condition_errors.items()}

    @property
    def max_scaled_error(self) -> float:
        """Largest node error relative to its state's scale (what :attr:`passed` judges)."""
        return max(self.scaled_state_errors.values(), default=self.max_error)

    @property
    def max_scaled_condition_error(self) -> float:
        return max(self.scaled_condition_errors.values(), default=0.0)

    @property
    def passed(self) -> bool:
        """The re-simulation ran through and meets the solution's nodes and every condition to
        ``tolerance`` relative to each state's or quantity's scale (``state_scales``,
        ``condition_scales``: absolute for anything whose range is below 1)."""
        return bool(self.success and self.max_scaled_error <= self.tolerance
                    and self.max_scaled_condition_error <= self.tolerance)

    def failures(self) -> list:
        """One sentence per miss (empty when :attr:`passed`), worst first; the absolute figure
        and, when the scale is not 1, the scaled one."""
        out = [] if self.success else ["the re-simulation stopped early (the integrator failed)"]
        scaled = self.scaled_state_errors
        if self.max_scaled_error > self.tolerance:
            worst = max(scaled, key=scaled.get)
            out.append("the re-simulated states leave the planned ones by up to "
                       f"{self.state_errors[worst]:.3g} "
                       f"({worst}{_relative(scaled[worst], self.state_scales.get(worst, 1.0))}; "
                       f"tolerance {self.tolerance:g})")
        for name, err in sorted(self.scaled_condition_errors.items(), key=lambda kv: -kv[1]):
            if err > self.tolerance:
                out.append(f"{name} missed by {self.condition_errors[name]:.3g}"
                           f"{_relative(err, self.condition_scales.get(name, 1.0))} (tolerance "
                           f"{self.tolerance:g})")
        return out


def _relative(scaled: float, scale: float) -> str:
    return "" if scale == 1.0 else f", {scaled:.3g} of its scale {scale:.4g}"


def scales(values: np.ndarray) -> np.ndarray:
    """max(1, max − min) of each row of ``values`` (rows: states or quantities over the nodes): the
    scale a verification error is judged against."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return np.ones(values.shape[0])
    spread = np.nanmax(values, axis=1) - np.nanmin(values, axis=1)
    return np.maximum(1.0, np.where(np.isfinite(spread), spread, 1.0))


@dataclass(frozen=True)
class Integrator:
    """The settings of scipy's ``solve_ivp`` for a re-simulation: ``method``, ``rtol``, ``atol``."""

    method: str = "DOP853"
    rtol: float = 1e-10
    atol: float = 1e-12


def simulate_piecewise_constant(model, params, t, z0, controls, integrator: Integrator = Integrator()):
    """Integrate ż = rhs(t, z, u_k, params) interval by interval with scipy ``solve_ivp``:
    ``model`` a derived model (its numeric ``rhs``), or a CasADi Function ż = f(t, z, u) with
    the parameters bound (``params`` then unused, None) — a problem's states with its integral
    states, :meth:`~nhgait.ocp.problem.OptimalControlProblem.ode`.

    Returns the states at the grid ``t`` (nz × len(t)) and whether all intervals succeeded; a
    right-hand side that is not finite ends the integration there (the later columns NaN).
    """
    from scipy.integrate import solve_ivp

    method, rtol, atol = integrator.method, integrator.rtol, integrator.atol
    nz = len(z0)
    ts, zs, us = ca.SX.sym("t"), ca.SX.sym("z", nz), ca.SX.sym("u", controls.shape[0])
    rate = model(ts, zs, us) if isinstance(model, ca.Function) else model.numeric["rhs"](ts, zs, us, params)
    f = ca.Function("f", [ts, zs, us], [rate])
    jac = ca.Function("J", [ts, zs, us], [ca.jacobian(rate, zs)])
    out = np.full((nz, len(t)), np.nan)
    out[:, 0] = z0
    z = np.asarray(z0, dtype=float)
    ok = True
    for k in range(len(t) - 1):
        u = controls[:, k]
        try:
            sol = solve_ivp(_finite(f, u), (t[k], t[k + 1]), z, method=method, rtol=rtol, atol=atol,
                            **({"jac": lambda tt, zz, u=u: np.asarray(jac(tt, zz, u))}
                               if method in ("Radau", "BDF", "LSODA")
                               else {}))
        except _NotFinite:
            return out, False
        ok &= bool(sol.success)
        z = sol.y[:, -1]
        out[:, k + 1] = z
    return out, ok


class _NotFinite(ArithmeticError):
    """The right-hand side was not finite (the model's singular set)."""


def _finite(f, u):
    """ż = f(t, z, u) for ``solve_ivp``, raising :class:`_NotFinite` on a NaN or inf: with one,
    SciPy's explicit Runge–Kutta step control computes a NaN step size and then never fails
    (every comparison with NaN is false) — a verification once ran for minutes."""
    def rhs(tt, zz):
        out = np.asarray(f(tt, zz, u)).ravel()
        if not np.all(np.isfinite(out)):
            raise _NotFinite(f"the right-hand side is not finite at t = {tt:g}")
        return out
    return rhs


class _Values:
    """Quantities of ``problem`` at the nodes of ``states`` (nz × (N+1)): a state quantity at
    every node, a quantity of the inputs at the nodes 0 … N−1 with the interval's input
    (``controls`` nu × N) and the node time (``t``)."""

    def __init__(self, problem, states, controls=None, t=None):
        self.problem, self.states, self.controls, self.t = problem, np.asarray(states, float), controls, t
        self._rows = {}

    def __call__(self, name) -> np.ndarray:
        if name not in self._rows:
            p, Z = self.problem, self.states
            zs = ca.SX.sym("z", Z.shape[0])
            if p.uses_inputs(name):
                us, ts = ca.SX.sym("u", p.n_controls), ca.SX.sym("t")
                f = ca.Function("y", [zs, us, ts], [p.quantity(name, zs, u=us, t=ts)]).map(Z.shape[1] - 1)
                row = f(Z[:, :-1], self.controls, np.asarray(self.t, float)[:-1])
            else:
                row = ca.Function("y", [zs], [p.quantity(name, zs)]).map(Z.shape[1])(Z)
            self._rows[name] = np.asarray(row, float).ravel()
        return self._rows[name]


def _conditions(problem):
    """(label, name, node or None (periodic), mapping) of every condition checked, and the path bounds."""
    from .schedule import schedule
    sched = schedule(problem)
    out = [(f"{e.label}.{n}", n, e.node, e.conditions) for e in sched.events for n in e.conditions]
    out += [(f"periodic.{n}", n, None, None) for n in problem.periodic]
    return out, sched


def condition_errors(problem, states, controls=None, t=None) -> dict:
    """How far ``states`` (nz × (N+1)) are from meeting each condition of ``problem``: the
    distance of y at an event's node (initial, waypoints, phase ends, final) to its value or
    range, |y(t_N) − y(t_0)| of a periodic one and, given ``controls`` and ``t``, the largest
    violation of each path bound over the nodes ("bounds.<name>")."""
    values, out = _Values(problem, states, controls, t), {}
    conditions, sched = _conditions(problem)
    for label, name, node, mapping in conditions:
        y = values(name)
        if node is None:
            out[label] = float(abs(y[-1] - y[0]))
        else:
            lo, hi = problem.bounds(mapping, name)
            out[label] = float(max(lo - y[node], y[node] - hi, 0.0))
    if controls is not None and t is not None:
        names = sched.path_names(problem)
        lo, hi = sched.node_ranges(problem, names)
        for i, name in enumerate(names):
            y = values(name)
            out[f"bounds.{name}"] = float(np.max(np.maximum(np.maximum(lo[i, :y.size] - y,
                                                                       y - hi[i, :y.size]), 0.0)))
    return out


def condition_scales(problem, states, controls=None, t=None) -> dict:
    """The scale (:func:`scales`) of the quantity of each condition of :func:`condition_errors`,
    over the nodes ``states`` (nz × (N+1))."""
    values = _Values(problem, states, controls, t)
    conditions, sched = _conditions(problem)
    out = {label: float(scales(values(name)[None, :])[0]) for label, name, _, _ in conditions}
    if controls is not None and t is not None:
        out.update({f"bounds.{n}": float(scales(values(n)[None, :])[0]) for n in sched.path_names(problem)})
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


@dataclass(kw_only=True, frozen=True, eq=False)
class Solution:
    """Result of :func:`nhgait.ocp.solve` (see the module docstring for array shapes)."""

    success: bool
    status: str
    message: str
    iterations: int
    objective: float
    t: np.ndarray
    #: ((N+1) × nz) the states at the nodes, time first (columns: ``state_names``)
    z: np.ndarray
    #: (N × nu) the controls, constant on [t_k, t_{k+1}), time first (columns: ``control_names``)
    u: np.ndarray
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
            u = self.u[:, i]
            at = np.zeros(u.shape, dtype=bool)
            for b in (lo[i], hi[i]):
                if np.isfinite(b):
                    at |= np.abs(u - b) <= tol * max(1.0, abs(b))
            out[name] = float(at.mean()) if u.size else 0.0
        return out

    # ---------------------------------------------------------------- access
    def state(self, name: str) -> np.ndarray:
        """Node values (N+1,) of state ``name``."""
        return self.z[:, self.state_names.index(name)]

    def control(self, name: str) -> np.ndarray:
        """Interval values (N,) of control ``name``."""
        return self.u[:, self.control_names.index(name)]

    @property
    def states(self) -> np.ndarray:
        """Deprecated: ``z.T`` (nz × (N+1)), the former orientation; use ``z`` (time first)."""
        warnings.warn("Solution.states (states × nodes) is deprecated and goes in the next release: use "
                      "Solution.z, time first ((N+1) × nz), or Solution.to_numpy()",
                      DeprecationWarning, stacklevel=2)
        return self.z.T

    @property
    def controls(self) -> np.ndarray:
        """Deprecated: ``u.T`` (nu × N), the former orientation; use ``u`` (time first)."""
        warnings.warn("Solution.controls (controls × intervals) is deprecated and goes in the next release: "
                      "use Solution.u, time first (N × nu), or Solution.to_numpy()",
                      DeprecationWarning, stacklevel=2)
        return self.u.T

    @property
    def q(self) -> np.ndarray:
        """((N+1) × n) the coordinates at the nodes, time first, in the system's order (the
        first n states)."""
        return self.z[:, :len(self.coordinates)]

    @property
    def qdot(self) -> np.ndarray:
        """((N+1) × n) the velocities q̇ at the nodes, time first (:meth:`velocities`)."""
        return self.velocities().T

    @property
    def coordinates(self) -> tuple[str, ...]:
        """The system's coordinates, the first states (empty without a problem)."""
        if self.problem is None:
            return ()
        return tuple(getattr(self.problem.model.system, "coordinates", ()))

    @property
    def verification_error(self) -> float:
        return self.verification.max_error if self.verification is not None else math.nan

    def velocities(self) -> np.ndarray:
        """Generalised velocities q̇ at the nodes (n × (N+1)) through the model's qdot(z)."""
        qdot = self.problem.model.numeric["qdot"]
        nz = len(self.problem.model.state_names)               # the model's states (integral states follow)
        return np.column_stack([np.asarray(qdot(self.z[k, :nz], self.problem.params)).ravel()
                                for k in range(self.z.shape[0])])

    # ---------------------------------------------------------------- checks
    def verify(self, rtol: float = 1e-10, atol: float = 1e-12, method: str = "DOP853",
               tolerance: float = 1e-6) -> Verification:
        """Re-simulate the optimal controls from z(0) with an independent integrator; the
        verification passes when nodes and conditions are met to ``tolerance``."""
        import time
        if self.problem is None:
            raise ValueError("this solution has no problem attached; cannot re-simulate")
        t0 = time.perf_counter()
        sim, ok = simulate_piecewise_constant(self.problem.ode(), None, self.t, self.z[0], self.u.T,
                                              Integrator(method, rtol, atol))
        err = np.abs(sim - self.z.T)
        err[np.isnan(err)] = np.inf                      # not reached (the integration stopped)
        return Verification(max_error=float(err.max()),
                            state_errors={n: float(e)
                                          for n, e in zip(self.state_names, err.max(axis=1), strict=True)},
                            states=sim, method=method, rtol=rtol, atol=atol, success=ok,
                            time_s=time.perf_counter() - t0,
                            condition_errors=condition_errors(self.problem, sim, self.u.T, self.t),
                            tolerance=float(tolerance),
                            state_scales=dict(zip(self.state_names,
                                                  map(float, scales(self.z.T)), strict=True)),
                            condition_scales=condition_scales(self.problem, self.z.T,
                                                              self.u.T, self.t))

    def verified(self, **kwargs) -> Solution:
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
                "condition_errors": v.condition_errors, "max_condition_error": v.max_condition_error,
                "state_scales": v.state_scales, "condition_scales": v.condition_scales,
                "max_scaled_error": v.max_scaled_error,
                "max_scaled_condition_error": v.max_scaled_condition_error},
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
               "states": {n: self.z[:, i] for i, n in enumerate(self.state_names)},
               "controls": {n: self.u[:, i] for i, n in enumerate(self.control_names)},
               "inputs": list(self.control_names), "u": self.u}
        if self.problem is not None:
            out.update({"coordinates": list(self.coordinates), "q": self.q, "qdot": self.qdot})
        return out

    def to_json(self, path, extra: dict | None = None) -> Path:
        """Write :meth:`to_dict` (plus ``extra`` top-level keys) to ``path`` (parents created)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        data = self.to_dict()
        data.update(_jsonable(dict(extra or {})))
        path.write_text(json.dumps(data, indent=1))
        return path

    def table(self, units=None) -> Table:
        """The gait as one time-first table, the rows of ``trajectory.csv``: columns ``t``, the
        coordinates q, their velocities ``<q>_dot``, the solution's other states (the momenta or
        velocity states it was solved in, then a task's integral states) and the controls.
        A control is constant on [t_k, t_{k+1}); row k holds that value, and the last row
        (t_N) the last interval's (its left limit at t_N). ``units`` (a scene's ``[units]``)
        and the system give each column's unit by :func:`nhgait.dynamics.units.unit_of` — the
        figures' units ("SI" where it cannot place one)."""
        from nhgait.dynamics.units import unit_of
        n = len(self.coordinates)
        names = ["t"] + list(self.state_names[:n])
        blocks = [self.t[:, None], self.z[:, :n]]
        if n:
            names += [f"{c}_dot" for c in self.coordinates]
            blocks.append(self.qdot)
        names += list(self.state_names[n:]) + list(self.control_names)
        held = np.vstack([self.u, self.u[-1:]]) if len(self.u) else np.zeros((len(self.t), 0))
        blocks += [self.z[:, n:], held]
        system = getattr(getattr(self.problem, "model", None), "system", None)
        return Table(tuple(names), tuple(unit_of(c, units, system) or "SI" for c in names),
                     np.hstack(blocks).astype(float))

    def to_numpy(self) -> np.ndarray:
        """The :meth:`table` as a float array ((N+1) × columns), time first; its column names are
        ``table().columns``."""
        return self.table().values

    def to_csv(self, path, units=None) -> Path:
        """Write the :meth:`table` to ``path`` (parents created): a header ``name [unit]`` and one
        row per node, every number written exactly (``repr``: ``np.loadtxt(path, delimiter=",",
        skiprows=1)`` gives :meth:`to_numpy` bit for bit)."""
        table = self.table(units)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(table.header())
            writer.writerows([[repr(float(v)) for v in row] for row in table.values])
        return path

    def summary(self) -> str:
        v = self.verification_error
        return (f"{'success' if self.success else 'FAILED'} ({self.status}): J = {self.objective:.6g}, "
                f"{self.iterations} iterations, solve {self.solve_time_s * 1e3:.1f} ms "
                f"(functions {self.function_time_s * 1e3:.1f} ms, solver {self.solver_time_s * 1e3:.1f} ms), "
                f"setup {self.setup_time_s * 1e3:.1f} ms"
                + ("" if math.isnan(v) else f", verification error {v:.2e}"))


class NodeArrays(NamedTuple):
    """A trajectory in the transcription's layout: ``states`` (nz × (N+1)), ``controls`` (nu × N)."""

    states: np.ndarray
    controls: np.ndarray


def node_arrays(guess) -> NodeArrays:
    """The node states and controls of an :class:`~nhgait.ocp.solver.InitialGuess` (as given) or
    of a :class:`Solution` (its time-first ``z``, ``u`` transposed), as floats."""
    if isinstance(guess, Solution):
        return NodeArrays(np.asarray(guess.z, float).T, np.asarray(guess.u, float).T)
    return NodeArrays(np.asarray(guess.states, float), np.asarray(guess.controls, float))


class Table(NamedTuple):
    """A time-first table of a gait (:meth:`Solution.table`): ``columns`` and ``units`` per
    column, ``values`` ((N+1) × columns)."""

    columns: tuple
    units: tuple
    values: np.ndarray

    def header(self) -> list:
        """``["t [s]", "x [m]", …]``."""
        return [f"{c} [{u}]" for c, u in zip(self.columns, self.units, strict=True)]
