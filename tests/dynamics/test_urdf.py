"""Systems from URDF files (no Pinocchio needed): the snakeboard and the roller racer written as
URDF give the equations of their written scenes (metric, potential, constraint distribution and
forces at random states; the same runs), and bad URDF input is one error naming each problem.
References: the written scenes (dynamics/scenes/snakeboard.toml, examples/roller_racer.toml)
and the KanesMethod + DOP853 value x(10π) = 2.2990248 of the thesis PD run."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import derive, simulate
from nhgait.dynamics.derivation.input.scene import load_scene, scene_from_text
from nhgait.dynamics.errors import ModelError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _subs(system):
    return {s: v for s, v in system.param_subs().items()}


@pytest.mark.parametrize("written, urdf", [("snakeboard", "snakeboard_urdf.toml"),
                                           (str(EXAMPLES / "roller_racer.toml"), "roller_racer_urdf.toml")])
def test_urdf_scene_has_the_written_equations(written, urdf):
    a, b = load_scene(written).system, load_scene(EXAMPLES / urdf).system
    assert a.coordinates == b.coordinates
    assert a.k == b.k
    assert a.inputs == b.inputs
    a_num = [sp.lambdify([a.q, a.q_dot, a.input_symbols, sp.Symbol("t", real=True)],
                         e.xreplace(_subs(a)), "numpy")
             for e in (a.mass_matrix(), a.potential(), a.omega(), sp.Matrix(a.tau))]
    b_num = [sp.lambdify([b.q, b.q_dot, b.input_symbols, sp.Symbol("t", real=True)], e, "numpy")
             for e in (b.mass_matrix(), b.potential(), b.omega(), sp.Matrix(b.tau))]
    rng = np.random.default_rng(4)
    for _ in range(10):
        q, qd, u = rng.uniform(-1.2, 1.2, a.n), rng.uniform(-1, 1, a.n), rng.uniform(-1, 1, len(a.inputs))
        t = rng.uniform(0, 5)
        (Ma, Va, Wa, Fa), (Mb, Vb, Wb, Fb) = ([np.array(f(q, qd, u, t), dtype=float) for f in fs]
                                              for fs in (a_num, b_num))
        np.testing.assert_allclose(Mb, Ma, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Vb, Va, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Fb, Fa, rtol=0, atol=1e-12)
        # the same constraint distribution: each row of one is ± the same row of the other
        for row_a, row_b in zip(Wa, Wb, strict=True):
            sign = np.sign(row_a @ row_b)
            np.testing.assert_allclose(sign * row_b, row_a, rtol=0, atol=1e-12)


def _final_state(scene, rtol=1e-12):
    spec = scene.simulation
    model = derive(scene.system, "reduced")
    traj = simulate(model, (spec.t0, spec.t_final), spec.q0, spec.qdot0, controller=spec.controller,
                    method="DOP853", rtol=rtol, atol=rtol * 1e-2, t_eval=[spec.t0, spec.t_final])
    assert traj.success, traj.message
    return traj.q[-1]


def test_snakeboard_urdf_pd_run_matches_the_written_scene():
    written = _final_state(load_scene("snakeboard"))
    from_urdf = _final_state(load_scene(EXAMPLES / "snakeboard_urdf.toml"))
    np.testing.assert_allclose(from_urdf, written, rtol=0, atol=1e-9)
    assert from_urdf[0] == pytest.approx(2.2990248, abs=2e-7)   # KanesMethod + DOP853 at 1e-12


def test_roller_racer_urdf_run_matches_the_written_scene():
    written = _final_state(load_scene(EXAMPLES / "roller_racer.toml"), rtol=1e-11)
    from_urdf = _final_state(load_scene(EXAMPLES / "roller_racer_urdf.toml"), rtol=1e-11)
    np.testing.assert_allclose(from_urdf, written, rtol=0, atol=1e-8)
    assert abs(written[0]) > 0.05                     # it does move


# ------------------------------------------------------------------ bad input
WHEEL = """<link name="{name}"><inertial><mass value="0.5"/>
  <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.002"/></inertial><collision><geometry><cylinder radius="0.1" length="0.02"/></geometry>
  </collision></link>
