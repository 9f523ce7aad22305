"""A previous answer as the first guess of a new plan (``nhgait plan --guess``, a sweep point
from its neighbour): :func:`read_solution` reads a ``solution.json`` as data, :func:`warm_start`
resamples any previous result onto a problem's grid in normalised time t/T.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["MAX_SOLUTION_BYTES", "read_solution", "warm_start"]

#: the largest solution.json read (bytes; the largest plans, with their feedback gains, write a
#: few MB)
MAX_SOLUTION_BYTES = 64 * 1024 * 1024


def read_solution(path) -> dict:
    """The content of a ``solution.json`` written by :func:`plan` (a dict), read as data
    (:func:`~nhgait.dynamics.derivation.textfiles.read_text_file`); a file that is not one is
    a :class:`~nhgait.dynamics.errors.ModelError` naming it."""
    import json

    from nhgait.dynamics.derivation.textfiles import read_text_file
    from nhgait.dynamics.errors import ModelError
    title = "cannot read the solution"
    text = read_text_file(path, "solution file", limit=MAX_SOLUTION_BYTES, title=title)
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise ModelError([f"solution file {path} is not JSON ({exc})"], title=title) from None
    if not isinstance(data, dict):
        raise ModelError([f"solution file {path} holds a JSON {type(data).__name__}, not the object "
                          "nhgait plan writes"], title=title)
    return data


def _trajectory_of(previous) -> tuple:
    """(t (K+1,), q (n × K+1), q̇ (n × K+1), u (m × K)) of a previous result of any kind."""
    from nhgait.ocp import Solution
    if hasattr(previous, "solution") and not isinstance(previous, Solution):     # a PlanResult
        previous = previous.solution
    if isinstance(previous, (str, Path)):
        previous = read_solution(previous)
    if isinstance(previous, Solution):
        n = len(previous.problem.model.system.coordinates)
        return previous.t, previous.states[:n], previous.velocities(), previous.controls
    tr = previous["trajectory"]
    return (np.asarray(tr["t"], float), np.asarray(tr["q"], float).T, np.asarray(tr["qdot"], float).T,
            np.asarray(tr["u"], float).T)


def warm_start(previous, problem, label: str = "warm start"):
    """An initial guess for ``problem`` from a previous solution (Solution, PlanResult,
    solution.json dict or path, or an InitialGuess), resampled on the problem's grid in
    normalised time t/T (configurations and velocities linearly, inputs piecewise constant)
    and mapped to the problem's state by the model's ``state(q, q̇)``."""
    from nhgait.ocp import InitialGuess
    if isinstance(previous, InitialGuess):
        return previous
    t, q, qdot, u = _trajectory_of(previous)
    grid = problem.grid()
    s_old, s_new = t / t[-1], grid / grid[-1]
    q_new = np.vstack([np.interp(s_new, s_old, row) for row in q])
    qd_new = np.vstack([np.interp(s_new, s_old, row) for row in qdot]) * (t[-1] / grid[-1])
    mid = (s_new[:-1] + s_new[1:]) / 2
    k = np.clip(np.searchsorted(s_old, mid, side="right") - 1, 0, u.shape[1] - 1)
    state = problem.model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q_new[:, j], qd_new[:, j], problem.params)).ravel()
                         for j in range(grid.size)])
    return InitialGuess(Z, u[:, k], horizon=float(grid[-1]), label=label)
