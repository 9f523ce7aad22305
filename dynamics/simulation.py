"""Forward simulation of any formulation: :func:`simulate` → :class:`Trajectory`.

What is integrated
------------------
The formulation's own state x (``model.state_names``: reduced z = (q, P, P̃), Lagrangian
(q, q̇), Hamiltonian (q, p = M q̇)), extended by the work W = ∫ τ·q̇ dt as a quadrature state,
so the energy balance E(t) − E(0) − W(t) is an accuracy check of the run.

* Reduced ODE: ż = f(t, z, u) with any scipy method (``method``); no multipliers.
* DAE forms, ``dae="index1"``: λ is solved from the differentiated constraint (the
  acceleration-level equation d/dt(ω q̇) = 0, resp. d/dt(ω ∂H/∂p) = 0) and the resulting ODE is
  integrated with scipy; λ(t) is reported from the same solve.
* DAE forms, ``dae="idas"``: CasADi IDAS (variable-order BDF) on the semi-explicit index-1 DAE
  ẋ = f(t, x, λ, u), 0 = g₁(t, x, λ, u) with λ an algebraic variable; λ(t) is IDAS's own.
  The controller must then be a CasADi expression (``controller.casadi``).

Both DAE routes integrate the *index-reduced* system: the velocity constraint ω(q)q̇ = 0 itself
is only an invariant and drifts at the level of the integration error. Stabilisation is off by
default and recorded in ``Trajectory.settings`` when on:

* ``"baumgarte"``, ``baumgarte=(α, β)``: the algebraic equation becomes
  ġ + 2α g + β² ∫g dt = 0 with g = ω q̇ (the ∫g states are appended when β ≠ 0);
* ``"projection"`` (scipy only): after every accepted step the velocity part of the state is
  projected onto {g = 0} in the kinetic-energy metric (minimum change of kinetic energy) and
  the integrator restarts from the projected state.

Controllers (see :mod:`.controllers`) give u = controller(t, q, q̇). A controller with
``breakpoints`` (e.g. :class:`~.controllers.OpenLoop`) is integrated interval by interval; on
[a, b) it is evaluated at t clamped to [a, b), so switches are exact. Bad input raises
:class:`ModelError` listing every problem; integrator failure returns a Trajectory with
``success=False`` and the points reached so far. Angles are never wrapped.
"""
from __future__ import annotations

import csv
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

from .errors import ModelError
from .states import to_state

SCIPY_METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau, "BDF": BDF,
                 "LSODA": LSODA}