<joint name="{name}_joint" type="continuous"><parent link="body"/><child link="{name}"/>
  <origin xyz="0 {y} 0.1" rpy="-1.5707963267948966 0 0"/><axis xyz="0 0 1"/><limit effort="3" velocity="9"/>
</joint>"""  # noqa: E501 - the URDF as written, one link per line
BODY = """<link name="body"><inertial><mass value="4"/>
  <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.2"/></inertial></link>"""


def _robot(*parts):
    return "<?xml version='1.0'?>\n<robot name='cart'>" + "\n".join(parts) + "</robot>"


def _scene(tmp_path, urdf_text, system_lines):
    (tmp_path / "robot.urdf").write_text(urdf_text)
    (tmp_path / "s.toml").write_text('[system]\nurdf = "robot.urdf"\n' + system_lines)
    return tmp_path / "s.toml"


def _problems(path):
    with pytest.raises(ModelError) as info:
        load_scene(path)
    return info.value.problems


def test_a_differential_drive_from_urdf(tmp_path):
    urdf = _robot(BODY, WHEEL.format(name="left", y=0.2), WHEEL.format(name="right", y=-0.2))
    scene = load_scene(_scene(tmp_path, urdf, 'joints = ["left_joint", "right_joint"]\n'
                              'rolling = ["left_joint", "right_joint"]\n'
                              'inputs = {left_joint = "tau_l", right_joint = "tau_r"}\n'
                              'names = {left_joint = "phi_l"}\n'
                              '[task]\nhorizon = 2.0\nfinal = {x = 1.0}\n'))
    system = scene.system
    assert system.coordinates == ("x", "y", "theta", "phi_l", "right_joint")
    assert (system.n, system.k) == (5, 3)         # the second side-slip row is dropped
    # each wheel: u ∓ 0.2 θ̇ = 0.1 φ̇ (rolling), w = 0 (no side slip): ω q̇ = 0 for this q̇
    theta, u, rate = 0.3, 0.5, 0.7
    q_dot = [u * np.cos(theta), u * np.sin(theta), rate, (u - 0.2 * rate) / 0.1, (u + 0.2 * rate) / 0.1]
    W = np.array(sp.lambdify([system.q], system.omega())([0, 0, theta, 0, 0]), dtype=float)
    np.testing.assert_allclose(W @ q_dot, 0, atol=1e-14)
    assert scene.task["control_bounds"] == {"tau_l": [-3.0, 3.0], "tau_r": [-3.0, 3.0]}  # effort limits
    assert scene.task["bounds"]["phi_l_dot"] == [-9.0, 9.0]                               # velocity limits
    assert system.tau[3] == sp.Symbol("tau_l", real=True)


@pytest.mark.parametrize("urdf, keys, expected", [
    (_robot(BODY, WHEEL.format(name="left", y=0.2)), 'joints = ["left_joint", "nope"]\n',
     ["unknown joint 'nope'"]),
    (_robot(BODY, "<link name='arm'/><joint name='lift' type='prismatic'><parent link='body'/><child "
                  "link='arm'/>"
            "<axis xyz='0 0 1'/><limit lower='0' upper='0.3' effort='100' velocity='1'/></joint>"),
     'locked = {lift = 0.5}\n', ["locked.lift = 0.5 is outside the joint's limits [0, 0.3]"]),
    (_robot(BODY, WHEEL.format(name="left", y=0.2).replace("<collision>", "<visual>")
            .replace("</collision>", "</visual>")),
     'joints = ["left_joint"]\nrolling = ["left_joint"]\n', ["has no collision cylinder; give radius"]),
    (_robot(BODY, WHEEL.format(name="left", y=0.2).replace('rpy="-1.5707963267948966 0 0"', 'rpy="0 0 0"')),
     'joints = ["left_joint"]\nrolling = ["left_joint"]\n', ["cannot roll on the ground plane"]),
    (_robot(BODY, WHEEL.format(name="left", y=0.2).replace('0.1" rpy', '0.3" rpy')),
     'joints = ["left_joint"]\nrolling = ["left_joint"]\n', ["does not touch the ground"]),
    (_robot("<link name='world'/>", BODY, "<joint name='free' type='floating'><parent link='world'/>"
            "<child link='body'/></joint>"), '', ["joint 'free' is floating"]),
    (_robot(BODY, "<link name='a'/>", "<link name='b'/>",
            "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>",
            "<joint name='j2' type='fixed'><parent link='b'/><child link='a'/></joint>"),
     '', ["not reached from the root 'body': a closed loop"]),
    (_robot("<link name='a'/>", "<link name='b'/>",
            "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>",
            "<joint name='j2' type='fixed'><parent link='b'/><child link='a'/></joint>"),
     '', ["no root link"]),
    (_robot(BODY, "<link name='c'/>",
            "<joint name='j1' type='fixed'><parent link='body'/><child link='c'/></joint>",
            "<joint name='j2' type='fixed'><parent link='body'/><child link='c'/></joint>"),
     '', ["child of two joints ('j1' and 'j2'): a closed loop"]),
    (_robot(BODY, "<link name='broken'>"), '', ["malformed XML"]),
    ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY lol "lol">]><robot name="x">' + BODY + '</robot>', '',
     ["document type declaration"]),
])
def test_bad_urdf_is_one_error_naming_the_problem(tmp_path, urdf, keys, expected):
    problems = _problems(_scene(tmp_path, urdf, keys))
    for text in expected:
        assert any(text in p for p in problems), problems


