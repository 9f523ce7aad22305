"""The documentation builds with warnings as errors (``make docs``; issue 43): the Markdown
pages, the API reference from the docstrings and the gallery, whose figures are made here by
running every ``examples/gallery/plot_*.py``. Built from a copy of ``docs/`` in a temporary
folder (a build writes the gallery's pages beside its sources; sphinx-gallery skips scripts
whose output is already there, which would test nothing), with this session's model cache.
Nothing is fetched: the build runs offline.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx_gallery", reason="the docs extra: pip install -e '.[docs]' (make test has it)")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples" / "gallery").glob("plot_*.py"))


def _make_docs_command() -> list:
    """The sphinx arguments of the Makefile's ``docs`` recipe (one source for both)."""
    recipe = re.search(r"^docs:.*\n\t(.+)$", (ROOT / "Makefile").read_text(), re.M).group(1)
    args = recipe.split()
    assert args[:3] == ["$(PY)", "-m", "sphinx"], recipe
    return [a for a in args[3:] if not a.startswith(("$(", "-d", "docs"))]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    folder = tmp_path_factory.mktemp("docs")
    source = folder / "docs"
    shutil.copytree(ROOT / "docs", source, ignore=shutil.ignore_patterns("gallery", "sg_execution_times.rst",
                                                                          "_build"))
    html = folder / "html"
    env = dict(os.environ, NHGAIT_REPO=str(ROOT), MPLBACKEND="Agg")
    command = [sys.executable, "-m", "sphinx", *_make_docs_command(), "-d", str(folder / "doctrees"),
               str(source), str(html)]
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=600)
    return done, html


def test_make_docs_builds_with_warnings_as_errors(built):
    done, html = built
    assert "-W" in _make_docs_command()
    assert done.returncode == 0, done.stderr[-4000:]
    assert "WARNING" not in done.stderr and "ERROR" not in done.stderr, done.stderr[-4000:]
    for page in ("index", "getting-started", "gait-planning", "benchmarks", "api", "gallery/index"):
        assert (html / f"{page}.html").is_file(), page


def test_every_gallery_example_ran_and_made_its_figures(built):
    done, html = built
    assert 3 <= len(EXAMPLES) <= 6
    for script in EXAMPLES:
        page = (html / "gallery" / f"{script.stem}.html").read_text()
        figures = sorted((html / "_images").glob(f"sphx_glr_{script.stem}_0*.png"))
        assert figures, script.name
        assert all(f.stat().st_size > 5000 for f in figures)
        assert f"sphx_glr_{script.stem}_001.png" in page
        assert "Traceback" not in page


def test_the_api_reference_holds_the_public_names_and_their_docstrings(built):
    done, html = built
    page = (html / "api.html").read_text()
    for name in ("nhgait.dynamics.derive", "nhgait.dynamics.simulate", "nhgait.dynamics.System",
                 "nhgait.gaits.plan", "nhgait.ocp.Solution", "nhgait.gaits.figures.plots.plot_path"):
        assert f'id="{name}"' in page, name
    # a sentence of a docstring, rendered: the reference is made from the code, not written apart
    assert "Plan a gait" in page
