"""The ranking of shape loops by the connection's prediction and the height-function figures
(issue 42, items 3–4)."""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.dynamics import derive
from nhgait.dynamics.derivation.models import snakeboard
from nhgait.dynamics.geometry.connection_fields import local_connection
from nhgait.dynamics.geometry.heights import HeightGrid, evaluate_heights
from nhgait.gaits.figures.geometry import heights_figure, moved_component


@pytest.fixture(scope="module")
def board_heights():
    model = derive(snakeboard(), "reduced")
    return evaluate_heights(local_connection(model), "psi", "phi",
                            HeightGrid(bounds={"psi": (-1, 1), "phi": (-1, 1)}, points=11,
                                       units={"x": "m", "y": "m", "theta": "rad", "psi": "rad",
                                              "phi": "rad"}))


def test_height_figure_has_names_units_colour_bar_and_arrows(board_heights, tmp_path):
    fig = heights_figure(board_heights, loop=(0.5 * np.cos(np.linspace(0, 6.3, 50)),
                                              0.5 * np.sin(np.linspace(0, 6.3, 50))))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "psi [rad]" and ax.get_ylabel() == "phi [rad]"
    assert any("height of x [m/rad²]" in a.get_ylabel() for a in fig.axes)   # the colour bars
    assert any(type(c).__name__ == "Quiver" for c in ax.collections)
    fig.savefig(tmp_path / "h.png")
    assert (tmp_path / "h.png").stat().st_size > 10_000


def test_plot_takes_an_axes_and_the_moved_component_is_the_largest():
    assert moved_component(("x", "y", "theta"), [0.1, -0.3, 0.05]) == "y"


def test_ranking_puts_the_loop_predicted_toward_the_target_first():
    """Two circles in (psi, phi) of opposite orientation around phi = 0.5 for a kinematic
    stand-in: the one whose predicted x motion is toward x = +1 ranks first, whatever the order."""
    from nhgait.gaits.planning import loop_ranking
    from nhgait.gaits.planning.waves import ShapeGuess

    def A(q):                             # ξ = −A ṙ with A = [[0, -r_a], [0, 0], [0, 0]]: H_x = 1
        return np.array([[0.0, -q[3]], [0, 0], [0, 0]])

    class Problem:
        horizon, initial, final, periodic, state_bounds = 1.0, {"x": 0.0}, {"x": 0.05}, (), {}
        params = None

        class model:
            class system:
                coordinates, planar_frame = ("x", "y", "theta", "a", "b"), None

        def fixed_value(self, where, name):
            start = name in ("y", "theta", "a", "b") and where is self.initial
            return where.get(name, 0.0 if start else None)

    ccw = ShapeGuess("ccw", (("a", 0.1, 1, np.pi / 2), ("b", 0.1, 1, 0.0)))       # a = cos, b = sin
    cw = ShapeGuess("cw", (("a", 0.1, 1, np.pi / 2), ("b", -0.1, 1, 0.0)))
    ramps = ShapeGuess("ramps only", ())

    def motion(t, q):                     # ṡ = −A ṙ, trapezoidal (s does not enter A)
        rdot = np.diff(q[3:], axis=1)
        steps = np.array([-A(0.5 * (q[:, k] + q[:, k + 1])) @ dr for k, dr in enumerate(rdot.T)]).T
        return np.hstack([np.zeros((3, 1)), np.cumsum(steps, axis=1)])

    predictor = loop_ranking.Predictor(
        fiber=("x", "y", "theta"), shape=("a", "b"), shape_index=(3, 4),
        lift_sizes=lambda q: np.array([np.linalg.norm(A(q[:, k])) for k in range(q.shape[1])]), motion=motion)
    scores = loop_ranking.loop_scores(Problem(), [cw, ccw], predictor)
    ranked = loop_ranking.rank_loops(Problem(), [cw, ramps, ccw], predictor=predictor)
    assert scores[1].moved[0] == pytest.approx(np.pi * 0.01, rel=1e-3)       # H·area = π ε²
    assert scores[0].moved[0] == pytest.approx(-np.pi * 0.01, rel=1e-3)
    assert [g.label for g in ranked.front] == ["ccw", "ramps only"]     # the loop toward x = +0.05 first
    assert [g.label for g in ranked.away] == ["cw"]                       # the mirror image: tried last


def _problem(text):
    from nhgait.gaits.planner import prepare
    from nhgait.gaits.tasks.sources import resolve
    return prepare(resolve(text)).problem


def test_reach_says_a_sideways_target_is_not_reachable_by_the_snakeboards_loops(tmp_path):
    """The snakeboard's connection has no y row and [A_ψ, A_φ] = 0 (A_φ = 0): H_y ≡ 0, so no
    loop in the bounded (ψ, φ) box moves it sideways — and the sentence says so and what to do."""
    from pathlib import Path

    from nhgait.gaits.verification.loop_reach import reach_sentence
    root = Path(__file__).resolve().parents[2]
    text = (root / "experiments" / "user_robots" / "snakeboard_fwd.toml").read_text()
    text = text.replace("final = {x = 0.6, y = 0.0,", "final = {x = 0.0, y = 0.3,")
    text = text.replace("bounds = {phi = [-0.8, 0.8]}", "bounds = {phi = [-0.8, 0.8], psi = [-1.5, 1.5]}")
    scene = tmp_path / "sideways.toml"
    scene.write_text(text)
    sentence = reach_sentence(_problem(str(scene)))
    assert sentence.startswith("not reachable by shape loops within the bounds")
    assert "y by +0.3" in sentence and "widen the shape bounds" in sentence
    forward = scene.with_name("forward.toml")
    forward.write_text(text.replace("final = {x = 0.0, y = 0.3,", "final = {x = 0.6, y = 0.0,"))
    assert reach_sentence(_problem(str(forward))).startswith("reachable within the bounds")
