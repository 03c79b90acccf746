# The README's two commands are the whole set-up: `make train ...` and `make test` create
# .venv and install the project on first use (the stamp file records it).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

ENV    ?= maze-very-sparse
ALGO   ?= a2c
STEPS  ?= 2000000
SEEDS  ?= 1
OUT    ?=
ARGS   ?=

.PHONY: train test bench clean-venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

train: $(STAMP)
	$(PY) -m simjax.train --env $(ENV) --algo $(ALGO) --total-steps $(STEPS) --num-seeds $(SEEDS) $(if $(OUT),--out $(OUT)) $(ARGS)

test: $(STAMP)
	$(PY) tools/run_tests.py

bench: $(STAMP)
	$(PY) experiments/bench.py --out BENCHMARKS.md

clean-venv:
	rm -rf $(VENV)
