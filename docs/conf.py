"""Sphinx configuration of nhgait's documentation (``make docs``; warnings are errors).

Pages are Markdown (MyST), the API reference comes from the docstrings (autodoc + napoleon:
numpydoc sections), the gallery from the scripts in ``examples/gallery`` (sphinx-gallery: each
script is run and its figures are put on its page). Nothing is fetched from the network (no
intersphinx), so the build runs offline, in CI, from a fresh clone.
"""
from __future__ import annotations

import os
from pathlib import Path

import nhgait

#: the repository (its examples/gallery); a build from a copy of docs/ names it in $NHGAIT_REPO
ROOT = Path(os.environ.get("NHGAIT_REPO") or Path(__file__).resolve().parents[1])

project = "nhgait"
author = "the nhgait authors"
release = version = nhgait.__version__
copyright = "the nhgait authors, MIT licence"

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax",
              "sphinx_gallery.gen_gallery"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "gallery/*.ipynb", "gallery/*.py", "gallery/*.md5", "gallery/*.json",
                    "gallery/*.zip", "gallery/*.codeobj.json"]

# MyST: GitHub-style Markdown as the pages are written (tables, ``$…$`` not used); headings get
# anchors down to level 3 so that ``page.md#a-heading`` links resolve
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# autodoc: the public names as a user imports them (nhgait.dynamics.derive, …), numpydoc sections
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False

html_theme = "furo"
html_title = f"nhgait {release}"
html_static_path: list = []

# the gallery: run every script in examples/gallery, keep its figures and its printed output
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples" / "gallery"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "image_scrapers": ("matplotlib",),
    "matplotlib_animations": False,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "show_memory": False,
    "min_reported_time": 1,
    "plot_gallery": os.environ.get("NHGAIT_DOCS_GALLERY", "True"),
}

# a run of the gallery writes nothing outside the build: the examples' figures stay in memory
os.environ.setdefault("MPLBACKEND", "Agg")