IMPLICIT_METHODS = ("Radau", "BDF", "LSODA")
DAE_FORMS = ("index1", "idas")
STABILIZATIONS = (None, "baumgarte", "projection")
CSV_COLUMNS = ("q", "qdot", "state", "all")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulated trajectory sampled at N times.

    Attributes
    ----------
    t : (N,) times.
    q, qdot : (N, n) coordinates and velocities in ``coordinates`` order (angles unwrapped).
    state : (N, dim) the formulation's own state (``state_names``).
    u : (N, m) inputs applied (at a switch time: the left limit).
    lam : (N, k) Lagrange multipliers, or None for the reduced ODE.
    constraint_residual : (N, k) ω(q) q̇.
    energy : (N,) E (Lagrangian energy, H or h).
    work : (N,) ∫ τ·q̇ dt, integrated as a quadrature state.
    energy_balance : (N,) E − E(0) − work.
    nfev, njev, n_steps : right-hand-side / Jacobian evaluations and accepted steps.
    wall_time_s : wall time of the integration and evaluation of the outputs.
    success, status, message : 0 = reached the end, −1 = integrator failure (points so far kept).
    formulation, method : "reduced" | "lagrange" | "hamilton"; scipy method name or "IDAS".
    coordinates, state_names, input_names : names of the columns.
    settings : dict of every option the run used (tolerances, DAE form, stabilisation, …).
    """

    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    state: np.ndarray
    u: np.ndarray
    lam: np.ndarray | None
    constraint_residual: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    energy_balance: np.ndarray
    nfev: int
    njev: int
    n_steps: int
    wall_time_s: float
    success: bool
    status: int
    message: str
    formulation: str
    method: str
    coordinates: tuple
    state_names: tuple
    input_names: tuple
    settings: dict = field(default_factory=dict)

    def to_csv(self, path, columns: str = "q") -> None:
        """Write column ``t`` and then, per ``columns``:

        * ``"q"``: one column per coordinate, named as in the system (``x``, ``y``, ``theta`` …);
        * ``"qdot"``: q then ``<name>_dot`` velocities;
        * ``"state"``: the formulation's state (``state_names``);
        * ``"all"``: q, velocities, inputs, multipliers (``lambda1`` …), ``energy``, ``work``,
          ``energy_balance``.
        """
        if columns not in CSV_COLUMNS:
            raise ModelError([f"unknown columns {columns!r} (choose from {', '.join(CSV_COLUMNS)})"],
                             title="invalid request")
        names, blocks = ["t"], [self.t[:, None]]
        if columns == "state":
            names += list(self.state_names)
            blocks.append(self.state)
        else:
            names += list(self.coordinates)
            blocks.append(self.q)
        if columns in ("qdot", "all"):
            names += [f"{c}_dot" for c in self.coordinates]
            blocks.append(self.qdot)
        if columns == "all":
            names += list(self.input_names)
            blocks.append(self.u)
            if self.lam is not None:
                names += [f"lambda{i + 1}" for i in range(self.lam.shape[1])]
                blocks.append(self.lam)
            names += ["energy", "work", "energy_balance"]
            blocks += [self.energy[:, None], self.work[:, None], self.energy_balance[:, None]]
        table = np.hstack(blocks)
        with open(path, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(names)
            writer.writerows([[repr(float(v)) for v in row] for row in table])


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------
def _check_request(model, t_span, t_eval, controller, method, dae, stabilization, baumgarte,
                   rtol, atol, max_steps=1):
    """Every problem with the request, as a list of sentences."""
    system = model.system
    problems = []
    try:
        t0, tf = (float(v) for v in t_span)
        if not (np.isfinite(t0) and np.isfinite(tf) and tf > t0):
            problems.append(f"t_span must be increasing and finite, got ({t0:g}, {tf:g})")
    except (TypeError, ValueError):
        problems.append(f"t_span must be a pair (t0, tf), got {t_span!r}")
        t0 = tf = None
    if method not in SCIPY_METHODS:
        problems.append(f"unknown method {method!r} (choose from {', '.join(SCIPY_METHODS)})")
    if dae not in DAE_FORMS:
        problems.append(f"unknown dae form {dae!r} (choose from {', '.join(DAE_FORMS)})")
    if stabilization not in STABILIZATIONS:
        problems.append(f"unknown stabilization {stabilization!r} (None, 'baumgarte' or 'projection')")
    if model.formulation == "reduced":
        if dae == "idas":
            problems.append("dae='idas' applies to the DAE forms (lagrange, hamilton); the reduced "
                            "form is an ODE")
        if stabilization is not None:
            problems.append("stabilization applies to the DAE forms; the reduced ODE satisfies the "
                            "constraints by construction")
    if dae == "idas" and stabilization == "projection":
        problems.append("stabilization='projection' needs dae='index1' (it restarts a scipy solver)")
    if stabilization == "baumgarte":
        try:
            alpha, beta = (float(v) for v in baumgarte)
            if not (alpha >= 0 and beta >= 0 and np.isfinite(alpha + beta)):
                problems.append(f"baumgarte = (alpha, beta) must be finite and ≥ 0, got {baumgarte!r}")
        except (TypeError, ValueError):
            problems.append(f"baumgarte must be a pair (alpha, beta), got {baumgarte!r}")
    if not (isinstance(max_steps, (int, np.integer)) and max_steps > 0):
        problems.append(f"max_steps must be a positive integer, got {max_steps!r}")
    if not (rtol > 0 and atol > 0):
        problems.append(f"rtol and atol must be positive, got rtol={rtol!r}, atol={atol!r}")
    if t_eval is not None and t0 is not None:
        te = np.asarray(t_eval, dtype=float)
        span = max(abs(t0), abs(tf), 1.0) * 1e-12
        if te.ndim != 1 or te.size == 0:
            problems.append("t_eval must be a non-empty 1-D array")
        elif not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
            problems.append("t_eval must be finite and strictly increasing")
        elif te[0] < t0 - span or te[-1] > tf + span:
            problems.append(f"t_eval must lie in t_span [{t0:g}, {tf:g}], got [{te[0]:g}, {te[-1]:g}]")
    if dae == "idas" and t_eval is None:
        problems.append("dae='idas' needs t_eval (IDAS reports on a given grid)")
    if controller is not None:
        if not callable(controller):
            problems.append("controller must be callable as controller(t, q, qdot) -> u")
        coords = getattr(controller, "system_coordinates", None)
        if coords is not None and tuple(coords) != tuple(system.coordinates):
            problems.append(f"controller indexes q as {tuple(coords)}, the system's coordinates "
                            f"are {tuple(system.coordinates)}")
        names = getattr(controller, "inputs", None)
        if names is not None and tuple(names) != tuple(system.inputs):
            problems.append(f"controller outputs {tuple(names)}, the system's inputs are "
                            f"{tuple(system.inputs)}")
        domain = getattr(controller, "domain", None)
        if domain is not None and t0 is not None and (t0 < domain[0] or tf > domain[1]):
            problems.append(f"t_span [{t0:g}, {tf:g}] exceeds the controller's domain "
                            f"[{domain[0]:g}, {domain[1]:g}]")
        if dae == "idas" and not hasattr(controller, "casadi"):
            problems.append("dae='idas' needs a controller with a casadi(t, q, qdot) method "
                            "(IDAS evaluates u as a CasADi expression of the state)")
    return problems


def _segments(t0, tf, controller):
    """Integration intervals [(a, b)] split at the controller's breakpoints inside (t0, tf)."""
    cuts = [t0, tf]
    if controller is not None and getattr(controller, "breakpoints", None) is not None:
        bp = np.asarray(controller.breakpoints, dtype=float).ravel()
        cuts = [t0] + sorted(float(b) for b in bp if t0 < b < tf) + [tf]
    return list(zip(cuts[:-1], cuts[1:]))


