"""``plan()``'s own arguments and a sweep's options, checked before any work
(gaits/planning/arguments.py, gaits/sweeps/point.py ``option_problems``), and the solver that
``--hessian limited-memory`` gets with ``--solver auto``.

Each bad argument once passed silently (``intervals=3.5`` truncated to 3, ``intervals=True`` taken
for N = 1, ``time_limit=True`` for one second, ``overrides="final.y=0.3"`` split into 11
one-character overrides, ``animate=True`` without ``out_dir`` writing nothing, an unknown sweep
option ignored) or failed deep inside (``workers="many"``, ``progress="yes"``, ``max_iter=-1`` in
Ipopt's option dump, a sweep's ``workers="2"``); now every problem is one ProblemError naming
the argument, before the derivation (a planner whose derivation raises proves it).
"""
from __future__ import annotations

import numpy as np
import pytest

from nhgait.gaits import planner
from nhgait.gaits.cli.main import main
from nhgait.gaits.planner import plan
from nhgait.gaits.planning.arguments import argument_problems, checked_request, override_list
from nhgait.gaits.planning.options import solver_order
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import ProblemError

PARK = ("unicycle", "parallel-park")


@pytest.fixture
def no_derivation(monkeypatch):
    """A planner that fails if it gets as far as the derivation."""
    def derived(*args, **kwargs):
        raise AssertionError("derived before the arguments were checked")
    monkeypatch.setattr(planner, "prepare", derived)


BAD = [
    ({"intervals": 3.5}, "intervals = 3.5 must be a whole number (N control intervals) or None"),
    ({"intervals": True}, "intervals = True must be a whole number"),
    ({"time_limit": True}, "time_limit = True must be a positive number of seconds"),
    ({"time_limit": -1.0}, "time_limit = -1.0 must be a positive number of seconds"),
    ({"max_guesses": -3}, "max_guesses = -3 must be a whole number ≥ 1"),
    ({"max_guesses": 2.5}, "max_guesses = 2.5 must be a whole number ≥ 1"),
    ({"workers": "many"}, "workers = 'many' must be a whole number ≥ 1 or 'auto'"),
    ({"workers": 0}, "workers = 0 must be a whole number ≥ 1 or 'auto'"),
    ({"progress": "yes"}, "progress = 'yes' must be a nhgait.dynamics.progress.Progress"),
    ({"max_iter": -1}, "max_iter = -1 must be a whole number ≥ 1"),
    ({"overrides": [3]}, "overrides = [3]: give 'key=value' strings"),
    ({"animate": True}, "animate=True writes motion.gif into out_dir: give out_dir"),
    ({"solver": "snopt"}, "solver = 'snopt': use one of 'auto', 'fatrop', 'ipopt'"),
    ({"hessian": "bfgs"}, "hessian = 'bfgs': use one of 'auto', 'exact', 'gauss-newton', 'limited-memory'"),
    ({"solver": "fatrop", "hessian": "limited-memory"}, "solver = 'fatrop' has no limited-memory Hessian"),
    ({"transcription": "ms"}, "transcription = 'ms': use None or one of 'multiple-shooting'"),
    ({"jit": "yes"}, "jit = 'yes' must be True or False or None"),
    ({"verify": 1}, "verify = 1 must be True or False"),
    ({"params": [1.0]}, "params = [1.0] must be a mapping of parameter names to values"),
]


@pytest.mark.parametrize("given, said", BAD, ids=[next(iter(g)) + "=" + repr(next(iter(g.values())))
                                                  for g, _ in BAD])
def test_a_bad_argument_is_one_problem_error_before_the_derivation(given, said, no_derivation):
    with pytest.raises(ProblemError) as bad:
        plan(*PARK, **given)
    assert bad.value.title == "invalid plan request"
    assert len(bad.value.problems) == 1
    assert said in bad.value.problems[0]


def test_every_problem_at_once_with_the_task_and_the_output_folder(tmp_path, no_derivation):
    """Bad arguments, an unknown gait and an output folder that is a file: one error, all five."""
    (tmp_path / "file").write_text("")
    with pytest.raises(ProblemError) as bad:
        plan("unicycle", "fowrard", intervals=3.5, workers="many", max_iter=-1, out_dir=tmp_path / "file")
    text = str(bad.value)
    assert "invalid plan request: 5 problem(s)" in text
    for said in ("intervals = 3.5", "workers = 'many'", "max_iter = -1", "unknown gait 'fowrard'",
                 "is a file: a directory is needed"):
        assert said in text


