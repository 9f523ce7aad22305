"""What a plan gives out beside solution.json (gaits/files/exports.py): the summary's sentence on the
states a gait was solved in and stored in, and trajectory.csv where the plan's folder is."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from nhgait.gaits.files.exports import TRAJECTORY_CSV, states_text, write_trajectory_csv


def test_one_list_when_the_solve_and_the_file_agree():
    same = SimpleNamespace(state_names=("x", "y", "p"), settings={})
    assert states_text(same) == "states (x, y, p); trajectory.csv adds q̇"
    other = SimpleNamespace(state_names=("x", "y", "p", "pt_psi"),
                            settings={"transcribed_in": ["x", "y", "forward_velocity", "psi_dot"]})
    assert states_text(other) == ("solved in the states (x, y, forward_velocity, psi_dot); solution.json "
                                  "holds (x, y, p, pt_psi) and trajectory.csv adds q̇")


def test_the_csv_goes_into_the_plans_folder(tmp_path):
    calls = []

    class _Solution:
        def to_csv(self, path, units=None):
            calls.append((path, units))
            return path

    assert write_trajectory_csv(_Solution(), str(tmp_path), units={"x": "m"}) == tmp_path / TRAJECTORY_CSV
    assert calls == [(Path(tmp_path) / "trajectory.csv", {"x": "m"})]
