"""The integration routes behind :func:`~.simulation.simulate`, one function per route, and
what they share (the frozen :class:`RunRequest`, the :class:`Run` they return, the statuses);
the scipy route lives here, the SUNDIALS and compiled routes in their own modules.

Each route integrates the closed loop ẏ = f(t, t_c, y, p) of :mod:`.closed_loop` interval by
interval (``segments``: the controller's switch times) and returns a :class:`Run` — the output
points reached, counters and a status — never raising for a numerical failure:

* :func:`integrate_scipy`: scipy's step loop (RK23, RK45, DOP853, Radau, BDF, LSODA), driven one
  step at a time so that every accepted step is checked (non-finite values, the singular-set
  event, the step budget, stiffness) and projection can restart the solver;
* :func:`~.route_sundials.integrate_sundials` (:mod:`.route_sundials`): CasADi's CVODES (BDF) on the
  ODE, or IDAS on the index-1 DAE with λ algebraic, reporting on the output grid;
* :func:`~.route_compiled.integrate_compiled` (:mod:`.route_compiled`): the compiled Dormand–Prince
  integrator of :mod:`.compiled`, one C call per interval.

Statuses (``Run.status``): :data:`FINISHED` 0, :data:`FAILED` −1 (the method gave up: step size
underflow, solver error), :data:`MAX_STEPS` −2, :data:`NONFINITE` −3 (a non-finite right-hand
side, input or state; ``Run.t_fail`` is the time), :data:`SINGULAR` −4 (the singular-set measure
fell below its threshold; ``Run.t_fail`` is the crossing time, located to ~1e-15 relative on the
dense output of the explicit methods, to the output grid for SUNDIALS).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

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
class Segment:
    """One integration interval [start, end] between the controller's switch times: its
    ``index``, its ends and ``params``, the closed loop's parameter vector p on it."""

    index: int
    start: float
    end: float
    params: np.ndarray

    @property
    def t_hi(self) -> float:
        """The last time before ``end``: where the controller's and the forces' time is clamped."""
        return left_of(self.end)


@dataclass(frozen=True, eq=False)
class RunRequest:
    """One integration of a closed loop, as every route sees it (built once by ``simulate``).

    loop : the :class:`~.closed_loop.ClosedLoop`; controller : the user's controller or None;
    segments : [(a, b)] intervals between the controller's switch times; y0 : (n_y,) start;
    seg_params : the loop's parameter vector of each segment; options : the run's
    :class:`~.options.SimulationOptions` (output times, tolerances, step limits, the singular-set
    threshold — None or 0: no event —, the constraint stabilisation).
    """

    loop: object
    controller: object
    segments: list
    y0: np.ndarray
    seg_params: list
    options: object             # SimulationOptions

    @property
    def python_inputs(self) -> bool:
        """The inputs come from a Python controller called at every evaluation (it has no
        CasADi form and is not piecewise given): no compiled route, no symbolic Jacobian in u."""
        return self.controller is not None and not (self.loop.symbolic_u or self.loop.segment_u)

    def intervals(self) -> list:
        """The integration intervals as :class:`Segment` values, in time order."""
        return [Segment(j, float(a), float(b), np.asarray(self.seg_params[j], dtype=float))
                for j, (a, b) in enumerate(self.segments)]