# --------------------------------------------------------------------------------------------
# the closed-loop system as CasADi functions
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _ClosedLoop:
    """CasADi functions of the extended state y = (x, W, ∫g) for one run.

    ``rhs(t, t_c, y, u, params) → ẏ``, ``jac`` its ∂/∂y, ``outputs(t, t_c, y, u, params) →
    (q, q̇, λ, g, E, u)``, ``project(y, params) → y`` and, for IDAS, ``dae`` (a dict for
    ``casadi.integrator``) with parameters (params, t_hi). ``u`` is an explicit argument only
    for a numeric controller (``symbolic_u`` False).
    """

    rhs: ca.Function
    jac: ca.Function
    outputs: ca.Function
    project: ca.Function | None
    dae: dict | None
    qdot: ca.Function
    symbolic_u: bool
    n_q: int
    n_x: int
    n_y: int


def _closed_loop(model, controller, stabilization, baumgarte, need_dae) -> _ClosedLoop:
    num = model.numeric
    system = model.system
    n, nx, m = system.n, len(model.state_names), len(system.inputs)
    reduced = model.formulation == "reduced"
    k = 0 if reduced else num.n_multipliers
    alpha, beta = (float(v) for v in baumgarte) if stabilization == "baumgarte" else (0.0, 0.0)
    n_int = k if (stabilization == "baumgarte" and beta != 0.0) else 0
    t, t_c, t_hi = ca.SX.sym("t"), ca.SX.sym("t_c"), ca.SX.sym("t_hi")
    params = ca.SX.sym("params", len(num.param_names))
    x, work, g_int = ca.SX.sym("x", nx), ca.SX.sym("work"), ca.SX.sym("g_int", n_int)
    y = ca.vertcat(x, work, g_int)
    q = x[:n]
    qdot = num["qdot"](x, params)

    symbolic_u = controller is not None and hasattr(controller, "casadi")
    u_args = []
    if controller is None:
        u = ca.SX.zeros(m)
    elif symbolic_u:
        u = ca.vertcat(controller.casadi(t_c, q, qdot))
        if u.shape != (m, 1):
            raise ModelError([f"controller.casadi returned shape {u.shape}, expected ({m}, 1)"],
                             title="invalid controller")
    else:
        u = ca.SX.sym("u", m)
        u_args = [u]

    if reduced:
        xdot = num["rhs"](t, x, u, params)
        lam = ca.SX(0, 1)
        g = num["constraint"](q, qdot, params)
    else:
        g = num["constraint"](x, params)
        if stabilization == "baumgarte":
            lam_sym = ca.SX.sym("lam", k)
            res = num["dae_g"](t, x, lam_sym, u, params) + 2 * alpha * g
            if n_int:
                res = res + beta ** 2 * g_int
            S = ca.jacobian(res, lam_sym)
            lam = -ca.solve(S, ca.substitute(res, lam_sym, ca.SX.zeros(k)))
            xdot = num["dae_f"](t, x, lam, u, params)
        else:
            xdot, lam = num["ode"](t, x, u, params)
    power = num["power"](t, x, u, params)
    energy = num["energy"](x, params)
    ydot = ca.vertcat(xdot, power, g if n_int else ca.SX(0, 1))
    args, names = [t, t_c, y] + u_args + [params], ["t", "t_c", "y"] + ["u"] * bool(u_args) + ["params"]
    rhs = ca.Function("closed_loop", args, [ca.densify(ydot)], names, ["ydot"])
    jac = ca.Function("closed_loop_jac", args, [ca.densify(ca.jacobian(ydot, y))], names,
                      ["dydot_dy"])
    outputs = ca.Function("outputs", args, [q, qdot, lam, g, energy, u], names,
                          ["q", "qdot", "lam", "g", "energy", "u_applied"])

    project = None
    if stabilization == "projection":
        v = x[n:]
        Jv = ca.jacobian(g, v)                        # g is linear in v (q̇ or p)
        W = ca.hessian(energy, v)[0]                  # kinetic metric in v (M or M⁻¹)
        WinvJt = ca.solve(W, Jv.T)
        dv = -ca.mtimes(WinvJt, ca.solve(ca.mtimes(Jv, WinvJt), g))
        project = ca.Function("project", [y, params], [ca.densify(ca.vertcat(q, v + dv, work, g_int))],
                              ["y", "params"], ["y_projected"])

    dae = None
    if need_dae:
        z = ca.SX.sym("lam", k)
        u_d = ca.substitute(u, t_c, ca.fmin(t, t_hi)) if symbolic_u else u
        res = num["dae_g"](t, x, z, u_d, params)
        if stabilization == "baumgarte":
            res = res + 2 * alpha * g + (beta ** 2 * g_int if n_int else 0)
        ode = ca.vertcat(num["dae_f"](t, x, z, u_d, params), num["power"](t, x, u_d, params),
                         g if n_int else ca.SX(0, 1))
        dae = {"t": t, "x": y, "z": z, "p": ca.vertcat(params, t_hi), "ode": ode, "alg": res}
    return _ClosedLoop(rhs=rhs, jac=jac, outputs=outputs, project=project, dae=dae,
                       qdot=ca.Function("qdot", [y, params], [ca.densify(qdot)]), symbolic_u=symbolic_u,
                       n_q=n, n_x=nx, n_y=int(y.shape[0]))


