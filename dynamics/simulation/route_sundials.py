"""The SUNDIALS route: CasADi's CVODES (BDF, Newton with the exact Jacobian) on the closed
loop's ODE, or IDAS on the semi-explicit index-1 DAE with λ algebraic, reporting on the output
grid in chunks (a failure loses at most :data:`_CHUNK` outputs and is bracketed to name its
time). Returns an :class:`~.integrators.Run`; never raises for a numerical failure.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca
import numpy as np

from .integrators import FAILED, MAX_STEPS, SINGULAR, WATCH, EventWatch, Measure, Run, RunRequest, Segment

__all__ = ["integrate_sundials"]


#: output points per SUNDIALS call: a failure loses at most this many outputs
_CHUNK = 16


class _Start(NamedTuple):
    """Where a SUNDIALS call starts: time, state, multipliers (IDAS) or None."""

    t: float
    y: np.ndarray
    lam: np.ndarray | None


@dataclass(frozen=True, eq=False, kw_only=True)
class _SundialsCall:
    """One SUNDIALS problem on one segment: ``kind`` ("cvodes" or "idas"), the CasADi
    ``problem`` and ``opts``, ``pv`` = (p, t_hi) its parameter vector, the ``segment``, the
    event ``watch`` (or None) and ``max_steps`` (named in a failure message)."""

    kind: str
    problem: dict
    opts: dict
    pv: np.ndarray
    segment: Segment
    watch: EventWatch | None
    max_steps: int

    def integrator(self, name: str, t0: float, grid: list) -> ca.Function:
        """The CasADi integrator from ``t0`` to the times of ``grid``."""
        return ca.integrator(f"{self.kind}_{name}", self.kind, self.problem, t0, grid, self.opts)

    def arguments(self, start: _Start) -> dict:
        args = dict(x0=start.y, p=self.pv)
        if start.lam is not None:
            args["z0"] = start.lam
        return args

    def integrate(self, name: str, start: _Start, grid: list) -> dict:
        """The integrator's outputs (``xf``, ``zf``) from ``start`` to the times of ``grid``
        (a SUNDIALS failure raises RuntimeError)."""
        return self.integrator(name, start.t, grid)(**self.arguments(start))


def integrate_sundials(request: RunRequest, kind: str, lam0=None) -> Run:
    """CVODES (``kind="cvodes"``, BDF with Newton) on the ODE or IDAS (``kind="idas"``, from the
    multipliers ``lam0``) on the index-1 DAE; outputs at ``t_eval`` (or the interval ends),
    :data:`_CHUNK` output points per call; the event is checked at the outputs. For CVODES a
    step size below 10⁻¹³·max(1, |t|) is a failure (it would otherwise spend ``max_steps``
    steps going nowhere next to a singularity)."""
    loop, segments, options = request.loop, request.segments, request.options
    te = None if options.t_eval is None else np.asarray(options.t_eval, dtype=float)
    run = Run(with_lam=kind == "idas")
    y, lam = np.array(request.y0, dtype=float), None if lam0 is None else np.array(lam0, dtype=float)
    t_max = max(abs(segments[0][0]), abs(segments[-1][1]), 1.0)
    opts = {"abstol": options.atol, "reltol": options.rtol, "max_num_steps": int(options.max_steps),
            "print_stats": False, "show_eval_warnings": False, "disable_internal_warnings": True}
    if kind == "idas":
        opts.update(calc_ic=True, suppress_algebraic=True)
        problem = loop.dae()
    else:
        opts["min_step_size"] = 1e-13 * t_max        # CVODES only (IDAS has no such option)
        problem = _cvodes_problem(loop)
    measure = Measure(loop.event) if (loop.event is not None and options.singular_tol) else None
    for segment in request.intervals():
        a, b = segment.start, segment.end
        tol = 1e-12 * max(1.0, abs(b))
        wanted = [] if te is None else [float(tt) for tt in te
                                        if a + 1e-12 * max(1.0, abs(a)) < tt <= b + tol]
        grid = [min(tt, b) for tt in wanted]
        if not grid or grid[-1] < b:
            grid.append(b)
        names = dict(zip(grid, wanted, strict=False)) if te is not None else {b: b}
        watch = None if measure is None else EventWatch(measure, segment.params, options.singular_tol)
        call = _SundialsCall(kind=kind, problem=problem, opts=opts, pv=np.r_[segment.params, segment.t_hi],
                             segment=segment, watch=watch, max_steps=options.max_steps)
        start = _Start(a, y, lam)
        for c in range(0, len(grid), _CHUNK):
            chunk = grid[c:c + _CHUNK]
            F = call.integrator(f"segment_{segment.index}", start.t, chunk)
            try:
                out = F(**call.arguments(start))
            except RuntimeError as err:
                run.nfev += int(F.stats().get("nfevals", 0))
                return _sundials_failure(run, call, start, err, (chunk, names))
            stats = F.stats()
            run.nfev += int(stats.get("nfevals", 0))
            run.njev += int(stats.get("n_call_jacF", stats.get("njevals", 0)))
            run.n_steps += int(stats.get("nsteps", 0))
            xf = np.asarray(out["xf"]).reshape(y.size, -1)
            zf = np.asarray(out["zf"]).reshape(lam.size, -1) if kind == "idas" else None
            if _record_outputs(run, call, (chunk, names), xf, zf):
                return run
            start = _Start(chunk[-1], xf[:, -1].copy(), None if zf is None else zf[:, -1].copy())
        y, lam = start.y, start.lam
    return run


def _record_outputs(run, call: _SundialsCall, outputs: tuple, xf, zf) -> bool:
    """Add the outputs of one integrator call (columns of ``xf``/``zf`` at the times of
    ``outputs`` = (grid, names of the grid times)) to ``run``, checking the singular-set
    measure at each; True when it stopped the run there."""
    chunk, names = outputs
    segment, watch = call.segment, call.watch
    for col, gt in enumerate(chunk):
        if gt not in names:
            continue
        if watch is not None:
            g = watch(xf[:, col])
            if not watch.clear(g):
                last = run.last()
                t_prev = last[0] if last is not None else segment.start
                run.fail(SINGULAR, names[gt], f"reached the singular set between t = {t_prev:.9g} and "
                         f"t = {names[gt]:.9g} (measure {g:.3g} < {watch.tol:g} on the output grid)")
                return True
        run.add(names[gt], segment.t_hi, segment.index, xf[:, col], None if zf is None else zf[:, col])
    return False


def _outputs_before(run, call: _SundialsCall, start: _Start, t_ok: float, pending: tuple) -> bool:
    """After a failure: the outputs of the failed call (``pending`` = (its grid, the names of
    the grid times)) that lie before ``t_ok`` (the last time the bracketing reached),
    integrated again so that none is lost; True when one of them is on the singular set (the
    run stopped there)."""
    chunk, names = pending
    before = [gt for gt in chunk if start.t < gt <= t_ok]
    if not before:
        return False
    try:
        out = call.integrate("outputs", start, before)
    except RuntimeError:
        return False
    xf = np.asarray(out["xf"]).reshape(np.size(start.y), -1)
    zf = None if start.lam is None else np.asarray(out["zf"]).reshape(np.size(start.lam), -1)
    return _record_outputs(run, call, (before, names), xf, zf)


def _sundials_failure(run, call: _SundialsCall, start: _Start, err, pending: tuple) -> Run:
    """Bracket a SUNDIALS failure after ``start`` and classify it (singular set, max_steps,
    other); the failed call's outputs before the failure are kept (``pending``: its output
    times and their names), and the last state reached ends the trajectory, as on the other
    routes."""
    kind, watch = call.kind.upper(), call.watch
    reached, t_bad = _bracket_failure(call, start)
    if _outputs_before(run, call, start, reached.t, pending):
        return run
    last = run.last()
    if reached.t > (last[0] if last is not None else -np.inf):
        run.add(reached.t, call.segment.t_hi, call.segment.index, reached.y, reached.lam)
    run.y_fail, run.t_bad = reached.y, t_bad
    t_ok = reached.t
    if watch is not None and watch(reached.y) < WATCH * watch.tol:
        return run.fail(SINGULAR, t_ok, f"{kind} stopped between t = {t_ok:.9g} and "
                        f"t = {t_bad:.9g}, next to the singular set (measure "
                        f"{watch(reached.y):.3g} at t = {t_ok:.9g})")
    reason = str(err).splitlines()[-1].split(": ")[-1]
    if "TOO_MUCH_WORK" in reason:
        return run.fail(MAX_STEPS, t_ok, f"max_steps = {call.max_steps} (per output interval) reached "
                        f"between t = {t_ok:.9g} and t = {t_bad:.9g}")
    return run.fail(FAILED, t_ok, f"{kind} failed between t = {t_ok:.9g} and "
                    f"t = {t_bad:.9g}: {reason}")


def _bracket_failure(call: _SundialsCall, start: _Start, levels=2, pieces=16) -> tuple:
    """(the last point reached as a :class:`_Start`, the first time not reached): the failed
    interval [start.t, segment end] re-integrated piece by piece, twice refined (only on
    failure)."""
    b = call.segment.end
    for _ in range(levels):
        for t_next in np.linspace(start.t, b, pieces + 1)[1:]:
            try:
                out = call.integrate("bracket", start, [float(t_next)])
            except RuntimeError:
                b = float(t_next)
                break
            start = _Start(float(t_next), np.asarray(out["xf"]).ravel(),
                           None if start.lam is None else np.asarray(out["zf"]).ravel())
        else:
            return start, b
    return start, b


def _cvodes_problem(loop) -> dict:
    pc = loop._pieces
    t, y, p = pc["t"], pc["y"], pc["p"]
    t_hi = ca.SX.sym("t_hi")
    ydot = ca.substitute(pc["ydot"], pc["t_c"], ca.fmin(t, t_hi))
    return {"t": t, "x": y, "p": ca.vertcat(p, t_hi), "ode": ydot}
