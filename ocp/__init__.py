"""nhgait.ocp — optimal control of reduced ODEs: statement, transcription, solver, solution.

Layers (each imports only the ones before it; none imports sympy):

* :mod:`.statement` — :class:`ProblemStatement`: the fields of a problem and their validators, no model;
* :mod:`.problem` — :class:`OptimalControlProblem` (what to solve: a statement bound to a model);
* :mod:`.transcription` — :class:`MultipleShooting` (RK4, default), :class:`Collocation`;
* :mod:`.solver` — :class:`OCPSolver` / :func:`solve` (Ipopt by default here, FATROP on a stage-ordered
  transcription; optional cached jit — ``nhgait.gaits.planner.plan`` tries FATROP first);
* :mod:`.solution` — :class:`Solution` (data, with ``verify()`` and ``to_json()``);
* :mod:`.scenarios` — :class:`Scenarios`, :class:`ScenarioShooting`: robust planning, copies of the
  state under other parameter values driven by the same inputs.

Example::

    from nhgait.ocp import OptimalControlProblem, InitialGuess, solve
    problem = OptimalControlProblem(model, horizon=4.0, intervals=50,
                                    initial={n: 0.0 for n in model.state_names},
                                    final={"x": 0.0, "y": 0.5, "theta": 0.0, "p": 0.0, "pt_theta": 0.0},
                                    control_bounds=5.0)
    solution = solve(problem, InitialGuess(states, controls)).verified()
"""
from __future__ import annotations

from nhgait.lazy import lazy_getattr

_EXPORTS = {
    "OptimalControlProblem": "problem", "Quantity": "problem", "ProblemError": "problem",
    "ProblemStatement": "statement",
    "MultipleShooting": "transcription", "Collocation": "transcription", "TranscribedNLP": "transcription",
    "get_transcription": "transcription",
    "SolverOptions": "solver", "OCPSolver": "solver", "solve": "solver", "InitialGuess": "solver",
    "Solution": "solution", "Verification": "solution",
    "Scenarios": "scenarios", "ScenarioShooting": "scenarios",
}

__all__ = sorted(_EXPORTS)

__getattr__ = lazy_getattr(__name__, _EXPORTS)
