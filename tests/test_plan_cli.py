"""`nhgait plan` end to end (a user's scene file, --set, a built-in gait, errors) and the figures
for any robot (units from the scene, legends, no global matplotlib state, the [drawing] table)."""
from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import matplotlib
import numpy as np
import pytest

from nhgait.gaits.cli.main import main

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parents[1]
SLEIGH = str(ROOT / "examples" / "rotor_sleigh.toml")


def test_plan_a_scene_file_with_an_override(tmp_path, capsys):
    out = tmp_path / "sleigh"
    code = main(["plan", SLEIGH, "--set", "final.x=0.8", "--intervals", "50", "--no-jit", "--gif",
                 "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "SUCCESS" in text
    assert "conditions met to" in text
    assert "rotor_sleigh/forward-1m" in text
    data = json.loads((out / "solution.json").read_text())
    assert data["task"]["final"]["x"] == 0.8
    assert data["task"]["intervals"] == 50
    q = np.array(data["trajectory"]["q"])
    assert q[-1, 0] == pytest.approx(0.8, abs=1e-8)
    assert data["verification"]["max_condition_error"] < 1e-6
    for name in ("path.png", "shape.png", "histories.png", "momentum.png", "motion.gif"):
        assert (out / name).stat().st_size > 1000


def test_a_plan_refined_from_a_previous_answer(tmp_path, capsys):
    """--guess: the N = 25 answer resampled onto N = 50 is tried first and wins; the refined
    optimum is the one the planner reaches on its own at N = 50 (same local optimum)."""
    coarse, fine, alone = tmp_path / "coarse", tmp_path / "fine", tmp_path / "alone"
    common = ["--set", "final.x=0.8", "--no-jit"]
    assert main(["plan", SLEIGH, *common, "--intervals", "25", "--out", str(coarse)]) == 0
    assert main(["plan", SLEIGH, *common, "--intervals", "50", "--guess", str(coarse / "solution.json"),
                 "--out", str(fine)]) == 0
    assert main(["plan", SLEIGH, *common, "--intervals", "50", "--out", str(alone)]) == 0
    capsys.readouterr()
    refined, own = (json.loads((d / "solution.json").read_text()) for d in (fine, alone))
    assert refined["guess"]["won"] == "warm start"
    assert refined["task"]["intervals"] == 50
    assert refined["objective"] == pytest.approx(own["objective"], rel=1e-6)


def test_builtin_gait_as_in_make_demo(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["plan", "snakeboard", "--gait", "forward", "--intervals", "25", "--no-jit",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    # the GIF is made on request only (make demo stays fast), and the summary says so
    assert not (out / "motion.gif").exists()
    assert "add --gif" in text
    wall = re.search(r"wall time +([0-9.]+) s in all: model ([0-9.]+) s, .* verification ([0-9.]+) s", text)
    # parts of the whole
    assert wall
    assert float(wall.group(1)) >= float(wall.group(2)) + float(wall.group(3)) - 0.1
    data = json.loads((out / "solution.json").read_text())
    assert data["objective"] == pytest.approx(0.110252, rel=1e-4)       # hand-written reference, N = 25
    assert data["settings"]["solver"] == "fatrop"  # the default: auto
    assert data["guess"]["won"]
    assert data["guess"]["tried"][0]["solver"] == "fatrop"


def test_plan_errors_are_one_message(tmp_path, capsys):
    scene = tmp_path / "robot.toml"
    scene.write_text('[system]\ncoordinates = ["x"]\nlagrangian = "m*x_dot**2/2"\ninputs = ["F"]\n'
                     '[system.forces]\nx = "F"\n[system.parameters]\nm = 1.0\n')
    assert main(["plan", str(scene), "--out", str(tmp_path / "o")]) == 2
    assert "has no [task] table" in capsys.readouterr().err
    # a scene file whose robot is named like a built-in scene is not offered its gaits (--gait
    # refuses them for a file)
    scene.write_text(scene.read_text().replace("[system]", '[system]\nname = "snakeboard"'))
    assert main(["plan", str(scene), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "has no [task] table: add one (docs/gait-planning.md)\n" in err and "--gait" not in err
    code = main(["plan", SLEIGH, "--set", "final.zz=1", "--set", "bounds.alpha=2,1", "--no-jit",
                 "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    # the form and the names are checked together: one message with both problems
    assert code == 2
    assert "contradictory range" in err
    assert "unknown name 'zz'" in err
    assert "2 problem(s)" in err


# ----------------------------------------------------------------------------- figures
@pytest.fixture(scope="module")
def car_solution():
    from nhgait.gaits.planner import plan
    result = plan(str(ROOT / "examples" / "car.toml"), intervals=20, jit=False, verify=False)
    return result


def _ctx(result):
    from nhgait.gaits.figures.plots import figure_context
    return figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)


def test_plots_use_the_scene_units_and_leave_global_state(car_solution):
    import matplotlib.pyplot as plt

    from nhgait.gaits.figures import plots
    before = dict(matplotlib.rcParams)
    ctx = _ctx(car_solution)
    fig, axes = plt.subplots(3, 1)
    plots.plot_histories(car_solution.solution, ctx, axes=axes)
    ylabels = [ax.get_ylabel() for ax in axes]
    assert ylabels[0] == "shape φ [rad]"
    assert "input [N]" in ylabels
    assert "input [N·m]" in ylabels
    fig2, ax = plt.subplots()
    plots.plot_path(car_solution.solution, ctx, ax=ax)
    assert ax.get_xlabel() == "x [m]"
    assert ax.get_ylabel() == "y [m]"
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("colour: time" in t for t in legend)
    assert any(t.startswith("start") for t in legend)
    fig3, axes3 = plt.subplots(2, 1)
    plots.plot_momentum(car_solution.solution, ctx, axes=axes3)
    assert all("SI" not in a.get_ylabel() for a in axes3)
    assert axes3[1].get_ylabel() == "p̃_φ [N·m·s]"
    # P = XᵀMq̇ with the car's basis entry 1·sin φ on θ: an angular momentum
    assert axes3[0].get_ylabel() == "p [N·m·s]"
    for f in (fig, fig2, fig3):
        plt.close(f)
    assert dict(matplotlib.rcParams) == before


def test_shape_views_for_one_two_and_more_shape_variables(car_solution):
    import matplotlib.pyplot as plt

    from nhgait.gaits.figures import plots
    ctx = _ctx(car_solution)
    fig, axes = plt.subplots(1, 2)
    plots.plot_shape_loop(car_solution.solution, ctx, ax=axes[0])          # one: φ against φ̇
    assert axes[0].get_xlabel() == "φ [rad]"
    assert axes[0].get_ylabel() == "φ\u0307 [rad/s]"
    many = replace(ctx, shape=("theta", "phi", "x"))
    plots.plot_shape_loop(car_solution.solution, many, ax=axes[1])         # parallel coordinates
    assert len(axes[1].get_xticks()) == 3
    assert "parallel" in axes[1].get_title()
    plt.close(fig)


def test_gif_has_time_unit_and_scale(car_solution, tmp_path):
    from PIL import Image

    from nhgait.gaits.figures.animation import _nice, animate_solution
    path = animate_solution(car_solution.solution, _ctx(car_solution), tmp_path / "m.gif", frames=5)
    assert Image.open(path).n_frames == 5
    assert _nice(2.0) == 0.5
    assert _nice(0.3) == 0.05
    assert _nice(7.0) == 1.0


def test_drawing_problems_are_listed(car_solution):
    from nhgait.gaits.figures.drawing import parse_drawing
    from nhgait.ocp import ProblemError
    bad = {"frame": ["x", "y"], "colour": 1,
           "segment": [{"from": ["l", "zz"], "to": [0]},
                       {"from": [0, 0], "to": [1, 0], "width": -1, "kind": 2}]}
    with pytest.raises(ProblemError) as info:
        parse_drawing(bad, car_solution.plan.scene.system)
    text = str(info.value)
    for fragment in ("unknown key(s) ['colour']", "frame: need three coordinates", "unknown name 'zz'",
                     "segment[0].to must be a point", "segment[1].width must be a positive number",
                     "segment[1]: unknown key(s) ['kind']"):
        assert fragment in text, fragment
