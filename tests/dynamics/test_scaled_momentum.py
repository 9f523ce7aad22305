"""Shammas's scaled-momentum height functions of a mixed system (issue 42, item 3) against
independent computations: the compiled reduced equations (σ_ab by exact polarisation of ṗ(ṙ),
Γ from ṡ at ṙ = 0, p = 1 and a hand-written SE(2) frame) with complex-step derivatives of A,
to 1e-9; and the snakeboard's full reduced ODE along circular shape loops from rest
(:func:`fibre_motion`, midpoint rule, 2000 steps), against which the Stokes estimate's relative
error falls at least linearly in the loop's radius ε."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from nhgait.dynamics import derive
from nhgait.dynamics.derivation.input.scene import load_scene
from nhgait.dynamics.derivation.models import snakeboard
from nhgait.dynamics.errors import ModelError
from nhgait.dynamics.geometry.connection_fields import local_connection, numeric_connection
from nhgait.dynamics.geometry.heights import (
    HeightGrid,
    evaluate_heights,
    evaluate_heights_numeric,
    height_function,
)
from nhgait.dynamics.geometry.prescribed import FibreIntegrator
from nhgait.dynamics.geometry.reconstruction import reconstruction
from nhgait.dynamics.geometry.scaled_momentum import scaled_momentum
from nhgait.dynamics.geometry.stokes import stokes_displacement

CENTRE = np.array([0.2, 0.3])          # (ψ, φ) of the loops: away from φ = 0, where H_θ = 0


@pytest.fixture(scope="module")
def board():
    return derive(snakeboard(), "reduced")


@pytest.fixture(scope="module")
def momentum(board):
    return scaled_momentum(board, "psi", "phi")


@pytest.fixture(scope="module")
def integrator(board):
    return FibreIntegrator(board)


def _rates(model, q, r_dot, p):
    """(ṡ, ṗ) of the compiled reduced equations at q with shape velocity ``r_dot`` and
    nonholonomic momentum ``p`` (the shape momenta from the horizontal lift, inputs zero)."""
    numeric, layout = model.numeric, model.layout
    n, d, nP = model.system.n, layout.d, len(model.momenta)
    values = np.asarray(numeric.params(None), float)
    X = np.asarray(numeric["basis"](np.concatenate([q, np.zeros(nP)]), values))
    P_r = np.asarray(numeric["state"](q, X[:, d:] @ r_dot, values)).ravel()[n + d:]
    z_dot = np.asarray(numeric["rhs"](0.0, np.concatenate([q, [p], P_r]), np.zeros(len(model.system.inputs)),
                                      values)).ravel()
    return z_dot[list(layout.si)], z_dot[n]


def _independent_scaled_height(model, q, h=1e-30):
    """H_A by complex-step derivatives of A (sympy matrix lambdified) and the hand-written se(2)
    bracket, plus −σ_ψφ Γ from the compiled equations: σ_ψφ = [f(1,1) − f(1,−1) − f(−1,1) +
    f(−1,−1)]/8 for the quadratic f(ṙ) = ṗ at p = 0 (exact: no step), Γ = g(θ)ᵀṡ at ṙ = 0, p = 1."""
    system = model.system
    f = sp.lambdify(list(system.q) + list(system.param_symbols), local_connection(model).A, "numpy")
    params = list(system.param_vector())

    def dA(i):
        z = np.array(q, complex)
        z[i] += 1j * h
        return np.imag(np.array(f(*z, *params), complex)) / h

    A = np.array(f(*q, *params), float)
    u, v = A[:, 0], A[:, 1]
    bracket = np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], 0.0])
    H = -(dA(3)[:, 1] - dA(4)[:, 0]) + bracket
    p_dot = [_rates(model, q, np.array(s), 0.0)[1] for s in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    sigma = (p_dot[0] - p_dot[1] - p_dot[2] + p_dot[3]) / 8
    c, s = np.cos(q[2]), np.sin(q[2])
    g = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    Gamma = g.T @ _rates(model, q, np.zeros(2), 1.0)[0]
    return H - sigma * Gamma


def test_scaled_momentum_height_matches_the_compiled_equations(board, momentum):
    system = board.system
    H = sp.lambdify(list(system.q) + list(system.param_symbols),
                    height_function(local_connection(board), "psi", "phi", momentum=momentum), "numpy")
    for q in np.random.default_rng(7).uniform(-0.9, 0.9, size=(5, system.n)):
        got = np.array(H(*q, *system.param_vector()), float).ravel()
        want = _independent_scaled_height(board, q)
        assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, np.max(np.abs(want)))


def test_the_snakeboard_in_closed_form(momentum):
    """With the default r = √((J + J_r + 2J_w)/m) the denominators are c = J + J_r + 2J_w:
    σ_ψφ = J_r cos²φ, σ_φp = −tan φ (F = ln cos φ), Γ = (r/2c, 0, tan φ/2c)
    (hand-derived), so H̄_x = J_r r(cos 2φ − cos²φ/2)/c and H̄_θ = ¾ J_r sin 2φ/c."""
    m, J, J_r, J_w, r = momentum.params
    c = J + J_r + 2 * J_w
    phi = 0.4
    assert np.isclose(momentum.factor(0.7, phi), np.log(np.cos(phi)), atol=1e-12)
    assert np.allclose(momentum.Gamma_bar(0.7, phi), [r * np.cos(phi) / (2 * c), 0, np.sin(phi) / (2 * c)])
    assert np.allclose(momentum.sigma_bar(0.7, phi), [[0, J_r * np.cos(phi)], [J_r * np.cos(phi), 0]])
    H = sp.lambdify(momentum.system.q[4], momentum.height().subs(
        dict(zip(momentum.system.param_symbols, momentum.params, strict=True))), "numpy")
    assert np.allclose(np.asarray(H(phi), float).ravel(),
                       [-J_r * np.cos(phi) ** 2 * r / (2 * c), 0, -J_r * np.sin(2 * phi) / (4 * c)])


def _log_se2(x, y, th):
    a = th / 2 / np.tan(th / 2) if abs(th) > 1e-12 else 1.0
    return np.array([a * x + th / 2 * y, -th / 2 * x + a * y, th])


def _circle(integrator, eps, phase=0.0, steps=2000):
    """(samples ψ, φ, the simulated displacement log(g), final p) of the counter-clockwise
    circle r = CENTRE + ε(cos(t + phase), sin(t + phase)) from rest at the identity."""
    t = np.linspace(0, 2 * np.pi, steps + 1)
    a, b = CENTRE[0] + eps * np.cos(t + phase), CENTRE[1] + eps * np.sin(t + phase)
    motion = integrator(t, np.vstack([np.zeros((3, t.size)), a, b]))
    return a, b, _log_se2(*motion.fiber[:, -1]), motion.momentum[0, -1]


def _height_of(board, momentum=None):
    system = board.system
    H = height_function(local_connection(board), "psi", "phi", momentum=momentum)
    values = dict(zip(system.param_symbols, system.param_vector(), strict=True))
    return sp.lambdify(system.q[3:5], H.subs(values), "numpy")


def test_stokes_estimate_of_a_circle_from_rest_converges_linearly(board, momentum, integrator):
    """∬H̄ over the disc against the simulated loop: relative error O(ε), the momentum back at
    zero; the connection's height alone (momentum held at zero) is off by about 90 %."""
    scaled, geometric = _height_of(board, momentum), _height_of(board)
    errors = []
    for eps in (0.2, 0.1, 0.05):
        a, b, exact, p_end = _circle(integrator, eps)
        assert abs(p_end) < 1e-9
        errors.append([np.linalg.norm(stokes_displacement(H, a[:-1], b[:-1]) - exact) / np.linalg.norm(exact)
                       for H in (scaled, geometric)])
    errors = np.array(errors)
    assert np.all(errors[1:, 0] <= 0.6 * errors[:-1, 0])        # at least linear: halving ε
    assert errors[-1, 0] < 0.005
    assert np.all(errors[:, 1] > 0.5)


