# Quick start: `make demo` (plan + verify a snakeboard forward gait), `make test` (the test suite).
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench reproduce clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/nhgait plan snakeboard --gait forward --out out/demo

test: $(STAMP)
	$(PY) -m pytest -q

reproduce: $(STAMP)
	$(VENV)/bin/nhgait reproduce --out out/reproduce

bench: $(STAMP)
	$(PY) experiments/bench_derivation.py
	$(PY) experiments/bench_ocp.py

clean:
	rm -rf $(VENV) out .pytest_cache