# --------------------------------------------------------------------------------------------
# integrators
# --------------------------------------------------------------------------------------------
class _Fast:
    """Evaluate a CasADi Function on dense numpy vectors through a FunctionBuffer (no copies of
    the call machinery: ~0.5 µs instead of ~30 µs per call). Outputs are flat copies."""

    def __init__(self, function: ca.Function):
        self._buffer, self._eval = function.buffer()
        self._args = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        self._res = [np.zeros(function.nnz_out(i)) for i in range(function.n_out())]
        self._shapes = [function.size_out(i) for i in range(function.n_out())]
        for i, a in enumerate(self._args):
            self._buffer.set_arg(i, memoryview(a))
        for i, r in enumerate(self._res):
            self._buffer.set_res(i, memoryview(r))

    def __call__(self, *args) -> np.ndarray:
        for dst, a in zip(self._args, args):
            dst[:] = a
        self._eval()
        rows, cols = self._shapes[0]
        return self._res[0].reshape(cols, rows).T.copy() if cols > 1 else self._res[0].copy()


@dataclass
class _Run:
    """What an integrator produced: outputs at times t (with the controller time t_c)."""

    t: list
    t_c: list
    y: list
    lam: list | None = None
    nfev: int = 0
    njev: int = 0
    n_steps: int = 0
    status: int = 0
    message: str = "The solver successfully reached the end of the integration interval."


