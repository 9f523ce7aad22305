"""Holonomic constraints h(q) = 0 (System(holonomic=...), scene ``holonomic = [...]``):
eliminated where linear in a coordinate, kept with their velocity row otherwise, in all three
formulations. References:

* the KanesMethod oracle ``disc_height`` (tests/oracles.py): the rolling disc with its centre's
  height z as a coordinate, the configuration constraint z = r cos(lean) given to KanesMethod as
  ``configuration_constraints`` and its time derivative stated physically (the rim's lowest
  point does not move vertically) — q̈ at random consistent states;
* the built-in ``rolling_disc`` scene, where z = r cos(lean) was substituted by hand;
* a pendulum of length l hanging from a free cart, written in Cartesian coordinates (px, py)
  with px² + py² = l² (kept): its small oscillation ω² = (g/l)(M + m)/M (closed form) and its
  motion against the same pendulum written with the angle (an independent, unconstrained
  formulation).
"""
from pathlib import Path

import numpy as np
import pytest
from oracles import oracle

from nhgait.dynamics import ModelError, System, derive, load_scene, simulate
from nhgait.dynamics.derivation.holonomic import consistent_configuration
from nhgait.dynamics.derivation.input.scene import scene_from_text
from nhgait.dynamics.derivation.states import consistent_velocities, to_state
from nhgait.dynamics.linearisation import linearise

SCENE = (Path(__file__).parent.parent / "scenes" / "disc_height.toml").read_text()
R = 0.26
RTOL = 1e-10


def _eliminated_text():
    """The disc_height scene without ``dependent`` (so z is eliminated) and its [simulation]."""
    text = "\n".join(line for line in SCENE.splitlines() if not line.startswith("dependent"))
    return text[:text.index("[simulation]")]


@pytest.fixture(scope="module")
def kept():
    return load_scene(str(Path(__file__).parent.parent / "scenes" / "disc_height.toml")).system


def _cart_pendulum(**extra):
    return System(coordinates=["s", "px", "py"],
                  lagrangian="M*s_dot**2/2 + m*((s_dot + px_dot)**2 + py_dot**2)/2 - m*g*py",
                  holonomic=["px**2 + py**2 - l**2"], forces={"s": "F"},
                  parameters={"M": 2.0, "m": 0.5, "g": 9.81, "l": 0.7}, planar_frame=None,
                  name="cart_pendulum_xy", **extra)


def _disc_states(system, orc, count=40, seed=0):
    rng = np.random.default_rng(seed)
    po = np.array([system.parameters[p] for p in orc.parameters])
    for _ in range(count):
        q = rng.uniform(-1.2, 1.2, 6)
        q[4] = rng.uniform(0.2, 1.2) * rng.choice([-1, 1])      # lean, away from upright (∂h/∂lean = 0)
        q[2] = R * np.cos(q[4])                                   # on the constraint surface
        qd = orc.consistent_qdot(q, rng.uniform(-1.0, 1.0, 3), po)
        yield q, qd, rng.uniform(-2.0, 2.0, 1), po


def test_a_constraint_linear_in_a_coordinate_eliminates_it():
    system = scene_from_text(_eliminated_text()).system
    assert system.coordinates == ("x", "y", "yaw", "lean", "spin")
    assert [c for c, _ in system.eliminated] == ["z"]
    assert str(system.eliminated[0][1]) == "r*cos(lean)"
    assert system.holonomic == ()
    assert system.k == 2
    # the same M(q) and V(q) as the scene where z = r cos(lean) was substituted by hand
    by_hand = load_scene("rolling_disc").system
    M1, _, V1 = system.numeric_functions()
    M2, _, V2 = by_hand.numeric_functions()
    pv = system.param_vector()
    for q in np.random.default_rng(1).uniform(-1.2, 1.2, (10, 5)):
        np.testing.assert_allclose(M1(q, pv), M2(q, pv), rtol=1e-14, atol=1e-14)
        assert V1(q, pv) == pytest.approx(V2(q, pv), rel=1e-14)


def test_the_force_on_an_eliminated_coordinate_does_virtual_work():
    system = System(coordinates=["x", "z", "a"], lagrangian="(x_dot**2 + z_dot**2 + a_dot**2)/2",
                    holonomic=["z - r*sin(a)"], forces={"z": "F"}, parameters={"r": 0.5}, planar_frame=None)
    assert system.coordinates == ("x", "a")
    assert str(system.tau[1]) == "F*r*cos(a)"                    # τ_a = F ∂z/∂a


def test_eliminated_disc_equals_the_kane_oracle():
    system = scene_from_text(_eliminated_text()).system
    num, orc = derive(system).numeric, oracle("disc_height")
    pv, keep = system.param_vector(), [0, 1, 3, 4, 5]          # oracle q without z
    worst = 0.0
    for q, qd, u, po in _disc_states(system, orc):
        ref = orc.qddot(q, qd, u, po)
        z = num.call("state", q[keep], qd[keep], pv)
        got = num.call("qddot", 0.0, z, u, pv)
        worst = max(worst, np.max(np.abs(got - ref[keep])) / max(1.0, np.max(np.abs(ref))))
    assert worst < RTOL