@dataclass(frozen=True, eq=False)
class Samples:
    """Output points as arrays: ``t`` (N,) times, ``t_c`` (N,) the times the controller and the
    forces see (t clamped to its segment), ``seg`` (N,) segment indices, ``y`` (N, n_y) states,
    ``lam`` (N, k) multipliers (IDAS) or None."""

    t: np.ndarray
    t_c: np.ndarray
    seg: np.ndarray
    y: np.ndarray
    lam: np.ndarray | None = None

    def __len__(self) -> int:
        return self.t.size

    def rows(self, start: int = 0, stop: int | None = None) -> Samples:
        """The points ``start:stop`` (views)."""
        part = slice(start, stop)
        return Samples(self.t[part], self.t_c[part], self.seg[part], self.y[part],
                       None if self.lam is None else self.lam[part])

    def with_lam(self, lam) -> Samples:
        """These points with the multipliers ``lam`` (N, k)."""
        return Samples(self.t, self.t_c, self.seg, self.y, lam)

    @classmethod
    def join(cls, parts) -> Samples:
        """The points of ``parts`` one after the other (multipliers only if all have them)."""
        lams = [part.lam for part in parts]
        return cls(*(np.concatenate([getattr(part, name) for part in parts])
                     for name in ("t", "t_c", "seg", "y")),
                   None if any(lam is None for lam in lams) else np.concatenate(lams))

    @classmethod
    def point(cls, t: float, t_c: float, seg: int, y, lam=None) -> Samples:
        """One point."""
        return cls(np.array([float(t)]), np.array([float(t_c)]), np.array([seg], dtype=np.intp),
                   np.array(y, dtype=float).reshape(1, -1),
                   None if lam is None else np.array(lam, dtype=float).reshape(1, -1))


@dataclass
class Run:
    """What a route produced: the output points (:meth:`samples`), counters and a status.

    A route adds points one at a time (:meth:`add`) or as arrays (:meth:`add_block`, the
    compiled route's blocks, kept as arrays); :meth:`samples` joins them once, at the end."""

    with_lam: bool = False                # points carry multipliers (IDAS)
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
    _rows: list = field(default_factory=list, repr=False)      # points added one by one
    _blocks: list = field(default_factory=list, repr=False)    # Samples, in time order

    def add(self, t, t_hi, seg, y, lam=None):
        t = float(t)
        self._rows.append((t, min(t, t_hi), seg, np.array(y, dtype=float),
                           None if lam is None else np.array(lam, dtype=float)))

    def add_block(self, t, t_hi, seg, Y, copy: bool = True):
        """:meth:`add` for N points at once: ``t`` (N,), ``Y`` (N, n_y) (copied; with
        ``copy=False`` kept as they are: the caller hands them over and never writes them again)."""
        self._flush()
        if copy:
            t, Y = np.array(t, dtype=float), np.array(Y, dtype=float)
        if t.size:
            self._blocks.append(Samples(t, np.minimum(t, t_hi), np.full(t.size, seg, dtype=np.intp),
                                        Y.reshape(t.size, -1)))

    def _flush(self) -> None:
        if self._rows:
            t, t_c, seg, y, lam = zip(*self._rows, strict=True)
            self._blocks.append(Samples(np.array(t), np.array(t_c), np.array(seg, dtype=np.intp),
                                        np.array(y), np.array(lam) if self.with_lam else None))
            self._rows = []

    def samples(self, n_y: int, n_lam: int = 0) -> Samples:
        """Every point added, as arrays (``lam`` (N, n_lam) when the points carry multipliers)."""
        self._flush()
        if not self._blocks:
            return Samples(np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.intp), np.zeros((0, n_y)),
                           np.zeros((0, n_lam)) if self.with_lam else None)
        if len(self._blocks) > 1:
            self._blocks = [Samples.join(self._blocks)]
        return self._blocks[0]

    def keep_first(self, rows: int) -> None:
        """Drop every point after the first ``rows``."""
        self._flush()
        if self._blocks:
            self._blocks = [self.samples(0).rows(0, rows)]

    def last(self) -> tuple | None:
        """(t, segment index, y) of the last point added, or None."""
        if self._rows:
            t, _, seg, y, _ = self._rows[-1]
            return t, seg, y
        if self._blocks and len(self._blocks[-1]):
            block = self._blocks[-1]
            return float(block.t[-1]), int(block.seg[-1]), block.y[-1]
        return None

    def fail(self, status, t, message, bad=None):
        self.status, self.t_fail, self.message, self.bad = status, float(t), message, bad
        return self


def left_of(b: float) -> float:
    """The largest float below ``b``."""
    return math.nextafter(float(b), -math.inf)


