"""Every figure the command line writes, for a robot that is not built in (issue 18, item 4):
the sleigh with a sliding mass (tests/scenes/sleigh_slider.toml) through ``simulate --plot``,
``plan``, ``sweep`` and ``bench precision``. Each figure is caught as it is saved and checked
for its title, its axis labels (with units), its number of series, titles that do not overlap,
and series that differ in colour, marker or line style.
"""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import matplotlib
import pytest
from matplotlib.figure import Figure

from nhgait.gaits.cli.main import main

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parents[2]
SLIDER = str(ROOT / "tests" / "scenes" / "sleigh_slider.toml")


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("figures")


@pytest.fixture(scope="module")
def figures(out):
    """name → Figure for every PNG written by the four commands (their files in ``out``)."""
    caught = {}
    original = Figure.savefig

    def catch(fig, fname, *args, **kwargs):
        original(fig, fname, *args, **kwargs)
        path = Path(fname)        # <command>/<name>, or <command>/.writing-*/<name> (a plan's staging folder)
        caught[f"{path.relative_to(out).parts[0]}/{path.name}"] = fig

    from nhgait.ocp import supervision
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", catch)
        # a plan draws its figures in supervised children: here in this process, to be caught
        mp.setattr(supervision, "supervise", lambda jobs, **kwargs: [job.run() for job in jobs])
        runs = (["simulate", SLIDER, "--plot", str(out / "simulate")],
                ["plan", SLIDER, "--no-jit", "--quiet", "--out", str(out / "plan")],
                ["sweep", SLIDER, "--grid", "final.y=0.2,0.3", "--grid", "horizon=3.5,4", "--workers", "0",
                 "--quiet", "--out", str(out / "sweep")],
                ["bench", "precision", SLIDER, "--tols", "1e-4,1e-8", "--methods", "DOP853,RK45",
                 "--formulations", "reduced,lagrange", "--no-idas", "--repeats", "1", "--quiet",
                 "--out", str(out / "bench")])
        for args in runs:
            assert main(args) == 0, args
    return caught


EXPECTED = {"simulate/time_series.png", "simulate/path.png", "plan/path.png", "plan/shape.png",
            "plan/histories.png", "plan/momentum.png", "sweep/landscape.png", "sweep/feasibility.png",
            "sweep/loops.png", "bench/precision.png"}


def _series(ax):
    """Lines that carry data (more than one point or a marker), not legend stand-ins."""
    return [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 0]


def _labelled(ax):
    return [ln.get_label() for ln in ax.get_lines() if not ln.get_label().startswith("_")]


def _overlap(a, b) -> bool:
    return a.width > 0 and b.width > 0 and a.overlaps(b)


