"""Printing of the reduced model: Markdown and LaTeX with no arguments, LaTeX that a real
LaTeX engine compiles (pdflatex when installed; otherwise the structural checks alone: ASCII
only, balanced braces, velocities as \\dot{…}), a one-line repr, and the implicit form's text."""
import re
import shutil
import subprocess
from pathlib import Path

import experiment_scripts
import pytest

from nhgait.dynamics.derivation.steps import latex_document, tex_text

ROOT = Path(__file__).resolve().parents[2]


def _family_system(name):
    return experiment_scripts.load("scaling_systems").system(name)


@pytest.fixture(scope="module")
def trailer():
    from nhgait.dynamics import derive
    return derive(_family_system("cart_trailer_absolute"), "reduced")


def _structural(tex: str):
    assert tex.isascii(), sorted({c for c in tex if not c.isascii()})
    depth = 0
    for ch in re.sub(r"\\[{}]", "", tex):
        depth += ch == "{"
        depth -= ch == "}"
        assert depth >= 0
    assert depth == 0
    assert "_{dot}" not in tex
    assert "\\paragraph{Step" in tex


def test_tex_text_transliterates_unicode():
    assert tex_text("ω(q)q̇ = 0, P̃_α, ṡ = gξ, rank < k") == \
        "$\\omega$(q)$\\dot{q}$ = 0, $\\tilde{P}$\\_$\\alpha$, $\\dot{s}$ = g$\\xi$, rank $<$ k"


@pytest.mark.parametrize("which", ["snakeboard", "trailer"])
def test_steps_print_without_arguments(which, models, trailer):
    model = models["snakeboard"]["reduced"] if which == "snakeboard" else trailer
    md = model.steps.to_markdown()
    tex = model.steps.to_latex()
    assert all(f"### Step {i}:" in md for i in range(1, 21))
    _structural(tex)
    if which == "snakeboard":
        assert "\\dot{\\theta}" in tex
        assert "\\tilde{p}_{\\psi}" in tex


def _compile(tex: str, tmp_path):
    (tmp_path / "steps.tex").write_text(latex_document(tex))
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "steps.tex"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-3000:]
    assert (tmp_path / "steps.pdf").stat().st_size > 0


@pytest.mark.skipif(shutil.which("pdflatex") is None,
                    reason="no LaTeX engine installed (structural checks run)")
@pytest.mark.parametrize("which", ["snakeboard", "trailer"])
def test_latex_export_compiles(which, models, trailer, tmp_path):
    model = models["snakeboard"]["reduced"] if which == "snakeboard" else trailer
    _compile(model.steps.to_latex(), tmp_path)


def test_repr_is_one_line_and_text_of_the_implicit_form(trailer, models):
    for model in (trailer, models["unicycle"]["reduced"]):
        assert "\n" not in repr(model)
        assert repr(model).startswith("ReducedODE(")
    text = trailer.to_text()
    assert "implicit form" in text
    assert "K(q) v = (pt_theta0, pt_theta1)" in text
    assert trailer.rhs is None
    assert trailer.steps[5].A.operations > 0


def test_cli_derive_scene_file_with_checks_and_steps(tmp_path, capsys):
    from nhgait.gaits.cli.main import main
    mod = experiment_scripts.load("scaling_systems")
    scene = tmp_path / "trailer.toml"
    scene.write_text(mod.cart_trailer_absolute())
    assert main(["derive", str(scene), "--checks", "--steps", "latex"]) == 0
    out = capsys.readouterr().out
    assert "7 = 2n − k first-order ODEs, implicit form" in out
    assert "reduced bracket: almost-Poisson (the Jacobi identity does not hold" in out
    assert "singular set:" in out
    assert "\\paragraph{Step 20: Reconstruction of the fiber velocities}" in out


def test_dataclasses_replace_keeps_every_field(models):
    import dataclasses

    from nhgait.dynamics import unicycle
    model = models["unicycle"]["reduced"]
    other = dataclasses.replace(model, system=unicycle(m=2.0))
    assert other.system.parameters["m"] == 2.0
    assert other.form == model.form
    assert other.rhs == model.rhs
