"""Short ``repr`` s and notebook Markdown for nhgait's result objects.

A result prints in a few lines what a user checks first — what it is, its shape, the time span,
whether it succeeded — and where the arrays are (``traj.q (201, 4)``), never the arrays
themselves::

    <Trajectory sleigh_slider: reduced, compiled DOP853, success, t = 0 … 4 s (81 samples)
     arrays: t (81,), q (81, 4), qdot (81, 4), state (81, 7), u (81, 2); 620 evaluations>

``*_markdown`` give the ``_repr_markdown_`` of models and solutions (Jupyter renders them as a
table and the equations). No sympy, numpy only: every layer may import this module.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ModelDisplay", "shape_of", "arrays_text", "trajectory_repr", "model_repr", "model_markdown",
           "solution_repr", "solution_markdown", "plan_repr", "sweep_repr"]


def shape_of(value) -> str:
    """``(81, 4)`` or ``(81,)`` for an array, ``-`` for None."""
    if value is None:
        return "-"
    return str(tuple(np.shape(value)))


def arrays_text(obj, names) -> str:
    """``t (81), q (81, 4)`` for the attributes ``names`` of ``obj`` that are set."""
    return ", ".join(f"{n} {shape_of(getattr(obj, n))}" for n in names if getattr(obj, n, None) is not None)


def _span(t) -> str:
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return "no samples"
    return f"t = {t[0]:.4g} … {t[-1]:.4g} s ({t.size} samples)"


def _status(success, message="") -> str:
    return "success" if success else f"FAILED ({message[:80]})" if message else "FAILED"


def trajectory_repr(traj) -> str:
    name = getattr(traj, "settings", {}).get("system", "")
    head = f"<Trajectory{' ' + name if name else ''}: {traj.formulation}, {traj.method}, " \
           f"{_status(traj.success, traj.message)}, {_span(traj.t)}"
    arrays = arrays_text(traj, ("t", "q", "qdot", "state", "u", "lam"))
    return f"{head}\n arrays: {arrays}; coordinates ({', '.join(traj.coordinates)}); {traj.nfev} evaluations>"


def model_repr(model) -> str:
    """One line: kind, system, dimension, state names."""
    kind = type(model).__name__
    return (f"<{kind} of {model.system.name}: {model.dimension} states z = ({', '.join(model.state_names)}); "
            "model.to_text() prints the equations>")


def model_markdown(model) -> str:
    """A table (system, form, state, fibre/shape) and the equations in a code block."""
    rows = [("system", model.system.name), ("formulation", model.formulation),
            ("state", ", ".join(model.state_names)), ("dimension", str(model.dimension))]
    if getattr(model, "fiber", None) is not None:
        rows += [("fibre (group) coordinates", ", ".join(model.fiber)),
                 ("shape coordinates", ", ".join(model.shape) or "none"),
                 ("classification", model.classification)]
    table = "| | |\n|---|---|\n" + "\n".join(f"| {a} | {b} |" for a, b in rows)
    return f"**{type(model).__name__}** of `{model.system.name}`\n\n{table}\n\n```\n{model.to_text()}\n```\n"


def _checked(solution) -> str | None:
    """How an unstable gait was verified (``settings["checks"]``, nhgait.gaits.verification.checks),
    None when the open loop decides."""
    checks = (getattr(solution, "settings", None) or {}).get("checks") or {}
    if checks.get("decided_by") != "interval and closed loop":
        return None
    worst = max(checks["interval"]["error"] or float("inf"), checks["closed_loop"]["error"] or float("inf"))
    return (f"verified by the interval and closed-loop checks to {worst:.2g} (unstable: open loop reported)"
            if checks.get("passed") else f"verification FAILED (interval and closed loop: {worst:.2g})")


def solution_repr(solution) -> str:
    v = solution.verification
    verified = "not verified" if v is None else (f"verified to {v.max_error:.2g}" if v.passed
                                                 else f"verification FAILED ({v.max_error:.2g})")
    verified = _checked(solution) or verified
    return (f"<Solution: {_status(solution.success, solution.status)}, J = {solution.objective:.6g}, "
            f"{solution.iterations} iterations, {verified}, {_span(solution.t)}, horizon "
            f"{solution.horizon:.4g} s\n"
            f" arrays (time first): t {shape_of(solution.t)}, z {shape_of(solution.z)} columns "
            f"({', '.join(solution.state_names)}), u {shape_of(solution.u)} columns "
            f"({', '.join(solution.control_names)})>")


def solution_markdown(solution) -> str:
    v = solution.verification
    rows = [("status", _status(solution.success, solution.status)),
            ("objective J", f"{solution.objective:.6g}"),
            ("iterations", str(solution.iterations)), ("horizon", f"{solution.horizon:.4g} s"),
            ("solve time", f"{solution.solve_time_s * 1e3:.1f} ms"),
            ("verification", "not run" if v is None
             else _checked(solution) or f"{'passed' if v.passed else 'FAILED'}, max error {v.max_error:.2g}"),
            ("states", f"`solution.z` {shape_of(solution.z)}: {', '.join(solution.state_names)}"),
            ("controls",
             f"`solution.u` {shape_of(solution.u)}: {', '.join(solution.control_names)}")]
    return "**Solution**\n\n| | |\n|---|---|\n" + "\n".join(f"| {a} | {b} |" for a, b in rows) + "\n"


def plan_repr(result) -> str:
    files = f"{len(result.files)} files in {result.files[0].parent}" if result.files else "no files written"
    solution = solution_repr(result.solution) if result.solution is not None else None
    return (f"<PlanResult {result.label}: {'SUCCESS' if result.success else 'FAILED'}, guess "
            f"{result.guess!r} of {len(result.attempts)} tried, {files}\n solution: {solution}>")


def sweep_repr(result) -> str:
    solved = sum(1 for r in result.records if r.success)
    axes = ", ".join(f"{a.name} ({len(a)})" for a in result.grid.axes)
    return (f"<SweepResult {result.case.get('label', '')}: {solved} of "
            f"{int(np.prod(result.grid.shape))} points "
            f"solved and verified, grid {shape_of(np.empty(result.grid.shape))} over {axes}; "
            f"{result.directory}; result.objectives() is the grid of costs>")


class ModelDisplay:
    """``dimension``, ``repr`` and notebook Markdown shared by the derived models (Lagrange and
    Hamilton DAEs, the reduced ODE): their dataclasses say ``repr=False`` so these are used."""

    __slots__ = ()

    @property
    def dimension(self) -> int:
        return len(self.state)

    def __repr__(self) -> str:
        return model_repr(self)

    def _repr_markdown_(self) -> str:
        return model_markdown(self)
