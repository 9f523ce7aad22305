"""Systems stated as rigid bodies and rolling wheels ([[system.bodies]], [[system.wheels]];
nhgait.dynamics.derivation.bodies). References:

* the rolling disc built from one wheel against the built-in ``rolling_disc``, whose Lagrangian
  was written by hand and whose state derivatives equal sympy's test_kane5.py
  (tests/dynamics/test_linearisation.py): M(q), V(q), the constraint distribution and q̈;
* the Whipple bicycle's pitch against the closed-form front-contact constraint of Moore's
  derivation (Moore, PhD thesis 2012; ``dtk.bicycle.pitch_from_roll_and_steer`` and
  ``benchmark_to_moore`` of the DynamicistToolKit, transcribed below), including the value its
  documentation prints for the benchmark bicycle (roll 10°, steer −5°: pitch 18.062710178550127°).
"""
from math import cos, sin, tan
from pathlib import Path

import numpy as np
import pytest

from nhgait.dynamics import ModelError, derive, load_scene
from nhgait.dynamics.derivation.holonomic import consistent_configuration, holonomic_residual
from nhgait.dynamics.derivation.input.scene import scene_from_text
from nhgait.dynamics.derivation.states import consistent_velocities

DISC = (Path(__file__).parent.parent / "scenes" / "disc_bodies.toml").read_text()


@pytest.fixture(scope="module")
def bicycle():
    return load_scene("whipple_bicycle").system


def test_disc_from_a_wheel_equals_the_hand_written_disc():
    built = scene_from_text(DISC).system
    by_hand = load_scene("rolling_disc").system
    assert built.coordinates == by_hand.coordinates  # lowest point at the base
    assert built.holonomic == ()
    (M1, W1, V1), (M2, W2, V2) = built.numeric_functions(), by_hand.numeric_functions()
    pv = built.param_vector()
    for q in np.random.default_rng(0).uniform(-1.2, 1.2, (10, 5)):
        np.testing.assert_allclose(M1(q, pv), M2(q, pv), rtol=1e-14, atol=1e-14)
        assert V1(q, pv) == pytest.approx(V2(q, pv), rel=1e-14)
        both = np.vstack([np.array(W1(q, pv), dtype=float), np.array(W2(q, pv), dtype=float)])
        assert np.linalg.matrix_rank(both, tol=1e-10) == 2                      # the same distribution
    a, b = derive(built).numeric, derive(by_hand).numeric
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = rng.uniform(-1.2, 1.2, 5)
        qd = consistent_velocities(by_hand, q,
                                   dict(zip(("yaw", "lean", "spin"), rng.uniform(-2, 2, 3), strict=True)))
        u = rng.uniform(-1, 1, 1)
        np.testing.assert_allclose(a.call("qddot", 0.0, a.call("state", q, qd, pv), u, pv),
                                   b.call("qddot", 0.0, b.call("state", q, qd, pv), u, pv),
                                   rtol=1e-12, atol=1e-12)


def _moore_geometry(p):
    """dtk.bicycle.benchmark_to_moore: the rear and front offsets d1, d3 from the steer axis and
    the distance d2 between them along it."""
    lam = p["lam"]
    d1 = cos(lam) * (p["c"] + p["w"] - p["rR"] * tan(lam))
    d3 = -cos(lam) * (p["c"] - p["rF"] * tan(lam))
    d2 = (p["rR"] + d1 * sin(lam) - p["rF"] + d3 * sin(lam)) / cos(lam)
    return d1, d2, d3


def _moore_pitch_constraint(q5, q4, q7, rF, rR, d1, d2, d3):
    """dtk.bicycle.pitch_from_roll_and_steer's pitch_constraint (Moore's q4 roll, q5 pitch of the
    rear frame, q7 steer): zero when the front wheel touches the ground."""
    e = sin(q4) * sin(q7) - sin(q5) * cos(q4) * cos(q7)
    root = (cos(q4) ** 2 * cos(q5) ** 2 + e ** 2) ** 0.5
    return (d2 * cos(q4) * cos(q5) + rF * cos(q4) ** 2 * cos(q5) ** 2 / root
            + e * (d3 + rF * e / root) - rR * cos(q4) - d1 * sin(q5) * cos(q4))


def test_bicycle_is_built_from_bodies_with_one_kept_holonomic_constraint(bicycle):
    assert bicycle.coordinates == ("x", "y", "yaw", "lean", "pitch", "steer", "rear", "front")
    assert bicycle.k == 5
    assert len(bicycle.holonomic) == 1
    assert bicycle.dependent == ("pitch",)
    assert holonomic_residual(bicycle, np.zeros(8))[0] == pytest.approx(0.0, abs=1e-15)   # upright: pitch 0


@pytest.mark.parametrize("lean, steer",
                         [(0.1745329251994330, 0.0872664625997165), (0.3, -0.5), (-0.6, 0.9), (0.0, 1.2)])
def test_bicycle_pitch_is_moores_closed_form(bicycle, lean, steer):
    from scipy.optimize import brentq
    p = bicycle.parameters
    d1, d2, d3 = _moore_geometry(p)
    q = np.zeros(8)
    q[3], q[5] = lean, steer
    pitch = consistent_configuration(bicycle, q)[4]
    # Moore: roll as ours (to the right), steer the other way, pitch q5 = λ − ours (nose up)
    moore = brentq(_moore_pitch_constraint, p["lam"] - 0.5, p["lam"] + 0.5,
                   args=(lean, -steer, p["rF"], p["rR"], d1, d2, d3), xtol=1e-15)
    assert pitch == pytest.approx(p["lam"] - moore, abs=1e-12)
    if lean == 0.1745329251994330:                     # dtk's documented value for the benchmark
        assert np.degrees(p["lam"] - pitch) == pytest.approx(18.062710178550127, abs=1e-11)


