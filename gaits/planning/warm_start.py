"""A previous answer as the first guess of a new plan (``nhgait plan --guess``, a sweep point
from its neighbour): :func:`previous_answer` takes any previous result (a ``solution.json``
read as data and checked by :mod:`.solution_file`) and refuses one of another robot,
:func:`warm_start` resamples it onto a problem's grid in normalised time.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files.solution_file import GUESS_TITLE, MAX_SOLUTION_BYTES, PreviousTrajectory, read_solution

__all__ = ["MAX_SOLUTION_BYTES", "read_solution", "previous_answer", "warm_start"]


def _of_solution(solution) -> PreviousTrajectory:
    """The trajectory of a :class:`~nhgait.ocp.Solution` (its own names; trusted)."""
    from nhgait.ocp.problem import model_coordinates
    coordinates = model_coordinates(solution.problem.model)
    return PreviousTrajectory(t=solution.t, q=solution.z[:, :len(coordinates)].T, qdot=solution.velocities(),
                              u=solution.u.T, coordinates=coordinates,
                              inputs=tuple(solution.problem.control_names), system=solution.problem.name)


def _source(previous) -> str:
    """How messages name a previous answer: its file, else "the guess"."""
    return f"the guess {previous}" if isinstance(previous, (str, Path)) else "the guess"


def _trajectory_of(previous) -> PreviousTrajectory:
    """The checked trajectory of a previous result of any kind (one ProblemError listing every
    problem of a solution.json's trajectory)."""
    from nhgait.ocp import ProblemError, Solution

    from ..files.solution_file import previous_trajectory
    if isinstance(previous, PreviousTrajectory):
        return previous
    if hasattr(previous, "solution") and not isinstance(previous, Solution):     # a PlanResult
        previous = previous.solution
    if isinstance(previous, Solution):
        return _of_solution(previous)
    if isinstance(previous, (str, Path)):
        return previous_trajectory(read_solution(previous), _source(previous))
    if isinstance(previous, dict):
        return previous_trajectory(previous, _source(previous))
    raise ProblemError([f"a guess must be a Solution, a PlanResult, a solution.json (its path or its "
                        f"content) or an InitialGuess, got a {type(previous).__name__}"], title=GUESS_TITLE)


def previous_answer(previous, coordinates, inputs, label: str):
    """``previous`` (as :func:`warm_start` takes it) checked for the robot with ``coordinates``
    and ``inputs`` (``label``: its name in messages), before any derivation: a
    :class:`~nhgait.gaits.files.solution_file.PreviousTrajectory` (an InitialGuess as it is). One
    :class:`~nhgait.ocp.ProblemError` lists every problem of its form, or says that it is
    another robot's."""
    from nhgait.ocp import InitialGuess, ProblemError

    from ..files.solution_file import robot_problems
    if isinstance(previous, InitialGuess):
        return previous
    trajectory = _trajectory_of(previous)
    problems = robot_problems(trajectory, coordinates, inputs, label, _source(previous))
    if problems:
        raise ProblemError(problems, title=GUESS_TITLE)
    return trajectory


def warm_start(previous, problem, label: str = "warm start"):
    """An initial guess for ``problem`` from a previous solution (Solution, PlanResult,
    solution.json dict or path, checked :func:`previous_answer`, or an InitialGuess),
    resampled on the problem's grid in normalised time (t − t₀)/(t_K − t₀) (configurations and
    velocities linearly, inputs piecewise constant) and mapped to the problem's state by the
    model's ``state(q, q̇)``. A previous answer of another robot, or one whose trajectory is
    not well formed, is one :class:`~nhgait.ocp.ProblemError`."""
    from nhgait.ocp import InitialGuess
    from nhgait.ocp.problem import model_coordinates
    if isinstance(previous, InitialGuess):
        return previous
    previous = previous_answer(previous, model_coordinates(problem.model), problem.control_names,
                               problem.name or "this task")
    t, q, qdot, u = previous.t, previous.q, previous.qdot, previous.u
    grid = problem.grid()
    duration = t[-1] - t[0]
    s_old, s_new = (t - t[0]) / duration, grid / grid[-1]
    q_new = np.vstack([np.interp(s_new, s_old, row) for row in q])
    qd_new = np.vstack([np.interp(s_new, s_old, row) for row in qdot]) * (duration / grid[-1])
    mid = (s_new[:-1] + s_new[1:]) / 2
    k = np.clip(np.searchsorted(s_old, mid, side="right") - 1, 0, u.shape[1] - 1)
    state = problem.model.numeric["state"]
    Z = np.column_stack([np.asarray(state(q_new[:, j], qd_new[:, j], problem.params)).ravel()
                         for j in range(grid.size)])
    return InitialGuess(Z, u[:, k], horizon=float(grid[-1]), label=label)
