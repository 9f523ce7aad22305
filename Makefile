# Quick start: `make demo` (plan + verify a snakeboard forward gait), `make test` (the test suite).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
LOG    := $(VENV)/install.log

.PHONY: demo test bench reproduce clean

# The set-up's pip/setuptools output goes to $(LOG) (shown in full if the install fails).
$(STAMP): pyproject.toml
	@echo "setting up $(VENV) (log: $(LOG))"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install --upgrade pip > $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@$(PY) -m pip install -e ".[test,dask,pinocchio]" >> $(LOG) 2>&1 || (cat $(LOG); exit 1)
	@touch $(STAMP)

demo: $(STAMP)
	@$(VENV)/bin/nhgait plan snakeboard --gait forward --out out/demo

test: $(STAMP)
	$(PY) -m ruff check .
	$(PY) -m pytest -q

reproduce: $(STAMP)
	$(VENV)/bin/nhgait reproduce --out out/reproduce

bench: $(STAMP)
	$(PY) experiments/bench_derivation.py
	$(PY) experiments/bench_ocp.py

clean:
	rm -rf $(VENV) out .pytest_cache
