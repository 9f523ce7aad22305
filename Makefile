# Quick start: `make demo` (plan + verify a snakeboard forward gait), `make test` (the test suite,
# the docs build included), `make docs` (the documentation into out/docs/html).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
LOG    := $(VENV)/install.log

DOCS_STAMP := $(VENV)/.docs-installed
DOCS_OUT ?= out/docs

.PHONY: demo test docs bench reproduce clean

# The set-up's pip/setuptools output goes to $(LOG) (shown in full if the install fails).
$(STAMP): pyproject.toml
	@echo "setting up $(VENV) (log: $(LOG))"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install --upgrade pip > $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@$(PY) -m pip install -e ".[test,dask,pinocchio]" >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(STAMP)

# The docs extra (Sphinx, MyST, sphinx-gallery, furo): for `make test` and `make docs`, not `make demo`.
$(DOCS_STAMP): $(STAMP)
	@$(PY) -m pip install -e ".[docs]" >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(DOCS_STAMP)

demo: $(STAMP)
	@$(VENV)/bin/nhgait plan snakeboard --gait forward --out out/demo

test: $(STAMP) $(DOCS_STAMP)
	$(PY) -m ruff check .
	$(PY) -m pytest -q

# The documentation: pages (docs/*.md), the API reference (docstrings) and the gallery (each
# examples/gallery/plot_*.py run); warnings are errors. tests/test_docs_build.py runs the same.
docs: $(DOCS_STAMP)
	$(PY) -m sphinx -W --keep-going -q -b html -d $(DOCS_OUT)/doctrees docs $(DOCS_OUT)/html

reproduce: $(STAMP)
	$(VENV)/bin/nhgait reproduce --out out/reproduce

bench: $(STAMP)
	$(PY) experiments/bench_derivation.py
	$(PY) experiments/bench_ocp.py

clean:
	rm -rf $(VENV) out .pytest_cache
