"""The result first (issue 40): ``nhgait plan`` prints its result line and writes solution.json
and trajectory.csv before it draws a figure; the figures follow in the same run."""
from __future__ import annotations

import json

from nhgait.gaits import plan_files, planner
from nhgait.gaits.cli.main import main
from nhgait.gaits.figures import plots


def test_the_planner_writes_through_plan_files():
    """The planner's writers are the plan files' (one implementation, issue 40)."""
    assert planner.written is plan_files.written
    assert planner.with_figures is plan_files.with_figures


def test_the_result_line_and_solution_json_exist_before_the_figures(tmp_path, capsys, monkeypatch):
    out = tmp_path / "plan"
    seen = {}
    draw = plots.write_figures

    def watched(solution, folder, **kwargs):
        """What the run had done when it came to the figures (then the figures themselves)."""
        seen["stdout"] = capsys.readouterr().out
        seen["files"] = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
        seen["solution"] = json.loads((out / "solution.json").read_text())
        return draw(solution, folder, **kwargs)

    monkeypatch.setattr(plots, "write_figures", watched)
    code = main(["plan", "unicycle", "--gait", "parallel-park", "--intervals", "25", "--no-jit",
                 "--quiet", "--out", str(out)])
    after = capsys.readouterr().out
    assert code == 0, seen.get("stdout", "") + after
    assert seen["stdout"].startswith("nhgait plan unicycle/parallel-park: SUCCESS")
    assert "objective          J = " in seen["stdout"]
    assert seen["files"] == ["solution.json", "trajectory.csv"]          # no figure yet
    assert seen["solution"]["success"] is True
    # the objective printed is the one written (the solution.json the line describes)
    printed = float(seen["stdout"].split("J = ")[1].split()[0])
    assert abs(printed - seen["solution"]["objective"]) <= 5e-7 * max(1.0, abs(printed))
    for name in ("path.png", "shape.png", "histories.png", "momentum.png"):
        assert (out / name).stat().st_size > 1000
        assert str(out / name) in after                                  # listed after the result
    assert not (out / "motion.gif").exists()                             # the animation only on request
