"""The fault probe's defects of issue 41 (item 4), each a clear error (exit 2, one message
naming the problem) or a correct answer, and nothing left in $TMPDIR or --out (contract:
tests/adversarial.py):

=====================================================  ==========================================
case                                                   before → after
=====================================================  ==========================================
``objective = {effort = 0.0}``                         exit 3 (CasADi "Expected a dense 'f'") → 2
``holonomic`` fixing every coordinate                  exit 3 (IndexError) → 2
parameters ``"ﬁ"`` and ``fi``                          wrong equations, exit 0 → 2 (one name)
``planar_frame = ["x", "x", "theta"]``                 accepted → 2
``[system].description = 5``                          accepted → 2
a killed writer's ``--out/.writing-*/``               kept by a rerun → removed by the next writer
an unwritable cache's ``$TMPDIR/nhgait-jit-*``         two left after exit 0 → none
another scene's entry, header key rewritten           served, exit 0 → refused and rebuilt
smooth walls ``exp(50*(x + 0.75))``                    "exceeds 1e+15" (folded) → accepted
=====================================================  ==========================================
"""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from adversarial import CAR, answer

CAR_TEXT = Path(CAR).read_text()
GARAGE_TEXT = (Path(CAR).parent / "opty_garage.toml").read_text()


def _scene(sandbox, text: str, name: str = "scene.toml") -> Path:
    path = sandbox.root / name
    path.write_text(text, encoding="utf-8")
    return path


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# ----------------------------------------------------------------------------- refused input
ZERO = "every weight is 0, so there is nothing to minimise"


def test_an_objective_of_zero_weight_is_refused_before_any_work(sandbox):
    """CasADi's solvers cannot take a structurally empty objective ("Expected a dense 'f'")."""
    scene = _scene(sandbox, CAR_TEXT.replace('objective = "effort"', "objective = {effort = 0.0}"))
    said = answer(["plan", scene, "--out", sandbox.out / "p"]).check(
        2, r"\[task\]\.objective = \{effort = 0\.0\}: " + ZERO, sandbox)
    assert said.err.count(" - ") == 1
    assert not (sandbox.out / "p").exists()


def test_an_objective_whose_inputs_all_weigh_zero_is_refused():
    """``{effort = 0, F = 1}``: effort multiplies each input's weight, so every term is 0."""
    from nhgait.gaits.tasks.statement import objective_problems, parse_task
    task = parse_task({"horizon": 1.0, "objective": {"effort": 0.0, "F": 1.0}})
    assert objective_problems(task, ("F", "tau_phi")) == [
        "[task].objective = {effort = 0.0, F = 1.0}: every term weighs 0 (effort = 0 multiplies each "
        "input's weight), so there is nothing to minimise (give effort a positive weight, e.g. "
        "objective = \"effort\")"]
    assert objective_problems(parse_task({"horizon": 1.0, "objective": {"effort": 0.0, "F": 1.0,
                                                                   "G": 0.0}}), ("F",)) != []
    assert objective_problems(parse_task({"horizon": 1.0, "objective": {"F": 0.0}}), ("F", "G")) == []


def test_holonomic_constraints_fixing_every_coordinate_are_refused(sandbox):
    scene = _scene(sandbox, CAR_TEXT.replace('inputs = ["F", "tau_phi"]', 'inputs = ["F", "tau_phi"]\n'
                                             'holonomic = ["x - 1", "y", "theta", "phi - 0.1"]'))
    answer(["derive", scene]).check(
        2, r"holonomic: 4 holonomic constraint\(s\) on 4 coordinate\(s\) \(x, y, theta, phi\) fix every "
           r"coordinate: no motion is left \(each removes one coordinate; keep at most 3\)", sandbox)


def test_names_one_under_unicode_normalisation_are_refused_as_a_pair(sandbox):
    """Python's parser reads the ligature ﬁ (U+FB01) as fi (NFKC): with both declared, the
    Lagrangian's ﬁ silently meant fi (x(2π) 6.466 instead of 7.781)."""
    text = CAR_TEXT.replace("l = 0.5 ", '"ﬁ" = 0.5\nfi = 5.0\nl = 0.5 ').replace(
        "I_s*phi_dot**2/2", "I_s*phi_dot**2/2 - ﬁ*phi**2 - fi*phi**4")
    said = answer(["derive", _scene(sandbox, text)]).check(
        2, r"names 'ﬁ' and 'fi' differ only by Unicode normalisation \(both read as 'fi'\): they are one "
           r"name — rename one", sandbox)
    assert said.err.count(" - ") == 1


