"""Linearisation about equilibria and straight steady motions, checked on the rolling disc
(the built-in scene ``rolling_disc``: a thin uniform disc rolling in 3-D) against

* sympy's published state derivatives of the same disc (``sympy/physics/mechanics/tests/
  test_kane5.py``, KanesMethod: two states, ten derivatives printed to 15 digits) — the
  nonlinear model the linearisation starts from;
* the closed form of the disc's linearised lean–yaw motion about upright rolling at spin rate
  Ω = v/r (Neimark & Fufaev, *Dynamics of Nonholonomic Systems*, 1972, ch. II; O'Reilly,
  Nonlinear Dynamics 10 (1996) 287–305): with A the moment of inertia about a diameter, C about
  the axle, (A + m r²) φ̈ + (C (C + m r²) Ω²/A − m g r) φ = 0, so the non-zero eigenvalues are
  ±√c with c = (m g r A − C (C + m r²) Ω²)/(A (A + m r²)), and upright rolling is stable above
  v = √(g r/3) for the thin disc (A = m r²/4, C = m r²/2).
"""
import json

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import ModelError, derive, load_scene
from nhgait.dynamics.linearisation import linearise, stability_chart
from nhgait.gaits.cli.main import main

M, R, G = 3.43, 0.26, 9.81          # the scene's (and test_kane5.py's) parameters


@pytest.fixture(scope="module")
def disc():
    return derive(load_scene("rolling_disc").system)


def _closed_form_c(v, m=M, r=R, g=G):
    A, C, omega = m * r ** 2 / 4, m * r ** 2 / 2, v / r
    return (m * g * r * A - C * (C + m * r ** 2) * omega ** 2) / (A * (A + m * r ** 2))


def _disc_rates():
    """u = W(q) q̇ of test_kane5.py: the disc's angular velocity in the disc frame (yaw q1 and lean
    q2 body-fixed z-x, spin q3 about the leaned y axis), W and its time derivative as functions
    of (q1, q2, q3, q̇1, q̇2, q̇3), built with sympy.physics.vector."""
    from sympy.physics.vector import ReferenceFrame, dynamicsymbols
    q = dynamicsymbols("q1:4")
    N = ReferenceFrame("N")
    I = ReferenceFrame("I")
    I.orient_body_fixed(N, (q[0], q[1], 0), "zxy")
    D = I.orientnew("D", "Axis", (q[2], I.y))
    w = D.ang_vel_in(N)
    qd = [qi.diff() for qi in q]
    W = sp.Matrix([[w.dot(axis).diff(v) for v in qd] for axis in (D.x, D.y, D.z)])
    Wdot = W.diff(dynamicsymbols._t)
    plain = sp.symbols("a0:6")
    subs = dict(zip(qd + q, plain[3:] + plain[:3], strict=True))
    return (sp.lambdify([plain], W.subs(subs)), sp.lambdify([plain], Wdot.subs(subs)))


# test_kane5.py: p = (g, r, m) = (9.81, 0.26, 3.43); q = (q1 yaw, q2 lean, q3 spin, q4 x, q5 y),
# u1..u3 the disc's angular velocity components, the expected [q̇1..q̇5, u̇1..u̇5]
KANE5 = [
    ((0.3, 0.1, 1.97, -0.35, 2.27), (-0.2, 1.3, 0.15),
     (0.126603940595934, 0.215942571601660, 1.28736069604936, 0.319764288376543, 0.0989146857254898,
      -0.925848952664489, -0.0181350656532944, 2.91695398184589, -0.00992793421754526, 0.0412861634829171)),
    ((3.97, -0.28, 8.2, -0.35, 2.27), (-0.25, -2.2, 0.62),
     (0.0259159090798597, 0.668041660387416, -2.19283799213811, 0.385441810852219, 0.420109283790573,
      1.45030568179066, -0.0110924422400793, -8.35617840186040, -0.154098542632173, -0.146102664410010)),
]


@pytest.mark.parametrize("q_kane, u_kane, expected", KANE5)
def test_disc_matches_sympys_published_state_derivatives(disc, q_kane, u_kane, expected):
    W, Wdot = _disc_rates()
    q1, q2, q3, q4, q5 = q_kane
    rates = np.linalg.solve(np.array(W([q1, q2, q3, 0, 0, 0]), dtype=float), u_kane)   # (q̇1, q̇2, q̇3)
    q = np.array([q4, q5, q1, q2, q3])                       # scene order (x, y, yaw, lean, spin)
    qdot = np.array([R * np.cos(q1) * rates[2], R * np.sin(q1) * rates[2], *rates])
    num = disc.numeric
    pv = num.params()
    z = num.call("state", q, qdot, pv)
    qddot = num.call("qddot", 0.0, z, np.zeros(1), pv)
    ours_qdot = np.array([qdot[2], qdot[3], qdot[4], qdot[0], qdot[1]])
    udot = (np.array(W([q1, q2, q3, *rates]), dtype=float) @ qddot[2:]
            + np.array(Wdot([q1, q2, q3, *rates]), dtype=float) @ rates)
    ours = np.concatenate([ours_qdot, udot, qddot[:2]])
    np.testing.assert_allclose(ours, expected, rtol=0, atol=2e-14)


