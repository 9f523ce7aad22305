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
def cli_runs(out):
    """The four commands run once: ``figures`` (name → Figure for every PNG written, their files
    in ``out``) and ``plan`` (the PlanResult the ``plan`` command made)."""
    from nhgait.gaits import planner
    caught, plans = {}, []
    original = Figure.savefig
    original_plan = planner.plan

    def keep_plan(*args, **kwargs):
        plans.append(original_plan(*args, **kwargs))
        return plans[-1]

    def catch(fig, fname, *args, **kwargs):
        original(fig, fname, *args, **kwargs)
        path = Path(fname)        # <command>/<name>, or <command>/.writing-*/<name> (a plan's staging folder)
        caught[f"{path.relative_to(out).parts[0]}/{path.name}"] = fig

    from nhgait.ocp import supervision
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", catch)
        mp.setattr(planner, "plan", keep_plan)
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
    assert len(plans) == 1
    return SimpleNamespace(figures=caught, plan=plans[0])


@pytest.fixture(scope="module")
def figures(cli_runs):
    return cli_runs.figures


EXPECTED = {"simulate/time_series.png", "simulate/path.png", "simulate/checks.png", "plan/path.png",
            "plan/shape.png",
            "plan/histories.png", "plan/momentum.png", "plan/convergence.png",
            "sweep/landscape.png", "sweep/feasibility.png",
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
    # 5 instants × 3 segments (sled, rail, sliding mass) of the scene's [drawing] + the path + start + end
    assert len(_series(path)) == 5 * 3 + 3


def test_plan_figures(figures):
    path = figures["plan/path.png"].axes[0]
    assert path.get_title() == "path in the plane (to scale)"
    assert len(_series(path)) == 5 * 3 + 3
    shape = figures["plan/shape.png"].axes[0]          # SE(2) on (x, y, theta): one shape coordinate, s
    assert shape.get_title() == "shape motion: s against its rate"
    assert (shape.get_xlabel(), shape.get_ylabel()) == ("s [m]", "s\u0307 [m/s]")
    hist = figures["plan/histories.png"].axes
    assert hist[0].get_ylabel() == "shape s [m]"
    assert _labelled(hist[0]) == ["s [m]"]
    assert hist[1].get_ylabel() == "input [N]"
    assert _labelled(hist[1]) == ["F [N]", "f_s [N]"]
    mom = figures["plan/momentum.png"].axes
    assert [ax.get_ylabel() for ax in mom] == ["p1 [unit of XᵀMq̇]", "p2 [unit of XᵀMq̇]", "p̃_s [N·s]"]
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


def test_result_reprs_are_short_and_say_where_the_arrays_are(cli_runs, out):
    """PlanResult, Solution and SweepResult of this robot print a few lines (issue 18: a
    trajectory's repr was 4 194 characters of arrays). The plan is the ``plan`` command's."""
    from nhgait.gaits.sweeps.driver import load_sweep
    text = repr(load_sweep(out / "sweep"))
    assert text.startswith("<SweepResult sleigh_slider/sidestep: 4 of 4 points solved and "
                           "verified, grid (2, 2)")
    assert "result.objectives()" in text
    assert len(text) < 400
    result = cli_runs.plan
    text = repr(result)
    assert text.startswith("<PlanResult sleigh_slider/sidestep: SUCCESS")
    assert len(text) < 600
    assert "z (21, 7) columns (x, y, theta, s, p1, p2, pt_s)" in text      # time first
    assert "u (20, 2) columns" in text
    assert "verified to" in text
    assert "t = 0 … 4 s (21 samples)" in text
    from nhgait.gaits.plan_summary import summary_lines
    assert any("SE(2) (x, y, theta) moves the fibre (x, y, theta); the guesses loop the shape (s)" in line
               for line in summary_lines(result))
    md = result.solution._repr_markdown_()
    assert "| verification | passed" in md
    assert "`solution.z` (21, 7)" in md


# ----------------------------------------------------------------------------- figures to publish
def _drawn(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def test_simulate_checks_show_the_residual_and_the_energy_balance(figures, out):
    """checks.png holds what the CSV's columns hold: |ω(q)q̇| per constraint row and E − E₀ − W,
    read back from the drawn lines and compared with an independent run's own arrays."""
    import numpy as np

    from nhgait.dynamics import derive, load_scene, simulate
    fig = figures["simulate/checks.png"]
    residual_ax, energy_ax = fig.axes
    assert residual_ax.get_yscale() == "log"
    assert residual_ax.get_ylabel() == "constraint residual [m/s]"       # the sleigh's rows: velocities
    assert energy_ax.get_ylabel() == "energy balance [J]"
    assert energy_ax.get_xlabel() == "t [s]"
    scene = load_scene(SLIDER)
    spec = scene.simulation
    traj = simulate(derive(scene.system), (spec.t0, spec.t_final), spec.q0, spec.qdot0, t_eval=spec.t_eval,
                    controller=spec.controller, params=spec.parameters or None, rtol=1e-8, atol=1e-10)
    drawn = np.asarray(energy_ax.get_lines()[0].get_ydata())
    assert drawn.shape == traj.energy_balance.shape
    # the same physical invariant: both runs keep it at rounding level (the reduced ODE)
    assert np.abs(drawn).max() < 1e-8 and np.abs(traj.energy_balance).max() < 1e-8
    rows = [ln for ln in residual_ax.get_lines() if ln.get_label().startswith("|ω_")]
    assert len(rows) == traj.constraint_residual.shape[1]
    assert all(np.asarray(ln.get_ydata()).max() < 1e-10 for ln in rows)


def test_the_path_strobe_is_coloured_by_time_and_its_legend_outside(figures):
    fig = figures["plan/path.png"]
    ax, bar = fig.axes                                    # the path and its colour bar of time
    assert bar.get_ylabel() == "time of the drawn body t [s]"
    assert bar.get_ylim() == pytest.approx((0.0, 4.0))   # the sidestep's horizon
    renderer = _drawn(fig)
    legend = ax.get_legend().get_window_extent(renderer)
    assert not legend.overlaps(ax.get_window_extent(renderer))
    bodies = [ln for ln in ax.get_lines() if ln.get_zorder() == 1]
    assert len({ln.get_color() for ln in bodies}) == 5                   # one colour per instant


def test_start_and_end_are_both_visible_where_they_coincide():
    """A gait that ends where it starts (P3 turns on the spot): both markers are seen in the
    rendered image — red of the open start circle and black of the end square around the point."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from nhgait.gaits.figures import plots
    from nhgait.gaits.planner import plan
    result = plan("snakeboard", "rotate", intervals=20, jit=False, verify=False)
    ctx = plots.figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
    fig = plots.gait_figure(result.solution, ctx, plots.figure_layouts(result.solution, ctx)[0])
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    ax = fig.axes[0]
    x, y = (plots.series(result.solution, c) for c in ctx.frame[:2])
    assert np.hypot(x[-1] - x[0], y[-1] - y[0]) < 1e-6                  # the task: back at the start
    px, py = ax.transData.transform((x[0], y[0]))
    image = np.asarray(canvas.buffer_rgba())[..., :3].astype(int)
    row = image.shape[0] - int(round(py))
    window = image[row - 14:row + 15, int(round(px)) - 14:int(round(px)) + 15]
    red = (np.abs(window - (214, 39, 40)).sum(axis=2) < 60).sum()        # C3, the start circle
    black = (window.sum(axis=2) < 60).sum()                              # the end square
    assert red > 20 and black > 10, (red, black)


def test_the_failed_banner_is_clear_of_every_title(figures):
    """A failed plan's figures: the banner (the figure's suptitle) and every axes' title have
    disjoint bounding boxes, and the banner fits the figure's width."""
    from nhgait.gaits.figures import plots
    from nhgait.gaits.planner import plan
    result = plan(SLIDER, jit=False, verify=False, intervals=10)
    ctx = plots.figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
    reason = "Verification_Failed: the re-simulation misses the nodes by 3e-3 (tolerance 1e-6) " * 3
    for layout in plots.figure_layouts(result.solution, ctx):
        fig = plots.gait_figure(result.solution, ctx, layout, failed=reason)
        renderer = _drawn(fig)
        banner = fig._suptitle.get_window_extent(renderer)
        assert fig._suptitle.get_text().startswith("FAILED — not a verified gait")
        assert banner.x0 >= 0 and banner.x1 <= fig.bbox.x1, layout.name
        for ax in fig.axes:
            if ax.get_title():
                assert not banner.overlaps(ax.title.get_window_extent(renderer)), layout.name
            assert not banner.overlaps(ax.get_window_extent(renderer)), layout.name


def test_the_gif_frame_holds_the_whole_motion(tmp_path):
    """Every point of the path and of the body at every frame lies inside the GIF's axes, whose
    box has equal scales; the GIF's size is the computed figure's."""
    import numpy as np
    from PIL import Image

    from nhgait.gaits.figures import animation, plots
    from nhgait.gaits.planner import plan
    result = plan("snakeboard", "forward", intervals=20, jit=False, verify=False)
    ctx = plots.figure_context(result.solution, result.model, result.plan.units, result.plan.drawing)
    path = animation.animate_solution(result.solution, ctx, tmp_path / "motion.gif", frames=12)
    xs, ys = [plots.series(result.solution, "x")], [plots.series(result.solution, "y")]
    for k in range(len(result.solution.t)):
        for sx, sy in plots.body_segments(result.solution, ctx, k):
            xs.append(np.ravel(sx))
            ys.append(np.ravel(sy))
    x, y = np.concatenate(xs), np.concatenate(ys)
    geometry = animation.frame_geometry(x, y)
    assert geometry.xlim[0] < x.min() and x.max() < geometry.xlim[1]
    assert geometry.ylim[0] < y.min() and y.max() < geometry.ylim[1]
    width, height = geometry.xlim[1] - geometry.xlim[0], geometry.ylim[1] - geometry.ylim[0]
    assert height / width == pytest.approx(geometry.box[1] / geometry.box[0], rel=1e-12)   # equal scales
    assert width / (x.max() - x.min()) < 1.3                  # the long side fits the motion (padding only)
    gif = Image.open(path)
    assert gif.n_frames == 12
    assert gif.size == tuple(round(v * animation.DPI) for v in geometry.figsize)
    assert gif.size[0] > 1.5 * gif.size[1]                    # a forward gait: a wide frame, not a tall one


def test_simulate_draws_the_body_plan_draws(tmp_path):
    """The built-in snakeboard has its [drawing] in its gait library: simulate --plot draws it too."""
    from nhgait.dynamics import load_scene
    from nhgait.gaits.tasks.sources import figure_tables, resolve
    scene = load_scene("snakeboard")
    assert scene.drawing is None
    assert figure_tables(scene).drawing == resolve("snakeboard", "forward").drawing is not None
