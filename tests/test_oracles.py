"""Self-test of the Kane's-method oracles in tests/oracles.py."""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from oracles import ORACLE_NAMES, KaneOracle, oracle  # noqa: E402

N_SAMPLES = 25
H = 1e-6


# --------------------------------------------------------------------------- #
# random constraint-consistent states
# --------------------------------------------------------------------------- #
def _params(name, rng):
    o = oracle(name)
    p = rng.uniform(0.5, 2.0, len(o.parameters))
    if name == "knife_edge_incline":
        p[o.parameters.index("g")] = 9.81
        p[o.parameters.index("alpha")] = rng.uniform(0.1, 1.2)
    return p


def _q(name, rng):
    """Random configuration away from the primary variant's singularities."""
    o = oracle(name)
    while True:
        q = np.array([rng.uniform(-2, 2) if c in ("x", "y") else rng.uniform(-np.pi, np.pi)
                      for c in o.coordinates])
        th = q[o.coordinates.index("theta")]
        if name in ("chaplygin_sleigh", "knife_edge_incline") and abs(np.cos(th)) < 0.2:
            continue
        if name == "snakeboard" and abs(np.sin(2 * q[o.coordinates.index("phi")])) < 0.2:
            continue
        return q


def _state(name, rng):
    o = oracle(name)
    q = _q(name, rng)
    p = _params(name, rng)
    qd = o.consistent_qdot(q, rng.uniform(-1.5, 1.5, len(o.independent)), p)
    u = rng.uniform(-1.0, 1.0, len(o.inputs))
    return q, qd, u, p


def _states(name, seed=0, n=N_SAMPLES):
    rng = np.random.default_rng(seed)
    return [_state(name, rng) for _ in range(n)]


@pytest.fixture(scope="module", params=ORACLE_NAMES)
def name(request):
    oracle(request.param)  # build (cached) once
    return request.param


# --------------------------------------------------------------------------- #
# metadata
# --------------------------------------------------------------------------- #
def test_metadata():
    expected = {
        "unicycle": (("x", "y", "theta", "phi"), ("m", "r", "J_phi", "J_theta"),
                     ("tau_theta", "tau_phi"), ("theta", "phi")),
        "snakeboard": (("x", "y", "theta", "psi", "phi"), ("m", "J", "J_r", "J_w", "r"),
                       ("tau_psi", "tau_phi"), ("theta", "psi", "phi")),
        "chaplygin_sleigh": (("x", "y", "theta"), ("m", "I_c", "a"), ("F", "tau"),
                             ("x", "theta")),
        "knife_edge_incline": (("x", "y", "theta"), ("m", "I", "g", "alpha"), ("tau",),
                               ("x", "theta")),
    }
    for nm, (c, p, i, ind) in expected.items():
        o = oracle(nm)
        assert isinstance(o, KaneOracle)
        assert o is oracle(nm)  # cached
        assert (o.name, o.coordinates, o.parameters, o.inputs, o.independent) == (nm, c, p, i, ind)
    with pytest.raises(KeyError):
        oracle("bicycle")


def test_shape_validation():
    o = oracle("chaplygin_sleigh")
    with pytest.raises(ValueError):
        o.qddot(np.zeros(2), np.zeros(3), np.zeros(2), np.ones(3))
    with pytest.raises(ValueError):
        o.qddot(np.zeros(3), np.zeros(3), np.zeros(1), np.ones(3))


# --------------------------------------------------------------------------- #
# the no-slip constraints computed from point velocities have the stated form
# --------------------------------------------------------------------------- #
def _expected_residual(name, q, qd, p):
    if name == "unicycle":
        x, y, th, ph = q
        m, r, Jp, Jt = p
        return np.array([qd[0] - r * np.cos(th) * qd[3], qd[1] - r * np.sin(th) * qd[3]])
    if name == "snakeboard":
        x, y, th, psi, ph = q
        r = p[4]
        return np.array([
            -np.sin(th - ph) * qd[0] + np.cos(th - ph) * qd[1] - r * np.cos(ph) * qd[2],
            -np.sin(th + ph) * qd[0] + np.cos(th + ph) * qd[1] + r * np.cos(ph) * qd[2],
        ])
    th = q[2]
    return np.array([-np.sin(th) * qd[0] + np.cos(th) * qd[1]])