@pytest.mark.parametrize("v", [0.0, 0.5, 0.9, 1.0, 2.0, 3.5])
def test_disc_lean_pair_matches_the_closed_form(disc, v):
    lin = linearise(disc, speed=v)
    lam = lin.eigenvalues[np.argsort(-np.abs(lin.eigenvalues))][:2]
    c = _closed_form_c(v)
    assert (-lam[0] * lam[1]).real == pytest.approx(c, rel=1e-12, abs=1e-12)
    assert abs(lam[0] + lam[1]) < 1e-12 * max(1.0, abs(c))        # ±√c
    assert lin.states == ("lean", "p", "pt_yaw", "pt_lean")        # x, y, yaw, spin drift
    assert lin.cyclic == ("x", "y", "yaw", "spin")
    # the zero of a neighbouring speed is removed, the zero of a neighbouring steady turn is not
    assert len(lin.eigenvalues) == 3
    assert min(abs(lin.eigenvalues)) < 1e-12
    assert lin.stability == ("unstable" if c > 0 else "neutral")


def test_disc_at_rest_is_an_inverted_pendulum_about_the_contact(disc):
    lin = linearise(disc)          # no speed: an equilibrium; every momentum kept
    assert lin.reference.kind == "equilibrium"
    assert max(lin.eigenvalues.real) == pytest.approx(np.sqrt(_closed_form_c(0.0)), rel=1e-13)
    assert lin.B[lin.states.index("pt_lean"), 0] == 1.0        # the lean torque drives P̃_lean


def test_disc_stability_threshold_is_sqrt_g_r_over_3(disc):
    chart = stability_chart(disc, np.linspace(0.0, 3.0, 31))
    assert len(chart.changes) == 1
    change = chart.changes[0]
    assert change.speed == pytest.approx(np.sqrt(G * R / 3), abs=1e-10)
    assert (change.below, change.above) == ("unstable", "neutral")
    assert chart.verdicts[0] == "unstable"
    assert chart.verdicts[-1] == "neutral"


def test_the_threshold_moves_with_the_parameters(disc):
    chart = stability_chart(disc, np.linspace(0.0, 3.0, 16), params={"r": 0.5})
    assert chart.changes[0].speed == pytest.approx(np.sqrt(G * 0.5 / 3), abs=1e-10)


def test_a_reference_not_at_rest_is_an_error_naming_the_rates(disc):
    with pytest.raises(ModelError, match=r"not an equilibrium: dpt_lean/dt = "):
        linearise(disc, configuration={"lean": 0.3})      # gravity tips a leaning disc at rest
    with pytest.raises(ModelError, match="not a coordinate"):
        linearise(disc, configuration={"tilt": 0.3})


def test_speed_without_a_planar_frame_is_an_error():
    from nhgait.dynamics import System
    cart = System(coordinates=["s", "phi"], lagrangian="s_dot**2 + phi_dot**2/2 + cos(phi)",
                  parameters={}, planar_frame=None)
    with pytest.raises(ModelError, match="needs a planar frame"):
        linearise(derive(cart), speed=1.0)


def test_cli_prints_json_eigenvalues_and_draws_the_chart(tmp_path, capsys):
    assert main(["linearize", "rolling_disc", "--speed", "2", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    lam = np.array([complex(*pair) for pair in data["eigenvalues"]])
    assert np.max(lam.imag) == pytest.approx(np.sqrt(-_closed_form_c(2.0)), rel=1e-12)
    assert data["states"] == ["lean", "p", "pt_yaw", "pt_lean"]
    assert len(data["A"]) == 4
    assert main(["linearize", "rolling_disc", "--speeds", "0:3:16", "--out", str(tmp_path), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "stability changes at 0.922062904578" in text
    assert (tmp_path / "eigenvalues.png").stat().st_size > 10_000
    saved = json.loads((tmp_path / "eigenvalues.json").read_text())
    assert saved["changes"][0]["speed"] == pytest.approx(np.sqrt(G * R / 3), abs=1e-10)


def test_cli_bad_requests_exit_2(capsys):
    assert main(["linearize", "rolling_disc", "--set", "q.tilt=1", "--set", "params.mass=2"]) == 2
    err = capsys.readouterr().err
    assert "'tilt'" in err
    assert "'mass'" in err
    assert main(["linearize", "rolling_disc", "--speeds", "3:0:5"]) == 2
    assert main(["linearize", "rolling_disc", "--out", "x"]) == 2
