"""The scaling families of issue 8 (experiments/scaling_systems.py) against the independent
KanesMethod oracle (tests/oracles.py: frames, bodies, contact-point velocities).

At 100 random constraint-consistent states per member, q̈ of the reduced ODE equals the
oracle's to 1e-10 relative. States are drawn off the singular set (the reduction's singular
measure ≥ 1e-3; near it both sides lose digits with the conditioning of the constraints).
Members: the cart with k ≤ 2 trailers, the 2- and 3-link snakes, the 2-link snake with a head
rotor, and the issue's two reproduction cases (the cart with one trailer in absolute headings,
the snakeboard whose wheels steer independently). The snakeboard with the
implicit form forced checks that form on a thesis system.
"""
from pathlib import Path

import experiment_scripts
import numpy as np
import pytest
from oracles import agreement, oracle

ROOT = Path(__file__).resolve().parents[2]
RTOL = 1e-10


def _families():
    return experiment_scripts.load("scaling_systems")


MEMBERS = {"cart_trailers_0": "explicit", "cart_trailers_1": "implicit", "cart_trailers_2": "implicit",
           "cart_trailer_absolute": "implicit", "snake_2": "explicit", "snake_3": "implicit",
           "snake_2_rotor": "implicit", "snakeboard_two_steering": "implicit"}


@pytest.mark.parametrize("name", list(MEMBERS))
def test_family_member_equals_kane(name):
    from nhgait.dynamics import derive
    system = _families().system(name)
    model = derive(system, "reduced")
    assert model.form == MEMBERS[name]
    assert model.dimension == 2 * system.n - system.k
    worst = agreement(system, model, oracle(name))
    assert worst < RTOL, f"{name}: max relative q̈ error {worst:.3g}"


def test_implicit_form_forced_on_the_snakeboard(systems):
    from nhgait.dynamics.derivation.reduction import derive_reduced
    model = derive_reduced(systems["snakeboard"], form="implicit")
    assert model.form == "implicit"
    assert model.rhs is None
    assert model.implicit.pivots
    assert agreement(systems["snakeboard"], model, oracle("snakeboard")) < RTOL


def test_explicit_and_implicit_forms_give_the_same_vector_field(systems):
    """Both forms of the snakeboard at the same states: ż agrees to 1e-12 (the same Hamel
    equations computed by exact fractions and by CasADi linear solves)."""
    from nhgait.dynamics.derivation.reduction import derive_reduced
    ex = derive_reduced(systems["snakeboard"], form="explicit").numeric
    im = derive_reduced(systems["snakeboard"], form="implicit").numeric
    rng = np.random.default_rng(4)
    pv = systems["snakeboard"].param_vector()
    for _ in range(20):
        z = rng.uniform(-1.0, 1.0, 8)
        u = rng.uniform(-1.0, 1.0, 2)
        np.testing.assert_allclose(im.call("rhs", 0.0, z, u, pv), ex.call("rhs", 0.0, z, u, pv),
                                   rtol=1e-12, atol=1e-12)


def test_the_two_steering_snakeboard_keeps_the_thesis_structure():
    """Issue 8's 6-coordinate case (before: no result in 15 minutes): SE(2) fiber, mixed,
    2n − k states, implicit form (checked against the oracle above)."""
    from nhgait.dynamics import derive
    fam = _families()
    board = derive(fam.system("snakeboard_two_steering"), "reduced")
    assert board.form == "implicit"
    assert board.dimension == 2 * 6 - 2
    assert board.fiber == ("x", "y", "theta")
    assert board.classification == "mixed"


def test_constrained_shape_velocities_four_link_snake():
    """A 4-link snake has more constraints (4) than its fiber (x, y, θ) absorbs: one
    constraint restricts the shape velocities (an extension of the thesis). The reduced ODE
    still has 2n − k states and the constraint residual of q̇(z) vanishes."""
    from nhgait.dynamics import derive
    system = _families().system("snake_4")
    model = derive(system, "reduced")
    assert model.dimension == 2 * 6 - 4
    assert len(model.layout.dependent) == 1
    num, pv = model.numeric, system.param_vector()
    rng = np.random.default_rng(2)
    for _ in range(10):
        z = rng.uniform(-1.0, 1.0, model.dimension)
        qd = num.call("qdot", z, pv)
        assert np.max(np.abs(num.call("constraint", z[:6], qd, pv))) < 1e-12 * max(1.0, np.max(np.abs(qd)))
