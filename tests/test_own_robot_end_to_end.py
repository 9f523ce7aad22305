"""Issue 18, the second hour of a new user, with a robot of their own: a Chaplygin sleigh
carrying a laterally sliding mass, q = (x, y, theta, s) (tests/scenes/sleigh_slider.toml), whose
coordinate ``s`` shares its name with the method's letter for fibre coordinates.

1. printed output in the user's names (group, fibre and shape stated with the reason and the
   other choices; method symbols kept apart; named sub-expressions equal to the plain ones);
2. a CLI that does what people try (``simulate --set`` against an independent simulation,
   ``--plot``, "did you mean", compile time apart, progress with an estimate);
3. an API that introduces itself (``help(nhgait)``, short reprs, notebook Markdown, the
   getting-started guide's snippet against an independent, tighter computation of the number
   it quotes);
4. every figure the CLI writes for this robot: titles, axis labels with units, series counts,
   no overlapping titles, distinct series styles.
"""
from __future__ import annotations

import csv
import pydoc
import re
from pathlib import Path

import matplotlib
import numpy as np
import pytest
import sympy as sp

from nhgait.gaits.cli.main import main

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parents[1]
SLIDER = str(ROOT / "tests" / "scenes" / "sleigh_slider.toml")


@pytest.fixture(scope="module")
def slider():
    from nhgait.dynamics import derive, load_scene
    scene = load_scene(SLIDER)
    return scene, derive(scene.system)


# ----------------------------------------------------------------------------- 1. the user's names
def test_derive_states_group_fibre_and_shape_in_the_users_names(slider):
    _, model = slider
    text = model.to_text()
    assert "fiber s =" not in text  # the method's letters are gone
    assert "shape r =" not in text
    assert ("symmetry group SE(2) (x, y, theta) moves the fibre (group) coordinates (x, y, theta); shape "
            "coordinates (s)" in text)
    # the reason, and every other admissible choice written as the user would write it (issue 41:
    # SE(2) on the planar frame first, the translations still named)
    assert "chosen by the full-symmetry test (L and ω are SE(2)-invariant" in text
    assert ("preferred to the next candidate R^2 (x, y): SE(2) on the planar frame (x, y, heading) comes "
            "first" in text)
    assert "fiber = ['x', 'y'] (R^2 (x, y), full)" in text
    table = model.symmetry.table_markdown()
    assert table.startswith("| fibre coordinates | group G |")
    assert "do not depend on s" not in table


def test_choosing_another_fibre_as_the_output_says(slider):
    import dataclasses

    from nhgait.dynamics import derive
    scene, _ = slider
    model = derive(dataclasses.replace(scene.system, fiber=["x", "y"]))
    assert model.fiber == ("x", "y")
    assert model.shape == ("theta", "s")
    assert "chosen by the system's fiber = ['x', 'y']" in model.to_text()


def test_method_symbols_never_capture_a_users_name():
    """A parameter named p (the method's nonholonomic momentum) and one named p_x (Hamilton's
    momentum of x): the method's symbols are qualified, and the reduced ODE and the Hamilton
    DAE reach the Lagrange DAE's final state (three derivations, scipy DOP853 at 1e-11)."""
    from nhgait.dynamics import System, derive, simulate
    system = System(coordinates=["x", "y", "theta"],
                    lagrangian="p*((x_dot - p_x*sin(theta)*theta_dot)**2 + (y_dot + "
                               "p_x*cos(theta)*theta_dot)**2)/2 + I_c*theta_dot**2/2",
                    constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"], forces={"theta": "0.1*cos(t)"},
                    parameters={"p": 1.0, "p_x": 0.3, "I_c": 0.2}, name="renamed",
                    fiber=["x", "y"])                          # one nonholonomic momentum, named p
    reduced, hamilton = derive(system, "reduced", use_cache=False), derive(system, "hamilton",
                                                                           use_cache=False)
    assert "p_nh" in reduced.state_names
    assert "p" not in reduced.state_names
    assert "p_x_nh" in hamilton.state_names
    q0, qd0 = [0.0, 0.0, 0.0], [1.0, 0.0, 0.5]
    finals = [simulate(derive(system, f, use_cache=False), (0, 3), q0, qd0, rtol=1e-11, atol=1e-13).q[-1]
              for f in ("lagrange",)] + [simulate(m, (0, 3), q0, qd0, rtol=1e-11, atol=1e-13).q[-1]
                                         for m in (reduced, hamilton)]
    np.testing.assert_allclose(finals[1], finals[0], atol=1e-8)
    np.testing.assert_allclose(finals[2], finals[0], atol=1e-8)