class Fast:
    """Evaluate a CasADi Function on dense numpy vectors through a FunctionBuffer (no per-call
    conversions: about 60× cheaper a call, docs/benchmarks.md, "Measured numbers behind design
    choices"). Returns a copy of the first output, flattened column-major."""

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
        for dst, a in zip(self._args, args, strict=True):
            dst[:] = a
        self._eval()
        rows, cols = self._shapes[0]
        return self._res[0].reshape(cols, rows).T.copy() if cols > 1 else self._res[0].copy()

    def scalars(self, *args) -> tuple[float, ...]:
        """All outputs, each a scalar (for functions with scalar outputs only)."""
        for dst, a in zip(self._args, args, strict=True):
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

    def with_rate(self, y, ydot, p) -> tuple[float, ...]:
        return self._fast.scalars(y, ydot, p)


@dataclass(frozen=True, eq=False)
class EventWatch:
    """The singular-set event on one segment: the ``measure``, the segment's parameter vector
    ``params`` and the threshold ``tol`` (the run stops where s < tol)."""

    measure: Measure
    params: np.ndarray
    tol: float

    def __call__(self, y) -> float:
        return self.measure(y, self.params)

    def with_rate(self, y, ydot) -> tuple[float, ...]:
        return self.measure.with_rate(y, ydot, self.params)

    def clear(self, value) -> bool:
        """The measure ``value`` is finite and at or above the threshold."""
        return bool(np.isfinite(value) and value >= self.tol)


class _Budget(Exception):
    """Raised inside the right-hand side when the evaluation budget is spent."""


def _first_bad(v) -> int | None:
    bad = np.flatnonzero(~np.isfinite(np.asarray(v, dtype=float)))
    return int(bad[0]) if bad.size else None


class _Grid:
    """The output times ``te`` (or None: every accepted step) and the index of the next one
    still to be recorded (the one cursor a route moves along the grid)."""

    def __init__(self, t_eval, t0: float):
        self.te = None if t_eval is None else np.asarray(t_eval, dtype=float)
        self.next = grid_start(self.te, t0)

    def due(self, t: float) -> bool:
        """The next output time exists and lies at or before ``t`` (to 1e-12 relative)."""
        return self.next < self.te.size and self.te[self.next] <= t + 1e-12 * max(1.0, abs(t))


def grid_start(te, t0):
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


def _locate(dense, watch: EventWatch, t_lo, t_hi):
    """Bisection for the first time in (t_lo, t_hi] where the measure on ``dense(t)`` falls
    below the threshold."""
    lo, hi = t_lo, t_hi
    for _ in range(80):
        if hi - lo <= 4 * np.finfo(float).eps * max(abs(hi), 1.0):
            break
        mid = 0.5 * (lo + hi)
        if watch.clear(watch(dense(mid))):
            lo = mid
        else:
            hi = mid
    return hi, dense(hi)


def _golden(dense, watch: EventWatch, lo, hi):
    """(t, s) at the minimum of s(dense(t)) on [lo, hi] (golden-section search)."""
    r = 0.6180339887498949
    a, b = hi - r * (hi - lo), lo + r * (hi - lo)
    ga, gb = watch(dense(a)), watch(dense(b))
    for _ in range(60):
        if hi - lo <= 1e-13 * max(1.0, abs(hi)):
            break
        if not ga >= gb:
            hi, b, gb = b, a, ga
            a = hi - r * (hi - lo)
            ga = watch(dense(a))
        else:
            lo, a, ga = a, b, gb
            b = lo + r * (hi - lo)
            gb = watch(dense(b))
    return (a, ga) if ga < gb else (b, gb)


class _Step(NamedTuple):
    """An accepted step from ``t_old`` to ``t_new``, its end state and ẏ there."""

    t_old: float
    t_new: float
    y_new: np.ndarray
    f_new: np.ndarray


