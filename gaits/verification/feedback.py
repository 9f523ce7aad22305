"""What :func:`~nhgait.gaits.planner.plan` stores with a converged plan beyond the trajectory:
the time-varying LQR along it (:mod:`nhgait.ocp.feedback`, in the plan's own velocity
coordinates) and, for a periodic plan, the monodromy matrices and Floquet multipliers of the
open and the closed loop over one period (:mod:`nhgait.ocp.floquet`). Both go to
``solution.json`` (``feedback``, ``stability``); ``nhgait track`` (:mod:`nhgait.gaits.tracking`)
applies the feedback to the robot.
"""
from __future__ import annotations

__all__ = ["feedback_and_stability"]


def feedback_and_stability(solution, progress) -> dict:
    """{"feedback": Feedback[, "stability": Stability]} of a converged ``solution`` in the
    problem's own state (the planner's velocity coordinates)."""
    from nhgait.ocp.feedback import design_feedback
    from nhgait.ocp.floquet import stability
    from nhgait.ocp.transcription import ode_function
    problem = solution.problem
    with progress.phase("feedback: time-varying LQR on the plan's stage Jacobians"):
        feedback = design_feedback(problem, solution.t, solution.z.T, solution.u.T,
                                   steps=int(solution.settings.get("rk4_steps", 4)))
    out = {"feedback": feedback}
    if problem.periodic:
        with progress.phase("stability: monodromy matrices of the open and the closed loop over one period"):
            try:
                out["stability"] = stability(ode_function(problem), feedback,
                                             fiber=getattr(problem.model, "fiber", ()))
            except RuntimeError as exc:        # CVODES gave up on the variational equations
                progress.note("  not computed: the variational equations could not be integrated over the "
                              f"period ({str(exc).splitlines()[0][:160]})")
                return out
        for line in out["stability"].summary():
            progress.note(f"  {line}")
    return out
