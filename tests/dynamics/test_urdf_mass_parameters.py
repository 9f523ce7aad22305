"""Link masses as parameters in a URDF scene (dynamics/derivation/urdf/mass_parameters.py), on
the snakeboard's URDF (examples/snakeboard.urdf; the board 0.5 kg, I = diag(0.01, 0.29, 0.3)).
The independent reference: the same URDF with the board's mass and inertia doubled *in the
file* — the Lagrangian with m_board = 1.0 must be that file's Lagrangian exactly (a uniform
change of density: T and V linear in the link's mass properties), and with m_board = 0.5 the
URDF's own. Bad names are one error each."""
from __future__ import annotations

import shutil
from pathlib import Path
from types import SimpleNamespace

import pytest
import sympy as sp

from nhgait.dynamics.derivation.input.scene import load_scene
from nhgait.dynamics.derivation.urdf.mass_parameters import mass_problems
from nhgait.dynamics.errors import ModelError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
SCENE = """[system]
urdf = "{urdf}"
base = "planar"
joints = ["psi", "phi"]
skates = ["back_wheels", "front_wheels"]
inputs = {{psi = "tau_psi", phi = "tau_phi"}}
{extra}
"""


def _system(folder: Path, urdf_text: str, extra: str = "", name: str = "board.urdf"):
    (folder / name).write_text(urdf_text)
    scene = folder / f"{name}.toml"
    scene.write_text(SCENE.format(urdf=name, extra=extra))
    return load_scene(scene).system


def _lagrangian(system, values: dict):
    subs = {s: values.get(s.name, system.parameters.get(s.name)) for s in system.param_symbols}
    return sp.expand(system.L.subs(subs))


def test_a_mass_parameter_is_a_uniform_change_of_density(tmp_path):
    original = (EXAMPLES / "snakeboard.urdf").read_text()
    heavy = original.replace('<mass value="0.5"/>', '<mass value="1.0"/>').replace(
        '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.29" iyz="0" izz="0.3"/>',
        '<inertia ixx="0.02" ixy="0" ixz="0" iyy="0.58" iyz="0" izz="0.6"/>')
    assert heavy.count('<mass value="1.0"/>') == 1 and "izz=\"0.6\"" in heavy
    named = _system(tmp_path, original, 'masses = {board = "m_board"}')
    assert "m_board" in named.parameters and named.parameters["m_board"] == pytest.approx(0.5)
    doubled = _system(tmp_path, heavy, name="heavy.urdf")
    plain = _system(tmp_path, original, name="plain.urdf")
    assert sp.simplify(_lagrangian(named, {"m_board": 1.0}) - _lagrangian(doubled, {})) == 0
    assert sp.simplify(_lagrangian(named, {"m_board": 0.5}) - _lagrangian(plain, {})) == 0


def test_bad_mass_names_are_named(tmp_path):
    shutil.copy(EXAMPLES / "snakeboard.urdf", tmp_path / "s.urdf")
    (tmp_path / "s.toml").write_text(SCENE.format(urdf="s.urdf", extra='masses = {boad = "m", rotor = "2x"}'))
    with pytest.raises(ModelError) as caught:
        load_scene(tmp_path / "s.toml")
    text = str(caught.value)
    assert "unknown link 'boad'" in text and "link 'rotor' has no mass" in text and "'2x'" in text
    robot = SimpleNamespace(links={"board": SimpleNamespace(inertial=SimpleNamespace(mass=0.5)),
                                   "rotor": SimpleNamespace(inertial=None)})
    found = mass_problems(robot, {"board": "m", "rotor": "m"}, {"m": 1.0})
    assert found == ["[system].masses.board: 'm' is also in [system].parameters",
                     "[system].masses.rotor: link 'rotor' has no mass in the URDF to scale",
                     "[system].masses.rotor: 'm' is also in [system].parameters"]
    assert mass_problems(robot, {"board": "m_b"}, {}) == []
