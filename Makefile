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
RESUME ?=

.PHONY: train test lint bench clean-venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# make train RESUME=runs/FOLDER continues a stopped run from its checkpoint
train: $(STAMP)
ifneq ($(RESUME),)
	$(PY) -m simjax.train --resume $(RESUME)
else
	$(PY) -m simjax.train --env $(ENV) --algo $(ALGO) --total-steps $(STEPS) --num-seeds $(SEEDS) $(if $(OUT),--out $(OUT)) $(ARGS)
endif

test: $(STAMP)
	$(PY) tools/run_tests.py

# pyflakes, pycodestyle, import order, bugbear, pyupgrade: pyproject.toml's [tool.ruff]
lint: $(STAMP)
	$(PY) -m ruff check .

bench: $(STAMP)
	$(PY) experiments/bench.py --out BENCHMARKS.md

clean-venv:
	rm -rf $(VENV)
