# The README's two commands are the whole set-up: `make train ...` and `make test` create
# .venv and install the project on first use (the stamp file records it).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

ENV    ?= maze-very-sparse
ALGO   ?= sim
STEPS  ?= 2000000
SEEDS  ?= 1
OUT    ?=
ARGS   ?=
RESUME ?=
L      ?=
H      ?=

.PHONY: train sweep test lint bench clean-venv

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

# make sweep ALGO=sim L=1,2,3,4,5 H=10 SEEDS=3: every combination of the comma-separated values
# (and of any sweepable flag in ARGS, e.g. ARGS="--bonus-scale 0.01,0.001") in one compiled program
sweep: $(STAMP)
	$(PY) -m simjax.sweep --env $(ENV) --algo $(ALGO) --total-steps $(STEPS) --num-seeds $(SEEDS) \
		$(if $(L),--act-len $(L)) $(if $(H),--obs-len $(H)) $(if $(OUT),--out $(OUT)) $(ARGS)

test: $(STAMP)
	$(PY) -m pytest -n auto --dist loadgroup

# pyflakes, pycodestyle, import order, bugbear, pyupgrade: pyproject.toml's [tool.ruff]
lint: $(STAMP)
	$(PY) -m ruff check .

bench: $(STAMP)
	$(PY) experiments/bench.py --out BENCHMARKS.md

clean-venv:
	rm -rf $(VENV)
