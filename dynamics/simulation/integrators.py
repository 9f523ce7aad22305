"""The integration routes behind :func:`~.simulation.simulate`, one function per route.

Each route integrates the closed loop ẏ = f(t, t_c, y, p) of :mod:`.closed_loop` interval by
interval (``segments``: the controller's switch times) and returns a :class:`Run` — the output
points reached, counters and a status — never raising for a numerical failure:

* :func:`integrate_scipy`: scipy's step loop (RK23, RK45, DOP853, Radau, BDF, LSODA), driven one
  step at a time so that every accepted step is checked (non-finite values, the singular-set
  event, the step budget, stiffness) and projection can restart the solver;
* :func:`integrate_sundials`: CasADi's CVODES (BDF) on the ODE, or IDAS on the index-1 DAE with
  λ algebraic, reporting on the output grid;
* :func:`integrate_compiled`: the compiled Dormand–Prince integrator of :mod:`.compiled`, one C
  call per interval.

Statuses (``Run.status``): :data:`FINISHED` 0, :data:`FAILED` −1 (the method gave up: step size
underflow, solver error), :data:`MAX_STEPS` −2, :data:`NONFINITE` −3 (a non-finite right-hand
side, input or state; ``Run.t_fail`` is the time), :data:`SINGULAR` −4 (the singular-set measure
fell below its threshold; ``Run.t_fail`` is the crossing time, located to ~1e-15 relative on the
dense output of the explicit methods, to the output grid for SUNDIALS).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

FINISHED, FAILED, MAX_STEPS, NONFINITE, SINGULAR = 0, -1, -2, -3, -4
SCIPY_METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853, "Radau": Radau, "BDF": BDF,
                 "LSODA": LSODA}
IMPLICIT_METHODS = ("Radau", "BDF", "LSODA")
#: stiffness test (HNW II, §IV.2): h|λ| above this for 15 consecutive steps means the step is
#: set by stability, not accuracy. About half the stability limit on the negative real axis
#: (RK45 3.3, DOP853 6.1): the error estimators keep h|λ| there (measured on the snakeboard with
#: k_p = 10⁴: median 1.5 / 4.1 at k_d = 200), while accuracy-limited runs stay below 0.7 / 1.5.
STIFF_LIMIT = {"RK45": 1.2, "DOP853": 3.0}
#: evaluations allowed per permitted step: a backstop against a solver that never returns
_EVALS_PER_STEP = 100


@dataclass(frozen=True, eq=False)
class RunRequest:
    """One integration of a closed loop, as every route sees it (built once by ``simulate``).

    loop : the :class:`~.closed_loop.ClosedLoop`; controller : the user's controller or None;
    segments : [(a, b)] intervals between the controller's switch times; y0 : (n_y,) start;
    seg_params : the loop's parameter vector of each segment; t_eval : output times or None
    (every accepted step); rtol, atol, max_step, max_steps : the solver settings; event_tol :
    the singular-set threshold (None or 0: no event); stabilization, baumgarte : the DAE's
    constraint stabilisation.
    """

    loop: object
    controller: object
    segments: list
    y0: np.ndarray
    seg_params: list
    t_eval: object
    rtol: float
    atol: float
    max_step: float
    max_steps: int
    event_tol: float | None
    stabilization: str | None = None
    baumgarte: tuple = (1.0, 0.0)

    @property
    def python_inputs(self) -> bool:
        """The inputs come from a Python controller called at every evaluation (it has no
        CasADi form and is not piecewise given): no compiled route, no symbolic Jacobian in u."""
        return self.controller is not None and not (self.loop.symbolic_u or self.loop.segment_u)


@dataclass
class Run:
    """What a route produced: output times, controller times, segment indices and states."""

    t: list = field(default_factory=list)
    t_c: list = field(default_factory=list)
    seg: list = field(default_factory=list)
    y: list = field(default_factory=list)
    lam: list | None = None
    nfev: int = 0
    njev: int = 0
    n_steps: int = 0
    n_rejected: int = 0
    status: int = FINISHED
    message: str = "The solver successfully reached the end of the integration interval."
    t_fail: float | None = None
    bad: int | None = None                # index of a non-finite component of ẏ, if known
    y_fail: np.ndarray | None = None      # last good state before a failure, if not an output
    t_bad: float | None = None            # a time the failed step could not reach
    t_stiff: float | None = None          # first time stiffness was detected
    h_lambda: float = 0.0                 # largest h|λ| estimate (explicit methods)

    def add(self, t, t_hi, seg, y, lam=None):
        self.t.append(float(t))
        self.t_c.append(min(float(t), t_hi))
        self.seg.append(seg)
        self.y.append(np.array(y, dtype=float))
        if lam is not None:
            self.lam.append(np.array(lam, dtype=float))

    def add_block(self, t, t_hi, seg, Y):
        """:meth:`add` for N points at once: ``t`` (N,), ``Y`` (N, n_y) (copied)."""
        t = np.asarray(t, dtype=float)
        self.t.extend(t.tolist())
        self.t_c.extend(np.minimum(t, t_hi).tolist())
        self.seg.extend([seg] * t.size)
        self.y.extend(np.array(Y, dtype=float))

    def fail(self, status, t, message, bad=None):
        self.status, self.t_fail, self.message, self.bad = status, float(t), message, bad
        return self


def left_of(b: float) -> float:
    return float(np.nextafter(b, -np.inf))


class Fast:
    """Evaluate a CasADi Function on dense numpy vectors through a FunctionBuffer (~0.5 µs a
    call instead of ~30 µs). Returns a copy of the first output, flattened column-major."""

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

    def scalars(self, *args) -> tuple:
        """All outputs, each a scalar (for functions with scalar outputs only)."""
        for dst, a in zip(self._args, args):
            dst[:] = a
        self._eval()
        return tuple(float(r[0]) for r in self._res)


class Measure:
    """The singular-set measure s(y) and its rate ṡ = ∇s·ẏ (``ClosedLoop.event``)."""

    def __init__(self, event: ca.Function):
        self._fast = Fast(event)
        self._zeros = np.zeros(event.nnz_in(0))

    def __call__(self, y, p) -> float:
        return self._fast.scalars(y, self._zeros, p)[0]

    def with_rate(self, y, ydot, p) -> tuple:
        return self._fast.scalars(y, ydot, p)


class _Budget(Exception):
    """Raised inside the right-hand side when the evaluation budget is spent."""


def _first_bad(v) -> int | None:
    bad = np.flatnonzero(~np.isfinite(np.asarray(v, dtype=float)))
    return int(bad[0]) if bad.size else None


def _grid_start(te, t0):
    """Index of the first output time after t0 (t0 itself is recorded by the caller)."""
    if te is None:
        return 0
    return int(np.searchsorted(te, t0 + 1e-12 * max(1.0, abs(t0)), side="right"))


# --------------------------------------------------------------------------------------------
# scipy
# --------------------------------------------------------------------------------------------
def _stiffness(solver, method) -> float | None:
    """h|λ| estimated from the two stages with c = 1 (RK45 stage 6, DOP853 stage 12) and
    f(t+h, y₁): h‖f(y₁) − f(Y)‖ / ‖y₁ − Y‖ (Hairer & Wanner II, §IV.2)."""
    K, C = getattr(solver, "K", None), getattr(solver, "C", None)
    if method not in STIFF_LIMIT or K is None or C is None:
        return None
    i = int(np.flatnonzero(np.asarray(C) == 1.0)[-1])
    h = solver.h_previous
    Y = solver.y_old + h * (solver.A[i, :i] @ K[:i])
    den = np.linalg.norm(solver.y - Y)
    return abs(h) * np.linalg.norm(K[-1] - K[i]) / den if den > 0 else None


#: a step whose end-point measures are below WATCH·tol is also checked inside (see below)
WATCH = 1e4


def _locate(dense, event, params, t_lo, t_hi, tol):
    """Bisection for the first time in (t_lo, t_hi] where event(dense(t)) < tol."""
    lo, hi = t_lo, t_hi
    for _ in range(80):
        if hi - lo <= 4 * np.finfo(float).eps * max(abs(hi), 1.0):
            break
        mid = 0.5 * (lo + hi)
        g = event(dense(mid), params)
        if np.isfinite(g) and g >= tol:
            lo = mid
        else:
            hi = mid
    return hi, dense(hi)


def _golden(dense, event, params, lo, hi):
    """(t, s) at the minimum of s(dense(t)) on [lo, hi] (golden-section search)."""
    r = 0.6180339887498949
    a, b = hi - r * (hi - lo), lo + r * (hi - lo)
    ga, gb = event(dense(a), params), event(dense(b), params)
    for _ in range(60):
        if hi - lo <= 1e-13 * max(1.0, abs(hi)):
            break
        if not ga >= gb:
            hi, b, gb = b, a, ga
            a = hi - r * (hi - lo)
            ga = event(dense(a), params)
        else:
            lo, a, ga = a, b, gb
            b = lo + r * (hi - lo)
            gb = event(dense(b), params)
    return (a, ga) if ga < gb else (b, gb)


def _event_in_step(solver, event, params, t_old, t_new, y_new, f_new, old, tol):
    """(t, y) of the first point of the step with measure < tol, or None; and (s, ṡ) at the end.

    The measure is a squared quantity: it touches 0 and rises again where a trajectory crosses
    the set, so a step can jump over a crossing its end points do not show. Near the set (an end
    below WATCH·tol) or when s can change by more than half its value within the step
    (h|ṡ| > s/2 at an end), 7 interior points of the dense output are sampled and every local
    minimum of the samples (and one next to an end where the end rate says so) is refined by
    golden-section search (the same rule as the compiled integrator)."""
    g_new, rate_new = event.with_rate(y_new, f_new, params)
    g_old, rate_old = old
    gmin = min(g_old, g_new)
    h = abs(t_new - t_old)
    if (np.isfinite(g_new) and g_new >= tol and gmin >= WATCH * tol
            and h * max(abs(rate_old), abs(rate_new)) <= 0.5 * gmin):
        return None, (g_new, rate_new)
    dense = solver.dense_output()
    ts = t_old + (t_new - t_old) * np.arange(9) / 8.0
    gs = [g_old] + [event(dense(tt), params) for tt in ts[1:8]] + [g_new]
    for j in range(9):
        if j > 0 and not (np.isfinite(gs[j]) and gs[j] >= tol):
            return _locate(dense, event, params, ts[j - 1], ts[j], tol), (g_new, rate_new)
        if j == 0:
            dip, a, b = rate_old < 0 and gs[1] > gs[0], ts[0], ts[1]
        elif j < 8:
            dip, a, b = gs[j] <= gs[j - 1] and gs[j] <= gs[j + 1], ts[j - 1], ts[j + 1]
        else:
            dip, a, b = rate_new > 0 and gs[7] > gs[8], ts[7], ts[8]
        if dip:
            t_min, g = _golden(dense, event, params, a, b)
            if not (np.isfinite(g) and g >= tol):
                return _locate(dense, event, params, a, t_min, tol), (g_new, rate_new)
    return None, (g_new, rate_new)


def integrate_scipy(request: RunRequest, method: str, *, projection=False, stop_on_stiff=False) -> Run:
    """Integrate with a scipy OdeSolver, one step at a time (see the module docstring);
    ``projection``: project the velocities onto the constraints after every step;
    ``stop_on_stiff``: end (message "stiff") when stiffness is detected."""
    loop, controller, segments, y0, seg_params, t_eval = (request.loop, request.controller, request.segments,
                                                          request.y0, request.seg_params, request.t_eval)
    rtol, atol, max_step, max_steps = request.rtol, request.atol, request.max_step, request.max_steps
    event_tol = request.event_tol
    cls = SCIPY_METHODS[method]
    run = Run()
    te = None if t_eval is None else np.asarray(t_eval, dtype=float)
    i_eval = _grid_start(te, segments[0][0])
    y = np.array(y0, dtype=float)
    rhs, qdot_fn = Fast(loop.rhs), Fast(loop.qdot)
    jac_fn = Fast(loop.jac) if method in IMPLICIT_METHODS and not _explicit_u(loop, controller) else None
    project = Fast(loop.project) if projection else None
    event = Measure(loop.event) if (loop.event is not None and event_tol) else None
    budget = {"left": _EVALS_PER_STEP * max_steps + 1000}
    last_h, stiff = None, {"count": 0}
    for j, (a, b) in enumerate(segments):
        t_hi, p = left_of(b), seg_params[j]
        fun = _scipy_fun(rhs, qdot_fn, loop, controller, t_hi, p, budget)
        f0 = fun(a, y)
        if _first_bad(f0) is not None:
            return run.fail(NONFINITE, a, "", bad=_first_bad(f0))

        def make(t_start, y_start, h, t_hi=t_hi, p=p, b=b, fun=fun):
            opts = dict(rtol=rtol, atol=atol, max_step=max_step)
            if h is not None:
                opts["first_step"] = min(h, b - t_start)
            if jac_fn is not None:
                opts["jac"] = lambda t, yy: jac_fn(t, min(t, t_hi), yy, p)
            return cls(fun, t_start, y_start, b, **opts)

        solver, counted = make(a, y, last_h), 0
        g_old = event.with_rate(y, f0, p) if event is not None else None
        while solver.status == "running":
            t_old = solver.t
            ok, counted = _advance(solver, run, method, b, counted)
            if not ok:
                return run
            t_new, y_new = solver.t, solver.y.copy()
            if _watch_stiffness(solver, method, run, stiff) and stop_on_stiff:
                return run.fail(FAILED, t_new, "stiff")
            if project is not None:
                y_new = project(y_new, p[:loop.n_params])
            found = None
            if event is not None:
                f_new = getattr(solver, "f", None)
                if f_new is None:                     # BDF, LSODA keep no f(t_new, y_new)
                    f_new, run.nfev = fun(t_new, y_new), run.nfev + 1
                found, g_old = _event_in_step(solver, event, p, t_old, t_new, y_new, f_new, g_old,
                                              event_tol)
            t_stop = t_new if found is None else found[0]
            i_eval = _record_step(run, solver, te, i_eval, t_stop, y_new, project, p[:loop.n_params],
                                  t_hi, j)
            if found is not None:
                run.add(found[0], t_hi, j, found[1])
                run.njev += getattr(solver, "njev", 0)
                return run.fail(SINGULAR, found[0], "")
            f_new = getattr(solver, "f", None)        # f(t_new, y_new) of the RK and Radau solvers
            if f_new is not None and _first_bad(f_new) is not None:
                return run.fail(NONFINITE, t_new, "", bad=_first_bad(f_new))
            if run.n_steps >= max_steps and (solver.status == "running" or j < len(segments) - 1):
                return run.fail(MAX_STEPS, t_new, f"max_steps = {max_steps} reached at t = {t_new:.9g}")
            if project is not None and solver.status == "running":
                run.njev += getattr(solver, "njev", 0)
                last_h = _next_step(solver)
                solver, counted = make(t_new, y_new, last_h), 0
        run.njev += getattr(solver, "njev", 0)
        last_h = _next_step(solver)
        y = np.asarray(solver.y if project is None else y_new, dtype=float)
    return run


def _advance(solver, run, method, b, counted):
    """One step of ``solver``: (True, evaluations counted) or (False, …) with ``run`` failed."""
    try:
        message = solver.step()
    except _Budget:
        run.nfev += solver.nfev - counted
        run.fail(MAX_STEPS, solver.t, f"evaluation budget ({_EVALS_PER_STEP}·max_steps) spent at "
                 f"t = {solver.t:.9g}")
        return False, counted
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        # e.g. a non-finite finite-difference Jacobian refused by the LU factorisation
        run.nfev += solver.nfev - counted
        run.t_bad = _attempted(solver, b)
        run.fail(FAILED, solver.t, f"integration failed at t = {solver.t:.9g}: scipy {method} "
                 f"raised {type(exc).__name__} ({exc})")
        return False, counted
    run.nfev += solver.nfev - counted
    if solver.status == "failed" or _first_bad(solver.y) is not None:
        run.njev += getattr(solver, "njev", 0)
        run.t_bad = _attempted(solver, b)
        run.fail(FAILED, solver.t, f"integration failed at t = {solver.t:.9g}: "
                 + (message or "non-finite state"))
        return False, solver.nfev
    run.n_steps += 1
    return True, solver.nfev


def _watch_stiffness(solver, method, run, stiff) -> bool:
    """Update h|λ| and the count of consecutive stiff steps; True when stiffness is detected."""
    hl = _stiffness(solver, method)
    if hl is None:
        return False
    run.h_lambda = max(run.h_lambda, hl)
    stiff["count"] = stiff["count"] + 1 if hl > STIFF_LIMIT[method] else 0
    if stiff["count"] >= 15 and run.t_stiff is None:
        run.t_stiff = float(solver.t)
        return True
    return False


def _record_step(run, solver, te, i_eval, t_stop, y_new, project, params, t_hi, j) -> int:
    """Record the step's output points up to ``t_stop`` (the step's end, or an event inside it);
    returns the next index into ``te``."""
    t_new = solver.t
    if te is None:
        if t_stop == t_new:
            run.add(t_new, t_hi, j, y_new)
        return i_eval
    dense = None
    while i_eval < te.size and te[i_eval] <= t_stop + 1e-12 * max(1.0, abs(t_stop)):
        tt = float(te[i_eval])
        if tt >= t_new:
            yy = y_new
        else:
            dense = dense or solver.dense_output()
            yy = dense(tt) if project is None else project(dense(tt), params)
        run.add(tt, t_hi, j, yy)
        i_eval += 1
    return i_eval


def _explicit_u(loop, controller) -> bool:
    return controller is not None and not (loop.symbolic_u or loop.segment_u)


def _scipy_fun(rhs, qdot_fn, loop, controller, t_hi, p, budget):
    """f(t, y) for scipy, with the evaluation budget."""
    if not _explicit_u(loop, controller):
        def fun(t, yy):
            budget["left"] -= 1
            if budget["left"] < 0:
                raise _Budget()
            return rhs(t, min(t, t_hi), yy, p)
        return fun

    def fun(t, yy):
        budget["left"] -= 1
        if budget["left"] < 0:
            raise _Budget()
        tc = min(t, t_hi)
        u = np.asarray(controller(tc, yy[:loop.n_q], qdot_fn(yy, p)), dtype=float).ravel()
        return rhs(t, tc, yy, u, p)
    return fun


def _attempted(solver, b) -> float:
    """A time the failed step tried to reach (for the diagnosis of the failure)."""
    h = getattr(solver, "h_abs", None)
    h = float(h) if h is not None and np.isfinite(h) and h > 0 else 0.0
    return min(float(solver.t) + max(h, 1e-9 * max(1.0, abs(solver.t))), b)


def _next_step(solver):
    """The step the solver proposes next (RK/Radau/BDF keep it as ``h_abs``), else the last."""
    h = getattr(solver, "h_abs", None)
    return float(h) if h is not None and np.isfinite(h) and h > 0 else solver.step_size


# --------------------------------------------------------------------------------------------
# SUNDIALS through CasADi
# --------------------------------------------------------------------------------------------
#: output points per SUNDIALS call: a failure loses at most this many outputs
_CHUNK = 16


def integrate_sundials(request: RunRequest, kind: str, lam0=None) -> Run:
    """CVODES (``kind="cvodes"``, BDF with Newton) on the ODE or IDAS (``kind="idas"``, from the
    multipliers ``lam0``) on the index-1 DAE; outputs at ``t_eval`` (or the interval ends),
    :data:`_CHUNK` output points per call; the event is checked at the outputs. For CVODES a
    step size below 10⁻¹³·max(1, |t|) is a failure (it would otherwise spend ``max_steps``
    steps going nowhere next to a singularity)."""
    loop, segments, y0, seg_params, t_eval = (request.loop, request.segments, request.y0, request.seg_params,
                                              request.t_eval)
    rtol, atol, max_steps, event_tol = request.rtol, request.atol, request.max_steps, request.event_tol
    stabilization, baumgarte = request.stabilization, request.baumgarte
    te = None if t_eval is None else np.asarray(t_eval, dtype=float)
    run = Run(lam=[] if kind == "idas" else None)
    y, lam = np.array(y0, dtype=float), None if lam0 is None else np.array(lam0, dtype=float)
    t_max = max(abs(segments[0][0]), abs(segments[-1][1]), 1.0)
    opts = {"abstol": atol, "reltol": rtol, "max_num_steps": int(max_steps), "print_stats": False,
            "show_eval_warnings": False, "disable_internal_warnings": True}
    if kind == "idas":
        opts.update(calc_ic=True, suppress_algebraic=True)
        problem = loop.dae(stabilization, baumgarte)
    else:
        opts["min_step_size"] = 1e-13 * t_max        # CVODES only (IDAS has no such option)
        problem = _cvodes_problem(loop)
    event = Measure(loop.event) if (loop.event is not None and event_tol) else None
    for j, (a, b) in enumerate(segments):
        tol = 1e-12 * max(1.0, abs(b))
        wanted = [] if te is None else [float(tt) for tt in te if a + 1e-12 * max(1.0, abs(a)) < tt <= b + tol]
        grid = [min(tt, b) for tt in wanted]
        if not grid or grid[-1] < b:
            grid.append(b)
        names = dict(zip(grid, wanted)) if te is not None else {b: b}
        p, t_cur = seg_params[j], a
        pv = np.r_[p, left_of(b)]
        for c in range(0, len(grid), _CHUNK):
            chunk = grid[c:c + _CHUNK]
            F = ca.integrator(f"{kind}_segment_{j}", kind, problem, t_cur, chunk, opts)
            args = dict(x0=y, p=pv) if kind != "idas" else dict(x0=y, p=pv, z0=lam)
            try:
                out = F(**args)
            except RuntimeError as err:
                run.nfev += int(F.stats().get("nfevals", 0))
                return _sundials_failure(run, kind, problem, opts, pv, p, t_cur, y, lam, b, err,
                                         event, event_tol, max_steps, (a, j, chunk, names))
            stats = F.stats()
            run.nfev += int(stats.get("nfevals", 0))
            run.njev += int(stats.get("n_call_jacF", stats.get("njevals", 0)))
            run.n_steps += int(stats.get("nsteps", 0))
            xf = np.asarray(out["xf"]).reshape(y.size, -1)
            zf = np.asarray(out["zf"]).reshape(lam.size, -1) if kind == "idas" else None
            if _record_outputs(run, (a, b, j, p), chunk, names, xf, zf, event, event_tol):
                return run
            y, t_cur = xf[:, -1].copy(), chunk[-1]
            lam = None if zf is None else zf[:, -1].copy()
    return run


def _record_outputs(run, where, chunk, names, xf, zf, event, event_tol) -> bool:
    """Add the outputs of one integrator call (columns of ``xf``/``zf`` at ``chunk``) to
    ``run``, checking the singular-set measure at each; True when it stopped the run there."""
    a, b, j, p = where
    for col, gt in enumerate(chunk):
        if gt not in names:
            continue
        if event is not None:
            g = event(xf[:, col], p)
            if not (np.isfinite(g) and g >= event_tol):
                t_prev = run.t[-1] if run.t else a
                run.fail(SINGULAR, names[gt], f"reached the singular set between t = {t_prev:.9g} and "
                         f"t = {names[gt]:.9g} (measure {g:.3g} < {event_tol:g} on the output grid)")
                return True
        run.add(names[gt], left_of(b), j, xf[:, col], None if zf is None else zf[:, col])
    return False


def _outputs_before(run, kind, problem, opts, pv, p, t, y, lam, b, t_ok, pending, event, event_tol) -> bool:
    """After a failure: the outputs of the failed call that lie before ``t_ok`` (the last time
    the bracketing reached), integrated again so that none is lost; True when one of them is
    on the singular set (the run stopped there)."""
    a, j, chunk, names = pending
    before = [gt for gt in chunk if t < gt <= t_ok]
    if not before:
        return False
    F = ca.integrator(f"{kind}_outputs", kind, problem, t, before, opts)
    try:
        out = F(**(dict(x0=y, p=pv) if lam is None else dict(x0=y, p=pv, z0=lam)))
    except RuntimeError:
        return False
    xf = np.asarray(out["xf"]).reshape(np.size(y), -1)
    zf = None if lam is None else np.asarray(out["zf"]).reshape(np.size(lam), -1)
    return _record_outputs(run, (a, b, j, p), before, names, xf, zf, event, event_tol)


def _sundials_failure(run, kind, problem, opts, pv, p, t, y, lam, b, err, event, event_tol,
                      max_steps, pending) -> Run:
    """Bracket a SUNDIALS failure after (t, y) and classify it (singular set, max_steps, other);
    the failed call's outputs before the failure are kept (``pending``: its segment start,
    index, output times and their names), and the last state reached ends the trajectory, as
    on the other routes."""
    t_ok, y_ok, lam_ok, t_bad = _bracket_failure(kind, problem, opts, pv, t, y, lam, b)
    if _outputs_before(run, kind, problem, opts, pv, p, t, y, lam, b, t_ok, pending, event, event_tol):
        return run
    if t_ok > (run.t[-1] if run.t else -np.inf):
        run.add(t_ok, left_of(b), pending[1], y_ok, lam_ok)
    run.y_fail, run.t_bad = y_ok, t_bad
    if event is not None and event(y_ok, p) < WATCH * event_tol:
        return run.fail(SINGULAR, t_ok, f"{kind.upper()} stopped between t = {t_ok:.9g} and "
                        f"t = {t_bad:.9g}, next to the singular set (measure "
                        f"{event(y_ok, p):.3g} at t = {t_ok:.9g})")
    reason = str(err).splitlines()[-1].split(": ")[-1]
    if "TOO_MUCH_WORK" in reason:
        return run.fail(MAX_STEPS, t_ok, f"max_steps = {max_steps} (per output interval) reached "
                        f"between t = {t_ok:.9g} and t = {t_bad:.9g}")
    return run.fail(FAILED, t_ok, f"{kind.upper()} failed between t = {t_ok:.9g} and "
                    f"t = {t_bad:.9g}: {reason}")


def _bracket_failure(kind, problem, opts, pv, t, y, lam, b, levels=2, pieces=16):
    """(last time reached, its state and multipliers, first time not reached): the failed
    interval [t, b] re-integrated piece by piece, twice refined (only on failure)."""
    for _ in range(levels):
        for t_next in np.linspace(t, b, pieces + 1)[1:]:
            F = ca.integrator(f"{kind}_bracket", kind, problem, t, [float(t_next)], opts)
            args = dict(x0=y, p=pv)
            if lam is not None:
                args["z0"] = lam
            try:
                out = F(**args)
            except RuntimeError:
                b = float(t_next)
                break
            t, y = float(t_next), np.asarray(out["xf"]).ravel()
            lam = None if lam is None else np.asarray(out["zf"]).ravel()
        else:
            return t, y, lam, b
    return t, y, lam, b


def _cvodes_problem(loop) -> dict:
    pc = loop._pieces
    t, y, p = pc["t"], pc["y"], pc["p"]
    t_hi = ca.SX.sym("t_hi")
    ydot = ca.substitute(pc["ydot"], pc["t_c"], ca.fmin(t, t_hi))
    return {"t": t, "x": y, "p": ca.vertcat(p, t_hi), "ode": ydot}


# --------------------------------------------------------------------------------------------
# compiled
# --------------------------------------------------------------------------------------------
_C_STATUS = {-1: FAILED, -2: MAX_STEPS, -3: NONFINITE, -4: NONFINITE, -5: SINGULAR}


def integrate_compiled(request: RunRequest, library, scheme: str, *, stop_on_stiff=False) -> Run:
    """Run the compiled integrator (:mod:`.compiled`, the closed loop's ``library``) interval by
    interval with the explicit Runge–Kutta ``scheme`` ("DOP853" or "DOPRI5")."""
    segments, y0, seg_params, t_eval = request.segments, request.y0, request.seg_params, request.t_eval
    rtol, atol, max_step, max_steps = request.rtol, request.atol, request.max_step, request.max_steps
    event_tol = request.event_tol
    from .compiled import RunState
    run = Run()
    te = None if t_eval is None else np.ascontiguousarray(t_eval, dtype=float)
    state = RunState.start(segments[0][0], rtol, atol, max_step, max_steps,
                           event_tol if (event_tol and library.has_event) else 0.0, stop_on_stiff)
    state.set("i_eval", _grid_start(te, segments[0][0]))
    y = np.ascontiguousarray(y0, dtype=float).copy()
    y_eval = None if te is None else np.zeros((te.size, library.ny))
    t_steps = y_steps = None
    if te is None:
        t_steps, y_steps = np.zeros(1025), np.zeros((1025, library.ny))
    code = 0
    for j, (a, b) in enumerate(segments):
        t_hi, p = left_of(b), np.ascontiguousarray(seg_params[j], dtype=float)
        state.set("t", a)
        first = state["i_eval"]
        while True:
            code = library.run(scheme, state, b, t_hi, y, p, te, y_eval, t_steps, y_steps)
            if te is None:
                run.add_block(t_steps[:state["n_out"]], t_hi, j, y_steps[:state["n_out"]])
            if code != 1:
                break
            t_steps, y_steps = np.zeros(2 * t_steps.size - 1), np.zeros((2 * t_steps.size - 1, library.ny))
        if te is not None:
            run.add_block(te[first:state["i_eval"]], t_hi, j, y_eval[first:state["i_eval"]])
        if code != 0:
            break
    run.nfev, run.n_steps, run.n_rejected = state["nfev"], state["accepted"], state["rejected"]
    run.h_lambda = float(state["h_lambda"])
    if not np.isnan(state["t_stiff"]):
        run.t_stiff = float(state["t_stiff"])
    if code == -6:
        return run.fail(FAILED, state["t"], "stiff")
    if code in _C_STATUS:
        t_fail = float(state["t_fail"])
        if code == -5 and te is not None:        # the event point itself closes the output
            run.add(t_fail, left_of(segments[j][1]), j, y)
        if code == -2:
            return run.fail(MAX_STEPS, t_fail, f"max_steps = {max_steps} reached at t = {t_fail:.9g}")
        if code == -1:
            return run.fail(FAILED, t_fail, f"integration failed at t = {t_fail:.9g}: required step "
                            "size is less than 16 ulp of t")
        return run.fail(_C_STATUS[code], t_fail, "", bad=int(state["bad"]) if code == -3 else None)
    return run
