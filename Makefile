# The whole set-up on a fresh machine is `make demo` or `make test`:
# each creates .venv and installs the project into it on first use.
PYTHON ?= python3.11
VENV := .venv
STAMP := $(VENV)/.installed
BIN := $(VENV)/bin

.PHONY: demo test test-all lint clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# Reinstall only when the dependency declaration changes.
$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# One closed-loop episode with the POMDP policy; the planning model is solved on first use
# (400 point-based trials, 8 s to 45 s) and kept in out/cache; the episode takes about 15 s.
demo: $(STAMP)
	$(BIN)/cmanip run --planner lat-despot --scene cul_de_sac --belief-mean 0.22 0 0 --seed 1 --out out/demo

# The suite on every core (pytest-xdist): about 8 min on 2 cores, 12 min on one.
test: $(STAMP)
	$(BIN)/python -m pytest -m "not slow" -q -n auto

test-all: $(STAMP)
	$(BIN)/python -m pytest -q -n auto

lint: $(STAMP)
	$(BIN)/ruff check .

clean:
	rm -rf $(VENV) out .pytest_cache
