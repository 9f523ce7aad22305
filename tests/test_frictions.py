"""Issue 41 item 3, the frictions a new user met: ``simulate`` stopping at the reduced chart's
singular set names the formulation that runs through it (and switches to it when none was
pinned); singular sets and step 1's M(q) stored readable (no common-subexpression soup);
step 2's sentence says where its columns span D_q; SE(2) on the planar frame preferred."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from adversarial import answer

SCENES = Path(__file__).resolve().parent / "scenes"
TWO_LINKS = SCENES / "sleigh_two_links.toml"
SLIDER = SCENES / "sleigh_slider.toml"
#: φ where the two-link sleigh's reduced chart is singular: L1 cos φ + L2 = 0 (L1 = 0.75, L2 = 0.5)
PHI_SINGULAR = math.acos(-0.5 / 0.75)


def _read_q(path: Path) -> np.ndarray:
    with path.open() as fh:
        rows = list(csv.reader(fh))
    return np.array(rows[-1][1:], dtype=float)


def test_simulate_switches_to_lagrange_through_the_charts_singular_set(sandbox):
    """No formulation pinned: the reduced run stops at φ = 2.3005, the command says that
    --formulation lagrange runs through it and does so; the end state matches the Hamilton
    DAE at rtol 1e-11 (an independent formulation) to 1e-6."""
    from nhgait.dynamics import derive, load_scene, simulate
    out = sandbox.out / "two.csv"
    said = answer(["simulate", TWO_LINKS, "--out", out]).check(0, None, sandbox)
    assert "reached the singular set" in said.err
    assert "--formulation lagrange runs through it: the set is the reduced chart's, not the robot's " \
           "(at phi = 2.3005" in said.err
    assert "integrating again with it (--formulation reduced keeps the stop)" in said.err
    assert "sleigh_two_links: lagrange formulation" in said.out
    scene = load_scene(TWO_LINKS)
    spec = scene.simulation
    reference = simulate(derive(scene.system, "hamilton"), (spec.t0, spec.t_final), spec.q0, spec.qdot0,
                         controller=spec.controller, rtol=1e-11, atol=1e-13)
    assert reference.success and reference.q[-1][3] > PHI_SINGULAR + 0.5      # it went through
    np.testing.assert_allclose(_read_q(out), reference.q[-1], atol=1e-6)


def test_a_pinned_reduced_formulation_keeps_the_stop_and_names_the_way_through(sandbox):
    said = answer(["simulate", TWO_LINKS, "--formulation", "reduced", "--out", sandbox.out / "r.csv"]).check(
        1, None, sandbox)
    assert "simulation stopped: reached the singular set" in said.err
    assert "L1*cos(phi) + L2 = 0" in said.err
    assert "; --formulation lagrange runs through it" in said.err
    assert _read_q(sandbox.out / "r.csv")[3] == pytest.approx(PHI_SINGULAR, abs=1e-4)


def test_the_singular_set_is_stored_readable_and_vanishes_where_the_run_stopped():
    """Each expression as stored: no CSE names, the trig normal form collected and factored;
    one of them is L1 cos φ + L2, zero at the stop."""
    from nhgait.dynamics import derive, load_scene
    model = derive(load_scene(TWO_LINKS).system, "reduced")
    text = model.checks_text().splitlines()[-1]
    assert text.startswith("singular set: ") and " where " not in text and "x0" not in text
    L1, L2, phi = sp.symbols("L1 L2 phi", real=True)
    assert any(sp.expand(e - (L1 * sp.cos(phi) + L2)) == 0 for e in model.singular_set)
    values = {s: v for s, v in zip(model.system.param_symbols, model.system.param_vector(), strict=True)}
    values[model.system.q[3]] = PHI_SINGULAR
    assert min(abs(float(e.subs(values))) for e in model.singular_set) < 1e-12


def test_step_one_shows_m_simplified_and_equal_to_the_hessian_of_l():
    """m_s(sin²θ + cos²θ) is shown as m_s; the shown M equals ∂²L/∂q̇² exactly."""
    from nhgait.dynamics import derive, load_scene
    system = load_scene(SLIDER).system
    shown = derive(system, "reduced").steps[1].M
    m_s = sp.Symbol("m_s", real=True)
    assert shown[3, 3] == m_s
    hessian = sp.hessian(system.L, system.q_dot)
    assert sp.simplify(shown - hessian) == sp.zeros(4, 4)
    assert "sin(theta)**2 + cos(theta)**2" not in str(shown)


def test_step_two_says_where_its_columns_span_the_distribution():
    """The sleigh with a sliding mass: the column (0, 0, sin θ, 0) vanishes at θ = 0, where
    rank ω = k = 1 — the sentence names the pivot minor det B = −sin θ, not "rank ω < k"."""
    from nhgait.dynamics import derive, load_scene
    system = load_scene(SLIDER).system
    step = derive(system, "reduced").steps[2]
    assert "vanish only where rank ω < k" not in step.note
    assert "with B = ω[:, (x)]" in step.note and "det B = -sin(theta) = 0" in step.note
    theta = system.q[2]
    at_zero = step.D.subs(theta, 0)
    assert any(all(e == 0 for e in at_zero[:, j]) for j in range(at_zero.shape[1]))
    assert system.omega().subs(theta, 0).rank() == system.k


def test_se2_on_the_planar_frame_is_preferred_and_the_others_named():
    """A sleigh with (x, y, θ): SE(2) moves (x, y, θ) — not R²(x, y) with θ a shape
    coordinate — and the translations stay named as a choice."""
    from nhgait.dynamics import derive, load_scene
    model = derive(load_scene(SLIDER).system, "reduced")
    assert tuple(model.fiber) == ("x", "y", "theta")
    text = model.to_text()
    assert "SE(2) on the planar frame (x, y, heading) comes first" in text
    assert "fiber = ['x', 'y'] (R^2 (x, y), full)" in text


def test_an_unevaluated_determinant_of_the_singular_set_is_named_by_its_size():
    """A determinant too large to write out (systems from bodies) is printed by its size, not
    as a page of sub-expressions."""
    from nhgait.dynamics.derivation.reduction.model import set_text
    x = sp.Symbol("x")
    text = set_text(sp.Determinant(sp.ImmutableMatrix([[x, 1], [2, sp.sin(x) + x ** 2]])))
    assert text == "det of a 2×2 matrix (3 operations; model.singular_set holds it)"