def test_the_convergence_holds_for_another_wheel_radius():
    """With r = 0.7 m (m r² ≠ J + J_r + 2J_w: no common denominator, F ≠ ln cos φ) the error
    still falls at least linearly (3.6 %, 1.3 %, 0.58 % measured)."""
    board = derive(snakeboard(r=0.7), "reduced")
    scaled, integrator = _height_of(board, scaled_momentum(board, "psi", "phi")), FibreIntegrator(board)
    errors = []
    for eps in (0.2, 0.1, 0.05):
        a, b, exact, _ = _circle(integrator, eps)
        estimate = stokes_displacement(scaled, a[:-1], b[:-1])
        errors.append(np.linalg.norm(estimate - exact) / np.linalg.norm(exact))
    assert np.all(np.array(errors[1:]) <= 0.6 * np.array(errors[:-1])) and errors[-1] < 0.01


def test_the_start_phase_multiplies_the_momentum_part_by_cos_2_theta0(board, momentum, integrator):
    """Started a quarter turn later (θ₀ = π/2) the momentum part changes sign (module docstring)."""
    scaled, geometric = _height_of(board, momentum), _height_of(board)
    a, b, exact, _ = _circle(integrator, 0.05, phase=np.pi / 2)
    S_geo = stokes_displacement(geometric, a[:-1], b[:-1])
    estimate = S_geo - (stokes_displacement(scaled, a[:-1], b[:-1]) - S_geo)
    assert np.linalg.norm(estimate - exact) / np.linalg.norm(exact) < 0.01       # 0.7 % measured