def _next_step(solver):
    """The step the solver proposes next (RK/Radau/BDF keep it as ``h_abs``), else the last."""
    h = getattr(solver, "h_abs", None)
    return float(h) if h is not None and np.isfinite(h) and h > 0 else solver.step_size


def _left_of(b):
    return float(np.nextafter(b, -np.inf))


def _controller_input(controller, loop, t_c, y, pv, qdot_fn=None):
    """u at controller time t_c for a numeric controller, (m,)."""
    qdot = qdot_fn(y, pv) if qdot_fn is not None else np.asarray(loop.qdot(y, pv)).ravel()
    return np.asarray(controller(t_c, y[:loop.n_q], qdot), dtype=float).ravel()


def _integrate_scipy(loop, controller, segments, y0, pv, t_eval, method, rtol, atol, max_step,
                     max_steps):
    cls = SCIPY_METHODS[method]
    run = _Run(t=[], t_c=[], y=[])
    te = None if t_eval is None else np.asarray(t_eval, dtype=float)
    t0 = segments[0][0]
    if te is None or abs(te[0] - t0) <= 1e-12 * max(1.0, abs(t0)):
        run.t.append(t0), run.t_c.append(t0), run.y.append(np.array(y0))
    y = np.array(y0, dtype=float)
    last_h = None
    rhs, jac_fn = _Fast(loop.rhs), _Fast(loop.jac)
    project = None if loop.project is None else _Fast(loop.project)
    qdot_fn = _Fast(loop.qdot)
    for a, b in segments:
        t_hi = _left_of(b)

        if loop.symbolic_u or controller is None:
            def fun(t, yy, t_hi=t_hi):
                return rhs(t, min(t, t_hi), yy, pv)

            def jac(t, yy, t_hi=t_hi):
                return jac_fn(t, min(t, t_hi), yy, pv)
        else:
            def fun(t, yy, t_hi=t_hi):
                tc = min(t, t_hi)
                return rhs(t, tc, yy, _controller_input(controller, loop, tc, yy, pv, qdot_fn), pv)
            jac = None

        def make(t_start, y_start, h):
            opts = dict(rtol=rtol, atol=atol, max_step=max_step)
            if h is not None:
                opts["first_step"] = min(h, b - t_start)
            if method in IMPLICIT_METHODS and jac is not None:
                opts["jac"] = jac
            return cls(fun, t_start, y_start, b, **opts)

        solver = make(a, y, last_h)
        while solver.status == "running":
            t_old = solver.t
            message = solver.step()
            if solver.status == "failed" or not np.all(np.isfinite(solver.y)):
                run.nfev += solver.nfev
                run.njev += getattr(solver, "njev", 0)
                run.status = -1
                run.message = (f"integration failed at t = {solver.t:.9g}: "
                               + (message or "non-finite state"))
                return run
            run.n_steps += 1
            if run.n_steps > max_steps:
                run.nfev += solver.nfev
                run.status = -1
                run.message = f"integration failed at t = {solver.t:.9g}: max_steps = {max_steps} reached"
                return run
            t_new, y_new = solver.t, solver.y.copy()
            if project is not None:
                y_new = project(y_new, pv)
            if te is None:
                run.t.append(t_new), run.t_c.append(min(t_new, t_hi)), run.y.append(y_new)
            else:
                inside = te[(te > t_old) & (te <= t_new + 1e-12 * max(1.0, abs(t_new)))]
                if inside.size:
                    dense = solver.dense_output()
                    for tt in inside:
                        yy = y_new if tt >= t_new else dense(tt)
                        if project is not None and tt < t_new:
                            yy = project(yy, pv)
                        run.t.append(float(tt)), run.t_c.append(min(float(tt), t_hi)), run.y.append(yy)
            if loop.project is not None and solver.status == "running":
                run.nfev += solver.nfev
                run.njev += getattr(solver, "njev", 0)
                last_h = _next_step(solver)
                solver = make(t_new, y_new, last_h)
        run.nfev += solver.nfev
        run.njev += getattr(solver, "njev", 0)
        last_h = _next_step(solver)
        y = np.asarray(solver.y if loop.project is None else y_new, dtype=float)
    return run


