"""The compiled route: the closed loop's C library (:mod:`.compiled`) integrated by the explicit
Dormand–Prince scheme, one C call per interval; the step rows or the grid rows handed over as
arrays. Returns an :class:`~.integrators.Run`; never raises for a numerical failure.
"""
from __future__ import annotations

import math

import numpy as np

from .compiled import OutputBuffers, RunState
from .integrators import FAILED, MAX_STEPS, NONFINITE, SINGULAR, Run, RunRequest, grid_start

__all__ = ["integrate_compiled"]


_C_STATUS = {-1: FAILED, -2: MAX_STEPS, -3: NONFINITE, -4: NONFINITE, -5: SINGULAR}


def integrate_compiled(request: RunRequest, library, scheme: str, *, stop_on_stiff=False) -> Run:
    """Run the compiled integrator (:mod:`.compiled`, the closed loop's ``library``) interval by
    interval with the explicit Runge–Kutta ``scheme`` ("DOP853" or "DOPRI5"); the outputs of
    each C call are kept as arrays (no per-step Python)."""
    options = request.options
    segments, event_tol = request.segments, options.singular_tol
    run = Run()
    te = None if options.t_eval is None else np.ascontiguousarray(options.t_eval, dtype=float)
    state = RunState.start(segments[0][0], (options.rtol, options.atol),
                           (options.max_step, options.max_steps),
                           event_tol if (event_tol and library.has_event) else 0.0, stop_on_stiff)
    state.set("i_eval", grid_start(te, segments[0][0]))
    y = np.ascontiguousarray(request.y0, dtype=float).copy()
    buffers = OutputBuffers.for_steps(library.ny) if te is None else OutputBuffers.for_grid(te, library.ny)
    code, handed_over = 0, None
    for segment in request.intervals():
        t_hi, j = segment.t_hi, segment.index
        p = np.ascontiguousarray(segment.params, dtype=float)
        state.set("t", segment.start)
        first = state["i_eval"]
        if handed_over is buffers:
            buffers = buffers.fresh()
        while True:
            code = library.run(scheme, state, (segment.end, t_hi), y, p, buffers)
            if te is None:        # the rows become the run's: no later call writes into them
                n_out = state["n_out"]
                run.add_block(buffers.t_steps[:n_out], t_hi, j, buffers.y_steps[:n_out], copy=False)
                handed_over = buffers
            if code != 1:
                break
            buffers = buffers.grown()
        if te is not None:
            run.add_block(te[first:state["i_eval"]], t_hi, j, buffers.y_eval[first:state["i_eval"]])
        if code != 0:
            break
    _count_compiled(run, state)
    return _compiled_outcome(run, state, code, (te, segment, y), options.max_steps)


def _count_compiled(run: Run, state) -> None:
    values = state.values()
    run.nfev, run.n_steps, run.n_rejected = values["nfev"], values["accepted"], values["rejected"]
    run.h_lambda = values["h_lambda"]
    if not math.isnan(values["t_stiff"]):
        run.t_stiff = values["t_stiff"]


def _compiled_outcome(run: Run, state, code: int, end: tuple, max_steps: int) -> Run:
    """The run's status from the C return ``code``; ``end`` = (output grid or None, the last
    segment, the last state) closes the output at an event."""
    te, segment, y = end
    if code == -6:
        return run.fail(FAILED, state["t"], "stiff")
    if code not in _C_STATUS:
        return run
    t_fail = float(state["t_fail"])
    if code == -5 and te is not None:        # the event point itself closes the output
        run.add(t_fail, segment.t_hi, segment.index, y)
    if code == -2:
        return run.fail(MAX_STEPS, t_fail, f"max_steps = {max_steps} reached at t = {t_fail:.9g}")
    if code == -1:
        return run.fail(FAILED, t_fail, f"integration failed at t = {t_fail:.9g}: required step "
                        "size is less than 16 ulp of t")
    return run.fail(_C_STATUS[code], t_fail, "", bad=int(state["bad"]) if code == -3 else None)