def test_a_lone_name_outside_normal_form_means_itself():
    """The ligature alone: the text's ﬁ is the parameter ﬁ, whose value is used: the force on
    φ from V = ﬁ φ² is −2 ﬁ φ (the same system as with an ASCII name)."""
    import sympy as sp

    from nhgait.dynamics import System
    def make(k):
        return System(coordinates=["x", "phi"], lagrangian=f"x_dot**2/2 + phi_dot**2/2 - {k}*phi**2",
                      parameters={k: 0.5})
    lig, plain = make("ﬁ"), make("k")
    assert [s.name for s in lig.param_symbols] == ["ﬁ"]
    assert sp.simplify(lig.potential().subs(lig.param_symbols[0], sp.Symbol("k", real=True))
                       - plain.potential()) == 0


@pytest.mark.parametrize("edit, said", [
    pytest.param(('name = "car"', 'name = "car"\nplanar_frame = ["x", "x", "theta"]'),
                 r"planar_frame = \['x', 'x', 'theta'\]: 'x' named twice \(need three different coordinates: "
                 r"x, y, heading\)", id="planar_frame x twice"),
    pytest.param(('name = "car"', 'name = "car"\ndescription = 5'),
                 r"\[system\]\.description must be a string, got an integer \(5\)",
                 id="system description 5"),
    pytest.param(('description = "move', 'description = 5\nnote = "move'),
                 r"\[task\]\.description must be a string", id="task description 5"),
])
def test_frames_and_descriptions_of_the_wrong_kind_are_refused(edit, said, sandbox):
    text = CAR_TEXT.replace(*edit).replace('note = "move', '# "move')
    answer(["plan", _scene(sandbox, text), "--out", sandbox.out / "p"]).check(2, said, sandbox)
    assert not (sandbox.out / "p").exists()


# ----------------------------------------------------------------------------- magnitudes
def test_the_magnitude_guard_judges_the_numbers_written_not_those_sympy_folds():
    """exp(50(x + 0.75)) is folded by sympy into 1.93e16·exp(50x): the smooth garage wall is a
    legitimate scene (opty's car in garage); a number the user writes beyond 1e15 is not."""
    import sympy as sp

    from nhgait.dynamics.derivation.input.expressions import parse_expression
    from nhgait.dynamics.errors import ModelError
    x, y = sp.symbols("x y", real=True)
    wall = parse_expression("y - 5*(1/(1 + exp(50*(x + 0.75))) + 1/(1 + exp(-50*(x - 0.75))))",
                            {"x": x, "y": y}, "wall0")
    for xv, yv in ((0.0, 1.0), (-0.74, 3.0), (2.0, 0.5)):
        closed = yv - 5 * (1 / (1 + math.exp(50 * (xv + 0.75))) + 1 / (1 + math.exp(-50 * (xv - 0.75))))
        assert float(wall.subs({x: xv, y: yv})) == pytest.approx(closed, rel=1e-12, abs=1e-12)
    for text, part in (("1e300*x", "1e300"), ("exp(40)*x", "exp(40)"), ("1e10*1e10*x", "1e10*1e10*x")):
        with pytest.raises(ModelError, match=rf"w: a constant in '.*' exceeds 1e\+15 in magnitude, the "
                                             rf"largest number nhgait accepts \('{re.escape(part)}'\)"):
            parse_expression(text, {"x": x}, "w")


def test_the_garage_with_its_walls_written_as_numbers_is_accepted(sandbox):
    """The probe's garage: x1, x2 and y12 written as numbers (−0.75, 0.75, 5) in the walls."""
    from nhgait.dynamics.derivation.input.scene import load_scene
    text = (GARAGE_TEXT.replace("exp(50*(x - x1))", "exp(50*(x + 0.75))")
            .replace("exp(-50*(x - x2))", "exp(-50*(x - 0.75))")
            .replace('wall0 = "y - y12*', 'wall0 = "y - 5*'))
    assert 'wall0 = "y - 5*(1/(1 + exp(50*(x + 0.75))) + 1/(1 + exp(-50*(x - 0.75))))"' in text
    scene = load_scene(_scene(sandbox, text))
    assert set(scene.quantities) >= {"wall0", "wall1", "wall2", "wall3", "pmin"}