def test_what_the_command_line_gives_passes_unchanged():
    """The values the CLI passes (argparse's types) and numpy integers are accepted as they are."""
    from nhgait.dynamics.progress import Progress
    assert argument_problems(overrides=[], intervals=None, solver="auto", transcription=None, jit=None,
                             workers=1, hessian="auto", max_guesses=12, progress=Progress.silent(),
                             time_limit=None) == []
    assert argument_problems(overrides=["final.y=0.3"], intervals=np.int64(40), solver="ipopt",
                             transcription="collocation", jit=False, workers="auto", hessian="limited-memory",
                             max_guesses=np.int32(3), time_limit=float("inf"), animate=True,
                             out_dir="out") == []
    assert argument_problems(time_limit=1e300) == []        # in effect unlimited, kept as given


def test_a_single_override_string_is_one_override():
    """``overrides="final.y=0.3"`` was 11 errors, one per character; now it is one override."""
    assert override_list("final.y=0.3") == ["final.y=0.3"]
    assert override_list(("a=1",), 40) == ["a=1", "intervals=40"]
    assert override_list(None) == []
    assert override_list([1]) is None
    to_plan, out, options = checked_request(*PARK, dict(overrides="final.y=0.3", intervals=20, out_dir=None))
    assert options.intervals == 20
    assert out is None
    assert to_plan.task.intervals == 20
    assert to_plan.task.to_dict()["final"]["y"] == pytest.approx(0.3)
    assert resolve(*PARK, overrides="final.y=0.3").task.to_dict()["final"]["y"] == pytest.approx(0.3)


def test_limited_memory_with_auto_is_ipopt_alone():
    """``--hessian limited-memory`` is Ipopt's L-BFGS: with solver auto the planner uses Ipopt
    (it once tried FATROP first and stopped with "FATROP has no limited-memory Hessian")."""
    assert solver_order("auto", None, None, "limited-memory") == ("ipopt",)
    assert solver_order("auto", None, None, "exact") == ("fatrop", "ipopt")
    result = plan(*PARK, intervals=20, jit=False, hessian="limited-memory", verify=False)
    assert result.success
    assert {a.solver for a in result.attempts} == {"ipopt"}
    assert result.solution.settings["hessian"] == "limited-memory"


def test_cli_plan_refuses_fatrop_with_limited_memory_at_once(tmp_path, capsys, no_derivation):
    """Exit 2 with every problem (here two) before the derivation."""
    code = main(["plan", "unicycle", "--gait", "parallel-park", "--solver", "fatrop", "--hessian",
                 "limited-memory", "--time-limit", "-1", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert "invalid plan request: 2 problem(s)" in err
    assert "solver = 'fatrop' has no limited-memory Hessian" in err
    assert "time_limit = -1.0 must be a positive number of seconds" in err
    assert "internal error" not in err


def test_a_sweeps_workers_and_options_are_checked_before_the_derivation(tmp_path, monkeypatch):
    from nhgait.gaits.sweeps import point
    from nhgait.gaits.sweeps.driver import sweep

    def described(*args, **kwargs):
        raise AssertionError("derived before the request was checked")

    monkeypatch.setattr(point, "describe_case", described)
    with pytest.raises(ProblemError) as bad:
        sweep(*PARK, ["final.y=0.3:0.5:2"], out=tmp_path / "s", workers="2",
              options={"zzz": 1, "solver": "auto", "jit": "no", "time_limit": True})
    text = str(bad.value)
    assert "invalid sweep: 5 problem(s)" in text
    assert "options: unknown option 'zzz' (options: transcription, solver, jit, time_limit)" in text
    assert "options: solver = 'auto': a sweep point runs one solver: use 'ipopt' or 'fatrop'" in text
    assert "options: jit = 'no' must be True or False or None" in text
    assert "options: time_limit = True must be a positive number of seconds" in text
    assert "--workers must be ≥ 0 (a whole number of worker processes), got '2'" in text
    assert not (tmp_path / "s").exists()
