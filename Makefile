# Quick start: `make demo` (plan + verify a snakeboard forward gait; installs the core only),
# `make test` (the test suite on 2 workers, the linter and the docs build; installs every extra CI
# checks), `make docs` (the documentation into out/docs/html).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
LOG    := $(VENV)/install.log

# One stamp per set of packages, so that `make test` after `make demo` installs what the demo skipped.
CORE_STAMP := $(VENV)/.core-installed
STAMP      := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.docs-installed
DOCS_OUT ?= out/docs
# pytest-xdist workers of `make test` (the suite is written to run on any number; 2 fits a laptop);
# --dist loadfile keeps a module's tests on one worker, so its module-scoped fixtures (plans, the
# docs build) are made once, not once per worker; the files are handed out costliest first
# (tests/file_costs.py, ordered in tests/conftest.py), so xdist's own order is turned off
TEST_WORKERS ?= 2

.PHONY: demo test docs bench reproduce clean

# The core (`pip install -e .`): what `make demo`, `make reproduce` and `make bench` use. The
# set-up's pip/setuptools output goes to $(LOG) (shown in full if the install fails).
$(CORE_STAMP): pyproject.toml
	@echo "setting up $(VENV) (log: $(LOG))"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install --upgrade pip > $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@$(PY) -m pip install -e . >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(CORE_STAMP)

# The extras the test suite checks: pytest (+ xdist), ruff and rockit (test), Dask (the sweep's
# distributed back end), Pinocchio (the URDF oracle).
$(STAMP): $(CORE_STAMP)
	@echo "installing the test, dask and pinocchio extras (log: $(LOG))"
	@$(PY) -m pip install -e ".[test,dask,pinocchio]" >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(STAMP)

# The docs extra (Sphinx, MyST, sphinx-gallery, furo): for `make test` and `make docs`, not `make demo`.
$(DOCS_STAMP): $(CORE_STAMP)
	@echo "installing the docs extra (log: $(LOG))"
	@$(PY) -m pip install -e ".[docs]" >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(DOCS_STAMP)

demo: $(CORE_STAMP)
	@$(VENV)/bin/nhgait plan snakeboard --gait forward --out out/demo

test: $(STAMP) $(DOCS_STAMP)
	$(PY) -m ruff check .
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# The documentation: pages (docs/*.md), the API reference (docstrings) and the gallery (each
# examples/gallery/plot_*.py run); warnings are errors. tests/test_docs_build.py runs the same.
docs: $(DOCS_STAMP)
	$(PY) -m sphinx -W --keep-going -q -b html -d $(DOCS_OUT)/doctrees docs $(DOCS_OUT)/html

reproduce: $(CORE_STAMP)
	$(VENV)/bin/nhgait reproduce --out out/reproduce

bench: $(CORE_STAMP)
	$(PY) experiments/bench_derivation.py
	$(PY) experiments/bench_ocp.py

clean:
	rm -rf $(VENV) out .pytest_cache
