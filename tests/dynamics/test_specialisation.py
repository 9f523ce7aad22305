"""dynamics.specialisation: parameter values bound (symbolic normal form or numeric binding),
velocity coordinates, the cache key, and the fallback for implicit models.

Independent references: the general reduced model evaluated with the parameter vector (the
specialisation must reproduce it to round-off at random states), and the momentum ODE
re-simulated by DOP853 (the velocity-coordinate flow must be the same flow).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.numerics.specialisation import choose_velocities, specialise

SNAKEBOARD_V = ("forward_velocity", "psi_dot", "phi_dot")


def _agree(a, b, nz, nu, params, rtol=1e-12, samples=20):
    rng = np.random.default_rng(1)
    for _ in range(samples):
        z, u = rng.uniform(-1, 1, nz), rng.normal(size=nu)
        x = np.asarray(a.numeric["rhs"](0, z, u, params)).ravel()
        y = np.asarray(b.numeric["rhs"](0, z, u, params)).ravel()
        assert np.allclose(x, y, rtol=rtol, atol=rtol), np.max(np.abs(x - y))


def test_symbolic_route_reproduces_the_general_model(models):
    model = models["snakeboard"]["reduced"]
    fast = specialise(model, use_cache=False)
    assert fast.route == "symbolic"
    assert fast.numeric["rhs"].n_instructions() < model.numeric["rhs"].n_instructions() / 2
    _agree(fast, model, 8, 2, model.numeric.params())


def test_velocity_model_is_small_and_has_the_momentum_flow(models):
    """Same controls, same initial condition mapped by state(q, q̇): the configurations agree."""
    from nhgait.ocp.solution import simulate_piecewise_constant
    model = models["snakeboard"]["reduced"]
    fast = specialise(model, velocities=SNAKEBOARD_V, use_cache=False)
    assert fast.route == "symbolic"
    assert fast.state_names[5:] == SNAKEBOARD_V
    assert fast.numeric["rhs"].n_instructions() <= 60     # hand-written reference: 49
    P = model.numeric.params()
    q0, qd0 = np.array([0.1, -0.2, 0.3, 0.1, 0.2]), np.array([0.0, 0.0, 0.0, 0.4, -0.3])
    qd0[:3] = np.asarray(model.numeric["qdot"](model.numeric["state"](q0, qd0, P), P)).ravel()[:3]
    t = np.linspace(0.0, 2.0, 9)
    controls = np.random.default_rng(2).normal(size=(2, 8))
    zv, ok_v = simulate_piecewise_constant(fast, P, t,
                                           np.asarray(fast.numeric["state"](q0, qd0, P)).ravel(), controls)
    zp, ok_p = simulate_piecewise_constant(model, P, t,
                                           np.asarray(model.numeric["state"](q0, qd0, P)).ravel(), controls)
    assert ok_v
    assert ok_p
    assert np.max(np.abs(zv[:5] - zp[:5])) < 1e-8          # DOP853 at rtol 1e-10 over 2 s
    mapped = np.column_stack([np.asarray(fast.numeric["momentum_state"](zv[:, k], P)).ravel()
                              for k in range(9)])
    assert np.max(np.abs(mapped - zp)) < 1e-8
    qd = np.asarray(fast.numeric["qdot"](zv[:, -1], P)).ravel()
    assert qd[0] * np.cos(zv[2, -1]) + qd[1] * np.sin(zv[2, -1]) == pytest.approx(zv[5, -1], abs=1e-12)


def test_parameter_values_key_the_cache(models):
    model = models["unicycle"]["reduced"]
    a = specialise(model)
    b = specialise(model, {"r": 0.2})
    assert a.numeric.params()[list(a.numeric.param_names).index("r")] == 0.1
    z = np.array([0.0, 0.0, 0.3, 0.0, 0.5, 0.2])
    ax = np.asarray(a.numeric["qdot"](z, a.numeric.params())).ravel()
    bx = np.asarray(b.numeric["qdot"](z, b.numeric.params())).ravel()
    # the rolling constraint ẋ = r cos θ φ̇ with each model's own r (closed form)
    assert ax[0] == pytest.approx(0.1 * np.cos(0.3) * ax[3], rel=1e-12)
    assert ax[0] != 0
    assert bx[0] == pytest.approx(0.2 * np.cos(0.3) * bx[3], rel=1e-12)
    again = specialise(model, {"r": 0.2})                  # from the cache: same functions
    assert np.allclose(np.asarray(again.numeric["qdot"](z, 0)).ravel(), bx, rtol=0, atol=0)


@dataclass(frozen=True, eq=False)
class _Implicit:
    """A reduced model in the engine's implicit form: no sympy rhs, numeric functions only."""

    base: object
    form: str = "implicit"
    rhs: object = None

    def __getattr__(self, name):
        return getattr(self.base, name)


def test_implicit_models_bind_numerically(models):
    """The snakeboard is SE(2)-invariant (forces included): the numeric route evaluates at the
    group identity and rotates ṡ back; in velocity coordinates Maggi's form (AD of L with the
    basis of ker ω dual to the velocity states) is cheaper still. Both reproduce the general
    model / its exact normal form, and each is cheaper than the 20 steps' graph with the values
    bound."""
    model = models["snakeboard"]["reduced"]
    implicit = _Implicit(model)
    plain = specialise(implicit, use_cache=False)
    assert plain.route == "numeric at the group identity"
    _agree(plain, model, 8, 2, model.numeric.params())
    assert plain.numeric["rhs"].n_instructions() < model.numeric["rhs"].n_instructions()
    fast = specialise(implicit, velocities=SNAKEBOARD_V, use_cache=False)
    symbolic = specialise(model, velocities=SNAKEBOARD_V, use_cache=False)
    assert fast.route == "Maggi in the velocity basis at the group identity"
    _agree(fast, symbolic, 8, 2, model.numeric.params(), rtol=1e-10)