def test_kept_constraint_in_all_three_formulations_equals_the_kane_oracle(kept):
    assert kept.coordinates == ("x", "y", "z", "yaw", "lean", "spin")
    assert kept.dependent == ("lean",)
    assert kept.k == 3
    assert kept.holonomic_rows == (2,)
    orc = oracle("disc_height")
    red, lag, ham = (derive(kept, f).numeric for f in ("reduced", "lagrange", "hamilton"))
    pv = kept.param_vector()
    worst = {"reduced": 0.0, "lagrange": 0.0, "lambda": 0.0}
    for q, qd, u, po in _disc_states(kept, orc, seed=2):
        ref = orc.qddot(q, qd, u, po)
        scale = max(1.0, np.max(np.abs(ref)))
        z = red.call("state", q, qd, pv)
        worst["reduced"] = max(worst["reduced"],
                               np.max(np.abs(red.call("qddot", 0.0, z, u, pv) - ref)) / scale)
        xdot, lam_l = lag.call("ode", 0.0, np.r_[q, qd], u, pv)
        worst["lagrange"] = max(worst["lagrange"], np.max(np.abs(xdot[6:] - ref)) / scale)
        M = lag.call("mass", np.r_[q, qd], pv)
        xdot_h, lam_h = ham.call("ode", 0.0, np.r_[q, M @ qd], u, pv)
        np.testing.assert_allclose(xdot_h[:6], qd, rtol=1e-12, atol=1e-12)
        worst["lambda"] = max(worst["lambda"], np.max(np.abs(np.atleast_1d(lam_l) - np.atleast_1d(lam_h)))
                              / max(1.0, np.max(np.abs(lam_l))))
    assert max(worst.values()) < RTOL, worst


def test_consistent_configuration_solves_the_dependent_coordinate(kept):
    q = consistent_configuration(kept, [0.1, 0.2, 0.2, 0.3, 0.4, 0.5])       # z given, lean solved
    assert q[4] == pytest.approx(np.arccos(0.2 / R), abs=1e-14)
    assert q[[0, 1, 2, 3, 5]].tolist() == [0.1, 0.2, 0.2, 0.3, 0.5]
    with pytest.raises(ModelError, match=r"no configuration satisfies .* with x = 0, y = 0, z = 0.3"):
        consistent_configuration(kept, [0, 0, 0.3, 0, 0.4, 0])               # z > r: none
    scene = load_scene(str(Path(__file__).parent.parent / "scenes" / "disc_height.toml"))
    assert scene.simulation.q0[4] == pytest.approx(np.arccos(0.25 / R), abs=1e-14)   # the scene's q0


def test_an_inconsistent_configuration_is_refused_with_the_consistent_value(kept):
    model = derive(kept)
    q = np.array([0, 0, 0.25, 0, 0.5, 0])
    with pytest.raises(ModelError, match=r"(?s)violates the holonomic constraint .*lean = 0\.27"):
        to_state(model, q, np.zeros(6))


def test_statement_errors_name_every_problem():
    with pytest.raises(ModelError) as err:
        System(coordinates=["x", "z"], lagrangian="(x_dot**2 + z_dot**2)/2",
               holonomic=["z - x_dot", "c", "x**2 + z**2 - 1"], dependent=["z", "z", "w"],
               parameters={"c": 1.0}, planar_frame=None)
    text = str(err.value)
    assert "unknown symbol 'x_dot' in holonomic constraint 1" in text
    assert "holonomic constraint 2 (c = 0) contains no coordinate" in text
    assert "'w' is not a coordinate of holonomic constraint 3" in text
    with pytest.raises(ModelError, match="one coordinate per holonomic constraint"):
        System(coordinates=["x", "z"], lagrangian="(x_dot**2 + z_dot**2)/2", holonomic=["x**2 + z**2 - 1"],
               dependent=["x", "z"], planar_frame=None)


def test_cart_pendulum_small_oscillation_is_the_closed_form():
    lin = linearise(derive(_cart_pendulum(dependent=["py"])), configuration={"py": -0.5})
    assert lin.reference.q[2] == pytest.approx(-0.7, abs=1e-15)              # py solved from px = 0
    omega = np.sqrt(9.81 / 0.7 * (2.0 + 0.5) / 2.0)
    assert max(lin.eigenvalues.imag) == pytest.approx(omega, rel=1e-13)
    assert len(lin.eigenvalues) == 3                                         # ±iω and the free cart's p
    assert any("leaving the holonomic constraint surface" in s for s in lin.removed)