# ----------------------------------------------------------------------------- leftovers
def test_a_killed_writers_staging_folder_goes_with_the_next_writer(tmp_path):
    """kill -9 while a plan writes leaves ``--out/.writing-<pid>-*/``: the next writer removes
    those of processes that are gone (and of no stated pid), keeps a live writer's, and its
    own staging folder goes too."""
    from nhgait.gaits.files.outputs import output_lock, staged
    out = tmp_path / "out"
    out.mkdir()
    dead = out / f".writing-{_dead_pid()}-k9x2"
    old = out / ".writing-abc123"
    live = out / f".writing-{os.getppid()}-live"
    for folder in (dead, old, live):
        folder.mkdir()
        (folder / "solution.json").write_text("{half")
    with output_lock(out, "test"):
        assert not dead.exists() and not old.exists() and live.exists()
        dead.mkdir()
        written = staged(out, lambda folder: [folder / "a.txt"] if (folder / "a.txt").write_text("1") else [])
    assert written == [out / "a.txt"] and (out / "a.txt").read_text() == "1"
    assert sorted(p.name for p in out.iterdir()) == sorted(["a.txt", live.name])


def test_a_rerun_of_plan_clears_a_killed_runs_staging(sandbox):
    out = sandbox.out / "p"
    stale = out / f".writing-{_dead_pid()}-k9x2"
    stale.mkdir(parents=True)
    (stale / "trajectory.csv").write_text("t,x\n0,")
    answer(["plan", "unicycle", "--gait", "parallel-park", "--out", out, "--quiet"]).check(0, None, sandbox)
    assert not any(p.name.startswith(".writing-") for p in out.iterdir())
    assert (out / "solution.json").exists()


def test_a_fast_library_built_privately_is_removed_once_loaded(sandbox, monkeypatch):
    """An unwritable cache: libraries are built in ``$TMPDIR/nhgait-jit-*``; the fitted roll-out's
    functions (compiled_fast) left two such folders after an exit-0 plan."""
    import casadi as ca

    from nhgait.dynamics.numerics import compiler, fast_compiler
    if fast_compiler.fast_compiler() is None:
        pytest.skip("no fast compiler")
    monkeypatch.setattr(compiler, "_library_dir", lambda: None)     # the cache refused for libraries
    x = ca.SX.sym("x", 2)
    f = ca.Function("probe_f", [x], [ca.sin(x[0]) * x[1] + x[1] ** 3])
    fast = fast_compiler.compiled_fast(f, salt="probe defects test")
    assert fast is not f                                        # it was compiled
    assert float(fast([0.3, 1.7])) == pytest.approx(math.sin(0.3) * 1.7 + 1.7 ** 3, rel=1e-14)
    assert list(sandbox.tmp.iterdir()) == []


def test_another_scenes_entry_with_its_header_key_rewritten_is_refused(sandbox, monkeypatch):
    """The unicycle's entry copied under the car's key with the key in its header rewritten:
    the key inside the checked payload is the unicycle's, so it is refused and the car derived."""
    from nhgait.dynamics import derive, unicycle
    from nhgait.dynamics.derivation.input.scene import load_scene
    from nhgait.dynamics.numerics import cache
    sandbox.use_cache(monkeypatch, sandbox.root / "cache")
    uni = derive(unicycle(), "reduced").provenance.key
    car_key = derive(load_scene(CAR).system, "reduced").provenance.key
    forged = cache.path_for(uni).read_bytes().replace(uni.encode(), car_key.encode(), 1)
    cache.path_for(car_key).write_bytes(forged)
    assert forged.count(uni.encode()) == 1                       # the payload still names the unicycle
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        said = answer(["derive", CAR]).check(0, r"equations of car", sandbox)
    assert "unicycle" not in said.out
    assert any(isinstance(w.message, cache.UntrustedCacheWarning)
               and "written for another key (its checked payload names" in str(w.message) for w in seen) \
        or "written for another key (its checked payload names" in said.err