def _event_in_step(solver, watch: EventWatch, step: _Step, old: tuple):
    """(t, y) of the first point of the step with measure < tol, or None; and (s, ṡ) at the
    end (``old``: (s, ṡ) at the start).

    The measure is a squared quantity: it touches 0 and rises again where a trajectory crosses
    the set, so a step can jump over a crossing its end points do not show. Near the set (an end
    below WATCH·tol) or when s can change by more than half its value within the step
    (h|ṡ| > s/2 at an end), 7 interior points of the dense output are sampled and every local
    minimum of the samples (and one next to an end where the end rate says so) is refined by
    golden-section search (the same rule as the compiled integrator)."""
    g_new, rate_new = watch.with_rate(step.y_new, step.f_new)
    g_old, rate_old = old
    gmin = min(g_old, g_new)
    h = abs(step.t_new - step.t_old)
    if (watch.clear(g_new) and gmin >= WATCH * watch.tol
            and h * max(abs(rate_old), abs(rate_new)) <= 0.5 * gmin):
        return None, (g_new, rate_new)
    dense = solver.dense_output()
    ts = step.t_old + (step.t_new - step.t_old) * np.arange(9) / 8.0
    gs = [g_old] + [watch(dense(tt)) for tt in ts[1:8]] + [g_new]
    for j in range(9):
        if j > 0 and not watch.clear(gs[j]):
            return _locate(dense, watch, ts[j - 1], ts[j]), (g_new, rate_new)
        if j == 0:
            dip, a, b = rate_old < 0 and gs[1] > gs[0], ts[0], ts[1]
        elif j < 8:
            dip, a, b = gs[j] <= gs[j - 1] and gs[j] <= gs[j + 1], ts[j - 1], ts[j + 1]
        else:
            dip, a, b = rate_new > 0 and gs[7] > gs[8], ts[7], ts[8]
        if dip:
            t_min, g = _golden(dense, watch, a, b)
            if not watch.clear(g):
                return _locate(dense, watch, a, t_min), (g_new, rate_new)
    return None, (g_new, rate_new)


@dataclass(frozen=True, eq=False)
class _ScipyTools:
    """What the scipy route evaluates: ``rhs`` and ``qdot`` (FunctionBuffers), ``jac`` (implicit
    methods with a symbolic input), ``project`` (projection), ``measure`` (the event), the
    solver class and the evaluation ``budget`` (a one-entry dict counting down)."""

    rhs: Fast
    qdot: Fast
    jac: Fast | None
    project: Fast | None
    measure: Measure | None
    solver_class: type
    budget: dict

    @classmethod
    def build(cls, request: RunRequest, method: str, projection: bool) -> _ScipyTools:
        loop, options = request.loop, request.options
        implicit = method in IMPLICIT_METHODS and not request.python_inputs
        return cls(rhs=Fast(loop.rhs), qdot=Fast(loop.qdot), jac=Fast(loop.jac) if implicit else None,
                   project=Fast(loop.project) if projection else None,
                   measure=Measure(loop.event) if (loop.event is not None and options.singular_tol) else None,
                   solver_class=SCIPY_METHODS[method],
                   budget={"left": _EVALS_PER_STEP * options.max_steps + 1000})

    def projector(self, segment: Segment, n_params: int):
        """y ↦ y projected onto the constraints on ``segment``, or None without projection."""
        if self.project is None:
            return None
        params = segment.params[:n_params]
        return lambda y: self.project(y, params)

    def solver_maker(self, request: RunRequest, segment: Segment, fun):
        """make(t_start, y_start, h) → a scipy solver on ``segment`` from (t_start, y_start),
        first step ``h`` (None: scipy's choice)."""
        t_hi, p, jac, options = segment.t_hi, segment.params, self.jac, request.options

        def make(t_start, y_start, h):
            opts = dict(rtol=options.rtol, atol=options.atol, max_step=options.max_step)
            if h is not None:
                opts["first_step"] = min(h, segment.end - t_start)
            if jac is not None:
                opts["jac"] = lambda t, yy: jac(t, min(t, t_hi), yy, p)
            return self.solver_class(fun, t_start, y_start, segment.end, **opts)
        return make