def test_no_configuration_when_the_front_wheel_cannot_touch_the_ground(bicycle):
    q = np.zeros(8)
    q[3], q[5] = 1.5, 1.0        # lying almost flat, steered: no pitch puts the front wheel down
    with pytest.raises(ModelError,
                       match=r"(?s)no configuration satisfies the holonomic constraint.*lean = 1.5"):
        consistent_configuration(bicycle, q)


def test_body_statement_errors_are_listed_together():
    bad = DISC.replace('parent = "leaning"', 'parent = "nowhere"').replace('axis = [1, 0, 0]',
                                                                           'axis = [0, 0, 0]')
    bad = (bad.replace('radius = "r"', 'radius = "rho"') + '\n[[system.bodies]]\nname = "x2"\nparent = '
                                                           '"base"\ncolour = 3\n')
    with pytest.raises(ModelError) as err:
        scene_from_text(bad)
    text = str(err.value)
    assert "the axis is zero" in text
    assert "unknown name(s) rho" in text
    assert "unknown key(s) ['colour']" in text
    assert "its parent 'nowhere' is not 'base' or a body" in text


_DRIVE = """[system]
name = "segway_bodies"
base = ["x", "y", "yaw"]
inputs = ["tau_L", "tau_R"]
gravity = "g"

[system.forces]
wL = "tau_L"
wR = "tau_R"

[system.parameters]
r = 0.1
b = 0.2
mc = 5.0
hc = 0.3
mw = 0.5
g = 9.81

[[system.bodies]]
name = "chassis"
parent = "base"
joint = "pitch"
axis = [0, 1, 0]
point = [0, 0, "r"]
mass = "mc"
com = [0, 0, "r + hc"]
inertia = [[0.2, 0, 0], [0, 0.2, 0], [0, 0, 0.1]]

[[system.wheels]]
name = "left"
parent = "chassis"
spin = "wL"
centre = [0, "b", "r"]
axle = [0, 1, 0]
radius = "r"
mass = "mw"
inertia = ["mw*r**2/4", "mw*r**2/2"]

[[system.wheels]]
name = "right"
parent = "chassis"
spin = "wR"
centre = [0, "-b", "r"]
axle = [0, 1, 0]
radius = "r"
mass = "mw"
inertia = ["mw*r**2/4", "mw*r**2/2"]
"""


def test_a_differential_drive_from_two_wheels_on_one_axle_drops_the_dependent_side_slip_row():
    """Two coaxial rolling wheels give four rows, two of them the same no-side-slip condition:
    the dependent one is dropped as for a URDF's wheels (``nhgait derive`` of a user's
    two-wheeled balancing robot stopped at "the constraints are dependent: rank ω(q) = 3 < k =
    4 … remove redundant constraints", which the user had not written). Reference: the same
    robot with the right wheel's rolling written by hand (cos ψ ẋ + sin ψ ẏ + b ψ̇ = r (θ̇ + φ̇_R),
    the wheel not rolling by itself): the same metric, distribution and accelerations."""
    built = scene_from_text(_DRIVE).system
    rolling = 'constraints = ["cos(yaw)*x_dot + sin(yaw)*y_dot + b*yaw_dot - r*(pitch_dot + wR_dot)"]'
    inputs = 'inputs = ["tau_L", "tau_R"]'
    by_hand = scene_from_text(_DRIVE.replace(inputs, f"{inputs}\n{rolling}")
                              .replace('spin = "wR"', 'spin = "wR"\nrolls = false')).system
    assert built.k == by_hand.k == 3
    (M1, W1, _), (M2, W2, _) = built.numeric_functions(), by_hand.numeric_functions()
    pv = built.param_vector()
    a, b = derive(built).numeric, derive(by_hand).numeric
    rng = np.random.default_rng(4)
    for _ in range(10):
        q = rng.uniform(-1.2, 1.2, 6)
        np.testing.assert_allclose(M1(q, pv), M2(q, pv), rtol=1e-13, atol=1e-13)
        both = np.vstack([np.array(W1(q, pv), dtype=float), np.array(W2(q, pv), dtype=float)])
        assert np.linalg.matrix_rank(both, tol=1e-10) == 3                      # the same distribution
        qd = consistent_velocities(by_hand, q, dict(zip(("yaw", "pitch", "wL"), rng.uniform(-2, 2, 3),
                                                        strict=True)))
        u = rng.uniform(-1, 1, 2)
        np.testing.assert_allclose(a.call("qddot", 0.0, a.call("state", q, qd, pv), u, pv),
                                   b.call("qddot", 0.0, b.call("state", q, qd, pv), u, pv),
                                   rtol=1e-10, atol=1e-10)


def test_a_bodies_robot_knows_its_angles():
    """The statement says which coordinates are angles (the heading, every revolute joint and
    every wheel's spin): their unit is rad and a torque on a spin is in N·m — a user's plot
    labelled the wheel angle "wR [m]" and its torque "τ_R [N]" (a spin enters no sine). The
    scene's own [units] still decide."""
    from nhgait.gaits.figures.plots import FigureContext, unit
    scene = scene_from_text(_DRIVE + '\n[units]\npitch = "deg"\n')
    assert scene.units == {"x": "m", "y": "m", "yaw": "rad", "pitch": "deg", "wL": "rad", "wR": "rad"}
    ctx = FigureContext(scene.system, dict(scene.units), None, None, (), ())
    assert [unit(ctx, n) for n in ("wR", "wR_dot", "tau_L", "tau_R")] == ["rad", "rad/s", "N·m", "N·m"]