def test_named_subexpressions_are_the_plain_equations(slider):
    import dataclasses

    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.cse_text import named_subexpressions
    scene, _ = slider
    model = derive(dataclasses.replace(scene.system, fiber=["x", "y"]))    # the explicit form
    rhs = list(model.pretty_rhs())
    definitions, reduced = named_subexpressions(rhs)
    assert len(definitions) >= 3
    back = {}
    for name, sub in definitions:                   # each name may use the earlier ones
        back[name] = sub.xreplace(back)
    for plain, named in zip(rhs, reduced, strict=True):
        assert sp.simplify(named.xreplace(back) - plain) == 0
    text = model.to_text()                          # long: named by default; --no-cse prints all
    assert "\n  where\n    w1 = " in text
    assert "where" not in model.to_text(cse=False)
    assert len(text) < 0.6 * len(model.to_text(cse=False))


def test_derive_cse_default_only_for_long_equations(capsys):
    assert main(["derive", "unicycle"]) == 0
    assert "where" not in capsys.readouterr().out
    assert main(["derive", "unicycle", "--formulation", "hamilton", "--cse"]) == 0
    assert "H = " in capsys.readouterr().out


# ----------------------------------------------------------------------------- 2. the CLI
def test_simulate_set_against_an_independent_run(tmp_path, capsys):
    """--set changes parameters, initial values, an input law and t_final (qdot0 is a table in the
    scene: y_dot is solved from the constraint, ẏ = tan θ ẋ); the CSV's last row
    equals the Lagrange DAE (another formulation) integrated by scipy DOP853 at rtol 1e-12 with
    the same values given through the Python API."""
    from nhgait.dynamics import derive, load_scene, simulate
    from nhgait.dynamics.derivation.input.expressions import parse_expression
    from nhgait.dynamics.derivation.input.scene import ExpressionController
    out = tmp_path / "t.csv"
    assert main(["simulate", SLIDER, "--set", "t_final=3", "--set", "params.m_s=0.8", "--set", "q0.theta=0.2",
                 "--set", "inputs.f_s=0.5*cos(3*t)", "--set", "qdot0.x=0.7", "--rtol", "1e-10",
                 "--out", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t [s]", "x [m]", "y [m]", "theta [rad]", "s [m]"]
    last = np.array(rows[-1], dtype=float)
    system = load_scene(SLIDER).system
    names = {s.name: s for s in system.q + system.q_dot + system.param_symbols}
    names["t"] = sp.Symbol("t", real=True)
    law = ExpressionController(system, (sp.Integer(0), parse_expression("0.5*cos(3*t)", names, "f_s")),
                               {"m_s": 0.8})
    ref = simulate(derive(system, "lagrange"), (0, 3), [0, 0, 0.2, 0], [0.7, 0.7 * np.tan(0.2), 0.3, 0],
                   controller=law, params={"m_s": 0.8}, rtol=1e-12, atol=1e-14)
    assert last[0] == pytest.approx(3.0)
    np.testing.assert_allclose(last[1:], ref.q[-1], atol=1e-7)


def test_every_unknown_name_gets_did_you_mean_and_the_known_names(tmp_path, capsys):
    assert main(["simulate", SLIDER, "--set", "t_fnal=6", "--set", "q0.tht=1", "--set", "params.mm=2",
                 "--out", str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert "3 problem(s)" in err
    assert "did you mean 't_final'?" in err
    assert "'tht' is not a coordinate: did you mean 'theta'? (coordinates: x, y, theta, s)" in err
    assert "unknown parameter 'mm': did you mean 'm'?" in err
    assert main(["simulate", SLIDER, "--set", "q0=1", "--set", "t_final.x=2", "--out",
                 str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert "q0 needs a name: q0.<name>=value" in err
    assert "t_final takes no .<name>" in err
    scene = tmp_path / "typo.toml"
    scene.write_text(Path(SLIDER).read_text().replace("I_c*theta_dot**2/2", "I_c*thetadot**2/2"))
    assert main(["derive", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "unknown symbol 'thetadot' in the Lagrangian" in err
    assert "did you mean 'theta_dot'" in err
    assert "(known: x, y, theta, s, x_dot, y_dot, theta_dot, s_dot, m, I_c, a, m_s, b)" in err
    assert main(["plan", "snakeboard", "--gait", "foward", "--out", str(tmp_path / "p")]) == 2
    assert "did you mean 'forward'" in capsys.readouterr().err
    assert main(["plan", SLIDER, "--set", "fnal.y=1", "--out", str(tmp_path / "p")]) == 2
    assert "did you mean 'final'?" in capsys.readouterr().err


def test_compile_time_reported_apart_from_run_time(tmp_path, monkeypatch, capsys):
    from nhgait.dynamics.numerics.compiler import compiler_command
    from nhgait.dynamics.simulation import compiled
    if compiler_command() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("NHGAIT_CACHE_DIR", str(tmp_path / "cache"))
    compiled.LOADED_LIBRARIES.clear()                       # a fresh process: nothing loaded yet
    args = ["simulate", SLIDER, "--method", "compiled", "--out", str(tmp_path / "t.csv")]
    assert main(args) == 0
    first = capsys.readouterr().out
    assert re.search(r"run \d+\.\d{3} s \+ compiling the integrator \d+\.\d{3} s \(once per model", first)
    assert main(args) == 0
    second = capsys.readouterr().out
    assert re.search(r"evaluations, run \d+\.\d{3} s\)", second)
    assert "compiling" not in second


def test_bench_says_how_many_points_and_how_long_is_left(tmp_path, capsys):
    assert main(["bench", "precision", SLIDER, "--tols", "1e-4,1e-6", "--methods", "DOP853",
                 "--formulations", "reduced", "--no-idas", "--repeats", "1", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    err = captured.err
    assert "measuring 1 formulation/method set-ups × 2 tolerances = 2 points" in err
    assert re.search(r"1/2 points: reduced/DOP853 .* — about \d+ s left", err)
    assert re.search(r"2/2 points: reduced/DOP853 .* — done", err)
    assert "precision.md (2 points in" in captured.out


def test_countdown_estimate():
    import io
    import time

    from nhgait.dynamics.countdown import Countdown, duration
    stream = io.StringIO()
    countdown = Countdown(4, stream=stream, what="points", started=time.perf_counter() - 10.0)
    countdown.step("first")
    assert countdown.remaining_s() == pytest.approx(30.0, rel=0.05)   # 10 s per point, 3 left
    assert "1/4 points: first — about 30 s left" in stream.getvalue()
    assert duration(185) == "3 min 05 s"
    assert duration(3720) == "1 h 02 min"


# ----------------------------------------------------------------------------- 3. the API
def test_help_lists_subpackages_the_first_five_things_and_the_true_default_solver():
    import nhgait
    from nhgait.gaits.planning.options import solver_order
    text = pydoc.render_doc(nhgait, renderer=pydoc.plaintext)
    for name in ("nhgait.dynamics", "nhgait.ocp", "nhgait.gaits", "load_scene", "derive", "simulate", "plan"):
        assert name in text
    assert solver_order("auto") == ("fatrop", "ipopt")          # what the planner really does ...
    doc = " ".join(nhgait.__doc__.split())
    assert ("by default FATROP on a stage-ordered multiple-shooting transcription for small ODEs and Ipopt "
            "for larger ones" in doc)
    assert nhgait.dynamics.__name__ == "nhgait.dynamics"          # sub-packages on first use
    # the five things: steps 1-3 run as written (4-5 plan, which test_plan_cli covers)
    code = nhgait.__doc__.split("The five things a user does first::")[1].split("The same from the shell")[0]
    lines = [ln.strip() for ln in code.strip().splitlines()]
    namespace = {}
    exec("\n".join(lines[:2] + [ln.replace("examples/", str(ROOT / "examples") + "/") for ln in lines[3:6]]),
         namespace)
    assert namespace["traj"].success
    assert namespace["traj"].q.shape[1] == 4


def test_short_reprs_and_notebook_markdown(slider):
    from nhgait.dynamics import derive, simulate
    scene, model = slider
    spec = scene.simulation
    traj = simulate(model, (0, spec.t_final), spec.q0, spec.qdot0, controller=spec.controller,
                    t_eval=spec.t_eval)
    text = repr(traj)
    assert len(text) < 300
    assert "success" in text
    assert "t = 0 … 4 s (81 samples)" in text
    assert "q (81, 4)" in text
    assert "state (81, 7)" in text
    lagrange = derive(scene.system, "lagrange")
    assert repr(lagrange).startswith("<LagrangianDAE of "
                                     "sleigh_slider: 8 states")
    assert len(repr(lagrange)) < 200
    md = model._repr_markdown_()
    assert "| shape coordinates | s |" in md
    assert "```\nReduced constrained" in md


def test_guide_snippet_reproduces_the_number_the_guide_quotes(capsys):
    """The Python snippet of docs/getting-started.md run as written: x(10π) printed with 8
    decimals equals the number in the reproduction table (docs/simulation.md), and so does an
    independent computation (the Lagrange DAE integrated by scipy DOP853 at rtol 1e-12, tighter
    than the snippet's 1e-10)."""
    from nhgait.dynamics import derive, simulate
    from nhgait.dynamics.simulation.controllers import snakeboard_pd
    guide = (ROOT / "docs" / "getting-started.md").read_text()
    code = re.search(r"```python\n(.*?)```", guide, re.S).group(1)
    table = (ROOT / "docs" / "simulation.md").read_text()
    quoted = float(re.search(r"\| snakeboard \(T = 10π\) \| ([0-9.]+) \|", table).group(1))
    assert f"# {quoted:.8f}" in code                               # the snippet quotes the table
    namespace = {}
    exec(code, namespace)
    printed = capsys.readouterr().out
    assert f"x(10π) = {quoted:.8f}" in printed
    ref = simulate(derive("snakeboard", "lagrange"), (0, 10 * np.pi), [0, 0, 0, 0, 1], [0, 0, 0, 1, 0],
                   controller=snakeboard_pd(), method="DOP853", rtol=1e-12, atol=1e-14)
    assert ref.q[-1, 0] == pytest.approx(quoted, abs=5e-9)         # the quote is the rounded reference
    assert namespace["traj"].q[-1, 0] == pytest.approx(ref.q[-1, 0], abs=5e-9)