def integrate_scipy(request: RunRequest, method: str, *, projection=False, stop_on_stiff=False) -> Run:
    """Integrate with a scipy OdeSolver, one step at a time (see the module docstring);
    ``projection``: project the velocities onto the constraints after every step;
    ``stop_on_stiff``: end (message "stiff") when stiffness is detected."""
    loop, segments = request.loop, request.segments
    tools = _ScipyTools.build(request, method, projection)
    run = Run()
    grid = _Grid(request.options.t_eval, segments[0][0])
    y = np.array(request.y0, dtype=float)
    last_h, stiff = None, {"count": 0}
    for segment in request.intervals():
        j, p, t_hi = segment.index, segment.params, segment.t_hi
        fun = _scipy_fun(request, tools, segment)
        f0 = fun(segment.start, y)
        if _first_bad(f0) is not None:
            return run.fail(NONFINITE, segment.start, "", bad=_first_bad(f0))
        make = tools.solver_maker(request, segment, fun)
        project = tools.projector(segment, loop.n_params)
        watch = None if tools.measure is None else EventWatch(tools.measure, p, request.options.singular_tol)
        solver, counted = make(segment.start, y, last_h), 0
        g_old = watch.with_rate(y, f0) if watch is not None else None
        while solver.status == "running":
            t_old = solver.t
            ok, counted = _advance(solver, run, method, segment.end, counted)
            if not ok:
                return run
            t_new, y_new = solver.t, solver.y.copy()
            if _watch_stiffness(solver, method, run, stiff) and stop_on_stiff:
                return run.fail(FAILED, t_new, "stiff")
            if project is not None:
                y_new = project(y_new)
            found = None
            if watch is not None:
                f_new = getattr(solver, "f", None)
                if f_new is None:                     # BDF, LSODA keep no f(t_new, y_new)
                    f_new, run.nfev = fun(t_new, y_new), run.nfev + 1
                found, g_old = _event_in_step(solver, watch, _Step(t_old, t_new, y_new, f_new), g_old)
            t_stop = t_new if found is None else found[0]
            _record_step(run, solver, grid, segment, (t_stop, y_new), project)
            if found is not None:
                run.add(found[0], t_hi, j, found[1])
                run.njev += getattr(solver, "njev", 0)
                return run.fail(SINGULAR, found[0], "")
            f_new = getattr(solver, "f", None)        # f(t_new, y_new) of the RK and Radau solvers
            if f_new is not None and _first_bad(f_new) is not None:
                return run.fail(NONFINITE, t_new, "", bad=_first_bad(f_new))
            max_steps = request.options.max_steps
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


def _record_step(run, solver, grid: _Grid, segment: Segment, stop: tuple, project) -> None:
    """Record the step's output points up to ``stop`` = (t_stop, y_new): the step's end and
    its (projected) state, or an event inside it; ``project`` (or None) projects dense output."""
    t_stop, y_new = stop
    t_new, t_hi, j = solver.t, segment.t_hi, segment.index
    if grid.te is None:
        if t_stop == t_new:
            run.add(t_new, t_hi, j, y_new)
        return
    dense = None
    while grid.due(t_stop):
        tt = float(grid.te[grid.next])
        if tt >= t_new:
            yy = y_new
        else:
            dense = dense or solver.dense_output()
            yy = dense(tt) if project is None else project(dense(tt))
        run.add(tt, t_hi, j, yy)
        grid.next += 1


def _scipy_fun(request: RunRequest, tools: _ScipyTools, segment: Segment):
    """f(t, y) for scipy on ``segment``, counting down the evaluation budget."""
    rhs, qdot_fn, budget, loop = tools.rhs, tools.qdot, tools.budget, request.loop
    t_hi, p = segment.t_hi, segment.params
    if not request.python_inputs:
        def fun(t, yy):
            budget["left"] -= 1
            if budget["left"] < 0:
                raise _Budget()
            return rhs(t, min(t, t_hi), yy, p)
        return fun
    controller = request.controller

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