def _titles_apart(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)           # drawn as when saved (layout engine included)
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = [ax.title.get_window_extent(renderer) for ax in fig.axes if ax.get_title()]
    if fig._suptitle is not None:
        boxes.append(fig._suptitle.get_window_extent(renderer))
    return not any(_overlap(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_every_cli_figure_is_written(figures):
    assert set(figures) == EXPECTED


def test_no_figure_has_overlapping_titles(figures):
    for name, fig in figures.items():
        assert _titles_apart(fig), name


def test_axis_labels_carry_units(figures):
    for name, fig in figures.items():
        for ax in fig.axes:
            for text in (ax.get_xlabel(), ax.get_ylabel()):
                if text:
                    assert re.search(r"\[[^\]]+\]", text), (name, text)


def test_simulate_figures(figures):
    ts = figures["simulate/time_series.png"]
    assert ts._suptitle.get_text().startswith("sleigh_slider: simulated reduced model")
    ylabels = [ax.get_ylabel() for ax in ts.axes]
    assert ylabels == ["coordinates [m]", "coordinates [rad]", "inputs [N]"]
    assert [_labelled(ax) for ax in ts.axes] == [["x [m]", "y [m]", "s [m]"], ["θ [rad]"],
                                                 ["F [N]", "f_s [N]"]]
    assert ts.axes[-1].get_xlabel() == "t [s]"
    path = figures["simulate/path.png"].axes[0]
    assert path.get_title().startswith("sleigh_slider: path in the plane")
    assert (path.get_xlabel(), path.get_ylabel()) == ("x [m]", "y [m]")
    # 7 instants × 3 segments (sled, rail, sliding mass) of the scene's [drawing] + the path + start + end
    assert len(_series(path)) == 7 * 3 + 3


def test_plan_figures(figures):
    path = figures["plan/path.png"].axes[0]
    assert path.get_title() == "path in the plane (to scale)"
    assert len(_series(path)) == 7 * 3 + 3
    shape = figures["plan/shape.png"].axes[0]
    assert shape.get_title() == "shape loop"
    assert (shape.get_xlabel(), shape.get_ylabel()) == ("θ [rad]", "s [m]")
    hist = figures["plan/histories.png"].axes
    assert hist[0].get_ylabel() == "shape θ, s [rad, m]"
    assert _labelled(hist[0]) == ["θ [rad]", "s [m]"]
    assert hist[1].get_ylabel() == "input [N]"
    assert _labelled(hist[1]) == ["F [N]", "f_s [N]"]
    mom = figures["plan/momentum.png"].axes
    assert [ax.get_ylabel() for ax in mom] == ["p [N·s]", "p̃_θ [N·m·s]", "p̃_s [N·s]"]
    assert all(len(_series(ax)) == 1 for ax in mom)


def test_sweep_figures(figures):
    land = figures["sweep/landscape.png"].axes[0]
    assert land.get_title().startswith("sleigh_slider/sidestep objective")
    assert (land.get_xlabel(), land.get_ylabel()) == ("final.y [m]", "horizon [s]")
    loops = figures["sweep/loops.png"]
    assert loops._suptitle.get_text().startswith("sleigh_slider/sidestep: shape loops along final.y")
    assert [ax.get_title() for ax in loops.axes] == ["final.y = 0.2", "final.y = 0.3"]
    assert all(len(_series(ax)) == 2 for ax in loops.axes)        # the loop and its start


def test_precision_figure_series_are_distinct(figures):
    ax = figures["bench/precision.png"].axes[0]
    assert ax.get_xlabel() == "wall time per run, median [s]"
    assert ax.get_ylabel().startswith("final-state error")
    assert "sleigh_slider" in ax.get_title()
    assert len(_labelled(ax)) == 4                                 # 2 formulations × 2 methods


def test_eighteen_series_get_eighteen_styles():
    """The issue's precision.png had 18 series and reused colours: every series now differs in
    colour, marker or line style from every other."""
    from nhgait.gaits.bench import work_precision as wp
    rows = [SimpleNamespace(label=f"form{i // 6}/method{i % 6}", success=True, error=10.0 ** -(i % 7 + 2),
                            rtol=tol, wall_s=1e-3 * (i + 1) * tol ** -0.1)
            for i in range(18) for tol in (1e-4, 1e-8)]
    ax = wp.plot_case(rows, Figure().add_subplot())
    styles = [(ln.get_color(), ln.get_marker(), ln.get_linestyle()) for ln in ax.get_lines()]
    assert len(styles) == 18
    assert len(set(styles)) == 18
    assert len({s[0] for s in styles}) == 10                      # the ten tab10 colours, then ...
    for i, a in enumerate(styles):                                # ... a series sharing a colour differs
        for b in styles[i + 1:]:                                  # in both marker and line style
            if a[0] == b[0]:
                assert a[1] != b[1], (a, b)
                assert a[2] != b[2], (a, b)


def test_result_reprs_are_short_and_say_where_the_arrays_are(figures, out):
    """PlanResult, Solution and SweepResult of this robot print a few lines (issue 18: a
    trajectory's repr was 4 194 characters of arrays)."""
    from nhgait.gaits.planner import plan
    from nhgait.gaits.sweeps.driver import load_sweep
    text = repr(load_sweep(out / "sweep"))
    assert text.startswith("<SweepResult sleigh_slider/sidestep: 4 of 4 points solved and "
                           "verified, grid (2, 2)")
    assert "result.objectives()" in text
    assert len(text) < 400
    result = plan(SLIDER, jit=False)
    text = repr(result)
    assert text.startswith("<PlanResult sleigh_slider/sidestep: SUCCESS")
    assert len(text) < 600
    assert "z (21, 7) columns (x, y, theta, s, p, pt_theta, pt_s)" in text      # time first
    assert "u (20, 2) columns" in text
    assert "verified to" in text
    assert "t = 0 … 4 s (21 samples)" in text
    from nhgait.gaits.planner import summary_lines
    assert any("R^2 (x, y) moves the fibre (x, y); the guesses loop the shape (theta, s)" in line
               for line in summary_lines(result))
    md = result.solution._repr_markdown_()
    assert "| verification | passed" in md
    assert "`solution.z` (21, 7)" in md