def _integrate_idas(loop, segments, y0, lam0, pv, t_eval, rtol, atol, max_steps):
    te = np.asarray(t_eval, dtype=float)
    run = _Run(t=[], t_c=[], y=[], lam=[])
    t0 = segments[0][0]
    if abs(te[0] - t0) <= 1e-12 * max(1.0, abs(t0)):
        run.t.append(t0), run.t_c.append(t0), run.y.append(np.array(y0)), run.lam.append(lam0)
    y, lam = np.array(y0, dtype=float), np.array(lam0, dtype=float)
    opts = {"abstol": atol, "reltol": rtol, "max_num_steps": int(max_steps), "calc_ic": True, "suppress_algebraic": True,
            "print_stats": False}
    for j, (a, b) in enumerate(segments):
        tol = 1e-12 * max(1.0, abs(b))
        record = [float(tt) for tt in te if a < tt <= b + tol]
        grid = record[:-1] + [b] if record and abs(record[-1] - b) <= tol else record + [b]
        F = ca.integrator(f"idas_segment_{j}", "idas", loop.dae, a, grid, opts)
        try:
            out = F(x0=y, z0=lam, p=np.r_[pv, _left_of(b)])
        except RuntimeError as err:
            run.status = -1
            run.message = f"IDAS failed on [{a:.9g}, {b:.9g}]: {str(err).splitlines()[-1]}"
            return run
        finally:
            stats = F.stats()
            run.nfev += int(stats.get("nfevals", 0))
            run.njev += int(stats.get("n_call_jacF", 0))
            run.n_steps += int(stats.get("nsteps", 0))
        xf, zf = np.asarray(out["xf"]), np.asarray(out["zf"]).reshape(len(lam), -1)
        for i, tt in enumerate(record):
            run.t.append(tt), run.t_c.append(min(tt, _left_of(b))), run.y.append(xf[:, i].copy())
            run.lam.append(zf[:, i].copy())
        y, lam = xf[:, -1].copy(), zf[:, -1].copy()
    return run


