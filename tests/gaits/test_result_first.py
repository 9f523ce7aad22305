"""The result first (issue 40): ``nhgait plan`` prints its result line and writes solution.json
and trajectory.csv before a figure is in its output directory; the figures, drawn while the
gait is verified, follow in the same run, and no process of the plan outlives it."""
from __future__ import annotations

import json
import os

from nhgait.gaits import plan_files, planner
from nhgait.gaits.cli.main import main
from nhgait.gaits.files import outputs

PLAN = ["plan", "unicycle", "--gait", "parallel-park", "--intervals", "25", "--no-jit", "--quiet"]
FIGURES = ("path.png", "shape.png", "histories.png", "momentum.png", "convergence.png")


def test_the_planner_writes_through_plan_files():
    """The planner's writers are the plan files' (one implementation, issue 40)."""
    assert planner.written is plan_files.written
    assert planner.with_figures is plan_files.with_figures


def _children(pid: int) -> list:
    """The live processes whose parent is ``pid`` (Linux /proc; elsewhere none)."""
    found = []
    try:
        entries = [e.name for e in os.scandir("/proc") if e.name.isdigit()]
    except OSError:
        return found
    for entry in entries:
        try:
            with open(f"/proc/{entry}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.append(int(entry))
    return found


def test_the_result_line_and_solution_json_exist_before_the_figures(tmp_path, capsys, monkeypatch):
    """Every file reaches ``out`` by one rename (``outputs.move_into``); at the first rename of a
    figure the result line is printed and solution.json is in place, and no figure is there."""
    out = tmp_path / "plan"
    moves = []
    move = outputs.move_into

    def watched(folder, paths):
        """What the run had done when these files were moved into ``folder``."""
        names = [os.path.basename(str(p)) for p in paths]
        if any(name.endswith(".png") for name in names):
            moves.append({"names": names, "stdout": capsys.readouterr().out,
                          "present": sorted(p.name for p in out.iterdir() if not p.name.startswith(".")),
                          "solution": json.loads((out / "solution.json").read_text())})
        return move(folder, paths)

    monkeypatch.setattr(outputs, "move_into", watched)
    before = set(_children(os.getpid()))
    code = main([*PLAN, "--out", str(out)])
    after = capsys.readouterr().out
    assert code == 0, (moves[0]["stdout"] if moves else "") + after
    first = moves[0]
    assert first["stdout"].startswith("nhgait plan unicycle/parallel-park: SUCCESS")
    assert "objective          J = " in first["stdout"]
    assert first["present"] == ["solution.json", "trajectory.csv"]          # no figure yet
    assert first["solution"]["success"] is True
    # the objective printed is the one written (the solution.json the line describes)
    printed = float(first["stdout"].split("J = ")[1].split()[0])
    assert abs(printed - first["solution"]["objective"]) <= 5e-7 * max(1.0, abs(printed))
    for name in FIGURES:
        assert (out / name).stat().st_size > 1000
        assert str(out / name) in after                                  # listed after the result
    assert not (out / "motion.gif").exists()                             # the animation only on request
    assert not [p for p in out.iterdir() if p.name.startswith(outputs.STAGING_PREFIX)]   # no staging left
    assert set(_children(os.getpid())) <= before                         # no figure process left running


def test_figures_drawn_ahead_of_a_gait_that_fails_its_verification_are_drawn_again(tmp_path, monkeypatch):
    """The figures drawn while the gait is verified show the converged gait; when the verified
    result is another (here: its verification fails), they are drawn again, titled FAILED, and
    those drawn ahead are not used."""
    from dataclasses import replace

    from nhgait.gaits.figures import plots
    from nhgait.gaits.verification import gait_check
    log = tmp_path / "titles.txt"
    figure = plots.gait_figure

    def titled(solution, ctx, layout, failed=None):
        """Each figure's title, appended to ``log`` by the child process that draws it."""
        with open(log, "a") as fh:
            fh.write(f"{layout.name}: {'FAILED' if failed else 'converged'}\n")
        return figure(solution, ctx, layout, failed)

    def refused(solution, opened, checks):
        """The deciding checks as failed, whatever they found."""
        return replace(opened, success=False, status="Verification_Failed",
                       message="the verification failed (test)")
    monkeypatch.setattr(plots, "gait_figure", titled)
    monkeypatch.setattr(gait_check, "decided", refused)
    out = tmp_path / "failed"
    result = planner.plan("unicycle", "parallel-park", intervals=25, jit=False, out_dir=out)
    assert not result.success
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert names == sorted(["solution.json", "trajectory.csv", *FIGURES])
    drawn = sorted(log.read_text().splitlines())
    assert drawn == sorted([f"{name}: {title}" for name in FIGURES[:4] for title in ("converged", "FAILED")])
    assert not [p for p in out.iterdir() if p.name.startswith(outputs.STAGING_PREFIX)]
