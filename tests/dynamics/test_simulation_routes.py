"""The compiled and the SUNDIALS integration routes (dynamics/simulation/route_compiled.py,
route_sundials.py), each seen to run (a spy on the route function the driver calls) and checked
against references that are not the route:

* a second integrator at a tighter tolerance: scipy's DOP853 at rtol 1e-12 on the same model;
* a physical invariant: the Chaplygin sleigh without inputs keeps its energy
  E = ½ m v² + ½ (I_c + m a²) ω² (v the blade's forward speed, ω = θ̇; the constraint
  force does no work), and its blade never moves sideways (−ẋ sin θ + ẏ cos θ = 0).

Tolerances: each route runs at rtol 1e-9, atol 1e-11 over 4 s; its global error stays
within 1e-6 of the states' unit scale (a margin of ~100 over the local tolerance's growth on
this non-stiff, bounded motion).
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from nhgait.dynamics import derive, simulate
from nhgait.dynamics.simulation import driver, route_compiled, route_sundials

SLEIGH = {"m": 1.0, "I_c": 0.2, "a": 0.3}       # the built-in scene's values, the reference's
Q0, QDOT0 = np.zeros(3), np.array([0.8, 0.0, 1.5])   # at θ = 0: ẏ = 0 is on the constraint
T_EVAL = np.linspace(0.0, 4.0, 41)


def _energy(traj) -> np.ndarray:
    th, xd, yd, thd = traj.q[:, 2], traj.qdot[:, 0], traj.qdot[:, 1], traj.qdot[:, 2]
    v = xd * np.cos(th) + yd * np.sin(th)
    m, I_c, a = SLEIGH["m"], SLEIGH["I_c"], SLEIGH["a"]
    return 0.5 * m * v ** 2 + 0.5 * (I_c + m * a ** 2) * thd ** 2


@pytest.fixture(scope="module")
def sleigh():
    model = derive("chaplygin_sleigh", "reduced")
    reference = simulate(model, (0.0, 4.0), Q0, QDOT0, method="DOP853", rtol=1e-12, atol=1e-14, t_eval=T_EVAL)
    assert reference.success
    return model, reference


def _spied(monkeypatch, name: str, route) -> list:
    calls = []

    def spy(*args, **kwargs):
        calls.append(name)
        return route(*args, **kwargs)
    monkeypatch.setattr(driver, name, spy)
    return calls


def _check(traj, reference):
    assert traj.success
    np.testing.assert_allclose(traj.t, T_EVAL, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.q, reference.q, rtol=0, atol=1e-6)
    np.testing.assert_allclose(traj.qdot, reference.qdot, rtol=0, atol=1e-6)
    energy = _energy(traj)
    assert np.max(np.abs(energy - energy[0])) <= 1e-7 * energy[0]
    th = traj.q[:, 2]
    sideways = -traj.qdot[:, 0] * np.sin(th) + traj.qdot[:, 1] * np.cos(th)
    assert np.max(np.abs(sideways)) <= 1e-9


NO_C_COMPILER = shutil.which("gcc") is None and shutil.which("cc") is None


@pytest.mark.parametrize("method, route, module", [
    ("CVODES", "integrate_sundials", route_sundials),
    pytest.param("compiled", "integrate_compiled", route_compiled,
                 marks=pytest.mark.skipif(NO_C_COMPILER, reason="no C compiler"))])
def test_each_route_agrees_with_a_tighter_integrator_and_keeps_the_energy(sleigh, monkeypatch, method, route,
                                                                           module):
    """The SUNDIALS and the compiled routes (each spied on: the route really ran) against the
    tighter reference, the sleigh's energy and its rolling constraint (:func:`_check`)."""
    model, reference = sleigh
    calls = _spied(monkeypatch, route, getattr(module, route))
    traj = simulate(model, (0.0, 4.0), Q0, QDOT0, method=method, rtol=1e-9, atol=1e-11, t_eval=T_EVAL)
    assert calls == [route]
    _check(traj, reference)