@pytest.mark.parametrize("formulation", ["reduced", "lagrange", "hamilton"])
def test_cart_pendulum_motion_drift_and_projection(formulation):
    system = _cart_pendulum(dependent=["py"])
    angle = System(coordinates=["s", "phi"], lagrangian="M*s_dot**2/2 + m*((s_dot + l*cos(phi)*phi_dot)**2 "
                   "+ (l*sin(phi)*phi_dot)**2)/2 + m*g*l*cos(phi)", forces={"s": "F"},
                   parameters=dict(system.parameters), planar_frame=None)
    phi0, l = 0.4, 0.7
    q0 = np.array([0.0, l * np.sin(phi0), -l * np.cos(phi0)])
    qd0 = consistent_velocities(system, q0, {"s": 0.1, "px": 0.5})
    reference = simulate(derive(angle, "reduced"), (0, 5), [0.0, phi0], [0.1, 0.5 / (l * np.cos(phi0))],
                         rtol=1e-12, atol=1e-14, method="DOP853")
    model = derive(system, formulation)
    free = simulate(model, (0, 5), q0, qd0, rtol=1e-10, atol=1e-12)
    projected = simulate(model, (0, 5), q0, qd0, rtol=1e-10, atol=1e-12, stabilization="projection")
    assert free.holonomic_residual.shape == (len(free.t), 1)
    assert 0 < np.abs(free.holonomic_residual).max() < 1e-7                   # drift: integration error
    assert np.abs(projected.holonomic_residual).max() < 1e-14                # projection removes it
    phi_end = reference.q[-1, 1]
    for run in (free, projected):
        np.testing.assert_allclose(run.q[-1], [reference.q[-1, 0], l * np.sin(phi_end), -l * np.cos(phi_end)],
                                   atol=2e-7)


def test_simulate_cli_reports_the_drift(tmp_path, capsys):
    from nhgait.gaits.cli.main import main
    scene = tmp_path / "disc.toml"
    scene.write_text(SCENE)
    assert main(["simulate", str(scene), "--out", str(tmp_path / "t.csv"), "--columns", "all"]) == 0
    assert "max |h(q)|" in capsys.readouterr().out
    assert "holonomic1" in (tmp_path / "t.csv").read_text().splitlines()[0]


_SLEIGH = ("m*((x_dot - a*sin(theta)*theta_dot)**2 + (y_dot + a*cos(theta)*theta_dot)**2)/2"
           " + I_c*theta_dot**2/2"
           " + m_s*((x_dot + {ud}*cos(theta) - {wd}*sin(theta)"
           " - ((c + {u})*sin(theta) + {w}*cos(theta))*theta_dot)**2"
           " + (y_dot + {ud}*sin(theta) + {wd}*cos(theta)"
           " + ((c + {u})*cos(theta) - {w}*sin(theta))*theta_dot)**2)/2")
_SLEIGH_PARAMETERS = {"m": 1.0, "I_c": 0.05, "a": 0.1, "m_s": 0.4, "c": 0.2, "R": 0.1}


def test_hamiltonian_form_of_a_configuration_dependent_metric_with_a_kept_constraint():
    """A Chaplygin sleigh carrying a mass on a ring of radius R, written in the mass's body
    coordinates (u, w) with u² + w² = R² kept (w dependent): a 5 × 5 metric that depends on
    the configuration, whose Hamiltonian form never finished deriving (a user's trial,
    2026-11-29: sympy expanded pᵀM⁻¹p, then differentiated M⁻¹). Reference: the same robot
    with the mass's angle ψ (u = R sin ψ, w = R cos ψ, no holonomic constraint), reduced
    form, at a tighter tolerance; coasting for 2 s from a consistent state."""
    kept = System(coordinates=["x", "y", "theta", "u", "w"],
                  lagrangian=_SLEIGH.format(u="u", w="w", ud="u_dot", wd="w_dot"),
                  constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"], holonomic=["u**2 + w**2 - R**2"],
                  dependent=["w"], forces={"u": "F"}, parameters=_SLEIGH_PARAMETERS, name="ring_uw")
    angle = System(coordinates=["x", "y", "theta", "psi"],
                   lagrangian=_SLEIGH.format(u="R*sin(psi)", w="R*cos(psi)", ud="R*cos(psi)*psi_dot",
                                             wd="(-R*sin(psi)*psi_dot)"),
                   constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"], forces={"psi": "F"},
                   parameters=_SLEIGH_PARAMETERS, name="ring_psi")
    psi, psi_dot, R = 0.3, 1.0, 0.1
    q0 = [0.0, 0.0, 0.0, R * np.sin(psi), R * np.cos(psi)]
    qd0 = [0.2, 0.0, 0.5, R * np.cos(psi) * psi_dot, -R * np.sin(psi) * psi_dot]
    reference = simulate(derive(angle, "reduced", use_cache=False), (0, 2), [0.0, 0.0, 0.0, psi],
                         [0.2, 0.0, 0.5, psi_dot], rtol=1e-12, atol=1e-14, method="DOP853")
    run = simulate(derive(kept, "hamilton", use_cache=False), (0, 2), q0, qd0, rtol=1e-10, atol=1e-12)
    x, y, theta, psi_end = reference.q[-1]
    np.testing.assert_allclose(run.q[-1], [x, y, theta, R * np.sin(psi_end), R * np.cos(psi_end)], atol=1e-7)
    assert abs(run.q[-1, 2]) > 0.05                 # it turned: the test is not of a body at rest