def test_constraint_form(name):
    o = oracle(name)
    rng = np.random.default_rng(1)
    for _ in range(N_SAMPLES):
        q = _q(name, rng)
        p = _params(name, rng)
        qd = rng.uniform(-2, 2, len(q))  # arbitrary, not consistent
        np.testing.assert_allclose(o.constraint_residual(q, qd, p),
                                   _expected_residual(name, q, qd, p), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- #
# generic properties
# --------------------------------------------------------------------------- #
def test_consistent_qdot(name):
    o = oracle(name)
    rng = np.random.default_rng(2)
    ind = [o.coordinates.index(c) for c in o.independent]
    for _ in range(N_SAMPLES):
        q, p = _q(name, rng), _params(name, rng)
        qi = rng.uniform(-1.5, 1.5, len(ind))
        qd = o.consistent_qdot(q, qi, p)
        assert qd.shape == (len(o.coordinates),)
        np.testing.assert_array_equal(qd[ind], qi)
        res = o.constraint_residual(q, qd, p)
        assert res.shape == (len(o.coordinates) - len(o.independent),)
        np.testing.assert_allclose(res, 0.0, atol=1e-12 * (1 + np.abs(qd).max()))


def test_constraint_derivative_vanishes(name):
    """d/dt of the no-slip velocities along (qdot, qddot) is zero."""
    o = oracle(name)
    for q, qd, u, p in _states(name, seed=3):
        qdd = o.qddot(q, qd, u, p)
        assert qdd.shape == q.shape
        assert np.all(np.isfinite(qdd))
        rp = o.constraint_residual(q + H * qd, qd + H * qdd, p)
        rm = o.constraint_residual(q - H * qd, qd - H * qdd, p)
        scale = 1 + np.abs(qd).max() ** 2 + np.abs(qdd).max()
        np.testing.assert_allclose((rp - rm) / (2 * H), 0.0, atol=1e-8 * scale)


def test_dependent_speed_choices_agree(name):
    """Kane models with different dependent speeds give the same accelerations."""
    o = oracle(name)
    for q, qd, u, p in _states(name, seed=4):
        ref = o.qddot(q, qd, u, p)
        for v in o._variants:
            np.testing.assert_allclose(o._qddot_variant(v, q, qd, u, p), ref,
                                       rtol=1e-10, atol=1e-10 * (1 + np.abs(ref).max()))


# --------------------------------------------------------------------------- #
# unicycle
# --------------------------------------------------------------------------- #
def test_unicycle_analytic():
    o = oracle("unicycle")
    for i, (q, qd, u, p) in enumerate(_states("unicycle", seed=5)):
        if i % 2 == 0:
            u = np.zeros(2)
        m, r, Jp, Jt = p
        th, thd, phd = q[2], qd[2], qd[3]
        qdd = o.qddot(q, qd, u, p)
        thdd = u[0] / Jt
        phdd = u[1] / (Jp + m * r**2)
        expected = np.array([
            r * np.cos(th) * phdd - r * np.sin(th) * thd * phd,
            r * np.sin(th) * phdd + r * np.cos(th) * thd * phd,
            thdd, phdd])
        np.testing.assert_allclose(qdd, expected, rtol=1e-10, atol=1e-12)
        if i % 2 == 0:  # free rolling: constant spin and heading rates
            np.testing.assert_allclose(qdd[2:], 0.0, atol=1e-12)
        T = 0.5 * m * (qd[0]**2 + qd[1]**2) + 0.5 * Jt * thd**2 + 0.5 * Jp * phd**2
        assert o.kinetic_energy(q, qd, p) == pytest.approx(T, rel=1e-12)


# --------------------------------------------------------------------------- #
# snakeboard
# --------------------------------------------------------------------------- #
def _snake_M(p):
    m, J, Jr, Jw, r = p
    M = np.zeros((5, 5))
    M[0, 0] = M[1, 1] = m
    M[2, 2] = J + Jr + 2 * Jw
    M[2, 3] = M[3, 2] = Jr
    M[3, 3] = Jr
    M[4, 4] = 2 * Jw
    return M


def test_snakeboard_energy():
    o = oracle("snakeboard")
    for q, qd, u, p in _states("snakeboard", seed=6):
        m, J, Jr, Jw, r = p
        xd, yd, thd, psid, phd = qd
        T = (0.5 * m * (xd**2 + yd**2) + 0.5 * J * thd**2 + 0.5 * Jr * (thd + psid)**2
             + 0.5 * Jw * (thd - phd)**2 + 0.5 * Jw * (thd + phd)**2)
        assert o.kinetic_energy(q, qd, p) == pytest.approx(T, rel=1e-12)
        assert 0.5 * qd @ _snake_M(p) @ qd == pytest.approx(T, rel=1e-12)
        qdd = o.qddot(q, qd, u, p)
        dT = qd @ _snake_M(p) @ qdd        # M is constant
        power = u[0] * psid + u[1] * phd
        scale = np.abs(qd) @ np.abs(_snake_M(p)) @ np.abs(qdd) + abs(power)
        assert abs(dT - power) <= 1e-10 * scale


def test_snakeboard_lagrange_multipliers():
    """Independent check: M qdd = Q + A^T lam, A qdd + Adot qd = 0 (analytic A, Adot)."""
    o = oracle("snakeboard")
    for q, qd, u, p in _states("snakeboard", seed=7):
        r = p[4]
        th, ph = q[2], q[4]
        thd, phd = qd[2], qd[4]
        A = np.array([
            [-np.sin(th - ph), np.cos(th - ph), -r * np.cos(ph), 0, 0],
            [-np.sin(th + ph), np.cos(th + ph), r * np.cos(ph), 0, 0]])
        Ad = np.array([
            [-np.cos(th - ph) * (thd - phd), -np.sin(th - ph) * (thd - phd),
             r * np.sin(ph) * phd, 0, 0],
            [-np.cos(th + ph) * (thd + phd), -np.sin(th + ph) * (thd + phd),
             -r * np.sin(ph) * phd, 0, 0]])
        Q = np.array([0, 0, 0, u[0], u[1]])
        K = np.block([[_snake_M(p), -A.T], [A, np.zeros((2, 2))]])
        sol = np.linalg.solve(K, np.concatenate([Q, -Ad @ qd]))
        qdd = o.qddot(q, qd, u, p)
        np.testing.assert_allclose(qdd, sol[:5], rtol=1e-9, atol=1e-10 * (1 + np.abs(sol[:5]).max()))


def test_snakeboard_at_parallel_wheels():
    """phi = 0 is singular for the primary (x, y)-dependent choice, not for qddot."""
    o = oracle("snakeboard")
    rng = np.random.default_rng(8)
    p = _params("snakeboard", rng)
    q = np.array([0.3, -0.2, 0.7, 0.1, 0.0])
    v = 0.8
    qd = np.array([v * np.cos(0.7), v * np.sin(0.7), 0.0, 0.4, 0.5])
    np.testing.assert_allclose(o.constraint_residual(q, qd, p), 0.0, atol=1e-14)
    u = np.array([0.3, -0.2])
    qdd = o.qddot(q, qd, u, p)
    assert np.all(np.isfinite(qdd))
    rp = o.constraint_residual(q + H * qd, qd + H * qdd, p)
    rm = o.constraint_residual(q - H * qd, qd - H * qdd, p)
    np.testing.assert_allclose((rp - rm) / (2 * H), 0.0, atol=1e-8)


# --------------------------------------------------------------------------- #
# Chaplygin sleigh
# --------------------------------------------------------------------------- #
def _sleigh_check(o, q, qd, u, p):
    m, Ic, a = p
    th = q[2]
    c, s = np.cos(th), np.sin(th)
    v, w = qd[0] * c + qd[1] * s, qd[2]
    qdd = o.qddot(q, qd, u, p)
    vdot = qdd[0] * c + qdd[1] * s + w * (-qd[0] * s + qd[1] * c)
    wdot = qdd[2]
    F, tau = u
    scale = 1 + m * a * w**2 + m * a * abs(v * w) + abs(F) + abs(tau)
    assert abs(m * vdot - (m * a * w**2 + F)) <= 1e-10 * scale
    assert abs((Ic + m * a**2) * wdot - (-m * a * v * w + tau)) <= 1e-10 * scale
    # lateral velocity stays zero: d/dt(-s xd + c yd) = -v w + (-s xdd + c ydd)
    assert abs(-s * qdd[0] + c * qdd[1] - v * w) <= 1e-10 * scale
    T = 0.5 * m * ((qd[0] - a * s * w)**2 + (qd[1] + a * c * w)**2) + 0.5 * Ic * w**2
    assert o.kinetic_energy(q, qd, p) == pytest.approx(T, rel=1e-12)


def test_chaplygin_sleigh_analytic():
    o = oracle("chaplygin_sleigh")
    for i, (q, qd, u, p) in enumerate(_states("chaplygin_sleigh", seed=9)):
        if i % 2 == 0:
            u = np.zeros(2)  # free sleigh: the standard Chaplygin equations
        _sleigh_check(o, q, qd, u, p)


def test_chaplygin_sleigh_heading_singularity():
    """qddot stays regular at theta = +-pi/2 (switches to the x-dependent model)."""
    o = oracle("chaplygin_sleigh")
    rng = np.random.default_rng(10)
    for th in (np.pi / 2, -np.pi / 2, np.pi / 2 + 1e-9):
        p = _params("chaplygin_sleigh", rng)
        q = np.array([0.1, 0.2, th])
        v, w = rng.uniform(-1, 1, 2)
        qd = np.array([v * np.cos(th), v * np.sin(th), w])
        _sleigh_check(o, q, qd, rng.uniform(-1, 1, 2), p)


# --------------------------------------------------------------------------- #
# knife edge on an incline
# --------------------------------------------------------------------------- #
def test_knife_edge_energy_and_analytic():
    o = oracle("knife_edge_incline")
    for q, qd, u, p in _states("knife_edge_incline", seed=11):
        m, I, g, alpha = p
        qdd = o.qddot(q, qd, u, p)
        T = 0.5 * m * (qd[0]**2 + qd[1]**2) + 0.5 * I * qd[2]**2
        assert o.kinetic_energy(q, qd, p) == pytest.approx(T, rel=1e-12)
        dT = m * (qd[0] * qdd[0] + qd[1] * qdd[1]) + I * qd[2] * qdd[2]
        p_grav = m * g * np.sin(alpha) * qd[0]
        power = p_grav + u[0] * qd[2]
        scale = m * np.abs(qd[:2]) @ np.abs(qdd[:2]) + I * abs(qd[2] * qdd[2]) + abs(p_grav) \
            + abs(u[0] * qd[2])
        assert abs(dT - power) <= 1e-10 * scale
        # E = T + V, V = -m g sin(alpha) x  =>  dE/dt = tau * thetadot
        assert abs((dT - p_grav) - u[0] * qd[2]) <= 1e-10 * scale
        # analytic: I thdd = tau ; m vdot = m g sin(alpha) cos(theta)
        th = q[2]
        vdot = qdd[0] * np.cos(th) + qdd[1] * np.sin(th) \
            + qd[2] * (-qd[0] * np.sin(th) + qd[1] * np.cos(th))
        assert qdd[2] == pytest.approx(u[0] / I, rel=1e-10, abs=1e-12)
        assert vdot == pytest.approx(g * np.sin(alpha) * np.cos(th), rel=1e-10, abs=1e-12)


def test_knife_edge_heading_singularity():
    """qddot stays regular at theta = +-pi/2 (switches to the x-dependent model)."""
    o = oracle("knife_edge_incline")
    rng = np.random.default_rng(12)
    for th in (np.pi / 2, -np.pi / 2):
        m, I, g, alpha = p = _params("knife_edge_incline", rng)
        q = np.array([0.3, -0.4, th])
        v, w = rng.uniform(-1, 1, 2)
        qd = np.array([v * np.cos(th), v * np.sin(th), w])
        tau = rng.uniform(-1, 1)
        qdd = o.qddot(q, qd, np.array([tau]), p)
        vdot = qdd[0] * np.cos(th) + qdd[1] * np.sin(th)
        assert qdd[2] == pytest.approx(tau / I, rel=1e-10, abs=1e-12)
        assert vdot == pytest.approx(g * np.sin(alpha) * np.cos(th), abs=1e-12)
        # lateral acceleration = v * w keeps the lateral velocity at zero
        assert -np.sin(th) * qdd[0] + np.cos(th) * qdd[1] == pytest.approx(v * w, rel=1e-10)
