"""``nhgait track`` (gaits/tracking/) and link masses as parameters of a URDF scene.

References: the closed loop's physical claim (the feedback brings a mismatched robot at least
ten times closer to the plan's end than the open loop — measured ~1/100 on the unicycle with
J_θ +20 %), the seeded noise (same seed, same numbers, in this process, in a serial back end
and in worker processes), and for the URDF masses a second URDF file whose link mass and
inertia are scaled by hand (the parametrised Lagrangian at that mass equals the edited file's
to 1e-12 at random states). Like ``plan``: a bad plan file is one error (exit 2), a write that
fails at the end keeps tracking.json in a fallback, a study that runs out of time ends as a
clean failure with the samples it did, and SIGTERM/Ctrl-C during the samples stops it at once
leaving nothing (the samples made endless, so the signal always finds them running).
"""
from __future__ import annotations

import errno
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from nhgait.gaits.cli.main import main
from nhgait.gaits.tracking.study import track

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PARK = {"system": "unicycle", "task": "parallel-park", "overrides": ["intervals=30"],
        "mismatch": ["params.J_theta=1.2"]}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("track")
    return track(PARK["system"], PARK["task"], overrides=PARK["overrides"], mismatch=PARK["mismatch"],
                 samples=4, seed=3, out_dir=out), out


def test_tracking_json_reports_both_loops_with_units(study):
    result, out = study
    report = json.loads((out / "tracking.json").read_text())
    assert report["samples"] == 4
    assert report["mismatch"] == {"J_theta": 1.2}
    assert report["params"]["robot"]["J_theta"] == pytest.approx(1.2 * report["params"]["nominal"]["J_theta"])
    for loop in ("open_loop", "closed_loop"):
        f = report[loop]["final_position_error"]
        assert f["unit"] == "m"
        assert len(f["samples"]) == 4
        assert 0 <= f["median"] <= f["max"]
        errors = report[loop]["state_errors"]
        assert sorted(errors) == sorted(["x", "y", "theta", "phi", "theta_dot", "phi_dot"])
        assert errors["theta"]["unit"] == "rad"
        assert errors["theta_dot"]["unit"] == "rad/s"
        assert report[loop]["failed"] == 0
        assert report[loop]["saturation_time_s"]["max"] >= 0
    closed, opened = (report[loop]["final_position_error"] for loop in ("closed_loop", "open_loop"))
    assert closed["max"] <= 0.1 * opened["median"]
    assert report["closed_max_over_open_median"] <= 0.1
    for name in ("tracking.json", "solution.json", "tracking_paths.png", "tracking_errors.png"):
        assert (out / name).stat().st_size > 0


def test_noise_is_seeded_and_the_back_ends_agree(study):
    """The same seed gives the same samples in this process, in a serial back end and in two
    worker processes; another seed gives other samples."""
    result, out = study
    kwargs = dict(mismatch=PARK["mismatch"], samples=4, plan_file=out / "solution.json")
    finals = lambda r: r.report["closed_loop"]["final_position_error"]["samples"]  # noqa: E731
    here = track(PARK["system"], seed=3, **kwargs)
    assert finals(here) == pytest.approx(finals(result), rel=1e-9)
    assert (finals(track(PARK["system"], seed=3, workers=0, **kwargs))
            == pytest.approx(finals(here), rel=1e-12))
    assert (finals(track(PARK["system"], seed=3, workers=2, **kwargs))
            == pytest.approx(finals(here), rel=1e-12))
    assert finals(track(PARK["system"], seed=4, **kwargs)) != pytest.approx(finals(here), rel=1e-3)


def test_cli_track_writes_the_study_and_reads_a_plan(study, tmp_path, capsys):
    _, out = study
    code = main(["track", "unicycle", "--plan", str(out / "solution.json"), "--mismatch",
                 "params.J_theta=1.2", "--samples", "2", "--out", str(tmp_path), "--quiet"])
    assert code == 0
    assert "closed-loop worst / open-loop median" in capsys.readouterr().out
    assert (tmp_path / "tracking.json").exists()
    assert not (tmp_path / "solution.json").exists()