def test_a_force_that_breaks_the_symmetry_keeps_the_general_functions():
    """A world-frame force on the Chaplygin sleigh (F along x whatever the heading) is not
    invariant under rotations: evaluated at θ = 0 and rotated back it would be wrong, so the
    check keeps the general functions — which reproduce the derived model."""
    from nhgait.dynamics import System, derive

    def sleigh(forces):
        return System(coordinates=["x", "y", "theta"],
                      lagrangian="m*((x_dot - a*sin(theta)*theta_dot)**2 + (y_dot + "
                                 "a*cos(theta)*theta_dot)**2)/2 + I_c*theta_dot**2/2",
                      constraints=["-sin(theta)*x_dot + cos(theta)*y_dot"], forces=forces,
                      parameters={"m": 1.0, "I_c": 0.2, "a": 0.3}, fiber=["x", "y", "theta"], name="sleigh")
    from nhgait.dynamics.numerics.specialisation import _agrees, _at_identity, _numeric_bound, _Reference
    world = derive(sleigh({"x": "F", "theta": "tau"}), "reduced")
    plain = specialise(_Implicit(world), use_cache=False)
    assert plain.route == "numeric"
    _agree(plain, world, 5, 2, world.numeric.params())
    # the mechanism: evaluated at θ = 0 and rotated back, the world-frame force is wrong (the
    # check refuses it); the same force written in the body frame is right
    body = derive(sleigh({"x": "F*cos(theta)", "y": "F*sin(theta)", "theta": "tau"}), "reduced")
    for model, invariant in ((world, False), (body, True)):
        params = model.numeric.params()
        reference = _numeric_bound(model, params)
        assert (_agrees(_at_identity(model, reference), _Reference(reference, 5, 2, params), 1e-10)
                is invariant)


def test_choose_velocities(models):
    assert choose_velocities(models["snakeboard"]["reduced"], ("x", "forward_velocity", "psi", "phi_dot")) \
        == ("forward_velocity", "phi_dot", "psi_dot")
    assert (choose_velocities(models["unicycle"]["reduced"], ("phi_dot", "theta_dot"))
            == ("phi_dot", "theta_dot"))


def test_bad_velocity_coordinates_are_listed(models):
    with pytest.raises(ModelError, match=r"(?s)'omega' is not a velocity quantity.*repeated names"):
        specialise(models["snakeboard"]["reduced"], velocities=("omega", "psi_dot", "psi_dot"))
    with pytest.raises(ModelError, match=r"\[ω; Y\] is singular"):
        specialise(models["snakeboard"]["reduced"], velocities=("lateral_velocity", "psi_dot", "phi_dot"))
    with pytest.raises(ModelError, match="needs 3 velocity quantities"):
        specialise(models["snakeboard"]["reduced"], velocities=("psi_dot",))


def test_generated_chain_specialised_where_its_chart_is_singular():
    """A 5-link chain of the any-robot benchmark (pair 24/4: n = 7, k = 4) in the velocities
    (ẋ, ẏ, q̇₄) — the planner's choice for its turning task. Two bugs stood in the way: the rank
    check evaluated Y X in the reduction's chart, non-finite at a random posture (numpy's SVD raised
    LinAlgError), and Maggi's form substituted q̇ = X v with a structurally sparse X v (CasADi
    refused). Checked against the benchmark's independent Lagrange DAE (q̈, λ from the KKT system)
    at random postures and at the straight one, on the chart's singular set: q̇ satisfies the
    constraints and has the velocity states as its components, and ẏ = (ẍ, ÿ, q̈₄) to 1e-8."""
    import experiment_scripts

    from nhgait.dynamics import derive
    from nhgait.dynamics.derivation.input.scene import scene_from_text
    gen, ref = experiment_scripts.load("robot_generator"), experiment_scripts.load("reference_dae_ocp")
    pair = gen.pair(24, 4)
    scene = scene_from_text(pair.scene, pair.name)
    model = derive(scene.system, "reduced")
    names = ("x_dot", "y_dot", "q4_dot")
    fast = specialise(model, velocities=names, quantities=scene.quantities, use_cache=False)
    dae = ref.dae(pair.robot)
    params = model.numeric.params()
    coords = list(model.system.coordinates)
    pick = [coords.index(c[:-4]) for c in names]
    rng = np.random.default_rng(4)
    postures = [np.zeros(7)] + [rng.uniform(-0.7, 0.7, 7) for _ in range(4)]
    for q in postures:
        y, u = rng.normal(size=3), rng.normal(size=4)
        z = np.concatenate([q, y])
        qdot = np.asarray(fast.numeric["qdot"](z, params)).ravel()
        assert np.allclose(np.asarray(dae["omega"](q)) @ qdot, 0, atol=1e-10)
        assert np.allclose(qdot[pick], y, atol=1e-12)
        qddot = np.asarray(dae["accel"](q, qdot, u)[0]).ravel()
        ydot = np.asarray(fast.numeric["rhs"](0, z, u, params)).ravel()[7:]
        assert np.allclose(ydot, qddot[pick], rtol=1e-8, atol=1e-8), (q, ydot, qddot[pick])