def test_every_problem_is_listed_at_once(tmp_path):
    urdf = _robot(BODY, WHEEL.format(name="left", y=0.2), WHEEL.format(name="right", y=-0.2))
    problems = _problems(_scene(tmp_path, urdf,
                                'joints = ["left_joint", "ghost"]\nrolling = ["right_joint"]\n'
                                'inputs = {left = "u"}\nbase = "floating"\ncolour = "red"\n'
                                'names = {left_joint = "2x"}\n'))
    for text in ("unknown key(s) ['colour']", 'only "planar"', "unknown joint 'ghost'",
                 "wheel 'right_joint' must be a coordinate", "'left' is not a joint kept as a coordinate",
                 "names.left_joint must be an identifier"):
        assert any(text in p for p in problems), (text, problems)


def test_missing_urdf_file(tmp_path):
    (tmp_path / "s.toml").write_text('[system]\nurdf = "nothere.urdf"\n')
    assert any("does not exist" in p for p in _problems(tmp_path / "s.toml"))


def test_urdf_scene_text_resolves_relative_to_its_source():
    text = (EXAMPLES / "roller_racer_urdf.toml").read_text()
    scene = scene_from_text(text, str(EXAMPLES / "roller_racer_urdf.toml"))
    assert scene.system.coordinates == ("x", "y", "theta", "phi")


# ------------------------------------------------------------------ TIAGo (example-robot-data)
def _tiago_scene(name):
    scene_path = EXAMPLES / name
    from nhgait.dynamics.derivation.urdf.builder import resolve_path
    try:
        resolve_path("example-robot-data:tiago_description/robots/tiago.urdf", EXAMPLES)
    except ModelError:
        pytest.skip("example-robot-data is not installed (pip install 'nhgait[pinocchio]')")
    return scene_path


def test_tiago_parallel_park_is_planned_within_its_limits(tmp_path, capsys):
    from nhgait.gaits.cli.main import main
    out = tmp_path / "tiago"
    code = main(["plan", str(_tiago_scene("tiago_park.toml")), "--intervals", "30", "--no-jit", "--no-gif",
                 "--quiet", "--out", str(out)])
    assert code == 0, capsys.readouterr().out
    import json
    data = json.loads((out / "solution.json").read_text())
    trajectory = data["trajectory"]
    q, q_dot = np.array(trajectory["q"]), np.array(trajectory["qdot"])
    np.testing.assert_allclose(q[-1, :3], [0.0, 0.5, 0.0], atol=1e-7)
    np.testing.assert_allclose(q_dot[[0, -1]], 0.0, atol=1e-7)
    for values in trajectory["controls"].values():           # TIAGo's URDF: effort="6.0"
        assert np.max(np.abs(values)) <= 6.0 + 1e-6
    # the wheels roll (TIAGo's URDF: wheels at y = ±0.2022 m, radius 0.0985 m): at every node
    # u ∓ 0.2022 θ̇ = 0.0985 φ̇ and the base does not slip sideways
    theta = q[:, 2]
    u = np.cos(theta) * q_dot[:, 0] + np.sin(theta) * q_dot[:, 1]
    w = -np.sin(theta) * q_dot[:, 0] + np.cos(theta) * q_dot[:, 1]
    np.testing.assert_allclose(u - 0.2022 * q_dot[:, 2], 0.0985 * q_dot[:, 3], atol=1e-9)
    np.testing.assert_allclose(u + 0.2022 * q_dot[:, 2], 0.0985 * q_dot[:, 4], atol=1e-9)
    np.testing.assert_allclose(w, 0.0, atol=1e-9)


