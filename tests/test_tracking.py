"""``nhgait track`` (gaits/tracking/) and link masses as parameters of a URDF scene.

References: the closed loop's physical claim (the feedback brings a mismatched robot at least
ten times closer to the plan's end than the open loop — measured ~1/100 on the unicycle with
J_θ +20 %), the seeded noise (same seed, same numbers, in this process, in a serial back end
and in worker processes), and for the URDF masses a second URDF file whose link mass and
inertia are scaled by hand (the parametrised Lagrangian at that mass equals the edited file's
to 1e-12 at random states).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from nhgait.gaits.cli.main import main
from nhgait.gaits.tracking.study import track

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PARK = {"system": "unicycle", "task": "parallel-park", "overrides": ["intervals=30"],
        "mismatch": ["params.J_theta=1.2"]}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("track")
    return track(PARK["system"], PARK["task"], overrides=PARK["overrides"], mismatch=PARK["mismatch"], samples=4,
                 seed=3, out_dir=out), out


def test_tracking_json_reports_both_loops_with_units(study):
    result, out = study
    report = json.loads((out / "tracking.json").read_text())
    assert report["samples"] == 4 and report["mismatch"] == {"J_theta": 1.2}
    assert report["params"]["robot"]["J_theta"] == pytest.approx(1.2 * report["params"]["nominal"]["J_theta"])
    for loop in ("open_loop", "closed_loop"):
        f = report[loop]["final_position_error"]
        assert f["unit"] == "m" and len(f["samples"]) == 4 and 0 <= f["median"] <= f["max"]
        errors = report[loop]["state_errors"]
        assert sorted(errors) == sorted(["x", "y", "theta", "phi", "theta_dot", "phi_dot"])
        assert errors["theta"]["unit"] == "rad" and errors["theta_dot"]["unit"] == "rad/s"
        assert report[loop]["failed"] == 0 and report[loop]["saturation_time_s"]["max"] >= 0
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
    assert finals(track(PARK["system"], seed=3, workers=0, **kwargs)) == pytest.approx(finals(here), rel=1e-12)
    assert finals(track(PARK["system"], seed=3, workers=2, **kwargs)) == pytest.approx(finals(here), rel=1e-12)
    assert finals(track(PARK["system"], seed=4, **kwargs)) != pytest.approx(finals(here), rel=1e-3)


def test_cli_track_writes_the_study_and_reads_a_plan(study, tmp_path, capsys):
    _, out = study
    code = main(["track", "unicycle", "--plan", str(out / "solution.json"), "--mismatch", "params.J_theta=1.2",
                 "--samples", "2", "--out", str(tmp_path), "--quiet"])
    assert code == 0
    assert "closed-loop worst / open-loop median" in capsys.readouterr().out
    assert (tmp_path / "tracking.json").exists() and not (tmp_path / "solution.json").exists()


def test_cli_track_lists_every_problem_of_its_request(tmp_path, capsys):
    code = main(["track", "unicycle", "--gait", "parallel-park", "--mismatch", "params.mm=1.1", "--mismatch", "m=2",
                 "--mismatch", "params.r=-1", "--samples", "0", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "4 problem(s)" in err and "did you mean 'm'?" in err and "write params.NAME=FACTOR" in err
    assert "positive number" in err and "--samples must be an integer ≥ 1" in err
    assert main(["track", "unicycle", "--plan", str(tmp_path / "none.json"), "--set", "final.y=0.3",
                 "--out", str(tmp_path)]) == 2


# ------------------------------------------------------------------------------ URDF masses
def _lagrangian_at(scene_path, values, rng):
    from nhgait.dynamics.derivation.scene import load_scene
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
    from nhgait.dynamics.derivation.scene import load_scene
    from nhgait.dynamics.errors import ModelError
    scene = (EXAMPLES / "snakeboard_urdf.toml").read_text()
    (tmp_path / "snakeboard.urdf").write_text((EXAMPLES / "snakeboard.urdf").read_text())
    (tmp_path / "bad.toml").write_text(scene.replace(
        'inputs = {psi = "tau_psi", phi = "tau_phi"}',
        'inputs = {psi = "tau_psi", phi = "tau_phi"}\nmasses = {boards = "m", rotor = "m_r", board = "1x"}'))
    with pytest.raises(ModelError) as info:
        load_scene(tmp_path / "bad.toml")
    text = str(info.value)
    assert "unknown link 'boards'" in text and "link 'rotor' has no mass" in text
    assert "masses.board must be a parameter name" in text
