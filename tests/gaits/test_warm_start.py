"""A previous answer as a guess (``plan(..., guess=)``, ``nhgait plan --guess``;
gaits/planning/warm_start.py, gaits/files/solution_file.py): a solution.json whose trajectory is
not well formed,
or that belongs to another robot, is one ProblemError listing every problem — before any
derivation — never numpy's or CasADi's exception; a good one is resampled faithfully.

The bad files are the unicycle's own solution.json (parallel park, N = 20) with one part broken
by hand, so each expected message follows from the edit; the other robots are the built-in
snakeboard and examples/car.toml, whose coordinates and inputs the scene files state."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nhgait.gaits.cli.main import main
from nhgait.gaits.planner import plan, prepare
from nhgait.gaits.planning.warm_start import warm_start
from nhgait.gaits.tasks.sources import resolve
from nhgait.ocp import ProblemError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PARK = ("unicycle", "parallel-park")
INTERVALS = 20


@pytest.fixture(scope="module")
def park(tmp_path_factory):
    """(the unicycle's solution.json as a dict, its path) from one small plan."""
    out = tmp_path_factory.mktemp("park")
    result = plan(*PARK, intervals=INTERVALS, jit=False, verify=False, out_dir=out)
    assert result.success
    path = out / "solution.json"
    return json.loads(path.read_text()), path


@pytest.fixture(scope="module")
def park_problem():
    """The unicycle's parallel-park problem on the same grid (N = 20)."""
    return prepare(resolve(*PARK, overrides=[f"intervals={INTERVALS}"])).problem


def _edited(good: dict, folder: Path, edit) -> Path:
    """A copy of ``good`` with ``edit(copy)`` applied, written to ``folder``/guess.json."""
    data = json.loads(json.dumps(good))
    edit(data)
    path = folder / "guess.json"
    path.write_text(json.dumps(data))
    return path


def _problems(guess, system=PARK[0], task=PARK[1]) -> tuple:
    """The problems of the ProblemError ``plan`` raises for ``guess`` (before any derivation)."""
    with pytest.raises(ProblemError) as info:
        plan(system, task, intervals=INTERVALS, jit=False, verify=False, guess=guess)
    assert info.value.title == "invalid guess"
    return info.value.problems


def _reversed_t(data):
    data["trajectory"]["t"] = data["trajectory"]["t"][::-1]


def _nan_in_u(data):
    data["trajectory"]["u"][3][1] = float("nan")      # json writes NaN, as Python's encoder does


BROKEN = [
    # (what, the edit, the message fragment it must produce)
    ("no trajectory", lambda d: d.pop("trajectory"),
     "has no 'trajectory', not the object with t, q, qdot and u"),
    ("trajectory.t a string", lambda d: d["trajectory"].update(t="abc"),
     "trajectory.t must be a list of numbers, got 'abc'"),
    ("fewer rows of q than times", lambda d: d["trajectory"].update(q=d["trajectory"]["q"][:10]),
     f"trajectory.q has 10 rows, trajectory.t needs {INTERVALS + 1} (one per time)"),
    ("u one row short", lambda d: d["trajectory"].update(u=d["trajectory"]["u"][:-1]),
     f"trajectory.u has {INTERVALS - 1} rows, trajectory.t needs {INTERVALS} (one per interval)"),
    ("time reversed", _reversed_t, "trajectory.t must increase strictly; t[1] = "),
    ("NaN in u", _nan_in_u, "trajectory.u holds values that are not finite numbers"),
    ("a ragged q", lambda d: d["trajectory"]["q"][4].pop(),
     "trajectory.q has rows of different lengths (3, 4)"),
    ("numbers as text", lambda d: d["trajectory"]["qdot"][0].__setitem__(0, "0.0"),
     "trajectory.qdot must be a list of rows of numbers, one row per time, got"),
    ("a column missing", lambda d: [row.pop() for row in d["trajectory"]["q"]],
     "trajectory.q has 3 columns, trajectory.coordinates names 4"),
    ("one time", lambda d: d["trajectory"].update(t=[0.0]), "trajectory.t has 1 time(s)"),
]


@pytest.mark.parametrize("edit, said", [pytest.param(*case[1:], id=case[0]) for case in BROKEN])
def test_a_broken_trajectory_is_named_in_one_error(park, tmp_path, edit, said):
    good, _ = park
    path = _edited(good, tmp_path, edit)
    problems = _problems(path)
    assert any(p.startswith(f"the guess {path}") for p in problems), problems
    assert any(said in p for p in problems), problems


def test_every_problem_of_a_file_is_listed_at_once(park, tmp_path):
    """Four independent faults, four sentences in one error."""
    def edit(data):
        tr = data["trajectory"]
        _reversed_t(data)
        tr["q"] = tr["q"][:10]
        tr["qdot"] = "abc"
        _nan_in_u(data)
    problems = _problems(_edited(park[0], tmp_path, edit))
    assert len(problems) == 4, problems
    text = "\n".join(problems)
    for said in ("trajectory.t must increase strictly", "trajectory.q has 10 rows",
                 "trajectory.qdot must be a list of rows of numbers",
                 "trajectory.u holds values that are not finite"):
        assert said in text


def test_a_plan_of_another_robot_is_refused_naming_both(park):
    """The unicycle (x, y, theta, phi; tau_theta, tau_phi) is not the snakeboard (5
    coordinates), nor the car of examples/car.toml, which has the unicycle's coordinates but
    other inputs (F, tau_phi)."""
    _, path = park
    problem, = _problems(path, "snakeboard", "forward")
    assert problem == (f"the guess {path} is a plan of 'unicycle/parallel-park', not of "
                       "'snakeboard/forward': its coordinates (x, y, theta, phi) are not this robot's "
                       "(x, y, theta, psi, phi); "
                       "its inputs (tau_theta, tau_phi) are not this robot's (tau_psi, tau_phi)")
    problem, = _problems(path, str(EXAMPLES / "car.toml"), None)
    assert problem == (f"the guess {path} is a plan of 'unicycle/parallel-park', not of 'car/parallel-park': "
                       "its inputs (tau_theta, tau_phi) are not this robot's (F, tau_phi)")


def test_unnamed_warm_data_of_another_size_is_refused(park, park_problem):
    """A sweep's warm data without names: the counts are compared instead."""
    tr = park[0]["trajectory"]
    data = {"trajectory": {"t": tr["t"], "q": [row[:3] for row in tr["q"]],
                           "qdot": [row[:3] for row in tr["qdot"]], "u": tr["u"]}}
    with pytest.raises(ProblemError, match=r"is a plan of another robot, not of 'unicycle/parallel-park': "
                                           r"it has 3 coordinates, this robot 4"):
        warm_start(data, park_problem)


def test_a_good_file_is_resampled_faithfully(park, park_problem):
    """On the file's own grid the guess is the file: the configurations at the nodes (the first
    n states of z = (q, y)) and the inputs on the intervals, exactly; a trajectory whose clock
    starts at 5 s gives the same guess (normalised time (t − t₀)/(t_K − t₀))."""
    good, path = park
    tr = good["trajectory"]
    guess = warm_start(path, park_problem)
    assert guess.states.shape == (len(park_problem.state_names), INTERVALS + 1)
    np.testing.assert_allclose(guess.states[:4], np.array(tr["q"]).T, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(guess.controls, np.array(tr["u"]).T)
    later = json.loads(json.dumps(good))
    later["trajectory"]["t"] = [t + 5.0 for t in tr["t"]]
    shifted = warm_start(later, park_problem)
    np.testing.assert_allclose(shifted.states, guess.states, rtol=1e-12, atol=1e-12)


def test_cli_plan_with_another_robots_guess_exits_2(park, tmp_path, capsys):
    """``nhgait plan snakeboard --guess <the unicycle's solution.json>``: exit 2, the message,
    no internal error, nothing written."""
    _, path = park
    out = tmp_path / "o"
    code = main(["plan", "snakeboard", "--gait", "forward", "--guess", str(path), "--out", str(out),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "nhgait: invalid guess: 1 problem(s)" in err
    assert "is a plan of 'unicycle/parallel-park', not of 'snakeboard/forward'" in err
    assert "internal error" not in err
    assert "Traceback" not in err
    assert not (out / "solution.json").exists()