def test_tiago_arm_swing_reduced_against_lagrange_dae():
    """The shoulder swings, the free wheels let the base turn and roll: the reduced ODE and the
    Lagrange DAE (a second formulation, integrated at tighter tolerance) give the same run."""
    scene = load_scene(_tiago_scene("tiago_arm.toml"))
    spec = scene.simulation
    runs = {}
    for form, rtol in (("reduced", 1e-10), ("lagrange", 1e-12)):
        traj = simulate(derive(scene.system, form), (spec.t0, spec.t_final), spec.q0, spec.qdot0,
                        controller=spec.controller, rtol=rtol, atol=rtol * 1e-2, t_eval=spec.t_eval)
        assert traj.success, traj.message
        runs[form] = traj
    assert (scene.system.n, scene.system.k) == (6, 3)
    np.testing.assert_allclose(runs["reduced"].q, runs["lagrange"].q, rtol=0, atol=1e-9)
    # the base moved
    assert abs(runs["reduced"].q[-1, 2]) > 0.1
    assert np.hypot(*runs["reduced"].q[-1, :2]) > 0.1


def test_canonical_trig_form_applies_the_identities():
    from nhgait.dynamics.derivation.urdf.fourier import canonical_trig
    a, b, s = sp.symbols("a b s", real=True)
    assert canonical_trig(sp.sin(a) ** 2 + sp.cos(a) ** 2) == 1
    assert canonical_trig(sp.sin(a) * sp.cos(b) + sp.cos(a) * sp.sin(b)) == sp.sin(a + b)
    assert canonical_trig(2 * s * sp.sin(a) * sp.cos(a)) == s * sp.sin(2 * a)
    assert canonical_trig(sp.cos(a - b) - sp.cos(b - a)) == 0
    rng = np.random.default_rng(1)
    expr = (sp.cos(a) + 0.3 * s * sp.sin(2 * b - a)) ** 3 * sp.sin(a + 0.5)
    f, g = (sp.lambdify([a, b, s], e) for e in (expr, canonical_trig(expr)))
    for values in rng.uniform(-3, 3, (10, 3)):
        assert g(*values) == pytest.approx(f(*values), abs=1e-13)


def test_derive_shows_the_generated_system(capsys):
    from nhgait.gaits.cli.main import main
    assert main(["derive", str(EXAMPLES / "snakeboard_urdf.toml")]) == 0
    text = capsys.readouterr().out
    assert "from the URDF" in text
    assert "n = 5 coordinates" in text
    assert "k = 2 constraints" in text
    assert "0.35*theta_dot**2" in text            # (J + J_r + 2 J_w)/2: the written scene's θ̇² term
    assert "Reduced constrained Hamiltonian equations of snakeboard" in text


def test_a_malformed_urdf_and_bad_scene_keys_are_listed_together(tmp_path):
    problems = _problems(_scene(tmp_path, _robot(BODY, "<link name='broken'>"), 'colour = "red"\n'))
    assert any("malformed XML" in p for p in problems)
    assert any("['colour']" in p for p in problems)


def test_bench_urdf_smoke(capsys):
    import experiment_scripts
    result = experiment_scripts.load("bench_urdf").main(["--robots", "snakeboard", "--repeats",
                                                         "1", "--no-plan"])
    assert result["robots"][0]["n"] == 5
    assert result["robots"][0]["k"] == 2
    assert "| snakeboard | 5 | 2 |" in capsys.readouterr().out