# --------------------------------------------------------------------------------------------
# the driver
# --------------------------------------------------------------------------------------------
def simulate(model, t_span, q0, qdot0, *, controller=None, params=None, method: str = "DOP853",
             rtol: float = 1e-8, atol: float = 1e-10, t_eval=None, dae: str = "index1",
             stabilization: str | None = None, baumgarte=(1.0, 0.0),
             max_step: float = np.inf, max_steps: int = 1_000_000) -> Trajectory:
    """Simulate a derived formulation from a consistent physical state (q0, q̇0).

    Parameters
    ----------
    model : ReducedODE, LagrangianDAE or HamiltonianDAE
        From :func:`~nhgait.dynamics.derivation.derive`.
    t_span : (t0, tf) with tf > t0.
    q0, qdot0 : (n,) initial coordinates and velocities; q̇0 must satisfy ω(q0)q̇0 = 0 (it is
        mapped to the formulation's state by :func:`~nhgait.dynamics.states.to_state`, which
        raises for an inconsistent or singular state).
    controller : callable (t, q, q̇) → u (m,), optional
        See :mod:`.controllers`. None applies u = 0.
    params : dict or (n_params,) array, optional
        Parameter values overriding the system's defaults.
    method : scipy method ("DOP853", "RK45", "RK23", "Radau", "BDF", "LSODA") for the ODE and
        the index-1 route; ignored with ``dae="idas"`` (recorded as "IDAS").
    rtol, atol : integrator tolerances (IDAS: reltol, abstol).
    t_eval : (N,) output times in t_span, optional; None reports every accepted step (scipy).
        Required with ``dae="idas"``.
    dae : {"index1", "idas"} — how a DAE form is integrated (see the module docstring).
    stabilization : {None, "baumgarte", "projection"} — constraint stabilisation of the DAE forms.
    baumgarte : (alpha, beta) — ġ + 2αg + β²∫g = 0 when ``stabilization="baumgarte"``.
    max_step : largest step of the scipy solvers.
    max_steps : cap on accepted steps (scipy: in total; IDAS: per output interval); reaching it
        is an integrator failure.

    Returns
    -------
    Trajectory
    """
    problems = _check_request(model, t_span, t_eval, controller, method, dae, stabilization,
                              baumgarte, rtol, atol, max_steps)
    if problems:
        raise ModelError(problems, title="invalid simulation request")
    system, num = model.system, model.numeric
    pv = num.params(params)
    t0, tf = float(t_span[0]), float(t_span[1])
    x0 = to_state(model, q0, qdot0, params)
    segments = _segments(t0, tf, controller)
    if controller is not None:
        u0 = np.asarray(controller(t0, np.asarray(q0, float), np.asarray(qdot0, float)), float).ravel()
        if u0.shape != (len(system.inputs),):
            raise ModelError([f"controller returned {u0.size} inputs, the system has "
                              f"{len(system.inputs)} ({', '.join(system.inputs)})"],
                             title="invalid simulation request")

    start = time.perf_counter()
    loop = _closed_loop(model, controller, stabilization, baumgarte, need_dae=(dae == "idas"))
    y0 = np.r_[x0, 0.0, np.zeros(loop.n_y - loop.n_x - 1)]
    if dae == "idas":
        lam0 = _evaluate(loop, controller, [t0], [t0], [y0], pv)["lam"][0]
        run = _integrate_idas(loop, segments, y0, lam0, pv, t_eval, rtol, atol, max_steps)
        method_name = "IDAS"
    else:
        run = _integrate_scipy(loop, controller, segments, y0, pv, t_eval, method, rtol, atol,
                               max_step, max_steps)
        method_name = method
    out = _evaluate(loop, controller, run.t, run.t_c, run.y, pv)
    wall = time.perf_counter() - start

    Y = np.array(run.y).reshape(len(run.y), loop.n_y)
    lam = None
    if model.formulation != "reduced":
        lam = np.array(run.lam).reshape(len(run.t), -1) if run.lam is not None else out["lam"]
    work = Y[:, loop.n_x]
    energy = out["energy"].ravel()
    settings = {"method": method_name, "dae": dae if model.formulation != "reduced" else None,
                "rtol": rtol, "atol": atol, "stabilization": stabilization,
                "baumgarte": tuple(float(v) for v in baumgarte) if stabilization == "baumgarte" else None,
                "max_step": max_step, "max_steps": max_steps, "t_span": (t0, tf), "segments": len(segments),
                "params": dict(zip(num.param_names, pv.tolist())),
                "controller": None if controller is None else type(controller).__name__}
    arrays = dict(t=np.array(run.t, dtype=float), q=out["q"], qdot=out["qdot"], state=Y[:, :loop.n_x],
                  u=out["u"], lam=lam, constraint_residual=out["g"], energy=energy, work=work,
                  energy_balance=energy - energy[0] - work)
    for a in arrays.values():
        if a is not None:
            a.setflags(write=False)
    return Trajectory(**arrays, nfev=run.nfev, njev=run.njev, n_steps=run.n_steps,
                      wall_time_s=wall, success=run.status == 0, status=run.status,
                      message=run.message, formulation=model.formulation, method=method_name,
                      coordinates=tuple(system.coordinates), state_names=tuple(model.state_names),
                      input_names=tuple(system.inputs), settings=settings)


def _evaluate(loop, controller, t, t_c, y, pv) -> dict:
    """(q, q̇, λ, g, E, u) at the output points, each (N, ·)."""
    N = len(t)
    names = ("q", "qdot", "lam", "g", "energy", "u")
    if N == 0:
        return {k: np.zeros((0, 0)) for k in names}
    T, Tc = np.array(t, float)[None, :], np.array(t_c, float)[None, :]
    Y = np.array(y, dtype=float).T
    P = np.repeat(pv[:, None], N, axis=1)
    if loop.symbolic_u or controller is None:
        res = loop.outputs.map(N)(T, Tc, Y, P)
    else:
        U = np.array([_controller_input(controller, loop, tc, Y[:, i], pv)
                      for i, tc in enumerate(t_c)]).T
        res = loop.outputs.map(N)(T, Tc, Y, U, P)
    return {k: np.asarray(v).T.reshape(N, -1) for k, v in zip(names, res)}