def test_cli_track_lists_every_problem_of_its_request(tmp_path, capsys):
    code = main(["track", "unicycle", "--gait", "parallel-park", "--mismatch", "params.mm=1.1", "--mismatch",
                 "m=2", "--mismatch", "params.r=-1", "--samples", "0", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "4 problem(s)" in err
    assert "did you mean 'm'?" in err
    assert "write params.NAME=FACTOR" in err
    assert "positive number" in err
    assert "--samples must be an integer ≥ 1" in err
    assert main(["track", "unicycle", "--plan", str(tmp_path / "none.json"), "--set", "final.y=0.3",
                 "--out", str(tmp_path)]) == 2


def test_cli_track_lists_every_bad_option_together_before_planning(tmp_path, capsys, monkeypatch):
    """A negative seed, a factor of −1, no samples and a negative noise: one error listing all
    four, exit 2, and no plan made (a negative seed was an internal error after the plan, and
    --state-noise hid the others)."""
    from nhgait.gaits import planner

    def no_plan(*args, **kwargs):
        raise AssertionError("planned before the request was checked")

    monkeypatch.setattr(planner, "plan", no_plan)
    code = main(["track", "unicycle", "--gait", "parallel-park", "--mismatch", "params.m=-1",
                 "--samples", "0", "--seed", "-1", "--state-noise", "-0.1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "invalid tracking study: 4 problem(s)" in err
    assert "--samples must be an integer ≥ 1, got 0" in err
    assert "--seed must be an integer ≥ 0, got -1" in err
    assert "--state-noise must be a finite number ≥ 0, got -0.1" in err
    assert "--mismatch 'params.m=-1': the factor must be a positive number" in err
    assert "internal error" not in err
    code = main(["track", "unicycle", "--gait", "parallel-park", "--seed", "-1", "--samples", "2",
                 "--out", str(tmp_path), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "1 problem(s)" in err and "--seed must be an integer ≥ 0, got -1" in err
    code = main(["track", "unicycle", "--gait", "fowrard", "--seed", "-1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "2 problem(s)" in err and "unknown gait 'fowrard'" in err and "--seed" in err


def test_a_parameter_mismatched_twice_is_refused_not_overwritten(tmp_path, capsys):
    """``--mismatch params.m=1.1 --mismatch params.m=1.2`` once kept the last factor silently."""
    code = main(["track", "unicycle", "--gait", "parallel-park", "--mismatch", "params.m=1.1",
                 "--mismatch", "params.m=1.2", "--out", str(tmp_path)])
    assert code == 2
    assert ("--mismatch params.m given 2 times ('params.m=1.1', 'params.m=1.2'): give each "
            "parameter once") in capsys.readouterr().err


def test_track_checks_its_python_arguments_like_the_options():
    """The API: a mapping of factors is checked like the strings, a single string is one item,
    seeds and noise are checked, every problem in one ProblemError before planning."""
    from nhgait.gaits.tracking.request import parse_mismatch
    from nhgait.gaits.tracking.runs import Noise
    from nhgait.ocp import ProblemError
    assert parse_mismatch("params.m=1.1", {"m": 1.0}) == {"m": 1.1}
    assert parse_mismatch({"m": 0.9}, {"m": 1.0}) == {"m": 0.9}
    with pytest.raises(ProblemError) as bad:
        track("unicycle", "parallel-park", mismatch={"m": -1.0, "mm": 2.0}, seed=2.5, samples=True,
              noise=Noise(float("nan"), 0.05))
    text = str(bad.value)
    assert "5 problem(s)" in text
    assert "--samples must be an integer ≥ 1, got True" in text
    assert "--seed must be an integer ≥ 0, got 2.5" in text
    assert "--state-noise must be a finite number ≥ 0, got nan" in text
    assert "--mismatch 'params.m=-1.0': the factor must be a positive number" in text
    assert "unknown parameter 'mm'" in text


def test_the_robot_starts_on_its_own_constraints():
    """robot_start against closed forms: a pendulum on a cart kept on px² + py² = l² with the
    robot's l 10 % longer lands on the robot's circle (the dependent coordinate solved) with
    px ṗx + py ṗy = 0; the snakeboard with its wheel base r 20 % longer gets velocities that
    meet the robot's two wheel constraints; with a mass changed nothing moves."""
    from nhgait.dynamics.derivation.input.scene import load_scene
    from nhgait.dynamics.derivation.system import System
    from nhgait.gaits.tracking.runs import robot_start
    cart = System(coordinates=["s", "px", "py"],
                  lagrangian="M*s_dot**2/2 + m*((s_dot + px_dot)**2 + py_dot**2)/2 - m*g*py",
                  holonomic=["px**2 + py**2 - l**2"], forces={"s": "F"},
                  parameters={"M": 2.0, "m": 0.5, "g": 9.81, "l": 0.7}, planar_frame=None,
                  name="cart_pendulum")
    angle, rate = 0.4, 1.3
    q = np.array([0.2, 0.7 * np.sin(angle), -0.7 * np.cos(angle)])
    qdot = np.array([0.5, 0.7 * rate * np.cos(angle), 0.7 * rate * np.sin(angle)])
    q1, qdot1 = robot_start(cart, q, qdot, {**cart.parameters, "l": 0.77})
    assert np.hypot(q1[1], q1[2]) == pytest.approx(0.77, rel=1e-12)
    assert q1[1] * qdot1[1] + q1[2] * qdot1[2] == pytest.approx(0.0, abs=1e-12)
    q2, qdot2 = robot_start(cart, q, qdot, {**cart.parameters, "M": 2.2})
    assert np.allclose(q2, q, rtol=0, atol=1e-14)
    assert np.allclose(qdot2, qdot, rtol=0, atol=1e-14)

    board = load_scene("snakeboard").system
    r = board.parameters["r"]
    q = np.array([0.1, -0.2, 0.3, 0.4, 0.5])                 # x, y, theta, psi, phi

    def wheels(qd, r):
        x, y, th, psi, phi = q
        return [-np.sin(th - phi) * qd[0] + np.cos(th - phi) * qd[1] - r * np.cos(phi) * qd[2],
                -np.sin(th + phi) * qd[0] + np.cos(th + phi) * qd[1] + r * np.cos(phi) * qd[2]]
    qdot = np.array([0.0, 0.0, 0.3, 0.2, 0.1])               # θ̇, ψ̇, φ̇; (ẋ, ẏ) from the wheels
    qdot[:2] = _on_both_wheels(q, qdot, r)
    assert np.allclose(wheels(qdot, r), 0.0, atol=1e-12)
    _, moved = robot_start(board, q, qdot, {**board.parameters, "r": 1.2 * r})
    assert np.allclose(wheels(moved, 1.2 * r), 0.0, atol=1e-12)
    assert not np.allclose(moved, qdot)
    _, same = robot_start(board, q, qdot, {**board.parameters, "m": 0.55})
    assert np.allclose(same, qdot, rtol=0, atol=1e-13)


def _on_both_wheels(q, qdot, r):
    """(ẋ, ẏ) meeting both snakeboard wheel constraints for the given θ̇ (a 2×2 solve)."""
    th, phi = q[2], q[4]
    A = np.array([[-np.sin(th - phi), np.cos(th - phi)], [-np.sin(th + phi), np.cos(th + phi)]])
    return np.linalg.solve(A, [r * np.cos(phi) * qdot[2], -r * np.cos(phi) * qdot[2]])


def _bad_plan_files(folder: Path, good: dict) -> dict:
    """Plan files nhgait must refuse, by what is wrong with them."""
    files = {"not JSON": "{\"feedback\": ", "a JSON list": "[1, 2]"}
    short = json.loads(json.dumps(good))
    short["feedback"]["gains"] = short["feedback"]["gains"][:-1]
    files["gains of the wrong shape"] = json.dumps(short)
    unread = json.loads(json.dumps(good))
    del unread["feedback"]["weights"]
    files["no weights"] = json.dumps(unread)
    paths = {}
    for i, (what, text) in enumerate(files.items()):
        paths[what] = folder / f"bad{i}.json"
        paths[what].write_text(text)
    paths["a directory"] = folder
    return paths


@pytest.mark.parametrize("what, said", [("not JSON", "is not JSON"), ("a JSON list", "holds a JSON list"),
                                        ("gains of the wrong shape", "feedback.gains has the shape"),
                                        ("no weights", "its feedback cannot be read"),
                                        ("a directory", "is a directory")])
def test_a_bad_plan_file_is_one_error(study, tmp_path, capsys, what, said):
    _, out = study
    bad = _bad_plan_files(tmp_path, json.loads((out / "solution.json").read_text()))[what]
    code = main(["track", "unicycle", "--plan", str(bad), "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert said in err
    assert "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_plan_of_another_robot_is_said_to_be_one(study, tmp_path, capsys):
    """The unicycle's plan tracked on the snakeboard: the file is another robot's (it was "invalid
    mismatch: unknown parameter 'J_phi'", the unicycle's parameters read as the snakeboard's)."""
    _, out = study
    code = main(["track", "snakeboard", "--plan", str(out / "solution.json"), "--mismatch", "params.m=1.1",
                 "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("nhgait: invalid plan file: 1 problem(s)\n")
    assert (f"{out / 'solution.json'} is a plan of 'unicycle/parallel-park', not of 'snakeboard': its "
            "coordinates (x, y, theta, phi) are not this robot's (x, y, theta, psi, phi)") in err
    assert "unknown parameter" not in err


def test_a_study_whose_files_cannot_be_written_keeps_its_report(study, sandbox, monkeypatch, capsys):
    """The disk fills while the figures are written: exit 1, the summary names the failure and
    the fallback, which holds the tracking.json of the summary's numbers; nothing half-written
    left behind."""
    from nhgait.gaits.tracking import plots
    _, out = study

    def no_space(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(plots, "write_tracking_figures", no_space)
    code = main(["track", "unicycle", "--plan", str(out / "solution.json"), "--mismatch",
                 "params.J_theta=1.2", "--samples", "2", "--out", str(sandbox.out / "t"), "--quiet"])
    text = capsys.readouterr().out
    assert code == 1
    assert re.search(r"NOT WRITTEN: writing .* failed: no space left", text)
    rescued = re.search(r"the tracking report was saved to (\S+tracking\.json)", text).group(1)
    assert rescued.startswith(str(sandbox.tmp))
    report = json.loads(Path(rescued).read_text())
    median = float(re.search(r"closed loop +final position error median ([-\d.e+]+)", text).group(1))
    assert report["closed_loop"]["final_position_error"]["median"] == pytest.approx(median, rel=1e-3)
    assert not (sandbox.out / "t").exists()           # created by this run, left empty: removed


def test_a_study_that_runs_out_of_time_is_a_clean_failure(study, tmp_path, monkeypatch):
    """Samples that take at least 0.5 s each (20 of them: 10 s) and a budget of 4 s: the study
    ends in the noise-free run or the samples (a loaded machine may need the budget for the
    first), not successful, with the budget and the phase in tracking.json, the samples it did
    summarised; exit 1 from the CLI."""
    from nhgait.gaits.tracking import runs
    _, out = study
    real = runs.run_sample

    def slow(ctx, case, index):
        if index >= 0:
            time.sleep(0.5)                 # slow work (each sample costs at least this), not a sync
        return real(ctx, case, index)
    monkeypatch.setattr(runs, "run_sample", slow)
    result = track("unicycle", plan_file=out / "solution.json", mismatch=["params.J_theta=1.2"], samples=20,
                   time_limit=4.0, out_dir=tmp_path / "t")
    assert not result.success
    assert result.overrun.phase in ("the noise-free run", "the samples")
    report = json.loads((tmp_path / "t" / "tracking.json").read_text())
    assert report["success"] is False
    assert report["samples_requested"] == 20
    assert report["samples"] < 20
    assert "the time budget of 4 s (--time-limit / track(time_limit=...)) ran out" in report["time_budget"][0]
    assert "--time-limit SECONDS" in report["time_budget"][1]
    if report["samples"]:
        assert len(report["closed_loop"]["final_position_error"]["samples"]) == report["samples"]


#: nhgait with every noisy sample endless (the noise-free run as it is), Ctrl-C as in a terminal
ENDLESS_SAMPLES = ("import signal, sys, time\n"
                   "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                   "from nhgait.gaits.tracking import runs\n"
                   "real = runs.run_sample\n"
                   "def endless(ctx, case, index):\n"
                   "    while index >= 0:\n"
                   "        real(ctx, case, index)\n"
                   "    return real(ctx, case, index)\n"
                   "runs.run_sample = endless\n"
                   "from nhgait.gaits.cli.main import main\n"
                   "sys.exit(main())\n")


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="needs POSIX process groups")
@pytest.mark.parametrize("signame, status, said",
                         [("SIGTERM", 143, "terminated"), ("SIGINT", 130, "interrupted")])
def test_a_study_stopped_during_its_samples_leaves_nothing(study, tmp_path, signame, status, said):
    """SIGTERM or Ctrl-C once the samples run: exit 143 or 130, nothing in --out (the files are
    written at the end, staged), no process of its session left."""
    _, out = study
    err_path = tmp_path / "stderr.txt"
    with open(err_path, "w") as err:
        proc = subprocess.Popen([sys.executable, "-c", ENDLESS_SAMPLES, "track", "unicycle", "--plan",
                                 str(out / "solution.json"), "--samples", "3", "--out", str(tmp_path / "o")],
                                stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
    try:
        deadline = time.monotonic() + 240.0
        while "3 samples in this process" not in err_path.read_text():
            assert proc.poll() is None, err_path.read_text()
            assert time.monotonic() < deadline, err_path.read_text()
            time.sleep(0.05)
        os.killpg(proc.pid, getattr(signal, signame))
        assert proc.wait(timeout=120.0) == status            # a hang guard
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert f"nhgait: {said}" in err_path.read_text()
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())
    deadline = time.monotonic() + 120.0                   # polled; fails only if the group never ends
    while True:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < deadline, "processes of the study's session outlived it"
        time.sleep(0.02)


# ------------------------------------------------------------------------------ URDF masses
def _lagrangian_at(scene_path, values, rng):
    from nhgait.dynamics.derivation.input.scene import load_scene
    system = load_scene(scene_path).system
    symbols = {**{s.name: s for s in system.L.free_symbols}}
    subs = {symbols[k]: v for k, v in values.items() if k in symbols}
    L = sp.lambdify([*system.q, *system.q_dot], system.L.subs(subs), "numpy")
    return [float(L(*rng.uniform(-1, 1, 2 * system.n))) for _ in range(5)], system


def test_a_named_link_mass_is_a_parameter_equal_to_the_edited_urdf(tmp_path):
    """masses = {board = "m_board"}: at its default L is the URDF's; at 1.3× it equals the L of
    a copy of the URDF whose board mass and inertia are multiplied by 1.3 (1e-12 relative)."""
    scene = (EXAMPLES / "snakeboard_urdf.toml").read_text()
    urdf = (EXAMPLES / "snakeboard.urdf").read_text()
    (tmp_path / "snakeboard.urdf").write_text(urdf)
    (tmp_path / "named.toml").write_text(scene.replace('inputs = {psi = "tau_psi", phi = "tau_phi"}',
                                                       'inputs = {psi = "tau_psi", phi = "tau_phi"}\n'
                                                       'masses = {board = "m_board"}'))
    edited = urdf.replace('<mass value="0.5"/>', '<mass value="0.65"/>').replace(
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.29" iyz="0" izz="0.3"/>',
        '<inertia ixx="0.013" ixy="0" ixz="0" iyy="0.377" iyz="0" izz="0.39"/>')
    assert edited != urdf
    (tmp_path / "edited.urdf").write_text(edited)
    (tmp_path / "edited.toml").write_text(scene.replace('urdf = "snakeboard.urdf"', 'urdf = "edited.urdf"'))
    named, system = _lagrangian_at(tmp_path / "named.toml", {"m_board": 0.65}, np.random.default_rng(1))
    assert system.parameters == {"m_board": 0.5}
    reference, _ = _lagrangian_at(tmp_path / "edited.toml", {}, np.random.default_rng(1))
    assert np.allclose(named, reference, rtol=1e-12, atol=1e-14)
    default, _ = _lagrangian_at(tmp_path / "named.toml", {"m_board": 0.5}, np.random.default_rng(1))
    original, _ = _lagrangian_at(EXAMPLES / "snakeboard_urdf.toml", {}, np.random.default_rng(1))
    assert np.allclose(default, original, rtol=1e-12, atol=1e-14)


def test_bad_mass_names_are_listed(tmp_path):
    from nhgait.dynamics.derivation.input.scene import load_scene
    from nhgait.dynamics.errors import ModelError
    scene = (EXAMPLES / "snakeboard_urdf.toml").read_text()
    (tmp_path / "snakeboard.urdf").write_text((EXAMPLES / "snakeboard.urdf").read_text())
    (tmp_path / "bad.toml").write_text(scene.replace(
        'inputs = {psi = "tau_psi", phi = "tau_phi"}',
        'inputs = {psi = "tau_psi", phi = "tau_phi"}\nmasses = {boards = "m", rotor = "m_r", board = "1x"}'))
    with pytest.raises(ModelError) as info:
        load_scene(tmp_path / "bad.toml")
    text = str(info.value)
    assert "unknown link 'boards'" in text
    assert "link 'rotor' has no mass" in text
    assert "masses.board must be a parameter name" in text