@pytest.mark.parametrize("field", ["sigma_rr", "Gamma"])
def test_a_flipped_sign_in_sigma_or_Gamma_fails_the_simulation_check(board, momentum, integrator, field):
    flipped = dataclasses.replace(momentum, **{field: -getattr(momentum, field)})
    a, b, exact, _ = _circle(integrator, 0.05)
    estimate = stokes_displacement(_height_of(board, flipped), a[:-1], b[:-1])
    assert np.linalg.norm(estimate - exact) / np.linalg.norm(exact) > 0.5


def test_the_integrating_factor_makes_the_momentum_equation_exact(momentum, integrator):
    """Along a large loop from rest (ψ = 0.8 sin t, φ = 0.3 + 0.5 cos t), p̄ = e^{−F}p from the
    full reduced ODE equals ∫ṙᵀσ̄_rr ṙ dt (trapezoid on the samples) to 1e-4 of its range; with
    σ_rp's sign flipped (p̄ = e^{+F}p, σ̄ = e^{+F}σ) or no factor at all it does not."""
    t = np.linspace(0, 2 * np.pi, 4001)
    a, b = 0.8 * np.sin(t), 0.3 + 0.5 * np.cos(t)
    p = integrator(t, np.vstack([np.zeros((3, t.size)), a, b])).momentum[0]
    F = momentum.factor(a, b)
    rate = (np.gradient(a, t), np.gradient(b, t))
    system = momentum.system
    sigma = sp.lambdify(system.q[3:5], momentum.sigma_rr[0, 1].subs(
        dict(zip(system.param_symbols, momentum.params, strict=True))), "numpy")(a, b) + 0 * a

    def mismatch(sign):
        f = np.exp(sign * F)                                        # sign −1: the scaled momentum
        integrand = 2 * f * sigma * rate[0] * rate[1]
        integral = np.concatenate([[0], np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(t))])
        return np.max(np.abs(f * p - integral)) / np.ptp(integral)

    assert mismatch(-1) < 1e-4
    assert mismatch(+1) > 1e-2
    assert np.max(np.abs(F)) > 0.1                                  # the factor is not trivial here


def test_numeric_scaled_heights_equal_the_symbolic_ones(board, momentum):
    """evaluate_heights_numeric(..., equation=) (compiled basis, central differences, σ and Γ
    from the reconstruction's numbers) = evaluate_heights(..., momentum=) to 1e-7."""
    box = HeightGrid(bounds={"psi": (-1, 1), "phi": (-1, 1)}, points=7)
    symbolic = evaluate_heights(local_connection(board), "psi", "phi", box, momentum=momentum)
    numeric = evaluate_heights_numeric(numeric_connection(board), "psi", "phi", box,
                                       equation=reconstruction(board))
    assert symbolic.form == numeric.form == "scaled momentum"
    scale = np.max(np.abs(symbolic.heights))
    assert np.max(np.abs(numeric.heights - symbolic.heights)) <= 1e-7 * scale
    assert np.allclose(numeric.momentum_part, symbolic.momentum_part, atol=1e-12)
    plain = evaluate_heights(local_connection(board), "psi", "phi", box)
    assert np.allclose(symbolic.heights - symbolic.momentum_part, plain.heights, atol=1e-12)


def test_bad_requests_name_every_problem(board):
    snake = derive(load_scene(str(Path(__file__).resolve().parents[1] / "scenes" / "snake3.toml")).system,
                   "reduced")
    with pytest.raises(ModelError, match=r"(?s)'x' is not a shape coordinate.*one nonholonomic momentum"):
        scaled_momentum(snake, "x", "alpha1")
    with pytest.raises(ModelError, match="two different shape coordinates"):
        scaled_momentum(board, "phi", "phi")


def test_parts_figure_has_names_units_and_three_columns(board, momentum, tmp_path):
    from nhgait.gaits.figures.geometry import height_parts_figure
    units = {"x": "m", "y": "m", "theta": "rad", "psi": "rad", "phi": "rad"}
    grid = evaluate_heights(local_connection(board), "psi", "phi",
                            HeightGrid(bounds={"psi": (-1, 1), "phi": (-1, 1)}, points=9, units=units),
                            momentum=momentum)
    fig = height_parts_figure(grid, components=("x", "theta"))
    labels = [a.get_ylabel() for a in fig.axes]
    assert any("scaled-momentum height H̄ of x [m/rad²]" in text for text in labels)
    assert any("momentum part −σ̄Γ̄ of theta [rad/rad²]" in text for text in labels)
    assert fig.axes[0].get_xlabel() == "psi [rad]"
    fig.savefig(tmp_path / "parts.png")
    assert (tmp_path / "parts.png").stat().st_size > 10_000


def test_the_docstring_example_runs():
    """The ``>>>`` example of :func:`scaled_momentum` (F = ln cos φ, the closed form above)."""
    import doctest

    import nhgait.dynamics.geometry.scaled_momentum as module
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.attempted >= 4 and result.failed == 0
