"""The reduced derivation has a fast path (ring fractions, `FracField`) and the plain sympy
path it falls back to for expressions outside rational trig functions. Both must give the
same objects; the fallback must be exercised and correct."""
import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import System, derive
from nhgait.dynamics.reduction import _derive_reduced_field, _derive_reduced_plain
from conftest import SYSTEMS


@pytest.mark.parametrize("name", SYSTEMS)
def test_fast_and_plain_paths_give_identical_objects(name, systems):
    s = systems[name]
    fast, plain = _derive_reduced_field(s), _derive_reduced_plain(s)
    for attr in ("rhs", "X", "K", "qdot", "momenta_of_velocity", "structure"):
        assert getattr(fast, attr) == getattr(plain, attr), attr
    assert sp.expand(fast.hamiltonian - plain.hamiltonian) == 0
    for a, b in zip(fast.steps, plain.steps):
        for key in a.items:
            va, vb = a.items[key], b.items[key]
            if isinstance(va, (sp.Basic, sp.MatrixBase)):
                assert va == vb, (a.number, key)


def test_fallback_path_for_non_rational_expressions():
    """A potential with √(1 + x²) and exp(θ/3) (shape coordinates of the fiber y): derivatives of opaque functions
    of coordinates force the plain path; the result must still equal the Lagrangian DAE."""
    import nhgait.dynamics.reduction as red_mod
    with pytest.raises(red_mod._NotRational):
        red_mod._derive_reduced_field(System(coordinates=["x", "y", "theta"],
            lagrangian="m*(x_dot**2 + y_dot**2)/2 + I*theta_dot**2/2 - k*sqrt(1 + x**2)",
            constraints=["sin(theta)*x_dot - cos(theta)*y_dot"], parameters={"m": 1.0, "I": 0.1, "k": 0.5}))
    s = System(coordinates=["x", "y", "theta"],
               lagrangian="m*(x_dot**2 + y_dot**2)/2 + I*theta_dot**2/2 - k*sqrt(1 + x**2) - c*exp(theta/3)",
               constraints=["sin(theta)*x_dot - cos(theta)*y_dot"], forces={"theta": "tau"},
               parameters={"m": 1.0, "I": 0.1, "k": 0.5, "c": 0.2}, name="opaque")
    red = derive(s, "reduced", use_cache=False)
    lag = derive(s, "lagrange", use_cache=False).numeric
    pv = s.param_vector()
    rng = np.random.default_rng(3)
    for _ in range(30):
        q = rng.uniform(-1.0, 1.0, 3)
        v, w = rng.uniform(-1, 1, 2)
        qd = np.array([v * np.cos(q[2]), v * np.sin(q[2]), w])
        u = rng.uniform(-1, 1, 1)
        z = red.numeric.call("state", q, qd, pv)
        ref = lag.call("ode", 0.0, np.r_[q, qd], u, pv)[0][3:]
        got = red.numeric.call("qddot", 0.0, z, u, pv)
        assert np.max(np.abs(got - ref)) / max(1.0, np.max(np.abs(ref))) < 1e-10
