"""What produced a failure: the time and the quantity (the state, the controller's input, a
force τ_i and its expression, the right-hand side) behind a run that stopped, for the
message of :class:`~.trajectory.Trajectory` (:func:`diagnose_failure`). Evaluated only after a
failure, never on the way of a successful run.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .integrators import NONFINITE, RunRequest, left_of

__all__ = ["diagnose_failure"]


def diagnose_failure(model, request: RunRequest, run) -> None:
    """Name the time and the quantity behind a failure; a failure caused by a non-finite value
    becomes status NONFINITE."""
    segments = request.segments
    last = run.last()
    t = run.t_fail if run.t_fail is not None else (last[0] if last else segments[0][0])
    j = last[1] if last else 0
    y = run.y_fail if run.y_fail is not None else (last[2] if last else request.y0)
    if run.y_fail is not None and run.t_bad is not None:
        j = int(np.searchsorted([b for _, b in segments], run.t_bad))
        j = min(j, len(segments) - 1)
    found = None
    probes = [t, np.nextafter(t, np.inf), t + 1e-9 * max(1.0, abs(t)), t + 1e-6 * max(1.0, abs(t))]
    probes += [] if run.t_bad is None else [run.t_bad]
    for tt in probes:
        if tt > segments[-1][1]:
            break
        found = _nonfinite_source(model, request, (float(tt), y, j), run.bad)
        if found:
            break
    if found:
        run.status = NONFINITE
        run.message = f"stopped at t = {t:.9g}: {found}"
    elif not run.message:
        run.message = f"integration failed at t = {t:.9g}"


def _nonfinite_source(model, request: RunRequest, point: tuple, bad) -> str | None:
    """A sentence naming the first non-finite quantity at ``point`` = (t, y, segment index),
    or None (``bad``: the index of a non-finite entry of ẏ the integrator reported, if any)."""
    system, loop, controller = model.system, request.loop, request.controller
    t, y, j = point
    p, t_hi = request.seg_params[j], left_of(request.segments[j][1])
    if _bad(y) is not None:
        return f"the state entry {_y_name(model, loop, _bad(y))} is non-finite"
    tc = min(t, t_hi)
    qdot = np.asarray(loop.qdot(y, p)).ravel()
    q = _full_q(model, loop, y)
    with np.errstate(all="ignore"):
        if controller is not None:
            if loop.symbolic_u or loop.segment_u:
                u = np.asarray(loop.outputs(t, tc, y, p)[5]).ravel()
            else:
                u = np.asarray(controller(tc, q, qdot), dtype=float).ravel()
            if _bad(u) is not None:
                name = system.inputs[_bad(u)]
                return (f"the controller {type(controller).__name__} returned a non-finite input "
                        f"{name} = {u[_bad(u)]} at t = {t:.9g}")
        else:
            u = np.zeros(len(system.inputs))
        tau = _force_values(system, (t, q, qdot, u), p[:loop.n_params])
    if tau is not None and _bad(tau) is not None:
        i = _bad(tau)
        return (f"the force on {system.coordinates[i]}, τ = {system.tau[i]}, is {tau[i]} at "
                f"t = {t:.9g}")
    args = [t, tc, y] + ([u] if request.python_inputs else []) + [p]
    with np.errstate(all="ignore"):
        ydot = np.asarray(loop.rhs(*args)).ravel()
    if _bad(ydot) is not None or bad is not None:
        i = _bad(ydot) if _bad(ydot) is not None else bad
        return (f"the right-hand side d/dt {_y_name(model, loop, i)} is non-finite at t = {t:.9g}"
                + (" (the state is near the singular set)" if loop.event is not None and
                   float(np.asarray(loop.event(y, np.zeros_like(y), p)[0]).ravel()[0]) < 1e-6
                   else ""))
    return None


def _bad(v) -> int | None:
    bad = np.flatnonzero(~np.isfinite(np.asarray(v, dtype=float).ravel()))
    return int(bad[0]) if bad.size else None


def _y_name(model, loop, i) -> str:
    names = [model.state_names[k] for k in loop.state_index] + ["work"] * loop.has_work
    names += [f"integral of constraint {k + 1}" for k in range(loop.n_int)]
    return names[i] if i < len(names) else f"y[{i}]"


def _full_q(model, loop, y) -> np.ndarray:
    q = np.full(loop.n_q, np.nan)
    for j, i in enumerate(loop.state_index):
        if i < loop.n_q:
            q[i] = y[j]
    return q


def _force_values(system, point: tuple, params):
    """τ(t, q, q̇, u) at ``point`` = (t, q, q̇, u) from the system's force expressions
    (evaluated only to explain a failure)."""
    t, q, qdot, u = point
    from ..derivation.system import TIME
    from ..numerics.bridge import to_casadi
    syms = ([TIME] + list(system.q) + list(system.q_dot) + list(system.input_symbols)
            + list(system.param_symbols))
    values = [t] + list(q) + list(qdot) + list(u) + list(params)
    try:
        sx = [ca.SX.sym(f"a{i}") for i in range(len(syms))]
        f = ca.Function("tau", sx, to_casadi(list(system.tau), syms, sx))
        return np.array([float(v) for v in f(*values)])
    except Exception:  # a diagnostic must never replace the run's own message
        return None
