"""Scene files: the same meaning as the Python API; unknown keys are errors."""
import numpy as np
import pytest

from nhgait.dynamics import ModelError, load_scene

GOOD = '''
[system]
name = "cart"
coordinates = ["x", "phi"]
lagrangian = "m*x_dot**2/2 + J*phi_dot**2/2"
constraints = ["x_dot - r*phi_dot"]
[system.forces]
phi = "tau"
[system.parameters]
m = 1.0
J = 0.1
r = "1/2"
[simulation]
q0 = [0, 0]
qdot0 = [0.5, 1.0]
t_final = "pi"
samples = 11
[simulation.inputs]
tau = "0.1*sin(t) - phi_dot"
'''


def write(tmp_path, text):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


def test_good_scene(tmp_path):
    scene = load_scene(write(tmp_path, GOOD))
    assert scene.system.coordinates == ("x", "phi")
    assert scene.system.parameters["r"] == 0.5
    assert scene.simulation.t_final == pytest.approx(np.pi)
    assert scene.simulation.t_eval.shape == (11,)
    u = scene.simulation.controller(np.pi / 2, [0, 0], [0, 2.0])
    np.testing.assert_allclose(u, [0.1 - 2.0], rtol=1e-15)


def test_unknown_keys_are_errors(tmp_path):
    text = GOOD.replace('name = "cart"', 'name = "cart"\ncolour = "red"').replace("samples = 11",
                                                                                  "samples = 11\nstep = 0.1")
    with pytest.raises(ModelError) as info:
        load_scene(write(tmp_path, text))
    msg = str(info.value)
    assert "[system]: unknown key(s) ['colour']" in msg
    assert "[simulation]: unknown key(s) ['step']" in msg


def test_unknown_top_level_table(tmp_path):
    with pytest.raises(ModelError, match=r"unknown top-level table\(s\) \['plot'\]"):
        load_scene(write(tmp_path, GOOD + "\n[plot]\nx = 1\n"))


def test_missing_input_law_and_bad_sizes(tmp_path):
    text = GOOD.replace('tau = "0.1*sin(t) - phi_dot"', "").replace("q0 = [0, 0]", "q0 = [0, 0, 0]")
    with pytest.raises(ModelError) as info:
        load_scene(write(tmp_path, text))
    msg = str(info.value)
    assert "q0 has 3 entries" in msg
    assert "no law for input(s) ['tau']" in msg


def test_bad_horizon_and_samples(tmp_path):
    text = GOOD.replace('t_final = "pi"', "t_final = -1").replace("samples = 11", "samples = 1")
    with pytest.raises(ModelError) as info:
        load_scene(write(tmp_path, text))
    assert "must be greater than t0" in str(info.value)
    assert "samples must be an integer from 2" in str(info.value)


def test_toml_syntax_error(tmp_path):
    with pytest.raises(ModelError, match="TOML syntax error"):
        load_scene(write(tmp_path, "[system\n"))


def test_missing_file_and_unknown_builtin(tmp_path):
    with pytest.raises(ModelError, match="does not exist"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(ModelError, match="neither a scene file nor a built-in scene"):
        load_scene("bicycle")
