"""What ``nhgait plan`` prints about a :class:`~.planner.PlanResult`: :func:`summary_lines` —
the result line, the objective and solve, each verification check, the grid, solver and compiled
code, the feedback, the symmetry, the files and the figures, and where the wall time went."""
from __future__ import annotations

from .files.exports import states_text
from .planner import PlanResult
from .verification.checks import open_loop_label, solution_check_lines

__all__ = ["summary_lines"]


def summary_lines(result: PlanResult) -> list:
    """The lines ``nhgait plan`` prints."""
    s = result.solution
    if s is None:             # the budget ran out before any attempt
        lines = [f"nhgait plan {result.label}: FAILED (time budget spent)", "  no attempt was made"]
        return lines + _closing_lines(result)
    v = s.verification
    status = "time budget spent; closest point: " + s.status if result.overrun is not None else s.status
    lines = [f"nhgait plan {result.label}: {'SUCCESS' if result.success else 'FAILED'} ({status})",
             f"  objective          J = {s.objective:.6f}",
             f"  iterations         {s.iterations}  (guess: {result.guess}; tried {len(result.attempts)})",
             f"  solve time         {s.solve_time_s * 1e3:.1f} ms  (functions "
             f"{s.function_time_s * 1e3:.1f} ms, "
             f"solver {s.solver_time_s * 1e3:.1f} ms); set-up {s.setup_time_s * 1e3:.1f} ms"]
    if v is not None:
        lines.append(f"  {open_loop_label(s)}{'passed' if v.passed else 'FAILED'}: max state error "
                     f"{v.max_error:.2e}, conditions met to {v.max_condition_error:.2e}; relative to each "
                     f"state's range {v.max_scaled_error:.2e}, {v.max_scaled_condition_error:.2e} (tolerance "
                     f"{v.tolerance:g}; DOP853, rtol {v.rtol:g})")
    else:
        lines.append("  verification       not run")
    lines += [f"  {line}" for line in solution_check_lines(s)]              # issue 41
    st = s.settings
    lines.append(f"  N = {st.get('intervals')}, T = {s.horizon:.4f} s, {st.get('transcription')}, "
                 f"{st.get('solver')}, {st.get('hessian', 'exact')} Hessian, {_compiled_text(st)}, "
                 f"{states_text(s)}")
    lines += [f"  conditions         {line}"
              for line in (result.conditions.lines() if result.conditions else ())]
    if s.feedback is not None:                                               # issue 28
        lines.append(f"  feedback           time-varying LQR, {s.feedback.gains.shape[0]} gains "
                     f"{s.feedback.gains.shape[1]}×{s.feedback.gains.shape[2]} in solution.json; "
                     "nhgait track applies it to a robot that differs")
    if s.stability is not None:
        lines += [f"  stability          {line}" for line in s.stability.summary()]
    if st.get("robust"):                                                     # [task.robust]
        from .planning.robust import summary_line
        lines.append(f"  robust             {summary_line(st['robust'])}")
    symmetry = getattr(result.model, "symmetry", None)
    if symmetry is not None:
        lines.append(f"  symmetry           {symmetry.chosen.group} moves the fibre "
                     f"({', '.join(result.model.fiber)}); "
                     f"the guesses loop the shape ({', '.join(result.model.shape)}); why, and the "
                     "other choices (fiber = [...] in [system]): nhgait derive")
    checked = getattr(s.problem, "model", None)
    if symmetry is not None and checked is not None and not hasattr(checked, "fiber"):
        lines.append("  verified in        x = (q, q̇) on the Euler–Lagrange equations: the gait crosses "
                     "the singular set of every chart of the reduction tried")
    elif symmetry is not None and checked is not None and tuple(checked.fiber) != tuple(result.model.fiber):
        lines.append(f"  verified in        the chart with fiber ({', '.join(checked.fiber)}): the gait "
                     "crosses the "
                     f"singular set of fiber ({', '.join(result.model.fiber)}), where its momenta "
                     "are not defined")
    return lines + _closing_lines(result)


def _closing_lines(result: PlanResult) -> list:
    """The diagnosis and the files written."""
    lines = []
    if result.diagnosis:
        lines.append("  why:")
        lines.extend(f"    {line}" for line in result.diagnosis)
    if result.unwritten:
        lines.append(f"  files              NOT WRITTEN: {result.unwritten}")
    if result.files:
        lines.append("  files:")
        lines.extend(f"    {f}" for f in result.files)
        if result.success and not any(str(f).endswith(".gif") for f in result.files):
            lines.append("  animation          not written (made on request): add --gif "
                         "(plan(..., animate=True)) to write motion.gif")
    if result.overrun is not None:
        lines.append("  figures            not written: the time budget was spent")
    return lines


def _compiled_text(settings) -> str:
    """Which code solved and what was started for later (:class:`~nhgait.ocp.nlp_code.CompileReport`)."""
    c = settings.get("compile") or {}
    later = c.get("later") or {}
    after = ""
    if later.get("summary"):
        after = f"; {later['summary']}"
    if not settings.get("jit"):
        reason = settings.get("jit_fallback")
        return "interpreted" + (f" ({reason}{after})" if reason else (f" ({after[2:]})" if after else ""))
    size = f"{c.get('c_bytes', 0) / 1e6:.2f} MB of C"
    if c.get("code") == "fast":
        return f"compiled fast ({c.get('compiler')}, {size}, {c.get('compile_s', 0):.2f} s{after})"
    size += f", {' '.join(c.get('flags') or [])}"
    if c.get("switched_from"):
        return (f"compiled ({size}, built in the background during this plan; the attempts before it ran "
                f"{c['switched_from']})")
    return f"compiled ({size}" + (", cached)" if settings.get("jit_cached")
                                  else f", {c.get('compile_s', 0):.1f} s)")
