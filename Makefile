# turbinefit: the two commands of the README, plus benchmarks and checks.
# Each target creates its own virtual environment (.venv) and installs what it needs.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
DEMO   := demo

.PHONY: demo test bench lint typecheck check clean

$(STAMP): pyproject.toml setup.py src/turbinefit/_kernels.c
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

## demo: simulate a 200-keyframe flight, fit it, write results and plots to demo/
demo: $(STAMP)
	$(BIN)/turbinefit simulate $(DEMO)/flight --keyframes 200 --seed 1 --overwrite
	$(BIN)/turbinefit fit $(DEMO)/flight --out $(DEMO)/fit --overwrite
	@echo "results and plots: $(DEMO)/fit (summary.json, scene.png, reprojections.png)"

## test: run the test suite
test: $(STAMP)
	$(BIN)/python -m pytest

## bench: accuracy and speed figures (writes benchmarks/results/*.json)
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_fit.py

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

typecheck: $(STAMP)
	$(BIN)/mypy

check: lint typecheck test

clean:
	rm -rf $(VENV) $(DEMO) .pytest_cache .mypy_cache .ruff_cache
