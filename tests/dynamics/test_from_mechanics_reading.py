"""What dynamics/derivation/input/from_mechanics.py reads from a KanesMethod, field by field,
against sympy.physics.mechanics itself: the Chaplygin sleigh of tests/oracles.py (a body at
distance a ahead of a knife edge P, the edge's sideways velocity zero, a force F along the
blade at P and a torque τ). References: sympy's ``kinetic_energy`` of the body (T at every
velocity: the sleigh's velocities are its positions' derivatives), its partial velocities
for the generalized forces, and the constraint ``P.vel(N).dot(B.y)`` — each with the speeds
u = q̇ — at random states."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from oracles import kanes_method, model_description
from sympy.physics import mechanics as me

from nhgait.dynamics.derivation.input import from_mechanics

VALUES = {"m": 1.3, "I_c": 0.2, "a": 0.3}


@pytest.fixture(scope="module")
def sleigh():
    description = model_description("chaplygin_sleigh")
    return description, kanes_method(description, [1])


def _plain(expr, q, q_dot, speeds):
    """``expr`` of q(t), q'(t), u(t) in the plain symbols (u = q̇)."""
    t = me.dynamicsymbols._t
    subs = {**{qi.diff(t): v for qi, v in zip(q, q_dot, strict=True)},
            **{u: v for u, v in zip(speeds, q_dot, strict=True)}}
    expr = me.msubs(expr, subs)
    return expr.xreplace({qi: sp.Symbol(qi.func.__name__, real=True) for qi in q})


def test_the_source_fields_are_the_kane_objects(sleigh):
    description, km = sleigh
    source = from_mechanics.read_source(km)
    assert source.kind == "KanesMethod"
    assert source.q == tuple(km.q) and source.u == tuple(km.u)
    assert [q.func.__name__ for q in source.q] == ["x", "y", "theta"]
    assert [u.func.__name__ for u in source.u] == ["u_x", "u_theta", "u_y"]   # independent, then dependent
    assert len(source.velocity_rows) == 1 and source.holonomic == ()
    assert source.frame is description["N"] and len(source.loads) == 2


def test_the_statement_is_sympys_energy_forces_and_constraint(sleigh):
    description, km = sleigh
    statement = from_mechanics.read_statement(km, VALUES)
    fields = statement.fields
    q = description["q"]
    names = [qi.func.__name__ for qi in q]
    assert [str(c) for c in fields["coordinates"]] == names and fields["inputs"] == ["F", "tau"]
    q_dot = sp.symbols([f"{n}_dot" for n in names], real=True)
    speeds = [me.dynamicsymbols(f"u_{n}") for n in names]
    (body,) = description["bodies"]
    N = description["N"]
    T = _plain(me.kinetic_energy(N, body), q, q_dot, speeds)
    F, tau = description["inputs"]
    P, B = description["loads"][0][0], description["loads"][1][0]
    v_P = P.vel(N)
    w_B = B.ang_vel_in(N)
    rates = [qi.diff(me.dynamicsymbols._t) for qi in q]          # partial velocities ∂v/∂q̇_i
    forces = [_plain(v_P.diff(r, N).dot(F * B.x) + w_B.diff(r, N).dot(tau * N.z), q, q_dot, speeds)
              for r in rates]
    row = _plain(description["constraints"][0], q, q_dot, speeds)
    def value(expr, point: dict) -> float:
        """``expr`` at ``point`` (values by symbol name: the model's symbols are positive, the
        statement's real)."""
        expr = sp.sympify(expr)
        return float(expr.xreplace({s: point[s.name] for s in expr.free_symbols}))

    stated_forces = [fields["forces"].get(c, 0) for c in fields["coordinates"]]
    pairs = [(fields["lagrangian"], T), *zip(stated_forces, forces, strict=True)]
    rng = np.random.default_rng(5)
    for _ in range(10):
        point = dict(zip(names + [str(v) for v in q_dot], rng.uniform(-2, 2, 6), strict=True))
        point.update(VALUES, F=0.7, tau=-0.4)
        for got, want in pairs:
            assert value(got, point) == pytest.approx(value(want, point), rel=1e-12, abs=1e-12)
        (c,) = fields["constraints"]                 # the same row up to its sign
        assert abs(value(c, point) / value(row, point)) == pytest.approx(1.0, rel=1e-12)
